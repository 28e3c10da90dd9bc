"""HDF5 stage files: the contract between subcommands (docs/stage-files.md).

Dataset and group names live here and nowhere else. Files are written
atomically (a temporary file in the destination folder, then a rename), so a
killed job leaves either the old file or the complete new one, never a part.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from . import __version__
from .atomic import atomic_path
from .config import MATERIAL_RANGE, material_range_error
from .errors import InputError

FORMAT = "hairinv"
SCHEMA_VERSION = 1

CURVES = "curves"
HELICES = "helices"
CONTACTS = "contacts"
MODEL = "model"
FRAMES = "frames"
PIPELINE = (CURVES, HELICES, CONTACTS, MODEL, FRAMES)

# The datasets of each group: name -> (dtype kind, shape). A shape is a tuple of fixed sizes and of
# counts the reader resolves from the file (check_consistency): S strands, P points of /curves,
# E elements of /helices, C contacts, F frames, Ef elements of the frames' strands (E unless a trim
# scene stored its own layout), n any. Datasets of REQUIRED must be there; the others are checked
# where present.
LAYOUT = {
    CURVES: {"points": ("f", ("P", 3)), "offsets": ("i", ("S+1",))},
    HELICES: {
        "root": ("f", ("S", 3)),
        "frame0": ("f", ("S", 3, 3)),
        "offsets": ("i", ("S+1",)),
        "length": ("f", ("E",)),
        "omega": ("f", ("E", 3)),
        "fit_error": ("f", ("S", 2)),
    },
    CONTACTS: {
        "strand": ("i", ("C", 2)),
        "s": ("f", ("C", 2)),
        "point": ("f", ("C", 3)),
        "frame": ("f", ("C", 3, 3)),
        "mu": ("f", ("C",)),
        "gap": ("f", ("C",)),
        "element": ("i", ("C", 2)),
    },
    MODEL: {
        "omega_rest": ("f", ("E", 3)),
        "omega_target": ("f", ("E", 3)),
        "target_weight": ("f", ("E",)),
        "force": ("f", ("C", 3)),
        "residual_history": ("f", ("n", 2)),
        "stiffening": ("f", ("S",)),
        "omega_rest_stiffened": ("f", ("E", 3)),
        "stability_margin": ("f", ("S",)),
        "contact_gamma": ("f", ("C",)),
    },
    FRAMES: {
        "time": ("f", ("F",)),
        "omega": ("f", ("F", "Ef", 3)),
        "root": ("f", ("F", "S", 3)),
        "frame0": ("f", ("F", "S", 3, 3)),
        "body_transform": ("f", ("F", 4, 4)),
        "displacement": ("f", ("F",)),
        "strand_displacement": ("f", ("F", "S")),
        "kinetic_energy": ("f", ("F",)),
        "elastic_energy": ("f", ("F",)),
        "contact_count": ("i", ("F",)),
        "solver_residual": ("f", ("F",)),
        "frame_seconds": ("f", ("F",)),
        "offsets": ("i", ("S+1",)),
        "length": ("f", ("Ef",)),
        "body_vertices": ("f", ("F", "V", 3)),
        "body_faces": ("i", ("T", 3)),
        "binding_triangle": ("i", ("S",)),
        "binding_barycentric": ("f", ("S", 3)),
        "binding_offset": ("f", ("S", 3)),
        "binding_distance": ("f", ("S",)),
    },
}

REQUIRED = {
    CURVES: ("points", "offsets"),
    HELICES: ("root", "frame0", "offsets", "length", "omega", "fit_error"),
    CONTACTS: ("strand", "s", "point", "frame", "mu"),
    MODEL: ("omega_rest", "omega_target", "target_weight", "force"),
    FRAMES: ("time", "omega", "root", "frame0", "body_transform"),
}

#: The groups a group is defined against: a model and frames are sized by the fitted strands' elements.
#: Contacts name strands and arc lengths of /helices too, but a file may hold them without it (``invert``
#: then fits the curves again and detects the contacts again): their strands are then those of /curves.
NEEDS = {MODEL: HELICES, FRAMES: HELICES}

#: The inversion targets a /model records (docs/stage-files.md).
MODEL_TARGETS = ("actual", "zero", "uniform", "tip", "gravity-only")

# The attributes hairinv reads: name -> (kind, required). Kinds: "positive" and "nonnegative" (a finite
# number), "count" (an integer >= 0), "vector" (3 finite numbers, not all 0), "vector0" (3 finite numbers,
# all 0 allowed), "str", "bool", or a tuple of the strings allowed.
ATTRS = {
    CURVES: {"up": ("vector", False), "scale_to_m": ("positive", False), "source": ("str", False)},
    HELICES: {"seconds": ("nonnegative", False)},
    CONTACTS: {"seconds": ("nonnegative", False)},
    MODEL: {
        "youngs_modulus": ("material", True),  # within config.MATERIAL_RANGE
        "shear_modulus": ("material", True),
        "density": ("material", True),
        "radius": ("material", True),
        "gravity": ("vector0", True),  # all 0: a scene without gravity (material.gravity = 0); length in range
        "gamma": ("positive", True),
        "gamma_relative": ("nonnegative", False),
        "target": (MODEL_TARGETS, False),
        "iterations": ("count", False),
        "prior_sweeps": ("count", False),
        "residual": ("nonnegative", False),
        "relative_residual": ("nonnegative", False),
        "seconds": ("nonnegative", False),
        "carrying_threshold": ("nonnegative", False),
        "status": ("str", False),
        "stable_under": (("forces", "supports"), False),
    },
    FRAMES: {
        "time_step": ("positive", False),
        "steps_per_frame": ("count", False),
        "fps": ("positive", False),
        "init": (("inverted", "naive", "gravity-only"), False),
        "scene": ("str", False),
        "body_removed": ("bool", False),
        "trimmed": ("bool", False),
        "stopped": ("bool", False),
        "interrupted": ("bool", False),
        "frames_requested": ("count", False),
        "seconds": ("nonnegative", False),
        "preroll": ("nonnegative", False),
        "body_animated": ("bool", False),
    },
}

#: Largest deviation of a frame's rows from orthonormal (|R R^T - I|, elementwise) a reader accepts: the
#: writers' frames are orthonormal to round-off (1e-15); 1e-6 leaves room for files from other tools.
FRAME_TOLERANCE = 1e-6
#: How far past either end of its strand a contact's arc length may lie: 1e-6 m plus 1e-9 of the strand's
#: length (the round-off of summing element lengths).
ARC_TOLERANCE_M = 1e-6
ARC_TOLERANCE_RELATIVE = 1e-9


@dataclass
class Group:
    """One stage group: datasets, attributes and provenance.

    ``config`` is the effective settings that produced the group and
    ``inputs`` the files it was computed from (name and SHA-256).
    """

    name: str
    datasets: dict[str, np.ndarray]
    attrs: dict = field(default_factory=dict)
    config: dict = field(default_factory=dict)
    inputs: list[dict] = field(default_factory=list)

    def __getitem__(self, key: str) -> np.ndarray:
        return self.datasets[key]


@dataclass
class StageFile:
    """A stage file read into memory: its groups in pipeline order."""

    path: Path
    groups: dict[str, Group]
    producer: str = ""
    schema_version: int = SCHEMA_VERSION

    def __contains__(self, name: str) -> bool:
        return name in self.groups

    def __getitem__(self, name: str) -> Group:
        return self.groups[name]

    @property
    def last_stage(self) -> str:
        return [g for g in PIPELINE if g in self.groups][-1]


def sha256_file(path) -> str:
    """SHA-256 hex digest of a file's bytes; of a sequence of frames (a folder, a ``body.####.obj`` pattern),
    of its frame numbers and their files' digests."""
    path = Path(path)
    if path.is_dir() or "#" in path.name:
        from .formats.sequence import sequence_frames

        digest = hashlib.sha256()
        for number, frame in sequence_frames(path):
            digest.update(f"{number} {sha256_file(frame)}\n".encode())
        return digest.hexdigest()
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def file_record(path) -> dict:
    """Provenance entry of an input file: ``name``, ``path`` as given, ``abspath`` (absolute, so that it is
    found again from another working folder) and ``sha256``."""
    path = Path(path)
    return {"name": path.name, "path": str(path), "abspath": str(path.resolve()), "sha256": sha256_file(path)}


