"""hairinv.testing, the independent checks the other tests judge the solvers with, checked themselves.

From the definitions: the projection onto ``K_mu`` is the closest point of the cone (no random
point of the cone is closer) and with the projection onto the dual cone makes Moreau's decomposition
``x = P_K(x) - P_K*(-x)``; a velocity is in ``K*_mu`` exactly when its product with every force of
``K_mu`` is nonnegative; the violation measures vanish on the cones and stay within sqrt(2) of the
distance to them; the natural residual vanishes on complementary pairs built by construction and not
elsewhere; the optimality check passes a hand-made problem with a known answer and names the
condition a perturbed answer breaks. Last, the solver's kernels agree with these to round-off.
"""

from __future__ import annotations

import numpy as np
import pytest

from conftest import ROUNDOFF
from hairinv.testing import (
    check_cone_qp,
    check_coulomb,
    complementarity,
    cone_qp_violations,
    cone_violation,
    delassus_scaling,
    desaxce_velocity,
    dual_cone_violation,
    in_cone,
    in_dual_cone,
    natural_residual,
    project_cone,
    project_dual_cone,
)

MUS = [0.0, 1e-8, 1e-3, 0.3, 1.0, 7.0, 1e6, np.inf]


def random_rows(rng, n=400):
    """Rows with magnitudes from 1e-3 to 1e3 and every sign: inside, polar and between."""
    return rng.normal(size=(n, 3)) * 10.0 ** rng.uniform(-3, 3, (n, 1))


def points_of_the_cone(rng, mu, radius, n=20000):
    """Random points of ``K_mu`` (0 < mu < inf) of norm up to ``radius``, half of them on its boundary."""
    s = rng.uniform(0, radius / np.hypot(1, mu), n)
    a = rng.uniform(0, 2 * np.pi, n)
    c = np.where(np.arange(n) % 2 == 0, 1.0, rng.uniform(0, 1, n))
    return np.stack([s, mu * c * s * np.cos(a), mu * c * s * np.sin(a)], axis=1)


@pytest.mark.parametrize("mu", [1e-3, 0.3, 1.0, 7.0])
def test_no_point_of_the_cone_is_closer_than_the_projection(mu, rng):
    for x in random_rows(rng, 30):
        p = project_cone(x, mu)
        assert in_cone(p, mu, ROUNDOFF * np.linalg.norm(x))
        others = points_of_the_cone(rng, mu, 2 * np.linalg.norm(x))
        assert np.linalg.norm(x - p) <= np.linalg.norm(x - others, axis=1).min() * (1 + ROUNDOFF)


@pytest.mark.parametrize("mu", MUS)
def test_moreau_decomposition(mu, rng):
    x = random_rows(rng)
    size = np.linalg.norm(x, axis=1)
    p, q = project_cone(x, mu), project_dual_cone(-x, mu)
    np.testing.assert_allclose(p - q, x, rtol=0, atol=ROUNDOFF * size.max())
    assert np.all(in_cone(p, mu, ROUNDOFF * size)) and np.all(in_dual_cone(q, mu, ROUNDOFF * size))
    assert np.all(np.abs(complementarity(p, q)) <= ROUNDOFF * size ** 2)
    np.testing.assert_allclose(project_cone(p, mu), p, rtol=0, atol=ROUNDOFF * size.max())  # idempotent


@pytest.mark.parametrize("mu", MUS)
def test_special_regions(mu):
    inside = np.array([2.0, 0.1 * min(mu, 1.0), 0.0])
    np.testing.assert_array_equal(project_cone(inside, mu), inside)
    polar = np.array([-2.0, 0.0, 0.0]) if mu == np.inf else np.array([-2.0, 0.1 / max(mu, 1.0), 0.0])
    np.testing.assert_array_equal(project_cone(polar, mu), 0.0)
    xn = 0.05 / max(mu, 1.0) if mu < np.inf else 0.05
    x = np.array([xn, -3.0, 4.0])
    if mu == np.inf:
        np.testing.assert_array_equal(project_cone(x, mu), x)
    else:  # onto the generator (1, mu e): alpha = (x_N + mu |x_T|) / (1 + mu^2)
        alpha = (xn + mu * 5.0) / (1.0 + mu * mu)
        np.testing.assert_allclose(project_cone(x, mu), alpha * np.array([1.0, -0.6 * mu, 0.8 * mu]),
                                   rtol=ROUNDOFF, atol=0)
    # the dual of the half-line is the half-space, of the half-space the ray
    np.testing.assert_array_equal(project_dual_cone(np.array([-1.0, 2.0, 3.0]), 0.0), [0.0, 2.0, 3.0])
    np.testing.assert_array_equal(project_dual_cone(np.array([1.0, 2.0, 3.0]), np.inf), [1.0, 0.0, 0.0])


