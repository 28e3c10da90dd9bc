"""Body meshes: OBJ, PLY, STL, OFF and glTF (binary ``.glb`` or ``.gltf``), returned as unprocessed triangle
meshes. (Static USD meshes are read in :mod:`hairinv.formats.usd_anim`, beside the animated ones.)

OBJ files are parsed here (with :func:`hairinv.formats.obj.parse_obj`) rather
than by trimesh, because trimesh splits OBJ vertices along UV and normal
seams (ruby_head.obj would grow from 17892 to 23220 vertices); parsing
ourselves keeps one vertex per ``v`` line, in file order, so vertex indices
match the file. Every ``f`` of every group/object goes into the one mesh;
n-gons are fan-triangulated (n - 2 triangles), and their texture coordinates (``vt``) are kept per
triangle corner (``mesh.metadata[CORNER_UV]``) when every face has them. The other formats go through
``trimesh.load(path, force="mesh", process=False)``, which concatenates all
the geometry of a scene. Nothing is merged or removed in either case.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .._trimesh import load as load_trimesh
from ..errors import InputError
from .base import register_mesh_reader
from .obj import parse_obj


#: ``mesh.metadata`` key of the texture coordinates: (T, 3, 2) float64, u and v at each corner of each
#: triangle (corners, not vertices: a UV seam gives one vertex several), when the file has them for every face.
CORNER_UV = "hairinv_corner_uv"
#: ``mesh.metadata`` key of what the file states of its frame, where it does: ``{"scale_to_m": float or None,
#: "up": "x" | "y" | "z" or None, "by": why}`` (glTF: metres and +Y up, by its specification; USD:
#: ``metersPerUnit`` and ``upAxis``). For ``hairinv info``: the pipeline reads a body in the hair's unit and
#: axes unless the [body] settings say otherwise.
STATED_FRAME = "hairinv_stated_frame"


def _checked(vertices, faces, path: Path, corner_uv=None):
    trimesh = load_trimesh()

    vertices = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if len(faces) == 0:
        raise InputError("has no faces; a body mesh needs triangles", path)
    if not np.isfinite(vertices).all():
        raise InputError("has vertex coordinates that are NaN or Inf", path)
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    if corner_uv is not None:
        corner_uv = np.asarray(corner_uv, dtype=np.float64).reshape(len(faces), 3, 2)
        if np.isfinite(corner_uv).all():
            mesh.metadata[CORNER_UV] = corner_uv
    return mesh


@register_mesh_reader(".obj")
def read_obj_mesh(path: Path):
    """Read an OBJ body mesh.

    Returns
    -------
    trimesh.Trimesh
        ``vertices`` (V, 3) float64, one per ``v`` line in the file's units;
        ``faces`` (T, 3) int64, every ``f`` fan-triangulated.
    """
    path = Path(path)
    vertices, polygons, uvs, texture = parse_obj(path, "f", texture=True)
    faces, corners = [], []
    for (number, idx), tex in zip(polygons, texture):
        if len(idx) < 3:
            raise InputError(f"line {number} has a face with fewer than 3 vertices", path)
        faces.extend((idx[0], idx[k], idx[k + 1]) for k in range(1, len(idx) - 1))
        if tex is not None and corners is not None:
            corners.extend((tex[0], tex[k], tex[k + 1]) for k in range(1, len(tex) - 1))
        else:
            corners = None  # a face without texture coordinates: the mesh has none
    if not faces:
        hint = "; is it a hairstyle?" if parse_obj(path, "l")[1] else ""
        raise InputError(f"has no faces{hint}", path)
    corner_uv = uvs[np.asarray(corners, dtype=np.int64)] if corners and len(uvs) else None
    return _checked(vertices, faces, path, corner_uv)


@register_mesh_reader(".ply", ".stl", ".off", ".glb", ".gltf")
def read_trimesh(path: Path):
    """Read a PLY, STL, OFF or glTF (``.glb``, ``.gltf``) body mesh with trimesh (all parts concatenated).

    Returns
    -------
    trimesh.Trimesh
        ``vertices`` (V, 3) float64 in the file's units, ``faces`` (T, 3)
        int64, unprocessed.
    """
    trimesh = load_trimesh()

    path = Path(path)
    try:
        mesh = trimesh.load(str(path), force="mesh", process=False)
    except Exception as exc:  # trimesh raises many types for corrupt files
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(f"could not be read as a {path.suffix.lower()} mesh ({reason})", path) from None
    if not isinstance(mesh, trimesh.Trimesh):
        raise InputError(f"holds no triangle mesh (trimesh read a {type(mesh).__name__})", path)
    uv = getattr(mesh.visual, "uv", None)  # per vertex, for the formats trimesh reads them from
    corner_uv = np.asarray(uv)[np.asarray(mesh.faces)] if uv is not None and len(uv) == len(mesh.vertices) else None
    checked = _checked(mesh.vertices, mesh.faces, path, corner_uv)
    if path.suffix.lower() in (".glb", ".gltf"):
        checked.metadata[STATED_FRAME] = {"scale_to_m": 1.0, "up": "y", "by": "glTF's specification"}
    return checked


def triangle_mesh(vertices, faces, path: Path, stated: dict | None = None):
    """A body mesh of ``vertices`` (V, 3) and ``faces`` (T, 3) read by another module, checked as every reader's
    (faces present, coordinates finite); ``stated``: what the file states of its frame (:data:`STATED_FRAME`)."""
    mesh = _checked(vertices, faces, path)
    if stated is not None:
        mesh.metadata[STATED_FRAME] = stated
    return mesh
