"""From a hairstyle file to clean strands in metres, and the body beside it.

Readers return strands in the file's own units and axes. This module applies
what the user said (or what was guessed, always reported): axis flips, the
unit, the up axis; then cleans the strands (merging repeated points, dropping
strands too short to carry a rod) and optionally keeps a seeded subset of
guide strands spread evenly over the scalp.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import formats, stages
from .config import UNITS, BodySettings, ImportSettings
from .errors import InputError
from .formats.mesh import CORNER_UV

AXES = {"x": 0, "y": 1, "z": 2}
# Typical diagonal of the bounding box, m: a head of hair, and a bust.
_TYPICAL_HAIR_SIZE = 0.45
_TYPICAL_BODY_SIZE = 0.6
# m: the longest strand a groom may have once in metres. The longest human hair on record is under 6 m; a
# longer strand is a unit mistake (a file in centimetres read as metres) or a corrupt file, and fitting it
# would take minutes and gigabytes for nothing.
MAX_STRAND_LENGTH = 10.0
# |a . b| above this: two unit vectors are the same axis (a stored up vector is a unit axis to round-off).
SAME_AXIS = 1.0 - 1e-9


@dataclass
class Groom:
    """Clean strands in metres.

    Attributes
    ----------
    points : (P, 3) float64, m
    offsets : (S + 1,) int64
    up : (3,) float64, unit vector; gravity is along ``-up``
    scale_to_m : float, the factor applied on import
    source : str, original file name and format
    index : (S,) int64, each strand's index in the original file
    """

    points: np.ndarray
    offsets: np.ndarray
    up: np.ndarray
    scale_to_m: float
    source: str
    index: np.ndarray

    @property
    def n_strands(self) -> int:
        return int(len(self.offsets) - 1)

    def curves_group(self, settings: ImportSettings, inputs: list[dict]) -> stages.Group:
        return stages.Group(
            stages.CURVES,
            {"points": self.points, "offsets": self.offsets},
            attrs={"source": self.source, "scale_to_m": self.scale_to_m, "up": self.up},
            config={"import": dataclasses.asdict(settings)},
            inputs=inputs,
        )


@dataclass
class ImportReport:
    """What the import did, as counts and sentences for the user."""

    strands_read: int = 0
    points_read: int = 0
    merged_points: int = 0
    dropped_degenerate: int = 0
    dropped_short: int = 0
    kept: int = 0
    notes: list[str] = field(default_factory=list)

    def lines(self) -> list[str]:
        lines = [f"read {self.strands_read} strands, {self.points_read} points"]
        lines += self.notes
        if self.merged_points:
            lines.append(f"merged {self.merged_points} repeated points")
        if self.dropped_degenerate:
            lines.append(f"dropped {self.dropped_degenerate} strands with fewer than 2 distinct points")
        if self.dropped_short:
            lines.append(f"dropped {self.dropped_short} strands shorter than the minimum length")
        lines.append(f"kept {self.kept} strands")
        return lines


def guess_units(size: float, typical: float) -> str:
    """The unit in which a bounding-box diagonal ``size`` is closest to ``typical`` metres."""
    best = min(UNITS, key=lambda unit: abs(np.log(size * UNITS[unit] / typical)))
    return best


def guess_body_units(size: float) -> str:
    """The unit a body whose bounding-box diagonal is ``size`` file units is taken to be in (``body.units =
    auto``): the one that makes it closest to a bust's size."""
    return guess_units(size, _TYPICAL_BODY_SIZE)


def guess_hair_units(size: float) -> str:
    """The unit a hairstyle whose bounding-box diagonal is ``size`` file units is taken to be in
    (``import.units = auto``): the one that makes it closest to a head of hair's size."""
    return guess_units(size, _TYPICAL_HAIR_SIZE)


def _axis_label(up: np.ndarray) -> str:
    for name, index in AXES.items():
        if abs(abs(up[index]) - 1.0) < 1e-12:
            return f"{'+' if up[index] > 0 else '-'}{name.upper()}"
    return "(" + ", ".join(f"{v:.3g}" for v in up) + ")"


