"""Readers and writers of hairstyle and body-mesh formats, registered by suffix.

Each module of this package handles one format and registers its functions
with the decorators of :mod:`hairinv.formats.base`; importing this package
imports them all. Use :func:`read_curves` and :func:`read_mesh`.
"""

from __future__ import annotations

from pathlib import Path

from ..errors import InputError
from .base import (
    CURVE_READERS,
    CURVE_WRITERS,
    MESH_READERS,
    RawCurves,
    curves_reader_for,
    curves_writer_for,
    mesh_reader_for,
)

# Each import registers its format.
from . import yuksel, usc, tressfx, obj, usd, hdf5, mesh  # noqa: E402,F401

__all__ = ["RawCurves", "read_curves", "read_mesh", "write_curves", "CURVE_READERS", "MESH_READERS", "CURVE_WRITERS"]


def _existing(path) -> Path:
    path = Path(path)
    if not path.exists():
        raise InputError("no such file", path)
    if path.is_dir():
        raise InputError("is a folder, not a file", path)
    if path.stat().st_size == 0:
        raise InputError("the file is empty", path)
    return path


def read_curves(path) -> RawCurves:
    """Read strand polylines from any registered hairstyle format."""
    path = _existing(path)
    return curves_reader_for(path)(path)


def read_mesh(path):
    """Read a body mesh (``trimesh.Trimesh``, triangles) from any registered format."""
    path = _existing(path)
    return mesh_reader_for(path)(path)


def write_curves(path, points, offsets, **options) -> None:
    """Write strand polylines in the format given by ``path``'s suffix."""
    path = Path(path)
    curves_writer_for(path)(path, points, offsets, **options)
