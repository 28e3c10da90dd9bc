"""Render strands following guides (hairinv.follow): the weights' closed form and continuity, the binding pose
given back, rigid motions carried rigidly, a bent and a twisted guide against their circles and helices, and
roots held on a deforming skin; each against geometry computed here, not by the kernels."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from conftest import ROUNDOFF, strands
from hairinv import stages
from hairinv.follow import SAME_ROOT, Follow, Following, SkinRoots, guide_weights, shepard_weights
from hairinv.model import Helices

# Round-off of a centerline evaluated over a few elements and a frame turned back and forth, on offsets of
# centimetres: metres.
POSITION = 1e-12


def _shepard(d, reach):
    """Franke and Nielson's modified Shepard weights of distances ``d`` with the next distance ``reach``."""
    w = np.array([((reach - x) / (reach * x)) ** 2 for x in d])
    return w / w.sum()


def test_weights_are_the_modified_shepard_kernel_of_the_root_distances():
    guides = np.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0], [0.02, 0.0, 0.0], [0.03, 0.0, 0.0], [0.04, 0.0, 0.0]])
    render = np.array([[0.013, 0.0, 0.0], [0.0, 0.0, 0.004]])
    guide, weight = guide_weights(render, guides, 3)
    # the first: 3 mm from guide 1, 7 from guide 2, 13 from guide 0; the 4th nearest (guide 3) 17 mm away
    assert guide[0].tolist() == [1, 2, 0]
    np.testing.assert_allclose(weight[0], _shepard([0.003, 0.007, 0.013], 0.017), rtol=ROUNDOFF)
    # the second: 4 mm above guide 0; sqrt(4^2 + 10^2), sqrt(4^2 + 20^2); the next sqrt(4^2 + 30^2)
    d = np.hypot(0.004, [0.0, 0.01, 0.02])
    assert guide[1].tolist() == [0, 1, 2]
    np.testing.assert_allclose(weight[1], _shepard(d, np.hypot(0.004, 0.03)), rtol=ROUNDOFF)


def test_weights_with_no_guide_left_out_are_inverse_squared_distances():
    guides = np.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0]])
    guide, weight = guide_weights(np.array([[0.002, 0.0, 0.0]]), guides, 3)
    inverse = np.array([1.0 / 0.002 ** 2, 1.0 / 0.008 ** 2])
    assert guide[0].tolist() == [0, 1]
    np.testing.assert_allclose(weight[0], inverse / inverse.sum(), rtol=ROUNDOFF)


def test_a_root_on_a_guide_follows_that_guide_alone():
    guides = np.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0], [0.0, 0.01, 0.0], [0.01, 0.01, 0.0]])
    guide, weight = guide_weights(guides[2:3] + SAME_ROOT / 2, guides, 3)
    assert guide[0, 0] == 2
    assert weight[0].tolist() == [1.0, 0.0, 0.0]


def test_tied_distances_share_the_weight():
    chosen, weight = shepard_weights(np.array([[0.01, 0.01, 0.01, 0.01]]), 3)
    assert sorted(chosen[0].tolist()) == [0, 1, 2]
    np.testing.assert_allclose(weight[0], 1.0 / 3.0, rtol=ROUNDOFF)


def test_weights_are_continuous_where_the_nearest_guides_change(rng):
    """A render root walking across a scalp of scattered guides: every guide's weight changes by at most a
    step's worth (a Lipschitz bound), even where one guide leaves the 3 nearest and another enters; plain
    inverse distances over the 3 nearest jump there."""
    guides = np.column_stack([rng.uniform(0.0, 0.05, 40), rng.uniform(0.0, 0.05, 40), np.zeros(40)])
    step = 1e-6
    path = np.column_stack([np.arange(0.005, 0.045, step), np.full(40_000, 0.025), np.full(40_000, 0.002)])
    guide, weight = guide_weights(path, guides, 3)
    dense = np.zeros((len(path), len(guides)))
    np.put_along_axis(dense, guide, weight, axis=1)
    changed = (np.sort(guide, axis=1)[1:] != np.sort(guide, axis=1)[:-1]).any(axis=1)
    assert changed.sum() >= 5  # the walk crosses several changes of the nearest set
    # roots 2 mm above the plane of the guides, so the distances stay >= 2 mm: |dw/dx| is a few hundred per metre
    assert np.abs(np.diff(dense, axis=0)).max() < 2e3 * step
    plain = np.zeros_like(dense)
    near = np.take_along_axis(np.linalg.norm(path[:, None, :] - guides[None], axis=2), guide, axis=1)
    np.put_along_axis(plain, guide, (1.0 / near) / (1.0 / near).sum(axis=1, keepdims=True), axis=1)
    assert np.abs(np.diff(plain, axis=0)).max() > 100 * np.abs(np.diff(dense, axis=0)).max()


