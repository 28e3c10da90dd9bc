"""The law of one contact: Coulomb cone, Fischer-Burmeister function, local solve; Clarabel reference.

Every check is taken from the definitions, not from the kernels' formulas (hairinv.testing): the
cone ``K_mu = {|r_T| <= mu r_N}``, its dual ``K*_mu = {|u_T| <= u_N / mu}``, the polar cone
``-K*_mu``, complementarity ``r . u = 0``; closed-form solutions built by construction;
and Clarabel's interior-point solution of the same SOCQP.
"""

from __future__ import annotations

import sys

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import FINITE_DIFFERENCE, ROUNDOFF
from hairinv.solver.local import (
    LOCAL_TOL,
    CODE_NOT_CONVERGED,
    CODE_NUMERICAL,
    CODE_OK,
    fb_function,
    fb_jacobian,
    natural_residual,
    project_cone,
    relative_residual,
    solve_contact,
)
from hairinv.testing import check_cone_qp, check_coulomb, complementarity, in_cone, in_dual_cone

# Cone membership, Moreau decomposition and FB zeros are exact formulas evaluated in
# floating point: a few ulps of the magnitudes involved.
CONE = 1e-12
# Optimality conditions of a converged local solve (tolerance eps^(3/4) on the relative
# natural-map residual), relative to |b| and rho |r|; W with condition number up to 1e8
# loses up to cond * eps in u = W r + b, so allow 1e-8 there.
OPTIMALITY = 1e-10
OPTIMALITY_ILL = 1e-8
# Clarabel stops at a duality gap ~1e-10; on a second-order cone the gap is quadratic in the
# angular error of the tangential force, so its r is only ~1e-5 accurate (measured: 5e-5 worst,
# 2e-7 median, on cond(W) <= 1e3). The comparison therefore uses the strong-convexity
# certificate |r - r*|^2 <= 2 (f(r) - f*) / lambda_min instead of a fixed relative tolerance.
CLARABEL_FEAS = 1e-8
CLARABEL_MATCH = 1e-4

MUS = [0.0, 1e-3, 0.3, 1.0, 7.0, 1e6, np.inf]
FINITE_MUS = [m for m in MUS if 0.0 < m < np.inf]
hyp = settings(max_examples=60, deadline=None)
# magnitudes 0 or 1e-100..1e3: squares of smaller numbers underflow in the checks themselves
floats = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False).filter(lambda v: v == 0.0 or abs(v) > 1e-100)
vec3 = st.tuples(floats, floats, floats).map(lambda t: np.array(t, dtype=np.float64))


# ----------------------------------------------------------------- independent helpers


def assert_ccp(W, b, mu, r, tol, desaxce=False):
    """K_mu ∋ r ⟂ u(~) ∈ K*_mu, relative to the scales of the problem."""
    rho = np.trace(W) / 3.0
    scale = np.linalg.norm(b) + rho * np.linalg.norm(r)  # the size of u's terms
    if desaxce and mu < np.inf:
        scale *= 1.0 + mu  # mu |u_T| carries mu times u's round-off
    check = check_coulomb if desaxce else check_cone_qp
    # rho r and u on the same scale; |r . u| relative to |r| times it
    check(W, b, r, mu, primal=tol * scale / rho, dual=tol * scale, complementarity=tol * np.linalg.norm(r) * scale)


def random_spd(rng, cond, scale=1.0):
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    ev = np.exp(rng.uniform(0.0, np.log(cond), 3))
    ev[0], ev[1] = 1.0, cond
    return scale * (q * ev) @ q.T


def solve(W, b, mu, r0=None, desaxce=False, max_iter=50):
    r = np.zeros(3) if r0 is None else np.array(r0, dtype=np.float64)
    status, res = solve_contact(np.ascontiguousarray(W, dtype=np.float64), np.asarray(b, dtype=np.float64),
                                float(mu), r, LOCAL_TOL, max_iter, desaxce)
    return status, res, r


def sliding_problem(rng, mu, cond=1e2, scale=1.0):
    """Random W, b whose static solution slides (neither r = 0 nor -W^-1 b is the answer)."""
    while True:
        W = random_spd(rng, cond, scale)
        b = rng.normal(size=3)
        s = -np.linalg.solve(W, b)
        if s[0] >= 0 and np.hypot(s[1], s[2]) <= mu * s[0]:
            continue
        if mu * np.hypot(b[1], b[2]) <= b[0]:
            continue
        return W, b


