"""The library at the extremes of real hair.

Every check is against mathematics computed here: the helix about its constant Darboux axis
(Rodrigues' formula) and its complex-step derivatives, the circular helix of a coil, the
closed-form gravity moment of a straight cantilever, the equilibrium as the gradient of an
energy taken by finite differences (``conftest.energy_gradient``), and the natural map of
the cone problem on a dense ``W`` (hairinv.testing). The extremes: curvature exactly 0 and up to
1e4 1/m, 1 mm coils, elements from 1e-6 m to 1 m, strands from 1 mm to 2 m, friction 0, 2 and
infinite, gamma from 1e-12 to 1e9, Young's modulus from 1e6 to 1e12 Pa, no gravity, contacts
at element ends and at the root, two identical contacts, two strands lying on each other, a
strand lying along the body, and one groom read in m, cm, mm and inches.

For every inversion: all results finite, the forces in their cones, the input an equilibrium,
and the solver's status honest (for the sweeps, ``CONVERGED`` only where the natural-map residual,
recomputed here, meets the tolerance or their rest-shape bound meets ``rest_tolerance``, ``MAX_ITERS``
only where they ran out; for the interior-point method, the default's choice on these scenes,
``CONVERGED`` only where its rest-shape bound meets ``rest_tolerance``; either bound holds against the
rest shape of sweeps stopped by the residual alone).
"""

from __future__ import annotations

import dataclasses
import re
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import (FINITE_DIFFERENCE, UP, dense_problem, energy_gradient, horizontal_strand, make_contacts,
                      material, strands, three_strands_on_the_body, two_strand_scene)
from hairinv.config import MATERIAL_RANGE, MaterialSettings, SolverSettings
from hairinv.gravity import generalized_gravity
from hairinv.invert import invert
from hairinv.model import Contacts, Helices, Material, stiffness
from hairinv.rod.helix import chain, element_derivatives, element_step, frames_at, points_at
from hairinv.rod.statics import gravity_forces, point_jacobian
from hairinv.solver.interior import mu_in_range
from hairinv.solver.local import CODE_OK, solve_contact
from hairinv.testing import complementarity, delassus_scaling, in_cone, in_dual_cone, natural_residual

EPS = np.finfo(float).eps
hyp = settings(max_examples=12, deadline=None, derandomize=True)
# magnitudes drawn on a log scale
log10 = st.floats(-6.0, 0.0)


def random_frame(seed) -> np.ndarray:
    q, _ = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    return q if np.linalg.det(q) > 0 else -q


# ------------------------------------------------------------------------------------------ helices


def rodrigues(omega, sigma, F0):
    """End point (from the origin) and frame of an element: the rotation by ``|Om| sigma`` about the
    constant axis ``Om = kappa1 n1 + kappa2 n2 + tau t`` and the centerline it sweeps. Written for
    complex ``omega`` too (no abs, no conjugation), so that its complex step is a derivative; without
    cancellation (``1 - cos x = 2 sin^2(x/2)``)."""
    Om = omega[0] * F0[1] + omega[1] * F0[2] + omega[2] * F0[0]
    a = np.sqrt(Om @ Om)
    t0 = F0[0]
    u = Om / a
    x = a * sigma
    ut = u @ t0
    one_minus_cos = 2.0 * np.sin(0.5 * x) ** 2
    point = ut * sigma * u + np.sin(x) / a * (t0 - ut * u) + one_minus_cos / a * np.cross(u, t0)
    frame = np.array([np.cos(x) * v + np.sin(x) * np.cross(u, v) + one_minus_cos * (u @ v) * u for v in F0])
    return point, frame


def kernel_step(omega, sigma, F0):
    R, P, Q = np.empty((3, 3)), np.empty(3), np.empty(3)
    element_step(omega[2], omega[0], omega[1], sigma, R, P, Q)
    return F0.T @ P, R.T @ F0


def test_straight_element_is_a_straight_line_and_its_derivatives_are_the_closed_forms():
    """Curvature exactly 0: the line ``sigma t``, the frame unchanged, bit for bit; the derivatives are
    those of a clamped straight rod: ``dx/dkappa1 = -sigma^2/2 n2``, ``dx/dkappa2 = sigma^2/2 n1``,
    ``dx/dtau = 0``, and the frame turns by ``sigma`` about ``n1``, ``n2`` and ``t``."""
    F0 = random_frame(1)
    for sigma in (1e-6, 1e-3, 0.3, 1.0, 2.0):
        x, F = kernel_step(np.zeros(3), sigma, F0)
        np.testing.assert_array_equal(x, sigma * F0[0])
        np.testing.assert_array_equal(F, F0)
        dx, dth = np.empty((3, 3)), np.empty((3, 3))
        element_derivatives(np.zeros(3), sigma, F0, dx, dth)
        expected_dx = np.array([-0.5 * sigma ** 2 * F0[2], 0.5 * sigma ** 2 * F0[1], np.zeros(3)])
        expected_dth = sigma * np.array([F0[1], F0[2], F0[0]])
        np.testing.assert_allclose(dx, expected_dx, rtol=0, atol=4 * EPS * sigma ** 2)
        np.testing.assert_allclose(dth, expected_dth, rtol=0, atol=4 * EPS * sigma)


@hyp
@given(curvature=st.one_of(st.just(1e4), st.floats(0.0, 4.0).map(lambda e: 10.0 ** e)), sigma=log10,
       seed=st.integers(0, 2 ** 16))