def is_stage_file(path) -> bool:
    """True if ``path`` is an HDF5 file written by hairinv."""
    try:
        with h5py.File(path, "r") as fh:
            return fh.attrs.get("format") == FORMAT
    except (OSError, ValueError):
        return False


def check_output_path(out, inputs=()) -> Path:
    """Refuse an output path that would destroy something the user gave us.

    Writing over one of the inputs, over a folder, or over an existing file
    that is not a hairinv stage file raises :class:`InputError`; an older
    stage file is replaced (atomically) as a Makefile rerun expects.
    """
    out = Path(out)
    resolved = out.resolve()
    for src in inputs:
        if src is not None and Path(src).resolve() == resolved:
            raise InputError("the output file would overwrite an input file; choose another -o", out)
    if out.is_dir():
        raise InputError("the output path is a folder", out)
    if out.exists() and not is_stage_file(out):
        raise InputError("exists and is not a hairinv stage file; refusing to overwrite it", out)
    if not out.parent.exists():
        raise InputError("the output folder does not exist", out.parent)
    return out


def write_stage(path, groups: list[Group], command: str, record: dict | None = None) -> Path:
    """Write ``groups`` to ``path`` atomically.

    Parameters
    ----------
    path : path-like
        Destination; its folder must exist.
    groups : list of Group
        Written in pipeline order whatever the order given.
    command : str
        The subcommand that produced the file, recorded in ``producer``.
    record : dict, optional
        What made the file (:func:`hairinv.staleness.command_record`), stored as JSON in the root
        attribute ``command``.
    """
    path = Path(path)
    order = {name: i for i, name in enumerate(PIPELINE)}
    groups = sorted(groups, key=lambda g: order.get(g.name, len(order)))
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as fh:
        fh.attrs["format"] = FORMAT
        fh.attrs["schema_version"] = SCHEMA_VERSION
        fh.attrs["producer"] = f"hairinv {__version__} {command}"
        fh.attrs["stages"] = ",".join(g.name for g in groups)
        if record is not None:
            fh.attrs["command"] = json.dumps(record, sort_keys=True, default=str)
        for group in groups:
            h5 = fh.create_group(group.name)
            for key, value in group.datasets.items():
                value = np.asarray(value)
                h5.create_dataset(key, data=value)
            for key, value in group.attrs.items():
                h5.attrs[key] = value
            h5.attrs["config"] = json.dumps(group.config, sort_keys=True, default=str)
            h5.attrs["inputs"] = json.dumps(group.inputs)
    return path


