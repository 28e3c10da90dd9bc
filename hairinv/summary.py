"""Plain-data summaries of stage files: one dictionary serves ``hairinv info`` (as text or ``--json``) and
``hairinv export -o OUT.json`` (docs/export.md gives its schema). Also what ``hairinv info`` says of a body
mesh (:func:`body_summary`) and of a hairstyle file (:func:`hairstyle_summary`) before any stage reads them.

Every value is computed here once, at full precision; :func:`summary_lines` only formats it for a terminal.
Keys are stable: every group present in the file has all its keys, ``null`` where the file does not record
the value; a group the file lacks is ``null``.
"""

from __future__ import annotations

import json

import numpy as np

from pathlib import Path

from . import stages
from ._text import counted
from .groom import guess_body_units, guess_hair_units, strand_lengths
from .model import UNSTABLE_MARGIN

__all__ = ["SCHEMA", "body_lines", "body_summary", "file_summary", "hairstyle_lines", "hairstyle_summary",
           "summarise", "summary_lines"]

#: Version of the summary's layout: raised when a key is renamed, removed or changes meaning (keys are
#: only ever added within one version).
SCHEMA = 1
# Significant digits of the numbers in the text summary.
TEXT_DIGITS = 4


def _stats(values, scale: float = 1.0) -> dict | None:
    """``{min, median, max, mean}`` of ``values * scale``, or None for no values."""
    values = np.asarray(values, dtype=np.float64).ravel() * scale
    if values.size == 0:
        return None
    return {"min": float(values.min()), "median": float(np.median(values)), "max": float(values.max()),
            "mean": float(values.mean())}


def _count(mask) -> int:
    return int(np.count_nonzero(mask))


def _curves(g: stages.Group) -> dict:
    pts, off = g["points"], g["offsets"]
    return {
        "source": str(g.attrs.get("source", "")),
        "strands": int(len(off) - 1),
        "points": len(pts),
        "points_per_strand": _stats(np.diff(off)),
        "length_m": _stats(strand_lengths(pts, off)),
        "bbox_min_m": [float(v) for v in pts.min(axis=0)] if len(pts) else None,
        "bbox_max_m": [float(v) for v in pts.max(axis=0)] if len(pts) else None,
        "scale_to_m": float(g.attrs.get("scale_to_m", 1.0)),
        "up": [float(v) for v in np.asarray(g.attrs.get("up", (0, 1, 0))).reshape(3)],
    }


def _helices(g: stages.Group) -> dict:
    off, omega, error = g["offsets"], g["omega"], g["fit_error"]
    tolerance = g.config.get("fit", {}).get("tolerance")
    return {
        "strands": int(len(off) - 1),
        "elements": int(off[-1]),
        "elements_per_strand": _stats(np.diff(off)),
        "curvature_1_per_m": _stats(np.hypot(omega[:, 0], omega[:, 1])),
        "twist_1_per_m": _stats(np.abs(omega[:, 2])),
        "fit_error_mean_mm": _stats(error[:, 0], 1e3),
        "fit_error_max_mm": _stats(error[:, 1], 1e3),
        "fit_tolerance_mm": None if tolerance is None else 1e3 * float(tolerance),
        "strands_over_tolerance": None if tolerance is None else _count(error[:, 1] > float(tolerance)),
    }


def _carrying_threshold(model: stages.Group) -> float:
    """N: the normal force above which a contact carries force, as invert counts it (/model
    ``carrying_threshold``; 0 for files written before it was stored)."""
    return float(model.attrs.get("carrying_threshold", 0.0))