def test_element_step_and_its_derivatives_match_the_rotation_about_the_darboux_axis(curvature, sigma, seed):
    """Curvatures 1 to 1e4 1/m (exactly 1e4 among them) over 1 um to 1 m: up to 1e4 rad in one
    element. Position and frame against Rodrigues' formula, the derivatives against its complex step
    where that is accurate (from 0.1 rad: below, ``sigma - sin(x) / a`` cancels in the reference, and
    tests/test_helix.py checks small angles against the frame ODE)."""
    sigma = 10.0 ** sigma
    rng = np.random.default_rng(seed)
    omega = rng.normal(size=3)
    omega *= curvature / np.linalg.norm(omega)
    F0 = random_frame(seed)
    angle = curvature * sigma
    x, F = kernel_step(omega, sigma, F0)
    x_ref, F_ref = rodrigues(omega, sigma, F0)
    assert np.all(np.isfinite(x)) and np.all(np.isfinite(F))
    # the reference loses eps * angle in its own trigonometric arguments
    tol = 8 * EPS * max(1.0, angle)
    np.testing.assert_allclose(x, x_ref, rtol=0, atol=tol * max(sigma, 1.0 / curvature) + EPS * sigma)
    np.testing.assert_allclose(F, F_ref, rtol=0, atol=tol)
    np.testing.assert_allclose(F @ F.T, np.eye(3), rtol=0, atol=8 * EPS)
    dx, dth = np.empty((3, 3)), np.empty((3, 3))
    element_derivatives(omega, sigma, F0, dx, dth)
    assert np.all(np.isfinite(dx)) and np.all(np.isfinite(dth))
    # the complex-step reference from 0.1 rad only (see the docstring); the checks above hold everywhere
    if angle >= 0.1:
        h = 1e-30
        for k in range(3):
            w = omega.astype(complex)
            w[k] += 1j * h
            xc, Fc = rodrigues(w, sigma, F0.astype(complex))
            S = (Fc.imag / h).T @ F_ref  # d(F^T) F = [dth]x in world coordinates
            dth_ref = np.array([S[2, 1], S[0, 2], S[1, 0]])
            scale_x = np.abs(xc.imag / h).max()
            np.testing.assert_allclose(dx[k], xc.imag / h, rtol=0,
                                       atol=1e-13 * max(1.0, angle) * max(scale_x, sigma ** 2))
            np.testing.assert_allclose(dth[k], dth_ref, rtol=0, atol=1e-13 * max(1.0, angle) * sigma)


def circular_helix(radius, pitch):
    """The coil of ``radius`` rising ``pitch`` per turn about +z: its material Darboux components in the
    Frenet frame (kappa1 = 0, kappa2 = curvature, tau = torsion) and its closed-form point and frame."""
    c = np.hypot(radius, pitch / (2 * np.pi))
    h = pitch / (2 * np.pi)

    def at(s):
        phi = np.asarray(s) / c
        x = np.stack([radius * np.cos(phi), radius * np.sin(phi), h * phi], axis=-1)
        t = np.stack([-radius / c * np.sin(phi), radius / c * np.cos(phi), np.full_like(phi, h / c)], axis=-1)
        n = np.stack([-np.cos(phi), -np.sin(phi), np.zeros_like(phi)], axis=-1)
        return x, np.stack([t, n, np.cross(t, n)], axis=-2)

    return np.array([0.0, radius / c ** 2, h / c ** 2]), at