def _attr(value):
    if isinstance(value, bytes):
        return value.decode(errors="replace")
    if isinstance(value, np.generic):
        return value.item()
    return value


def _memory_bytes() -> int | None:
    """This machine's physical memory in bytes, or None where the system does not say."""
    try:
        return int(os.sysconf("SC_PAGE_SIZE")) * int(os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, ValueError, OSError):
        return None


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__


def read_stage(path) -> StageFile:
    """Read and validate a stage file.

    Every reader of a stage file goes through here, so a file that breaks the contract of
    docs/stage-files.md is refused before any computation, with one sentence naming the file and what
    is wrong (:func:`check_consistency` lists the checks).

    Raises
    ------
    InputError
        If the file is not a hairinv stage file, has a newer schema, lacks a dataset or attribute hairinv
        needs, has one of the wrong type or shape, or holds groups inconsistent with one another.
    """
    path = Path(path)
    with _opened(path) as fh:
        stage = _read(fh, path)
    check_consistency(stage)
    return stage


@contextlib.contextmanager
def _opened(path: Path):
    """The stage file open for reading; h5py's errors on a file that is not HDF5, or is damaged, become
    one :class:`InputError` sentence."""
    try:
        fh = h5py.File(path, "r")
    except (OSError, ValueError):
        raise InputError("is not a readable HDF5 file", path) from None
    with fh:
        try:
            yield fh
        except InputError:
            raise
        except (OSError, KeyError, ValueError, TypeError, RuntimeError) as exc:  # h5py on a damaged file
            raise InputError(f"cannot be read, the HDF5 file is damaged ({_one_line(exc)})", path) from None


def check_metadata(path) -> None:
    """Check a stage file as far as its metadata tells, without reading its arrays.

    For a quick look at a large file (``hairinv status``): the root attributes, every group's attributes,
    config and inputs, the datasets' dtypes and shapes, and the counts the shapes must agree on (strands,
    points, elements, contacts, frames), which it reads from the first and last entries of each ``offsets``
    (two numbers per group) and the datasets' shapes. The checks that need the arrays' values (finite
    numbers, frames, contact indices and arc lengths, offsets in between) are left to :func:`read_stage`,
    and so is the size of the file against this machine's memory (nothing large is read here).

    Raises
    ------
    InputError
        Whatever :func:`read_stage` refuses that the metadata shows, with the same sentence.
    """
    path = Path(path)
    with _opened(path) as fh:
        _, members = _read_members(fh, path)
        attrs = {name: _group_attrs(fh[name], name, path)[0] for name in members}
        shapes = {name: {key: d.shape for key, d in datasets.items() if key in LAYOUT[name]}
                  for name, datasets in members.items()}
        ends = {name: _ends(datasets["offsets"]) for name, datasets in members.items() if "offsets" in datasets}
    _check_layout(path, shapes, attrs, ends)


def _ends(offsets) -> tuple[int, int] | None:
    """The first and last entries of an ``offsets`` array or h5py dataset (reading two numbers), or None if
    it is empty."""
    return (int(offsets[0]), int(offsets[-1])) if len(offsets) else None


def _schema_version(value, path: Path) -> int:
    value = _attr(value)
    if isinstance(value, str):
        value = value.strip()
        if value.isdigit():
            return int(value)
    elif isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        return int(value)
    raise InputError(f"has a schema_version attribute that is not an integer ({value!r})", path)


def _json_attr(h5, key: str, default: str, path: Path, where: str):
    text = _attr(h5.attrs.get(key, default))
    try:
        return json.loads(text)
    except (TypeError, ValueError):
        raise InputError(f"{where} attribute {key} is not JSON", path) from None


def _read_members(fh, path: Path) -> tuple[int, dict]:
    """The schema version and every group's datasets (h5py objects, not read), after the root attributes'
    checks and each dataset's dtype and dimensions (:func:`_group_members`)."""
    if _attr(fh.attrs.get("format")) != FORMAT:
        raise InputError("is an HDF5 file but not a hairinv stage file", path)
    version = _schema_version(fh.attrs.get("schema_version", 0), path)
    if version > SCHEMA_VERSION:
        raise InputError(
            f"was written with stage-file schema {version}; this hairinv reads schema {SCHEMA_VERSION} "
            "(upgrade hairinv)",
            path,
        )
    if "command" in fh.attrs:
        check_command_record(_json_attr(fh, "command", "{}", path, "the root"), path)
    members = {}
    for name in PIPELINE:
        if name not in fh:
            continue
        h5 = fh[name]
        if not isinstance(h5, h5py.Group):
            raise InputError(f"/{name} is not an HDF5 group", path)
        members[name] = _group_members(h5, name, path)
    if not members:
        raise InputError("holds no hairinv stage group", path)
    return version, members


def _group_attrs(h5, name: str, path: Path) -> tuple[dict, dict, list]:
    """A group's attributes (but ``config`` and ``inputs``), ``config`` and ``inputs``, the last two checked."""
    attrs = {key: _attr(h5.attrs[key]) for key in h5.attrs.keys() if key not in ("config", "inputs")}
    config = _json_attr(h5, "config", "{}", path, f"/{name}")
    inputs = _json_attr(h5, "inputs", "[]", path, f"/{name}")
    _check_provenance(name, config, inputs, path)
    return attrs, config, inputs