def _contacts(g: stages.Group, model: stages.Group | None) -> dict:
    """Contacts by kind (hair-body, hair-hair) and by the rule that declared them, and how many carry force.

    The rule follows from the gap stored at detection and the distances of the detection's settings
    (hairinv.contacts.detect): a body contact at ``gap >= body_distance`` was declared by the layer rule, a
    hair-hair one at ``gap >= hair_distance`` by the wisp rule, every other by its distance.
    """
    strand, mu = g["strand"], g["mu"]
    body = strand[:, 1] < 0
    gap = g.datasets.get("gap")
    settings = g.config.get("contacts", {})
    force = model["force"] if model is not None and len(model["force"]) == len(strand) else None
    carrying = force[:, 0] > _carrying_threshold(model) if force is not None else None

    def kind(mask, distance_key, rule):
        out = {"declared": _count(mask),
               "carrying_force": None if carrying is None else _count(mask & carrying),
               "by_rule": None, "gap_mm": None if gap is None else _stats(gap[mask], 1e3)}
        if gap is not None and distance_key in settings:
            beyond = mask & (gap >= float(settings[distance_key]))
            out["by_rule"] = {"distance": _count(mask & ~beyond), rule: _count(beyond)}
        return out

    return {
        "contacts": len(strand),
        "hair_body": _count(body),
        "hair_hair": _count(~body),
        "carrying_force": None if carrying is None else _count(carrying),
        "strands_touching_body": len(np.unique(strand[body, 0])),
        "inside_body": None if gap is None else _count(body & (gap < 0)),
        # infinite friction (sticking contacts) is counted apart: the statistics are of the finite values
        "mu": _stats(mu[np.isfinite(mu)]),
        "mu_infinite": _count(np.isinf(mu)),
        "by_kind": {"hair_body": kind(body, "body_distance", "layer"),
                    "hair_hair": kind(~body, "hair_distance", "wisp")},
    }


def _model(g: stages.Group) -> dict:
    # the rest shape the model is simulated with (the stiffened strands' own where it has them)
    rest = g["omega_rest_stiffened"] if "omega_rest_stiffened" in g.datasets else g["omega_rest"]
    target, force = g["omega_target"], g["force"]
    normal = force[:, 0] if len(force) else np.zeros(0)
    history = g.datasets.get("residual_history")
    stabilize = g.config.get("solver", {}).get("stabilize")
    # files written before solver.stable_under existed were checked on their supports
    under = g.config.get("solver", {}).get("stable_under", None if stabilize is None else "supports")
    factor = np.asarray(g["stiffening"], dtype=np.float64) if "stiffening" in g.datasets else None
    stiffened = None if factor is None else np.flatnonzero(factor > 1.0)
    margin = np.asarray(g["stability_margin"], dtype=np.float64) if "stability_margin" in g.datasets else None
    return {
        "target": str(g.attrs.get("target", "")),
        "status": str(g.attrs.get("status", "")),
        "sweeps": int(g.attrs.get("iterations", 0)),
        "prior_sweeps": int(g.attrs.get("prior_sweeps", 0)),
        "residual_N": float(g.attrs.get("residual", 0.0)),
        "relative_residual": float(g.attrs.get("relative_residual", 0.0)),
        "residual_history": None if history is None else [[int(s), float(r)] for s, r in history],
        "solve_seconds": float(g.attrs.get("seconds", 0.0)),
        # sweeps for files written before solver.method existed
        "method": str(g.attrs.get("method", "sweeps")),
        # the duality-gap bound on the rest shape's rms distance from the optimum; None where the file has none
        "rest_bound_1_per_m": float(g.attrs["rest_bound"]) if "rest_bound" in g.attrs else None,
        "rest_curvature_1_per_m": _stats(np.hypot(rest[:, 0], rest[:, 1])),
        "drift_from_target_1_per_m": _stats(np.linalg.norm(rest - target, axis=1)),
        "contacts_carrying_force": _count(normal > _carrying_threshold(g)),
        "normal_force_N": _stats(normal),
        "youngs_modulus_Pa": float(g.attrs.get("youngs_modulus", 0.0)),
        "radius_m": float(g.attrs.get("radius", 0.0)),
        "gamma": float(g.attrs.get("gamma", 0.0)),
        # 0 for files written before solver.gamma_relative (every contact weighed gamma)
        "gamma_relative": float(g.attrs.get("gamma_relative", 0.0)),
        "stabilize": None if stabilize is None else str(stabilize),
        "stable_under": None if under is None else str(under),
        "strands_stiffened": None if factor is None else len(stiffened),
        "stiffening_factor": None if factor is None else _stats(factor),
        "stiffened": None if factor is None else [{"strand": int(k), "factor": float(factor[k])} for k in stiffened],
        # null for files that store no margins (stability not checked, or written before they were stored)
        "unstable_strands": None if margin is None else [int(k) for k in np.flatnonzero(margin < UNSTABLE_MARGIN)],
        "stability_margin": None if margin is None else _stats(margin[np.isfinite(margin)]),
    }


