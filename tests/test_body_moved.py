"""A prepared body moved to a new pose answers as the moved mesh prepared afresh."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from hairinv.contacts.body import BodyMesh
from hairinv.dynamics.skin import MeshArrays


def _twisted(vertices: np.ndarray, amount: float) -> np.ndarray:
    """A non-rigid pose: twisted about y by ``amount`` rad per metre, stretched along y, bulged in x."""
    x, y, z = vertices.T
    angle = amount * y
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([(c * x - s * z) * (1.0 + 0.3 * y), 1.2 * y, s * x + c * z], axis=1)


@pytest.mark.parametrize("amount", [0.0, 2.0, 8.0])
def test_a_moved_body_answers_as_the_moved_mesh_prepared_afresh(rng, amount):
    """An ellipsoid cut open at its bottom (open edges), with every face's corners repeated (a UV-seamed OBJ:
    the welding matters) and one sliver, is prepared once and moved to twisted poses (a quarter to two turns
    over its height): signed distances, closest points and normals of points around it equal those of
    ``BodyMesh.from_mesh`` on the twisted mesh (another tree, built afresh), to round-off."""
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=0.1)
    vertices = sphere.vertices * [1.0, 1.5, 0.8]
    faces = sphere.faces[vertices[sphere.faces].mean(axis=1)[:, 1] > -0.12]  # open at the bottom
    seamed = vertices[faces].reshape(-1, 3)
    seamed_faces = np.arange(len(seamed)).reshape(-1, 3)
    sliver = np.array([[0, 1, 1]]) + 0  # a zero-area triangle on the first face's edge
    seamed_faces = np.concatenate([seamed_faces, sliver])
    rest = BodyMesh.from_mesh(MeshArrays(seamed, seamed_faces))
    assert any("degenerate" in note for note in rest.notes)
    posed = _twisted(seamed, amount)
    moved = rest.moved(posed)
    fresh = BodyMesh.from_mesh(MeshArrays(posed, seamed_faces))
    assert amount == 0.0 or not np.allclose(fresh.node_lo[:len(moved.node_lo)], moved.node_lo), \
        "the poses do not move the tree's boxes: nothing is tested"
    points = posed[rng.integers(0, len(posed), 2000)] + rng.normal(scale=0.02, size=(2000, 3))
    sd_m, c_m, n_m, _ = moved.closest(points)
    sd_f, c_f, n_f, _ = fresh.closest(points)
    assert np.abs(sd_m - sd_f).max() < 1e-12
    assert np.abs(c_m - c_f).max() < 1e-12
    # the pseudo-normal of the closest feature (where two features are equally close, either may answer)
    same = np.einsum("ij,ij->i", n_m, n_f) > 1.0 - 1e-9
    assert same.mean() > 0.99, same.mean()


def test_moving_takes_the_mesh_it_was_prepared_from():
    box = trimesh.creation.box()
    body = BodyMesh.from_mesh(box)
    with pytest.raises(ValueError):
        body.moved(box.vertices[:-1])
