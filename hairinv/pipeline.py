"""Run whatever upstream stage a command needs and the input lacks.

``hairinv invert style.h5 body.obj`` accepts raw curves in any readable
format or a stage file at any stage: a stage already in the file is used as
it is (and said so); a missing one is computed with the current settings.
Contacts stored with other contact settings than the current ones, against
another body file than the one given (or without one), for helices fitted
again, or by a gravity-only inversion (which declares none) are detected
again (detection is cheap and its settings are easy to change).

Once inverted, :func:`model_groups` assembles what the model's stage file
holds, and refuses a model the contact solver could not compute.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import formats, stages
from .config import BodySettings, UNITS, ImportSettings, Settings
from .contacts import detect_contacts
from .contacts.body import BodyMesh
from .errors import InputError, RunError, in_file
from .features import Features, detect_features, invert_features
from .fit import fit_groom
from .groom import (body_to_groom, load_body, load_groom, pose_record, pose_setting, pose_words, posed_mesh,
                    recorded_body_transform, rotation_onto, strand_lengths)
from .model import BODY, Contacts, Helices, Material
from .solver.status import Status

__all__ = ["Prepared", "prepare", "check_invert_settings", "model_features", "model_groups"]


@dataclass
class Prepared:
    """The prepared inputs of a stage: a groom fitted (and, when asked, its contacts declared), ready for
    the later stages.

    Attributes
    ----------
    groups : dict of stage name -> Group, the upstream groups to carry into the output file
    helices : Helices
    up : (3,) float64
    contacts : Contacts or None (None until detected)
    body : trimesh.Trimesh or None, in metres
    inputs : list of provenance records (the style file, then the body file)
    lines : report lines of the stages that ran or were reused
    """

    groups: dict
    helices: Helices
    up: np.ndarray
    contacts: Contacts | None = None
    body: object = None
    inputs: list = field(default_factory=list)
    lines: list = field(default_factory=list)
    model: object = None
    """the style file's /model group, kept only when its contacts are the ones used (its forces match them)"""
    timings: dict = field(default_factory=dict)
    """seconds of the stages run here (``fit``, ``detect``); stages reused from the style file are absent"""
    features: Features | None = None
    """what the contacts model and skip, and why (:func:`hairinv.features.detect_features`)"""


def _stale_contacts(stored, model, wanted: dict, body_record: dict | None, refitted: bool,
                    hair_unit: tuple[float, str] = (1.0, "")) -> str | None:
    """Why the stored ``/contacts`` group cannot be used as it is (None: it can).

    ``hair_unit``: the groom's metres per unit and flip, how a file that records no body transform read
    its body."""
    if stored is None:
        return None
    if refitted:  # contacts name strands and arc lengths of the stored helices
        return "belong to helices that are not in the file"
    if model is not None and model.attrs.get("target") == "gravity-only":
        return "belong to a gravity-only model, which declares none"
    if stored.config != wanted:
        return "were detected with other settings"
    if body_record is None:  # no body given: the contacts stand for the body they were detected against
        return None
    stored_body = stored.inputs[1].get("sha256") if len(stored.inputs) > 1 else None
    if stored_body is None:
        return "were detected without a body"
    if stored_body != body_record.get("sha256"):
        return "were detected against another body"
    stored_transform = recorded_body_transform(stored.inputs[1], *hair_unit)
    if not np.allclose(stored_transform, np.asarray(body_record["to_groom"]), rtol=1e-12, atol=0.0):
        return "were detected with the body in other units or axes"
    if _pose_key(stored.inputs[1].get("pose")) != _pose_key(body_record.get("pose")):
        return "were detected on the body in another pose"
    return None


def _pose_key(pose) -> tuple:
    """A body input's recorded pose, to compare: a rest mesh by its contents."""
    pose = pose or {}
    if "bind_time" in pose:
        return ("time", pose["bind_time"])
    if "rest_mesh" in pose:
        return ("mesh", (pose["rest_mesh"] or {}).get("sha256") if isinstance(pose["rest_mesh"], dict) else None)
    return ()


#: m: roots farther than this from the body (median over the strands) are reported, with what it suggests
ROOTS_FAR = 0.02


#: Roots checked against the body, at most (a seeded, even subset of a large groom's).
_ROOTS_CHECKED = 512
#: Usual ratios between two files' units (m, cm, mm, in), tried on the body to find a unit mix-up.
_UNIT_FACTORS = (1000.0, 100.0, 25.4, 10.0, 2.54, 1 / 2.54, 0.1, 1 / 25.4, 0.01, 0.001)


