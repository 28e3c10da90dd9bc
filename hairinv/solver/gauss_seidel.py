"""Block Gauss-Seidel over contacts for the cone complementarity problem.

Solves ``K_mu ∋ r_i ⟂ (W r + b)_i ∈ K*_mu`` for every contact ``i`` with
``W = H D H^T + gamma I`` (Daviet et al. 2011, So-bogus), never assembling
``W``: the solver keeps ``f = D H^T r`` (one entry per coordinate of q), so
``(W r)_i = H_i f + gamma r_i`` and updating ``r_i`` by ``d`` adds
``D H_i^T d`` to ``f``. A sweep costs O(nnz(H)).

Parallel sweeps with deterministic results: the strands are split in two
halves by the position of their roots (balanced by contact count). The
contacts inside one half touch only that half's part of ``f`` and ``r``,
so the two halves are swept at the same time on two threads; the contacts
between the halves follow, coloured so that contacts sharing no strand get
the same colour (a large colour is again split over threads). The order
of the updates does not depend on the number of threads, so neither do the
results. On ruby short (29,118 contacts) 11 % of the contacts join the two
halves. The rows of ``H`` and every per-contact array are copied into that
order for the solve, so that a sweep reads memory front to back (on large
grooms, where they do not fit in cache, half the time of reading them in
detection's order).

The stop test is the natural map ``|r_i - P_K(r_i - (W r + b)_i / rho_i)|``
with ``rho_i = trace(W_ii) / 3``: a force, in newtons, zero exactly at the
solution. Its largest value over the contacts is compared with
``tolerance * force_scale``. The inverse problem's sweeps stop too once
the rest shape is provably within ``rest_tolerance`` (1/m, rms over
elements) of the optimum, by a duality gap measured at each check
(:func:`rest_gap`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .._jit import jit


from .._parallel import blas_pinned, executor, in_worker, worker_count
from .local import CODE_NUMERICAL, project_cone, solve_contact_with
from .problem import ConeProblem, Law, SweepSettings
from .rows import ContactRows
from .status import Status

__all__ = ["SolverResult", "SweepOrder", "accumulate_f", "colour_contacts", "diagonal_blocks", "natural_residuals",
           "project_forces", "residual", "rest_gap", "solve", "split_strands", "sweep_order", "sweep_plan"]

# Colours with fewer contacts than this run on one thread: handing a small
# colour to the thread pool costs more than it saves.
_MIN_PARALLEL = 4096
# Below this many contacts a whole sweep runs on one thread: a sweep then takes well under a
# millisecond, and handing the two halves to the pool costs about as much as it saves.
_MIN_HALVES = 2048
_LOCAL_ITERATIONS = 50
# Below this many contacts the passes other than the sweep (the rebuild of f, the checks) run their pieces on
# one thread: each takes a few microseconds a contact, and a hand-off to the pool about as long as 10,000 of them.
_MIN_PIECES = 32768


@dataclass
class SolverResult:
    """What the cone solver found.

    Attributes
    ----------
    r : (C, 3) float64, N, forces in the contact frames (the last iterate)
    status : Status, CONVERGED, MAX_ITERS or NUMERICAL_ERROR
    sweeps : int, Gauss-Seidel sweeps done
    residual : float, N, largest natural-map residual over the contacts
    relative_residual : float, ``residual / force_scale``
    history : list of (sweep, residual in N)
    seconds : float
    colours : int
    local_failures : int, local solves that returned their best iterate unconverged in the last sweep
    method : "sweeps", or "interior-point" when the forces come from :mod:`hairinv.solver.interior`
    interior_steps : int, interior-point steps taken (0 for the sweeps)
    rest_bound : float, 1/m, a bound on the rest shape's distance from the optimum, rms over elements, from
        a duality gap (:func:`rest_gap` for the sweeps, the interior-point method's own for its forces; NaN
        when there is none: the De Saxce problem of the dynamics)
    """

    r: np.ndarray
    status: Status
    sweeps: int
    residual: float
    relative_residual: float
    history: list = field(default_factory=list)
    seconds: float = 0.0
    colours: int = 0
    local_failures: int = 0
    restarts: int = 0
    method: str = "sweeps"
    interior_steps: int = 0
    rest_bound: float = float("nan")
    bound_from: str = "sweeps"
    """whose duality gap ``rest_bound`` is: "sweeps", or "interior-point" when the steps' forces were final"""