@pytest.mark.parametrize("pitch", [0.0, 1e-3, 5e-3])
def test_a_one_millimetre_coil_follows_the_circular_helix(pitch):
    """A coil of 1 mm radius (curvature 1000 1/m), 30 turns in elements of uneven lengths, some of
    them 1 um long: points and frames along the chain against the circular helix."""
    omega_e, at = circular_helix(1e-3, pitch)
    c = np.hypot(1e-3, pitch / (2 * np.pi))
    total = 30 * 2 * np.pi * c
    rng = np.random.default_rng(5)
    cuts = np.sort(np.concatenate([rng.uniform(0, total, 25), [0.3 * total + 1e-6, 0.6 * total + 2e-6]]))
    cuts = np.concatenate([cuts, [0.3 * total, 0.6 * total, 0.6 * total + 1e-6]])
    edges = np.unique(np.concatenate([[0.0], np.sort(cuts), [total]]))
    length = np.diff(edges)
    assert length.min() < 2e-6
    omega = np.tile(omega_e, (len(length), 1))
    x0, F0 = at(0.0)
    s = np.concatenate([edges, np.linspace(0.0, total, 997)])
    x, F = np.empty((len(s), 3)), np.empty((len(s), 3, 3))
    frames_at(x0, F0, omega, length, s, x, F)
    x_ref, F_ref = at(s)
    # round-off grows with the number of elements and the turns made
    np.testing.assert_allclose(x, x_ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(F, F_ref, rtol=0, atol=1e-10)
    xs, Fs = np.empty((len(length) + 1, 3)), np.empty((len(length) + 1, 3, 3))
    chain(x0, F0, omega, length, xs, Fs)
    np.testing.assert_allclose(xs, at(edges)[0], rtol=0, atol=1e-12)


def test_point_jacobian_of_a_strand_of_curvature_1e4_matches_finite_differences():
    """Three 1 mm elements at 1e4 1/m (10 rad each) and a 1 um one: the derivatives of a point at the tip,
    at an element end and at the root against central differences of the points themselves."""
    rng = np.random.default_rng(11)
    omega = rng.normal(size=(4, 3))
    omega *= 1e4 / np.linalg.norm(omega, axis=1, keepdims=True)
    length = np.array([1e-3, 1e-6, 1e-3, 1e-3])
    root, frame0 = np.zeros(3), random_frame(2)
    for s in (0.0, 1e-3, 1e-3 + 1e-6, length.sum()):
        J = np.empty((4, 3, 3))
        point_jacobian(root, frame0, omega, length, s, J)
        assert np.all(np.isfinite(J))
        fd = np.zeros_like(J)
        h = 1e-6 * 1e4
        for e in range(4):
            for k in range(3):
                pts = []
                for sign in (1.0, -1.0):
                    w = omega.copy()
                    w[e, k] += sign * h
                    p = np.empty((1, 3))
                    points_at(root, frame0, w, length, np.array([s]), p)
                    pts.append(p[0])
                fd[e, k] = (pts[0] - pts[1]) / (2 * h)
        if s == 0.0:
            assert np.all(J == 0.0)  # nothing moves the clamped root
        np.testing.assert_allclose(J, fd, rtol=0, atol=FINITE_DIFFERENCE * max(np.abs(fd).max(), 1e-300))


@hyp
@given(exponents=st.lists(log10, min_size=1, max_size=6))
def test_gravity_on_a_horizontal_cantilever_of_any_element_lengths(exponents):
    """Elements from 1 um to 1 m (strands up to 6 m): the bending force of every element is the gravity
    moment of the rod beyond each of its points, integrated over it: ``-lam g ((L-a)^3 - (L-b)^3) / 6``."""
    length = 10.0 ** np.array(exponents)
    n = len(length)
    lam, g = 1e-5, np.array([0.0, -9.81, 0.0])
    force = np.empty((n, 3))
    gravity_forces(np.zeros(3), np.eye(3), np.zeros((n, 3)), length, lam, g, force)
    L = length.sum()
    b = np.cumsum(length)
    a = b - length
    expected = -lam * 9.81 * ((L - a) ** 3 - (L - b) ** 3) / 6.0
    np.testing.assert_allclose(force[:, 1], expected, rtol=1e-12, atol=1e-14 * lam * 9.81 * L ** 3)
    assert np.all(force[:, [0, 2]] == 0.0)


# ------------------------------------------------------------------------------------------ inversion


def weight_of(helices, mat):
    """The force the tolerance is relative to: the heaviest strand's weight (at 9.81 m/s^2 without gravity)."""
    g = np.linalg.norm(mat.gravity)
    lengths = np.add.reduceat(helices.length, helices.offsets[:-1])
    return mat.linear_density * (g if g > 0 else 9.81) * lengths.max()


def checked_inversion(helices, contacts, mat, tolerance=1e-8, max_sweeps=20000, method="sweeps", **solver):
    """Invert, then check everything the module docstring promises, independently; returns (model, report).
    With the interior-point method (``method`` interior-point or auto), its status is checked against the
    rest shape of the sweeps at ``tolerance`` (:func:`interior_status_is_honest`). The sweeps stop at
    ``tolerance`` alone unless ``rest_tolerance`` is given (tests/test_invert.py tests their bound's stop)."""
    if method == "sweeps":
        solver.setdefault("rest_tolerance", 1e-300)
    settings = SolverSettings(**{"tolerance": tolerance, "max_sweeps": max_sweeps, "method": method, **solver})
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # no inf * 0 or 0 / 0 on the way
        model, report = invert(helices, contacts, mat, settings)
    result = report.result
    for name in ("omega_rest", "force", "rest"):
        assert np.all(np.isfinite(getattr(model, name))), name
    assert np.isfinite(result.residual) and np.isfinite(result.relative_residual)
    if model.stability_margin is not None:
        assert not np.any(np.isnan(model.stability_margin))
    if contacts is None:
        contacts = Contacts.empty()
    # the cones the forces were found in: the declared friction less its reserve (inside the declared cones)
    r, mu = model.force, contacts.mu * (1.0 - settings.friction_reserve)
    assert np.all(in_cone(r, mu, atol=0.0, rtol=1e-12))  # exactly: projected onto the cones
    # the equilibrium, from the energy, at the material's stiffness (omega_rest) ...
    grad, _ = energy_gradient(helices, contacts, model, mat)
    load = np.abs(stiffness(helices, mat) * (helices.omega - model.omega_rest).ravel()).max()
    scale = max(np.abs(generalized_gravity(helices, mat)).max(), load, 1e-300)
    assert np.abs(grad).max() <= FINITE_DIFFERENCE * scale
    # ... and the stiffened strands' rest shape holds the same load at their stiffness
    if model.stiffening is not None:
        stiffened = stiffness(helices, mat, model.stiffening) * (helices.omega - model.rest).ravel()
        np.testing.assert_allclose(stiffened, stiffness(helices, mat) * (helices.omega - model.omega_rest).ravel(),
                                   rtol=0, atol=1e-9 * scale)
    # an honest status
    if settings.target != "gravity-only" and contacts.n_contacts:
        W, b, _, _ = dense_problem(helices, contacts, mat, model)
        residual = float(natural_residual(r, (W @ r.ravel() + b).reshape(-1, 3), mu, delassus_scaling(W)).max())
        target = tolerance * weight_of(helices, mat)
        assert result.status in ("CONVERGED", "MAX_ITERS")
        # the residual reported is that of the forces returned (to the round-off of recomputing it here, a
        # few ulps of the largest force: levers near a root of metre-long elements carry thousands of weights)
        assert abs(result.residual - residual) <= 1e-3 * target + 1e-6 * residual \
            + 64 * np.finfo(float).eps * np.abs(r).max(initial=0.0)
        # the steps decided the status (friction within their range: the sweeps had nothing to finish)
        if result.method == "interior-point" and np.all(mu_in_range(mu)):
            assert result.bound_from == "interior-point"
            interior_status_is_honest(helices, contacts, mat, settings, model, result)
        else:  # the sweeps: the residual or their rest-shape bound
            met = result.rest_bound <= settings.rest_tolerance
            if result.status == "CONVERGED":
                assert residual <= target * (1 + 1e-6) or met
            else:
                assert result.sweeps == max_sweeps and residual > target * (1 - 1e-6) and not met
            bound_holds(helices, contacts, mat, settings, model, result.rest_bound)
    return model, report


def bound_holds(helices, contacts, mat, settings, model, bound):
    """The rest shape is at most ``bound`` (rms over elements, 1/m) from the one the sweeps reach at the
    settings' residual tolerance alone (when they converge, and up to what that tolerance resolves)."""
    assert np.isfinite(bound) and bound >= 0.0
    tight = dataclasses.replace(settings, method="sweeps", rest_tolerance=1e-300)
    reference, report = invert(helices, contacts, mat, tight)
    if report.result.status == "CONVERGED":
        distance = np.sqrt(np.mean(np.sum((model.omega_rest - reference.omega_rest) ** 2, axis=1)))
        sag = np.abs(generalized_gravity(helices, mat).ravel() / stiffness(helices, mat)).max()
        assert distance <= bound + 1e-6 * max(sag, 1.0)


def interior_status_is_honest(helices, contacts, mat, settings, model, result):
    """The interior-point method's CONVERGED means its rest-shape bound is within ``rest_tolerance``, and the
    bound holds: the rest shape is at most that far (rms over elements, 1/m) from the one the sweeps reach
    at the same settings' tolerance (when they converge, and up to what that tolerance resolves)."""
    assert (result.status == "CONVERGED") == (result.rest_bound <= settings.rest_tolerance)
    bound_holds(helices, contacts, mat, settings, model, result.rest_bound)


@pytest.mark.parametrize("mu", [0.0, 2.0, np.inf])
@pytest.mark.parametrize("scene", ["resting", "two strands"])
def test_friction_zero_two_and_infinite(mu, scene):
    """mu = 0 carries no friction at all, mu = inf any (the half-space r_N >= 0)."""
    if scene == "resting":
        helices = strands([horizontal_strand(curl=4.0)])
        tilted = UP + np.array([0.4, 0.0, 0.3])
        contacts = make_contacts(helices, [(0, s, -1, 0.0, tilted, mu) for s in (0.05, 0.08, 0.115)])
    else:
        helices, contacts = two_strand_scene(mu=mu)
    model, report = checked_inversion(helices, contacts, material())
    assert report.result.status == "CONVERGED" and report.carrying > 0
    if mu == 0.0:
        assert np.all(model.force[:, 1:] == 0.0)
    if mu == np.inf:
        # infinite friction holds more than any finite one: the rest shape is at least as close to the input
        finite, _ = checked_inversion(helices, dataclasses.replace(contacts, mu=np.full(contacts.n_contacts, 2.0)),
                                      material())
        drift = np.sum((model.omega_rest - helices.omega) ** 2)
        sag = np.abs(generalized_gravity(helices, material()).ravel() / stiffness(helices, material())).max()
        assert drift <= np.sum((finite.omega_rest - helices.omega) ** 2) * (1 + 1e-6) + (1e-6 * sag) ** 2


def test_the_status_is_that_of_the_forces_returned():
    """The local solves meet the cones to about 1e-12 of the force, and the forces are projected onto them
    before they are returned. The status used to be decided, and the residual reported, before that
    projection: here (two contacts at the tip of a strand with elements from 1 cm to 1 m) the solver said
    CONVERGED at sweep 0 with 2.92e-12 N for a tolerance of 3.00e-12 N, and returned forces whose
    residual is 3.33e-12 N."""
    length = 10.0 ** np.array([-0.0078125, 0.0, -2.0, 0.0])
    omega = np.zeros((4, 3))
    omega[:, 1] = 24.0
    helices = strands([(np.zeros(3), (1.0, 0.0, 0.0), omega, length)])
    places = np.concatenate([np.cumsum(length), [length.sum()]])
    contacts = make_contacts(helices, [(0, s, -1, 0.0, UP, 0.3) for s in places])
    _, report = checked_inversion(helices, contacts, material(), max_sweeps=2000)
    assert report.result.status == "CONVERGED"


@pytest.mark.parametrize("mu", [0.0, 0.3, 2.0])
def test_body_contacts_solved_together_report_the_residual_of_the_forces_returned(mu):
    """Body contacts only: each strand's contacts are first solved together by Newton, whose iterates meet
    the cones only in the limit. Its forces used to be measured before their projection onto the cones:
    at mu = 2 here the solver said CONVERGED without a sweep, with the projected forces' residual at 1.3
    times the tolerance; now the Newton keeps the projected iterate that meets it."""
    helices, contacts = three_strands_on_the_body(mu)
    _, report = checked_inversion(helices, contacts, material(), tolerance=1e-6)
    assert report.result.status == "CONVERGED" and report.result.sweeps == 0


@pytest.mark.parametrize("gamma", [1e-12, 1e-9, 1e-6, 1e-3, 1.0, 1e3, 1e6, 1e9])
def test_gamma_from_1e_minus_12_to_1e9(gamma):
    helices, contacts = two_strand_scene()
    model, report = checked_inversion(helices, contacts, material(), gamma=gamma)
    assert report.result.status == "CONVERGED"


@hyp
@given(exponent=st.floats(6.0, 12.0))
def test_youngs_modulus_from_1e6_to_1e12(exponent):
    """A soft rod's ``H K^-2 H^T`` reaches 1e20 where gamma is 1e-3: the blocks of ``W`` are singular to
    working precision (gamma lost in the sum; before the fix the local solve refused them as not positive
    definite, and a Young's modulus of 1e8 Pa ended the inversion with NUMERICAL_ERROR)."""
    helices, contacts = two_strand_scene()
    mat = material(youngs_modulus=10.0 ** exponent)
    model, report = checked_inversion(helices, contacts, mat)
    assert report.result.status == "CONVERGED"


@pytest.mark.parametrize("exponent", [6.0, 8.0])
def test_soft_rods_with_stabilisation_off(exponent):
    helices, contacts = two_strand_scene()
    _, report = checked_inversion(helices, contacts, material(youngs_modulus=10.0 ** exponent), stabilize="off")
    assert report.result.status == "CONVERGED" and report.unstable > 0


def test_a_block_singular_to_working_precision_is_solved_not_refused():
    """``W = Z^T Z + gamma I`` with ``Z`` two rows of 1e10 (a contact point that moves in two directions
    only) and gamma 1e-3: in floating point the sum is not positive definite (its Cholesky fails), gamma
    being lost next to 1e20. The local solve takes it as the semidefinite matrix it is to working
    precision (it used to refuse it as NUMERICAL_ERROR) and returns the solution of the contact law,
    checked from the definitions: r in the cone, u in the dual cone, r . u = 0, relative to the data."""
    for seed in (1, 2, 3):
        Z = np.random.default_rng(seed).normal(size=(2, 3)) * 1e10
        W = Z.T @ Z + 1e-3 * np.eye(3)
        with pytest.raises(np.linalg.LinAlgError):
            np.linalg.cholesky(W)
        for mu in (0.0, 0.3, 2.0, np.inf):
            for b in (np.array([-1.0, 0.2, 0.1]), np.array([-1.0, 3.0, -2.0]), np.array([2.0, 0.0, 0.0])):
                b = Z.T @ (Z @ b) / 1e10  # a load the point can feel (in the range of W, as H D (...) is)
                r = np.zeros(3)
                status, res = solve_contact(W, b, mu, r, 1e-12, 50, False)
                assert status == CODE_OK and np.isfinite(res) and np.all(np.isfinite(r))
                u = W @ r + b
                size_u = np.abs(b).max()
                size_r = max(np.abs(r).max(), 1e-300)
                assert in_cone(r, mu, atol=0.0, rtol=1e-12)
                assert in_dual_cone(u, mu, 1e-9 * size_u)
                assert abs(complementarity(r, u)) <= 1e-9 * size_r * size_u


def test_contacts_at_element_ends_and_at_the_root():
    """Contacts exactly at every element end, the root (s = 0: the clamped point, whose rows of H are zero
    and whose force only gamma fixes: zero) and the tip."""
    helices = strands([horizontal_strand(n=4, total=0.12, curl=2.0)])
    ends = [0.0, 0.03, 0.06, 0.09, 0.12]
    for mu in (0.0, 0.3, np.inf):
        contacts = make_contacts(helices, [(0, s, -1, 0.0, UP, mu) for s in ends])
        model, report = checked_inversion(helices, contacts, material())
        assert report.result.status == "CONVERGED"
        assert np.all(model.force[0] == 0.0)
        root_only = make_contacts(helices, [(0, 0.0, -1, 0.0, UP, mu)])
        model, report = checked_inversion(helices, root_only, material())
        assert report.result.status == "CONVERGED" and np.all(model.force == 0.0)


@pytest.mark.parametrize("mu", [0.0, 0.3, np.inf])
def test_two_identical_contacts_act_as_one(mu):
    """Two identical contacts: W has two equal block rows, and only the sum of their forces is felt. The
    pair holds the strand as the one contact does (the same rest shape and total force); with gamma of
    the order of W's diagonal, which then decides the split, they share the load equally. With the paper's
    single gamma: solver.gamma_relative weighs each copy by its own diagonal, so the pair is one contact of
    half the weight; there the problem is strictly convex and symmetric in the pair, which shares equally."""
    helices = strands([horizontal_strand(n=4, total=0.12, curl=3.0)])
    contacts = make_contacts(helices, [(0, 0.1, -1, 0.0, UP, mu)] * 2 + [(0, 0.06, -1, 0.0, UP, mu)])
    single_contacts = contacts.subset([0, 2])
    mat = material()
    for gamma in (1e-3, None):
        if gamma is None:
            probe, _ = checked_inversion(helices, contacts, mat, max_sweeps=1)
            W, *_ = dense_problem(helices, contacts, mat, probe)
            gamma = float(np.mean(np.diag(W)))
        # (W is singular to working precision along the pair's difference: the rest shapes agree to
        # what the tolerance resolves, 6e-8 here at 1e-10, 5e-6 at 1e-8)
        model, report = checked_inversion(helices, contacts, mat, gamma=gamma, tolerance=1e-10, gamma_relative=0.0)
        single, _ = checked_inversion(helices, single_contacts, mat, gamma=gamma, tolerance=1e-10,
                                      gamma_relative=0.0)
        assert report.result.status == "CONVERGED" and report.carrying > 0
        sag = np.abs(single.omega_rest - helices.omega).max()
        if gamma < 1.0:  # gamma negligible: the pair is the one contact
            np.testing.assert_allclose(model.omega_rest, single.omega_rest, rtol=0, atol=1e-6 * sag)
            np.testing.assert_allclose(model.force[0] + model.force[1], single.force[0], rtol=0,
                                       atol=1e-6 * np.abs(single.force).max())
        else:
            np.testing.assert_allclose(model.force[0], model.force[1], rtol=0, atol=1e-6 * np.abs(model.force).max())
    shared, report = checked_inversion(helices, contacts, mat, tolerance=1e-10, gamma_relative=1e-4)
    assert report.result.status == "CONVERGED" and report.carrying > 0
    np.testing.assert_allclose(shared.force[0], shared.force[1], rtol=0, atol=1e-6 * np.abs(shared.force).max())


def test_two_strands_lying_exactly_on_each_other():
    """Two identical strands, one on the other (the same centre line, from the same root): hair-hair
    contacts at equal arc lengths, at the root (both sides clamped: zero rows) and at element ends; the
    lower strand on the body."""
    helices = strands([horizontal_strand(n=4, total=0.1, curl=3.0), horizontal_strand(n=4, total=0.1, curl=3.0)])
    specs = [(0, s, -1, 0.0, UP, 0.3) for s in (0.05, 0.09)]
    specs += [(0, s, 1, s, -UP, 0.3) for s in (0.0, 0.03, 0.05, 0.075, 0.1)]
    contacts = make_contacts(helices, specs)
    model, report = checked_inversion(helices, contacts, material())
    assert report.result.status == "CONVERGED" and report.carrying > 0


def test_a_strand_lying_entirely_along_the_body():
    """A support at every element end and midpoint, the root included: the body carries the weight, and
    the rest shape stays far closer to the input than the gravity-only one."""
    n = 8
    helices = strands([horizontal_strand(n=n, total=0.16)])
    contacts = make_contacts(helices, [(0, s, -1, 0.0, UP, 0.3) for s in np.linspace(0.0, 0.16, 2 * n + 1)])
    mat = material()
    model, report = checked_inversion(helices, contacts, mat, tolerance=1e-5)
    baseline, _ = checked_inversion(helices, None, mat, target="gravity-only")
    assert report.result.status == "CONVERGED"
    assert np.abs(model.omega_rest - helices.omega).max() < 2e-3 * np.abs(baseline.omega_rest - helices.omega).max()
    assert model.force[:, 0].sum() == pytest.approx(mat.linear_density * 9.81 * 0.16, rel=0.1)


def _extreme_scene(case):
    """(helices, contacts, material, solver settings) of the extremes above, for the default method."""
    mat = material()
    if case.startswith("gamma"):
        return (*two_strand_scene(), mat, {"gamma": float(case.split()[1])})
    if case.startswith("E"):
        return (*two_strand_scene(), material(youngs_modulus=float(case.split()[1])), {})
    if case.startswith("mu"):
        return (*two_strand_scene(mu=float(case.split()[1])), mat, {})
    if case == "on each other":
        helices = strands([horizontal_strand(n=4, total=0.1, curl=3.0), horizontal_strand(n=4, total=0.1, curl=3.0)])
        specs = [(0, s, -1, 0.0, UP, 0.3) for s in (0.05, 0.09)]
        specs += [(0, s, 1, s, -UP, 0.3) for s in (0.0, 0.03, 0.05, 0.075, 0.1)]
        return helices, make_contacts(helices, specs), mat, {}
    if case == "along the body":
        helices = strands([horizontal_strand(n=8, total=0.16)])
        return helices, make_contacts(helices, [(0, s, -1, 0.0, UP, 0.3) for s in np.linspace(0.0, 0.16, 17)]), mat, {}
    if case == "element ends and root":
        helices = strands([horizontal_strand(n=4, total=0.12, curl=2.0)])
        return helices, make_contacts(helices, [(0, s, -1, 0.0, UP, 0.3) for s in (0.0, 0.03, 0.06, 0.09, 0.12)]), \
            mat, {}
    if case == "strand of 1 mm":
        helices = strands([horizontal_strand(n=4, total=1e-3, curl=1e3)])
        return helices, make_contacts(helices, [(0, f * 1e-3, -1, 0.0, UP, 0.3) for f in (0.5, 0.8, 1.0)]), mat, {}
    if case == "no gravity":
        weightless = dataclasses.replace(Material.from_settings(MaterialSettings(), UP), gravity=np.zeros(3))
        helices = strands([horizontal_strand(n=5, total=0.1, curl=-20.0),
                           horizontal_strand(n=4, total=0.08, curl=5.0, root=(0.0, 0.0, 0.001))])
        contacts = make_contacts(helices, [(0, 0.08, -1, 0.0, UP, 0.3), (0, 0.05, 1, 0.05, -UP, 0.3),
                                           (1, 0.07, -1, 0.0, UP, 0.3)])
        return helices, contacts, weightless, {"target": "zero"}
    raise ValueError(case)


@pytest.mark.parametrize("case", ["gamma 1e-12", "gamma 1e9", "E 1e6", "E 1e12", "mu 0", "mu inf", "on each other",
                                  "along the body", "element ends and root", "strand of 1 mm", "no gravity"])
def test_auto_at_the_extremes(case):
    """solver.method = auto takes the interior-point method on these small scenes: every result finite, the
    equilibrium exact, forces in the cones, and its status honest (its bound, at 1e-4 of the scene's sag,
    holds against the sweeps' rest shape at 1e-8); friction outside its range is finished by the sweeps."""
    helices, contacts, mat, extra = _extreme_scene(case)
    # 1/m, the largest curvature change the weight would cause (at 9.81 m/s^2 in the scene without gravity)
    sag = np.abs(generalized_gravity(helices, material()).ravel() / stiffness(helices, mat)).max()
    model, report = checked_inversion(helices, contacts, mat, method="auto",
                                      rest_tolerance=1e-4 * sag, max_iterations=200, **extra)
    assert report.result.method == "interior-point"
    assert report.result.status == "CONVERGED"


def _floor(width=4.0):
    """A flat floor (a box as the body) whose top face is 1 mm below the plane y = 0."""
    import trimesh

    from hairinv.contacts.body import BodyMesh

    floor = trimesh.creation.box(extents=(width, 0.2, width))
    floor.apply_translation((0.3, -0.1 - 1e-3, 0.0))
    return BodyMesh.from_mesh(floor)


def _coils(count):
    """``count`` 1 mm coils (pitch 2 mm, 20 turns in 40 elements) lying side by side along +x, 1.5 mm apart."""
    omega_e, at = circular_helix(1e-3, 2e-3)
    _, F0 = at(0.0)
    Rw = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])  # the coil's axis (+z) along +x, +y up
    n = 40
    total = 20 * 2 * np.pi * np.hypot(1e-3, 2e-3 / (2 * np.pi))
    return Helices(np.array([[0.0, 0.0, 1.5e-3 * k] for k in range(count)]), np.stack([F0 @ Rw.T] * count),
                   np.arange(0, n * count + 1, n, dtype=np.int64), np.full(n * count, total / n),
                   np.tile(omega_e, (n * count, 1)), np.zeros((count, 2)))


