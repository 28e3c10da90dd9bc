"""USD ``BasisCurves`` hairstyles (.usd, .usda, .usdc, .usdz), read and written with usd-core.

Reading gathers every ``UsdGeom.BasisCurves`` prim of the stage (in
traversal order, instance proxies included), transforms its points to world
space and turns each curve into a polyline of points that lie on the curve:

* ``linear``: the vertices themselves.
* ``cubic`` ``bezier`` (n = 3k + 1 control points): every segment is
  evaluated at t = 0, 1/3, 2/3, plus the last end point, so the polyline
  has n points, all on the curve (every third one is a segment end point).
* ``cubic`` ``bspline`` (uniform): the curve evaluated at its knots, i.e.
  ``(P[i] + 4 P[i+1] + P[i+2]) / 6``, n - 2 points for a non-periodic curve
  and n points for ``wrap = pinned`` (phantom end points ``2 P0 - P1``).
* ``cubic`` ``catmullRom``: the curve interpolates its control points, so
  the knots are ``P[1:-1]`` (n - 2 points), or all of P when pinned.

Periodic (closed) curves are refused: they are not hair strands.
Time-sampled data is read at the default time, else at the earliest sample.
Prims that ``hairinv export`` marks as another shape of the groom beside it
(custom data ``hairinv:role`` other than ``groom``: the rest shape, a trimmed
simulation) are skipped, so an exported file reads back as the groom it holds.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..atomic import atomic_path
from ..errors import InputError
from .base import check_strands, register_curves_reader, register_curves_writer

ROLE_KEY = "hairinv:role"
"""Prim custom data naming what a curves prim written by ``hairinv export`` holds (``groom``, ``rest``, ``frames``)."""
GROOM_ROLE = "groom"


def _get(attr):
    from pxr import Usd

    value = attr.Get(Usd.TimeCode.Default())
    if value is None:
        value = attr.Get(Usd.TimeCode.EarliestTime())
    return value


def _evaluate(ctrl: np.ndarray, basis: str, wrap: str) -> np.ndarray:
    """Points on one cubic curve at its control-point parameters; see the module docstring."""
    n = len(ctrl)
    pinned = wrap == "pinned"
    if basis == "bezier":
        if n < 4 or (n - 1) % 3:
            raise ValueError(f"a cubic bezier curve needs 3k + 1 (k >= 1) points, not {n}")
        p0, p1, p2, p3 = ctrl[0:-1:3], ctrl[1::3], ctrl[2::3], ctrl[3::3]
        out = np.empty((n, 3))
        for j, t in enumerate((0.0, 1 / 3, 2 / 3)):
            s = 1.0 - t
            out[j:-1:3] = s**3 * p0 + 3 * s * s * t * p1 + 3 * s * t * t * p2 + t**3 * p3
        out[-1] = ctrl[-1]
        return out
    if basis in ("bspline", "catmullRom"):
        if n < (2 if pinned else 4):
            raise ValueError(f"a cubic {basis} curve needs at least {2 if pinned else 4} points, not {n}")
        if basis == "catmullRom":
            return ctrl.copy() if pinned else ctrl[1:-1].copy()
        if pinned:
            ctrl = np.vstack([2 * ctrl[0] - ctrl[1], ctrl, 2 * ctrl[-1] - ctrl[-2]])
        return (ctrl[:-2] + 4 * ctrl[1:-1] + ctrl[2:]) / 6.0
    raise ValueError(f"cubic basis {basis!r} is not supported")


@register_curves_reader(".usd", ".usda", ".usdc", ".usdz")
def read_usd_curves(path: Path):
    """Read every BasisCurves prim of a USD stage as strands.

    Returns
    -------
    RawCurves
        ``points`` (P, 3) float64 in world space and stage units,
        ``offsets`` (S + 1,) int64, ``up`` from the stage (``"y"``/``"z"``),
        ``scale_to_m`` the stage's metersPerUnit if authored, else None.
        ``extras["widths"]`` (P,) when every prim is linear with per-vertex
        widths; ``extras["prims"]`` lists the prim paths read, ``extras["skipped_prims"]``
        the curves prims skipped as another shape of the groom (see the module docstring).
    """
    from pxr import Usd, UsdGeom

    path = Path(path)
    try:
        stage = Usd.Stage.Open(str(path))
    except Exception:
        stage = None
    if stage is None:
        raise InputError("could not be opened as a USD stage", path)

    pieces, counts, widths, prims, skipped = [], [], [], [], []
    strand = 0
    for prim in stage.Traverse(Usd.TraverseInstanceProxies()):
        if not prim.IsA(UsdGeom.BasisCurves):
            continue
        curves = UsdGeom.BasisCurves(prim)
        name = str(prim.GetPath())
        role = prim.GetCustomDataByKey(ROLE_KEY)
        if role is not None and role != GROOM_ROLE:
            skipped.append(name)
            continue
        pts = _get(curves.GetPointsAttr())
        vcounts = _get(curves.GetCurveVertexCountsAttr())
        pts = np.zeros((0, 3)) if pts is None else np.asarray(pts, dtype=np.float64).reshape(-1, 3)
        vcounts = np.zeros(0, np.int64) if vcounts is None else np.asarray(vcounts, dtype=np.int64)
        if np.any(vcounts < 0) or vcounts.sum() != len(pts):
            raise InputError(f"prim {name} has curveVertexCounts that do not add up to its {len(pts)} points", path)
        m = np.asarray(curves.ComputeLocalToWorldTransform(Usd.TimeCode.Default()), dtype=np.float64)
        pts = pts @ m[:3, :3] + m[3, :3]  # USD matrices act on row vectors
        kind, basis, wrap = (str(_get(a) or "") for a in (curves.GetTypeAttr(), curves.GetBasisAttr(), curves.GetWrapAttr()))
        kind, basis, wrap = kind or "cubic", basis or "bezier", wrap or "nonperiodic"
        if wrap == "periodic":
            raise InputError(f"prim {name} holds periodic (closed) curves, which are not hair strands", path)
        starts = np.concatenate([[0], np.cumsum(vcounts)])
        for c in range(len(vcounts)):
            ctrl = pts[starts[c] : starts[c + 1]]
            if kind == "linear":
                piece = ctrl
            else:
                try:
                    piece = _evaluate(ctrl, basis, wrap)
                except ValueError as exc:
                    raise InputError(f"{exc} (prim {name})", path, strand=strand + c) from None
            pieces.append(piece)
            counts.append(len(piece))
        strand += len(vcounts)
        prims.append(name)
        w = _get(curves.GetWidthsAttr())
        w = None if w is None else np.asarray(w, dtype=np.float64)
        widths.append(w if kind == "linear" and w is not None and len(w) == len(pts) else None)
    if not prims:
        raise InputError("has no BasisCurves prims", path)

    offsets = np.zeros(len(counts) + 1, dtype=np.int64)
    np.cumsum(counts, out=offsets[1:])
    points = np.concatenate(pieces) if pieces else np.zeros((0, 3))
    raw = check_strands(points, offsets, path, "usd-basiscurves")
    raw.up = str(UsdGeom.GetStageUpAxis(stage)).lower()
    if UsdGeom.StageHasAuthoredMetersPerUnit(stage):
        raw.scale_to_m = float(UsdGeom.GetStageMetersPerUnit(stage))
    if all(w is not None for w in widths):
        raw.extras["widths"] = np.concatenate(widths)
    raw.extras["prims"] = prims
    raw.extras["skipped_prims"] = skipped
    return raw


@register_curves_writer(".usd", ".usda", ".usdc")
def write_usd_curves(path: Path, points, offsets, widths=None, up: str = "y", meters_per_unit: float = 1.0) -> None:
    """Write strands as one linear BasisCurves prim ``/Root/Hair`` (``/Root`` is the default prim).

    Parameters
    ----------
    points : (P, 3) float
        Vertices, strand after strand; stored as float32.
    offsets : (S + 1,) int
        CSR offsets; every strand needs at least 2 points.
    widths : float or (P,) float, optional
        Strand diameter in stage units, constant or per vertex.
    up : {"y", "z"}
        Stage up axis.
    meters_per_unit : float
        Stage ``metersPerUnit``.

    The stage is saved with :func:`save_stage` (a temporary file in the same
    folder, then a rename), so a reader never sees a half-written file.
    """
    from pxr import Usd, UsdGeom, Vt

    path = Path(path)
    raw = check_strands(points, offsets, path, "usd-basiscurves")
    counts = np.diff(raw.offsets)
    if np.any(counts < 2):
        s = int(np.argmax(counts < 2))
        raise InputError(f"has {int(counts[s])} points but a linear USD curve needs at least 2", path, strand=s)
    if str(up).lower() not in ("y", "z"):
        raise InputError(f"the up axis must be 'y' or 'z', not {up!r}", path)
    if not (np.isfinite(meters_per_unit) and meters_per_unit > 0):
        raise InputError(f"metersPerUnit must be a positive number, not {meters_per_unit!r}", path)
    if widths is not None:
        widths = np.asarray(widths, dtype=np.float32)
        if widths.ndim == 0:
            widths = widths.reshape(1)
        elif widths.shape != (len(raw.points),):
            raise InputError(f"widths must be a number or one value per point, not shape {widths.shape}", path)

    stage = Usd.Stage.CreateInMemory()
    root = UsdGeom.Xform.Define(stage, "/Root")
    stage.SetDefaultPrim(root.GetPrim())
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y if str(up).lower() == "y" else UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, float(meters_per_unit))
    curves = UsdGeom.BasisCurves.Define(stage, "/Root/Hair")
    curves.CreateTypeAttr(UsdGeom.Tokens.linear)
    curves.CreateWrapAttr(UsdGeom.Tokens.nonperiodic)
    pts32 = np.ascontiguousarray(raw.points, dtype=np.float32)
    curves.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(pts32))
    curves.CreateCurveVertexCountsAttr(Vt.IntArray.FromNumpy(counts.astype(np.int32)))
    pad = 0.0
    if widths is not None:
        curves.CreateWidthsAttr(Vt.FloatArray.FromNumpy(widths))
        curves.SetWidthsInterpolation(UsdGeom.Tokens.constant if len(widths) == 1 else UsdGeom.Tokens.vertex)
        pad = float(widths.max()) / 2
    lo, hi = pts32.min(axis=0) - pad, pts32.max(axis=0) + pad
    curves.CreateExtentAttr(Vt.Vec3fArray.FromNumpy(np.stack([lo, hi]).astype(np.float32)))
    save_stage(stage, path)


def save_stage(stage, path: Path) -> None:
    """Save a USD stage's root layer to ``path`` through the atomic writer (:mod:`hairinv.atomic`).

    The file format follows the suffix (``.usda`` text, ``.usdc`` and ``.usd`` binary crate). Raises
    :class:`InputError` naming ``path`` if it cannot be written; the destination is then unchanged.
    """
    path = Path(path)
    try:
        with atomic_path(path, suffix=f".tmp{path.suffix}") as tmp:
            if not stage.GetRootLayer().Export(str(tmp)):
                raise OSError("the USD layer could not be exported")
    except Exception as exc:  # pxr raises Tf.ErrorException, the file system OSError
        reason = str(exc).strip().splitlines()[-1] if str(exc).strip() else type(exc).__name__
        raise InputError(f"cannot be written as USD ({reason})", path) from None
