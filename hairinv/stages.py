"""HDF5 stage files: the contract between subcommands (docs/stage-files.md).

Dataset and group names live here and nowhere else. Files are written
atomically (a temporary file in the destination folder, then a rename), so a
killed job leaves either the old file or the complete new one, never a part.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from . import __version__
from .atomic import atomic_path
from .errors import InputError

FORMAT = "hairinv"
SCHEMA_VERSION = 1

CURVES = "curves"
HELICES = "helices"
CONTACTS = "contacts"
MODEL = "model"
FRAMES = "frames"
PIPELINE = (CURVES, HELICES, CONTACTS, MODEL, FRAMES)

# Required datasets of each group: name -> (dtype kind, trailing shape).
# The leading dimension is checked against the group's own counts on read.
SCHEMA = {
    CURVES: {"points": ("f", (3,)), "offsets": ("i", ())},
    HELICES: {
        "root": ("f", (3,)),
        "frame0": ("f", (3, 3)),
        "offsets": ("i", ()),
        "length": ("f", ()),
        "omega": ("f", (3,)),
        "fit_error": ("f", (2,)),
    },
    CONTACTS: {
        "strand": ("i", (2,)),
        "s": ("f", (2,)),
        "point": ("f", (3,)),
        "frame": ("f", (3, 3)),
        "mu": ("f", ()),
    },
    MODEL: {
        "omega_rest": ("f", (3,)),
        "omega_target": ("f", (3,)),
        "target_weight": ("f", ()),
        "force": ("f", (3,)),
    },
    FRAMES: {
        "time": ("f", ()),
        "omega": ("f", (None, 3)),
        "root": ("f", (None, 3)),
        "frame0": ("f", (None, 3, 3)),
        "body_transform": ("f", (4, 4)),
    },
}


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
    """SHA-256 hex digest of a file's bytes."""
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
        return value.decode()
    if isinstance(value, np.generic):
        return value.item()
    return value


def read_stage(path) -> StageFile:
    """Read and validate a stage file.

    Raises
    ------
    InputError
        If the file is not a hairinv stage file, has a newer schema, or a
        group lacks a required dataset or has one of the wrong shape.
    """
    path = Path(path)
    try:
        fh = h5py.File(path, "r")
    except (OSError, ValueError):
        raise InputError("is not a readable HDF5 file", path) from None
    with fh:
        if _attr(fh.attrs.get("format")) != FORMAT:
            raise InputError("is an HDF5 file but not a hairinv stage file", path)
        version = int(_attr(fh.attrs.get("schema_version", 0)))
        if version > SCHEMA_VERSION:
            raise InputError(
                f"was written with stage-file schema {version}; this hairinv reads schema {SCHEMA_VERSION} "
                "(upgrade hairinv)",
                path,
            )
        groups = {}
        for name in PIPELINE:
            if name not in fh:
                continue
            h5 = fh[name]
            datasets = {key: h5[key][()] for key in h5.keys()}
            attrs = {key: _attr(h5.attrs[key]) for key in h5.attrs.keys() if key not in ("config", "inputs")}
            config = json.loads(_attr(h5.attrs.get("config", "{}")))
            inputs = json.loads(_attr(h5.attrs.get("inputs", "[]")))
            _validate_group(path, name, datasets)
            groups[name] = Group(name, datasets, attrs, config, inputs)
        if not groups:
            raise InputError("holds no hairinv stage group", path)
        return StageFile(path, groups, _attr(fh.attrs.get("producer", "")), version)


def _validate_group(path: Path, name: str, datasets: dict) -> None:
    for key, (kind, trailing) in SCHEMA[name].items():
        if key not in datasets:
            raise InputError(f"group /{name} lacks the dataset {key!r}", path)
        value = datasets[key]
        if value.dtype.kind not in (kind, "u" if kind == "i" else kind):
            raise InputError(f"/{name}/{key} has dtype {value.dtype}, expected {'float' if kind == 'f' else 'integer'}", path)
        shape = value.shape[1:]
        if len(shape) != len(trailing) or any(t is not None and t != s for t, s in zip(trailing, shape)):
            raise InputError(f"/{name}/{key} has shape {value.shape}, expected (n, {', '.join(str(t) for t in trailing)})", path)
        if not np.all(np.isfinite(value)) if kind == "f" else False:
            raise InputError(f"/{name}/{key} contains NaN or Inf", path)
    if "offsets" in datasets:
        offsets = datasets["offsets"]
        if len(offsets) < 1 or offsets[0] != 0 or np.any(np.diff(offsets) < 0):
            raise InputError(f"/{name}/offsets is not a valid CSR offset array", path)