@jit
def diagonal_blocks(ptr, cols, vals, d, gamma, out):
    """``W_ii = H_i D H_i^T + gamma_i I`` of every contact, (C, 3, 3); ``gamma`` is (C,)."""
    for i in range(ptr.shape[0] - 1):
        for a in range(3):
            for c in range(3):
                out[i, a, c] = 0.0
        for j in range(ptr[i], ptr[i + 1]):
            dj = d[cols[j]]
            for a in range(3):
                for c in range(3):
                    out[i, a, c] += vals[j, a] * dj * vals[j, c]
        for a in range(3):
            out[i, a, a] += gamma[i]


@jit
def accumulate_f(ptr, cols, vals, d, r, f):
    """``f = D H^T r`` from scratch."""
    f[:] = 0.0
    _add_f(ptr, cols, vals, r, f, 0, ptr.shape[0] - 1)
    for k in range(f.shape[0]):
        f[k] *= d[k]


@jit
def _add_f(ptr, cols, vals, r, f, lo, hi):
    """``f += H^T r`` over the contacts ``lo:hi``, one after the other."""
    for i in range(lo, hi):
        for j in range(ptr[i], ptr[i + 1]):
            f[cols[j]] += vals[j, 0] * r[i, 0] + vals[j, 1] * r[i, 1] + vals[j, 2] * r[i, 2]


@jit(inline="always")
def _contact_u(i, ptr, cols, vals, f, gamma, b, r, u):
    """``u = (W r + b)_i = H_i f + gamma_i r_i + b_i`` with ``f = D H^T r``."""
    u[0] = b[i, 0] + gamma[i] * r[i, 0]
    u[1] = b[i, 1] + gamma[i] * r[i, 1]
    u[2] = b[i, 2] + gamma[i] * r[i, 2]
    for j in range(ptr[i], ptr[i + 1]):
        fj = f[cols[j]]
        u[0] += vals[j, 0] * fj
        u[1] += vals[j, 1] * fj
        u[2] += vals[j, 2] * fj


@jit
def _sweep(lo, hi, ptr, cols, vals, d, gamma, Wd, b, mu, r, f, local_tol, desaxce):
    """Update the contacts ``lo:hi`` one after the other; returns (failures, numerical errors)."""
    u = np.empty(3)
    bl = np.empty(3)
    rn = np.empty(3)
    M = np.empty((6, 3, 3))  # the local solves' scratch
    V = np.empty((8, 3))
    failures = 0
    numerical = 0
    for i in range(lo, hi):
        if mu[i] == 0.0 and r[i, 1] == 0.0 and r[i, 2] == 0.0 and Wd[i, 0, 0] > 0.0:
            # frictionless: a 1-D normal complementarity problem, r_N = max(0, r_N - u_N / W_NN) and r_T = 0
            # exactly, on the normal row of H alone (150 wavy guides, 1,120 contacts: 0.18 ms a sweep against
            # 0.28 through the 3-D local solve; the same optimum)
            uN = b[i, 0] + gamma[i] * r[i, 0]
            for j in range(ptr[i], ptr[i + 1]):
                uN += vals[j, 0] * f[cols[j]]
            if not np.isfinite(uN):
                numerical += 1
                continue
            rN = r[i, 0] - uN / Wd[i, 0, 0]
            if rN < 0.0:
                rN = 0.0
            d0 = rN - r[i, 0]
            r[i, 0] = rN
            for j in range(ptr[i], ptr[i + 1]):
                c = cols[j]
                f[c] += d[c] * vals[j, 0] * d0
            continue
        _contact_u(i, ptr, cols, vals, f, gamma, b, r, u)
        # local problem W_ii r_i + bl with the other contacts frozen
        for a in range(3):
            bl[a] = u[a] - (Wd[i, a, 0] * r[i, 0] + Wd[i, a, 1] * r[i, 1] + Wd[i, a, 2] * r[i, 2])
            rn[a] = r[i, a]
        status, _ = solve_contact_with(Wd[i], bl, mu[i], rn, local_tol, _LOCAL_ITERATIONS, desaxce, M, V)
        if status == CODE_NUMERICAL:
            numerical += 1
            continue
        if status != 0:
            failures += 1
        d0 = rn[0] - r[i, 0]
        d1 = rn[1] - r[i, 1]
        d2 = rn[2] - r[i, 2]
        r[i, 0] = rn[0]
        r[i, 1] = rn[1]
        r[i, 2] = rn[2]
        for j in range(ptr[i], ptr[i + 1]):
            c = cols[j]
            f[c] += d[c] * (vals[j, 0] * d0 + vals[j, 1] * d1 + vals[j, 2] * d2)
    return failures, numerical


