"""Independent checks of the contact problems, used by the tests and the benchmarks.

Everything here is written from the mathematical definitions, in plain numpy and apart from the
solvers' numba kernels (``hairinv.solver``, ``hairinv.dynamics``), so that it can judge them. It is
shipped inside the package, as cvxpy ships ``solver_test_helpers``, so that tests and benchmarks
import it the same way.

A contact's force ``r`` and relative velocity ``u`` are rows ``(normal, tangent 1, tangent 2)`` in
the contact's frame; every function takes one row ``(3,)`` or many ``(n, 3)``, with ``mu`` a number
or one per row.

- The Coulomb cone ``K_mu = {r : mu r_N >= |r_T|}``: ``mu = 0`` is the half-line ``r_T = 0,
  r_N >= 0``, ``mu = inf`` the half-space ``r_N >= 0``.
- Its dual ``K*_mu = {u : u_N >= mu |u_T|}``, which is ``K_(1/mu)``: ``mu = 0`` gives the half-space
  ``u_N >= 0``, ``mu = inf`` the ray ``u_T = 0, u_N >= 0``. The polar cone is ``-K*_mu``, and every
  ``x`` is ``P_K(x) - P_K*(-x)`` (Moreau).
- The static problem (``invert``): ``min 1/2 r'Wr + b'r`` over ``r`` in the cones, convex; ``r`` is
  optimal if and only if ``K ∋ r ⟂ u = W r + b ∈ K*`` (primal feasibility, dual feasibility,
  complementarity ``r_i . u_i = 0`` for each contact).
- The dynamic Coulomb law (``simulate``): the same conditions on De Saxce's velocity
  ``u~ = u + mu |u_T| e_N`` (not convex); ``u~`` in ``K*`` says ``u_N >= 0``, and complementarity
  says the contact sticks, takes off, or slides with the friction force opposing the slip.
- The natural map ``r - P_K(r - u / rho)``: zero exactly at the solutions; the solvers scale each
  contact by ``rho_i = trace(W_ii) / 3`` (:func:`delassus_scaling`), which gives it force units.

Violations of the cones are in the units of ``x`` and follow the scaling of Daviet, Bertails-Descoubes
and Boissieux (2011, appendix A): ``(mu x_N, x_T) / max(1, mu)`` maps ``K_mu`` onto the Lorentz cone
``{|y_T| <= y_0}``, whose inequality then misses by ``(|x_T| - mu x_N) / max(1, mu)``. With
``x_N >= 0`` beside it (which the scaling loses at ``mu = 0``) the measure is within a factor sqrt(2)
of the Euclidean distance to the cone for every ``mu``: round-off in ``x_N`` is not multiplied by a
wide cone's ``mu``, nor round-off in ``u_N`` by a narrow cone's ``1 / mu``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "Violations",
    "check_cone_qp",
    "check_coulomb",
    "complementarity",
    "cone_qp_violations",
    "cone_violation",
    "coulomb_violations",
    "delassus_scaling",
    "desaxce_velocity",
    "dual_cone_violation",
    "in_cone",
    "in_dual_cone",
    "natural_residual",
    "problem_scales",
    "project_cone",
    "project_dual_cone",
]


# --------------------------------------------------------------------------------------------- cones


def _rows(x) -> np.ndarray:
    x = np.asarray(x, dtype=np.float64)
    if x.ndim == 0 or x.shape[-1] != 3:
        raise ValueError(f"rows of 3 (normal, tangent 1, tangent 2) expected, got shape {x.shape}")
    return x


def _friction(mu, shape) -> np.ndarray:
    mu = np.broadcast_to(np.asarray(mu, dtype=np.float64), shape)
    if np.any(np.isnan(mu) | (mu < 0.0)):
        raise ValueError("friction coefficients must be >= 0 (inf allowed)")
    return mu


def _inverse(mu) -> np.ndarray:
    """``1 / mu`` with ``1 / 0 = inf`` and ``1 / inf = 0``: ``K*_mu = K_(1/mu)``."""
    mu = np.asarray(mu, dtype=np.float64)
    with np.errstate(divide="ignore"):
        return np.where(mu == 0.0, np.inf, 1.0 / np.where(mu == 0.0, 1.0, mu))


def project_cone(x, mu) -> np.ndarray:
    """Euclidean projection of each row onto ``K_mu``: the closest point of the cone.

    ``x`` itself inside ``K_mu``; ``0`` inside the polar cone ``-K*_mu`` (``-x_N >= mu |x_T|``); else
    the projection onto the boundary ray through ``x``'s meridian, ``max(0, x . g) g`` with the unit
    generator ``g = (1, mu x_T / |x_T|) / sqrt(1 + mu^2)``. ``mu = inf``: ``(max(x_N, 0), x_T)``.

    Parameters
    ----------
    x : (3,) or (n, 3) float64
    mu : float or (n,) float64, each >= 0 or inf

    Returns
    -------
    (3,) or (n, 3) float64, a new array
    """
    x = _rows(x)
    n, t = x[..., 0], np.hypot(x[..., 1], x[..., 2])
    mu = _friction(mu, n.shape)
    wide = np.isinf(mu)
    m = np.where(wide, 0.0, mu)
    inside = (n >= 0.0) & (t <= m * n)
    polar = m * t <= -n
    norm = np.hypot(1.0, m)
    gn, gt = 1.0 / norm, m / norm  # the generator's normal and tangential components
    a = np.maximum(n * gn + t * gt, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        direction = x[..., 1:] / t[..., None]  # only read where t > 0 (outside K and -K*)
    boundary = np.concatenate([(a * gn)[..., None], (a * gt)[..., None] * direction], axis=-1)
    out = np.where(inside[..., None], x, np.where(polar[..., None], 0.0, boundary))
    half_space = np.concatenate([np.maximum(n, 0.0)[..., None], x[..., 1:]], axis=-1)
    return np.where(wide[..., None], half_space, out)


def project_dual_cone(u, mu) -> np.ndarray:
    """Euclidean projection of each row onto ``K*_mu = {u_N >= mu |u_T|} = K_(1/mu)``; as
    :func:`project_cone`."""
    u = _rows(u)
    return project_cone(u, _inverse(_friction(mu, u.shape[:-1])))


def cone_violation(x, mu) -> np.ndarray:
    """How far each row misses ``K_mu``: ``max(0, -x_N, (|x_T| - mu x_N) / max(1, mu))`` (``mu = inf``:
    ``max(0, -x_N)``), in the units of ``x`` and within sqrt(2) of the distance to the cone; 0 on the
    cone. (n,), or 0-d for one row."""
    x = _rows(x)
    n, t = x[..., 0], np.hypot(x[..., 1], x[..., 2])
    mu = _friction(mu, n.shape)
    wide = np.isinf(mu)
    m = np.where(wide, 1.0, mu)
    excess = np.where(wide, 0.0, (t - m * n) / np.maximum(1.0, m))
    return np.maximum(np.maximum(-n, excess), 0.0)


def dual_cone_violation(u, mu) -> np.ndarray:
    """How far each row misses ``K*_mu = K_(1/mu)``: ``max(0, -u_N, (mu |u_T| - u_N) / max(1, mu))``
    (``mu = 0``: ``max(0, -u_N)``; ``mu = inf``: ``max(0, -u_N, |u_T|)``), as :func:`cone_violation`."""
    u = _rows(u)
    return cone_violation(u, _inverse(_friction(mu, u.shape[:-1])))


def in_cone(x, mu, atol, rtol=0.0) -> np.ndarray:
    """Whether each row lies in ``K_mu`` to the tolerances: :func:`cone_violation` at most ``atol`` (in the
    units of ``x``: a number, or one per row) beyond ``rtol`` times the bound ``mu x_N / max(1, mu)``
    (``atol = 0, rtol = 1e-12``: in the cone to the round-off of the bound, as a projection returns it)."""
    x = _rows(x)
    mu = _friction(mu, x.shape[:-1])
    finite = np.isfinite(mu)
    m = np.where(finite, mu, 1.0)
    bound = np.where(finite, m * np.maximum(x[..., 0], 0.0) / np.maximum(1.0, m), 0.0)
    return cone_violation(x, mu) <= atol + rtol * bound


def in_dual_cone(u, mu, atol, rtol=0.0) -> np.ndarray:
    """Whether each row lies in ``K*_mu`` to the tolerances: :func:`dual_cone_violation` at most ``atol`` beyond
    ``rtol`` times the bound; as :func:`in_cone`."""
    u = _rows(u)
    return in_cone(u, _inverse(_friction(mu, u.shape[:-1])), atol, rtol)


def desaxce_velocity(u, mu) -> np.ndarray:
    """De Saxce's velocity ``u~ = u + mu |u_T| e_N`` of each row (``u`` itself where ``mu`` is 0 or inf:
    there the term is 0 or the dual cone is the normal ray, where ``u_T = 0``)."""
    u = _rows(u)
    mu = _friction(mu, u.shape[:-1])
    finite = np.isfinite(mu)
    out = u.copy()
    out[..., 0] = u[..., 0] + np.where(finite, np.where(finite, mu, 0.0) * np.hypot(u[..., 1], u[..., 2]), 0.0)
    return out


def complementarity(r, u) -> np.ndarray:
    """``r_i . u_i`` of each contact (0 at a solution: sticking ``u = 0``, take-off ``r = 0``, or
    sliding on the cone's boundary against the slip); (n,) or 0-d."""
    return np.einsum("...i,...i->...", _rows(r), _rows(u))


def natural_residual(r, u, mu, rho=1.0, desaxce=False) -> np.ndarray:
    """The natural map's residual of each contact, ``|r - P_K(r - u / rho)|`` (De Saxce's ``u~`` in place
    of ``u`` with ``desaxce``). Zero exactly where ``K ∋ r ⟂ u ∈ K*``; in the units of ``r`` when ``rho``
    has those of ``W`` (the solvers' ``rho_i = trace(W_ii) / 3``, :func:`delassus_scaling`).

    Parameters
    ----------
    r, u : (3,) or (n, 3) float64
    mu : float or (n,) float64
    rho : float or (n,) float64, > 0
    """
    r, u = _rows(r), _rows(u)
    v = desaxce_velocity(u, mu) if desaxce else u
    x = r - v / np.asarray(rho, dtype=np.float64)[..., None]
    return np.linalg.norm(r - project_cone(x, mu), axis=-1)


def delassus_scaling(W) -> np.ndarray:
    """``rho_i = trace(W_ii) / 3`` of each contact's diagonal 3x3 block of a dense ``W`` (3n, 3n); (n,)."""
    W = np.asarray(W, dtype=np.float64)
    c = W.shape[0] // 3
    blocks = W.reshape(c, 3, c, 3)[np.arange(c), :, np.arange(c), :]
    return np.trace(blocks, axis1=1, axis2=2) / 3.0


# ----------------------------------------------------------------------------- optimality conditions


@dataclass(frozen=True)
class Violations:
    """The measured violations of the optimality conditions, one value per contact.

    primal : (n,) how far ``r_i`` misses ``K_mu`` (:func:`cone_violation`), force units
    dual : (n,) how far ``u_i`` (``u~_i`` for the Coulomb law) misses ``K*_mu``, velocity units
    complementarity : (n,) ``|r_i . u_i|`` (``u~_i``), force x velocity
    natural : (n,) the natural map's residual with ``rho_i = trace(W_ii) / 3``, force units
    u : (n, 3) ``W r + b`` (``u~`` for the Coulomb law)
    """

    primal: np.ndarray
    dual: np.ndarray
    complementarity: np.ndarray
    natural: np.ndarray
    u: np.ndarray

    def worst(self) -> dict[str, float]:
        """The largest violation of each condition (0 without contacts)."""
        return {name: float(np.max(getattr(self, name), initial=0.0))
                for name in ("primal", "dual", "complementarity", "natural")}


def _violations(W, b, r, mu, desaxce: bool) -> Violations:
    W = np.asarray(W, dtype=np.float64)
    r = _rows(r).reshape(-1, 3)
    b = np.asarray(b, dtype=np.float64).reshape(-1, 3)
    if W.shape != (3 * len(r), 3 * len(r)) or b.shape != r.shape:
        raise ValueError(f"W {W.shape}, b {b.shape} and r {r.shape} do not describe the same contacts")
    mu = _friction(mu, r.shape[:-1])
    u = (W @ r.ravel()).reshape(-1, 3) + b
    if desaxce:
        u = desaxce_velocity(u, mu)
    rho = delassus_scaling(W) if len(r) else np.ones(0)
    # the natural map of u~ itself: desaxce_velocity is applied once, above
    return Violations(primal=cone_violation(r, mu), dual=dual_cone_violation(u, mu),
                      complementarity=np.abs(complementarity(r, u)), natural=natural_residual(r, u, mu, rho),
                      u=u)


def cone_qp_violations(W, b, r, mu) -> Violations:
    """The optimality conditions of ``min 1/2 r'Wr + b'r`` over the Coulomb cones at ``r``, measured.

    Parameters
    ----------
    W : (3n, 3n) float64, dense, symmetric positive semidefinite
    b : (3n,) or (n, 3) float64
    r : (n, 3) or (3,) float64, each contact's force in its frame
    mu : float or (n,) float64
    """
    return _violations(W, b, r, mu, desaxce=False)


def coulomb_violations(W, b, r, mu) -> Violations:
    """The conditions of the dynamic Coulomb law ``K ∋ r ⟂ u~ ∈ K*`` at ``r``, ``u = W r + b``, measured;
    as :func:`cone_qp_violations`."""
    return _violations(W, b, r, mu, desaxce=True)


def problem_scales(W, b, r) -> tuple[float, float]:
    """``(force, velocity)``, the sizes the conditions of one problem are relative to: the largest force
    ``max |r|`` (1e-300 for no force) and the largest velocity term ``max(|b|, |W| force)``."""
    force = max(float(np.abs(r).max(initial=0.0)), 1e-300)
    velocity = max(float(np.abs(b).max(initial=0.0)), float(np.abs(W).max(initial=0.0)) * force)
    return force, velocity


def _check(v: Violations, primal, dual, complementarity) -> Violations:
    """Each condition within its bound (absolute: a number or one per contact), or an AssertionError
    naming the condition, the contact, what was measured and the bound."""
    for name, label, bound in (("primal", "primal feasibility, r in K_mu", primal),
                               ("dual", "dual feasibility, u in K*_mu", dual),
                               ("complementarity", "complementarity, |r . u|", complementarity)):
        measured = getattr(v, name)
        limit = np.broadcast_to(np.asarray(bound, dtype=np.float64), measured.shape)
        over = ~(measured <= limit)  # NaN is over
        if np.any(over):
            i = int(np.argmax(np.where(over, measured - limit, -np.inf)))
            raise AssertionError(f"{label}: contact {i} of {len(measured)} misses it by {measured[i]:.3g} "
                                 f"> {limit[i]:.3g} ({int(over.sum())} contacts over)")
    return v


def check_cone_qp(W, b, r, mu, *, primal, dual, complementarity) -> Violations:
    """Assert the optimality conditions of ``min 1/2 r'Wr + b'r`` over the cones at ``r``, each within its
    bound, and return what was measured (:func:`cone_qp_violations`).

    The bounds are absolute (a number, or one per contact): ``primal`` in force units, ``dual`` in
    velocity units, ``complementarity`` in force x velocity. Name each with its reason at the caller,
    as a tolerance times the scale it is relative to (:func:`problem_scales`)."""
    return _check(cone_qp_violations(W, b, r, mu), primal, dual, complementarity)


def check_coulomb(W, b, r, mu, *, primal, dual, complementarity) -> Violations:
    """Assert the conditions of the dynamic Coulomb law at ``r`` (De Saxce's ``u~``), each within its bound;
    as :func:`check_cone_qp`."""
    return _check(coulomb_violations(W, b, r, mu), primal, dual, complementarity)
