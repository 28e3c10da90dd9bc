"""Containers and registries shared by every format module.

A reader turns one file into a :class:`RawCurves` (strand polylines in the
file's own units and axes) or a :class:`trimesh.Trimesh` body, and raises
:class:`hairinv.errors.InputError` naming the file, and the strand where it
applies, for anything it cannot read. Readers never rescale or reorient:
units and axes are applied afterwards by :mod:`hairinv.groom`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from .. import atomic
from ..errors import InputError

__all__ = [
    "RawCurves",
    "register_curves_reader",
    "register_mesh_reader",
    "register_curves_writer",
    "curves_reader_for",
    "mesh_reader_for",
    "curves_writer_for",
    "check_strands",
    "write_atomic",
    "CURVE_READERS",
    "MESH_READERS",
    "CURVE_WRITERS",
    "ANIMATED_READERS",
    "SEQUENCE",
    "register_animated_reader",
    "animated_reader_for",
]


@dataclass
class RawCurves:
    """Strand polylines as stored in a file.

    Attributes
    ----------
    points : (P, 3) float64
        Vertices, strand after strand, root first, in the file's units.
    offsets : (S + 1,) int64
        CSR offsets: strand ``s`` owns ``points[offsets[s]:offsets[s+1]]``.
    format : str
        Short name of the format, e.g. ``"tressfx-v4"``.
    up : str or None
        The file's own up axis (``"y"`` or ``"z"``) when the format or file
        states one, else None (the importer decides and says so).
    scale_to_m : float or None
        Metres per file unit when the file states it (USD ``metersPerUnit``,
        hairinv HDF5), else None.
    extras : dict
        Optional per-strand or per-point arrays the format carries
        (``thickness``, ``color``, ``pinned_tip`` ...), kept for export.
    """

    points: np.ndarray
    offsets: np.ndarray
    format: str
    up: str | None = None
    scale_to_m: float | None = None
    extras: dict = field(default_factory=dict)

    @property
    def n_strands(self) -> int:
        return int(len(self.offsets) - 1)


CurvesReader = Callable[[Path], RawCurves]
MeshReader = Callable[[Path], "object"]
CurvesWriter = Callable[..., None]

CURVE_READERS: dict[str, CurvesReader] = {}
MESH_READERS: dict[str, MeshReader] = {}
CURVE_WRITERS: dict[str, CurvesWriter] = {}
#: Animated-body readers: key -> (probe, reader). ``probe(path) -> bool`` says whether the file animates a body;
#: ``reader(path, fps=None) -> AnimatedBody``. The key is a suffix, or :data:`SEQUENCE` for a folder or a
#: ``body.####.obj`` pattern of per-frame meshes.
ANIMATED_READERS: dict[str, tuple[Callable[[Path], bool], Callable[..., object]]] = {}
SEQUENCE = "sequence"


def _register(table: dict, suffixes: tuple[str, ...]):
    def decorate(fn):
        for suffix in suffixes:
            table[suffix.lower()] = fn
        return fn

    return decorate


def register_curves_reader(*suffixes: str):
    """Register ``fn(path) -> RawCurves`` for file suffixes such as ``".hair"``."""
    return _register(CURVE_READERS, suffixes)


def register_mesh_reader(*suffixes: str):
    """Register ``fn(path) -> trimesh.Trimesh`` for body-mesh file suffixes."""
    return _register(MESH_READERS, suffixes)


def register_curves_writer(*suffixes: str):
    """Register ``fn(path, points, offsets, **options)`` writing strands to a file."""
    return _register(CURVE_WRITERS, suffixes)


def register_animated_reader(*keys: str, probe: Callable[[Path], bool]):
    """Register ``fn(path, fps=None) -> AnimatedBody`` for suffixes (or :data:`SEQUENCE`), with ``probe(path)``
    telling whether a file of that suffix holds an animated body (a GLB may hold a static one)."""

    def decorate(fn):
        for key in keys:
            ANIMATED_READERS[key.lower()] = (probe, fn)
        return fn

    return decorate


def _animated_key(path: Path) -> str:
    path = Path(path)
    return SEQUENCE if path.is_dir() or "#" in path.name else _suffix(path)


def animated_reader_for(path: Path):
    """The ``(probe, reader)`` pair of an animated-body path, or None when no animated reader takes it."""
    return ANIMATED_READERS.get(_animated_key(path))


def _suffix(path: Path) -> str:
    return path.suffix.lower()


def _lookup(table: dict, path: Path, what: str):
    path = Path(path)
    fn = table.get(_suffix(path))
    if fn is None:
        known = ", ".join(sorted(table))
        raise InputError(
            f"unknown {what} file type {path.suffix or '(no suffix)'!r}; known types are {known}", path
        )
    return fn


def curves_reader_for(path: Path) -> CurvesReader:
    return _lookup(CURVE_READERS, path, "hairstyle")


def mesh_reader_for(path: Path) -> MeshReader:
    return _lookup(MESH_READERS, path, "body mesh")


def curves_writer_for(path: Path) -> CurvesWriter:
    return _lookup(CURVE_WRITERS, path, "hairstyle output")


def check_strands(points: np.ndarray, offsets: np.ndarray, path: Path, fmt: str) -> RawCurves:
    """Validate decoded strands and wrap them in a :class:`RawCurves`.

    Checks shapes, CSR offsets and that every coordinate is finite; a NaN or
    Inf names the first strand that has one.
    """
    points = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    offsets = np.ascontiguousarray(offsets, dtype=np.int64)
    if offsets.ndim != 1 or len(offsets) < 1 or offsets[0] != 0:
        raise InputError("strand offsets are malformed", path)
    if len(offsets) == 1:
        raise InputError("the file holds no strands", path)
    if np.any(np.diff(offsets) < 0) or offsets[-1] != len(points):
        raise InputError("strand vertex counts do not add up to the number of points", path)
    bad = ~np.isfinite(points).all(axis=1)
    if bad.any():
        first = int(np.argmax(bad))
        strand = int(np.searchsorted(offsets, first, side="right") - 1)
        raise InputError("vertex coordinates contain NaN or Inf", path, strand=strand)
    return RawCurves(points=points, offsets=offsets, format=fmt)


def write_atomic(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` with the atomic writer (:mod:`hairinv.atomic`): the old file or the new one."""
    path = Path(path)
    try:
        atomic.write_bytes(path, data)
    except OSError as exc:
        raise InputError(f"cannot be written ({exc.strerror or exc})", path) from None