def _frames(g: stages.Group) -> dict:
    time = g["time"]

    def series(name, scale=1.0):
        return _stats(g[name], scale) if name in g.datasets else None

    def last(name, scale=1.0):
        return scale * float(g[name][-1]) if name in g.datasets and len(g[name]) else None

    return {
        "frames": len(time),
        "seconds": float(time[-1]) if len(time) else 0.0,
        "fps": float(g.attrs["fps"]) if "fps" in g.attrs else None,
        "scene": str(g.attrs.get("scene", "")),
        "init": str(g.attrs.get("init", "")),
        "time_step_s": float(g.attrs.get("time_step", 0.0)),
        "body_removed": bool(g.attrs.get("body_removed", False)),
        "trimmed": bool(g.attrs.get("trimmed", False)),
        "interrupted": bool(g.attrs.get("interrupted", False)),
        "frames_requested": int(g.attrs["frames_requested"]) if "frames_requested" in g.attrs else None,
        "largest_displacement_mm": None if "displacement" not in g.datasets else 1e3 * float(np.max(g["displacement"])),
        "final_displacement_mm": last("displacement", 1e3),
        "final_kinetic_energy_J": last("kinetic_energy"),
        "final_elastic_energy_J": last("elastic_energy"),
        "contacts": series("contact_count"),
        "solver_relative_residual": series("solver_residual"),
    }


def _warnings(out: dict) -> list[str]:
    """What a reader should know, from what the file records (the file stores no run-time messages)."""
    g = out["groups"]
    found = []
    if g["helices"] and g["helices"]["strands_over_tolerance"]:
        h = g["helices"]
        found.append(f"{counted(h['strands_over_tolerance'], 'strand is', 'strands are')} fitted worse than the fit "
                     f"tolerance {h['fit_tolerance_mm']:g} mm (largest {h['fit_error_max_mm']['max']:.3g} mm)")
    if g["contacts"] and g["contacts"]["inside_body"]:
        found.append(f"{counted(g['contacts']['inside_body'], 'body contact lies', 'body contacts lie')} inside the body")
    if g["model"] and g["model"]["status"] not in ("", "CONVERGED"):
        m = g["model"]
        found.append(f"the contact solver stopped with status {m['status']} after {m['sweeps']} sweeps "
                     f"(residual {m['residual_N']:.3g} N)")
    if g["model"] and g["model"]["strands_stiffened"]:
        m = g["model"]
        found.append(f"{counted(m['strands_stiffened'], 'strand was', 'strands were')} stiffened so that "
                     f"{'it rests' if m['strands_stiffened'] == 1 else 'they rest'} stably (factor up to "
                     f"{m['stiffening_factor']['max']:.3g})")
    if g["frames"] and g["frames"]["interrupted"]:
        f = g["frames"]
        found.append(f"the simulation was interrupted (Ctrl-C) after {f['frames']} of {f['frames_requested']} frames: "
                     "a rerun computes it whole")
    if g["model"] and g["model"]["unstable_strands"]:
        m = g["model"]
        found.append(f"{counted(len(m['unstable_strands']), 'strand rests', 'strands rest')} in an unstable equilibrium "
                     f"(with its contact forces held {'fixed' if m['stable_under'] == 'forces' else 'in place'}): "
                     "a simulation of the model will move it")
    return found


def _features(g: stages.Group) -> dict | None:
    """What the stage that wrote ``g`` modelled and skipped, and why (its ``features`` attribute,
    docs/stage-files.md), or None where the file does not say (older files) or says it unreadably."""
    try:
        said = json.loads(str(g.attrs["features"]))
    except (KeyError, ValueError):
        return None
    if not (isinstance(said, dict) and isinstance(said.get("modelled"), list)
            and isinstance(said.get("skipped"), dict)):
        return None
    return {"modelled": [str(k) for k in said["modelled"]],
            "skipped": {str(k): str(v) for k, v in said["skipped"].items()}}


