"""USD (usd-core): the groom as BasisCurves with its rest shape, simulation and body (docs/export.md).

Layout (``/Root`` is the default prim):

- ``/Root/Hair``, BasisCurves, ``type = linear`` (the vertices joined by straight segments; no basis),
  ``wrap = nonperiodic``; or with ``--basis catmull-rom`` ``type = cubic``, ``basis = catmullRom``,
  ``wrap = pinned`` (a C1 curve through every vertex, the root and tip included): the shape asked for
  (``all``: the input shape), ``widths`` per vertex = the rod diameter in stage units, and primvars: ``groom_id``, ``groom_guide`` (1: every strand is a simulated
  guide) and ``id`` (uniform int, Unreal's and Houdini's strand ids); ``rest`` (vertex point3f, the rest
  shape at the same vertices, Houdini's rest attribute); hairinv's quantities with the ``groom_`` prefix
  Unreal's importer keeps (``groom_fit_error_mean``, ``groom_fit_error_max``, ``groom_stiffening``,
  ``groom_stability_margin`` uniform float, ``groom_stable`` uniform int; ``groom_contact_force``,
  ``groom_rest_curvature`` vertex; SI units, stated in each primvar's documentation); ``groom_root_uv``
  (uniform texCoord2f) where the body file has texture coordinates: the body's UV at the surface point
  closest to each root. With ``all`` and ``/frames``, ``points`` carries one time sample per frame.
- ``/Root/Rest`` (``all``, with ``/model``): the rest shape as curves of its own.
- ``/Root/Frames`` (``all``, a trimmed simulation): the frames on the cut strands' own topology.
- ``/Root/Body``, Mesh: the body the file records, if it is still there unchanged; with frames its
  rigid motion as time samples of ``xformOp:transform``.

Stage metadata: ``metersPerUnit`` is the groom's unit (``/curves`` ``scale_to_m``), ``upAxis`` its up axis
(turned onto +Y if it is neither +Y nor +Z); with frames ``timeCodesPerSecond`` = ``framesPerSecond`` = the
run's frame rate and time code ``t * fps`` for a frame at ``t`` seconds. Curves prims other than
``/Root/Hair`` carry the custom data ``hairinv:role`` so that hairinv's reader skips them.
"""

from __future__ import annotations

import numpy as np

from .. import __version__, stages
from ..formats.usd import GROOM_ROLE, ROLE_KEY, save_stage
from ..contacts.body import texture_coordinates
from ..errors import InputError
from .base import register_exporter
from .source import ExportSource, OutputAxes, Shape, Strands

# m: roots farther than this from the body get a root UV with a warning (the nearest surface point's)
ROOT_UV_FAR = 0.02
# A frame's time code t * fps this close to an integer is that integer (frames are written at k / fps).
_WHOLE_CODE = 1e-6


def _codes(source: ExportSource) -> list[float]:
    codes = source.times * source.fps
    return [float(round(c)) if abs(c - round(c)) < _WHOLE_CODE else float(c) for c in codes]