def root_distance_lines(roots: np.ndarray, body_mesh, body, up, body_settings: BodySettings,
                        to_groom: np.ndarray | None = None, reach: np.ndarray | None = None,
                        other_poses=None) -> list[str]:
    """A warning when the strands' roots do not lie on or near the body (checked before the fit), and a
    refusal when no strand can touch it.

    Roots grow from the scalp: a median root more than :data:`ROOTS_FAR` from the mesh means the two files
    do not meet, most often because they are in different units (a groom in centimetres on a head in metres
    reads a hundred times too large) or axes (a Z-up body under a Y-up groom), and then no body contact is
    found. Each usual factor between units, and each other up axis of the body file when none was given,
    is tried on the body (as the roots moved the other way about the origin); the one that puts the roots
    on the body is named with the option that does it. ``to_groom``: the body's transform in use, whose
    scale the suggested unit is computed from.

    ``reach``: (S,) m, how far from its root each strand can touch the body (its length plus the farthest
    a contact is declared from the body). When the roots lie far from it (as above) and every root lies
    outside the body, farther from it than that, the body can carry no strand whatever its shape, so it
    is not the body the groom rests on: an :class:`InputError` of the body file says so, with the fix,
    before any work is done.

    ``other_poses``: for an animated body read in its rest pose, a callable giving ``(seconds, BodyMesh)`` of
    other poses of its animation; where the roots lie on one of them, the fix named is ``--bind-time``."""
    if len(roots) == 0 or len(body_mesh.face_index) == 0:
        return []
    every_root = roots = np.ascontiguousarray(roots, dtype=np.float64)
    sample = slice(None)
    if len(roots) > _ROOTS_CHECKED:
        sample = np.random.default_rng(0).choice(len(roots), _ROOTS_CHECKED, replace=False)
        roots = roots[sample]

    def signed_distance(points: np.ndarray) -> np.ndarray:
        return body_mesh.closest(np.ascontiguousarray(points))[0]  # signed: negative inside

    distance = np.abs(signed_distance(roots))
    median, nearest = float(np.median(distance)), float(distance.min())
    if not median > ROOTS_FAR:
        return []
    fix = _pose_fix(roots, other_poses) if other_poses is not None else None
    if fix is None:
        fix = _body_fix(roots, signed_distance, up, body_settings, to_groom,
                        None if reach is None else np.asarray(reach, dtype=np.float64)[sample])
    if reach is not None:
        # signed: a root inside the body is in contact with it, however deep
        outside = signed_distance(every_root)
        if not np.any(outside <= reach):
            k = int(np.argmin(outside - reach))  # the strand that comes closest to reaching it
            raise InputError(f"no strand can reach this body: every root lies outside it, farther from it than its "
                             f"strand is long (the closest, strand {k}, {1e3 * outside[k]:.4g} mm away with "
                             f"{1e3 * reach[k]:.4g} mm of strand and contact distance); {fix}, or run without a body",
                             body)
    name = getattr(body, "name", str(body))
    return [f"warning: the strands' roots lie {1e3 * median:.4g} mm from the body {name} (median over "
            f"{len(roots)} strands; nearest {1e3 * nearest:.4g} mm), so few or no body contacts will be found; "
            + fix]


def _pose_fix(roots: np.ndarray, other_poses) -> str | None:
    """``--bind-time T`` where the roots lie on the animated body's pose at ``T`` (median within
    :data:`ROOTS_FAR`; the nearest such pose), else None."""
    best = None
    for seconds, mesh in other_poses():
        median = float(np.median(np.abs(mesh.closest(roots)[0])))
        if median <= ROOTS_FAR and (best is None or median < best[1]):
            best = (seconds, median)
    if best is None:
        return None
    return (f"they lie {1e3 * best[1]:.3g} mm from the body's pose at {best[0]:.4g} s of its animation: if the groom "
            f"was made on that pose, pass --bind-time {best[0]:.4g}")


#: How many poses of an animated body the roots are tried on when they lie far from its rest pose.
POSES_TRIED = 12


def animation_poses(body, to_groom: np.ndarray):
    """A callable for :func:`root_distance_lines`: up to :data:`POSES_TRIED` poses of the animated body file
    ``body`` at its key times (evenly picked, the first included), each brought into the groom's frame."""
    def poses():
        from .dynamics.skin import MeshArrays

        animated = formats.read_animated_body(body)
        times = animated.times[np.unique(np.linspace(0, len(animated.times) - 1, POSES_TRIED).round().astype(int))]
        M = np.asarray(to_groom, dtype=np.float64)
        for t in times:
            vertices = animated.vertices_at(float(t)) @ M[:3, :3].T + M[:3, 3]
            yield float(t - animated.start), BodyMesh.from_mesh(MeshArrays(vertices, animated.faces))
    return poses


