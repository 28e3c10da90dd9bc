"""Run whatever upstream stage a command needs and the input lacks.

``hairinv invert style.h5 body.obj`` accepts raw curves in any readable
format or a stage file at any stage: a stage already in the file is used as
it is (and said so); a missing one is computed with the current settings.
Contacts stored with other contact settings than the current ones, against
another body file than the one given (or without one), for helices fitted
again, or by a gravity-only inversion (which declares none) are detected
again (detection is cheap and its settings are easy to change).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import formats, stages
from .config import ImportSettings, Settings
from .contacts import Contacts, detect_contacts
from .contacts.body import BodyMesh
from .errors import InputError
from .fit import Helices, fit_groom
from .groom import load_body, load_groom

__all__ = ["Scene", "prepare"]


@dataclass
class Scene:
    """A groom ready for the later stages.

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


def _stale_contacts(stored, model, wanted: dict, body_record: dict | None, refitted: bool) -> str | None:
    """Why the stored ``/contacts`` group cannot be used as it is (None: it can)."""
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
    return None


#: m: roots farther than this from the body (median over the strands) are reported, with what it suggests
ROOTS_FAR = 0.02


def root_distance_lines(roots: np.ndarray, body_mesh, body, scale: float = 1.0) -> list[str]:
    """A warning when the strands' roots do not lie on or near the body (checked before the fit).

    Roots grow from the scalp: a median root more than :data:`ROOTS_FAR` from the mesh means the two files
    do not meet, most often because they are in different units (a groom in centimetres on a head in metres
    reads a hundred times too large), and then no body contact is found. Each usual factor between units
    is tried on the hair (the roots scaled about the origin, as a change of unit does); one that puts the
    roots on the body is named (``scale``: the hair's metres per file unit, which the body is read in too)."""
    if len(roots) == 0 or len(body_mesh.face_index) == 0:
        return []
    roots = np.ascontiguousarray(roots, dtype=np.float64)

    def median_distance(points: np.ndarray) -> tuple[float, float]:
        distance = np.abs(body_mesh.closest(points)[0])  # signed: negative inside the body
        return float(np.median(distance)), float(distance.min())

    median, nearest = median_distance(roots)
    if not median > ROOTS_FAR:
        return []
    name = getattr(body, "name", str(body))
    line = (f"warning: the strands' roots lie {1e3 * median:.4g} mm from the body {name} (median over "
            f"{len(roots)} strands; nearest {1e3 * nearest:.4g} mm), so few or no body contacts will be found")
    best = None
    for factor in (1000.0, 100.0, 25.4, 10.0, 2.54, 1 / 2.54, 0.1, 1 / 25.4, 0.01, 0.001):
        moved, _ = median_distance(roots * factor)
        if moved <= ROOTS_FAR and (best is None or moved < best[1]):
            best = (factor, moved)
    if best is not None:
        factor, moved = best
        return [line + f"; the hair {factor:.4g} times larger would put them {1e3 * moved:.3g} mm from it: the two "
                       f"files are likely in different units (the body is read in the hair's unit, "
                       f"{scale:.6g} m per file unit; bring both files to one unit)"]
    return [line + "; check that the groom and the body share their units, up axis and placement"]


def prepare(style, body, settings: Settings, contacts: bool = True, progress=None) -> Scene:
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
    native = formats.read_mesh(body) if body is not None else None  # read once: units guess and contacts
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
    else:
        size = float(np.linalg.norm(np.ptp(np.asarray(native.vertices), axis=0))) if native is not None else None
        groom, report = load_groom(style, settings.import_, body_size_native=size)
        lines += report.lines()
        groups[stages.CURVES] = groom.curves_group(settings.import_, inputs[:1])
        up, scale, flip = groom.up, groom.scale_to_m, settings.import_.flip
        helices = None
        stored_contacts = stored_model = None
    refitted = helices is None
    mesh = load_body(body, scale, flip, native) if body is not None else None
    # built once: the roots' check here and the body contacts below
    body_mesh = BodyMesh.from_mesh(mesh) if mesh is not None else None
    if body_mesh is not None:
        roots = groom.points[groom.offsets[:-1]] if helices is None else helices.root
        lines += root_distance_lines(roots, body_mesh, body, groom.scale_to_m if groom is not None else scale)
    if helices is None:
        bar = progress("fit", groom.n_strands) if progress else None
        try:
            helices, fit_report = fit_groom(groom, settings.fit, progress=bar)
        finally:
            if bar is not None:
                bar.close()
        lines += fit_report.lines()
        groups[stages.HELICES] = helices.group(settings.fit, inputs[:1])
    scene = Scene(groups, helices, up, None, mesh, inputs, lines)
    if not contacts:
        return scene
    wanted = {"contacts": dataclasses.asdict(settings.contacts)}
    stale = _stale_contacts(stored_contacts, stored_model, wanted, inputs[1] if body is not None else None,
                            refitted=refitted)
    if stored_contacts is not None and stale is None:
        scene.contacts = Contacts.from_group(stored_contacts)
        groups[stages.CONTACTS] = stored_contacts
        lines.append(f"using the {scene.contacts.n_contacts} contacts in {style.name}")
        if (stored_model is not None and scene.contacts.n_contacts
                and np.shape(stored_model["force"]) == (scene.contacts.n_contacts, 3)):
            scene.model = stored_model
        return scene
    if stored_contacts is not None:
        lines.append(f"the contacts in {style.name} {stale}; detecting them again")
    if mesh is None and settings.contacts.body:
        lines.append("no body given: only hair-hair contacts are declared")
    found, detect_report = detect_contacts(helices, body_mesh, settings.contacts, up=up)
    lines += detect_report.lines()
    scene.contacts = found
    groups[stages.CONTACTS] = found.group(settings.contacts, inputs)
    return scene
