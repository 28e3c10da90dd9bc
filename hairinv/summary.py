"""Plain-data summaries of stage files (for ``hairinv info`` and reports)."""

from __future__ import annotations

import numpy as np

from . import stages
from .groom import strand_lengths


def _stats(values, scale: float = 1.0, digits: int = 4) -> dict:
    values = np.asarray(values, dtype=np.float64) * scale
    if values.size == 0:
        return {}
    return {
        "min": round(float(values.min()), digits),
        "median": round(float(np.median(values)), digits),
        "max": round(float(values.max()), digits),
    }


def summarise(stage: stages.StageFile) -> dict:
    """A JSON-ready dictionary describing every group of a stage file."""
    out = {
        "producer": stage.producer,
        "schema_version": stage.schema_version,
        "stages": ",".join(stage.groups),
        "groups": {},
    }
    if stages.CURVES in stage:
        g = stage[stages.CURVES]
        pts, off = g["points"], g["offsets"]
        out["groups"]["curves"] = {
            "source": g.attrs.get("source", ""),
            "strands": int(len(off) - 1),
            "points": int(len(pts)),
            "points_per_strand": _stats(np.diff(off), digits=1),
            "length_m": _stats(strand_lengths(pts, off)),
            "bbox_min_m": [round(float(v), 4) for v in pts.min(axis=0)],
            "bbox_max_m": [round(float(v), 4) for v in pts.max(axis=0)],
            "scale_to_m": float(g.attrs.get("scale_to_m", 1.0)),
            "up": [float(v) for v in np.asarray(g.attrs.get("up", (0, 1, 0)))],
        }
    if stages.HELICES in stage:
        g = stage[stages.HELICES]
        off = g["offsets"]
        omega = g["omega"]
        curvature = np.hypot(omega[:, 0], omega[:, 1])
        out["groups"]["helices"] = {
            "strands": int(len(off) - 1),
            "elements": int(off[-1]),
            "elements_per_strand": _stats(np.diff(off), digits=1),
            "curvature_1_per_m": _stats(curvature, digits=3),
            "twist_1_per_m": _stats(np.abs(omega[:, 2]), digits=3),
            "fit_error_mean_mm": _stats(g["fit_error"][:, 0], 1e3),
            "fit_error_max_mm": _stats(g["fit_error"][:, 1], 1e3),
        }
    for name in (stages.CONTACTS, stages.MODEL, stages.FRAMES):
        if name in stage:
            g = stage[name]
            out["groups"][name] = {key: list(value.shape) for key, value in g.datasets.items()}
    return out
