"""The time step of simulate: the linearly implicit Euler step and the factored Delassus operator.

Everything is checked against dense matrices assembled here from the
inertia kernels (themselves checked against independent energies in
test_inertia.py), never against the step's own output.
"""

from __future__ import annotations

import dataclasses


import numpy as np
import pytest

from conftest import material, two_strand_scene
from hairinv.config import DynamicsSettings, Settings
from hairinv.dynamics.contact import (back_substitute, contact_keys, delassus_blocks, factored_blocks, factored_rows,
                                      forward_substitute)
from hairinv.dynamics.inertia import gauss_nodes, inertia_terms, strand_nodes
from hairinv.dynamics.simulate import Motion, Simulation, _free_chunk
from hairinv.gravity import generalized_gravity
from hairinv.contacts.rows import contact_rows
from hairinv.model import stiffness

H = 0.01


def _free_step(helices, q0, mat, v, settings: DynamicsSettings, motion: Motion):
    sim = Simulation(helices, q0, mat, None, Settings().contacts, settings)
    sim.v = v.copy()
    v_free = np.zeros_like(sim.q)
    _free_chunk(helices.root, helices.frame0, helices.offsets, helices.length, sim.q, sim.v, sim.rest, sim.stiff,
                sim.lam, sim.rot, settings.damping, settings.air_damping, H, motion.per_strand(helices.n_strands), sim.gx, sim.gw,
                sim.chol, sim.chol_ptr, v_free, sim.kinetic, sim.hess, sim.mass, np.ones(helices.n_strands, np.bool_),
                sim.factored_h, np.zeros_like(sim.hess), 0, helices.n_strands)
    return sim, v_free