@pytest.mark.parametrize("case", ["coincident", "coincident straight", "on the body", "elements of 1 um",
                                  "two metres", "coils"])
def test_detected_contacts_at_the_extremes(case):
    """Contacts detected (not built by hand) on a flat floor: two strands with the same centre line
    (the distance between them is zero, so their normal comes from the geometry), a strand whose centre
    line lies on the body's surface, elements of 1 um, a 2 m strand, two 1 mm coils touching each other.
    Every contact is finite with an orthonormal frame, and the inversion passes every check."""
    from hairinv.config import Settings
    from hairinv.contacts import detect_contacts

    helices = {
        "coincident": lambda: strands([horizontal_strand(n=4, total=0.1, curl=3.0)] * 2),
        "coincident straight": lambda: strands([horizontal_strand(n=4, total=0.1)] * 2),
        "on the body": lambda: strands([horizontal_strand(n=4, total=0.1, root=(0.0, -1e-3, 0.0))]),
        "elements of 1 um": lambda: strands([(np.zeros(3), (1.0, 0.0, 0.0), np.zeros((4, 3)),
                                              np.array([1e-6, 0.05, 1e-6, 0.05]))]),
        "two metres": lambda: strands([horizontal_strand(n=8, total=2.0)]),
        "coils": lambda: _coils(2),
    }[case]()
    contacts, _ = detect_contacts(helices, _floor(), Settings().contacts)
    assert contacts.n_body > 0 and (contacts.n_hair > 0) == (helices.n_strands > 1)
    for name in ("s", "point", "frame", "gap"):
        assert np.all(np.isfinite(getattr(contacts, name))), name
    np.testing.assert_allclose(np.einsum("cij,ckj->cik", contacts.frame, contacts.frame),
                               np.broadcast_to(np.eye(3), (contacts.n_contacts, 3, 3)), rtol=0, atol=1e-12)
    model, report = checked_inversion(helices, contacts, material(), tolerance=1e-6)
    assert report.result.status == "CONVERGED" and report.carrying > 0


