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
    if stages.CONTACTS in stage:
        g = stage[stages.CONTACTS]
        strand = g["strand"]
        body = strand[:, 1] < 0
        out["groups"]["contacts"] = {
            "contacts": int(len(strand)),
            "hair_body": int(body.sum()),
            "hair_hair": int((~body).sum()),
            "strands_touching_body": int(len(np.unique(strand[body, 0]))),
            "mu": _stats(g["mu"], digits=3),
        }
    if stages.MODEL in stage:
        g = stage[stages.MODEL]
        # the rest shape the model is simulated with (the stiffened strands' own where it has them)
        rest = g["omega_rest_stiffened"] if "omega_rest_stiffened" in g.datasets else g["omega_rest"]
        target, force = g["omega_target"], g["force"]
        drift = np.linalg.norm(rest - target, axis=1)
        normal = force[:, 0] if len(force) else np.zeros(0)
        out["groups"]["model"] = {
            "target": g.attrs.get("target", ""),
            "status": g.attrs.get("status", ""),
            "sweeps": int(g.attrs.get("iterations", 0)),
            "prior_sweeps": int(g.attrs.get("prior_sweeps", 0)),
            "residual_N": float(g.attrs.get("residual", 0.0)),
            "relative_residual": float(g.attrs.get("relative_residual", 0.0)),
            "solve_seconds": round(float(g.attrs.get("seconds", 0.0)), 3),
            "rest_curvature_1_per_m": _stats(np.hypot(rest[:, 0], rest[:, 1]), digits=3),
            "drift_from_target_1_per_m": _stats(drift, digits=3),
            "contacts_carrying_force": int((normal > 0).sum()),
            "normal_force_N": _stats(normal, digits=9),
            "youngs_modulus_Pa": float(g.attrs.get("youngs_modulus", 0.0)),
            "radius_m": float(g.attrs.get("radius", 0.0)),
        }
        if "stiffening" in g.datasets:
            factor = np.asarray(g["stiffening"])
            out["groups"]["model"]["strands_stiffened"] = int((factor > 1.0).sum())
            out["groups"]["model"]["stiffening_factor"] = _stats(factor, digits=3)
    if stages.FRAMES in stage:
        g = stage[stages.FRAMES]
        time = g["time"]
        frames = {"frames": int(len(time)), "seconds": float(time[-1]) if len(time) else 0.0,
                  "scene": str(g.attrs.get("scene", "")), "init": str(g.attrs.get("init", "")),
                  "time_step_s": float(g.attrs.get("time_step", 0.0)),
                  "body_removed": bool(g.attrs.get("body_removed", False)),
                  "trimmed": bool(g.attrs.get("trimmed", False))}
        if "displacement" in g.datasets:
            frames["largest_displacement_mm"] = round(1e3 * float(np.max(g["displacement"])), 6)
            frames["final_kinetic_energy_J"] = float(g["kinetic_energy"][-1])
            frames["contacts"] = _stats(g["contact_count"], digits=1)
        out["groups"]["frames"] = frames
    return out
