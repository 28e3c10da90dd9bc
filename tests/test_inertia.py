"""Strand inertia against independent kinematics and mechanics.

- node positions, frames, weights and Jacobians against ``points_at`` /
  ``frames_at`` and their central finite differences;
- ``1/2 v^T M v`` against the kinetic energy integrated here by composite
  Simpson on each element, with the centerline velocity and the angular
  velocity of the material frame taken by finite differences of
  ``points_at`` / ``frames_at`` (translational and rotational parts
  separately, and every entry of ``M`` by polarization);
- generalized node forces and torques against virtual work, and a uniform
  field against the closed-form ``gravity_forces``;
- the velocity-product accelerations against derivatives of exact
  (complex-step) velocities, against the planar arc in closed form and
  against a rigid swing about a twisted straight element;
- the velocity-product force against the Euler-Lagrange identity
  ``b = dK/dq - (dM/dt) q_dot`` (``M`` itself being checked above).
"""

from __future__ import annotations

import numpy as np
import pytest

from conftest import FINITE_DIFFERENCE, ROUNDOFF
from hairinv.dynamics.inertia import (
    gauss_nodes,
    inertia_terms,
    mass_from_nodes,
    node_bias_accelerations,
    node_forces_to_generalized,
    node_torques_to_generalized,
    strand_bias_forces,
    strand_mass,
    strand_node_loads,
    strand_nodes,
)
from hairinv.rod.helix import element_step, frames_at
from hairinv.rod.statics import gravity_forces

RHO = 1300.0  # kg/m^3
RADIUS = 40e-6  # m
LAM = RHO * np.pi * RADIUS**2  # kg/m
ROT = RHO * np.pi * RADIUS**4 / 4  # kg m
G = np.array([0.0, -9.81, 0.0])


def random_frame(rng) -> np.ndarray:
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q if np.linalg.det(q) > 0 else -q


def random_strand(rng, n, scale=30.0):
    """Root near a head (~0.1 m), |omega_e| up to 30 1/m, lengths 1-5 cm: |omega_e| l_e <= 1.5 rad."""
    direction = rng.normal(size=(n, 3))
    direction /= np.linalg.norm(direction, axis=1)[:, None]
    omega = direction * rng.uniform(0.0, scale, size=(n, 1))
    return 0.1 * rng.normal(size=3), random_frame(rng), omega, rng.uniform(0.01, 0.05, size=n)


def nodes_of(root, frame0, omega, length, order=4):
    gx, gw = gauss_nodes(order)
    n = len(length)
    k = n * order
    x, F, w = np.empty((k, 3)), np.empty((k, 3, 3)), np.empty(k)
    J, T = np.empty((k, 3, 3 * n)), np.empty((k, 3, 3 * n))
    strand_nodes(root, frame0, omega, length, gx, gw, x, F, w, J, T)
    return x, F, w, J, T


def node_arclengths(length, order=4):
    gx, _ = gauss_nodes(order)
    starts = np.concatenate([[0.0], np.cumsum(length)[:-1]])
    return (starts[:, None] + gx[None, :] * length[:, None]).ravel()


def mass(root, frame0, omega, length, lam, rot, order=4, impl="crb"):
    """M by the composite-rigid-body kernel or from the node Jacobians."""
    gx, gw = gauss_nodes(order)
    M = np.empty((3 * len(length), 3 * len(length)))
    if impl == "crb":
        strand_mass(root, frame0, omega, length, gx, gw, lam, rot, M)
    else:
        x, F, w, J, T = nodes_of(root, frame0, omega, length, order)
        mass_from_nodes(F, w, J, T, lam, rot, M)
    return M


def poses(root, frame0, omega, length, s):
    x = np.empty((len(s), 3))
    F = np.empty((len(s), 3, 3))
    frames_at(root, frame0, omega, length, s, x, F)
    return x, F


def vee_skew(S):
    """Axis vector of the skew part of ``S`` (..., 3, 3)."""
    A = 0.5 * (S - np.swapaxes(S, -1, -2))
    return np.stack([A[..., 2, 1], A[..., 0, 2], A[..., 1, 0]], axis=-1)


