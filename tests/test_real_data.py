"""Every real third-party hair and mesh file reads with the counts and bounds its README states.

The data (read-only) lives in ``/work/shared/data/real``; set ``HAIRINV_REAL_DATA``
to read it from elsewhere. Numbers below come from that folder's README.md and
are compared to the rounding the README uses.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from hairinv.formats import read_curves, read_mesh

REAL = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "real"
if not REAL.is_dir():
    REAL = Path(os.environ.get("HAIRINV_REAL_DATA", str(REAL)))
if not REAL.is_dir():
    pytest.skip(
        f"real data folder not found at {REAL} (set HAIRINV_REAL_DATA to the folder holding sintel/, ruby/, ponytail/)",
        allow_module_level=True,
    )

# file: (format, strands, points per strand, bbox ((xmin, xmax), (ymin, ymax), (zmin, zmax)) or None, bbox tolerance,
#        pinned_tip (bothEndsImmovable) or None for v4)
HAIR = {
    "sintel/GEO-sintel_hair_emit.001-sintel_hair.tfx": (
        "tressfx-v4", 228, 32, ((-10.62, 9.83), (20.72, 47.69), (-12.95, 11.66)), 0.006, None),
    "ruby/ruby_short_hair_16_guide.tfx": (
        "tressfx-v2", 1867, 16, ((-46.2, 50.0), (5.6, 101.7), (-51.4, 55.2)), 0.06, False),
    "ruby/ruby_long_hair_16_guide.tfx": (
        "tressfx-v2", 3000, 16, ((-55.7, 54.8), (-46.4, 87.4), (-58.6, 33.8)), 0.06, False),
    "ponytail/hair_free_16_guide.tfx": (
        "tressfx-v2", 3942, 16, ((-32.4, 32.9), (16.9, 123.7), (-46.6, 36.3)), 0.06, False),
    "ponytail/hair_front_16_guide.tfx": (
        "tressfx-v2", 93, 16, ((-25.4, 29.3), (50.7, 113.2), (16.2, 35.8)), 0.06, False),
    "ponytail/hair_pulled_16_guide.tfx": (
        "tressfx-v2", 517, 16, ((-22.6, 20.7), (62.4, 103.9), (-44.5, -17.5)), 0.06, True),
    "ponytail/hair_tail_16_guide.tfx": (
        "tressfx-v2", 474, 16, ((-4.5, 12.3), (-3.1, 83.2), (-78.0, -45.2)), 0.06, False),
    "ponytail/tressfx3/front_top.tfx": ("tressfx-v3", 876, 16, None, 0, False),
    "ponytail/tressfx3/side.tfx": ("tressfx-v3", 3066, 16, None, 0, False),
    "ponytail/tressfx3/back.tfx": ("tressfx-v3", 517, 16, None, 0, True),
    "ponytail/tressfx3/tail.tfx": ("tressfx-v3", 255, 16, None, 0, True),
}  # fmt: skip

# file: (vertices, triangles, bbox or None, boundary edges, non-manifold edges)
MESHES = {
    "sintel/sintel.obj": (3046, 5952, ((-19.74, 19.74), (2.54, 45.52), (-10.14, 11.88)), 148, 0),
    "sintel/sintel_eyeballs.obj": (708, 1408, None, 0, 0),
    "ruby/ruby_head.obj": (17892, None, ((-148.3, 145.6), (-120.7, 93.1), (-46.4, 60.1)), 949, 28),
    "ponytail/head_max4.obj": (9693, 18574, ((-84.8, 82.0), (-50.4, 120.0), (-47.1, 46.7)), 850, 94),
}  # fmt: skip


@pytest.fixture(scope="module")
def hair():
    cache = {}

    def get(name):
        if name not in cache:
            cache[name] = read_curves(REAL / name)
        return cache[name]

    return get


@pytest.mark.parametrize("name", sorted(HAIR))
def test_hair_counts_bbox_flags(hair, name):
    fmt, n_strands, n_verts, bbox, tol, pinned = HAIR[name]
    raw = hair(name)
    assert raw.format == fmt and raw.up == "y"
    assert raw.n_strands == n_strands
    assert np.all(np.diff(raw.offsets) == n_verts)
    assert raw.points.shape == (n_strands * n_verts, 3)
    if bbox is not None:
        lo, hi = raw.points.min(axis=0), raw.points.max(axis=0)
        assert lo == pytest.approx([b[0] for b in bbox], abs=tol)
        assert hi == pytest.approx([b[1] for b in bbox], abs=tol)
    if pinned is not None:
        assert raw.extras["pinned_tip"].shape == (n_strands,)
        assert raw.extras["pinned_tip"].tolist() == [pinned] * n_strands


def test_sintel_immovable_roots(hair):
    raw = hair("sintel/GEO-sintel_hair_emit.001-sintel_hair.tfx")
    immovable = raw.extras["immovable"].reshape(228, 32)
    assert immovable[:, 0].all() and not immovable[:, 1:].any()  # w = 0 on every root, 1 elsewhere


@pytest.mark.parametrize(
    "name, n_verts, lengths",
    [
        ("sintel/GEO-sintel_hair_emit.001-sintel_hair.tfx", 32, (3.8, 10.4, 20.6)),
        ("ruby/ruby_short_hair_16_guide.tfx", 16, (11, 66.6, 100)),
        ("ruby/ruby_long_hair_16_guide.tfx", 16, (40, 105, 135)),
    ],
)
def test_strand_lengths(hair, name, n_verts, lengths):
    pts = hair(name).points.reshape(-1, n_verts, 3)
    length = np.linalg.norm(np.diff(pts, axis=1), axis=2).sum(axis=1)
    tol = 0.06 if name.startswith("sintel") else 0.6
    assert [length.min(), np.median(length), length.max()] == pytest.approx(lengths, abs=tol)


def _same_strands(a: np.ndarray, b: np.ndarray, n_verts: int) -> float:
    """Largest distance from a strand of ``a`` to its nearest strand of ``b`` (as 3*n_verts vectors)."""
    from scipy.spatial import cKDTree

    dist, index = cKDTree(b.reshape(-1, 3 * n_verts)).query(a.reshape(-1, 3 * n_verts))
    assert len(set(index.tolist())) == len(index)  # a one-to-one match
    return float(dist.max())


def test_tressfx3_is_the_v2_ponytail_mirrored_in_z(hair):
    flip = np.array([1.0, 1.0, -1.0])
    back = hair("ponytail/tressfx3/back.tfx").points * flip
    assert _same_strands(hair("ponytail/hair_pulled_16_guide.tfx").points, back, 16) < 0.01
    v3_free = np.vstack([hair("ponytail/tressfx3/front_top.tfx").points, hair("ponytail/tressfx3/side.tfx").points])
    assert _same_strands(hair("ponytail/hair_free_16_guide.tfx").points, v3_free * flip, 16) < 0.01


def _face_sizes(path: Path) -> np.ndarray:
    sizes = [len(line.split()) - 1 for line in path.read_text(errors="replace").splitlines() if line.startswith("f ")]
    return np.array(sizes)


@pytest.mark.parametrize("name", sorted(MESHES))
def test_meshes(name):
    n_verts, n_tris, bbox, n_boundary, n_nonmanifold = MESHES[name]
    mesh = read_mesh(REAL / name)
    assert len(mesh.vertices) == n_verts
    if name == "ruby/ruby_head.obj":
        sizes = _face_sizes(REAL / name)
        ngons = sizes[sizes > 4]
        assert (sizes == 3).sum() == 11191 and (sizes == 4).sum() == 11693
        assert len(ngons) == 50 and ngons.max() == 22
        n_tris = 11191 + 2 * 11693 + int((ngons - 2).sum())
    assert len(mesh.faces) == n_tris
    if bbox is not None:
        tol = 0.006 if name.startswith("sintel") else 0.06
        assert mesh.bounds[0] == pytest.approx([b[0] for b in bbox], abs=tol)
        assert mesh.bounds[1] == pytest.approx([b[1] for b in bbox], abs=tol)
    edges = np.sort(mesh.faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    _, uses = np.unique(edges, axis=0, return_counts=True)
    assert (uses == 1).sum() == n_boundary
    assert (uses > 2).sum() == n_nonmanifold