# ------------------------------------------------------------------------- the cone


@hyp
@given(x=vec3, mu=st.sampled_from(MUS))
def test_projection_is_the_moreau_decomposition(x, mu):
    p = np.empty(3)
    project_cone(x, mu, p)
    scale = max(np.linalg.norm(x), 1e-300)
    assert in_cone(p, mu, CONE * scale)
    # x - P(x) lies in the polar cone -K* and is orthogonal to P(x): P(x) is the projection
    assert in_dual_cone(p - x, mu, CONE * scale)
    assert abs((x - p) @ p) <= CONE * scale**2
    again = np.empty(3)
    project_cone(p, mu, again)
    np.testing.assert_allclose(again, p, rtol=0, atol=CONE * scale)


@pytest.mark.parametrize("mu", MUS)
def test_projection_special_regions(mu):
    out = np.empty(3)
    inside = np.array([2.0, 0.1 * min(mu, 1.0), 0.0])
    project_cone(inside, mu, out)
    np.testing.assert_array_equal(out, inside)
    polar = np.array([-2.0, 0.0, 0.0]) if mu == np.inf else np.array([-2.0, 0.1 / max(mu, 1.0), 0.0])
    project_cone(polar, mu, out)
    np.testing.assert_array_equal(out, [0.0, 0.0, 0.0])
    xn = 0.05 / max(mu, 1.0) if mu < np.inf else 0.05  # outside K_mu, outside the polar cone
    x = np.array([xn, -3.0, 4.0])
    project_cone(x, mu, x)  # in place
    if mu == 0.0:
        np.testing.assert_array_equal(x, [xn, 0.0, 0.0])
    elif mu == np.inf:
        np.testing.assert_array_equal(x, [xn, -3.0, 4.0])
    else:
        # onto the generator (1, mu e): alpha = (x_N + mu |x_T|) / (1 + mu^2)
        alpha = (xn + mu * 5.0) / (1.0 + mu * mu)
        np.testing.assert_allclose(x, alpha * np.array([1.0, -0.6 * mu, 0.8 * mu]), rtol=ROUNDOFF)


@pytest.mark.parametrize("mu", MUS)
def test_natural_residual_is_zero_only_at_solutions(mu):
    r = np.array([1.0, 0.0, 0.0])
    assert natural_residual(r, np.zeros(3), mu) == 0.0  # sticking: u = 0
    assert natural_residual(np.zeros(3), np.array([1.0, 0.0, 0.0]), mu) == 0.0  # take-off
    assert natural_residual(r, np.array([1.0, 0.0, 0.0]), mu) > 0.5  # r.u != 0
    # the De Saxce variant uses u~ = u + mu |u_T| e_N: u = (0, -1, 0) slides against r_T > 0
    if 0.0 < mu < np.inf:
        rs = np.array([1.0, mu, 0.0])
        assert natural_residual(rs, np.array([0.0, -1.0, 0.0]), mu, True) <= CONE * mu
        # statics: u is not in K*; the distance is mu / sqrt(1 + mu^2) by hand
        static = natural_residual(rs, np.array([0.0, -1.0, 0.0]), mu, False)
        assert static == pytest.approx(mu / np.sqrt(1.0 + mu * mu), rel=1e-15 * (1.0 + mu))  # r - P(.) cancels ~mu


# ---------------------------------------------------------------- Fischer-Burmeister