def fd_velocities(root, frame0, omega, length, v, s, angle=1e-5):
    """Centerline and world angular velocities along ``omega + h v`` by central differences."""
    h = angle / max(np.abs(v).max() * length.max(), 1e-300)
    xp, Fp = poses(root, frame0, omega + h * v, length, s)
    xm, Fm = poses(root, frame0, omega - h * v, length, s)
    _, F0 = poses(root, frame0, omega, length, s)
    # R(h) = F(h)^T F(0) takes the frame at 0 to the frame at h; R'(0) = [W]
    Rp = np.swapaxes(Fp, -1, -2) @ F0
    Rm = np.swapaxes(Fm, -1, -2) @ F0
    return (xp - xm) / (2 * h), vee_skew((Rp - Rm) / (2 * h)), F0


def simpson_kinetic_energy(root, frame0, omega, length, v, lam, rot, intervals=200):
    """Composite Simpson on each element of the translational and rotational energy densities."""
    trans = 0.0
    rotational = 0.0
    start = 0.0
    weights = np.ones(2 * intervals + 1)
    weights[1:-1:2] = 4.0
    weights[2:-1:2] = 2.0
    for ln in length:
        s = start + np.linspace(0.0, ln, 2 * intervals + 1)
        xdot, W, F = fd_velocities(root, frame0, omega, length, v, s)
        # angular velocity in material components (t, n1, n2): inertia (2I, I, I)
        Wm = np.einsum("nij,nj->ni", F, W)
        dens_t = 0.5 * lam * (xdot**2).sum(axis=1)
        dens_r = 0.5 * rot * (2 * Wm[:, 0] ** 2 + Wm[:, 1] ** 2 + Wm[:, 2] ** 2)  # rot = rho I
        h = ln / (6 * intervals)
        trans += h * weights @ dens_t
        rotational += h * weights @ dens_r
        start += ln
    return trans, rotational


# -- nodes and Jacobians ----------------------------------------------------------------


def test_gauss_nodes_on_unit_interval():
    for order in (1, 2, 4, 7):
        gx, gw = gauss_nodes(order)
        assert np.all((gx > 0) & (gx < 1))
        assert gw.sum() == pytest.approx(1.0, rel=1e-15)
        # exact for degree 2 order - 1: int_0^1 s^p = 1 / (p + 1)
        for p in range(2 * order):
            assert gw @ gx**p == pytest.approx(1.0 / (p + 1), rel=1e-13)
    with pytest.raises(ValueError):
        gauss_nodes(0)


@pytest.mark.parametrize("n", [1, 3, 6])
def test_nodes_lie_on_the_strand(rng, n):
    root, frame0, omega, length = random_strand(rng, n)
    x, F, w, J, T = nodes_of(root, frame0, omega, length)
    x_ref, F_ref = poses(root, frame0, omega, length, node_arclengths(length))
    np.testing.assert_allclose(x, x_ref, rtol=0, atol=ROUNDOFF)
    np.testing.assert_allclose(F, F_ref, rtol=0, atol=ROUNDOFF)
    assert w.sum() == pytest.approx(length.sum(), rel=1e-14)
    assert np.all(w > 0)


@pytest.mark.parametrize("n", [1, 2, 5])
def test_jacobians_match_finite_differences(rng, n):
    root, frame0, omega, length = random_strand(rng, n)
    x, F, w, J, T = nodes_of(root, frame0, omega, length)
    s = node_arclengths(length)
    h = 1e-6
    for e in range(n):
        for k in range(3):
            plus, minus = omega.copy(), omega.copy()
            plus[e, k] += h
            minus[e, k] -= h
            xp, Fp = poses(root, frame0, plus, length, s)
            xm, Fm = poses(root, frame0, minus, length, s)
            dx = (xp - xm) / (2 * h)
            dth = vee_skew((np.swapaxes(Fp, -1, -2) @ F - np.swapaxes(Fm, -1, -2) @ F) / (2 * h))
            c = 3 * e + k
            # plus the differences' round-off, eps |root| / h ~ 2e-11 m^2
            np.testing.assert_allclose(J[:, :, c], dx, rtol=0, atol=FINITE_DIFFERENCE * np.abs(dx).max() + 1e-10)
            np.testing.assert_allclose(T[:, :, c], dth, rtol=0, atol=FINITE_DIFFERENCE * np.abs(dth).max() + 1e-10)
            # nodes of earlier elements do not move at all
            assert np.all(J[: 4 * e, :, c] == 0.0) and np.all(T[: 4 * e, :, c] == 0.0)


