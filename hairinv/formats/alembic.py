"""Alembic (``.abc``) point caches: recognised as animated bodies and refused with the USD route.

No maintained Alembic wheel installs for this Python (the Alembic project ships no Python package; the
bindings on PyPI are unofficial), so an ``.abc`` body is refused with one sentence saying how to bring it in
as USD, which hairinv reads (:mod:`hairinv.formats.usd_anim`).
"""

from __future__ import annotations

from pathlib import Path

from ..errors import InputError
from .base import register_animated_reader

__all__ = ["read_alembic"]


@register_animated_reader(".abc", probe=lambda path: True)
def read_alembic(path: Path, fps: float | None = None):
    raise InputError("is an Alembic cache, which hairinv does not read; export it as USD (a UsdGeomMesh with "
                     "time-sampled points, e.g. from Blender, Houdini or Maya) and give the .usd file", path)