def _body_fix(roots: np.ndarray, signed_distance, up, body_settings: BodySettings, to_groom,
              reach: np.ndarray | None) -> str:
    """What would put ``roots`` on the body: a body unit or up axis whose options, applied, bring the roots'
    median within :data:`ROOTS_FAR` of the body and some strand within its reach (each candidate is tried on
    the body before it is offered), with the options; else the options to check.

    A candidate scales the body by ``factor`` and turns it by ``R`` about the origin of the groom's frame, as
    the options do (:func:`hairinv.groom.body_to_groom`): the roots' distances to that body are ``factor``
    times those of ``R^T roots / factor`` to the body as it is. With the body's transform at hand, the units
    tried are the body units the options name (``--body-units``), whatever the body is read in now; fewer
    changes are offered before more (a unit before a unit and an axis)."""
    up = np.asarray(up, dtype=np.float64)
    turns = [(None, np.eye(3))]
    if body_settings.up == "hair":
        turns += [(axis, rotation_onto(np.eye(3)[i], up)) for axis, i in (("y", 1), ("z", 2), ("x", 0))
                  if abs(up[i]) < 0.5]
    if to_groom is not None and body_settings.flip == "hair":
        # the hair's --flip mirrors the body too (its transform is then the hair's scale times that mirror): a body
        # whose file is already in the hair's flipped axes is mirrored once too often
        M = np.asarray(to_groom, dtype=np.float64)[:3, :3]
        if np.linalg.det(M) < 0 and np.allclose(M, np.diag(np.diag(M)), atol=1e-12 * np.abs(M).max()):
            turns.append(("mirror", np.diag(np.sign(np.diag(M)))))
    body_scale = abs(float(np.linalg.det(to_groom[:3, :3]))) ** (1 / 3) if to_groom is not None else None
    if body_scale:
        scales = [(unit, metres / body_scale) for unit, metres in UNITS.items()]
    else:
        scales = [(None, factor) for factor in _UNIT_FACTORS]
    scales = [(None, 1.0)] + [(unit, f) for unit, f in scales if abs(f - 1.0) > 1e-9]
    best = None
    for axis, R in turns:
        for unit, factor in scales:
            if axis is None and unit is None and factor == 1.0:
                continue
            distance = factor * signed_distance(roots @ R / factor)  # to the body scaled by factor, turned by R
            moved = float(np.median(np.abs(distance)))
            if not moved <= ROOTS_FAR or (reach is not None and not np.any(distance <= reach)):
                continue
            rank = ((axis is not None) + (factor != 1.0), moved)
            if best is None or rank < best[0]:
                best = (rank, axis, unit, factor, moved)
    if best is None:
        return ("check that the groom and the body share their units, up axis and placement "
                "(--body-units, --body-scale, --body-up)")
    _, axis, unit, factor, moved = best
    fixes, what = [], []
    if factor != 1.0:
        what.append(f"at {factor:.4g} times its size")
        if body_scale:
            fixes.append(f"--body-units {unit}")
    if axis == "mirror":
        what.append("not mirrored")
        fixes.append("--body-flip none")
    elif axis is not None:
        what.append(f"turned as a +{axis.upper()}-up file")
        fixes.append(f"--body-up {axis}")
    return (f"the body {' and '.join(what)} would put them {1e3 * moved:.3g} mm from it: the two files "
            f"are likely in different {'units' if factor != 1.0 else 'axes'}"
            + (f" (try {' '.join(fixes)})" if fixes else ""))


def animated_body_lines(body, pose: dict | None = None) -> list[str]:
    """A note when the body file is animated: the pose the stages read (its rest pose, or ``pose``); its animation
    and skinning are not played."""
    if not formats.is_animated_body(body):
        return []
    motion = formats.read_animated_body(body)
    joints = f", {len(motion.joints)} joints" if motion.joints else ""
    where = (f"on {pose_words(pose)}" if pose else
             "on the mesh as the file stores it (its rest pose, a skinned mesh's bind pose; --bind-time or "
             "--body-rest say another)")
    return [f"note: {Path(body).name} is animated ({motion.n_frames} frames over {motion.end - motion.start:.3g} s"
            f"{joints}): the groom is placed {where}; `hairinv simulate` plays the animation from there"]