# -- mass matrix ------------------------------------------------------------------------


@pytest.mark.parametrize("impl", ["crb", "nodes"])
@pytest.mark.parametrize("n", [2, 6])
def test_translational_energy_matches_independent_quadrature(rng, n, impl):
    root, frame0, omega, length = random_strand(rng, n)
    M4 = mass(root, frame0, omega, length, LAM, 0.0, order=4, impl=impl)
    M8 = mass(root, frame0, omega, length, LAM, 0.0, order=8, impl=impl)
    for _ in range(3):
        v = rng.normal(size=(n, 3)) * 10.0
        ref, _ = simpson_kinetic_energy(root, frame0, omega, length, v, LAM, 0.0)
        # 8 nodes: limited by the reference's own finite differences (~1e-10)
        assert 0.5 * v.ravel() @ M8 @ v.ravel() == pytest.approx(ref, rel=1e-9)
        # 4 nodes at |omega_e| l_e <= 1.5 rad: ||M4 - M|| <~ 1e-5 ||M||; relative to the
        # energy itself the error can be larger along weak (twist) directions
        scale = 0.5 * np.linalg.norm(M8, 2) * (v**2).sum()
        assert abs(0.5 * v.ravel() @ M4 @ v.ravel() - ref) < 1e-5 * scale


@pytest.mark.parametrize("impl", ["crb", "nodes"])
@pytest.mark.parametrize("n", [2, 6])
def test_rotational_energy_matches_independent_quadrature(rng, n, impl):
    root, frame0, omega, length = random_strand(rng, n)
    M4 = mass(root, frame0, omega, length, 0.0, ROT, order=4, impl=impl)
    M8 = mass(root, frame0, omega, length, 0.0, ROT, order=8, impl=impl)
    for _ in range(3):
        v = rng.normal(size=(n, 3)) * 10.0
        _, ref = simpson_kinetic_energy(root, frame0, omega, length, v, 0.0, ROT)
        assert 0.5 * v.ravel() @ M8 @ v.ravel() == pytest.approx(ref, rel=1e-9)
        scale = 0.5 * np.linalg.norm(M8, 2) * (v**2).sum()
        assert abs(0.5 * v.ravel() @ M4 @ v.ravel() - ref) < 1e-5 * scale


def test_every_mass_entry_by_polarization(rng):
    """M_ij = K(e_i + e_j) - K(e_i) - K(e_j): the energy fixes every entry, not just v^T M v."""
    n = 3
    root, frame0, omega, length = random_strand(rng, n)
    M = mass(root, frame0, omega, length, LAM, ROT, order=8)
    basis = np.eye(3 * n).reshape(3 * n, n, 3)
    K = {}
    for i in range(3 * n):
        K[i] = sum(simpson_kinetic_energy(root, frame0, omega, length, basis[i], LAM, ROT, 100))
    ref = np.empty_like(M)
    for i in range(3 * n):
        ref[i, i] = 2 * K[i]
        for j in range(i):
            kij = sum(simpson_kinetic_energy(root, frame0, omega, length, basis[i] + basis[j], LAM, ROT, 100))
            ref[i, j] = ref[j, i] = kij - K[i] - K[j]
    np.testing.assert_allclose(M, ref, rtol=0, atol=1e-8 * np.abs(ref).max())