def _gravity_hessian(helices, mat, k, eps=1e-6):
    """-dF_g/dq of strand k by central differences of generalized_gravity, symmetrised."""
    a, z = helices.offsets[k], helices.offsets[k + 1]
    n = 3 * (z - a)
    G = np.empty((n, n))
    for j in range(n):
        out = []
        for sign in (1.0, -1.0):
            omega = helices.omega.copy()
            omega[a + j // 3, j % 3] += sign * eps
            moved = dataclasses.replace(helices, omega=omega)
            out.append(generalized_gravity(moved, mat)[a:z].ravel())
        G[:, j] = -(out[0] - out[1]) / (2.0 * eps)
    return 0.5 * (G + G.T)


def _dense_step_matrix(helices, mat, v, settings: DynamicsSettings):
    """Per strand: M, the velocity-product force, Mt and S = K + G (G clipped to keep Mt positive)."""
    lam = mat.linear_density
    rot = lam * settings.inertia_radius ** 2 / 4.0
    stiff = stiffness(helices, mat)
    out = []
    for k in range(helices.n_strands):
        a, z = helices.offsets[k], helices.offsets[k + 1]
        M, bias = inertia_terms(helices.root[k], helices.frame0[k], helices.omega[a:z], helices.length[a:z],
                                v[a:z], lam, rot, order=settings.quadrature)
        Kk = np.diag(stiff[3 * a:3 * z])
        S = Kk + _gravity_hessian(helices, mat, k)

        def step_matrix(S):
            return M * (1.0 + H * settings.air_damping) + H * settings.damping * Kk + H * H * S

        if np.linalg.eigvalsh(step_matrix(S))[0] <= 0:
            w, V = np.linalg.eigh(S)
            S = (V * np.maximum(w, 0.0)) @ V.T
        out.append((M, bias, step_matrix(S), Kk, S))
    return out


@pytest.mark.parametrize("moving", [False, True])
def test_free_velocity_is_the_linearly_implicit_euler_step(moving):
    """v_f = v + Mt^-1 (h (F_g + b - K (q - q0)) - (h D + h^2 K) v), assembled densely here."""
    helices, _ = two_strand_scene()
    mat = material()
    rng = np.random.default_rng(3)
    q0 = helices.omega + 0.5 * rng.standard_normal(helices.omega.shape)
    v = 0.3 * rng.standard_normal(helices.omega.shape) if moving else np.zeros_like(helices.omega)
    settings = DynamicsSettings(damping=0.02, air_damping=0.5)
    _, v_free = _free_step(helices, q0, mat, v, settings, Motion.still(mat.gravity))
    gravity = generalized_gravity(helices, mat)
    for k, (M, bias, Mt, Kk, S) in enumerate(_dense_step_matrix(helices, mat, v, settings)):
        a, z = helices.offsets[k], helices.offsets[k + 1]
        vk = v[a:z].ravel()
        force = gravity[a:z].ravel() + bias - Kk @ (helices.omega[a:z] - q0[a:z]).ravel()
        rhs = H * force - H * settings.damping * (Kk @ vk) - H * H * (S @ vk) - H * settings.air_damping * (M @ vk)
        expected = vk + np.linalg.solve(Mt, rhs)
        assert np.allclose(v_free[a:z].ravel(), expected, rtol=1e-6, atol=1e-8 * np.abs(expected).max())


def test_moving_frame_forces_are_those_of_the_dense_node_jacobians():
    """In a frame moving with acceleration a0, spin W, spin rate A and velocity u, each node of mass
    lam w at p feels -lam w (a0 + A x p + W x (W x p) + 2 W x p_dot + air (u + W x p)), p_dot = J v:
    the free velocity changes by h Mt^-1 sum_n J_n^T f_n, with J_n the node Jacobians (test_inertia)."""
    helices, _ = two_strand_scene()
    mat = material()
    rng = np.random.default_rng(8)
    v = 0.4 * rng.standard_normal(helices.omega.shape)
    settings = DynamicsSettings(damping=0.02, air_damping=0.7)
    a0, u, W, A = (rng.standard_normal(3) * s for s in (2.0, 0.3, 3.0, 20.0))
    _, still = _free_step(helices, helices.omega, mat, v, settings, Motion.still(mat.gravity))
    _, moving = _free_step(helices, helices.omega, mat, v, settings, Motion(mat.gravity, a0, u, W, A))
    gx, gw = gauss_nodes(settings.quadrature)
    m = len(gx)
    for k, (M, bias, Mt, Kk, S) in enumerate(_dense_step_matrix(helices, mat, v, settings)):
        a, z = helices.offsets[k], helices.offsets[k + 1]
        n = z - a
        x, F, w = np.empty((n * m, 3)), np.empty((n * m, 3, 3)), np.empty(n * m)
        J, T = np.empty((n * m, 3, 3 * n)), np.empty((n * m, 3, 3 * n))
        strand_nodes(helices.root[k], helices.frame0[k], helices.omega[a:z], helices.length[a:z], gx, gw, x, F, w, J, T)
        xdot = J @ v[a:z].ravel()
        frame = a0 + np.cross(A, x) + np.cross(W, np.cross(W, x)) + 2 * np.cross(W, xdot)
        f = -mat.linear_density * w[:, None] * (frame + settings.air_damping * (u + np.cross(W, x)))
        expected = H * np.linalg.solve(Mt, np.einsum("nic,ni->c", J, f))
        np.testing.assert_allclose((moving - still)[a:z].ravel(), expected, rtol=0, atol=1e-9 * np.abs(expected).max())


def test_a_kept_gravity_hessian_gives_the_same_step():
    """The Hessian is reused while the shape has not moved: the step from it is bit for bit the same."""
    helices, _ = two_strand_scene()
    mat = material()
    settings = DynamicsSettings()
    v = 0.1 * np.random.default_rng(5).standard_normal(helices.omega.shape)
    sim, v_free = _free_step(helices, helices.omega, mat, v, settings, Motion.still(mat.gravity))
    again = np.zeros_like(v_free)
    _free_chunk(helices.root, helices.frame0, helices.offsets, helices.length, sim.q, v, sim.rest, sim.stiff,
                sim.lam, sim.rot, settings.damping, settings.air_damping, H, Motion.still(mat.gravity).per_strand(helices.n_strands),
                sim.gx, sim.gw, sim.chol, sim.chol_ptr, again, sim.kinetic, sim.hess, sim.mass,
                np.zeros(helices.n_strands, np.bool_), sim.factored_h, np.zeros_like(sim.hess), 0, helices.n_strands)
    assert np.array_equal(again, v_free)


def test_factored_delassus_equals_the_dense_operator():
    """Z^T Z = H Mt^-1 H^T and L^-T Z^T r = Mt^-1 H^T r, with Mt assembled densely here."""
    helices, contacts = two_strand_scene()
    mat = material()
    settings = DynamicsSettings()
    sim, _ = _free_step(helices, helices.omega, mat, np.zeros_like(helices.omega), settings,
                        Motion.still(mat.gravity))
    rows = contact_rows(helices, contacts)
    Z = factored_rows(rows, contacts.strand, helices.offsets, sim.chol, sim.chol_ptr)
    blocks = [Mt for _, _, Mt, _, _ in _dense_step_matrix(helices, mat, np.zeros_like(helices.omega), settings)]
    n = rows.n_dofs
    Mt = np.zeros((n, n))
    for k, block in enumerate(blocks):
        a, z = 3 * helices.offsets[k], 3 * helices.offsets[k + 1]
        Mt[a:z, a:z] = block
    Hd = rows.to_sparse().toarray()
    W = Hd @ np.linalg.solve(Mt, Hd.T)
    Zd = Z.to_sparse().toarray()
    assert np.allclose(Zd @ Zd.T, W, rtol=1e-6, atol=1e-9 * np.abs(W).max())
    r = np.random.default_rng(0).standard_normal((contacts.n_contacts, 3))
    out = np.zeros(n)
    back_substitute(helices.offsets, sim.chol, sim.chol_ptr, Z.rmatvec(r), out, 0, helices.n_strands)
    expected = np.linalg.solve(Mt, Hd.T @ r.ravel())
    assert np.allclose(out, expected, rtol=1e-6, atol=1e-9 * np.abs(expected).max())
    # the same solve without the factored rows: L^-1 by forward substitution, then L^-T
    half = np.zeros(n)
    forward_substitute(helices.offsets, sim.chol, sim.chol_ptr, Hd.T @ r.ravel(), half, 0, helices.n_strands)
    again = np.zeros(n)
    back_substitute(helices.offsets, sim.chol, sim.chol_ptr, half, again, 0, helices.n_strands)
    assert np.allclose(again, expected, rtol=1e-6, atol=1e-9 * np.abs(expected).max())
    # the blocks W_ii without the rows: those of the dense operator, and bit for bit those from the rows
    blocks_only = factored_blocks(rows, contacts.strand, helices.offsets, sim.chol, sim.chol_ptr)
    dense = np.stack([W[3 * i:3 * i + 3, 3 * i:3 * i + 3] for i in range(contacts.n_contacts)])
    assert np.allclose(blocks_only, dense, rtol=1e-6, atol=1e-9 * np.abs(W).max())
    assert np.array_equal(blocks_only, delassus_blocks(Z, np.zeros(contacts.n_contacts)))


def test_contact_keys_name_elements():
    helices = two_strand_scene()[0]
    offsets, length = helices.offsets, helices.length
    ends = np.concatenate([[0.0], np.cumsum(length[offsets[0]:offsets[1]])])
    # a body contact inside element 1 of strand 0, and a hair-hair one from element 0 of strand 0
    # to the last element of strand 1 (its arc length clamped to the strand's end)
    strand = np.array([[0, -1], [0, 1]], np.int64)
    s = np.array([[0.5 * (ends[1] + ends[2]), 0.0], [0.25 * ends[1], 10.0]])
    keys = contact_keys(strand, s, offsets, length)
    E = int(offsets[-1])
    assert keys[0] == offsets[0] + 1
    assert keys[1] == E * (1 + offsets[0]) + offsets[2] - 1


def test_one_step_from_an_inverted_equilibrium_keeps_the_groom_still():
    """A sample groom inverted on the sample bust: with the inversion's forces (times h) as the first
    step's impulses, the contact problem is already solved and the step leaves the strands at rest."""
    from conftest import SAMPLES
    from hairinv import config
    from hairinv.contacts.body import BodyMesh
    from hairinv.invert import invert
    from hairinv.model import Material
    from hairinv.pipeline import prepare

    settings = config.apply(config.resolve(), {"import": {"guides": 20}, "solver": {"max_sweeps": 100}})
    scene = prepare(SAMPLES / "wavy.h5", SAMPLES / "body.obj", settings)
    mat = Material.from_settings(settings.material, scene.up)
    model, _ = invert(scene.helices, scene.contacts, mat, settings.solver)
    sim = Simulation(scene.helices, model.omega_rest, mat, BodyMesh.from_mesh(scene.body), settings.contacts,
                     settings.dynamics, initial=scene.contacts, initial_force=model.force)
    report = sim.step(Motion.still(mat.gravity))
    assert report.contacts == scene.contacts.n_contacts
    assert report.sweeps == 0 and report.status == "CONVERGED"
    # the free velocity is of order h g / length ~ 1 1/(m s); what is left is round-off
    assert np.abs(sim.v).max() < 1e-8
    # the naive model (q0 = q) is not an equilibrium: it starts to move at once
    naive = Simulation(scene.helices, scene.helices.omega, mat, BodyMesh.from_mesh(scene.body),
                       settings.contacts, settings.dynamics, initial=scene.contacts)
    naive.step(Motion.still(mat.gravity))
    assert np.abs(naive.v).max() > 1e-3


def test_persisting_body_gaps_stay_within_the_bound_of_an_exact_measurement(monkeypatch):
    """A body contact whose point has hardly moved takes its gap to first order from its last exact
    measurement: on a still inverted groom no closest-point query is made after the first step, on a
    moving (naive) one the points are measured again; either way every persisted gap is within
    ``tolerance g h^2 / 2`` of the exact signed distance, and each normal points from the closest
    surface point to the hair."""
    from conftest import SAMPLES
    from hairinv import config
    from hairinv.contacts.body import BodyMesh
    from hairinv.invert import invert
    from hairinv.model import Material
    from hairinv.pipeline import prepare

    settings = config.apply(config.resolve(), {"import": {"guides": 20}, "solver": {"max_sweeps": 100}})
    scene = prepare(SAMPLES / "wavy.h5", SAMPLES / "body.obj", settings)
    mat = Material.from_settings(settings.material, scene.up)
    model, _ = invert(scene.helices, scene.contacts, mat, settings.solver)
    body = BodyMesh.from_mesh(scene.body)
    bound = 0.5 * settings.dynamics.tolerance * np.linalg.norm(mat.gravity) * settings.dynamics.time_step ** 2
    queried = []
    closest = BodyMesh.closest

    def counted(self, points):
        queried.append(len(points))
        return closest(self, points)

    for rest, still in ((model.omega_rest, True), (scene.helices.omega, False)):
        sim = Simulation(scene.helices, rest, mat, body, settings.contacts, settings.dynamics,
                         initial=scene.contacts, initial_force=model.force if still else None)
        for k in range(4):
            monkeypatch.setattr(BodyMesh, "closest", counted)
            queried.clear()
            sim.step(Motion.still(mat.gravity))
            monkeypatch.setattr(BodyMesh, "closest", closest)
            c = sim.contacts
            on_body = c.strand[:, 1] < 0
            sd, surface, _, _ = body.closest(c.point[on_body])
            assert np.abs(c.gap[on_body] - sd).max() <= bound
            away = (c.point[on_body] - surface) * np.sign(sd)[:, None]
            assert np.all(np.einsum("ij,ij->i", away, c.frame[on_body, 0]) >= 0.99 * np.linalg.norm(away, axis=1))
            if k and still:
                assert sum(queried) == 0
            elif k:
                assert sum(queried) > 0


@pytest.mark.parametrize("solver", ["newton", "gauss-seidel"])
def test_a_strands_block_solves_the_convex_cone_problem_like_an_interior_point(solver):
    """The convex problem of each round of a strand's fixed point, on its dense block of W = Z^T Z + gamma
    (three nearly parallel contacts), by the block's Newton steps and by its Gauss-Seidel passes (where
    Newton stalls): the forces match Clarabel on the same problem."""
    from hairinv.dynamics.contact import strand_groups
    from hairinv.solver.blocks import _block_gauss_seidel, _block_newton, _newton_scratch
    from hairinv.solver.reference import solve_socqp_dense_clarabel
    from hairinv.solver.rows import ContactRows

    rng = np.random.default_rng(11)
    n_dofs, m = 6, 3
    base = rng.normal(size=(n_dofs, 3))
    vals = [base + 0.05 * rng.normal(size=(n_dofs, 3)) for _ in range(m)]  # nearly parallel rows
    rows = ContactRows(np.arange(m + 1) * n_dofs, np.tile(np.arange(n_dofs), m), np.concatenate(vals), n_dofs)
    gamma = np.full(m, 1e-6)
    members, group_ptr, block_ptr, blocks, Wd = strand_groups(rows, gamma, np.tile([0, -1], (m, 1)))
    W = blocks.reshape(3 * m, 3 * m)
    b = rng.normal(size=(m, 3))
    b[:, 0] = -np.abs(b[:, 0])  # pushing into the body
    mu = np.full(m, 0.3)
    rho = np.trace(Wd, axis1=1, axis2=2) / 3.0
    x = np.zeros(3 * m)
    if solver == "newton":
        best, _ = _block_newton(W, 3 * m, b.ravel().copy(), rho, mu, x, xbest := np.empty(3 * m), 1e-13, 50, False,
                                True, _newton_scratch(m))
        assert best <= 1e-13
        r = (xbest.reshape(m, 3) / rho[:, None])
    else:
        _block_gauss_seidel(W, 3 * m, b.ravel().copy(), rho, mu, x, 20000, False, _newton_scratch(m))
        r = x.reshape(m, 3) / rho[:, None]
    Z = rows.to_sparse().toarray()
    ref, info = solve_socqp_dense_clarabel(Z @ Z.T + np.diag(np.repeat(gamma, 3)), b.ravel(), mu, tol=1e-10)
    assert info["status"] == "Solved"
    assert np.abs(r - ref).max() <= 1e-6 * np.abs(ref).max()


@pytest.mark.parametrize("size", [1e-6, 1e-3, 0.1])
def test_the_detection_bounds_hold_at_every_point(rng, size):
    """Both re-detection bounds hold for every centerline point (sampled densely here): the cheap
    one (each element's turn swings its whole strand) and ``_strand_moves``, which for small
    changes is within a few times the true largest displacement."""
    from hairinv.dynamics.simulate import _strand_moves
    from hairinv.rod.helix import points_at

    helices, _ = two_strand_scene()
    q_to = helices.omega + size * rng.normal(size=helices.omega.shape) * (1.0 + np.abs(helices.omega))
    true = 0.0
    for k in range(helices.n_strands):
        a, z = helices.offsets[k], helices.offsets[k + 1]
        s = np.linspace(0.0, helices.length[a:z].sum(), 2001)
        x0, x1 = np.empty((len(s), 3)), np.empty((len(s), 3))
        points_at(helices.root[k], helices.frame0[k], helices.omega[a:z], helices.length[a:z], s, x0)
        points_at(helices.root[k], helices.frame0[k], q_to[a:z], helices.length[a:z], s, x1)
        true = max(true, np.linalg.norm(x1 - x0, axis=1).max())
    moves = np.zeros(helices.n_strands)
    _strand_moves(helices.root, helices.frame0, helices.offsets, helices.omega, q_to, helices.length, moves)
    bound = moves.max()
    assert true <= bound
    assert bound <= 4.0 * true
    turn = np.linalg.norm(q_to - helices.omega, axis=1) * helices.length
    lengths = np.add.reduceat(helices.length, helices.offsets[:-1])
    assert true <= (np.add.reduceat(turn, helices.offsets[:-1]) * lengths).max()


def test_the_step_stiffness_holds_the_contact_forces_share():
    """The step matrix's stiffness is the Hessian of the whole potential the step linearises: elastic,
    gravity and the remembered contact forces held in the world at their points (their share is what
    holds a strand pressed near its root; explicit, it limits the step). Checked on an inverted sample
    against second differences of the load potential from centerline points and against central
    differences of the gravity forces, both independent of the step's kernels."""
    from conftest import SAMPLES, point_load_potential

    from hairinv import config
    from hairinv.invert import invert
    from hairinv.model import Material
    from hairinv.pipeline import prepare

    settings = config.apply(config.resolve(), {"import": {"guides": 20}, "solver": {"max_sweeps": 100}})
    scene = prepare(SAMPLES / "wavy.h5", SAMPLES / "body.obj", settings)
    mat = Material.from_settings(settings.material, scene.up)
    model, _ = invert(scene.helices, scene.contacts, mat, settings.solver)
    c = scene.contacts
    sim = Simulation(scene.helices, model.omega_rest, mat, None, settings.contacts, settings.dynamics,
                     initial=c, initial_force=model.force)
    fresh = np.ones(scene.helices.n_strands, np.bool_)
    held = sim._contact_hessians(fresh)
    world = np.einsum("cji,cj->ci", c.frame, model.force)
    helices = scene.helices
    loaded_strands = np.unique(np.concatenate([c.strand[model.force[:, 0] > 0, 0],
                                               c.strand[(model.force[:, 0] > 0) & (c.strand[:, 1] >= 0), 1]]))
    assert len(loaded_strands) >= 3
    for k in loaded_strands[:3]:
        a, z = helices.offsets[k], helices.offsets[k + 1]
        n = 3 * (z - a)
        # the loads on strand k: +f on a contact's first strand, -f on its second
        first, second = c.strand[:, 0] == k, c.strand[:, 1] == k
        s = np.concatenate([c.s[first, 0], c.s[second, 1]])
        f = np.concatenate([world[first], -world[second]])
        step = 1e-2
        fd = np.empty((n, n))
        flat = helices.omega[a:z].ravel()

        def v(i, j, di, dj, k=k, a=a, z=z, s=s, f=f, flat=flat):
            w = flat.copy()
            w[i] += di
            w[j] += dj
            return point_load_potential(helices.root[k], helices.frame0[k], w.reshape(-1, 3), helices.length[a:z],
                                        s, f)
        for i in range(n):
            for j in range(n):
                fd[i, j] = (v(i, j, step, step) - v(i, j, step, -step) - v(i, j, -step, step)
                            + v(i, j, -step, -step)) / (4 * step * step)
        mine = held[sim.chol_ptr[k]:sim.chol_ptr[k + 1]].reshape(n, n)
        assert np.abs(fd).max() > 0
        assert np.abs(mine - fd).max() <= 1e-5 * np.abs(fd).max()
    # and one step keeps it: the kept stiffness is gravity's Hessian plus this share (where it is positive)
    sim.step(Motion.still(mat.gravity))
    checked = 0
    for k in loaded_strands:
        a, z = helices.offsets[k], helices.offsets[k + 1]
        n = 3 * (z - a)
        G = _gravity_hessian(helices, mat, k)
        total = G + held[sim.chol_ptr[k]:sim.chol_ptr[k + 1]].reshape(n, n)
        if np.linalg.eigvalsh(total + np.diag(sim.stiff[3 * a:3 * z]))[0] > 0:
            kept = sim.hess[sim.chol_ptr[k]:sim.chol_ptr[k + 1]].reshape(n, n)
            assert np.abs(kept - total).max() <= 1e-5 * np.abs(total).max()
            checked += 1
    assert checked >= 3