def summarise(stage: stages.StageFile) -> dict:
    """A JSON-ready dictionary describing every group of a stage file (docs/export.md, "JSON")."""
    groups = stage.groups
    out = {
        "schema": SCHEMA,
        "file": stage.path.name,
        "sha256": stages.sha256_file(stage.path) if stage.path.is_file() else None,
        "producer": stage.producer,
        "schema_version": stage.schema_version,
        "stages": ",".join(groups),
        "groups": {
            "curves": _curves(groups[stages.CURVES]) if stages.CURVES in groups else None,
            "helices": _helices(groups[stages.HELICES]) if stages.HELICES in groups else None,
            "contacts": (_contacts(groups[stages.CONTACTS], groups.get(stages.MODEL))
                         if stages.CONTACTS in groups else None),
            "model": _model(groups[stages.MODEL]) if stages.MODEL in groups else None,
            "frames": _frames(groups[stages.FRAMES]) if stages.FRAMES in groups else None,
        },
    }
    for name in (stages.CONTACTS, stages.MODEL, stages.FRAMES):
        said = _features(groups[name]) if name in groups else None
        if said is not None:
            out["groups"][name]["features"] = said
    # seconds each stage took, where the file records it (only the contact solve of invert does)
    model = out["groups"]["model"]
    def seconds(name):  # the stage's own computing time, None where the file does not record it
        return float(groups[name].attrs["seconds"]) if name in groups and "seconds" in groups[name].attrs else None

    out["timings_s"] = {"fit": seconds(stages.HELICES), "detect": seconds(stages.CONTACTS),
                        "invert": model["solve_seconds"] if model else None, "simulate": seconds(stages.FRAMES)}
    out["warnings"] = _warnings(out)
    return out


def _text(value) -> str:
    if isinstance(value, bool) or value is None:
        return "-" if value is None else str(value).lower()
    if isinstance(value, float):
        return f"{value:.{TEXT_DIGITS}g}"
    if isinstance(value, dict):
        return ", ".join(f"{k} {_text(v)}" for k, v in value.items())
    if isinstance(value, list):
        if len(value) > 6:
            return f"{len(value)} entries"
        return "[" + ", ".join(_text(v) for v in value) + "]"
    return str(value)


def summary_lines(summary: dict, name: str) -> list[str]:
    """The summary as text for a terminal: a header line, then each group's keys, numbers to 4 digits."""
    lines = [f"{name}: {summary['producer']}, schema {summary['schema_version']}, stages {summary['stages']}"]
    for group, values in summary["groups"].items():
        if values is None:
            continue
        lines.append(f"/{group}")
        for key, value in values.items():
            if isinstance(value, dict) and any(isinstance(v, dict) for v in value.values()):
                lines.append(f"  {key}:")
                lines += [f"    {k}: {_text(v)}" for k, v in value.items()]
            else:
                lines.append(f"  {key}: {_text(value)}")
    lines += [f"warning: {w}" for w in summary["warnings"]]
    return lines


# ------------------------------------------------------------------------ files before any stage: bodies, hairstyles

#: Names of the body-mesh formats by suffix, as ``hairinv info`` prints them.
MESH_FORMATS = {".obj": "OBJ", ".ply": "PLY", ".stl": "STL", ".off": "OFF", ".glb": "glTF binary", ".gltf": "glTF",
                ".tfxmesh": "TressFX mesh", ".usd": "USD", ".usda": "USD", ".usdc": "USD", ".usdz": "USD"}


def _bounds(points: np.ndarray) -> dict:
    lo, hi = points.min(axis=0), points.max(axis=0)
    return {"bounds_min": lo.tolist(), "bounds_max": hi.tolist(), "size": (hi - lo).tolist(),
            "diagonal": float(np.linalg.norm(hi - lo))}


def _surface(mesh) -> dict:
    """Whether a triangle mesh is closed, after joining coincident vertices (a UV seam splits one in a file),
    and how its triangles wind: edges on one triangle only (``boundary_edges``), on more than two
    (``nonmanifold_edges``), shared by two triangles that run it the same way (``flipped_edges``: their
    normals disagree), triangles of zero area, and for a closed surface whether its normals point out."""
    merged = mesh.copy()
    merged.merge_vertices(merge_tex=True, merge_norm=True)
    faces = np.asarray(merged.faces, dtype=np.int64)
    directed = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    _, uses = np.unique(np.sort(directed, axis=1), axis=0, return_counts=True)
    _, same_way = np.unique(directed, axis=0, return_counts=True)
    v = np.asarray(merged.vertices, dtype=np.float64)
    doubled_area = np.linalg.norm(np.cross(v[faces[:, 1]] - v[faces[:, 0]], v[faces[:, 2]] - v[faces[:, 0]]), axis=1)
    boundary, nonmanifold, flipped = _count(uses == 1), _count(uses > 2), _count(same_way > 1)
    closed = boundary == 0 and nonmanifold == 0
    outward = None
    if closed and flipped == 0:
        # the signed volume: the sum over triangles of a . (b x c) / 6, positive when the normals point out
        outward = bool(np.einsum("ij,ij->i", v[faces[:, 0]], np.cross(v[faces[:, 1]], v[faces[:, 2]])).sum() > 0)
    return {"closed": closed, "boundary_edges": boundary, "nonmanifold_edges": nonmanifold,
            "flipped_edges": flipped, "normals_outward": outward,
            "degenerate_triangles": _count(doubled_area <= 1e-12 * max(float(np.ptp(v, axis=0).max()), 1e-300) ** 2)}


