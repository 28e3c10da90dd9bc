"""Root UVs: the body's texture coordinates where each strand's root meets it (USD ``groom_root_uv``).

The body is given texture coordinates that are an affine function of position, ``uv = A x + b``. Linear
interpolation over a planar triangle reproduces an affine function exactly, so at any point of the surface
the interpolated UV is ``A x + b`` to round-off, and at a root a distance ``d`` off the surface it is within
``|A| d`` of ``A x_root + b``. Checked on points placed on the surface, through the OBJ reader (texture
indices per face corner, quads fan-triangulated, negative indices, a mirrored body) and end to end through
``detect`` and ``hairinv export``.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from pxr import Usd, UsdGeom

from conftest import ROUNDOFF, SAMPLES, hairinv
from hairinv.config import BodySettings
from hairinv.contacts.body import texture_coordinates
from hairinv.formats import read_mesh
from hairinv.formats.mesh import CORNER_UV
from hairinv.groom import body_to_groom, load_body

A = np.array([[2.0, 0.0, 0.5], [0.0, 1.5, -0.25]])
B = np.array([0.5, -1.6])


def affine(x: np.ndarray) -> np.ndarray:
    return x @ A.T + B


def write_obj_with_uv(path, vertices, faces, corner_uv, negative=False) -> None:
    """One ``vt`` per face corner (every corner its own texture vertex, as across a seam)."""
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in np.asarray(vertices, dtype=float).tolist()]
    for t, face in enumerate(faces):
        for u, v in np.asarray(corner_uv[t], dtype=float).tolist():
            lines.append(f"vt {u!r} {v!r}")
        if negative:  # relative indices: -1 is the last vt (and v) defined so far
            refs = [f"{int(k) - len(vertices)}/{c - 3}" for c, k in enumerate(face)]
        else:
            refs = [f"{int(k) + 1}/{3 * t + c + 1}" for c, k in enumerate(face)]
        lines.append("f " + " ".join(refs))
    path.write_text("\n".join(lines) + "\n")


@pytest.fixture(scope="module")
def body():
    return trimesh.load(SAMPLES / "body.obj", process=False)


def surface_points(mesh, n=200, seed=3):
    rng = np.random.default_rng(seed)
    faces = rng.choice(len(mesh.faces), n)
    w = rng.dirichlet(np.ones(3), n)
    return np.einsum("nk,nkj->nj", w, np.asarray(mesh.vertices)[np.asarray(mesh.faces)[faces]])


@pytest.mark.parametrize("negative", [False, True], ids=["indices", "negative-indices"])
def test_uv_on_the_surface_is_the_affine_map(tmp_path, body, negative):
    path = tmp_path / "body_uv.obj"
    vertices, faces = np.asarray(body.vertices), np.asarray(body.faces)
    write_obj_with_uv(path, vertices, faces, affine(vertices[faces]), negative)
    mesh = read_mesh(path)
    assert mesh.metadata[CORNER_UV].shape == (len(faces), 3, 2)
    points = surface_points(mesh)
    uv, distance = texture_coordinates(mesh, points)
    assert distance.max() < 1e-12
    np.testing.assert_allclose(uv, affine(points), atol=1e3 * ROUNDOFF)


def test_quads_are_fan_triangulated_with_their_texture_corners(tmp_path):
    """A unit square as one quad with UVs at its corners: any point of it gets its own (x, y) back."""
    path = tmp_path / "quad.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3 4/4\n")
    mesh = read_mesh(path)
    points = np.array([[0.2, 0.7, 0.0], [0.9, 0.1, 0.0], [0.5, 0.5, 0.0]])
    uv, _ = texture_coordinates(mesh, points)
    np.testing.assert_allclose(uv, points[:, :2], atol=ROUNDOFF)


def test_a_body_without_texture_coordinates_has_none(tmp_path):
    path = tmp_path / "mixed.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nf 1/1 2/2 3/3\nf 1 3 4\n")
    assert texture_coordinates(read_mesh(path), np.zeros((1, 3))) is None
    assert texture_coordinates(read_mesh(SAMPLES / "body.obj"), np.zeros((1, 3))) is None


def test_a_mirrored_body_keeps_each_corner_its_uv(tmp_path, body):
    """--body-flip x turns the triangles' winding back; the texture corners must turn with them: a point
    mirrored with the body keeps its UV."""
    path = tmp_path / "body_uv.obj"
    vertices, faces = np.asarray(body.vertices), np.asarray(body.faces)
    write_obj_with_uv(path, vertices, faces, affine(vertices[faces]))
    mirror, _ = body_to_groom(BodySettings(flip="x"), 1.0, (0.0, 1.0, 0.0), "")
    mesh = load_body(path, mirror)
    points = surface_points(read_mesh(path))
    uv, distance = texture_coordinates(mesh, points * [-1.0, 1.0, 1.0])
    assert distance.max() < 1e-12
    np.testing.assert_allclose(uv, affine(points), atol=1e3 * ROUNDOFF)


def test_usd_export_carries_the_root_uv(tmp_path, body):
    """End to end: detect against a body with texture coordinates, export USD: one UV per strand, within
    |A| d of the affine map at the root (d: the root's distance from the surface)."""
    vertices, faces = np.asarray(body.vertices), np.asarray(body.faces)
    write_obj_with_uv(tmp_path / "body_uv.obj", vertices, faces, affine(vertices[faces]))
    result = hairinv(tmp_path, "detect", SAMPLES / "wavy.h5", "body_uv.obj", "--guides", "4", "-o", "d.h5")
    assert result.returncode == 0, result.stderr
    out = hairinv(tmp_path, "export", "d.h5", "-o", "d.usda")
    assert out.returncode == 0, out.stderr
    assert "groom_root_uv from the body's texture coordinates" in out.stdout
    stage = Usd.Stage.Open(str(tmp_path / "d.usda"))
    hair = UsdGeom.BasisCurves(stage.GetPrimAtPath("/Root/Hair"))
    primvar = UsdGeom.PrimvarsAPI(hair.GetPrim()).GetPrimvar("groom_root_uv")
    assert primvar.GetInterpolation() == UsdGeom.Tokens.uniform
    uv = np.array(primvar.Get(), dtype=np.float64)
    counts = np.array(hair.GetCurveVertexCountsAttr().Get())
    points = np.array(hair.GetPointsAttr().Get(), dtype=np.float64) * UsdGeom.GetStageMetersPerUnit(stage)
    roots = points[np.concatenate([[0], np.cumsum(counts)[:-1]])]
    assert uv.shape == (len(counts), 2)
    distance = np.abs(trimesh.proximity.signed_distance(body, roots))
    bound = np.linalg.norm(A, 2) * distance + 1e-6  # float32 storage of the UVs and points
    assert np.all(np.linalg.norm(uv - affine(roots), axis=1) <= bound)
    assert distance.max() < 0.02  # the roots do lie on the body (the bound is not vacuous)