def _read(fh, path: Path) -> StageFile:
    version, members = _read_members(fh, path)
    # refuse what would not fit in memory before reading any of it (a dataset may declare any size and
    # store nothing: HDF5 fills it in on read)
    declared = {f"/{name}/{key}": (0 if d.shape is None else math.prod(d.shape)) * d.dtype.itemsize
                for name, datasets in members.items() for key, d in datasets.items()}
    memory = _memory_bytes()
    if memory is not None and sum(declared.values()) > memory:
        largest = max(declared, key=declared.get)
        raise InputError(f"would take {sum(declared.values()) / 1e9:.3g} GB of memory to read (its {largest} "
                         f"declares {declared[largest] / 1e9:.3g} GB), more than this machine's "
                         f"{memory / 1e9:.3g} GB", path)
    groups = {}
    for name, datasets in members.items():
        data = {key: _normalise(name, key, d[()], path) for key, d in datasets.items()}
        groups[name] = Group(name, data, *_group_attrs(fh[name], name, path))
    return StageFile(path, groups, str(_attr(fh.attrs.get("producer", ""))), version)


def _group_members(h5, name: str, path: Path) -> dict:
    """The datasets of one group (h5py objects, not read yet), their dtype and dimensions checked against
    :data:`LAYOUT`."""
    found = {}
    for key in h5.keys():
        obj = h5.get(key)
        if isinstance(obj, h5py.Dataset):
            found[key] = obj
        elif key in LAYOUT[name]:
            raise InputError(f"/{name}/{key} is not a dataset", path)
    for key in REQUIRED[name]:
        if key not in found:
            raise InputError(f"group /{name} lacks the dataset {key!r}", path)
    for key, (kind, dims) in LAYOUT[name].items():
        if key not in found:
            continue
        d = found[key]
        if d.shape is None:
            raise InputError(f"/{name}/{key} holds no data (an HDF5 null dataspace)", path)
        if d.dtype.kind not in ((kind, "u") if kind == "i" else (kind,)):
            raise InputError(f"/{name}/{key} has dtype {d.dtype}, expected {'float' if kind == 'f' else 'integer'}",
                             path)
        if len(d.shape) != len(dims) or any(isinstance(w, int) and w != s for w, s in zip(dims, d.shape)):
            raise InputError(f"/{name}/{key} has shape {d.shape}, expected ({', '.join(map(str, dims))})", path)
    return found


def _normalise(name: str, key: str, value: np.ndarray, path: Path) -> np.ndarray:
    """A dataset of :data:`LAYOUT` as the code uses it: native float64, or int64 (values checked to fit)."""
    if key not in LAYOUT[name]:
        return value
    if LAYOUT[name][key][0] == "f":
        return np.ascontiguousarray(value, dtype=np.float64)
    if value.dtype.kind == "u" and value.size and int(value.max()) > np.iinfo(np.int64).max:
        raise InputError(f"/{name}/{key} holds {int(value.max())}, too large for an index", path)
    return np.ascontiguousarray(value, dtype=np.int64)


def _check_provenance(name: str, config, inputs, path: Path) -> None:
    if not isinstance(config, dict):
        raise InputError(f"/{name} attribute config is not a JSON object", path)
    if not isinstance(inputs, list) or not all(isinstance(r, dict) for r in inputs):
        raise InputError(f"/{name} attribute inputs is not a JSON list of records", path)
    for record in inputs:
        for key in ("name", "path", "abspath", "sha256"):
            if key in record and not isinstance(record[key], str):
                raise InputError(f"/{name} attribute inputs has a {key} that is not a string", path)


def check_command_record(record, path) -> None:
    """Refuse a root ``command`` record (docs/stage-files.md) that is not shaped as hairinv writes it."""
    problem = None
    if not isinstance(record, dict) or not isinstance(record.get("subcommand"), str):
        problem = "is not a JSON object with a subcommand"
    elif not isinstance(record.get("inputs", []), list) or not all(
            r is None or (isinstance(r, dict) and isinstance(r.get("name"), str) and isinstance(r.get("sha256"), str))
            for r in record.get("inputs", [])):
        problem = "has inputs that are not records with a name and a sha256"
    elif not isinstance(record.get("settings", {}), dict) or not all(
            isinstance(v, dict) for v in record.get("settings", {}).values()):
        problem = "has settings that are not sections of values"
    elif not isinstance(record.get("options", {}), dict):
        problem = "has options that are not a JSON object"
    if problem:
        raise InputError(f"has a command attribute that {problem}", path)


# --------------------------------------------------------------------------- consistency