def body_summary(path) -> dict:
    """What ``hairinv info`` says of a static body mesh (any format :func:`hairinv.formats.read_mesh` reads): its
    size in the file's units, the unit and up axis the file states or the unit its size suggests, whether
    it is closed and how its triangles wind, and whether it has texture coordinates."""
    from . import formats
    from .formats.mesh import CORNER_UV, STATED_FRAME

    path = Path(path)
    mesh = formats.read_mesh(path)
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    out = {"file": path.name, "kind": "body mesh", "format": MESH_FORMATS.get(path.suffix.lower(), path.suffix),
           "vertices": int(len(vertices)), "triangles": int(len(mesh.faces)), **_bounds(vertices)}
    stated = mesh.metadata.get(STATED_FRAME, {})
    out["stated_scale_to_m"] = stated.get("scale_to_m")
    out["stated_up"] = stated.get("up")
    out["stated_by"] = stated.get("by")
    out["guessed_units"] = None if stated.get("scale_to_m") else guess_body_units(out["diagonal"])
    out.update(_surface(mesh))
    out["texture_coordinates"] = CORNER_UV in mesh.metadata
    return out


def _vector(values) -> str:
    return "(" + ", ".join(f"{c:.{TEXT_DIGITS}g}" for c in values) + ")"


def _extent_lines(summary: dict) -> list[str]:
    size = " x ".join(f"{c:.{TEXT_DIGITS}g}" for c in summary["size"])
    return [f"  bounds: {_vector(summary['bounds_min'])} .. {_vector(summary['bounds_max'])} file units, {size} "
            f"across (diagonal {summary['diagonal']:.{TEXT_DIGITS}g})"]


def _units_line(summary: dict, what: str, then: str) -> str:
    """``units: ...``: the unit stated or the one ``summary``'s size suggests for ``what``; ``then``: what the
    pipeline does with it."""
    from .config import UNITS

    if summary["stated_scale_to_m"]:
        scale = summary["stated_scale_to_m"]
        named = next((name for name, value in UNITS.items() if abs(value - scale) <= 1e-12 * scale), None)
        unit = f"{named} ({scale:g} m per unit)" if named else f"{scale:g} m per unit"
        return (f"  units: {unit}, stated by {summary['stated_by']}: {summary['diagonal'] * scale:.3g} m across "
                f"({then})")
    unit = summary["guessed_units"]
    metres = "" if unit == "m" else f", {summary['diagonal'] * UNITS[unit]:.3g} m"
    return f"  units: not stated by the file; {summary['diagonal']:.3g} across reads as {unit} for {what}{metres} ({then})"


def body_lines(summary: dict, name: str) -> list[str]:
    """The lines ``hairinv info`` prints for :func:`body_summary`."""
    lines = [f"{name}: {summary['kind']} ({summary['format']}), {summary['vertices']} vertices, "
             f"{summary['triangles']} triangles"]
    lines += _extent_lines(summary)
    lines.append(_units_line(summary, "a body", "a body is read in the hair's unit unless --body-units says another"))
    up = summary["stated_up"]
    lines.append(f"  up: +{up.upper()}, stated by {summary['stated_by']}" if up
                 else "  up: not stated by the file (a body is read with the hair's up unless --body-up says another)")
    if summary["closed"]:
        surface = "closed (watertight)"
        if summary["normals_outward"] is not None:
            surface += (", its triangles facing out" if summary["normals_outward"]
                        else ", its triangles facing in: inside out, so hairinv would take the outside for the inside")
    else:
        parts = [counted(summary["boundary_edges"], "boundary edge")] if summary["boundary_edges"] else []
        parts += [counted(summary["nonmanifold_edges"], "edge") + " shared by more than two triangles"
                  ] if summary["nonmanifold_edges"] else []
        surface = f"open ({', '.join(parts)}): hairinv's inside test needs no closed mesh"
    if summary["flipped_edges"]:
        surface += (f"; {counted(summary['flipped_edges'], 'edge')} between triangles wound opposite ways (their "
                    "normals disagree, and the inside test with them)")
    if summary["degenerate_triangles"]:
        surface += f"; {counted(summary['degenerate_triangles'], 'triangle')} of zero area"
    lines.append(f"  surface: {surface}")
    lines.append("  texture coordinates: " + ("yes (export writes each root's as groom_root_uv)"
                                               if summary["texture_coordinates"] else "none"))
    return lines