@pytest.mark.parametrize("impl", ["crb", "nodes"])
@pytest.mark.parametrize("n", [1, 4, 6])
def test_mass_symmetric_and_positive_definite(rng, n, impl):
    root, frame0, omega, length = random_strand(rng, n)
    M = mass(root, frame0, omega, length, LAM, ROT, impl=impl)
    assert np.array_equal(M, M.T)
    # rot << lam l^2: the twist directions are weak but strictly positive
    np.linalg.cholesky(M)
    assert np.linalg.eigvalsh(M).min() > 0
    # the translational part alone is positive definite away from straight strands
    Mt = mass(root, frame0, omega, length, LAM, 0.0, impl=impl)
    assert np.array_equal(Mt, Mt.T)
    assert np.linalg.eigvalsh(Mt).min() > 0


@pytest.mark.parametrize("impl", ["crb", "nodes"])
def test_straight_strand_twist_is_massless_without_rotational_inertia(rng, impl):
    """Twisting a perfectly straight strand moves no point: the only null space of M at rot = 0."""
    n = 4
    root, frame0, _, length = random_strand(rng, n)
    omega = np.zeros((n, 3))
    Mt = mass(root, frame0, omega, length, LAM, 0.0, impl=impl)
    scale = np.abs(Mt).max()
    np.testing.assert_allclose(Mt[:, 2::3], 0.0, rtol=0, atol=ROUNDOFF * scale)
    bend = np.delete(np.delete(Mt, np.s_[2::3], axis=0), np.s_[2::3], axis=1)
    assert np.linalg.eigvalsh(bend).min() > 1e-6 * scale
    # rotational inertia gives them mass: W = t int_0^s tau_dot, so K = rot int (W.t)^2 ds
    # with piecewise linear W.t, integrated exactly by the Gauss nodes
    Mr = mass(root, frame0, omega, length, 0.0, ROT, impl=impl)
    after = np.concatenate([np.cumsum(length[::-1])[::-1][1:], [0.0]])  # length after each element
    ref = np.empty((n, n))
    for a in range(n):
        for b in range(n):
            lo, hi = min(a, b), max(a, b)
            if a == b:
                ref[a, b] = length[a] ** 3 / 3 + length[a] ** 2 * after[a]
            else:
                ref[a, b] = length[lo] * length[hi] ** 2 / 2 + length[lo] * length[hi] * after[hi]
    np.testing.assert_allclose(Mr[2::3, 2::3], 2 * ROT * ref, rtol=1e-13)
    np.testing.assert_allclose(np.delete(Mr, np.s_[2::3], axis=1)[2::3], 0.0, atol=ROUNDOFF * np.abs(Mr).max())


# -- generalized forces -----------------------------------------------------------------


@pytest.mark.parametrize("n", [1, 4])
def test_node_forces_and_torques_do_the_virtual_work(rng, n):
    root, frame0, omega, length = random_strand(rng, n)
    x, F, w, J, T = nodes_of(root, frame0, omega, length)
    f = rng.normal(size=(len(w), 3))
    torque = rng.normal(size=(len(w), 3))
    gf = np.empty(3 * n)
    gt = np.empty(3 * n)
    node_forces_to_generalized(J, f, gf)
    node_torques_to_generalized(T, torque, gt)
    # the same loads through their resultants, without the Jacobians
    both = np.empty(3 * n)
    strand_node_loads(root, frame0, omega, length, gauss_nodes(4)[0], f, torque, both)
    for _ in range(3):
        delta = rng.normal(size=(n, 3))
        xdot, W, _ = fd_velocities(root, frame0, omega, length, delta, node_arclengths(length))
        work_f = np.sum(f * xdot)
        work_t = np.sum(torque * W)
        assert gf @ delta.ravel() == pytest.approx(work_f, rel=1e-8, abs=1e-9 * np.abs(f).sum() * np.abs(xdot).max())
        assert gt @ delta.ravel() == pytest.approx(work_t, rel=1e-8, abs=1e-9 * np.abs(torque).sum() * np.abs(W).max())
        assert both @ delta.ravel() == pytest.approx(work_f + work_t, rel=1e-8,
                                                     abs=1e-9 * np.abs(f).sum() * np.abs(xdot).max())