def _up_vector(axis) -> np.ndarray:
    if isinstance(axis, str):
        up = np.zeros(3)
        up[AXES[axis]] = 1.0
        return up
    up = np.asarray(axis, dtype=np.float64)
    return up / np.linalg.norm(up)


def _flip(points: np.ndarray, flip: str, path) -> np.ndarray:
    for axis in flip.replace(",", "").lower():
        if axis not in AXES:
            raise InputError(f"--flip takes axes among x, y, z; got {flip!r}", path)
        points[:, AXES[axis]] *= -1.0
    return points


def resolve_scale(settings: ImportSettings, stated: float | None, size_native: float, typical: float,
                  what: str, notes: list[str]) -> float:
    """Metres per file unit from the settings, the file, or a reported guess."""
    if settings.scale > 0:
        scale = settings.scale
        notes.append(f"units: {scale:g} m per file unit (--scale)")
    elif settings.units != "auto":
        if settings.units not in UNITS:
            raise InputError(f"unknown unit {settings.units!r}; choose m, cm, mm, in or auto")
        scale = UNITS[settings.units]
        notes.append(f"units: {settings.units} (as given)")
    elif stated is not None:
        scale = stated
        notes.append(f"units: {scale:g} m per unit (stated by the file)")
    else:
        unit = guess_units(size_native, typical)
        scale = UNITS[unit]
        # a warning: every length of the result (contacts, rest shape, forces) follows from this guess
        notes.append(
            f"warning: units: guessed {unit} from the {what}'s size ({size_native:.4g} file units across, "
            f"{size_native * scale:.3g} m), and every result depends on it: pass --units {unit} (or --scale) to "
            "say it"
        )
    if stated is not None and abs(scale - stated) > 1e-12 * stated:
        notes.append(f"warning: the file states {stated:g} m per unit; using {scale:g} as asked")
    return scale