# ---------------------------------------------------------------------------------------------- a small groom


def _groom(rng, n_guides=6, n_render=20):
    """Curly guides hanging from a 4 cm patch, and render strands of their own lengths and vertex counts
    hanging beside them."""
    specs = []
    for _ in range(n_guides):
        root = np.array([rng.uniform(-0.02, 0.02), 0.0, rng.uniform(-0.02, 0.02)])
        n = int(rng.integers(2, 5))
        specs.append((root, (rng.normal(0.0, 0.2), -1.0, rng.normal(0.0, 0.2)), rng.normal(0.0, 15.0, (n, 3)),
                      rng.uniform(0.02, 0.05, n)))
    guides = strands(specs)
    pieces, counts = [], []
    for _ in range(n_render):
        root = np.array([rng.uniform(-0.02, 0.02), 0.0, rng.uniform(-0.02, 0.02)])
        m = int(rng.integers(5, 30))
        drop = np.linspace(0.0, rng.uniform(0.05, 0.2), m)
        pieces.append(root + np.column_stack([0.01 * np.sin(30 * drop), -drop, 0.005 * np.cos(20 * drop)]))
        counts.append(m)
    return guides, np.concatenate(pieces), np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)


@pytest.mark.parametrize("by", ["root", "curve"])
@pytest.mark.parametrize("at_root", [True, False])
def test_the_binding_pose_gives_the_render_strands_back(rng, by, at_root):
    guides, points, offsets = _groom(rng)
    follow = Follow.bind(points, offsets, guides, by=by, at_root=at_root)
    np.testing.assert_allclose(follow.points(guides.root, guides.frame0, guides.omega), points, rtol=0,
                               atol=POSITION)
    np.testing.assert_allclose(follow.weight.sum(axis=1), 1.0, rtol=ROUNDOFF)