@pytest.mark.parametrize("n", [1, 3, 6])
@pytest.mark.parametrize("order, tol", [(4, 1e-7), (6, 1e-12)])
def test_uniform_field_matches_closed_form_gravity(rng, n, order, tol):
    """Gauss quadrature of lam g . J against the closed-form first moments of statics."""
    root, frame0, omega, length = random_strand(rng, n)
    x, F, w, J, T = nodes_of(root, frame0, omega, length, order)
    f = LAM * w[:, None] * G[None, :]
    out = np.empty(3 * n)
    node_forces_to_generalized(J, f, out)
    ref = np.empty((n, 3))
    gravity_forces(root, frame0, omega, length, LAM, G, ref)
    # |omega_e| l_e <= 1.5 rad: 4 nodes reach ~4e-8, 6 nodes ~1e-13 of the largest force
    np.testing.assert_allclose(out.reshape(n, 3), ref, rtol=0, atol=tol * np.abs(ref).max())
    strand_node_loads(root, frame0, omega, length, gauss_nodes(order)[0], f, np.zeros_like(f), out)
    np.testing.assert_allclose(out.reshape(n, 3), ref, rtol=0, atol=tol * np.abs(ref).max())


# -- velocity-product terms -------------------------------------------------------------


def bias_accelerations(frame0, omega, length, v, order=4):
    gx, _ = gauss_nodes(order)
    k = len(length) * order
    a, alpha = np.empty((k, 3)), np.empty((k, 3))
    node_bias_accelerations(np.zeros(3), frame0, omega, length, v, gx, a, alpha)
    return a, alpha


def complex_poses(root, frame0, omega, length, s):
    """Points and frames at arc lengths ``s`` of a strand with complex ``omega`` (a plain loop)."""
    starts = np.concatenate([[0.0], np.cumsum(length)])
    x = root.astype(complex)
    F = frame0.astype(complex)
    R, P, Q = np.empty((3, 3), complex), np.empty(3, complex), np.empty(3, complex)
    xs, Fs = np.empty((len(s), 3), complex), np.empty((len(s), 3, 3), complex)
    for e in range(len(length)):
        inside = (s >= starts[e]) & ((s < starts[e + 1]) | (e == len(length) - 1))
        for j in np.flatnonzero(inside):
            element_step(omega[e, 2], omega[e, 0], omega[e, 1], s[j] - starts[e], R, P, Q)
            xs[j] = x + F.T @ P
            Fs[j] = R.T @ F
        element_step(omega[e, 2], omega[e, 0], omega[e, 1], length[e], R, P, Q)
        x = x + F.T @ P
        F = R.T @ F
    return xs, Fs


def reference_accelerations(root, frame0, omega, length, v, s, angle=1e-3):
    """d/dt of the exact velocities along omega + t v, independently of second differences.

    The velocities at each t are complex-step derivatives (exact to round-off): x_dot =
    Im x(q + t v + i h v) / h and [W] = F_dot^T F. Their central differences at two steps,
    Richardson-extrapolated, leave ~1e-12 (a) and ~1e-10 (alpha) of the largest value.
    """
    hc = 1e-30

    def velocities(t):
        x, F = complex_poses(root, frame0, omega + t * v + 1j * hc * v, length, s)
        return x.imag / hc, vee_skew(np.swapaxes(F.imag / hc, -1, -2) @ F.real)

    def central(d):
        (xp, wp), (xm, wm) = velocities(d), velocities(-d)
        return (xp - xm) / (2 * d), (wp - wm) / (2 * d)

    d = angle / (np.linalg.norm(v, axis=1) * length).max()
    (a1, al1), (a2, al2) = central(d), central(d / 2)
    return (4 * a2 - a1) / 3, (4 * al2 - al1) / 3


