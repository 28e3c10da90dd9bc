"""Super-helix kernels against independent mathematics.

- element steps against numerical integration of the frame ODE
  ``dv/ds = Om x v`` and against the textbook helix about its axis;
- the series branch against the closed forms across the threshold;
- derivatives against complex-step derivatives of the step itself and
  against central finite differences;
- G1 continuity and orthonormal frames at the extremes.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from conftest import FINITE_DIFFERENCE, ODE, ROUNDOFF
from hairinv.rod.helix import (
    chain,
    element_derivatives,
    element_step,
    frames_at,
    helix_coefficient_derivatives,
    helix_coefficients,
    points_at,
)


def random_frame(rng) -> np.ndarray:
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    if np.linalg.det(q) < 0:
        q[2] *= -1
    return q  # rows are orthonormal, right-handed


def step_world(omega, sigma, x0, F0):
    """World end point and frame of one element (the kernel under test)."""
    R = np.empty((3, 3))
    P = np.empty(3)
    Q = np.empty(3)
    element_step(omega[2], omega[0], omega[1], sigma, R, P, Q)
    return x0 + F0.T @ P, R.T @ F0


def integrate_frame_ode(omega, sigma, x0, F0):
    """dx/ds = t, dv/ds = Om x v for v in (t, n1, n2), Om = k1 n1 + k2 n2 + tau t."""

    def rhs(_s, y):
        t, n1, n2 = y[3:6], y[6:9], y[9:12]
        Om = omega[0] * n1 + omega[1] * n2 + omega[2] * t
        return np.concatenate([t, np.cross(Om, t), np.cross(Om, n1), np.cross(Om, n2)])

    y0 = np.concatenate([x0, F0[0], F0[1], F0[2]])
    sol = solve_ivp(rhs, (0.0, sigma), y0, method="DOP853", rtol=1e-13, atol=1e-15)
    y = sol.y[:, -1]
    return y[:3], y[3:].reshape(3, 3)


def helix_about_axis(omega, sigma, x0, F0):
    """Textbook helix: rotation about the constant Darboux axis (independent formula)."""
    Om = omega[0] * F0[1] + omega[1] * F0[2] + omega[2] * F0[0]
    a = np.linalg.norm(Om)
    u = Om / a
    t0 = F0[0]
    along = (u @ t0) * sigma * u
    radial = np.sin(a * sigma) / a * (t0 - (u @ t0) * u) + (1 - np.cos(a * sigma)) / a * np.cross(u, t0)
    rot = [np.cos(a * sigma) * v + np.sin(a * sigma) * np.cross(u, v) + (1 - np.cos(a * sigma)) * (u @ v) * u
           for v in F0]
    return x0 + along + radial, np.array(rot)


@pytest.mark.parametrize("scale", [0.0, 1e-9, 1e-4, 1.0, 30.0, 300.0])
@pytest.mark.parametrize("sigma", [1e-6, 1e-3, 0.05])
def test_step_matches_frame_ode(rng, scale, sigma):
    omega = rng.normal(size=3) * scale
    x0 = rng.normal(size=3)
    F0 = random_frame(rng)
    x, F = step_world(omega, sigma, x0, F0)
    x_ref, F_ref = integrate_frame_ode(omega, sigma, x0, F0)
    np.testing.assert_allclose(x, x_ref, rtol=0, atol=ODE * max(sigma, 1e-3))
    np.testing.assert_allclose(F, F_ref, rtol=0, atol=ODE)


@pytest.mark.parametrize("magnitude", [1e-2, 1.0, 1e3, 1e5])
@pytest.mark.parametrize("sigma", [1e-6, 1e-3, 0.1, 1.0])
def test_step_matches_textbook_helix(rng, magnitude, sigma):
    """Extremely curly elements (|omega| up to 1e5 1/m, up to 1e5 rad) stay exact."""
    omega = rng.normal(size=3)
    omega *= magnitude / np.linalg.norm(omega)
    x0 = np.zeros(3)
    F0 = random_frame(rng)
    x, F = step_world(omega, sigma, x0, F0)
    x_ref, F_ref = helix_about_axis(omega, sigma, x0, F0)
    # the reference itself loses ~eps * (angle) in its trigonometric arguments
    angle = magnitude * sigma
    tol = 4 * np.finfo(float).eps * max(1.0, angle)
    np.testing.assert_allclose(x, x_ref, rtol=0, atol=tol * max(sigma, 1.0 / magnitude))
    np.testing.assert_allclose(F, F_ref, rtol=0, atol=tol)
    np.testing.assert_allclose(F @ F.T, np.eye(3), rtol=0, atol=8 * np.finfo(float).eps)


def test_straight_element_is_exact():
    x, F = step_world(np.zeros(3), 0.37, np.array([1.0, 2.0, 3.0]), np.eye(3))
    assert np.array_equal(x, [1.37, 2.0, 3.0])
    assert np.array_equal(F, np.eye(3))


def test_pure_twist_keeps_a_straight_centerline():
    tau = 250.0
    x, F = step_world(np.array([0.0, 0.0, tau]), 0.02, np.zeros(3), np.eye(3))
    np.testing.assert_allclose(x, [0.02, 0.0, 0.0], rtol=0, atol=1e-17)
    c, s = np.cos(tau * 0.02), np.sin(tau * 0.02)
    np.testing.assert_allclose(F[1], [0.0, c, s], rtol=0, atol=ROUNDOFF)


def test_series_and_closed_forms_agree_across_threshold():
    for y in (1.0 - 1e-12, 1.0, 1.0 + 1e-12, 0.999, 1.001):
        x = np.sqrt(y)
        closed = (
            np.sin(x) / x,
            (1 - np.cos(x)) / y,
            (x - np.sin(x)) / (x * y),
            (y / 2 - 1 + np.cos(x)) / (y * y),
        )
        got = helix_coefficients(y)
        np.testing.assert_allclose(got, closed, rtol=1e-13)
    # limits at zero
    np.testing.assert_allclose(helix_coefficients(0.0), (1.0, 0.5, 1.0 / 6.0, 1.0 / 24.0), rtol=0, atol=0)
    np.testing.assert_allclose(helix_coefficient_derivatives(0.0), (-1.0 / 24.0, -1.0 / 120.0), rtol=0, atol=1e-18)


def test_coefficient_derivatives_match_finite_differences():
    for y in (1e-3, 0.5, 0.99, 1.01, 3.0, 50.0):
        h = 1e-6 * max(y, 1.0)
        fd_b = (helix_coefficients(y + h)[1] - helix_coefficients(y - h)[1]) / (2 * h)
        fd_c = (helix_coefficients(y + h)[2] - helix_coefficients(y - h)[2]) / (2 * h)
        bp, cp = helix_coefficient_derivatives(y)
        np.testing.assert_allclose([bp, cp], [fd_b, fd_c], rtol=FINITE_DIFFERENCE, atol=1e-12)


def complex_step_derivatives(omega, sigma, F, h=1e-30):
    """d(point)/d omega_k and the frame's rotation vector, by complex step (exact to round-off)."""
    R = np.empty((3, 3))
    P = np.empty(3)
    Q = np.empty(3)
    element_step(omega[2], omega[0], omega[1], sigma, R, P, Q)
    Rc = np.empty((3, 3), complex)
    Pc = np.empty(3, complex)
    Qc = np.empty(3, complex)
    dx = np.empty((3, 3))
    dth = np.empty((3, 3))
    for k in range(3):
        w = np.array([omega[2], omega[0], omega[1]], complex)
        w[(k + 1) % 3] += 1j * h
        element_step(w[0], w[1], w[2], sigma, Rc, Pc, Qc)
        S = (Rc.imag / h) @ R.T  # [dphi] = dR R^T, skew
        dphi = np.array([S[2, 1], S[0, 2], S[1, 0]])
        dx[k] = F.T @ (Pc.imag / h)
        dth[k] = F.T @ dphi
    return dx, dth