@pytest.mark.parametrize("mu", MUS)
def test_the_dual_cone_is_the_dual(mu, rng):
    """``u`` in ``K*_mu`` if and only if ``r . u >= 0`` for every ``r`` of ``K_mu``: against its generators
    (``mu = inf``: the half-space's, ``e_N`` and every tangent, both signs), every half degree."""
    x = random_rows(rng)
    t = np.hypot(x[:, 1], x[:, 2])
    if mu == np.inf:  # and velocities built inside K*_mu: u_N >= mu |u_T|
        built = np.stack([np.abs(x[:, 0]), 0 * t, 0 * t], axis=1)
    else:
        built = np.column_stack([mu * t * rng.uniform(1, 2, len(t)) + (mu == 0) * np.abs(x[:, 0]), x[:, 1:]])
    u = np.concatenate([x, built])
    a = np.linspace(0, 2 * np.pi, 721)
    if mu == np.inf:
        generators = np.concatenate([np.stack([np.zeros_like(a), np.cos(a), np.sin(a)], axis=1), [[1.0, 0, 0]]])
    else:
        generators = np.stack([np.ones_like(a), mu * np.cos(a), mu * np.sin(a)], axis=1)
    products = u @ generators.T
    scale = np.linalg.norm(u, axis=1)[:, None] * np.linalg.norm(generators, axis=1)
    inside = in_dual_cone(u, mu, atol=0.0)
    assert np.all(products[inside] >= -ROUNDOFF * scale[inside])
    # outside by more than the half degree between generators can hide: some product is negative
    clearly = dual_cone_violation(u, mu) > 1e-2 * np.linalg.norm(u, axis=1)
    assert np.all(np.any(products[clearly] < 0.0, axis=1))
    assert inside.any() and clearly.any()


@pytest.mark.parametrize("mu", MUS)
def test_violations_vanish_on_the_cones_and_are_within_sqrt_2_of_the_distance(mu, rng):
    x = random_rows(rng)
    size = np.linalg.norm(x, axis=1)
    for violation, project in ((cone_violation, project_cone), (dual_cone_violation, project_dual_cone)):
        p = project(x, mu)
        assert np.all(violation(p, mu) <= ROUNDOFF * size)
        distance = np.linalg.norm(x - p, axis=1)
        v = violation(x, mu)
        assert np.all(v <= np.sqrt(2) * distance * (1 + ROUNDOFF) + ROUNDOFF * size)
        assert np.all(distance <= np.sqrt(2) * v * (1 + ROUNDOFF) + ROUNDOFF * size)
    # membership is the violation against the tolerance
    np.testing.assert_array_equal(in_cone(x, mu, 0.1 * size), cone_violation(x, mu) <= 0.1 * size)


def test_exact_membership_with_a_relative_tolerance():
    """``rtol`` loosens only the bound ``mu x_N``: a hair outside it passes, a negative normal never."""
    assert in_cone([1.0, 0.3 * (1 + 1e-13), 0.0], 0.3, atol=0.0, rtol=1e-12)
    assert not in_cone([1.0, 0.3 * (1 + 1e-11), 0.0], 0.3, atol=0.0, rtol=1e-12)
    assert not in_cone([-1e-300, 0.0, 0.0], 0.3, atol=0.0, rtol=1e-12)
    assert in_cone([0.0, 5.0, 0.0], np.inf, atol=0.0, rtol=1e-12)
    assert not in_cone([-1e-300, 0.0, 0.0], np.inf, atol=0.0, rtol=1e-12)


def complementary_pairs(mu, rng):
    """(r, u) with K_mu ∋ r ⟂ u ∈ K*_mu by construction: take-off, sticking, sliding."""
    a = rng.uniform(0, 2 * np.pi)
    e = np.array([np.cos(a), np.sin(a)])
    size, beta = rng.uniform(0.1, 3.0, 2)
    pairs = [(np.zeros(3), np.zeros(3)), (np.zeros(3), np.array([beta, 0.0, 0.0]))]
    if mu == np.inf:
        return pairs + [(np.array([size, *(5 * size * e)]), np.zeros(3))]
    pairs += [(size * np.array([1.0, *(0.5 * mu * e)]), np.zeros(3))]
    if mu > 0:
        pairs += [(size * np.array([1.0, *(mu * e)]), beta * np.array([mu, *(-e)]))]
    return pairs