def prepare(style, body, settings: Settings, contacts: bool = True, progress=None) -> Prepared:
    """Read ``style`` (raw curves or a stage file) and ``body`` and bring them to the contact stage.

    Parameters
    ----------
    style : path of a hairstyle file or a hairinv stage file
    body : path of the body mesh, or None (no body: no hair-body contacts)
    settings : Settings
    contacts : bool, detect (or reuse) contacts
    progress : callable(stage name, total) -> callable(n) with a ``close()``, optional
    """
    style = Path(style)
    if not style.exists():
        raise InputError("no such file", style)
    if body is not None and not Path(body).exists():
        raise InputError("no such file", body)
    inputs = [stages.file_record(style)]
    if body is not None:
        inputs.append(stages.file_record(body))
    lines: list[str] = []
    groups: dict = {}
    pose = pose_setting(settings.body, body) if body is not None else {}
    # read once: units guess and contacts; in the groom's pose
    native = posed_mesh(body, pose) if body is not None else None
    body_size = float(np.linalg.norm(np.ptp(np.asarray(native.vertices), axis=0))) if native is not None else None
    if body is not None:
        lines += animated_body_lines(body, pose)
    if stages.is_stage_file(style):
        stage = stages.read_stage(style)
        if stages.CURVES not in stage:
            raise InputError("has no /curves group, so its units and up axis are unknown", style)
        curves = stage[stages.CURVES]
        groups[stages.CURVES] = curves
        up = np.asarray(curves.attrs.get("up", (0.0, 1.0, 0.0)), dtype=np.float64)
        scale = float(curves.attrs.get("scale_to_m", 1.0))
        flip = str(curves.config.get("import", {}).get("flip", ""))
        if stages.HELICES in stage:
            helices = Helices.from_group(stage[stages.HELICES])
            groups[stages.HELICES] = stage[stages.HELICES]
            lines.append(f"using the fitted helices in {style.name} ({helices.n_strands} strands, "
                         f"{helices.n_elements} elements)")
            changed = [k for k, v in dataclasses.asdict(settings.import_).items()
                       if v != getattr(ImportSettings(), k)]
            if changed:
                lines.append(f"note: {style.name} is already fitted, so the import settings "
                             f"({', '.join(changed)}) do not apply; fit the raw curves to change them")
        else:
            helices = None
        stored_contacts = stage[stages.CONTACTS] if stages.CONTACTS in stage else None
        stored_model = stage[stages.MODEL] if stages.MODEL in stage and helices is not None else None
        groom = None
        if helices is None:
            groom, report = load_groom(style, settings.import_)
            lines += report.lines()
            same = np.array_equal(groom.offsets, curves["offsets"]) and np.array_equal(groom.points, curves["points"])
            if not same:  # cleaned or a guide subset: /curves holds the strands fitted, in the stored units and axes
                stored = curves.config.get("import", {})
                groups[stages.CURVES] = stages.Group(
                    stages.CURVES, {"points": groom.points, "offsets": groom.offsets}, attrs=dict(curves.attrs),
                    config={"import": {**stored, "guides": settings.import_.guides, "seed": settings.import_.seed}},
                    inputs=inputs[:1])
    else:
        # the hair's unit guessed from the body's size when the body is read in the hair's unit
        size = body_size if settings.body.units == "hair" and settings.body.scale <= 0 else None
        groom, report = load_groom(style, settings.import_, body_size_native=size)
        lines += report.lines()
        groups[stages.CURVES] = groom.curves_group(settings.import_, inputs[:1])
        up, scale, flip = groom.up, groom.scale_to_m, settings.import_.flip
        helices = None
        stored_contacts = stored_model = None
    refitted = helices is None
    mesh = None
    if body is not None:
        to_groom, notes = body_to_groom(settings.body, scale, up, flip, body, body_size)
        lines += notes
        inputs[1]["to_groom"] = to_groom.tolist()
        if pose:
            inputs[1]["pose"] = pose_record(pose)
        mesh = load_body(body, to_groom, native)
    # built once: the roots' check here and the body contacts below; with contacts.body off the body is
    # read (its file is an input) but never queried
    with in_file(body):
        body_mesh = BodyMesh.from_mesh(mesh) if mesh is not None and settings.contacts.body and contacts else None
    if body_mesh is not None:
        if helices is None:
            roots, lengths = groom.points[groom.offsets[:-1]], strand_lengths(groom.points, groom.offsets)
        else:  # every strand has an element (the stage file's checks)
            roots, lengths = helices.root, np.add.reduceat(helices.length, helices.offsets[:-1])
        c = settings.contacts  # a contact is declared up to body_distance from the body, or on a hair layer
        others = animation_poses(body, to_groom) if not pose and formats.is_animated_body(body) else None
        lines += root_distance_lines(roots, body_mesh, body, up, settings.body, to_groom,
                                     reach=lengths + max(c.body_distance, c.layer_max_gap if c.layer else 0.0),
                                     other_poses=others)
    if helices is None:
        bar = progress("fit", groom.n_strands) if progress else None
        try:
            helices, fit_report = fit_groom(groom, settings.fit, progress=bar)
        finally:
            if bar is not None:
                bar.close()
        lines += fit_report.lines()
        groups[stages.HELICES] = helices.group(settings.fit, inputs[:1], {"seconds": fit_report.seconds})
    prepared = Prepared(groups, helices, up, None, mesh, inputs, lines)
    if refitted:
        prepared.timings["fit"] = fit_report.seconds
    if not contacts:
        return prepared
    prepared.features = detect_features(settings.contacts, mesh is not None)
    wanted = {"contacts": dataclasses.asdict(settings.contacts)}
    stale = _stale_contacts(stored_contacts, stored_model, wanted, inputs[1] if body is not None else None,
                            refitted=refitted, hair_unit=(scale, flip))
    if stored_contacts is not None and stale is None:
        prepared.contacts = Contacts.from_group(stored_contacts)
        groups[stages.CONTACTS] = stored_contacts
        lines.append(f"using the {prepared.contacts.n_contacts} contacts in {style.name}")
        # what they model is what their detection modelled (with or without a body given now); a file
        # that does not record it models body contact where it has some
        stored = Features.from_attr(stored_contacts.attrs.get("features"))
        prepared.features = stored if stored is not None else detect_features(
            settings.contacts, bool(np.any(prepared.contacts.strand[:, 1] == BODY)))
        if (stored_model is not None and prepared.contacts.n_contacts
                and np.shape(stored_model["force"]) == (prepared.contacts.n_contacts, 3)):
            prepared.model = stored_model
        return prepared
    if stored_contacts is not None:
        lines.append(f"the contacts in {style.name} {stale}; detecting them again")
    if mesh is None and settings.contacts.body:
        lines.append("no body given: only hair-hair contacts are declared")
    if mesh is not None and not settings.contacts.body:
        lines.append("contacts.body is off: the body mesh is ignored (no body queries)")
    found, detect_report = detect_contacts(helices, body_mesh, settings.contacts, up=up)
    lines += detect_report.lines()
    prepared.timings["detect"] = detect_report.seconds
    prepared.contacts = found
    groups[stages.CONTACTS] = found.group(settings.contacts, inputs, seconds=detect_report.seconds)
    groups[stages.CONTACTS].attrs["features"] = prepared.features.attr()
    return prepared