@pytest.mark.parametrize("total, n", [(1e-3, 1), (1e-3, 4), (2.0, 2), (2.0, 20)])
def test_strands_of_one_millimetre_and_two_metres(total, n):
    helices = strands([horizontal_strand(n=n, total=total, curl=1.0 / total)])
    contacts = make_contacts(helices, [(0, f * total, -1, 0.0, UP, 0.3) for f in (0.5, 0.8, 1.0)])
    model, report = checked_inversion(helices, contacts, material())
    assert report.result.status == "CONVERGED" and report.carrying > 0


@hyp
@given(exponents=st.lists(log10, min_size=1, max_size=5), curl=st.floats(-50.0, 50.0),
       where=st.lists(st.floats(0.0, 1.0), min_size=1, max_size=4))
def test_elements_from_one_micrometre_to_one_metre(exponents, curl, where):
    """Element lengths drawn from 1 um to 1 m, supports at every element end and at random places."""
    length = 10.0 ** np.array(exponents)
    total = length.sum()
    omega = np.zeros((len(length), 3))
    omega[:, 1] = curl
    helices = strands([(np.zeros(3), (1.0, 0.0, 0.0), omega, length)])
    places = np.concatenate([np.cumsum(length), np.array(where) * total])
    contacts = make_contacts(helices, [(0, s, -1, 0.0, UP, 0.3) for s in places])
    checked_inversion(helices, contacts, material(), max_sweeps=2000)


