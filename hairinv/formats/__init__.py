"""Readers and writers of hairstyle and body-mesh formats, registered by suffix.

Each module of this package handles one format and registers its functions
with the decorators of :mod:`hairinv.formats.base`; importing this package
imports them all. Use :func:`read_curves` and :func:`read_mesh`; for a body that moves (a skinned glTF, a
USD point cache or skeleton, a mesh sequence), :func:`is_animated_body` and :func:`read_animated_body`.
"""

from __future__ import annotations

from pathlib import Path

from ..errors import InputError, in_file
from .base import (
    CURVE_READERS,
    CURVE_WRITERS,
    MESH_READERS,
    ANIMATED_READERS,
    RawCurves,
    animated_reader_for,
    curves_reader_for,
    curves_writer_for,
    mesh_reader_for,
)

# Each import registers its format.
from . import yuksel, usc, tressfx, obj, usd, hdf5, mesh  # noqa: E402,F401
from . import gltf_anim, usd_anim, sequence, alembic  # noqa: E402,F401
from .animated import AnimatedBody  # noqa: E402

__all__ = ["RawCurves", "AnimatedBody", "read_curves", "read_mesh", "write_curves", "is_animated_body",
           "read_animated_body", "CURVE_READERS", "MESH_READERS", "CURVE_WRITERS", "ANIMATED_READERS"]


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
    """Read a body mesh (``trimesh.Trimesh``, triangles) from any registered format; of a sequence of frames
    (a folder, a ``body.####.obj`` pattern), its first frame."""
    path = Path(path)
    if path.is_dir() or "#" in path.name:
        import trimesh

        body = read_animated_body(path)
        return trimesh.Trimesh(body.vertices, body.faces, process=False)
    path = _existing(path)
    return mesh_reader_for(path)(path)


def is_animated_body(path) -> bool:
    """Whether ``path`` names an animated body: a folder or ``body.####.obj`` pattern of frames, or a file whose
    reader finds motion in it (a GLB with a skin or animation, a USD stage with time samples, an Alembic cache).
    A file of one of those kinds that cannot be read at all raises :class:`InputError` naming it."""
    path = Path(path)
    entry = animated_reader_for(path)
    if entry is None:
        return False
    if path.is_dir() or "#" in path.name:
        return entry[0](path)
    return path.is_file() and path.stat().st_size > 0 and entry[0](path)


def read_animated_body(path, fps: float | None = None) -> AnimatedBody:
    """Read an animated body (:class:`AnimatedBody`) from any registered kind; ``fps`` states a sequence's frame
    rate (and overrides a file's)."""
    path = Path(path)
    entry = animated_reader_for(path)
    if not (path.is_dir() or "#" in path.name):
        path = _existing(path)
    if entry is None:
        known = ", ".join(sorted(k for k in ANIMATED_READERS if k.startswith(".")))
        raise InputError(f"is not an animated body; known kinds are {known}, a folder of frames or a "
                         "body.####.obj pattern", path)
    with in_file(path):  # the body's own checks name the file too
        return entry[1](path, fps=fps)


def write_curves(path, points, offsets, **options) -> None:
    """Write strand polylines in the format given by ``path``'s suffix."""
    path = Path(path)
    curves_writer_for(path)(path, points, offsets, **options)