@pytest.mark.parametrize("scale", [0.0, 1e-8, 1e-2, 1.0, 50.0, 1e3, 1e5])
@pytest.mark.parametrize("sigma", [1e-6, 1e-2, 0.3, 1.0])
def test_element_derivatives_match_complex_step(rng, scale, sigma):
    omega = rng.normal(size=3) * scale
    F = random_frame(rng)
    dx = np.empty((3, 3))
    dth = np.empty((3, 3))
    element_derivatives(omega, sigma, F, dx, dth)
    dx_ref, dth_ref = complex_step_derivatives(omega, sigma, F)
    np.testing.assert_allclose(dx, dx_ref, rtol=0, atol=ROUNDOFF * max(np.abs(dx_ref).max(), 1e-300))
    np.testing.assert_allclose(dth, dth_ref, rtol=0, atol=ROUNDOFF * max(np.abs(dth_ref).max(), 1e-300))


def test_element_derivatives_match_finite_differences(rng):
    omega = rng.normal(size=3) * 20.0
    sigma = 0.07
    F = random_frame(rng)
    dx = np.empty((3, 3))
    dth = np.empty((3, 3))
    element_derivatives(omega, sigma, F, dx, dth)
    h = 1e-6
    for k in range(3):
        plus, minus = omega.copy(), omega.copy()
        plus[k] += h
        minus[k] -= h
        xp, Fp = step_world(plus, sigma, np.zeros(3), F)
        xm, Fm = step_world(minus, sigma, np.zeros(3), F)
        np.testing.assert_allclose(dx[k], (xp - xm) / (2 * h), rtol=FINITE_DIFFERENCE, atol=1e-10)
        # the frame turns by dth: dF rows = dth x rows
        _, F0 = step_world(omega, sigma, np.zeros(3), F)
        dF = (Fp - Fm) / (2 * h)
        np.testing.assert_allclose(dF, np.cross(dth[k], F0), rtol=FINITE_DIFFERENCE, atol=1e-10)