@pytest.mark.parametrize("mu", MUS)
def test_the_natural_residual_is_zero_exactly_at_the_solutions(mu, rng):
    for _ in range(10):
        for r, u in complementary_pairs(mu, rng):
            scale = np.linalg.norm(r) + np.linalg.norm(u)
            assert natural_residual(r, u, mu) <= ROUNDOFF * scale * max(1.0, mu if mu < np.inf else 1.0)
            # off the solution: a force that opens (u_N > 0 under load) or a wrong slip
            assert natural_residual(r + np.array([1.0, 0.0, 0.0]), u + np.array([1.0, 0.0, 0.0]), mu) > 0.5
    # De Saxce: the contact slides tangentially (u_N = 0) against the friction, a solution of the dynamic
    # law and not of the static one
    if 0.0 < mu < np.inf:
        r, u = np.array([1.0, mu, 0.0]), np.array([0.0, -1.0, 0.0])
        assert natural_residual(r, u, mu, desaxce=True) <= ROUNDOFF * mu
        assert natural_residual(r, u, mu) == pytest.approx(mu / np.sqrt(1.0 + mu * mu), rel=ROUNDOFF * (1 + mu))
        np.testing.assert_array_equal(desaxce_velocity(u, mu), [mu, -1.0, 0.0])


def test_a_hand_made_cone_qp_passes_and_a_perturbed_answer_is_named():
    """W = I: ``min 1/2 |r|^2 + b'r`` over ``K`` is ``|r + b|^2 / 2 + c``, so ``r = P_K(-b)`` (textbook):
    two contacts, one sliding and one taking off."""
    mu = np.array([0.5, 0.5])
    b = np.array([[-1.0, 2.0, 0.0], [1.0, 0.1, 0.0]])
    W = np.eye(6)
    r = project_cone(-b, mu)
    v = check_cone_qp(W, b, r, mu, primal=ROUNDOFF, dual=ROUNDOFF, complementarity=ROUNDOFF)
    assert v.worst()["natural"] <= ROUNDOFF
    np.testing.assert_array_equal(delassus_scaling(W), [1.0, 1.0])
    with pytest.raises(AssertionError, match=r"primal feasibility.*contact 0"):
        check_cone_qp(W, b, r + np.array([[0.0, -0.1, 0.0], [0, 0, 0]]), mu, primal=1e-3, dual=1.0,
                      complementarity=1.0)
    with pytest.raises(AssertionError, match=r"dual feasibility.*contact 1"):  # u_1 = (1, 0.1, 2)
        check_cone_qp(W, b, r + np.array([[0, 0, 0], [0.0, 0.0, 2.0]]), mu, primal=10.0, dual=1e-3,
                      complementarity=10.0)
    with pytest.raises(AssertionError, match=r"complementarity.*contact 0"):
        check_cone_qp(W, b, 2 * r, mu, primal=1e-3, dual=10.0, complementarity=1e-3)
    nan = r.copy()
    nan[1, 0] = np.nan
    with pytest.raises(AssertionError):
        check_cone_qp(W, b, nan, mu, primal=1.0, dual=1.0, complementarity=1.0)


def test_the_coulomb_check_reads_de_saxce_velocities():
    """A contact sliding tangentially (u_N = 0) with friction at the cone's edge against the slip meets the
    dynamic law; the static conditions see ``u_T`` outside the dual cone."""
    mu = 0.4
    r = np.array([1.0, mu, 0.0])
    W = np.eye(3)
    b = np.array([0.0, -0.7, 0.0]) - r
    check_coulomb(W, b, r, mu, primal=ROUNDOFF, dual=ROUNDOFF, complementarity=ROUNDOFF)
    assert cone_qp_violations(W, b, r, mu).worst()["dual"] > 0.1


@pytest.mark.parametrize("mu", MUS)
def test_the_kernels_agree(mu, rng):
    """The solver's own projection and natural residual agree with these to round-off (each written apart)."""
    from hairinv.solver.local import natural_residual as kernel_natural
    from hairinv.solver.local import project_cone as kernel_projection

    x, u = random_rows(rng, 200), random_rows(rng, 200)
    size = np.linalg.norm(x, axis=1)
    out = np.empty(3)
    for i in range(len(x)):
        kernel_projection(x[i], mu, out)
        np.testing.assert_allclose(out, project_cone(x[i], mu), rtol=0, atol=ROUNDOFF * size[i])
        for desaxce in (False, True):
            expected = natural_residual(x[i], u[i], mu, desaxce=desaxce)
            scale = (size[i] + np.linalg.norm(u[i])) * (1 + (mu if desaxce and mu < np.inf else 0.0))
            assert kernel_natural(x[i], u[i], mu, desaxce) == pytest.approx(expected, rel=0, abs=ROUNDOFF * scale)