class _Writer:
    """Builds the stage in memory; :func:`export_usd` saves it atomically."""

    def __init__(self, source: ExportSource, shape: Shape, report, basis: str = "linear"):
        from pxr import Usd, UsdGeom

        self.source, self.shape, self.report, self.basis = source, shape, report, basis
        self.axes = OutputAxes.keeping(source.up, ("y", "z"), source.scale_to_m)
        if self.axes.note:
            report.lines.append(self.axes.note)
        self.stage = Usd.Stage.CreateInMemory()
        UsdGeom.SetStageUpAxis(self.stage, UsdGeom.Tokens.y if self.axes.up == "y" else UsdGeom.Tokens.z)
        UsdGeom.SetStageMetersPerUnit(self.stage, self.axes.meters_per_unit)
        root = UsdGeom.Xform.Define(self.stage, "/Root")
        self.stage.SetDefaultPrim(root.GetPrim())
        layer = self.stage.GetRootLayer()
        layer.documentation = (f"hairinv {__version__} export of {source.name} (--shape {shape}); "
                               "docs/export.md in hairinv says what each prim and primvar holds")
        layer.customLayerData = {"hairinv": {"version": __version__, "source": source.name,
                                             "source_sha256": stages.sha256_file(source.path),
                                             "shape": str(shape)}}
        self.radius, radius_note = source.radius
        self.width = float(self.axes.length(2.0 * self.radius))
        report.lines.append(f"widths: {self.width:.6g} stage units, the rod diameter from {radius_note}")

    # ------------------------------------------------------------------ pieces

    def _vec3(self, points: np.ndarray):
        from pxr import Vt

        return Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(self.axes.points(points), dtype=np.float32))

    def curves(self, path: str, strands: Strands, role: str):
        """A linear BasisCurves prim with points, counts, widths and the strand ids."""
        from pxr import Sdf, UsdGeom, Vt

        curves = UsdGeom.BasisCurves.Define(self.stage, path)
        prim = curves.GetPrim()
        prim.SetCustomDataByKey(ROLE_KEY, role)
        if self.basis == "linear":
            curves.CreateTypeAttr(UsdGeom.Tokens.linear)
            curves.CreateWrapAttr(UsdGeom.Tokens.nonperiodic)
        else:  # through every vertex, the ends included (pinned)
            curves.CreateTypeAttr(UsdGeom.Tokens.cubic)
            curves.CreateBasisAttr(UsdGeom.Tokens.catmullRom)
            curves.CreateWrapAttr(UsdGeom.Tokens.pinned)
        curves.CreateCurveVertexCountsAttr(Vt.IntArray.FromNumpy(strands.counts.astype(np.int32)))
        points = self._vec3(strands.points)
        curves.CreatePointsAttr(points)
        widths = Vt.FloatArray.FromNumpy(np.full(len(strands.points), self.width, dtype=np.float32))
        curves.CreateWidthsAttr(widths)
        curves.SetWidthsInterpolation(UsdGeom.Tokens.vertex)
        curves.CreateExtentAttr(UsdGeom.Curves.ComputeExtent(points, widths))
        kind = "linear curves" if self.basis == "linear" else "pinned Catmull-Rom cubic curves"
        prim.SetDocumentation(f"{strands.label} of {self.source.name}: {kind} through the strand vertices, "
                              "root first; widths are the rod diameter in stage units")
        ids = Vt.IntArray.FromNumpy(np.arange(strands.n_strands, dtype=np.int32))
        api = UsdGeom.PrimvarsAPI(prim)
        following = self.source.follow is not None
        where = "the render groom" if following else "the stage file"
        guide_doc = ("1: the strand is a simulated guide, 0: a render strand following the guides (Unreal groom "
                     "attribute)") if following else "1: every strand is a guide, simulated (Unreal groom attribute)"
        for name, values, doc in (
                ("groom_id", ids, f"strand index in {where} (Unreal groom attribute)"),
                ("id", ids, f"strand index in {where} (Houdini's per-curve id)"),
                ("groom_guide", Vt.IntArray.FromNumpy(self.source.guide_flags()), guide_doc)):
            primvar = api.CreatePrimvar(name, Sdf.ValueTypeNames.IntArray, UsdGeom.Tokens.uniform)
            primvar.Set(values)
            primvar.GetAttr().SetDocumentation(doc)
        return curves

    def follow_primvars(self, curves) -> None:
        """``guide_ids`` and ``guide_weights`` (uniform, K per strand): the guides each render strand follows."""
        from pxr import Sdf, UsdGeom, Vt

        follow = self.source.follow
        api = UsdGeom.PrimvarsAPI(curves.GetPrim())
        count = follow.guide.shape[1]
        for name, kind, values, doc in (
                ("guide_ids", Sdf.ValueTypeNames.IntArray, Vt.IntArray.FromNumpy(follow.guide.astype(np.int32).ravel()),
                 f"the {count} guides the strand follows, nearest root first: their strand indices in the stage "
                 "file's /curves"),
                ("guide_weights", Sdf.ValueTypeNames.FloatArray,
                 Vt.FloatArray.FromNumpy(follow.weight.astype(np.float32).ravel()),
                 "the weights of those guides (summing to 1)")):
            primvar = api.CreatePrimvar(name, kind, UsdGeom.Tokens.uniform, count)
            primvar.Set(values)
            primvar.GetAttr().SetDocumentation(doc)

    def float_primvar(self, curves, name: str, values: np.ndarray, interpolation: str, doc: str) -> None:
        from pxr import Sdf, UsdGeom, Vt

        primvar = UsdGeom.PrimvarsAPI(curves.GetPrim()).CreatePrimvar(name, Sdf.ValueTypeNames.FloatArray,
                                                                      interpolation)
        primvar.Set(Vt.FloatArray.FromNumpy(np.ascontiguousarray(values, dtype=np.float32)))
        primvar.GetAttr().SetDocumentation(doc)

    def animate(self, curves, codes: list[float]) -> None:
        """One time sample of ``points`` (and ``extent``) per frame."""
        from pxr import Usd, UsdGeom

        points_attr, extent_attr = curves.GetPointsAttr(), curves.GetExtentAttr()
        widths = curves.GetWidthsAttr().Get()
        for k, code in enumerate(codes):
            points = self._vec3(self.source.frame(k).points)
            points_attr.Set(points, Usd.TimeCode(code))
            extent_attr.Set(UsdGeom.Curves.ComputeExtent(points, widths), Usd.TimeCode(code))

    def root_uv(self, curves, strands: Strands, mesh) -> None:
        """``groom_root_uv`` (uniform texCoord2f, Unreal's): the body's UV where each strand's root meets it."""
        from pxr import Sdf, UsdGeom, Vt

        found = texture_coordinates(mesh, strands.points[strands.offsets[:-1]]) if mesh is not None else None
        if found is None:
            if mesh is not None:
                self.report.lines.append("no groom_root_uv: the body file has no texture coordinates")
            return
        uv, distance = found
        primvar = UsdGeom.PrimvarsAPI(curves.GetPrim()).CreatePrimvar(
            "groom_root_uv", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.uniform)
        primvar.Set(Vt.Vec2fArray.FromNumpy(np.ascontiguousarray(uv, dtype=np.float32)))
        primvar.GetAttr().SetDocumentation("the body's texture coordinates at the surface point closest to the "
                                           "strand's root (Unreal groom attribute)")
        far = int(np.count_nonzero(distance > ROOT_UV_FAR))
        self.report.lines.append("groom_root_uv from the body's texture coordinates (roots "
                                 f"{1e3 * np.median(distance):.3g} mm from the surface, median)")
        if far:
            self.report.warnings.append(f"warning: {self.source.name}: {far} of {len(uv)} roots lie more than "
                                        f"{1e3 * ROOT_UV_FAR:g} mm from the body; their groom_root_uv is the nearest "
                                        "surface point's")

    def body(self, codes: list[float] | None, frame: int | None, mesh, note: str) -> None:
        from pxr import Gf, Usd, UsdGeom, Vt

        if self.source.body_animated:  # a shot: the body as the frames keep it
            mesh = self.source.body_mesh(frame if frame is not None else 0)
            note = "the shot's animated body"
        if mesh is None:
            self.report.warnings.append(f"warning: {self.source.name}: {note}; the USD file has no body mesh")
            return
        body = UsdGeom.Mesh.Define(self.stage, "/Root/Body")
        points = self._vec3(np.asarray(mesh.vertices, dtype=np.float64))
        faces = np.asarray(mesh.faces, dtype=np.int32)
        body.CreatePointsAttr(points)
        body.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(faces), 3, dtype=np.int32)))
        body.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(faces.ravel()))
        body.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        body.CreateExtentAttr(UsdGeom.Mesh.ComputeExtent(points))
        body.GetPrim().SetDocumentation(f"the body mesh {self.source.name} was made with, in the groom's units")
        moved = None
        if codes is not None and self.source.body_animated:
            attr = body.GetPointsAttr()
            for k, code in enumerate(codes):
                attr.Set(self._vec3(np.asarray(self.source.frames["body_vertices"][k], dtype=np.float64)),
                         Usd.TimeCode(code))
            moved = "its animated points at each frame as time samples"
        elif codes is not None:
            op = body.AddTransformOp()
            for k, code in enumerate(codes):
                op.Set(Gf.Matrix4d(self.axes.transform(self.source.body_transform(k)).T.tolist()),
                       Usd.TimeCode(code))
            moved = "its transform at each frame as time samples"
            if self.source.body_removed:
                body.CreateVisibilityAttr().Set(UsdGeom.Tokens.invisible, Usd.TimeCode(codes[0]))
                moved = "hidden during the frames (the scene removed it)"
        elif frame is not None and self.source.body_animated:
            body.GetPointsAttr().Set(self._vec3(np.asarray(self.source.frames["body_vertices"][frame],
                                                           dtype=np.float64)))
            moved = f"as in frame {frame}"
        elif frame is not None:
            body.AddTransformOp().Set(Gf.Matrix4d(self.axes.transform(self.source.body_transform(frame)).T.tolist()))
            moved = f"placed as in frame {frame}"
        self.report.lines.append(f"{note}, as /Root/Body ({len(faces)} triangles)" + (f", {moved}" if moved else ""))

    # ------------------------------------------------------------------ the file

    def build(self) -> None:
        source, shape, report = self.source, self.shape, self.report
        main_shape = Shape("input") if shape.kind == "all" else shape
        strands = source.strands(main_shape)
        hair = self.curves("/Root/Hair", strands, GROOM_ROLE)
        same_topology = main_shape.kind != "frame" or not source.frames_trimmed
        described = [f"/Root/Hair: {strands.n_strands} strands, {len(strands.points)} points, {strands.label}"]
        if source.follow is not None:
            self.follow_primvars(hair)
            described.append("primvars guide_ids, guide_weights")
        for name, (values, doc) in source.strand_values().items():
            self.float_primvar(hair, f"groom_{name}", values, "uniform", doc)
        stable = source.stable()
        if stable is not None:
            from pxr import Sdf, UsdGeom, Vt

            primvar = UsdGeom.PrimvarsAPI(hair.GetPrim()).CreatePrimvar("groom_stable", Sdf.ValueTypeNames.IntArray,
                                                                        UsdGeom.Tokens.uniform)
            primvar.Set(Vt.IntArray.FromNumpy(stable.astype(np.int32)))
            primvar.GetAttr().SetDocumentation("1: the strand rests in a stable equilibrium (a still simulation "
                                               "keeps it), 0: unstable")
        if same_topology:
            for name, (values, doc) in source.vertex_values().items():
                self.float_primvar(hair, f"groom_{name}", values, "vertex", doc)
            if source.has_rest:
                from pxr import Sdf, UsdGeom

                rest = source.rest()
                primvar = UsdGeom.PrimvarsAPI(hair.GetPrim()).CreatePrimvar(
                    "rest", Sdf.ValueTypeNames.Point3fArray, UsdGeom.Tokens.vertex)
                primvar.Set(self._vec3(rest.points))
                primvar.GetAttr().SetDocumentation("rest shape at the same vertices (nothing pressing on it), "
                                                   "stage units (Houdini's rest attribute)")
                described.append("primvar rest")
        elif source.vertex_values() or source.has_rest:
            report.warnings.append(f"warning: {source.name}: frame {shape.frame} is on the trimmed strands, so the "
                                   "per-vertex primvars (rest, contact force, rest curvature) are left out")
        codes = None
        if shape.kind == "all":
            if source.has_rest:
                self.curves("/Root/Rest", source.rest(), "rest")
                described.append("/Root/Rest (rest shape)")
            if source.n_frames:
                codes = _codes(source)
                self.stage.SetTimeCodesPerSecond(source.fps)
                self.stage.SetFramesPerSecond(source.fps)
                self.stage.SetStartTimeCode(codes[0])
                self.stage.SetEndTimeCode(codes[-1])
                if source.frames_trimmed:
                    frames = self.curves("/Root/Frames", source.frame(0), "frames")
                    self.animate(frames, codes)
                    described.append(f"/Root/Frames: {source.n_frames} frames on the trimmed strands as time "
                                     f"samples at {source.fps:g} fps")
                else:
                    self.animate(hair, codes)
                    described.append(f"{source.n_frames} frames as time samples of its points at {source.fps:g} fps")
        mesh, note = source.body()
        # the roots at rest on the body as the file records it (a frame's roots moved with the body, rigidly)
        self.root_uv(hair, source.strands(Shape("input")), mesh)
        report.lines.append("; ".join(described))
        self.body(codes, shape.frame if shape.kind == "frame" else None, mesh, note)


#: ``--basis`` values: the curves' type in USD.
BASES = ("linear", "catmull-rom")


@register_exporter(".usda", ".usdc", ".usd", name="USD", default_shape="all", several_shapes=True,
                   options=("basis",))
def export_usd(source, path, shape, report, basis: str = "linear") -> None:
    if basis not in BASES:
        raise InputError(f"--basis takes {' or '.join(BASES)}, not {basis!r}", path)
    writer = _Writer(source, shape, report, basis)
    writer.build()
    save_stage(writer.stage, path)
    kind = "linear" if basis == "linear" else "cubic pinned Catmull-Rom"
    report.lines.insert(0, f"wrote {path}: USD, {kind} BasisCurves, metersPerUnit {writer.axes.meters_per_unit:g}, "
                           f"upAxis {writer.axes.up.upper()}")