@pytest.mark.parametrize("n", [1, 3, 6, 10])
def test_bias_accelerations_are_the_time_derivative_of_exact_velocities(rng, n):
    root, frame0, omega, length = random_strand(rng, n)
    for _ in range(2):
        v = rng.normal(size=(n, 3)) * 20.0
        a, alpha = bias_accelerations(frame0, omega, length, v)
        a_ref, alpha_ref = reference_accelerations(root, frame0, omega, length, v, node_arclengths(length))
        # the kernel is closed form (complex steps for each element's own second derivative): exact to
        # round-off; the reference is good to ~1e-12 (a) and ~1e-10 (alpha) of the largest value
        np.testing.assert_allclose(a, a_ref, rtol=0, atol=1e-10 * np.abs(a_ref).max())
        np.testing.assert_allclose(alpha, alpha_ref, rtol=0, atol=1e-9 * np.abs(alpha_ref).max())


def test_bias_accelerations_vanish_exactly_at_rest(rng):
    root, frame0, omega, length = random_strand(rng, 4)
    a, alpha = bias_accelerations(frame0, omega, length, np.zeros((4, 3)))
    assert np.all(a == 0.0) and np.all(alpha == 0.0)
    gx, gw = gauss_nodes(4)
    b = np.full(12, np.nan)
    strand_bias_forces(root, frame0, omega, length, np.zeros((4, 3)), gx, gw, LAM, ROT, b)
    assert np.all(b == 0.0)


@pytest.mark.parametrize("k0", [0.0, 20.0])
def test_bending_a_single_arc_closed_form(rng, k0):
    """One element bending at rate kd: the node at s is x = root + g1(k) t - g2(k) n2 with
    g1 = sin(ks)/k, g2 = (1 - cos ks)/k (kappa1 turns t towards -n2), so a = kd^2 (g1'' t - g2'' n2).
    The frame turns by k s about the fixed n1: no angular acceleration."""
    frame0 = random_frame(rng)
    ell = 0.05
    kd = 7.0
    omega = np.array([[k0, 0.0, 0.0]])
    a, alpha = bias_accelerations(frame0, omega, np.array([ell]), np.array([[kd, 0.0, 0.0]]))
    s = node_arclengths(np.array([ell]))
    if k0 == 0.0:
        g1pp = -(s**3) / 3
        g2pp = np.zeros_like(s)
    else:
        k = k0
        sn, cs = np.sin(k * s), np.cos(k * s)
        g1pp = -(s**2) * sn / k - 2 * s * cs / k**2 + 2 * sn / k**3
        g2pp = s**2 * cs / k - 2 * s * sn / k**2 + 2 * (1 - cs) / k**3
    expected = kd**2 * (g1pp[:, None] * frame0[0] - g2pp[:, None] * frame0[2])
    np.testing.assert_allclose(a, expected, rtol=0, atol=1e-8 * np.abs(expected).max())
    np.testing.assert_allclose(alpha, 0.0, rtol=0, atol=1e-8 * kd**2 * ell**2)


def test_twisting_a_straight_element_swings_the_rest_in_a_circle(rng):
    """Twist rate td of a straight first element turns everything after it rigidly about
    t0 through x1 at the constant rate td l0: centripetal a = -(td l0)^2 r_perp, no
    angular acceleration, and the first element's own nodes stay put."""
    n = 3
    root, frame0, omega, length = random_strand(rng, n)
    omega[0] = 0.0
    td = 9.0
    v = np.zeros((n, 3))
    v[0, 2] = td
    a, alpha = bias_accelerations(frame0, omega, length, v)
    x, F = poses(root, frame0, omega, length, node_arclengths(length))
    x1 = root + length[0] * frame0[0]
    r = x - x1
    r_perp = r - (r @ frame0[0])[:, None] * frame0[0]
    expected = -((td * length[0]) ** 2) * r_perp
    expected[:4] = 0.0
    scale = np.abs(expected).max()
    np.testing.assert_allclose(a, expected, rtol=0, atol=1e-8 * scale)
    np.testing.assert_allclose(alpha, 0.0, rtol=0, atol=1e-8 * (td * length[0]) ** 2)