def complementary_pairs(mu, rng):
    """(r, u) pairs with K_mu ∋ r ⟂ u ∈ K*_mu, built by construction."""
    a = rng.uniform(0, 2 * np.pi)
    e = np.array([np.cos(a), np.sin(a)])
    rho, beta = rng.uniform(0.1, 3.0, 2)
    pairs = [(np.zeros(3), np.zeros(3))]
    if mu == 0.0:
        pairs += [(np.array([rho, 0, 0]), np.array([0.0, *(beta * e)])),  # u_T free
                  (np.zeros(3), np.array([beta, *(3 * beta * e)]))]
        return pairs
    if mu == np.inf:
        pairs += [(np.array([rho, *(5 * rho * e)]), np.zeros(3)),
                  (np.array([0.0, *(rho * e)]), np.array([beta, 0, 0])),
                  (np.zeros(3), np.array([beta, 0, 0]))]
        return pairs
    pairs += [
        # sliding: r on the boundary, u on the dual boundary, u_T against r_T
        (rho * np.array([1.0, *(mu * e)]), beta * np.array([mu, *(-e)])),
        # sticking: r inside, u = 0
        (rho * np.array([1.0, *(0.5 * mu * e)]), np.zeros(3)),
        # take-off: r = 0, u inside the dual cone
        (np.zeros(3), beta * np.array([1.0, *(0.5 / mu * e)])),
        # non-strict: r on the boundary with u = 0, r = 0 with u on the dual boundary
        (rho * np.array([1.0, *(mu * e)]), np.zeros(3)),
        (np.zeros(3), beta * np.array([mu, *(-e)])),
    ]
    return pairs


@pytest.mark.parametrize("mu", MUS)
def test_fb_vanishes_on_complementary_pairs(mu, rng):
    phi = np.empty(3)
    for _ in range(20):
        for r, u in complementary_pairs(mu, rng):
            fb_function(r, u, mu, phi)
            scale = max(1.0, mu if mu < np.inf else 1.0) * (np.linalg.norm(r) + np.linalg.norm(u) + 1.0)
            assert np.linalg.norm(phi) <= 8 * CONE * scale, (r, u, phi)


@hyp
@given(r=vec3, u=vec3, mu=st.sampled_from(MUS))
def test_fb_is_nonzero_away_from_solutions(r, u, mu):
    """|FB| and the natural residual vanish together (equivalent up to mu-dependent constants)."""
    phi = np.empty(3)
    fb_function(r, u, mu, phi)
    nat = natural_residual(r, u, mu)
    size = np.linalg.norm(r) + np.linalg.norm(u)
    # measured on 1e5 random pairs: 0.6 nat <= |FB| <= 3.4 nat for mu = 0, 1, inf;
    # the lower constant shrinks like min(mu, 1/mu) through the cone rescaling
    lower = 0.1 if mu in (0.0, np.inf) else 1e-2 * min(1.0, mu, 1.0 / mu)
    assert np.linalg.norm(phi) >= lower * nat - CONE * size
    assert np.linalg.norm(phi) <= 4.0 * nat + CONE * size


@pytest.mark.parametrize("mu", MUS)
def test_fb_jacobian_matches_finite_differences(mu, rng):
    phi, Jr, Ju = np.empty(3), np.empty((3, 3)), np.empty((3, 3))
    plus, minus = np.empty(3), np.empty(3)
    h = 1e-6
    for _ in range(20):
        r, u = rng.normal(size=3), rng.normal(size=3)  # generic: FB is smooth there
        fb_jacobian(r, u, mu, phi, Jr, Ju)
        fb_function(r, u, mu, plus)
        np.testing.assert_allclose(phi, plus, rtol=0, atol=ROUNDOFF)
        for J, which in ((Jr, 0), (Ju, 1)):
            for j in range(3):
                dp = [r.copy(), u.copy()]
                dm = [r.copy(), u.copy()]
                dp[which][j] += h
                dm[which][j] -= h
                fb_function(dp[0], dp[1], mu, plus)
                fb_function(dm[0], dm[1], mu, minus)
                np.testing.assert_allclose(J[:, j], (plus - minus) / (2 * h), rtol=0, atol=FINITE_DIFFERENCE)


# --------------------------------------------------------------- local solve: forms


@pytest.mark.parametrize("desaxce", [False, True])
@pytest.mark.parametrize("mu", [0.0, 0.3, 1e6, np.inf])
def test_take_off(mu, desaxce, rng):
    W = random_spd(rng, 10.0)
    t = rng.normal(size=2)
    if mu == np.inf:
        t[:] = 0.0  # K*_inf is the normal ray
    elif mu > 0.0:
        t *= 0.5 / (mu * np.linalg.norm(t))  # |b_T| = b_N / (2 mu)
    b = np.array([1.0, *t])  # in K*_mu
    status, res, r = solve(W, b, mu, r0=[5.0, 1.0, 1.0], desaxce=desaxce)
    assert status == CODE_OK and res == 0.0
    np.testing.assert_array_equal(r, 0.0)