@pytest.mark.parametrize("n", [1, 4, 40])
def test_chain_is_g1_continuous(rng, n):
    omega = rng.normal(size=(n, 3)) * 40.0
    length = rng.uniform(1e-3, 0.05, size=n)
    root = rng.normal(size=3)
    F0 = random_frame(rng)
    starts = np.concatenate([[0.0], np.cumsum(length)])
    eps = 1e-9
    s = np.concatenate([starts[1:-1] - eps, starts[1:-1] + eps]) if n > 1 else np.array([0.5 * length[0]])
    x = np.empty((len(s), 3))
    F = np.empty((len(s), 3, 3))
    frames_at(root, F0, omega, length, s, x, F)
    if n > 1:
        half = n - 1
        # position and frame continuous across each joint (the gap is the eps step itself)
        np.testing.assert_allclose(x[:half], x[half:], rtol=0, atol=3 * eps)
        np.testing.assert_allclose(F[:half], F[half:], rtol=0, atol=eps * 40.0 * np.sqrt(3) * 3)
    # unit speed: the centerline is parametrised by arc length
    dense = np.linspace(0.0, starts[-1], 2001)
    pts = np.empty((len(dense), 3))
    points_at(root, F0, omega, length, dense, pts)
    arc = np.linalg.norm(np.diff(pts, axis=0), axis=1).sum()
    assert arc == pytest.approx(starts[-1], rel=1e-4)


def test_frames_stay_orthonormal_over_long_curly_chains(rng):
    n = 2000
    omega = rng.normal(size=(n, 3)) * 1e4
    length = np.full(n, 1e-3)
    xs = np.empty((n + 1, 3))
    Fs = np.empty((n + 1, 3, 3))
    chain(np.zeros(3), np.eye(3), omega, length, xs, Fs)
    gram = np.einsum("nij,nkj->nik", Fs, Fs)
    assert np.abs(gram - np.eye(3)).max() < 1e-12
    assert np.all(np.linalg.det(Fs) > 0)