def test_a_one_millimetre_coil_resting_on_supports():
    """A 1 mm coil (curvature 1000 1/m), 20 turns lying along +x on supports under its lowest points."""
    helices = _coils(1)
    s = np.linspace(0.0, helices.length.sum(), 4001)
    pts = np.empty((len(s), 3))
    points_at(helices.root[0], helices.frame0[0], helices.omega, helices.length, s, pts)
    lows = [s[k] for k in range(1, len(s) - 1) if pts[k, 1] <= pts[k - 1, 1] and pts[k, 1] <= pts[k + 1, 1]]
    assert len(lows) >= 19
    contacts = make_contacts(helices, [(0, sl, -1, 0.0, UP, 0.3) for sl in lows])
    model, report = checked_inversion(helices, contacts, material(), tolerance=1e-6)
    assert report.result.status == "CONVERGED" and report.carrying > 0


@pytest.mark.parametrize("target", ["actual", "zero"])
def test_no_gravity(target):
    """Without gravity the input shape is its own rest shape with no force (target actual); drawn towards
    straight (target zero), the contacts hold what they can. The tolerance is relative to the strands'
    weight at 9.81 m/s^2 (every weight is zero, and a residual relative to zero was 0/0)."""
    mat = Material.from_settings(MaterialSettings(), UP)
    mat = dataclasses.replace(mat, gravity=np.zeros(3))
    helices = strands([horizontal_strand(n=5, total=0.1, curl=-20.0),
                       horizontal_strand(n=4, total=0.08, curl=5.0, root=(0.0, 0.0, 0.001))])
    contacts = make_contacts(helices, [(0, 0.08, -1, 0.0, UP, 0.3), (0, 0.05, 1, 0.05, -UP, 0.3),
                                       (1, 0.07, -1, 0.0, UP, 0.3)])
    model, report = checked_inversion(helices, contacts, mat, target=target)
    assert report.result.status == "CONVERGED"
    assert report.result.relative_residual == report.result.residual / weight_of(helices, mat)
    assert any("no gravity" in line for line in report.lines())
    if target == "actual":
        assert np.all(model.force == 0.0) and np.array_equal(model.omega_rest, helices.omega)
    else:
        assert report.carrying > 0