def test_desaxce_take_off_ignores_the_tangent(rng):
    """Dynamics: u~ = b + mu |b_T| e_N is in K* whenever b_N >= 0, even if b itself is not."""
    W = random_spd(rng, 10.0)
    b = np.array([0.1, 3.0, -2.0])
    status, _, r = solve(W, b, 0.3, desaxce=True)
    assert status == CODE_OK
    np.testing.assert_array_equal(r, 0.0)
    status, _, r = solve(W, b, 0.3, desaxce=False)  # statics: b is not in K*, contact is kept
    assert status == CODE_OK and r[0] > 0
    assert_ccp(W, b, 0.3, r, OPTIMALITY)


@pytest.mark.parametrize("desaxce", [False, True])
@pytest.mark.parametrize("mu", [1e-3, 0.3, 2.0, 1e6, np.inf])
def test_sticking_is_minus_w_inverse_b(mu, desaxce, rng):
    for _ in range(10):
        W = random_spd(rng, 1e3)
        a = rng.uniform(0, 2 * np.pi)
        slope = 0.9 * rng.uniform() * mu if mu < np.inf else 5.0 * rng.uniform()  # |r_T| / r_N
        r_star = rng.uniform(0.1, 2.0) * np.array([1.0, slope * np.cos(a), slope * np.sin(a)])
        b = -W @ r_star
        status, res, r = solve(W, b, mu, desaxce=desaxce)
        assert status == CODE_OK and res <= LOCAL_TOL
        if desaxce and mu < np.inf and b[0] >= 0.0:
            # the De Saxce problem is not convex: r = 0 solves it too, and take-off is tried first
            np.testing.assert_array_equal(r, 0.0)
            continue
        # -W^-1 b from a Cholesky of W (cond <= 1e3): a few hundred ulps
        np.testing.assert_allclose(r, r_star, rtol=1e-11 * np.linalg.norm(r_star) / np.abs(r_star).min())


@pytest.mark.parametrize("desaxce", [False, True])
def test_frictionless(desaxce, rng):
    for _ in range(20):
        W = random_spd(rng, 1e3)
        b = rng.normal(size=3)
        status, _, r = solve(W, b, 0.0, r0=rng.normal(size=3), desaxce=desaxce)
        assert status == CODE_OK
        np.testing.assert_allclose(r, [max(0.0, -b[0] / W[0, 0]), 0.0, 0.0], rtol=ROUNDOFF, atol=0)
        assert_ccp(W, b, 0.0, r, OPTIMALITY)


@pytest.mark.parametrize("mu", FINITE_MUS)
def test_identity_w_slides_onto_the_projection_of_minus_b(mu, rng):
    """W = I: min 1/2 |r|^2 + b'r = 1/2 |r + b|^2 + c over K, so r = P_K(-b) (textbook formula)."""
    n = 0
    while n < 10:
        x = rng.normal(size=3)  # x = -b
        t = np.hypot(x[1], x[2])
        if t <= mu * x[0] or mu * t <= -x[0]:
            continue  # sticking or take-off
        n += 1
        alpha = (x[0] + mu * t) / (1.0 + mu * mu)
        expected = alpha * np.array([1.0, mu * x[1] / t, mu * x[2] / t])
        status, res, r = solve(np.eye(3), -x, mu)
        assert status == CODE_OK and res <= LOCAL_TOL
        np.testing.assert_allclose(r, expected, rtol=1e-10, atol=1e-12 * np.linalg.norm(x))