def hairstyle_summary(path) -> dict:
    """What ``hairinv info`` says of a hairstyle file (any format :func:`hairinv.formats.read_curves` reads) as
    it is, before ``fit`` cleans it: strands, points, size, the unit and up axis the file states or the
    unit its size suggests."""
    from . import formats

    path = Path(path)
    raw = formats.read_curves(path)
    counts = np.diff(raw.offsets)
    # polyline lengths: walked[i] is the length from point 0 to point i along the file's points
    walked = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(raw.points, axis=0), axis=1))])
    starts, ends = raw.offsets[:-1], raw.offsets[1:]
    per_strand = np.where(counts >= 2, walked[np.maximum(ends - 1, 0)] - walked[np.minimum(starts, len(walked) - 1)],
                          0.0)
    up = raw.up if isinstance(raw.up, str) else None  # a vector only from a stage file, which info reads whole
    out = {"file": path.name, "kind": "hairstyle", "format": raw.format, "strands": raw.n_strands,
           "points": int(len(raw.points)), "points_per_strand": _stats(counts),
           "strand_length": _stats(per_strand), **_bounds(raw.points),
           "stated_scale_to_m": raw.scale_to_m, "stated_up": up, "stated_by": "the file" if raw.scale_to_m or up
           else None}
    out["guessed_units"] = None if raw.scale_to_m else guess_hair_units(out["diagonal"])
    return out


def file_summary(path) -> dict:
    """:func:`body_summary` or :func:`hairstyle_summary`, by the file's suffix; for a suffix both read (OBJ,
    USD), a body where the file holds triangles (a mesh), else a hairstyle.

    Raises
    ------
    InputError
        A suffix neither reads, or a file that holds neither (the body reader's sentence).
    """
    from . import formats
    from .errors import InputError

    path = Path(path)
    suffix = path.suffix.lower()
    mesh, curves = suffix in formats.MESH_READERS, suffix in formats.CURVE_READERS
    if not mesh and not curves:
        meshes = " ".join(sorted(formats.MESH_READERS))
        styles = " ".join(sorted(set(formats.CURVE_READERS) - set(formats.MESH_READERS) - {".h5", ".hdf5"}))
        raise InputError(f"is not a kind of file hairinv reads ({suffix or 'no suffix'}): info takes a hairinv stage "
                         f"file (HDF5, .h5), a body mesh ({meshes}), an animated body or a hairstyle (also {styles})", path)
    if not mesh:
        return hairstyle_summary(path)
    try:
        return body_summary(path)
    except InputError as error:
        if not curves:
            raise
        try:
            return hairstyle_summary(path)
        except InputError:
            raise error from None


def hairstyle_lines(summary: dict, name: str) -> list[str]:
    """The lines ``hairinv info`` prints for :func:`hairstyle_summary`."""
    per = summary["points_per_strand"]
    length = summary["strand_length"]
    lines = [f"{name}: {summary['kind']} ({summary['format']}), {summary['strands']} strands, {summary['points']} "
             f"points ({per['min']:.0f} to {per['max']:.0f} per strand, median {per['median']:.0f})"]
    lines += _extent_lines(summary)
    lines.append(f"  strand length: median {length['median']:.{TEXT_DIGITS}g}, max {length['max']:.{TEXT_DIGITS}g} "
                 "file units")
    lines.append(_units_line(summary, "a head of hair", "fit reads it so unless --units or --scale says another"))
    up = summary["stated_up"]
    lines.append(f"  up: +{up.upper()}, as the file or its format states it (fit takes it unless --up says another)"
                 if up else "  up: not stated by the file (fit guesses it and says so; --up says another)")
    lines.append("  `hairinv fit` reads it as a groom: cleans, fits and says what it did")
    return lines
