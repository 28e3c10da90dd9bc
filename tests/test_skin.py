"""Roots bound to a deforming body, and the dynamics under it: closed forms, and the rigid path as reference."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from conftest import horizontal_strand, material, strands
from hairinv.config import DynamicsSettings, Settings
from hairinv.contacts.body import BodyMesh
from hairinv.dynamics.scene import Scene
from hairinv.dynamics.simulate import Motion, Simulation
from hairinv.dynamics.skin import Binding, SkinnedBody, rotation_log, triangle_frames
from hairinv.rod.helix import strand_points


def test_rotation_log_is_the_inverse_of_the_exponential(rng):
    vectors = [rng.normal(size=3) * a for a in (1e-9, 1e-5, 0.3, 2.0, 3.0)]
    vectors += [np.array([0.0, 0.0, np.pi - 1e-9]), np.array([np.pi, 0.0, 0.0]) / np.sqrt(1.0)]
    for phi in vectors:
        R = Rotation.from_rotvec(phi).as_matrix()
        got = rotation_log(R[None])[0]
        # a half turn has two logs, +-phi
        assert np.allclose(got, phi, atol=1e-9) or (np.linalg.norm(phi) > 3.1 and np.allclose(got, -phi, atol=1e-7))


def test_a_root_bound_to_a_triangle_follows_it_as_it_turns_and_translates(rng):
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=0.1)
    roots = sphere.vertices[rng.choice(len(sphere.vertices), 30, replace=False)] * 1.02  # 2 mm above the skin
    roots[:5] += rng.normal(scale=0.01, size=(5, 3))  # and some off it
    binding = Binding.bind(roots, sphere.vertices, sphere.faces)
    # at bind time: the roots themselves, the identity
    assert np.allclose(binding.roots(sphere.vertices, sphere.faces), roots, atol=1e-14)
    R0, c0 = binding.frames(sphere.vertices, sphere.faces)
    assert np.allclose(R0, np.eye(3), atol=1e-14) and np.allclose(c0, 0.0, atol=1e-14)
    # the distances are the signed distances to the sphere's surface (its triangles)
    assert np.all(np.abs(binding.distance[5:] - 0.002) < 0.002)
    # the whole mesh turned and moved: every root turned and moved with it, to round-off
    R = Rotation.from_rotvec([0.4, -1.1, 0.7]).as_matrix()
    t = np.array([0.3, -0.2, 1.5])
    moved = sphere.vertices @ R.T + t
    assert np.allclose(binding.roots(moved, sphere.faces), roots @ R.T + t, atol=1e-14)
    Rk, ck = binding.frames(moved, sphere.faces)
    assert np.allclose(Rk, R, atol=1e-14) and np.allclose(ck, t, atol=1e-14)


def test_a_root_on_a_deforming_skin_follows_its_own_triangle():
    """Two triangles; one turns about its own edge, the other stays: each root does what its triangle does."""
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0, 0, 1e-3]], float)[:4]
    faces = np.array([[0, 1, 2], [1, 3, 2]])
    roots = np.array([[0.2, 0.2, 0.01], [0.8, 0.8, 0.01]])
    binding = Binding.bind(roots, vertices, faces)
    assert list(binding.triangle) == [0, 1]
    # vertex 3 lifts: triangle 1 turns about the edge 1-2, triangle 0 does not move
    angle = 0.3
    axis = (vertices[2] - vertices[1]) / np.linalg.norm(vertices[2] - vertices[1])
    R = Rotation.from_rotvec(-angle * axis).as_matrix()
    lifted = vertices.copy()
    lifted[3] = vertices[1] + R @ (vertices[3] - vertices[1])
    got = binding.roots(lifted, faces)
    assert np.allclose(got[0], roots[0], atol=1e-15)
    expected = vertices[1] + R @ (roots[1] - vertices[1])
    assert np.allclose(got[1], expected, atol=1e-14)
    p, T = triangle_frames(lifted, faces, np.array([1]), binding.barycentric[1:])
    assert np.allclose(T[0][:, 2], R @ [0, 0, 1], atol=1e-14)  # its normal turned with it


# ------------------------------------------------------------------ the dynamics under a moving body

def _points(helices, q, R=None, c=None, per=4):
    """World points along every strand (strand frames R, c: x = R x_bind + c)."""
    S = helices.n_strands
    strand = np.repeat(np.arange(S), per)
    total = np.add.reduceat(helices.length, helices.offsets[:-1])
    s = np.tile(np.linspace(0.0, 1.0, per), S) * total[strand]
    x = strand_points(helices.root, helices.frame0, helices.offsets, q, helices.length, strand, s)
    if R is None:
        return x
    return np.einsum("nij,nj->ni", R[strand], x) + c[strand]


def _box(extents, center):
    box = trimesh.creation.box(extents=extents)
    box.apply_translation(center)
    return box


def test_a_rigid_motion_through_the_skin_gives_the_rigid_frames_answer():
    """Three strands resting on a box that turns and moves as the ``motion`` scene moves a head: once as
    today's single body frame with its exact fictitious forces, once as a skin whose every triangle
    moves rigidly (each root bound to its own, frames and forces from differences over the steps). The
    strands' points agree in the world to a small fraction of how far they move (0.36 % at 2 ms steps: the
    differences of the frames against the exact derivatives, first order in the step, and contacts found
    afresh each step against the moving body)."""
    helices = strands([horizontal_strand(n=5, total=0.1, curl=c, root=(0.0, 0.002, z))
                       for c, z in ((0.0, 0.0), (3.0, 0.03), (-3.0, 0.06))])
    box = _box((0.3, 0.1, 0.2), (0.05, -0.05, 0.03))
    mat = material()
    settings = Settings()
    dynamics = dataclasses.replace(settings.dynamics, time_step=2e-3)
    scene = Scene.load("motion")
    pivot = np.array([0.0, -0.1, 0.0])
    up = np.array([0.0, 1.0, 0.0])

    rigid = Simulation(helices, helices.omega.copy(), mat, BodyMesh.from_mesh(box), settings.contacts, dynamics)

    def vertices_at(t):
        m = scene.body_motion(t, pivot, up)
        return box.vertices @ m.R.T + m.c

    skinned = SkinnedBody(vertices_at, box.faces, Binding.bind(helices.root, box.vertices, box.faces), mat.gravity)
    skin = Simulation(helices, helices.omega.copy(), mat, BodyMesh.from_mesh(box), settings.contacts, dynamics)
    h = dynamics.time_step
    start = _points(helices, helices.omega)
    worst, travel = 0.0, 0.0
    for k in range(150):  # 0.3 s: the turn accelerates and the strands swing
        t = k * h
        m = scene.body_motion(t, pivot, up)
        R = m.R
        rigid.step(Motion(R.T @ mat.gravity, R.T @ m.acceleration, R.T @ m.velocity, R.T @ m.omega, R.T @ m.alpha),
                   h)
        skin.step(skinned, h, t)
        m1 = scene.body_motion(t + h, pivot, up)
        S = helices.n_strands
        Rs = np.broadcast_to(m1.R, (S, 3, 3))
        cs = np.broadcast_to(m1.c, (S, 3))
        a = _points(helices, rigid.q, Rs, cs)
        b = _points(helices, skin.q, skin.R, skin.c)
        assert np.allclose(skin.R, m1.R, atol=1e-12) and np.allclose(skin.c, m1.c, atol=1e-12)
        worst = max(worst, float(np.abs(a - b).max()))
        travel = max(travel, float(np.linalg.norm(_points(helices, rigid.q) - start, axis=1).max()))
    assert travel > 5e-3, "the strands hardly moved in the body's frame: the scene tests nothing"
    print(f"rigid vs skin: {worst:.3g} m apart, {travel:.3g} m moved")
    assert worst < 0.01 * travel, (worst, travel)


def _plane_and_post(plane_shift):
    """A post under the root (fixed) and a wide plane under the strand, shifted by ``plane_shift`` (3,)."""
    post = _box((0.02, 0.02, 0.02), (0.0, -0.0101, 0.0))
    plane = _box((0.6, 0.02, 0.4), (0.32, -0.0101, 0.0))
    mesh = trimesh.util.concatenate([post, plane])
    moving = np.zeros(len(mesh.vertices), bool)
    moving[len(post.vertices):] = True
    return mesh, moving


@pytest.mark.parametrize("mu, sticks", [(0.6, True), (0.05, False)])
def test_a_strand_on_an_accelerating_plane_sticks_or_slides_as_coulomb_says(mu, sticks):
    """A soft strand lying on a plane, rooted on a post beside it. The plane accelerates at ``a``
    sideways; the post stays. With ``mu g > a`` friction carries the strand with the plane (sticks);
    with ``mu g < a`` the strand slides and friction accelerates it at ``mu g`` (Coulomb's kinetic law).
    Its far half, which bending hardly holds, moves by ``a t^2 / 2`` or ``mu g t^2 / 2``."""
    a, T = 2.0, 0.12
    helices = strands([horizontal_strand(n=10, total=0.3)])
    mat = material(youngs_modulus=1e5)  # bending holds the strand over millimetres only
    settings = Settings()
    contacts = dataclasses.replace(settings.contacts, hair_hair=False, mu_body=mu)
    dynamics = dataclasses.replace(settings.dynamics, time_step=2e-3, air_damping=0.0, tolerance=1e-8)
    mesh, moving = _plane_and_post(np.zeros(3))
    shift = {"t0": 0.05}  # settle first, on the still plane

    def vertices_at(t):
        out = mesh.vertices.copy()
        s = max(t - shift["t0"], 0.0)
        out[moving, 2] += 0.5 * a * s * s
        return out

    skinned = SkinnedBody(vertices_at, mesh.faces, Binding.bind(helices.root, mesh.vertices, mesh.faces), mat.gravity)
    sim = Simulation(helices, helices.omega.copy(), mat, BodyMesh.from_mesh(mesh), contacts, dynamics)
    h = dynamics.time_step
    n_settle = int(round(shift["t0"] / h))
    for k in range(n_settle):
        sim.step(skinned, h, k * h)
    assert sim.contacts.n_body > 3, "the strand does not rest on the plane"
    far = lambda: _points(helices, sim.q, per=11)[6:, 2]  # noqa: E731  (the far 40 % of the strand)
    before = far()
    for k in range(int(round(T / h))):
        sim.step(skinned, h, shift["t0"] + k * h)
    moved = float(np.median(far() - before))
    g = np.linalg.norm(mat.gravity)
    expected = 0.5 * (a if sticks else mu * g) * T * T
    assert mu * g > a if sticks else mu * g < a
    assert abs(moved - expected) < 0.2 * expected, (moved, expected)


def test_a_fast_body_does_not_pass_through_a_strand():
    """A board 10 mm thick rising at 1 m/s, 10 mm a step (more than twice the detection distance, 200 hair
    radii), under a strand held out level from a post: the strand is carried up, and no point of it is ever
    found inside the board by more than 40 % of what the board moves in a step (3.4 mm; 2.9 mm while the first
    step kept a contact its sweep found 10 mm from the post's corner at that distance, which held the strand
    off the post). (Contacts found where the body will be at the step's end, without its velocity, let the
    strand through the board.)"""
    helices = strands([horizontal_strand(n=8, total=0.16)])
    mat = material()
    settings = Settings()
    contacts = dataclasses.replace(settings.contacts, hair_hair=False)
    dynamics = settings.dynamics
    post = _box((0.02, 0.02, 0.02), (0.0, -0.0101, 0.0))
    board = _box((0.2, 0.01, 0.1), (0.12, -0.08, 0.0))
    mesh = trimesh.util.concatenate([post, board])
    moving = np.zeros(len(mesh.vertices), bool)
    moving[len(post.vertices):] = True
    speed = 1.0

    def vertices_at(t):
        out = mesh.vertices.copy()
        out[moving, 1] += speed * min(max(t, 0.0), 0.12)  # up 12 cm, then it stops
        return out

    skinned = SkinnedBody(vertices_at, mesh.faces, Binding.bind(helices.root, mesh.vertices, mesh.faces), mat.gravity)
    sim = Simulation(helices, helices.omega.copy(), mat, BodyMesh.from_mesh(mesh), contacts, dynamics)
    h = dynamics.time_step
    assert speed * h > 2 * settings.contacts.body_distance
    deepest, lifted = 0.0, -np.inf
    for k in range(12):
        sim.step(skinned, h, k * h)
        body = BodyMesh.from_mesh(trimesh.Trimesh(vertices_at((k + 1) * h), mesh.faces, process=False))
        x = _points(helices, sim.q, sim.R, sim.c, per=33)
        sd = body.closest(x)[0]
        deepest = min(deepest, float(sd[x[:, 0] > 0.025].min(initial=np.inf)))
        lifted = max(lifted, float(x[-1, 1]))
    assert lifted > 0.03, "the board never lifted the strand"
    assert deepest > -0.4 * speed * h, deepest


@pytest.mark.parametrize("slide", [0.0, 0.005])
def test_a_body_moving_from_the_first_step_does_not_hold_the_hair_at_the_gap_its_sweep_found(slide):
    """A soft strand held out from a post over a plane 6 mm below it (beyond the contacts' 4 mm) sags onto the
    plane, as the plane on the accelerating-plane test above. With ``slide``, the plane slides sideways by 5 mm
    in the very first step (then stays): the first step's detection reaches further by that sweep and finds
    the plane under the strand, 6 mm away. Those contacts are new, and keep the room they have up to the body's
    thickness (2 mm), so the strand sags onto the plane as it does on a still one. (Taken as contacts of the
    starting shape, which touch at their own distance, they kept their 6 mm, and the strand floated on them
    4 mm above the plane.)"""
    helices = strands([horizontal_strand(n=10, total=0.3)])
    mat = material(youngs_modulus=1e5)
    settings = Settings()
    contacts = dataclasses.replace(settings.contacts, hair_hair=False)
    dynamics = settings.dynamics
    h = dynamics.time_step
    below = 0.006
    assert contacts.body_distance < below < contacts.body_distance + slide or not slide
    post = _box((0.02, 0.02, 0.02), (0.0, -0.0101, 0.0))
    plane = _box((0.6, 0.01, 0.4), (0.32, -0.005 - below, 0.0))
    mesh = trimesh.util.concatenate([post, plane])
    moving = np.zeros(len(mesh.vertices), bool)
    moving[len(post.vertices):] = True

    def vertices_at(t):
        out = mesh.vertices.copy()
        out[moving, 2] += slide * min(max(t / h, 0.0), 1.0)
        return out

    skinned = SkinnedBody(vertices_at, mesh.faces, Binding.bind(helices.root, mesh.vertices, mesh.faces), mat.gravity)
    sim = Simulation(helices, helices.omega.copy(), mat, BodyMesh.from_mesh(mesh), contacts, dynamics)
    for k in range(30):
        sim.step(skinned, h, k * h)
    assert sim.contacts.n_body > 3, "the strand does not rest on the plane"
    x = _points(helices, sim.q, sim.R, sim.c, per=31)
    gap = float(x[:, 1].min()) + below  # the plane's top is at y = -below
    assert 0.0 < gap < 0.0025, gap  # resting on the plane at about the body's thickness (2 mm)


def test_the_skin_under_a_first_element_does_not_swing_the_strand():
    """A strand held out level from a post 8 mm wide, and a plate beside the post, under the strand's first
    element (from 8 to 16 mm of its 20 mm), 1.9 mm below it, that rises 1 mm in 20 ms and stops, as the skin of a neck moves beside the roots when the head turns. The
    first element moves only by turning about the root, which swings the whole strand: asked to keep its gap
    to the plate, a point 8-16 mm from the root carries the tip 0.16 m away up by 14 times what the plate
    moved (14.5 mm). The contact moves with the root instead, and the tip stays where it was."""
    helices = strands([horizontal_strand(n=8, total=0.16)])
    post = _box((0.008, 0.02, 0.02), (0.0, -0.0101, 0.0))  # the strand leaves it within the root clearance
    plate = _box((0.008, 0.002, 0.02), (0.012, -0.0029, 0.0))  # top 1.9 mm under the strand
    mesh = trimesh.util.concatenate([post, plate])
    moving = np.zeros(len(mesh.vertices), bool)
    moving[len(post.vertices):] = True
    rise, T = 1e-3, 0.02
    mat = material(gravity=0.0)  # the strand stays level: only the plate moves it
    settings = Settings()
    contacts = dataclasses.replace(settings.contacts, hair_hair=False)
    dynamics = settings.dynamics
    assert helices.length[0] >= 0.018, "the plate is not under the first element"

    def rising(t):
        out = mesh.vertices.copy()
        out[moving, 1] += rise * min(max(t / T, 0.0), 1.0)
        return out

    binding = Binding.bind(helices.root, mesh.vertices, mesh.faces)
    sim = Simulation(helices, helices.omega.copy(), mat, BodyMesh.from_mesh(mesh), contacts, dynamics)
    skinned = SkinnedBody(rising, mesh.faces, binding, mat.gravity)
    h = dynamics.time_step
    start = _points(helices, helices.omega, per=9)[-1]
    moved = 0.0
    for k in range(int(round(3 * T / h))):
        sim.step(skinned, h, k * h)
        if k == 0:
            assert (sim.contacts.s[:, 0] < helices.length[0]).any(), "nothing touches the first element"
        moved = max(moved, float(np.linalg.norm(_points(helices, sim.q, sim.R, sim.c, per=9)[-1] - start)))
    print(f"tip moved {moved:.3g} m")
    assert moved < rise, moved


def test_strands_detected_again_after_the_body_stops_are_where_their_frames_put_them():
    """Three strands on a box that rises 3 cm in 0.1 s and stops, without hair-hair contact: once the body stops,
    only the strands that moved are detected again. Every body contact's gap is then the signed distance, to the
    body where it stopped, of its strand's point placed by the strand's frame (strands detected where the bind
    pose has them, 3 cm inside the risen box, took contacts 3 cm deep where none was)."""
    helices = strands([horizontal_strand(n=5, total=0.1, curl=c, root=(0.0, 0.002, z))
                       for c, z in ((0.0, 0.0), (3.0, 0.03), (-3.0, 0.06))])
    box = _box((0.3, 0.1, 0.2), (0.05, -0.05, 0.03))
    mat = material()
    settings = Settings()
    contacts = dataclasses.replace(settings.contacts, hair_hair=False)
    dynamics = settings.dynamics
    T = 0.1

    def risen(t):
        u = min(max(t / T, 0.0), 1.0)
        return box.vertices + [0.0, 0.03 * u * u * (3.0 - 2.0 * u), 0.0]

    skinned = SkinnedBody(risen, box.faces,
                          Binding.bind(helices.root, box.vertices, box.faces), mat.gravity)
    sim = Simulation(helices, helices.omega.copy(), mat, BodyMesh.from_mesh(box), contacts, dynamics)
    h = dynamics.time_step
    body = BodyMesh.from_mesh(trimesh.Trimesh(risen(T), box.faces, process=False))
    checked, redetected = 0, 0
    for k in range(int(round(2.5 * T / h))):
        q, R, c = sim.q.copy(), sim.R.copy(), sim.c.copy()  # the contacts are found and measured at the step's start
        report = sim.step(skinned, h, k * h)
        if k * h < T or report.substeps > 1:  # (a halved step's contacts are its last half's)
            continue
        redetected += 0 < sim._redetected < helices.n_strands
        found = sim.contacts
        x = strand_points(helices.root, helices.frame0, helices.offsets, q, helices.length, found.strand[:, 0],
                          found.s[:, 0])
        x = np.einsum("nij,nj->ni", R[found.strand[:, 0]], x) + c[found.strand[:, 0]]
        err = np.abs(found.gap - body.closest(x)[0]).max()
        assert err < 1e-6, (sim.time, err)
        checked += found.n_contacts
    assert checked > 20 and redetected > 0, (checked, redetected)


def test_a_strand_swinging_into_the_body_faster_than_the_contact_distance_a_step_does_not_pass_into_it():
    """A strand hanging 6 mm behind a body's flat back (beyond the contacts' 4 mm) swings into it at 4 rad/s
    about its root, as hair hanging down a back does when the character stops short: its lower half moves
    6-12 mm in the first step. The contact search reaches as far as the strand's own motion takes it over
    the step, so no point of it is ever found inside the body by more than half a millimetre. (Searched only as
    far as the body moves, nothing was found, the step was not halved, and the strand went 8.8 mm in.)"""
    L, n = 0.3, 6
    helices = strands([(np.zeros(3), (0.0, -1.0, 0.0), np.zeros((n, 3)), np.full(n, L / n))])
    mat = material()
    settings = Settings()
    contacts = dataclasses.replace(settings.contacts, hair_hair=False)
    dynamics = settings.dynamics
    gap, rate = 0.006, 4.0
    back = _box((0.3, 0.35, 0.3), (0.0, -0.275, gap + 0.15))  # its face at z = gap, from 10 cm below the root
    body = BodyMesh.from_mesh(back)
    sim = Simulation(helices, helices.omega.copy(), mat, body, contacts, dynamics)
    sim.v[0, 0] = -rate / helices.length[0]  # the first element bends: the strand beyond it turns towards +z
    h = dynamics.time_step
    # the tip would end farther inside than the contact distance, from beyond it
    assert rate * h * L - gap > contacts.body_distance and gap > contacts.body_distance
    still = Motion.still(mat.gravity)
    deepest = 0.0
    for k in range(5):
        sim.step(still, h, k * h)
        x = _points(helices, sim.q, per=61)
        deepest = min(deepest, float(body.closest(x)[0].min()))
    print(f"deepest {1e3 * deepest:.3g} mm")
    assert deepest > -5e-4, deepest