@pytest.mark.parametrize("mu", [0.1, 0.3, 1.0, 3.0])
def test_random_sliding_problems_against_clarabel(mu, rng):
    pytest.importorskip("clarabel")
    from hairinv.solver.reference import solve_socqp_dense_clarabel

    for _ in range(15):
        W, b = sliding_problem(rng, mu, cond=1e3)
        status, res, r = solve(W, b, mu)
        assert status == CODE_OK and res <= LOCAL_TOL
        assert_ccp(W, b, mu, r, OPTIMALITY)
        rc, info = solve_socqp_dense_clarabel(W, b, mu)
        assert info["status"] == "Solved"
        rc = rc[0]
        p = np.empty(3)
        project_cone(rc, mu, p)  # Clarabel's r, made exactly feasible
        assert np.linalg.norm(p - rc) <= CLARABEL_FEAS * np.linalg.norm(rc)

        def f(x):
            return 0.5 * x @ W @ x + b @ x

        # r is optimal: no feasible point does better, and by strong convexity
        # |p - r*|^2 <= 2 (f(p) - f*) / lambda_min
        slack = 64 * np.finfo(float).eps * (np.linalg.norm(W) * (r @ r) + np.linalg.norm(b) * np.linalg.norm(r))
        gap = f(p) - f(r)
        assert gap >= -slack
        lam_min = np.linalg.eigvalsh(W)[0]
        assert np.linalg.norm(p - r) ** 2 <= 2 * (gap + slack) / lam_min
        assert np.linalg.norm(p - r) <= CLARABEL_MATCH * np.linalg.norm(r)


@hyp
@given(seed=st.integers(0, 2**32 - 1), mu=st.sampled_from(FINITE_MUS), log_cond=st.floats(0, 8),
       log_b=st.floats(-12, 12), log_w=st.floats(-6, 6), desaxce=st.booleans())
def test_random_problems_meet_the_optimality_conditions(seed, mu, log_cond, log_b, log_w, desaxce):
    rng = np.random.default_rng(seed)
    W = random_spd(rng, 10**log_cond, 10**log_w)
    b = rng.normal(size=3) * 10**log_b
    status, res, r = solve(W, b, mu, r0=rng.normal(size=3) * 10**log_b / 10**log_w, desaxce=desaxce)
    assert status == CODE_OK and res <= LOCAL_TOL
    assert relative_residual(W, b, mu, r, desaxce) == pytest.approx(res, rel=1e-6, abs=1e-13)
    assert_ccp(W, b, mu, r, OPTIMALITY if log_cond < 4 else OPTIMALITY_ILL, desaxce)


# ------------------------------------------------------------ local solve: extremes


@pytest.mark.parametrize("mu", [1e-8, 0.3, 1e3, 1e6])
@pytest.mark.parametrize("cond", [1.0, 1e8])
@pytest.mark.parametrize("b_scale", [1e-12, 1.0, 1e12])
def test_extremes(mu, cond, b_scale, rng):
    for _ in range(5):
        W, b = sliding_problem(rng, mu, cond=cond)
        b = b * b_scale
        for desaxce in (False, True):
            status, res, r = solve(W, b, mu, desaxce=desaxce)
            assert status == CODE_OK and res <= LOCAL_TOL
            assert np.all(np.isfinite(r))
            assert_ccp(W, b, mu, r, OPTIMALITY if cond < 1e4 else OPTIMALITY_ILL, desaxce)


def test_scaling_w_and_b_scales_r(rng):
    W, b = sliding_problem(rng, 0.3, cond=1e2)
    _, _, r = solve(W, b, 0.3)
    for s_w, s_b in [(1e-9, 1.0), (1e9, 1e-9), (1e6, 1e12)]:
        _, _, rs = solve(W * s_w, b * s_b, 0.3)
        np.testing.assert_allclose(rs, r * s_b / s_w, rtol=1e-10)


@pytest.mark.parametrize("desaxce", [False, True])
def test_warm_start_from_the_answer_returns_it_unchanged(desaxce, rng):
    for _ in range(10):
        W, b = sliding_problem(rng, 0.4)
        status, _, r = solve(W, b, 0.4, desaxce=desaxce)
        assert status == CODE_OK
        again = r.copy()
        status, res, out = solve(W, b, 0.4, r0=again, desaxce=desaxce, max_iter=0)
        assert status == CODE_OK and res <= LOCAL_TOL
        np.testing.assert_array_equal(out, r)  # bit for bit: no Newton step was taken