def check_consistency(stage: StageFile) -> None:
    """Refuse a stage file whose groups disagree with one another or with docs/stage-files.md.

    Run by :func:`read_stage` on every file hairinv reads, before any computation. It checks that:

    - the groups a group refers to are there (``/model`` and ``/frames`` need ``/helices``; the strand
      indices of ``/contacts`` are checked against ``/helices`` or ``/curves`` where the file has them);
    - offsets are CSR (start at 0, never decrease) and end at the length of the arrays they index; every
      strand has an element or more in ``/helices`` (a strand of ``/curves`` with fewer than 2 points is
      dropped, and counted, where the groom is read);
    - ``/curves`` and ``/helices`` hold the same number of strands, and every dataset has the size of the
      counts it is defined by (strands, points, elements, contacts, frames: :data:`LAYOUT`);
    - float datasets are finite (``/model/stability_margin`` and ``/contacts/mu`` may be ``+inf``, as
      documented: :data:`MAY_BE_INFINITE`);
    - element lengths are > 0; frames are orthonormal (:data:`FRAME_TOLERANCE`), rod frames right-handed;
      ``/frames/body_transform`` is rigid; ``/frames/time`` increases;
    - contacts: side A is a strand in ``[0, S)``; side B is ``-1`` (the body) or a strand in ``(A, S)``
      (A is the lower index); arc lengths lie on their strands of ``/helices`` (within
      :data:`ARC_TOLERANCE_M` plus :data:`ARC_TOLERANCE_RELATIVE` of the length; not checked in a file
      without ``/helices``), and are 0 on the body's side; ``mu >= 0`` (``+inf`` allowed: a sticking contact);
    - ``/model``: weights >= 0, stiffening factors > 0, and the attributes hairinv reads (:data:`ATTRS`)
      of the right type and range.

    The checks that need no array but the ends of the offsets come first (:func:`_check_layout`);
    :func:`check_metadata` runs those alone.
    """
    path, groups = stage.path, stage.groups
    shapes = {name: {key: np.shape(v) for key, v in g.datasets.items() if key in LAYOUT[name]}
              for name, g in groups.items()}
    ends = {name: _ends(g["offsets"]) for name, g in groups.items() if "offsets" in g.datasets}
    counts = _check_layout(path, shapes, {name: g.attrs for name, g in groups.items()}, ends)
    for name, group in groups.items():
        for key, value in group.datasets.items():
            if key in LAYOUT[name] and LAYOUT[name][key][0] == "f":
                _check_finite(path, name, key, value)
    if CURVES in groups:
        # strands of fewer than 2 points are kept: reading a groom drops them and says so
        _check_offsets(path, CURVES, groups[CURVES]["offsets"], len(groups[CURVES]["points"]), "points", "point", 0)
    if HELICES in groups:
        h = groups[HELICES]
        _check_offsets(path, HELICES, h["offsets"], len(h["length"]), "length", "element", 1)
    if FRAMES in groups and "offsets" in groups[FRAMES].datasets:
        f = groups[FRAMES]
        _check_offsets(path, FRAMES, f["offsets"], len(f["length"]), "length", "element", 1)
    if HELICES in groups:
        h = groups[HELICES]
        _check_positive(path, HELICES, "length", h["length"], "element lengths")
        _check_frames(path, HELICES, "frame0", h["frame0"], right_handed=True)
        if np.any(h["fit_error"] < 0):
            raise InputError("/helices/fit_error holds a negative distance", path)
    if CONTACTS in groups:
        # a /contacts group alone (written for another file's strands) is checked for everything but its
        # strands' count
        strands = counts["S"][0] if "S" in counts else np.iinfo(np.int64).max
        _check_contacts(path, groups[CONTACTS], groups.get(HELICES), strands)
    if MODEL in groups:
        _check_model(path, groups[MODEL])
    if FRAMES in groups:
        _check_run(path, groups[FRAMES])


def _check_layout(path, shapes: dict, attrs: dict, ends: dict) -> dict:
    """The checks of :func:`check_consistency` that need no array's values: the groups a group refers to, the
    attributes, and every dataset's shape against the counts (strands, points, elements, contacts, frames).

    Parameters
    ----------
    shapes : {group: {dataset of LAYOUT: shape}}
    attrs : {group: {attribute: value}} (without ``config`` and ``inputs``)
    ends : {group: (first, last) entry of its ``offsets``, or None where they are empty}

    Returns the counts: ``{symbol of LAYOUT: (count, what it is counted from)}``.
    """
    for name, needed in NEEDS.items():
        if name in shapes and needed not in shapes:
            raise InputError(f"has a /{name} group but no /{needed}: its arrays are sized by the elements of "
                             f"/{needed}", path)
    for name in shapes:
        _check_attrs(path, name, attrs[name])
    counts = {}
    if CURVES in shapes:
        _check_offset_ends(path, CURVES, ends[CURVES], shapes[CURVES]["points"][0], "points")
        counts["S"] = (shapes[CURVES]["offsets"][0] - 1, "strands (/curves/offsets)")
        counts["P"] = (ends[CURVES][1], "points (/curves/offsets)")
    if HELICES in shapes:
        h = shapes[HELICES]
        _check_offset_ends(path, HELICES, ends[HELICES], h["length"][0], "length")
        strands = h["offsets"][0] - 1
        if "S" in counts and counts["S"][0] != strands:
            raise InputError(f"holds {counts['S'][0]} strands in /curves but {strands} in /helices", path)
        counts["S"] = (strands, "strands (/helices/offsets)")
        counts["E"] = (ends[HELICES][1], "elements (/helices/offsets)")
    if CONTACTS in shapes:
        counts["C"] = (shapes[CONTACTS]["strand"][0], "contacts (/contacts/strand)")
    else:
        counts["C"] = (0, "contacts (the file has no /contacts group)")
    if FRAMES in shapes:
        f, trimmed = shapes[FRAMES], attrs[FRAMES].get("trimmed")
        counts["F"] = (f["time"][0], "frames (/frames/time)")
        requested = attrs[FRAMES].get("frames_requested")
        if requested is not None and requested < f["time"][0]:  # a count, checked above
            raise InputError(f"/frames attribute frames_requested is {requested}, fewer than the {f['time'][0]} "
                             "frames it holds", path)
        counts["Ef"] = counts["E"]
        if ("offsets" in f) != ("length" in f):
            raise InputError("/frames holds one of offsets and length without the other (a trimmed run stores both)",
                             path)
        if "offsets" in f:
            _check_offset_ends(path, FRAMES, ends[FRAMES], f["length"][0], "length")
            counts["Ef"] = (ends[FRAMES][1], "elements of the frames' strands (/frames/offsets)")
        # a shot's body: its own vertex and triangle counts
        counts["V"] = (f["body_vertices"][1] if len(f.get("body_vertices", ())) > 1 else 0,
                       "body vertices (/frames/body_vertices)")
        counts["T"] = (f["body_faces"][0] if "body_faces" in f else 0, "body triangles (/frames/body_faces)")
        if ("body_vertices" in f) != ("body_faces" in f):
            raise InputError("/frames holds one of body_vertices and body_faces without the other (a shot stores "
                             "both)", path)
        if isinstance(trimmed, (bool, np.bool_)) and bool(trimmed) != ("offsets" in f):
            raise InputError(f"/frames says trimmed = {bool(trimmed)} but "
                             f"{'holds no' if trimmed else 'holds its own'} offsets and length", path)
    for name, datasets in shapes.items():
        for key, shape in datasets.items():
            _check_size(path, name, key, shape, LAYOUT[name][key][1], counts)
    return counts