@jit
def _objective(f, d, gamma, b, r):
    """``1/2 r^T W r + b^T r`` from ``f = D H^T r``: ``r^T H D H^T r = sum f^2 / d``."""
    acc = 0.0
    for k in range(f.shape[0]):
        acc += f[k] * f[k] / d[k]
    reg = 0.0
    lin = 0.0
    for i in range(r.shape[0]):
        for a in range(3):
            reg += gamma[i] * r[i, a] * r[i, a]
            lin += b[i, a] * r[i, a]
    return 0.5 * acc + 0.5 * reg + lin


@jit
def _extrapolate(x, x_prev, beta, mu, out):
    """``out = P_K(x + beta (x - x_prev))``, contact by contact."""
    y = np.empty(3)
    p = np.empty(3)
    for i in range(x.shape[0]):
        for a in range(3):
            y[a] = x[i, a] + beta * (x[i, a] - x_prev[i, a])
        project_cone(y, mu[i], p)
        for a in range(3):
            out[i, a] = p[a]


def project_forces(r: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """Each contact's force of ``r`` (C, 3) projected onto its Coulomb cone (a new array)."""
    r = np.ascontiguousarray(r, dtype=np.float64)
    out = np.empty_like(r)
    if len(r):
        _extrapolate(r, r, 0.0, np.ascontiguousarray(mu, dtype=np.float64), out)
    return out


@jit(error_model="numpy")
def rest_gap(ptr, cols, vals, f, gamma, b, mu, r):
    """A duality gap of forces ``r`` in the cones: ``f(r) - f* <= gap`` for ``f(r) = 1/2 r^T W r + b^T r``,
    ``W = H D H^T + diag(gamma)``, with ``f = D H^T r``.

    With ``b = H D a`` the problem is ``min 1/2 |D^1/2 (H^T r + a)|^2 + 1/2 sum gamma_i |r_i|^2`` over the
    cones, whose Lagrange dual is ``max_y -1/2 |y|^2 + y^T D^1/2 a - sum_i |P_K(-v_i)|^2 / (2 gamma_i)``,
    ``v = H D^1/2 y``. At ``y = D^1/2 (H^T r + a)`` (the rest shape's own deviation), ``v = H f + b`` and the
    gap is ``sum_i |gamma_i r_i - P_K(-v_i)|^2 / (2 gamma_i) + r_i . (P_K(-v_i) + v_i)``: each term is
    non-negative (``r_i`` in the cone, ``-v_i - P_K(-v_i)`` in its polar), and all vanish at the optimum.
    So no constant of the objective and no solve is needed: one pass over the rows. Since the objective is
    ``1/2 |q0 - t|^2`` plus the ``gamma`` term, ``|q0 - q0*|^2 <= 2 gap`` (docs/inverse.md).
    Returns inf where a contact of ``gamma_i = 0`` has ``P_K(-v_i) != 0``, NaN for a non-finite term.
    """
    u = np.empty(3)
    w = np.empty(3)
    p = np.empty(3)
    gap = 0.0
    for i in range(ptr.shape[0] - 1):
        _contact_u(i, ptr, cols, vals, f, gamma, b, r, u)
        g = gamma[i]
        for a in range(3):
            w[a] = -(u[a] - g * r[i, a])  # -v_i: u includes gamma_i r_i
        project_cone(w, mu[i], p)
        slack = 0.0
        for a in range(3):
            slack += r[i, a] * (p[a] - w[a])
        if slack < 0.0:  # round-off only: r_i in the cone, w - P_K(w) in its polar
            slack = 0.0
        apart = (g * r[i, 0] - p[0]) ** 2 + (g * r[i, 1] - p[1]) ** 2 + (g * r[i, 2] - p[2]) ** 2
        if g > 0.0:
            gap += apart / (2.0 * g) + slack
        elif apart > 0.0:
            gap += np.inf
        else:
            gap += slack
    return gap


@jit(error_model="numpy")
def natural_residuals(ptr, cols, vals, f, gamma, Wd, b, mu, r, desaxce, velocity, out):
    """Per-contact natural-map residual ``|r_i - P_K(r_i - u_i / rho_i)|`` in force units.

    ``u = H f + gamma r + b`` with ``f = D H^T r``; ``rho_i = trace(W_ii) / 3``.
    With ``desaxce``, ``u`` is the De Saxce velocity ``u + mu |u_T| e_N``. With
    ``velocity``, the residual is ``rho_i`` times the above, in velocity units
    (dynamics: a contact whose ``W_ii`` is large turns a small impulse error into
    a large velocity one).
    Returns the largest value (NaN if any is not finite, as for a contact whose ``W_ii`` is zero:
    the division yields inf or NaN instead of raising inside the kernel).
    """
    u = np.empty(3)
    x = np.empty(3)
    p = np.empty(3)
    worst = 0.0
    finite = True
    for i in range(ptr.shape[0] - 1):
        _contact_u(i, ptr, cols, vals, f, gamma, b, r, u)
        if desaxce and mu[i] < np.inf:  # (mu = inf: the dual cone is the ray u_T = 0, no De Saxce term)
            u[0] += mu[i] * np.sqrt(u[1] * u[1] + u[2] * u[2])
        rho = (Wd[i, 0, 0] + Wd[i, 1, 1] + Wd[i, 2, 2]) / 3.0
        for a in range(3):
            x[a] = r[i, a] - u[a] / rho
        project_cone(x, mu[i], p)
        e = np.sqrt((r[i, 0] - p[0]) ** 2 + (r[i, 1] - p[1]) ** 2 + (r[i, 2] - p[2]) ** 2)
        if velocity:
            e *= rho
        out[i] = e
        if not np.isfinite(e):
            finite = False
        elif e > worst:
            worst = e
    return worst if finite else np.nan


@jit
def _greedy_colours(strand, visit, n_strands, max_colours, colour):
    """Greedy colouring in the order ``visit``: contacts sharing a strand get different colours."""
    used = np.zeros((n_strands, max_colours), dtype=np.bool_)
    n_colours = 0
    for t in range(visit.shape[0]):
        i = visit[t]
        a = strand[i, 0]
        b = strand[i, 1]
        c = 0
        while used[a, c] or (b >= 0 and used[b, c]):
            c += 1
        colour[i] = c
        used[a, c] = True
        if b >= 0:
            used[b, c] = True
        if c + 1 > n_colours:
            n_colours = c + 1
    return n_colours


def colour_contacts(strand: np.ndarray, n_strands: int, s: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Order contacts by colour so that contacts of one colour share no strand.

    With the arc lengths ``s`` (C, 2), contacts far from the root are coloured
    first, so a sweep runs from the tips towards the roots (a contact near the
    tip moves every element of its strand, one near the root only a few). On
    the wavy sample this lowers the objective faster than root-first
    (0.26% lower after 100 sweeps, 0.15% after 400).

    Returns
    -------
    order : (C,) int64, contact indices colour after colour (stable within a colour)
    bounds : (n_colours + 1,) int64, colour ``k`` is ``order[bounds[k]:bounds[k+1]]``
    """
    strand = np.ascontiguousarray(strand, dtype=np.int64)
    if len(strand) == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(1, dtype=np.int64)
    degree = np.bincount(strand[:, 0], minlength=n_strands)
    other = strand[:, 1][strand[:, 1] >= 0]
    degree += np.bincount(other, minlength=n_strands)
    colour = np.empty(len(strand), dtype=np.int64)
    if s is None:
        visit = np.arange(len(strand), dtype=np.int64)
    else:
        visit = np.lexsort((np.arange(len(strand)), -np.asarray(s)[:, 0])).astype(np.int64)
    n_colours = _greedy_colours(strand, visit, n_strands, int(2 * degree.max() + 1), colour)
    rank = np.empty(len(strand), dtype=np.int64)
    rank[visit] = np.arange(len(strand))
    order = np.lexsort((rank, colour)).astype(np.int64)
    bounds = np.searchsorted(colour[order], np.arange(n_colours + 1)).astype(np.int64)
    return order, bounds


def split_strands(roots: np.ndarray, strand: np.ndarray) -> np.ndarray:
    """Two halves of the strands, (S,) int64 in {0, 1}, split across the roots' longest extent
    so that each half holds about as many contacts."""
    n_strands = len(roots)
    part = np.zeros(n_strands, dtype=np.int64)
    if n_strands < 2 or len(strand) == 0:
        return part
    axis = int(np.argmax(np.ptp(roots, axis=0)))
    by_position = np.argsort(roots[:, axis], kind="stable")
    load = np.bincount(strand[:, 0], minlength=n_strands).astype(np.float64)
    load += np.bincount(strand[:, 1][strand[:, 1] >= 0], minlength=n_strands)
    cumulative = np.cumsum(load[by_position])
    split = int(np.searchsorted(cumulative, 0.5 * cumulative[-1])) + 1
    part[by_position[split:]] = 1
    return part


def sweep_plan(strand: np.ndarray, n_strands: int, s: np.ndarray | None = None,
               part_of: np.ndarray | None = None) -> tuple[np.ndarray, list, np.ndarray]:
    """The order of the updates in a sweep.

    Returns
    -------
    order : (C,) int64, contact indices in update order
    halves : list of (lo, hi), ranges of ``order`` that may run at the same time (each on one thread,
        tips first along each strand)
    colours : (k + 1,) int64, the remaining range ``order[colours[0]:]`` split by colour
    """
    strand = np.ascontiguousarray(strand, dtype=np.int64)
    count = len(strand)
    if part_of is None or count == 0:
        order, bounds = colour_contacts(strand, n_strands, s)
        return order, [], bounds
    side_b = np.where(strand[:, 1] >= 0, strand[:, 1], strand[:, 0])
    pa, pb = part_of[strand[:, 0]], part_of[side_b]
    tips_first = np.arange(count) if s is None else np.lexsort((np.arange(count), -np.asarray(s)[:, 0]))
    pieces, halves, start = [], [], 0
    for half in (0, 1):
        inside = tips_first[(pa[tips_first] == half) & (pb[tips_first] == half)]
        pieces.append(inside)
        halves.append((start, start + len(inside)))
        start += len(inside)
    across = np.flatnonzero(pa != pb)
    sub_order, sub_bounds = colour_contacts(strand[across], n_strands, None if s is None else np.asarray(s)[across])
    pieces.append(across[sub_order])
    order = np.concatenate(pieces).astype(np.int64)
    return order, [h for h in halves if h[1] > h[0]], (sub_bounds + start).astype(np.int64)


@dataclass
class SweepOrder:
    """A problem's rows, regularisation and diagonal blocks stored in its sweeps' update order
    (:func:`sweep_order`): made once for several solves of the same ``H``, ``D``, ``gamma`` and contacts,
    such as the rounds of one dynamic step."""

    plan: np.ndarray
    """(C,) int64, contact indices in update order (:func:`sweep_plan`)"""
    halves: list
    """ranges of ``plan`` swept at the same time (:func:`sweep_plan`)"""
    bounds: np.ndarray
    """the colours of the rest of ``plan`` (:func:`sweep_plan`)"""
    rows: ContactRows
    """``H``'s rows in update order"""
    gamma: np.ndarray
    """(C,) float64, in update order"""
    Wd: np.ndarray
    """(C, 3, 3) float64, the blocks ``W_ii`` in update order"""


def sweep_order(problem: ConeProblem) -> SweepOrder:
    """The update order of :func:`solve` for this problem, with what it stores in it (made once for
    several solves of the same rows, ``D``, ``gamma``, strands and contacts, such as the rounds of one step).

    Every contact's rows and data are stored in update order, so that a sweep reads them front to back: on a
    30,000-strand head (780,199 contacts) a sweep took 0.84 s on one thread in the order detection wrote them,
    0.42 s so (the same updates, bit for bit; sums over all contacts, such as f, round differently)."""
    plan, halves, bounds = sweep_plan(problem.strand, problem.n_strands, problem.s, problem.part_of)
    rows = problem.rows.take(plan)
    gamma = np.ascontiguousarray(problem.gamma[plan])
    Wd = np.empty((rows.n_contacts, 3, 3))
    diagonal_blocks(rows.ptr, rows.cols, rows.vals, problem.d, gamma, Wd)
    return SweepOrder(plan, halves, bounds, rows, gamma, Wd)


def residual(problem: ConeProblem, law: Law, r: np.ndarray, Wd: np.ndarray | None = None) -> float:
    """The largest natural-map residual of forces ``r`` (C, 3) for ``problem`` under ``law``
    (:func:`natural_residuals`; in velocity units for a ``velocity`` problem). ``Wd``: the blocks ``W_ii``,
    if already at hand. 0 without contacts; NaN if any contact's residual is not finite."""
    rows = problem.rows
    if rows.n_contacts == 0:
        return 0.0
    if Wd is None:
        Wd = np.empty((rows.n_contacts, 3, 3))
        diagonal_blocks(rows.ptr, rows.cols, rows.vals, problem.d, problem.gamma, Wd)
    r = np.ascontiguousarray(r, dtype=np.float64)
    f = np.empty(rows.n_dofs)
    accumulate_f(rows.ptr, rows.cols, rows.vals, problem.d, r, f)
    per = np.empty(rows.n_contacts)
    return float(natural_residuals(rows.ptr, rows.cols, rows.vals, f, problem.gamma, Wd, problem.b, problem.mu, r,
                                   law.desaxce, problem.velocity, per))


def solve(problem: ConeProblem, law: Law, settings: SweepSettings = SweepSettings(), start: np.ndarray | None = None,
          progress=None, order: SweepOrder | None = None) -> SolverResult:
    """Solve ``problem`` under ``law`` by accelerated block Gauss-Seidel over the contacts (module docstring).

    Parameters
    ----------
    problem : ConeProblem, ``W = H D H^T + diag(gamma)``, ``b``, ``mu``, the strands' layout and the residual's scale
    law : Law, :data:`hairinv.solver.problem.CONE` (the convex problem) or ``COULOMB`` (De Saxce's)
    settings : SweepSettings, the stopping rule and the momentum
    start : (C, 3) float64, optional warm start (projected onto the cones first)
    progress : callable(sweeps, relative residual, rest-shape bound in 1/m), optional, called at every residual
        check (the bound NaN for a law that is not convex)
    order : SweepOrder, optional, :func:`sweep_order` of this problem (made here if not given)

    Returns the forces the last residual check measured (the iterate projected onto the cones), with the status
    (:class:`Status`) and residual of those forces.
    """
    rows, d, b, mu = problem.rows, problem.d, problem.b, problem.mu
    force_scale, velocity, desaxce = problem.scale, problem.velocity, law.desaxce
    tolerance, max_sweeps, check_every = settings.tolerance, settings.max_sweeps, settings.check_every
    max_seconds, rest_tolerance = settings.max_seconds, settings.rest_tolerance
    started = time.perf_counter()
    n_contacts = rows.n_contacts
    r = np.zeros((n_contacts, 3)) if start is None else np.array(start, dtype=np.float64, copy=True)
    if n_contacts == 0:
        return SolverResult(r, Status.CONVERGED, 0, 0.0, 0.0, [(0, 0.0)], time.perf_counter() - started,
                            rest_bound=float("nan") if desaxce else 0.0)
    if order is None:
        order = sweep_order(problem)
    plan, halves, bounds, rows, gamma, Wd = order.plan, order.halves, order.bounds, order.rows, order.gamma, order.Wd
    r, b, mu = r[plan], b[plan], mu[plan]
    # the start in the cones, as every point whose residual is measured: the local solves meet the cones
    # only to about eps^(3/4), and the forces returned are exactly admissible
    _extrapolate(r, r, 0.0, mu, r)
    threads = worker_count()
    pool = executor(threads) if threads > 1 and not in_worker() and n_contacts >= _MIN_HALVES else None

    # the other passes over the contacts run in three pieces: the two halves at once, then the contacts
    # across; the same pieces on one thread, so that what they return does not depend on the thread count
    pieces = [*halves, (halves[-1][1], n_contacts)] if len(halves) == 2 else [(0, n_contacts)]

    def by_pieces(kernel) -> list:
        """``kernel(lo, hi)`` over the pieces, in their order."""
        if pool is None or len(pieces) == 1 or n_contacts < _MIN_PIECES:
            return [kernel(lo, hi) for lo, hi in pieces]
        futures = [pool.submit(kernel, lo, hi) for lo, hi in pieces[:2]]
        return [future.result() for future in futures] + [kernel(*pieces[2])]

    def accumulate(point: np.ndarray, out: np.ndarray) -> None:
        """``out = D H^T point``. The two halves touch disjoint strands, so each entry sums its terms in the
        same order on any number of threads."""
        out[:] = 0.0
        by_pieces(lambda lo, hi: _add_f(rows.ptr, rows.cols, rows.vals, point, out, lo, hi))
        out *= d

    f = np.empty(rows.n_dofs)
    accumulate(r, f)
    per_contact = np.empty(n_contacts)
    # local solves to a tolerance near eps^(3/4), relative to the contact's own scale
    local_tol = np.finfo(float).eps ** 0.75
    target = tolerance * force_scale
    history = []
    status = Status.MAX_ITERS
    sweeps = 0
    failures = 0

    f_check = np.empty(rows.n_dofs)
    # the point of the last residual check, projected onto the cones: what the solver returns, so that the
    # status and the residual it reports are those of the forces it returns
    checked = np.empty((n_contacts, 3))

    elements = rows.n_dofs // 3
    bound = [np.nan]  # the rest-shape bound at the last check (1/m)
    # measured at every check where it can stop the sweeps or is shown, else once at the end (the dynamics'
    # inner solves have no use for it)
    every_check = rest_tolerance > 0.0 or progress is not None

    def _measure_bound() -> None:
        if law.convex and elements:
            gap = sum(by_pieces(lambda lo, hi: rest_gap(rows.ptr[lo:hi + 1], rows.cols, rows.vals, f_check,
                                                        gamma[lo:hi], b[lo:hi], mu[lo:hi], checked[lo:hi])))
            bound[0] = float(np.sqrt(2.0 * max(gap, 0.0) / elements))

    def _check(point: np.ndarray) -> float:
        by_pieces(lambda lo, hi: _extrapolate(point[lo:hi], point[lo:hi], 0.0, mu[lo:hi], checked[lo:hi]))
        # f rebuilt from the point itself, so round-off of the incremental updates cannot accumulate
        accumulate(checked, f_check)
        if every_check:
            _measure_bound()
        # the largest over the pieces (NaN if any is NaN, as over all contacts)
        return float(np.max(by_pieces(lambda lo, hi: natural_residuals(
            rows.ptr[lo:hi + 1], rows.cols, rows.vals, f_check, gamma[lo:hi], Wd[lo:hi], b[lo:hi], mu[lo:hi],
            checked[lo:hi], desaxce, velocity, per_contact[lo:hi]))))

    def _met(residual: float) -> bool:
        return residual <= target or (rest_tolerance > 0.0 and bound[0] <= rest_tolerance)

    def sweep_colour(lo: int, hi: int) -> tuple[int, int]:
        return _sweep(lo, hi, rows.ptr, rows.cols, rows.vals, d, gamma, Wd, b, mu, r, f, local_tol, desaxce)

    residual = _check(r)
    history.append((0, float(residual)))
    if np.isfinite(residual) and _met(residual):  # (a NaN residual is found NUMERICAL at the next check)
        status = Status.CONVERGED
    # momentum state: x the last accepted iterate, r the point the next sweep starts from
    accelerate = settings.accelerate and law.convex  # the De Saxce problem has no objective to guard the momentum
    x = r.copy()
    x_prev = r.copy()
    fx = _objective(f, d, gamma, b, r)
    tk = 1.0
    restarts = 0
    from_x = True
    with blas_pinned():  # the kernels' own threads, not BLAS's
        while status == Status.MAX_ITERS and sweeps < max_sweeps:
            failures = 0
            numerical = 0
            if len(halves) == 2 and pool is not None:
                futures = [pool.submit(sweep_colour, lo, hi) for lo, hi in halves]
                for future in futures:
                    fc, nc = future.result()
                    failures += fc
                    numerical += nc
            else:
                for lo, hi in halves:
                    fc, nc = sweep_colour(lo, hi)
                    failures += fc
                    numerical += nc
            for k in range(len(bounds) - 1):
                lo, hi = int(bounds[k]), int(bounds[k + 1])
                if pool is not None and hi - lo >= _MIN_PARALLEL:
                    step = -(-(hi - lo) // threads)
                    futures = [pool.submit(sweep_colour, a, min(hi, a + step)) for a in range(lo, hi, step)]
                    for future in futures:
                        fc, nc = future.result()
                        failures += fc
                        numerical += nc
                else:
                    fc, nc = sweep_colour(lo, hi)
                    failures += fc
                    numerical += nc
            sweeps += 1
            if numerical:
                status = Status.NUMERICAL_ERROR
                break
            if accelerate:
                fz = _objective(f, d, gamma, b, r)
                if fz > fx and not from_x:
                    # the extrapolated start did worse than x: drop the momentum, sweep from x again
                    # (a plain sweep from x is always accepted: it cannot raise the objective beyond round-off)
                    restarts += 1
                    tk = 1.0
                    r[:] = x
                    from_x = True
                else:
                    from_x = False
                    tn = 0.5 * (1.0 + np.sqrt(1.0 + 4.0 * tk * tk))
                    x_prev[:] = x
                    x[:] = r
                    fx = fz
                    beta = (tk - 1.0) / tn
                    by_pieces(lambda lo, hi: _extrapolate(x[lo:hi], x_prev[lo:hi], beta, mu[lo:hi], r[lo:hi]))
                    tk = tn
                accumulate(r, f)
            if sweeps % check_every == 0 or sweeps == max_sweeps:
                residual = _check(x if accelerate else r)
                history.append((sweeps, float(residual)))
                if progress is not None:
                    progress(sweeps, residual / force_scale, bound[0])
                if not np.isfinite(residual) or not np.all(np.isfinite(r)):
                    status = Status.NUMERICAL_ERROR
                elif _met(residual):
                    status = Status.CONVERGED
                elif max_seconds > 0 and time.perf_counter() - started > max_seconds:
                    break
    if accelerate:
        r = x
    if history[-1][0] != sweeps:  # (stopped by a numerical error before its check)
        residual = _check(r)
        history.append((sweeps, float(residual)))
    if not every_check:
        _measure_bound()  # at the last check's point: the forces returned
    # the forces the last check measured: the last iterate, projected onto the cones (in the caller's order)
    r = np.empty_like(checked)
    r[plan] = checked
    return SolverResult(r, status, sweeps, float(residual), float(residual / force_scale), history,
                        time.perf_counter() - started, len(bounds) - 1, failures, restarts, rest_bound=bound[0])