@pytest.mark.parametrize("turn", [0.3, 2.0, np.pi])
def test_a_warm_start_with_the_wrong_slip_angle_still_finds_the_sliding_answer(turn, rng):
    """A sliding contact first tries the slip angle of its warm start, refined on the sliding
    equation ``g(a) = 0``; that root may be another one (``g`` has up to four), whose force must be
    rejected. From warm starts turned by ``turn`` and twice too strong, the answer is the cold
    solve's (convex: unique) to round-off, and it meets the optimality conditions."""
    for _ in range(20):
        W, b = sliding_problem(rng, 0.4, cond=1e2)
        status, _, r = solve(W, b, 0.4)
        assert status == CODE_OK
        c, s = np.cos(turn), np.sin(turn)
        warm = 2.0 * np.array([r[0], c * r[1] - s * r[2], s * r[1] + c * r[2]])
        status, res, out = solve(W, b, 0.4, r0=warm)
        assert status == CODE_OK and res <= LOCAL_TOL
        assert_ccp(W, b, 0.4, out, OPTIMALITY)
        np.testing.assert_allclose(out, r, rtol=1e-9, atol=1e-9 * np.linalg.norm(r))


def test_not_converged_returns_the_best_point(rng):
    W, b = sliding_problem(rng, 0.3, cond=1e2)
    status, res, r = solve(W, b, 0.3, max_iter=0)  # no Newton step; the fail-safe still runs
    assert status in (CODE_OK, CODE_NOT_CONVERGED)
    assert res == pytest.approx(relative_residual(W, b, 0.3, r), rel=1e-6, abs=1e-13)
    r = np.zeros(3)
    status, res = solve_contact(W, b, 0.3, r, -1.0, 0, False)  # an unreachable tolerance
    assert status == CODE_NOT_CONVERGED and np.isfinite(res)
    assert_ccp(W, b, 0.3, r, OPTIMALITY)  # the best point is still the fail-safe's solution


def test_numerical_errors_leave_r_untouched():
    W = np.eye(3)
    b = np.array([-1.0, 0.5, 0.0])
    cases = [
        (np.array([[np.nan, 0, 0], [0, 1, 0], [0, 0, 1.0]]), b, 0.3),
        (W, np.array([np.inf, 0.0, 0.0]), 0.3),
        (W, b, np.nan),
        (W, b, -0.1),
        (np.diag([1.0, -1.0, 1.0]), b, 0.3),  # not positive
        (np.array([[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 1.0]]), b, 0.3),  # indefinite, positive diagonal
    ]
    for Wc, bc, mu in cases:
        r = np.array([7.0, 8.0, 9.0])
        status, res = solve_contact(Wc, bc, mu, r, LOCAL_TOL, 50, False)
        assert status == CODE_NUMERICAL and res == np.inf
        np.testing.assert_array_equal(r, [7.0, 8.0, 9.0])


def test_non_finite_warm_start_is_ignored(rng):
    W, b = sliding_problem(rng, 0.3)
    status, _, r = solve(W, b, 0.3, r0=[np.nan, 0.0, np.inf])
    assert status == CODE_OK
    assert_ccp(W, b, 0.3, r, OPTIMALITY)


def test_zero_b_gives_zero_force():
    status, res, r = solve(np.eye(3), np.zeros(3), 0.3, r0=[1.0, 2.0, 3.0])
    assert status == CODE_OK and res == 0.0
    np.testing.assert_array_equal(r, 0.0)


# ------------------------------------------------------------------ De Saxce (dynamics)


@pytest.mark.parametrize("W", [np.eye(3), np.diag([1.0, 2.0, 3.0]),
                               np.array([[2.0, 0.3, -0.2], [0.3, 1.0, 0.1], [-0.2, 0.1, 1.5]])])
@pytest.mark.parametrize("mu", [0.2, 0.8])
def test_desaxce_sliding_by_construction(W, mu):
    """r on the boundary, u = (0, -alpha e): u~ = alpha (mu, -e) is on the dual boundary, ⟂ r.

    The contact slides tangentially (u_N = 0) with friction against the slip (r_T parallel to -u_T).
    """
    for a in np.linspace(0.1, 2 * np.pi, 7):
        e = np.array([np.cos(a), np.sin(a)])
        r_star = 1.3 * np.array([1.0, *(mu * e)])
        u_star = np.array([0.0, *(-0.7 * e)])
        b = u_star - W @ r_star
        assert b[0] < 0  # no take-off
        s = -np.linalg.solve(W, b)
        assert not (s[0] >= 0 and np.hypot(s[1], s[2]) <= mu * s[0])  # no sticking
        status, res, r = solve(W, b, mu, desaxce=True)
        assert status == CODE_OK and res <= LOCAL_TOL
        assert_ccp(W, b, mu, r, OPTIMALITY, desaxce=True)
        np.testing.assert_allclose(r, r_star, rtol=1e-9, atol=1e-12)
        u = W @ r + b
        assert abs(u[0]) <= 1e-9 and np.hypot(*u[1:]) == pytest.approx(0.7, rel=1e-9)