@pytest.mark.parametrize("lam, rot", [(LAM, 0.0), (0.0, ROT)])
@pytest.mark.parametrize("n", [1, 3, 5])
def test_bias_force_satisfies_euler_lagrange(rng, n, lam, rot):
    """d/dt dK/dq_dot - dK/dq = M q_ddot + (dM/dt) q_dot - dK/dq, so b = dK/dq - (dM/dt) q_dot.

    dM/dt and dK/dq are central differences of the (separately verified) mass matrix; the
    translational and rotational parts are checked apart (rot << lam l^2 would hide the latter).
    """
    root, frame0, omega, length = random_strand(rng, n)
    v = rng.normal(size=(n, 3)) * 20.0
    vf = v.ravel()
    gx, gw = gauss_nodes(4)
    b = np.empty(3 * n)
    strand_bias_forces(root, frame0, omega, length, v, gx, gw, lam, rot, b)
    ht = 1e-5 / (np.linalg.norm(v, axis=1) * length).max()
    Mdot = (mass(root, frame0, omega + ht * v, length, lam, rot)
            - mass(root, frame0, omega - ht * v, length, lam, rot)) / (2 * ht)
    hq = 1e-4
    dK = np.empty(3 * n)
    for c in range(3 * n):
        plus, minus = omega.copy(), omega.copy()
        plus.flat[c] += hq
        minus.flat[c] -= hq
        dK[c] = 0.5 * vf @ (mass(root, frame0, plus, length, lam, rot)
                            - mass(root, frame0, minus, length, lam, rot)) @ vf / (2 * hq)
    ref = dK - Mdot @ vf
    # agreement ~3e-10: the kernel's accelerations (~1e-9) and the differences of M (~1e-10)
    np.testing.assert_allclose(b, ref, rtol=0, atol=1e-8 * np.abs(ref).max())


def test_inertia_terms_wrapper_and_the_two_mass_evaluations(rng):
    n = 5
    root, frame0, omega, length = random_strand(rng, n)
    v = rng.normal(size=(n, 3))
    M, b = inertia_terms(root, frame0, omega, length, v, LAM, ROT, order=4)
    gx, gw = gauss_nodes(4)
    b_ref = np.empty(3 * n)
    strand_bias_forces(root, frame0, omega, length, v, gx, gw, LAM, ROT, b_ref)
    assert np.array_equal(M, mass(root, frame0, omega, length, LAM, ROT)) and np.array_equal(b, b_ref)
    # both evaluations of the same quadrature (each checked against the energy above)
    M_nodes = mass(root, frame0, omega, length, LAM, ROT, impl="nodes")
    np.testing.assert_allclose(M, M_nodes, rtol=0, atol=ROUNDOFF * np.abs(M).max())
    # the root only translates the strand
    M_far = mass(root + 3.0, frame0, omega, length, LAM, ROT, impl="nodes")
    np.testing.assert_allclose(M_far, M_nodes, rtol=0, atol=1e-11 * np.abs(M).max())


@pytest.mark.parametrize("n", [1, 4, 12])
def test_velocity_products_are_below_the_skip_bound(rng, n):
    """The simulator leaves the velocity-product forces out while ``Omega^2 L < 1e-9 g``
    (``Omega = sum |v_e| l_e``, ``L`` the strand's length): they are then below 1e-8 of the
    largest moment gravity can exert, ``lam g L^2 max(l_e)``, with a wisp's rotational inertia."""
    gx, gw = gauss_nodes(4)
    worst = 0.0
    for _ in range(20):
        root, frame0, omega, length = random_strand(rng, n)
        v = rng.normal(size=(n, 3)) * rng.uniform(0.0, 1.0, size=(n, 1))
        spin = np.sum(np.linalg.norm(v, axis=1) * length)
        total = length.sum()
        v *= np.sqrt(1e-9 * 9.81 / total) / spin  # exactly at the bound
        b = np.empty(3 * n)
        rot = LAM * 5e-3 ** 2 / 4.0  # the default 5 mm inertia radius
        strand_bias_forces(root, frame0, omega, length, v, gx, gw, LAM, rot, b)
        worst = max(worst, np.abs(b).max() / (LAM * 9.81 * total ** 2 * length.max()))
    assert 0.0 < worst < 1e-8