def _rotation(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * K @ K


@pytest.mark.parametrize("at_root", [True, False])
def test_a_rigid_motion_of_the_guides_moves_the_render_strands_rigidly(rng, at_root):
    guides, points, offsets = _groom(rng)
    follow = Follow.bind(points, offsets, guides, at_root=at_root)
    Q, c = _rotation([0.3, 1.0, -0.2], 1.1), np.array([0.1, -0.05, 0.3])
    moved = follow.points(guides.root @ Q.T + c, guides.frame0 @ Q.T, guides.omega)
    np.testing.assert_allclose(moved, points @ Q.T + c, rtol=0, atol=POSITION)


def _straight_guide(root, length, elements):
    """One straight guide along -y from ``root``; frame rows t = -y, n1 = +x, n2 = t x n1 = +z."""
    frame = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    return Helices(np.array([root], float), frame[None], np.array([0, elements]), np.full(elements, length / elements),
                   np.zeros((elements, 3)), np.zeros((1, 2))), frame


@pytest.mark.parametrize("at_root", [True, False])
def test_a_bent_guide_carries_a_parallel_strand_onto_a_circle(at_root):
    """A straight guide bent into an arc of curvature kappa about its n1 axis (its tangent turns towards -n2,
    about the centre root - n2 / kappa); a render strand beside it, d along n2, straight and as long. Carried in
    the material frame it lies on the concentric circle of radius 1/kappa + d, at the guide's angles; carried
    in the root frame it is the guide's arc shifted by d n2."""
    length, kappa, d = 0.12, 9.0, 0.004
    guide, frame = _straight_guide([0.0, 0.0, 0.0], length, 3)
    t0, n2 = frame[0], frame[2]
    u = np.linspace(0.0, 1.0, 17)
    points = d * n2 + np.outer(u * length, t0)
    follow = Follow.bind(points, np.array([0, 17]), guide, at_root=at_root)
    bent = follow.points(guide.root, guide.frame0, np.tile([kappa, 0.0, 0.0], (3, 1)))
    theta = kappa * u * length
    centre = -n2 / kappa
    on_arc = np.outer(np.cos(theta), n2) + np.outer(np.sin(theta), t0)
    if at_root:
        expected = centre + on_arc / kappa + d * n2
    else:
        expected = centre + (1.0 / kappa + d) * on_arc
    np.testing.assert_allclose(bent, expected, rtol=0, atol=POSITION)


@pytest.mark.parametrize("at_root", [True, False])
def test_a_twisted_guide_winds_a_parallel_strand_into_a_helix(at_root):
    """A straight guide twisted at tau per metre: its material frame spins about the tangent, its centerline
    stays. A render strand d along n1 beside it winds about it, n1 cos(tau s) + n2 sin(tau s), in the
    material frame; in the root frame it stays where it is."""
    length, tau, d = 0.1, 40.0, 0.003
    guide, frame = _straight_guide([0.01, 0.02, 0.0], length, 2)
    t0, n1, n2 = frame
    u = np.linspace(0.0, 1.0, 11)
    points = guide.root[0] + d * n1 + np.outer(u * length, t0)
    follow = Follow.bind(points, np.array([0, 11]), guide, at_root=at_root)
    twisted = follow.points(guide.root, guide.frame0, np.tile([0.0, 0.0, tau], (2, 1)))
    s = u * length
    if at_root:
        expected = points
    else:
        expected = guide.root[0] + np.outer(s, t0) + d * (np.outer(np.cos(tau * s), n1) + np.outer(np.sin(tau * s), n2))
    np.testing.assert_allclose(twisted, expected, rtol=0, atol=POSITION)


def test_a_render_strand_that_is_a_guide_follows_that_guide():
    """The guide's own polyline as a render strand, between two other guides: it follows its guide alone, so
    it takes the guide's shape in any pose (here the arc of the bent-guide test, through its vertices)."""
    length, kappa = 0.1, 12.0
    specs = [(np.array([x, 0.0, 0.0]), (0.0, -1.0, 0.0), np.zeros((2, 3)), np.full(2, length / 2))
             for x in (-0.01, 0.0, 0.01)]
    guides = strands(specs)
    u = np.linspace(0.0, 1.0, 9)
    points = np.outer(u * length, [0.0, -1.0, 0.0])
    for by in ("root", "curve"):
        follow = Follow.bind(points, np.array([0, 9]), guides, by=by)
        assert follow.guide[0, 0] == 1 and follow.weight[0, 0] == 1.0
        omega = np.zeros((6, 3))
        omega[2:4] = [kappa, 0.0, 0.0]
        bent = follow.points(guides.root, guides.frame0, omega)
        t0, n2 = guides.frame0[1, 0], guides.frame0[1, 2]
        theta = kappa * u * length
        expected = -n2 / kappa + (np.outer(np.cos(theta), n2) + np.outer(np.sin(theta), t0)) / kappa
        np.testing.assert_allclose(bent, expected, rtol=0, atol=POSITION)


def test_curve_distance_picks_the_guides_lying_along_the_strand():
    """Two guides 2 mm either side of a render root, one leaving the same way as the render strand, one the
    opposite way (a parting); a third 8 mm away along the render strand's way. By root the parting guide
    weighs most; along the strand it gets no weight."""
    specs = [(np.array([-0.002, 0.0, 0.0]), (-1.0, -1.0, 0.0), np.zeros((1, 3)), [0.1]),
             (np.array([0.002, 0.0, 0.0]), (1.0, -1.0, 0.0), np.zeros((1, 3)), [0.1]),
             (np.array([0.008, 0.0, 0.0]), (1.0, -1.0, 0.0), np.zeros((1, 3)), [0.1]),
             (np.array([0.03, 0.0, 0.0]), (1.0, -1.0, 0.0), np.zeros((1, 3)), [0.1])]
    guides = strands(specs)
    u = np.linspace(0.0, 1.0, 6)
    points = np.outer(u * 0.1, np.array([1.0, -1.0, 0.0]) / np.sqrt(2.0)) + [0.0005, 0.0, 0.0]
    by_root = Follow.bind(points, np.array([0, 6]), guides, k=2, by="root")
    along = Follow.bind(points, np.array([0, 6]), guides, k=2, by="curve")
    assert set(by_root.guide[0].tolist()) == {0, 1}
    assert along.guide[0].tolist() == [1, 2]
    # parallel to guides 1, 2 and 3, point for point as far as their roots: 1.5, 7.5 and 29.5 mm (the next)
    np.testing.assert_allclose(along.weight[0], _shepard([0.0015, 0.0075], 0.0295), rtol=1e-9)


# ------------------------------------------------------------------------------------- roots on a moving skin


def _frames_group(root, frame0, omega, vertices=None, faces=None) -> stages.Group:
    data = {"time": np.arange(len(root)) / 30.0, "root": root, "frame0": frame0, "omega": omega,
            "body_transform": np.tile(np.eye(4), (len(root), 1, 1))}
    if vertices is not None:
        data["body_vertices"] = vertices
        data["body_faces"] = faces
    return stages.Group(stages.FRAMES, data)


def test_render_roots_stay_on_a_deforming_skin(rng):
    """A skin of two triangles stretched and sheared from frame to frame, the guides' roots carried by it,
    the render roots not quite (the guides' frames turn with their own triangles): each render root is where
    its triangle carries it, barycentric point plus its offset along the triangle's edge, normal x edge and
    normal, computed here; and the strand moves with it."""
    vertices0 = np.array([[-0.05, 0.0, -0.05], [0.05, 0.0, -0.05], [0.05, 0.0, 0.05], [-0.05, 0.0, 0.05]])
    faces = np.array([[0, 2, 1], [0, 3, 2]])  # normals +y
    guides, points, offsets = _groom(rng, 5, 12)
    F = 3
    stretch = [np.diag([1.0, 1.0, 1.0]), np.diag([1.3, 1.0, 0.9]), np.array([[1.0, 0.0, 0.4], [0.0, 1.0, 0.0],
                                                                                [0.0, 0.0, 1.1]])]
    vertices = np.stack([vertices0 @ A.T for A in stretch])
    root = np.stack([guides.root @ A.T for A in stretch])
    frame0 = np.stack([guides.frame0] * F)
    omega = np.stack([guides.omega] * F)
    following = Following(points, offsets, guides, _frames_group(root, frame0, omega, vertices, faces))
    roots0 = points[offsets[:-1]]
    for k in range(F):
        got = following.frame(k)
        expected = []
        for x in roots0:
            # the root's triangle and barycentric coordinates at rest (its projection on the plane y = 0)
            tri = faces[0] if x[0] >= x[2] else faces[1]
            a, b, c = vertices0[tri]
            M = np.column_stack([b - a, c - a])[[0, 2]]
            lam = np.linalg.solve(M, (x - a)[[0, 2]])
            bary = np.array([1.0 - lam.sum(), *lam])
            A, B, C = vertices[k][tri]
            e = (B - A) / np.linalg.norm(B - A)
            n = np.cross(B - A, C - A)
            n /= np.linalg.norm(n)
            T0e = (b - a) / np.linalg.norm(b - a)
            rel = x - bary @ vertices0[tri]
            offset = np.array([rel @ T0e, rel @ np.cross([0, 1, 0], T0e), x[1]])
            expected.append(bary @ vertices[k][tri] + offset[0] * e + offset[1] * np.cross(n, e) + offset[2] * n)
        np.testing.assert_allclose(got[offsets[:-1]], np.array(expected), rtol=0, atol=1e-12)
        # the rest of each strand moved with its root from where the guides carry it
        carried = following.pose(root[k], frame0[k], omega[k])
        shift = np.repeat(got[offsets[:-1]] - carried[offsets[:-1]], np.diff(offsets), axis=0)
        np.testing.assert_allclose(got, carried + shift, rtol=0, atol=1e-12)


# ------------------------------------------------------------------------------ against simulating them all


def test_render_strands_follow_a_simulated_wisp_within_the_measured_bound():
    """A wisp of 25 curled strands, 4 mm apart on a 16 mm square, hanging freely (no body, no contacts) in
    their gravity-only rest shape; the head turns 40 degrees and tips 10 in 0.3 s and holds. Every strand is
    simulated; then 9 of them (every other row and column) are the guides and the 16 others follow them from
    their rest shape. Against their own simulation, at 16 points each and 16 frames: the median error is under
    0.4 of the median distance the strands moved relative to the head, the 90th percentile under 0.5 of
    theirs (measured 0.30 and 0.40; a render strand that ignored its guides would be off by 1 and 1)."""
    from hairinv import config
    from hairinv.dynamics.run import run_scene
    from hairinv.dynamics.scene import Keyframe, Scene
    from hairinv.model import Material
    from hairinv.rod.helix import points_at

    rng = np.random.default_rng(5)
    side = 5
    specs = []
    for i in range(side):
        for j in range(side):
            omega = np.column_stack([rng.normal(0, 5, 3), rng.normal(0, 5, 3), rng.normal(0, 2, 3)])
            tangent = (0.3 + 0.05 * rng.normal(), -1.0, 0.2 + 0.05 * rng.normal())
            specs.append((np.array([0.004 * i, 1.7, 0.004 * j]), tangent, omega,
                          np.full(3, rng.uniform(0.12, 0.16) / 3)))
    helices = strands(specs)
    settings = config.resolve()
    mat = Material.from_settings(settings.material, np.array([0.0, 1.0, 0.0]))
    model = stages.Group(stages.MODEL, {}, attrs={
        "youngs_modulus": mat.youngs_modulus, "shear_modulus": mat.shear_modulus, "density": mat.density,
        "radius": mat.radius, "gravity": mat.gravity})
    scene = Scene(body="keyframed", keyframes=(Keyframe(0.0), Keyframe(0.3, yaw=40.0, pitch=10.0),
                                               Keyframe(0.6, yaw=40.0, pitch=10.0)))
    run = run_scene(helices, model, None, None, scene, settings, init="gravity-only", seconds=0.75, fps=20)
    frames = _frames_group(run.root, run.frame0, run.omega)
    count = 16

    def centerlines(root, frame0, omega):
        out = np.empty((helices.n_strands, count, 3))
        for k in range(helices.n_strands):
            a, z = helices.offsets[k], helices.offsets[k + 1]
            points_at(root[k], frame0[k], np.ascontiguousarray(omega[a:z]), helices.length[a:z],
                      np.linspace(0.0, helices.length[a:z].sum(), count), out[k])
        return out

    rest = centerlines(helices.root, helices.frame0, helices.omega)
    guides = np.array([i * side + j for i in range(0, side, 2) for j in range(0, side, 2)])
    render = np.setdiff1d(np.arange(side * side), guides)
    following = Following(rest[render].reshape(-1, 3), np.arange(len(render) + 1) * count, helices, frames,
                          guides=guides)
    error, moved = [], []
    for k in range(1, len(run.time)):
        own = centerlines(run.root[k], run.frame0[k], run.omega[k])[render]
        error.append(np.linalg.norm(following.frame(k).reshape(own.shape) - own, axis=2))
        T = run.body_transform[k]
        moved.append(np.linalg.norm(own - (rest[render] @ T[:3, :3].T + T[:3, 3]), axis=2))
    error, moved = np.concatenate(error).ravel(), np.concatenate(moved).ravel()
    assert np.median(moved) > 2e-3  # the hair swings relative to the head
    assert np.median(error) < 0.4 * np.median(moved)
    assert np.percentile(error, 90) < 0.5 * np.percentile(moved, 90)