def test_desaxce_and_static_differ_on_the_same_data():
    """The same sliding data in statics gives a different force (u_N > 0 there): the flag matters."""
    W = np.eye(3)
    mu = 0.5
    r_star = np.array([1.0, mu, 0.0])
    b = np.array([0.0, -0.7, 0.0]) - r_star
    _, _, r_dyn = solve(W, b, mu, desaxce=True)
    _, _, r_stat = solve(W, b, mu, desaxce=False)
    np.testing.assert_allclose(r_dyn, r_star, rtol=1e-10)
    p = np.empty(3)
    project_cone(-b, mu, p)
    np.testing.assert_allclose(r_stat, p, rtol=1e-10)
    assert np.linalg.norm(r_dyn - r_stat) > 0.1


# -------------------------------------------------------------------- reference solver


def random_socqp(rng, n_contacts, n_dofs, mus):
    H = sp.random(3 * n_contacts, n_dofs, density=0.3, random_state=np.random.RandomState(3), format="csr")
    H = H + sp.hstack([sp.identity(3 * n_contacts), sp.csr_matrix((3 * n_contacts, n_dofs - 3 * n_contacts))])
    d = rng.uniform(0.5, 2.0, n_dofs)
    b = rng.normal(size=3 * n_contacts)
    mu = np.array([mus[i % len(mus)] for i in range(n_contacts)])
    return sp.csr_matrix(H), d, 1e-3, b, mu


def test_sparse_and_dense_clarabel_agree_and_are_optimal(rng):
    pytest.importorskip("clarabel")
    from hairinv.solver.reference import solve_socqp_clarabel, solve_socqp_dense_clarabel

    H, d, gamma, b, mu = random_socqp(rng, 6, 30, [0.3, 0.0, 1.0, np.inf, 0.05, 5.0])
    r_sparse, info_s = solve_socqp_clarabel(H, d, gamma, b, mu)
    W = (H @ sp.diags(d) @ H.T).toarray() + gamma * np.eye(H.shape[0])
    r_dense, info_d = solve_socqp_dense_clarabel(W, b, mu)
    for info in (info_s, info_d):
        assert info["status"] == "Solved"
        assert info["iterations"] > 0 and info["solve_time"] >= 0.0
    scale = np.linalg.norm(r_dense)
    np.testing.assert_allclose(r_sparse, r_dense, rtol=0, atol=CLARABEL_MATCH * scale)
    u_scale = np.linalg.norm(b)
    for r in (r_sparse, r_dense):
        u = (W @ r.reshape(-1) + b).reshape(-1, 3)
        assert np.all(in_cone(r, mu, CLARABEL_FEAS * scale))
        assert np.all(in_dual_cone(u, mu, CLARABEL_MATCH * u_scale))
        assert np.all(np.abs(complementarity(r, u)) <= CLARABEL_MATCH * scale * u_scale)
        assert np.all(np.abs(r[mu == 0.0, 1:]) <= CLARABEL_FEAS * scale)


def test_single_contact_reference_matches_the_local_solve_for_every_kind_of_mu(rng):
    pytest.importorskip("clarabel")
    from hairinv.solver.reference import solve_socqp_dense_clarabel

    for mu in (0.0, 0.3, np.inf):
        for _ in range(5):
            W = random_spd(rng, 10.0)
            b = rng.normal(size=3)
            _, _, r = solve(W, b, mu)
            rc, info = solve_socqp_dense_clarabel(W, b, mu)
            assert info["status"] == "Solved"
            scale = max(np.linalg.norm(r), np.linalg.norm(b))
            np.testing.assert_allclose(rc[0], r, rtol=0, atol=CLARABEL_MATCH * scale)


def test_reference_without_clarabel_says_how_to_install_it(monkeypatch):
    from hairinv.solver.reference import solve_socqp_dense_clarabel

    monkeypatch.setitem(sys.modules, "clarabel", None)
    with pytest.raises(ImportError, match="clarabel"):
        solve_socqp_dense_clarabel(np.eye(3), np.ones(3), 0.3)