def check_invert_settings(settings: Settings) -> None:
    """Refuse bad material or solver settings (an :class:`InputError` naming the setting), before any
    fitting."""
    from .invert import validate_settings  # the solvers, imported only by the commands that invert

    Material.from_settings(settings.material, (0.0, 1.0, 0.0))
    validate_settings(settings.solver)


def model_features(prepared: Prepared, settings: Settings, material: Material) -> Features:
    """What an inversion of ``prepared`` models and skips, and why: body contact as the contacts in use
    model it (reused from the style file, they may have been found against a body not given now)."""
    if prepared.features is not None:
        body = "body_contact" in prepared.features.modelled
    else:
        body = prepared.body is not None
    return invert_features(settings.contacts, settings.solver, material.gravity, body)


def model_groups(prepared: Prepared, model, settings: Settings, features: Features) -> list[stages.Group]:
    """The groups of an inverted model's stage file: the prepared ones (with an empty ``/contacts`` for a
    gravity-only model, which declares none), then ``model``'s ``/model`` with ``features``; a ``/model``
    or ``/frames`` the style file held is dropped.

    Raises
    ------
    RunError
        The contact solver met a numerical error: there is no model to write.
    """
    from .inverse.report import settings_dict

    result = model.result
    if result.status == Status.NUMERICAL_ERROR:
        raise RunError(f"the contact solver met a numerical error after {result.sweeps} sweeps "
                       f"(residual {result.residual:.3g} N); no output was written")
    groups = dict(prepared.groups)
    if stages.CONTACTS not in groups:  # gravity-only: the model declares no contact
        groups[stages.CONTACTS] = Contacts.empty().group(settings.contacts, prepared.inputs)
    groups.pop(stages.MODEL, None)
    groups.pop(stages.FRAMES, None)
    groups[stages.MODEL] = model.group(settings_dict(settings.material, settings.solver), prepared.inputs)
    groups[stages.MODEL].attrs["features"] = features.attr()
    return list(groups.values())