def _check_offset_ends(path, name, ends, rows: int, indexed: str) -> None:
    """``offsets`` start at 0 and end at ``rows``, the length of the array they index (from their ends)."""
    if ends is None or ends[0] != 0:
        raise InputError(f"/{name}/offsets is not a valid CSR offset array (it must start at 0 and never decrease)",
                         path)
    if ends[1] != rows:
        raise InputError(f"/{name}/offsets ends at {ends[1]}, but /{name}/{indexed} has {rows} rows", path)


def _check_offsets(path, name, offsets, rows: int, indexed: str, unit: str, least: int) -> None:
    if len(offsets) < 1 or offsets[0] != 0 or np.any(np.diff(offsets) < 0):
        raise InputError(f"/{name}/offsets is not a valid CSR offset array (it must start at 0 and never decrease)",
                         path)
    if offsets[-1] != rows:
        raise InputError(f"/{name}/offsets ends at {int(offsets[-1])}, but /{name}/{indexed} has {rows} rows", path)
    counts = np.diff(offsets)
    if np.any(counts < least):
        k = int(np.flatnonzero(counts < least)[0])
        n = int(counts[k])
        raise InputError(f"strand {k} has {n} {unit}{'' if n == 1 else 's'} by /{name}/offsets; a strand needs at "
                         f"least {least}", path)


def _check_size(path, name, key, shape, dims, counts) -> None:
    expected = []
    why = []
    for size, dim in zip(shape, dims):
        if isinstance(dim, int) or dim == "n":
            expected.append(str(size) if dim == "n" else str(dim))
            continue
        symbol, plus = (dim[:-2], 1) if dim.endswith("+1") else (dim, 0)
        count, what = counts[symbol]
        expected.append(str(count + plus))
        if size != count + plus:
            why.append(f"{symbol} = {count} {what}")
    if why:
        raise InputError(f"/{name}/{key} has shape {tuple(shape)}, expected ({', '.join(expected)}"
                         f"{',' if len(expected) == 1 else ''}): {'; '.join(why)}", path)


#: Float datasets that may hold ``+inf`` (docs/stage-files.md): a strand's stability margin where no motion is
#: left, and a friction coefficient of a sticking contact (infinite friction: the cone is the half-space
#: r_N >= 0, which the solvers handle).
MAY_BE_INFINITE = {(MODEL, "stability_margin"), (CONTACTS, "mu")}


#: The largest magnitude of the values of a float dataset, with its unit, beyond which a value is a
#: mistake rather than hair: positions and lengths within 10 km, curvatures and twists within 1e6 1/m (a
#: curl of radius 1 um, a hundredth of a hair's). Any other float dataset holds numbers within
#: :data:`MAGNITUDE`, so that their squares and products stay finite in the arithmetic that reads them.
DATASET_RANGE = {
    **{(group, key): (1e4, "m") for group, key in [
        (CURVES, "points"), (HELICES, "root"), (HELICES, "length"), (HELICES, "fit_error"), (CONTACTS, "s"),
        (CONTACTS, "point"), (CONTACTS, "gap"), (FRAMES, "root"), (FRAMES, "length"), (FRAMES, "displacement"),
        (FRAMES, "strand_displacement")]},
    **{(group, key): (1e6, "1/m") for group, key in [
        (HELICES, "omega"), (MODEL, "omega_rest"), (MODEL, "omega_target"), (MODEL, "omega_rest_stiffened"),
        (FRAMES, "omega")]},
}
MAGNITUDE = 1e100


def _check_finite(path, name, key, value) -> None:
    infinite = (name, key) in MAY_BE_INFINITE
    bad = (np.isnan(value) | (value == -np.inf)) if infinite else ~np.isfinite(value)
    if np.any(bad):
        where = np.unravel_index(int(np.flatnonzero(bad.ravel())[0]), value.shape)
        raise InputError(f"/{name}/{key}{list(map(int, where))} is {value[where]}: the dataset must hold "
                         f"{'no NaN and no -inf' if infinite else 'finite numbers'}", path)
    largest, unit = DATASET_RANGE.get((name, key), (MAGNITUDE, ""))
    bad = np.abs(np.where(np.isinf(value), 0.0, value)) > largest if infinite else np.abs(value) > largest
    if np.any(bad):
        where = np.unravel_index(int(np.flatnonzero(bad.ravel())[0]), value.shape)
        raise InputError(f"/{name}/{key}{list(map(int, where))} is {value[where]:g}{' ' + unit if unit else ''}: "
                         f"the dataset must hold numbers within +-{largest:g}{' ' + unit if unit else ''}", path)