# ------------------------------------------------------------------------------------------ units


def _write_obj_mesh(path, vertices, faces):
    lines = [f"v {x!r} {y!r} {z!r}\n" for x, y, z in vertices.tolist()]
    lines += [f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in faces.tolist()]
    path.write_text("".join(lines))


def test_one_groom_in_metres_centimetres_millimetres_and_inches(tmp_path):
    """A small groom on a box head, written in m, cm, mm and inches (hair and body alike) and read with
    the matching ``import.units``: the imported points are the same in metres to round-off, and what is
    computed from them (fit, contacts, inversion) agrees to its own accuracy. (The fit is not invariant
    to round-off: its iterations stop at a tolerance, so the 1-ulp differences of the converted input
    move the fitted centre lines by about 4e-11 m and curvatures by 3e-6 1/m.)"""
    import trimesh

    from hairinv import config
    from hairinv.formats import write_curves
    from hairinv.pipeline import prepare
    from hairinv.rod.helix import points_at as centre_points

    box = trimesh.creation.box(extents=(0.2, 0.2, 0.2))
    box.apply_translation((0.0, -0.1, 0.0))
    grooms = []
    for k, z in enumerate((-0.03, 0.0, 0.03)):
        top = [(-0.05 + t, 0.0015 + 0.002 * np.sin(40 * t + k), z + 0.003 * np.sin(30 * t))
               for t in np.linspace(0.0, 0.15, 16)]
        side = [(0.1015, 0.0015 - t, z) for t in np.linspace(0.01, 0.08, 8)]
        grooms.append(np.array(top + side))
    points = np.concatenate(grooms)
    offsets = np.cumsum([0] + [len(g) for g in grooms])
    results = {}
    for unit, metres in config.UNITS.items():
        write_curves(tmp_path / f"hair_{unit}.obj", points / metres, offsets)
        _write_obj_mesh(tmp_path / f"body_{unit}.obj", np.asarray(box.vertices) / metres, np.asarray(box.faces))
        settings = config.apply(config.resolve(), {"import": {"units": unit}})
        scene = prepare(tmp_path / f"hair_{unit}.obj", tmp_path / f"body_{unit}.obj", settings)
        mat = Material.from_settings(settings.material, scene.up)
        model, report = invert(scene.helices, scene.contacts, mat, settings.solver)
        results[unit] = scene, model, report

    def centre_lines(helices):
        out = []
        for k in range(helices.n_strands):
            a, z = helices.offsets[k], helices.offsets[k + 1]
            s = np.linspace(0.0, helices.length[a:z].sum(), 200)
            p = np.empty((len(s), 3))
            centre_points(helices.root[k], helices.frame0[k], helices.omega[a:z], helices.length[a:z], s, p)
            out.append(p)
        return np.concatenate(out)

    scene_m, model_m, report_m = results["m"]
    assert scene_m.contacts.n_body > 0 and report_m.carrying > 0
    for unit, (scene, model, report) in results.items():
        curves = scene.groups["curves"]
        assert curves.attrs["scale_to_m"] == config.UNITS[unit]
        np.testing.assert_allclose(curves["points"], scene_m.groups["curves"]["points"], rtol=4 * EPS, atol=0)
        h, hm = scene.helices, scene_m.helices
        assert np.array_equal(h.offsets, hm.offsets)
        np.testing.assert_allclose(centre_lines(h), centre_lines(hm), rtol=0, atol=1e-9)
        np.testing.assert_allclose(h.fit_error, hm.fit_error, rtol=0, atol=1e-9)
        c, cm = scene.contacts, scene_m.contacts
        assert np.array_equal(c.strand, cm.strand)
        np.testing.assert_allclose(c.s, cm.s, rtol=0, atol=1e-9)
        # (the normals; the tangents are a choice in the normal plane, and a normal within round-off of an
        # axis may get them turned)
        np.testing.assert_allclose(c.frame[:, 0], cm.frame[:, 0], rtol=0, atol=1e-6)
        assert report.result.status == report_m.result.status and np.all(np.isfinite(model.force))
        sag, sag_m = h.omega - model.omega_rest, hm.omega - model_m.omega_rest
        np.testing.assert_allclose(sag, sag_m, rtol=0, atol=1e-5 * np.abs(sag_m).max())


