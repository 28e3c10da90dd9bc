"""Reference solver: the whole SOCQP with Clarabel (interior point), for tests and benchmarks.

Problem (statics, DESIGN.md "Inversion")::

    min_r 1/2 r' (H diag(d) H' + gamma I) r + b' r    s.t.  r_i in K_mu_i,

``r`` stacked per contact as ``(r_N, r_T1, r_T2)``. Nothing dense is built: with
the auxiliary ``z = diag(sqrt d) H' r`` the objective is
``1/2 |z|^2 + gamma/2 |r|^2 + b' r`` under ``n`` equality constraints.

Clarabel's constraints read ``A x + s = c, s in cone`` (so ``s = c - A x``); each
Coulomb cone becomes ``SecondOrderConeT(3)`` on ``s = (mu r_N, r_T) / max(1, mu)``
(the cone ``{|s_T| <= s_0}``; dividing by ``max(1, mu)`` keeps the rows of order one
for large ``mu``). ``mu = 0`` gives ``r_N >= 0`` (nonnegative cone) and ``r_T = 0``
(zero cone); ``mu = inf`` gives ``r_N >= 0`` alone.

Clarabel is a development dependency: it is imported inside the functions.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

__all__ = ["solve_socqp_clarabel", "solve_socqp_dense_clarabel"]


def _clarabel():
    try:
        import clarabel
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError(
            "the reference solver needs Clarabel: install the development extras "
            "(pip install -e '.[dev]') or 'pip install clarabel'"
        ) from exc
    return clarabel


def _cone_rows(mu: np.ndarray, n_vars: int):
    """Rows of ``A`` (``s = -A x``) and the cone list for the contact forces ``x[:3C]``.

    Returns (zero rows, nonnegative rows, second-order rows) as sparse matrices with
    ``n_vars`` columns, and the number of second-order cones.
    """
    C = mu.shape[0]
    zero_r, zero_c, zero_v = [], [], []
    nonneg_r, nonneg_c, nonneg_v = [], [], []
    soc_r, soc_c, soc_v = [], [], []
    n_zero = n_nonneg = n_soc = 0
    for i in range(C):
        m = mu[i]
        k = 3 * i
        if m == 0.0:
            nonneg_r.append(n_nonneg)
            nonneg_c.append(k)
            nonneg_v.append(-1.0)
            n_nonneg += 1
            zero_r += [n_zero, n_zero + 1]
            zero_c += [k + 1, k + 2]
            zero_v += [1.0, 1.0]
            n_zero += 2
        elif np.isinf(m):
            nonneg_r.append(n_nonneg)
            nonneg_c.append(k)
            nonneg_v.append(-1.0)
            n_nonneg += 1
        else:
            scale = max(1.0, m)
            soc_r += [3 * n_soc, 3 * n_soc + 1, 3 * n_soc + 2]
            soc_c += [k, k + 1, k + 2]
            soc_v += [-m / scale, -1.0 / scale, -1.0 / scale]
            n_soc += 1
    zero = sp.csc_matrix((zero_v, (zero_r, zero_c)), shape=(n_zero, n_vars))
    nonneg = sp.csc_matrix((nonneg_v, (nonneg_r, nonneg_c)), shape=(n_nonneg, n_vars))
    soc = sp.csc_matrix((soc_v, (soc_r, soc_c)), shape=(3 * n_soc, n_vars))
    return zero, nonneg, soc, n_soc


def _check_mu(mu, C: int) -> np.ndarray:
    mu = np.asarray(mu, dtype=np.float64).reshape(-1)
    if mu.shape != (C,):
        raise ValueError(f"mu must have one friction coefficient per contact ({C}), got shape {mu.shape}")
    if np.any(np.isnan(mu)) or np.any(mu < 0.0):
        raise ValueError("friction coefficients mu must be >= 0 (inf allowed)")
    return mu


def _solve(P, q, A_eq, mu, tol: float):
    """Run Clarabel on ``min 1/2 x'Px + q'x`` with ``A_eq x = 0`` and the cones of ``mu``.

    The contact forces are ``x[:3C]``. Returns (x, info).
    """
    clarabel = _clarabel()
    n_vars = P.shape[0]
    zero, nonneg, soc, n_soc = _cone_rows(mu, n_vars)
    blocks = [A_eq, zero] if A_eq is not None else [zero]
    A_zero = sp.vstack(blocks, format="csc")
    A = sp.vstack([A_zero, nonneg, soc], format="csc")
    c = np.zeros(A.shape[0])
    cones = []
    if A_zero.shape[0]:
        cones.append(clarabel.ZeroConeT(A_zero.shape[0]))
    if nonneg.shape[0]:
        cones.append(clarabel.NonnegativeConeT(nonneg.shape[0]))
    cones += [clarabel.SecondOrderConeT(3) for _ in range(n_soc)]
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.tol_gap_abs = tol
    settings.tol_gap_rel = tol
    settings.tol_feas = tol
    settings.max_iter = 500
    P = sp.triu(sp.csc_matrix(P), format="csc")
    solver = clarabel.DefaultSolver(P, np.ascontiguousarray(q, dtype=np.float64), A, c, cones, settings)
    solution = solver.solve()
    info = {
        "status": str(solution.status),
        "iterations": int(solution.iterations),
        "solve_time": float(solution.solve_time),
        "objective": float(solution.obj_val),
    }
    return np.asarray(solution.x, dtype=np.float64), info


def solve_socqp_clarabel(H, d, gamma, b, mu, tol: float = 1e-10):
    """Solve ``min 1/2 r'(H diag(d) H' + gamma I) r + b'r`` over the Coulomb cones with Clarabel.

    Parameters
    ----------
    H : (3C, n) scipy.sparse matrix (or array), contact rows
    d : (n,) float64, positive
    gamma : float >= 0, regularisation, or (C,) float64 >= 0, one per contact (``solver.gamma_relative``)
    b : (3C,) float64
    mu : (C,) float64 >= 0, friction coefficients (0 and inf allowed)
    tol : float, Clarabel's gap and feasibility tolerances

    Returns
    -------
    r : (C, 3) float64, forces (normal, tangent 1, tangent 2)
    info : dict with ``status`` (Clarabel's, e.g. ``"Solved"``), ``iterations``,
        ``solve_time`` (s) and ``objective`` (of the auxiliary form, ``1/2 r'Wr + b'r``)
    """
    H = sp.csr_matrix(H, dtype=np.float64)
    m3, n = H.shape
    if m3 % 3:
        raise ValueError(f"H must have 3 rows per contact, got {m3} rows")
    C = m3 // 3
    d = np.asarray(d, dtype=np.float64).reshape(-1)
    b = np.asarray(b, dtype=np.float64).reshape(-1)
    if d.shape != (n,):
        raise ValueError(f"d must have one entry per column of H ({n}), got shape {d.shape}")
    if not np.all(d > 0.0):
        raise ValueError("d must be positive")
    if b.shape != (m3,):
        raise ValueError(f"b must have shape ({m3},), got {b.shape}")
    gamma = np.broadcast_to(np.asarray(gamma, dtype=np.float64), (C,))
    if not np.all(gamma >= 0.0):
        raise ValueError("gamma must be >= 0")
    mu = _check_mu(mu, C)
    # x = (r, z):  1/2 |z|^2 + 1/2 sum_c gamma_c |r_c|^2 + b'r,  z - diag(sqrt d) H' r = 0
    P = sp.block_diag([sp.diags(np.repeat(gamma, 3)), sp.identity(n)], format="csc")
    q = np.concatenate([b, np.zeros(n)])
    A_eq = sp.hstack([-(sp.diags(np.sqrt(d)) @ H.T), sp.identity(n)], format="csc")
    x, info = _solve(P, q, A_eq, mu, tol)
    return x[:m3].reshape(C, 3), info


def solve_socqp_dense_clarabel(W, b, mu, tol: float = 1e-10):
    """Solve ``min 1/2 r'Wr + b'r`` over the Coulomb cones for a small dense SPD ``W``.

    Parameters
    ----------
    W : (3C, 3C) float64, symmetric positive definite
    b : (3C,) float64
    mu : (C,) float64 or float (one contact), >= 0
    tol : float, Clarabel's gap and feasibility tolerances

    Returns
    -------
    r : (C, 3) float64; info : dict as :func:`solve_socqp_clarabel`
    """
    W = np.asarray(W, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64).reshape(-1)
    m3 = b.shape[0]
    if m3 % 3 or W.shape != (m3, m3):
        raise ValueError(f"W must be (3C, 3C) and b (3C,), got {W.shape} and {b.shape}")
    C = m3 // 3
    mu = _check_mu(np.atleast_1d(mu), C)
    x, info = _solve(sp.csc_matrix(0.5 * (W + W.T)), b, None, mu, tol)
    return x.reshape(C, 3), info