def _check_positive(path, name, key, value, what: str) -> None:
    if np.any(value <= 0):
        k = int(np.flatnonzero(value <= 0)[0])
        raise InputError(f"/{name}/{key}[{k}] is {value[k]:g}: {what} must be > 0", path)


def _check_frames(path, name, key, frames, right_handed: bool) -> None:
    """Every 3x3 of ``frames`` (..., 3, 3) has orthonormal rows; with ``right_handed``, determinant +1."""
    R = frames.reshape(-1, 3, 3)
    if not len(R):
        return
    error = np.abs(R @ R.transpose(0, 2, 1) - np.eye(3)).max(axis=(1, 2))
    bad = np.flatnonzero(error > FRAME_TOLERANCE)
    if len(bad):
        where = list(map(int, np.unravel_index(int(bad[0]), frames.shape[:-2])))
        raise InputError(f"/{name}/{key}{where} is not an orthonormal frame (its rows are off by {error[bad[0]]:.2g}, "
                         f"more than {FRAME_TOLERANCE:g})", path)
    if right_handed:
        bad = np.flatnonzero(np.linalg.det(R) < 0)
        if len(bad):
            where = list(map(int, np.unravel_index(int(bad[0]), frames.shape[:-2])))
            raise InputError(f"/{name}/{key}{where} is a left-handed frame (rows t, n1, n2 need t x n1 = n2)", path)


def _check_contacts(path, contacts: Group, helices: Group | None, n_strands: int) -> None:
    strand, s = contacts["strand"], contacts["s"]
    where = f"/{HELICES}" if helices is not None else f"/{CURVES}"
    if len(strand) == 0:
        return
    a, b = strand[:, 0], strand[:, 1]
    bad = np.flatnonzero((a < 0) | (a >= n_strands))
    if len(bad):
        i = int(bad[0])
        raise InputError(f"/contacts/strand[{i}, 0] is {int(a[i])}, not a strand of the file: side A must be in "
                         f"[0, {n_strands}) ({n_strands} strands in {where})", path)
    bad = np.flatnonzero((b < -1) | (b >= n_strands))
    if len(bad):
        i = int(bad[0])
        raise InputError(f"/contacts/strand[{i}, 1] is {int(b[i])}: side B must be -1 (the body) or a strand in "
                         f"[0, {n_strands}) ({n_strands} strands in {where})", path)
    bad = np.flatnonzero((b >= 0) & (b <= a))
    if len(bad):
        i = int(bad[0])
        raise InputError(f"/contacts/strand[{i}] is ({int(a[i])}, {int(b[i])}): a hair-hair contact names the lower "
                         "strand on side A and another strand on side B", path)
    _check_frames(path, CONTACTS, "frame", contacts["frame"], right_handed=False)
    if np.any(contacts["mu"] < 0):
        i = int(np.flatnonzero(contacts["mu"] < 0)[0])
        raise InputError(f"/contacts/mu[{i}] is {contacts['mu'][i]:g}: a friction coefficient must be >= 0", path)
    if helices is None:  # the arc lengths belong to helices that are not in the file
        return
    offsets = helices["offsets"]
    total = np.add.reduceat(helices["length"], offsets[:-1]) if len(helices["length"]) else np.zeros(n_strands)
    for side, on in ((0, a), (1, b)):
        hair = on >= 0
        length = np.where(hair, total[np.where(hair, on, 0)], 0.0)
        tol = ARC_TOLERANCE_M + ARC_TOLERANCE_RELATIVE * length
        bad = np.flatnonzero((s[:, side] < -tol) | (s[:, side] > length + tol))
        if len(bad):
            i = int(bad[0])
            if not hair[i]:
                raise InputError(f"/contacts/s[{i}, 1] is {s[i, 1]:.6g} m on a body contact, where it must be 0",
                                 path)
            raise InputError(f"/contacts/s[{i}, {side}] is {s[i, side]:.6g} m, off strand {int(on[i])}, which runs "
                             f"from 0 to {length[i]:.6g} m along /helices", path)
    if "element" in contacts.datasets:
        _check_contact_elements(path, contacts["element"], a, b, s, helices)


def _check_contact_elements(path, element, a, b, s, helices: Group) -> None:
    """``/contacts/element``: each side's element is one of its strand's, and holds its arc length."""
    offsets, lengths = helices["offsets"], helices["length"]
    starts = np.concatenate([[0.0], np.cumsum(lengths)])
    for side, on in ((0, a), (1, b)):
        hair = on >= 0
        e = element[:, side]
        bad = np.flatnonzero(~hair & (e != -1))
        if len(bad):
            i = int(bad[0])
            raise InputError(f"/contacts/element[{i}, 1] is {int(e[i])} on a body contact, where it must be -1", path)
        first = np.where(hair, offsets[np.where(hair, on, 0)], 0)
        last = np.where(hair, offsets[np.where(hair, on, 0) + 1], 0)
        bad = np.flatnonzero(hair & ((e < first) | (e >= last)))
        if len(bad):
            i = int(bad[0])
            raise InputError(f"/contacts/element[{i}, {side}] is {int(e[i])}, not an element of strand {int(on[i])} "
                             f"(its elements are {int(first[i])} to {int(last[i]) - 1} in /helices)", path)
        # the arc length from the root lies on that element (up to the tolerance of arc lengths)
        k = np.where(hair, e, 0)
        lo = starts[k] - starts[first]
        hi = lo + lengths[k] if len(lengths) else lo
        tol = ARC_TOLERANCE_M + ARC_TOLERANCE_RELATIVE * hi
        bad = np.flatnonzero(hair & ((s[:, side] < lo - tol) | (s[:, side] > hi + tol)))
        if len(bad):
            i = int(bad[0])
            raise InputError(f"/contacts/element[{i}, {side}] is element {int(e[i])}, which runs from {lo[i]:.6g} to "
                             f"{hi[i]:.6g} m along strand {int(on[i])}, but /contacts/s[{i}, {side}] is "
                             f"{s[i, side]:.6g} m", path)