# ------------------------------------------------------------------------------------------ dynamics


@pytest.mark.parametrize("case", ["mu 0", "mu inf", "E 1e6", "E 1e12", "no gravity"])
def test_a_still_step_from_an_inverted_strand_on_a_floor_at_the_extremes(case):
    """A strand lying on a floor (a box), its contacts detected, inverted, and simulated from the model
    with the inversion's forces as the first impulses: the groom stays still (without gravity the
    simulation used to divide by zero in its contact tolerance)."""
    from hairinv.config import Settings
    from hairinv.contacts import detect_contacts
    from hairinv.dynamics.simulate import Motion, Simulation

    body = _floor(1.0)
    helices = strands([horizontal_strand(n=6, total=0.12, curl=3.0 if case == "no gravity" else 0.0)])
    settings = Settings()
    contacts, _ = detect_contacts(helices, body, settings.contacts)
    assert contacts.n_body >= 3
    mat = material(youngs_modulus={"E 1e6": 1e6, "E 1e12": 1e12}.get(case, 4e9))
    solver = {}
    if case.startswith("mu"):
        contacts = dataclasses.replace(contacts, mu=np.full(contacts.n_contacts, 0.0 if case == "mu 0" else np.inf))
    if case == "no gravity":
        mat = dataclasses.replace(mat, gravity=np.zeros(3))
        solver = {"target": "zero"}
    model, report = checked_inversion(helices, contacts, mat, tolerance=1e-6, **solver)
    assert report.result.status == "CONVERGED" and report.carrying > 0
    sim = Simulation(helices, model.rest, mat, body, settings.contacts, settings.dynamics, initial=contacts,
                     initial_force=model.force, stiffening=model.stiffening)
    for _ in range(3):
        step = sim.step(Motion.still(mat.gravity))
        assert step.status == "CONVERGED"
    # the free velocity is of order h g / length ~ 1 1/(m s); what is left is round-off
    assert np.all(np.isfinite(sim.q)) and np.abs(sim.v).max() < 1e-8


# ---------------------------------------------------------------------------- the material's range

#: (setting, value) at each end of hairinv.config.MATERIAL_RANGE
RANGE_ENDS = [(key, end) for key, (lo, hi, _) in MATERIAL_RANGE.items() for end in (lo, hi) if end > 0]


@pytest.mark.parametrize("key, value", RANGE_ENDS, ids=[f"{k}={v:g}" for k, v in RANGE_ENDS])
def test_every_material_constant_at_either_end_of_its_range_inverts(key, value):
    """The two-strand scene inverted with one material constant at an end of its range, by both methods:
    every result finite, the equilibrium and the cones hold, the status is honest (checked_inversion)."""
    helices, contacts = two_strand_scene()
    settings = MaterialSettings(**{key: value})
    mat = Material.from_settings(settings, UP)
    for method in ("sweeps", "auto"):
        model, report = checked_inversion(helices, contacts, mat, method=method)
        assert report.result.status in ("CONVERGED", "MAX_ITERS")


@pytest.mark.parametrize("key, factor", [(k, f) for k in MATERIAL_RANGE for f in (0.5, 2.0)])
def test_a_material_constant_out_of_its_range_is_refused_in_one_sentence(key, factor):
    """Just below or above the range (the values that overflowed or underflowed before: E = 1e-300 Pa gave
    an internal error, a density of 1e300 a NaN model written with exit 0): refused, naming the setting,
    the value and the range."""
    from hairinv.errors import InputError

    lo, hi, unit = MATERIAL_RANGE[key]
    value = (lo if factor < 1 else hi) * factor
    with pytest.raises(InputError, match=re.escape(f"material.{key} is {value!r}; it must be a number from "
                                                   f"{lo:g} to {hi:g} {unit}")):
        Material.from_settings(MaterialSettings(**{key: value}), UP)