def strand_lengths(points: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Polyline length of every strand (0 for strands of fewer than 2 points)."""
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1) if len(points) > 1 else np.zeros(0)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    counts = np.diff(offsets)
    last = np.maximum(offsets[1:] - 1, offsets[:-1])
    lengths = cum[np.minimum(last, len(cum) - 1)] - cum[np.minimum(offsets[:-1], len(cum) - 1)]
    return np.where(counts >= 2, lengths, 0.0)


def _clean(points, offsets, merge_tol, min_length, report: ImportReport):
    """Merge repeated consecutive points, drop degenerate and short strands."""
    strand_of = np.repeat(np.arange(len(offsets) - 1), np.diff(offsets))
    keep_pts = np.ones(len(points), dtype=bool)
    if len(points) > 1:
        step = np.linalg.norm(np.diff(points, axis=0), axis=1)
        same_strand = strand_of[1:] == strand_of[:-1]
        keep_pts[1:] = ~(same_strand & (step <= merge_tol))
    report.merged_points = int((~keep_pts).sum())
    counts = np.bincount(strand_of[keep_pts], minlength=len(offsets) - 1)
    new_offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    pts = points[keep_pts]
    lengths = strand_lengths(pts, new_offsets)
    degenerate = counts < 2
    short = ~degenerate & (lengths < min_length)
    report.dropped_degenerate = int(degenerate.sum())
    report.dropped_short = int(short.sum())
    keep = ~(degenerate | short)
    return pts, new_offsets, keep


def _subset(points, offsets, keep_idx) -> tuple[np.ndarray, np.ndarray]:
    counts = np.diff(offsets)[keep_idx]
    new_offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    rows = np.concatenate([np.arange(offsets[i], offsets[i + 1]) for i in keep_idx]) if len(keep_idx) else np.zeros(0, np.int64)
    return np.ascontiguousarray(points[rows]), new_offsets


def select_guides(roots: np.ndarray, n: int, seed: int) -> np.ndarray:
    """Indices of ``n`` strands, a seeded random subset spread evenly over the roots.

    The roots are bucketed in a cubic grid whose cell size is chosen (by
    bisection) so that about ``n`` cells are occupied; one random strand is
    drawn per cell, then the count is trimmed or topped up at random.
    """
    count = len(roots)
    if n <= 0 or n >= count:
        return np.arange(count)
    rng = np.random.default_rng(seed)
    lo, hi = 0.0, float(np.ptp(roots, axis=0).max()) + 1e-12
    origin = roots.min(axis=0)
    cells = None
    for _ in range(40):
        h = 0.5 * (lo + hi)
        keys = np.floor((roots - origin) / h).astype(np.int64)
        _, cells = np.unique(keys, axis=0, return_inverse=True)
        occupied = cells.max() + 1
        if occupied > n:
            lo = h
        else:
            hi = h
        if occupied == n:
            break
    order = rng.permutation(count)
    _, first = np.unique(cells[order], return_index=True)
    chosen = order[first]
    if len(chosen) > n:
        chosen = rng.choice(chosen, n, replace=False)
    elif len(chosen) < n:
        rest = np.setdiff1d(np.arange(count), chosen)
        chosen = np.concatenate([chosen, rng.choice(rest, n - len(chosen), replace=False)])
    return np.sort(chosen)


def load_groom(path, settings: ImportSettings, body_size_native: float | None = None) -> tuple[Groom, ImportReport]:
    """Read, orient, scale and clean a hairstyle file.

    Parameters
    ----------
    path : path-like
        Any registered hairstyle format.
    settings : ImportSettings
    body_size_native : float, optional
        Bounding-box diagonal of the paired body in the same file units; when
        given, an ``auto`` unit is guessed from the body instead of the hair.
    """
    path = Path(path)
    raw = formats.read_curves(path)
    report = ImportReport(strands_read=raw.n_strands, points_read=len(raw.points))
    points = _flip(raw.points.copy(), settings.flip, path)
    if settings.flip:
        report.notes.append(f"flipped axes: {settings.flip}")
    if body_size_native is not None:
        scale = resolve_scale(settings, raw.scale_to_m, body_size_native, _TYPICAL_BODY_SIZE, "body", report.notes)
    else:
        size = float(np.linalg.norm(np.ptp(points, axis=0))) if len(points) else 0.0
        scale = resolve_scale(settings, raw.scale_to_m, size, _TYPICAL_HAIR_SIZE, "hairstyle", report.notes)
    points *= scale
    if settings.up != "auto":
        if settings.up not in AXES:
            raise InputError(f"--up takes x, y, z or auto; got {settings.up!r}")
        up = _up_vector(settings.up)
        report.notes.append(f"up: +{settings.up.upper()} (as given); gravity along -{settings.up.upper()}")
    elif raw.up is not None:
        up = _up_vector(raw.up)
        label = f"+{raw.up.upper()}" if isinstance(raw.up, str) else _axis_label(up)
        source = "stated by the file" if raw.format == "hairinv-hdf5" else f"the {raw.format} convention"
        report.notes.append(f"up: {label} ({source}); pass --up to change it")
    else:
        up = _up_vector("y")
        report.notes.append("up: +Y (assumed); pass --up to change it")
    pts, offsets, keep = _clean(points, raw.offsets, settings.merge_tolerance, settings.min_length, report)
    keep_idx = np.flatnonzero(keep)
    if len(keep_idx) == 0:
        raise InputError("no strand is left after cleaning (all are degenerate or shorter than the minimum length)", path)
    pts, offsets = _subset(pts, offsets, keep_idx)
    lengths = strand_lengths(pts, offsets)
    if not np.all(lengths <= MAX_STRAND_LENGTH):  # (NaN included)
        worst = int(np.argmax(np.where(np.isfinite(lengths), lengths, np.inf)))
        raise InputError(f"a strand is {lengths[worst]:.3g} m long at {scale:.3g} m per file unit, longer than any hair "
                         f"({MAX_STRAND_LENGTH:g} m at most): pass --units or --scale if the unit is wrong, else the "
                         f"file is corrupt", path, strand=int(keep_idx[worst]))
    if settings.guides > 0 and settings.guides < len(keep_idx):
        chosen = select_guides(pts[offsets[:-1]], settings.guides, settings.seed)
        report.notes.append(f"guides: kept {len(chosen)} of {len(keep_idx)} strands (seed {settings.seed})")
        pts, offsets = _subset(pts, offsets, chosen)
        keep_idx = keep_idx[chosen]
    report.kept = len(keep_idx)
    source = raw.extras.get("source") if raw.format == "hairinv-hdf5" else f"{path.name} ({raw.format})"
    groom = Groom(pts, offsets, up, float(scale), str(source), keep_idx.astype(np.int64))
    return groom, report


def rotation_onto(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation taking unit vector ``a`` onto unit vector ``b`` (a half turn about an axis
    normal to both when they are opposite)."""
    c = float(a @ b)
    if c > SAME_AXIS:
        return np.eye(3)
    if c < -SAME_AXIS:
        axis = np.cross(a, np.eye(3)[int(np.argmin(np.abs(a)))])
        axis /= np.linalg.norm(axis)
        return 2.0 * np.outer(axis, axis) - np.eye(3)
    v = np.cross(a, b)
    K = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return np.eye(3) + K + K @ K / (1.0 + c)


def _flip_matrix(flip: str, path) -> np.ndarray:
    return np.diag(_flip(np.ones((1, 3)), flip, path)[0])


def hair_unit_transform(scale: float, flip: str = "", path=None) -> np.ndarray:
    """The 4x4 transform of a body read in the hair's unit and flip (the default of :func:`body_to_groom`, and
    how stage files that record no transform read their body): ``diag(flip) * scale``."""
    M = np.eye(4)
    M[:3, :3] = float(scale) * _flip_matrix(flip, path)
    return M


def body_to_groom(settings: BodySettings, groom_scale: float, groom_up, groom_flip: str, body_path=None,
                  body_size_native: float | None = None) -> tuple[np.ndarray, list[str]]:
    """The 4x4 transform from the body file's coordinates to the groom's frame in metres, and what it does.

    By default (every setting ``hair``) the body is read as the hair was: its flip, then its metres per
    unit. ``units``/``scale`` give the body its own unit, ``flip`` its own negated axes, and ``up`` its up
    axis, turned onto the groom's up by the smallest rotation (+Y onto +Z is a quarter turn about +X, as
    Y-up to Z-up exporters do). ``body_size_native``: the body's bounding-box diagonal in its file units,
    for ``units = auto``.
    """
    notes = []
    flip = groom_flip if settings.flip == "hair" else ("" if settings.flip.lower() == "none" else settings.flip)
    if settings.scale > 0:
        scale = float(settings.scale)
        notes.append(f"body units: {scale:g} m per body file unit (as given)")
    elif settings.units == "hair":
        scale = float(groom_scale)
    elif settings.units == "auto":
        if body_size_native is None:
            raise InputError("body.units = auto needs the body file to guess from", body_path)
        unit = guess_body_units(body_size_native)
        scale = UNITS[unit]
        notes.append(f"warning: body units: guessed {unit} from the body's size ({body_size_native:.4g} file units "
                     f"across, {body_size_native * scale:.3g} m), and every contact depends on it: pass "
                     f"--body-units {unit} to say it")
    elif settings.units in UNITS:
        scale = UNITS[settings.units]
        notes.append(f"body units: {settings.units} (as given)")
    else:
        raise InputError(f"unknown body unit {settings.units!r}; choose m, cm, mm, in, auto or hair", body_path)
    F = _flip_matrix(flip, body_path)
    if flip != groom_flip:
        notes.append(f"body flipped axes: {flip or 'none'}")
    R = np.eye(3)
    if settings.up != "hair":
        if settings.up not in AXES:
            raise InputError(f"--body-up takes x, y, z or hair; got {settings.up!r}", body_path)
        groom_up = _up_vector(groom_up)
        R = rotation_onto(F @ _up_vector(settings.up), groom_up)
        if not np.allclose(R, np.eye(3)):
            notes.append(f"body up: +{settings.up.upper()} turned onto the hair's up {_axis_label(groom_up)}")
    M = np.eye(4)
    M[:3, :3] = R @ (scale * F)
    return M, notes


def load_body(path, to_groom: np.ndarray, mesh=None):
    """Read a body mesh and bring it into the groom's frame, in metres.

    ``to_groom`` is the 4x4 transform of :func:`body_to_groom` (or the one a stage file records); ``mesh``,
    if given, is the file already read with :func:`formats.read_mesh`.

    Returns
    -------
    trimesh.Trimesh
        Triangles in metres, in the same world frame as the hair, outward normals kept.
    """
    mesh = formats.read_mesh(path) if mesh is None else mesh
    to_groom = np.asarray(to_groom, dtype=np.float64)
    vertices = np.array(mesh.vertices, dtype=np.float64) @ to_groom[:3, :3].T + to_groom[:3, 3]
    mesh = mesh.copy()
    mesh.vertices = vertices
    if np.linalg.det(to_groom[:3, :3]) < 0:  # a mirror turns the winding, so the normals, inside out
        mesh.invert()  # reverses each triangle's corners: their texture coordinates follow
        if CORNER_UV in mesh.metadata:
            mesh.metadata[CORNER_UV] = np.ascontiguousarray(mesh.metadata[CORNER_UV][:, ::-1])
    return mesh


def recorded_body_transform(record: dict | None, groom_scale: float, groom_flip: str, body_path=None) -> np.ndarray:
    """The body transform a stage file's body input ``record`` carries (``to_groom``), or, for files written
    before it was recorded, the hair's own unit and flip (how those files read their body)."""
    if record is not None and "to_groom" in record:
        M = np.asarray(record["to_groom"], dtype=np.float64)
        if M.shape == (4, 4) and np.all(np.isfinite(M)):
            return M
        raise InputError("records a body transform that is not a finite 4x4 matrix", body_path)
    return hair_unit_transform(groom_scale, groom_flip, body_path)


def find_recorded_body(stage, stage_path, groups=(stages.FRAMES, stages.CONTACTS, stages.MODEL)):
    """The body mesh file a stage file was made against, found again from its provenance.

    The body is the last input of the first of ``groups`` that records one. Its recorded path is tried as
    written (relative to the working directory, or absolute), relative to the stage file's folder, then as
    the absolute path it had (``abspath``), and accepted only where the file's SHA-256 equals the recorded
    one.

    Returns
    -------
    (path or None, record or None, str)
        The file found and its provenance record; the str says why none was found ("" when one was). A
        stage file that records no body gives ``(None, None, "")``.
    """
    record = None
    for name in groups:
        if name in stage and len(stage[name].inputs) >= 2:
            record = stage[name].inputs[-1]
            break
    if record is None:
        return None, None, ""
    path, why = find_recorded(record, stage_path, "the body")
    return path, record, why


def find_recorded(record: dict, stage_path, what: str = "the hairstyle") -> tuple[Path | None, str]:
    """An input file of a stage file found again from its provenance ``record`` (``path``, ``abspath``,
    ``sha256``; docs/stage-files.md): its recorded path as written (relative to the working directory, or
    absolute), relative to the stage file's folder, then its absolute path, accepted only where the file's
    SHA-256 equals the recorded one.

    Returns
    -------
    (path or None, str): the file, or None and why none was found, a clause naming ``what`` the file was
    """
    recorded = str(record.get("path", record.get("name", "")))
    candidates = [Path(recorded)]
    if not Path(recorded).is_absolute():
        candidates.append(Path(stage_path).parent / recorded)
    if record.get("abspath"):
        candidates.append(Path(record["abspath"]))
    found = [p for p in candidates if p.is_file()]
    if not found:
        return None, f"{what} {recorded!r} it was made with is not there any more"
    for path in found:
        if stages.sha256_file(path) == record.get("sha256"):
            return path, ""
    return None, f"{what} at {str(found[0])!r} has changed since (its SHA-256 differs from the recorded one)"


def run_body_record(given, stage, stage_path) -> tuple:
    """The body a run of a stage file's model uses and the provenance record of that very file: ``given`` (a body
    file named on the command line; its record only where its SHA-256 is the recorded one, else None), or the
    recorded body (:func:`find_recorded_body`), which must then be found. ``(None, None)`` without a body."""
    path, record, why = find_recorded_body(stage, stage_path, (stages.CONTACTS, stages.MODEL))
    if given is None:
        if why:
            raise InputError(f"was inverted against a body that cannot be found ({why}); give the body file as "
                             "the second argument", stage_path)
        return path, record
    given = Path(given)
    if record is None or stages.sha256_file(given) != record.get("sha256"):
        record = None
    return given, record


def simulation_body(settings: BodySettings, given, stage, stage_path, curves, found: tuple | None = None) -> tuple:
    """The body a run of a stage file's model uses, and the transform that brings it into the groom's frame.

    ``given``: a body file named on the command line, or None for the recorded one (:func:`find_recorded_body`,
    which must then be found). The transform is computed from ``settings`` when any is set, else it is the
    one recorded with that body file (same SHA-256), else the hair's unit and flip.

    Returns
    -------
    (path or None, (4, 4) transform or None, list of str, mesh or None): the notes say what was done; the
    mesh is the body file as read (:func:`formats.read_mesh`) where its size was needed, for
    :func:`load_body` to take instead of reading it again. ``found``: :func:`run_body_record`'s answer, when
    the caller has it.
    """
    scale = float(curves.attrs.get("scale_to_m", 1.0))
    flip = str(curves.config.get("import", {}).get("flip", ""))
    up = np.asarray(curves.attrs.get("up", (0.0, 1.0, 0.0)), dtype=np.float64)
    path, record = run_body_record(given, stage, stage_path) if found is None else found
    if path is None:
        return None, None, [], None
    if frame_settings(settings) != BodySettings():
        mesh = formats.read_mesh(path)
        size = float(np.linalg.norm(np.ptp(np.asarray(mesh.vertices), axis=0)))
        transform, notes = body_to_groom(settings, scale, up, flip, path, size)
        return path, transform, notes, mesh
    return path, recorded_body_transform(record, scale, flip, path), [], None


def simulation_pose(settings: BodySettings, body_path, record: dict | None, stage_path) -> dict:
    """The pose the groom was made on, for a run of a stage file's model on ``body_path``: the one ``settings``
    give (``--bind-time``, ``--body-rest``), else the one ``record`` (that very body file's provenance, from
    :func:`run_body_record`) holds, else its rest pose (``{}``)."""
    given = pose_setting(settings, body_path)
    if given or body_path is None:
        return given
    return recorded_pose(record, stage_path)


# ------------------------------------------------------------------------------------------ the groom's pose


def frame_settings(settings: BodySettings) -> BodySettings:
    """``settings`` without the pose (``bind_time``, ``rest_mesh``): what says the body file's unit and axes."""
    return dataclasses.replace(settings, bind_time=BodySettings.bind_time, rest_mesh=BodySettings.rest_mesh)


def pose_setting(settings: BodySettings, body_path=None) -> dict:
    """The pose the groom was made on, as ``settings`` say it: ``{}`` for the body file's rest pose,
    ``{"bind_time": seconds}``, or ``{"rest_mesh": path}`` (a path, not yet a record); checked in form only."""
    text = str(settings.bind_time).strip().lower()
    rest = str(settings.rest_mesh).strip()
    if text in ("", "rest"):
        return {"rest_mesh": rest} if rest else {}
    if rest:
        raise InputError("--bind-time and --body-rest both say which pose the groom was made on; give one")
    try:
        seconds = float(text[:-1] if text.endswith("s") else text)
    except ValueError:
        raise InputError(f"--bind-time is {settings.bind_time!r}; it must be rest or a time in seconds from "
                         "the animation's start", body_path) from None
    if not (np.isfinite(seconds) and seconds >= 0.0):
        raise InputError(f"--bind-time is {settings.bind_time!r}; it must be rest or a time in seconds from "
                         "the animation's start, 0 or more", body_path)
    return {"bind_time": seconds}


def pose_words(pose: dict) -> str:
    """The pose in words, for the notes: "its rest pose", "its pose at 0.5 s", "the rest mesh's"."""
    if "bind_time" in pose:
        return f"its pose at {pose['bind_time']:g} s of the animation (--bind-time)"
    if "rest_mesh" in pose:
        rest = pose["rest_mesh"]
        return f"the rest mesh {Path(rest['path'] if isinstance(rest, dict) else rest).name}'s (--body-rest)"
    return "its rest pose"


def pose_record(pose: dict) -> dict:
    """What a body input records of the pose (docs/stage-files.md): nothing for the rest pose, the time, or the
    rest mesh's provenance record."""
    if "rest_mesh" in pose and not isinstance(pose["rest_mesh"], dict):
        return {"rest_mesh": stages.file_record(pose["rest_mesh"])}
    return dict(pose)


def recorded_pose(record: dict | None, stage_path) -> dict:
    """The pose a stage file's body input ``record`` says the groom was made on (``{}``: the rest pose), with the
    rest mesh found again from its own record."""
    pose = (record or {}).get("pose") or {}
    if not isinstance(pose, dict):
        raise InputError("records a body pose that is not a table", stage_path)
    if "bind_time" in pose:
        seconds = pose["bind_time"]
        if isinstance(seconds, bool) or not isinstance(seconds, (int, float)) or not (np.isfinite(seconds)
                                                                                     and seconds >= 0):
            raise InputError(f"records a body pose at {seconds!r} s, which is not a time", stage_path)
        return {"bind_time": float(seconds)}
    if "rest_mesh" in pose:
        rest = pose["rest_mesh"]
        if not isinstance(rest, dict):
            raise InputError("records a rest mesh without its provenance", stage_path)
        path, why = find_recorded(rest, stage_path, "the rest mesh")
        if path is None:
            raise InputError(f"was inverted on a rest mesh that cannot be found ({why}); give it with --body-rest",
                             stage_path)
        return {"rest_mesh": str(path)}
    return {}


def pose_vertices(animated, pose: dict, body_path) -> np.ndarray:
    """(V, 3) the animated body ``animated`` (file units) in ``pose``: at a time of its animation, or the
    vertices of a rest mesh, which must be the same mesh (as many vertices, the same triangles)."""
    if "bind_time" in pose:
        seconds = float(pose["bind_time"])
        length = float(animated.end - animated.start)
        if seconds > length + 1e-9:
            raise InputError(f"--bind-time is {seconds:g} s, after the animation's end ({length:.4g} s from its "
                             "start)", body_path)
        return np.asarray(animated.vertices_at(animated.start + min(seconds, length)), dtype=np.float64)
    rest_path = Path(pose["rest_mesh"])
    if not rest_path.exists():
        raise InputError("no such file (the rest mesh, --body-rest)", rest_path)
    rest = formats.read_mesh(rest_path)
    vertices = np.asarray(rest.vertices, dtype=np.float64)
    faces = np.asarray(rest.faces, dtype=np.int64)
    if len(vertices) != len(animated.vertices):
        raise InputError(f"has {len(vertices)} vertices and the animated body {Path(body_path).name} "
                         f"{len(animated.vertices)}: a rest mesh must be that body's mesh in another pose", rest_path)
    if faces.shape != animated.faces.shape or not np.array_equal(faces, animated.faces):
        raise InputError(f"has other triangles than the animated body {Path(body_path).name}: a rest mesh must be "
                         "that body's mesh, its vertices in the same order, in another pose", rest_path)
    if not np.all(np.isfinite(vertices)):
        raise InputError("has vertices that are not finite numbers", rest_path)
    return vertices


def posed_animation(animated, pose: dict, body_path):
    """``animated`` with the groom's pose as its rest pose (``vertices``), which shots bind the roots on and pre-roll
    from."""
    if not pose:
        return animated
    return dataclasses.replace(animated, vertices=pose_vertices(animated, pose, body_path))


def posed_mesh(body_path, pose: dict, mesh=None, animated=None):
    """The body file's mesh (file units and axes) in the groom's pose: the file as read (``mesh``, else
    :func:`formats.read_mesh`) for its rest pose, else its animation's mesh in that pose (``animated``: the file
    already read by :func:`formats.read_animated_body`)."""
    if not pose:
        return formats.read_mesh(body_path) if mesh is None else mesh
    import trimesh

    if animated is None:
        if not formats.is_animated_body(body_path):
            option = "--bind-time" if "bind_time" in pose else "--body-rest"
            raise InputError(f"is a still mesh: {option} says which pose of an animated body the groom was made on",
                             body_path)
        animated = formats.read_animated_body(body_path)
    return trimesh.Trimesh(pose_vertices(animated, pose, body_path), animated.faces, process=False)