def _check_model(path, model: Group) -> None:
    weight = model["target_weight"]
    if np.any(weight < 0):
        i = int(np.flatnonzero(weight < 0)[0])
        raise InputError(f"/model/target_weight[{i}] is {weight[i]:g}: weights must be >= 0", path)
    if "stiffening" in model.datasets:
        _check_positive(path, MODEL, "stiffening", model["stiffening"], "stiffening factors")
    if ("stiffening" in model.datasets) != ("omega_rest_stiffened" in model.datasets):
        raise InputError("/model holds one of stiffening and omega_rest_stiffened without the other", path)


def _check_run(path, frames: Group) -> None:
    time = frames["time"]
    if np.any(np.diff(time) <= 0):
        i = int(np.flatnonzero(np.diff(time) <= 0)[0]) + 1
        raise InputError(f"/frames/time[{i}] is {time[i]:g} s, not after the frame before ({time[i - 1]:g} s)", path)
    if "length" in frames.datasets:
        _check_positive(path, FRAMES, "length", frames["length"], "element lengths")
    _check_frames(path, FRAMES, "frame0", frames["frame0"], right_handed=True)
    T = frames["body_transform"]
    if len(T):
        bottom = np.abs(T[:, 3, :] - np.array([0.0, 0.0, 0.0, 1.0])).max(axis=1)
        if np.any(bottom > 0):
            i = int(np.flatnonzero(bottom > 0)[0])
            raise InputError(f"/frames/body_transform[{i}] is not a rigid transform (its last row must be 0 0 0 1)",
                             path)
        _check_frames(path, FRAMES, "body_transform[:, :3, :3]", np.ascontiguousarray(T[:, :3, :3]),
                      right_handed=True)
    for key in ("displacement", "strand_displacement", "contact_count"):
        if key in frames.datasets and np.any(frames[key] < 0):
            raise InputError(f"/frames/{key} holds a negative value", path)
    # a shot's body and binding: triangles of existing vertices, roots on existing triangles
    if "body_faces" in frames.datasets:
        faces, n_vertices = frames["body_faces"], frames["body_vertices"].shape[1]
        if len(faces) and (faces.min() < 0 or faces.max() >= n_vertices):
            raise InputError(f"/frames/body_faces names vertices outside the {n_vertices} of /frames/body_vertices",
                             path)
    if "binding_triangle" in frames.datasets:
        if "body_faces" not in frames.datasets:
            raise InputError("/frames holds a binding without the body it binds to (body_vertices, body_faces)", path)
        triangle, n_faces = frames["binding_triangle"], len(frames["body_faces"])
        if len(triangle) and (triangle.min() < 0 or triangle.max() >= n_faces):
            raise InputError(f"/frames/binding_triangle names triangles outside the {n_faces} of /frames/body_faces",
                             path)


def _check_attrs(path, name, attrs: dict) -> None:
    for key, (kind, required) in ATTRS[name].items():
        if key not in attrs:
            if required:
                raise InputError(f"/{name} lacks the attribute {key!r}", path)
            continue
        value = attrs[key]
        number = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))
        if kind == "positive":
            ok, want = number and np.isfinite(value) and value > 0, "a finite number > 0"
        elif kind == "nonnegative":
            ok, want = number and np.isfinite(value) and value >= 0, "a finite number >= 0"
        elif kind == "count":
            ok, want = isinstance(value, (int, np.integer)) and not isinstance(value, bool) and value >= 0, \
                "an integer >= 0"
        elif kind == "material":
            problem = material_range_error(key, value, setting=False) if number else f"{key} is {value!r}; it must be a number"
            if problem is not None:
                raise InputError(f"/{name} attribute {problem}", path)
            continue
        elif kind in ("vector", "vector0"):
            v = np.asarray(value)
            ok = (v.shape == (3,) and v.dtype.kind in "iuf" and bool(np.all(np.isfinite(v)))
                  and (kind == "vector0" or bool(np.any(v != 0))))
            want = "3 finite numbers" + (", not all 0" if kind == "vector" else "")
            if ok and key == "gravity" and material_range_error(key, float(np.linalg.norm(v))) is not None:
                lo, hi, _ = MATERIAL_RANGE["gravity"]
                ok, want = False, want + f" of length 0 or from {lo:g} to {hi:g} m/s^2"
        elif kind == "str":
            ok, want = isinstance(value, str), "a string"
        elif kind == "bool":
            ok, want = isinstance(value, (bool, np.bool_)), "true or false"
        else:
            ok, want = isinstance(value, str) and value in kind, f"one of {', '.join(kind)}"
        if not ok:
            shown = np.asarray(value).tolist() if isinstance(value, np.ndarray) else value
            raise InputError(f"/{name} attribute {key} is {shown!r}; it must be {want}", path)
