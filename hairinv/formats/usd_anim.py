"""USD bodies: animated (``UsdGeomMesh`` prims with time-sampled points, ``UsdSkel`` skinned meshes) and static.

usd-core evaluates everything: a point cache's points at any time (USD interpolates its samples linearly),
the transforms above each mesh, and a skinned mesh's skinning (``UsdSkelSkinningQuery.ComputeSkinnedPoints``
with the skeleton's skinning transforms at that time; the result is in the skeleton's space, placed in the
world by the skeleton's own transform). Every mesh of the stage is read, fan-triangulated, and concatenated
in traversal order. The stage states its units (``metersPerUnit``), up axis, ``timeCodesPerSecond`` (time
code ``c`` is at ``c / timeCodesPerSecond`` seconds) and ``framesPerSecond``; the sample times are every
time sample authored on the stage. The rest pose is each mesh's authored points (a skinned mesh's bind pose,
through its ``geomBindTransform``) at the default time, placed in the world.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError
from .animated import AnimatedBody
from .base import register_animated_reader, register_mesh_reader
from .mesh import triangle_mesh

__all__ = ["read_usd_animated", "read_usd_mesh", "is_animated_usd"]

_SUFFIXES = (".usd", ".usda", ".usdc", ".usdz")


def _open(path: Path):
    try:
        from pxr import Usd
    except ImportError:
        raise InputError("is a USD file, and reading it needs usd-core (pip install usd-core)", path) from None
    try:
        stage = Usd.Stage.Open(str(path))
    except Exception as exc:  # pxr raises Tf errors of its own types
        reason = str(exc).strip().splitlines()[-1] if str(exc).strip() else type(exc).__name__
        raise InputError(f"could not be opened as a USD stage ({reason})", path) from None
    if stage is None:
        raise InputError("could not be opened as a USD stage", path)
    return stage


def _sample_codes(stage) -> list[float]:
    codes = set()
    for prim in stage.Traverse():
        for attribute in prim.GetAttributes():
            codes.update(attribute.GetTimeSamples())
    return sorted(codes)


def _meshes(stage):
    from pxr import UsdGeom

    return [UsdGeom.Mesh(prim) for prim in stage.Traverse() if prim.IsA(UsdGeom.Mesh)]


def is_animated_usd(path: Path) -> bool:
    """Whether a USD stage has a mesh and time samples (on points, transforms or a skeleton's animation); a
    file usd-core cannot open raises :class:`InputError`."""
    stage = _open(path)
    return bool(_meshes(stage)) and bool(_sample_codes(stage))


def _triangles(mesh, path: Path) -> np.ndarray:
    from pxr import UsdGeom

    counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get() or [], dtype=np.int64)
    indices = np.asarray(mesh.GetFaceVertexIndicesAttr().Get() or [], dtype=np.int64)
    if counts.sum() != len(indices) or np.any(counts < 3):
        raise InputError(f"mesh {mesh.GetPath()} has face vertex counts that do not match its indices", path)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    faces = [indices[[s, s + k, s + k + 1]] for s, n in zip(starts, counts) for k in range(1, n - 1)]
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if mesh.GetOrientationAttr().Get() == UsdGeom.Tokens.leftHanded:
        faces = faces[:, ::-1]  # outward normals by the right-hand rule, as every other reader gives
    return faces


def _matrix(gf) -> np.ndarray:
    """A Gf matrix (row vectors: p' = p M) as the 4x4 acting on column vectors."""
    return np.array(gf, dtype=np.float64).T


def _place(points, matrix: np.ndarray) -> np.ndarray:
    return np.asarray(points, dtype=np.float64).reshape(-1, 3) @ matrix[:3, :3].T + matrix[:3, 3]


@register_animated_reader(*_SUFFIXES, probe=is_animated_usd)
def read_usd_animated(path: Path, fps: float | None = None) -> AnimatedBody:
    """Read the meshes of a USD stage as one animated body; ``fps`` overrides the stage's frames per second."""
    from pxr import Usd, UsdGeom, UsdSkel

    path = Path(path)
    stage = _open(path)
    meshes = _meshes(stage)
    if not meshes:
        raise InputError("holds no UsdGeomMesh", path)
    per_second = float(stage.GetTimeCodesPerSecond())
    codes = _sample_codes(stage) or [float(stage.GetStartTimeCode())]
    if fps is None:
        fps = float(stage.GetFramesPerSecond())

    cache, skinning, joints = UsdSkel.Cache(), {}, []
    for prim in stage.Traverse():
        if not prim.IsA(UsdSkel.Root):
            continue
        root = UsdSkel.Root(prim)
        cache.Populate(root, Usd.PrimDefaultPredicate)
        for binding in cache.ComputeSkelBindings(root, Usd.PrimDefaultPredicate):
            skeleton = binding.GetSkeleton()
            query = cache.GetSkelQuery(skeleton)
            joints += [str(j).split("/")[-1] for j in query.GetJointOrder() if str(j).split("/")[-1] not in joints]
            for target in binding.GetSkinningTargets():
                skinning[target.GetPrim().GetPath()] = (query, target, UsdGeom.Xformable(skeleton.GetPrim()))

    xform_cache = UsdGeom.XformCache
    parts, faces, base = [], [], 0
    for mesh in meshes:
        points = mesh.GetPointsAttr()
        rest = points.Get(Usd.TimeCode.Default())
        if rest is None:
            rest = points.Get(Usd.TimeCode(codes[0]))
        if rest is None or len(rest) == 0:
            raise InputError(f"mesh {mesh.GetPath()} has no points", path)
        for code in points.GetTimeSamples():
            sample = points.Get(Usd.TimeCode(code))
            if sample is None or len(sample) != len(rest):
                raise InputError(f"mesh {mesh.GetPath()} has {0 if sample is None else len(sample)} points at time "
                                 f"code {code:g} and {len(rest)} at rest; an animated body needs one topology", path)
        for topology in (mesh.GetFaceVertexCountsAttr(), mesh.GetFaceVertexIndicesAttr()):
            if topology.GetNumTimeSamples() > 1:
                raise InputError(f"mesh {mesh.GetPath()} has time-sampled {topology.GetName()}; an animated body "
                                 "needs one topology", path)
        tri = _triangles(mesh, path)
        if len(tri) and tri.max() >= len(rest):
            raise InputError(f"mesh {mesh.GetPath()} has face indices past its points", path)
        faces.append(tri + base)
        base += len(rest)
        parts.append((mesh, skinning.get(mesh.GetPrim().GetPath())))

    def evaluate(t: float | None) -> np.ndarray:
        code = Usd.TimeCode.Default() if t is None else Usd.TimeCode(t * per_second)
        assert stage  # the prims live as long as their stage: this closure keeps it
        world = xform_cache(code)
        out = []
        for mesh, skinned in parts:
            points = mesh.GetPointsAttr().Get(code)
            if points is None:
                points = mesh.GetPointsAttr().Get(Usd.TimeCode(codes[0]))
            if skinned is None:
                out.append(_place(points, _matrix(world.GetLocalToWorldTransform(mesh.GetPrim()))))
                continue
            query, target, skeleton = skinned
            skeleton_world = _matrix(world.GetLocalToWorldTransform(skeleton.GetPrim()))
            if t is None:  # the bind pose: the authored points through the geom bind transform
                bind = _matrix(target.GetGeomBindTransform(code))
                out.append(_place(_place(points, bind), skeleton_world))
                continue
            points = type(points)(points)
            if not target.ComputeSkinnedPoints(query.ComputeSkinningTransforms(code), points, code):
                raise InputError(f"mesh {mesh.GetPath()}: usd-core could not skin it at {t:g} s", path)
            out.append(_place(points, skeleton_world))
        vertices = np.concatenate(out)
        if not np.isfinite(vertices).all():
            raise InputError(f"has vertex coordinates that are NaN or Inf at {t} s", path)
        return vertices

    times = np.asarray(codes, dtype=np.float64) / per_second
    return AnimatedBody(
        vertices=evaluate(None), faces=np.concatenate(faces), times=times, fps=fps,
        format="usd-skel" if skinning else "usd-points", evaluate=evaluate, joints=tuple(joints),
        scale_to_m=float(UsdGeom.GetStageMetersPerUnit(stage)), up=str(UsdGeom.GetStageUpAxis(stage)).lower(),
    )


@register_mesh_reader(*_SUFFIXES)
def read_usd_mesh(path: Path):
    """Read the meshes of a USD stage as one static body mesh: each placed in the world, at rest (a skinned
    mesh in its bind pose), fan-triangulated and concatenated, in the stage's units.

    Returns
    -------
    trimesh.Trimesh
        ``vertices`` (V, 3) float64 in the stage's units, ``faces`` (T, 3) int64; the stage's
        ``metersPerUnit`` and ``upAxis`` in ``metadata[STATED_FRAME]``.
    """
    from pxr import UsdGeom

    path = Path(path)
    body = read_usd_animated(path)
    stage = _open(path)
    up = str(UsdGeom.GetStageUpAxis(stage)).lower()
    stated = {"scale_to_m": float(UsdGeom.GetStageMetersPerUnit(stage)), "up": up if up in ("x", "y", "z") else None,
              "by": "the USD stage"}
    return triangle_mesh(body.vertices, body.faces, path, stated)
