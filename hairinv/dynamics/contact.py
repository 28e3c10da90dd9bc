"""Frictional contact of one time step: the Delassus operator in factored form.

With the step's mass matrix ``Mt = L L^T`` (one Cholesky factor per strand)
the Delassus operator is ``W = H Mt^-1 H^T = Z^T Z`` with ``Z_i = L^-1 H_i^T``
(one forward substitution per contact side). The cone solver of the
inverse problem then runs unchanged on the rows ``Z_i^T`` with ``D = I``
and ``gamma = 0``: it keeps ``z = Z^T r`` per strand coordinate, so that
``(W r)_i = Z_i^T z``, and the velocity correction of the impulses is
``Mt^-1 H^T r = L^-T z`` (one back substitution per strand). Nothing global
is factorised; hair-hair contacts couple two strands only through ``W``.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from .._jit import jit
from .._parallel import run_chunks
from ..solver import gauss_seidel
from ..solver.blocks import group_fixed_point, group_newton, strand_blocks
from ..solver.gauss_seidel import SolverResult, accumulate_f, diagonal_blocks, sweep_order
from ..solver.problem import CONE, COULOMB, ConeProblem, SweepSettings
from ..solver.rows import ContactRows
from ..solver.status import Status

__all__ = ["REACH", "CoulombSettings", "back_substitute", "contact_keys", "contact_velocities", "coulomb_problem",
           "delassus_blocks", "desaxce_residual", "factored_blocks", "factored_rows", "forward_substitute", "reachable",
           "solve_coulomb", "strand_groups"]

#: a contact is not asked to move its point along a direction that a unit impulse moves it less than
#: this fraction as fast as along the easiest one (eigenvalues of ``W_ii``; see :func:`reachable`)
REACH = 1e-2

#: Newton iterations of a strand's body contacts solved together (:func:`solve_coulomb`)
GROUP_NEWTON_ITERS = 30
#: Newton iterations of each round's convex problem in the strands' fixed point (:func:`solve_coulomb`);
#: where they leave it unsolved, Gauss-Seidel on the strand's block takes over
FIXED_POINT_NEWTON_ITERS = 10
#: a strand's fixed point stops after this many rounds without a new best (its residual is not monotone:
#: it may rise for several rounds before it falls below its best)
FIXED_POINT_PATIENCE = 20


@jit
def _side_columns(strand, offsets):
    return 3 * offsets[strand], 3 * (offsets[strand + 1] - offsets[strand])


@jit
def _count_z(strand, offsets, counts):
    for i in range(strand.shape[0]):
        c = 0
        for side in range(2):
            k = strand[i, side]
            if k >= 0:
                c += 3 * (offsets[k + 1] - offsets[k])
        counts[i] = c


@jit(inline="always")
def _z_side(i, side, ptr, cols, vals, strand, offsets, chol, chol_ptr):
    """``(a, x)``: the first coordinate ``a`` of the strand on side ``side`` of contact ``i``, and
    ``x = L^-1 H_i^T`` (n, 3) over that strand's ``n`` coordinates."""
    k = strand[i, side]
    a, n = _side_columns(k, offsets)
    x = np.zeros((n, 3))
    for t in range(ptr[i], ptr[i + 1]):
        c = cols[t] - a
        if 0 <= c < n:
            for row in range(3):
                x[c, row] += vals[t, row]
    base = chol_ptr[k]
    # forward substitution L x = h, L row-major n x n at chol[base:]
    for r in range(n):
        for row in range(3):
            acc = x[r, row]
            for m in range(r):
                acc -= chol[base + r * n + m] * x[m, row]
            x[r, row] = acc / chol[base + r * n + r]
    return a, x


@jit
def _fill_z(ptr, cols, vals, strand, offsets, chol, chol_ptr, zptr, zcols, zvals, lo, hi):
    for i in range(lo, hi):
        j = zptr[i]
        for side in range(2):
            if strand[i, side] < 0:
                continue
            a, x = _z_side(i, side, ptr, cols, vals, strand, offsets, chol, chol_ptr)
            for r in range(x.shape[0]):
                zcols[j] = a + r
                for row in range(3):
                    zvals[j, row] = x[r, row]
                j += 1


@jit
def _z_blocks(ptr, cols, vals, strand, offsets, chol, chol_ptr, out, lo, hi):
    for i in range(lo, hi):
        for p in range(3):
            for q in range(3):
                out[i, p, q] = 0.0
        for side in range(2):
            if strand[i, side] < 0:
                continue
            _, x = _z_side(i, side, ptr, cols, vals, strand, offsets, chol, chol_ptr)
            # summed in the order, and rounded as, diagonal_blocks does over the rows of factored_rows
            for r in range(x.shape[0]):
                for p in range(3):
                    for q in range(3):
                        out[i, p, q] += x[r, p] * x[r, q]


@jit
def _substitute(offsets, chol, chol_ptr, y, out, lo, hi, transposed):
    """``out = L^-1 y`` (``L^-T y`` if ``transposed``) strand by strand for strands ``lo:hi``, ``L`` each
    strand's Cholesky factor, row-major at ``chol[chol_ptr[k]:]`` (``y``, ``out`` over all coordinates)."""
    for k in range(lo, hi):
        a = 3 * offsets[k]
        n = 3 * (offsets[k + 1] - offsets[k])
        base = chol_ptr[k]
        for t in range(n):
            r = n - 1 - t if transposed else t
            acc = y[a + r]
            if transposed:
                for m in range(r + 1, n):
                    acc -= chol[base + m * n + r] * out[a + m]
            else:
                for m in range(r):
                    acc -= chol[base + r * n + m] * out[a + m]
            out[a + r] = acc / chol[base + r * n + r]


@jit
def forward_substitute(offsets, chol, chol_ptr, y, out, lo, hi):
    """``out = L^-1 y`` strand by strand for strands ``lo:hi`` (``y``, ``out`` over all coordinates)."""
    _substitute(offsets, chol, chol_ptr, y, out, lo, hi, False)


def factored_rows(rows: ContactRows, strand: np.ndarray, offsets: np.ndarray, chol: np.ndarray,
                  chol_ptr: np.ndarray, run=None) -> ContactRows:
    """The rows ``Z_i^T = (L^-1 H_i^T)^T`` over every coordinate of the strands contact ``i`` touches.

    Parameters
    ----------
    rows : ContactRows, ``H``
    strand : (C, 2) int64, the strands of each contact (-1: the body)
    offsets : (S + 1,) int64, element offsets of the strands
    chol, chol_ptr : the strands' Cholesky factors, row-major, strand ``k`` at ``chol[chol_ptr[k]:]``
    run : optional ``run(work, count)`` spreading ``work(lo, hi)`` over threads
    """
    n_contacts = rows.n_contacts
    counts = np.zeros(n_contacts, dtype=np.int64)
    _count_z(strand, offsets, counts)
    zptr = np.zeros(n_contacts + 1, dtype=np.int64)
    np.cumsum(counts, out=zptr[1:])
    zcols = np.empty(zptr[-1], dtype=np.int64)
    zvals = np.empty((zptr[-1], 3))

    def work(lo: int, hi: int) -> None:
        _fill_z(rows.ptr, rows.cols, rows.vals, strand, offsets, chol, chol_ptr, zptr, zcols, zvals, lo, hi)

    if run is None or n_contacts == 0:
        work(0, n_contacts)
    else:
        run(work, n_contacts)
    return ContactRows(zptr, zcols, zvals, rows.n_dofs)


def factored_blocks(rows: ContactRows, strand: np.ndarray, offsets: np.ndarray, chol: np.ndarray,
                    chol_ptr: np.ndarray, run=None) -> np.ndarray:
    """The blocks ``Z_i^T Z_i`` of ``W = H M^-1 H^T``, (C, 3, 3), without the rows ``Z`` themselves.

    The same, bit for bit, as ``delassus_blocks(factored_rows(...), 0)``, each contact's rows computed,
    summed and let go: a dense groom's factored rows are the largest arrays of a step (on a 30,000-strand
    head about 1 GB), and a step whose forces need no sweeps needs only these blocks (``Simulation``).
    Arguments as :func:`factored_rows`.
    """
    out = np.empty((rows.n_contacts, 3, 3))

    def work(lo: int, hi: int) -> None:
        _z_blocks(rows.ptr, rows.cols, rows.vals, strand, offsets, chol, chol_ptr, out, lo, hi)

    if run is None or rows.n_contacts == 0:
        work(0, rows.n_contacts)
    else:
        run(work, rows.n_contacts)
    return out


@jit
def back_substitute(offsets, chol, chol_ptr, z, out, lo, hi):
    """``out = L^-T z`` strand by strand for strands ``lo:hi`` (``z``, ``out`` over all coordinates)."""
    _substitute(offsets, chol, chol_ptr, z, out, lo, hi, True)


def contact_keys(strand: np.ndarray, s: np.ndarray, offsets: np.ndarray, length: np.ndarray) -> np.ndarray:
    """A key per contact that persists from step to step while the contact does, (C,) int64.

    Detection declares at most one body contact per element and one hair-hair
    contact per pair of elements, so the element (pair) names the contact:
    ``e_A`` for a body contact, ``E (1 + e_A) + e_B`` for a hair-hair one.
    """
    n_elements = int(offsets[-1])
    counts = np.diff(offsets)
    strand_of = np.repeat(np.arange(len(counts)), counts)
    cumulative = np.concatenate([[0.0], np.cumsum(length)])
    total = cumulative[offsets[1:]] - cumulative[offsets[:-1]]
    span = np.where(total > 0, total, 1.0) * (1.0 + 1e-9)
    # element starts as (strand + fraction of its length): one sorted array over all strands
    position = strand_of + (cumulative[:-1] - cumulative[offsets[:-1]][strand_of]) / span[strand_of]

    def element(k: np.ndarray, arc: np.ndarray) -> np.ndarray:
        # a point at an element's start belongs to it (detection declares nothing at an element's end):
        # nudged past the round-off of the two sums of lengths, so that it does not fall in the one before
        where = k + np.clip(arc, 0.0, total[k]) / span[k] + 1e-12
        return np.clip(np.searchsorted(position, where, side="right") - 1, offsets[k], offsets[k + 1] - 1)

    keys = element(strand[:, 0], s[:, 0])
    hair = strand[:, 1] >= 0
    if hair.any():
        keys[hair] = n_elements * (1 + keys[hair]) + element(strand[hair, 1], s[hair, 1])
    return keys


def reachable(Wd: np.ndarray, demand: np.ndarray, reach: float = REACH) -> np.ndarray:
    """``demand`` (C, 3) without its parts along directions its contact's point can hardly move.

    ``Wd`` (C, 3, 3) are the blocks ``W_ii``: the velocity of contact ``i``
    under a unit impulse at ``i``. Along an eigenvector of ``W_ii`` with
    eigenvalue ``lambda``, meeting a velocity ``v`` takes the impulse
    ``v / lambda``, which moves the strand's coordinates by about
    ``v / sqrt(lambda)``. A point on a strand's first element, a few
    millimetres from its root, cannot move along the strand (``lambda`` is
    zero there up to round-off): asked to, the solver answers with impulses
    of newton-seconds and the strand's tip with radians per step. So a
    velocity the solver is asked for on top of the free motion (the push out
    of a contact found too close, :class:`~hairinv.dynamics.simulate.Simulation`)
    keeps only its parts along eigenvectors with ``lambda >= reach *
    lambda_max``. The free motion's own part, ``H v``, needs no such care:
    it lies in the range of ``H``.
    """
    out = np.array(demand, dtype=np.float64, copy=True)
    # only blocks that may have a weak direction are decomposed: with m2 the sum of the principal 2x2
    # minors (l1 l2 + l1 l3 + l2 l3 >= l2 l3), lambda_min >= det / m2, and lambda_max <= trace, so
    # lambda_min < reach lambda_max implies det < reach trace m2
    w = Wd.reshape(-1, 9)
    det = (w[:, 0] * (w[:, 4] * w[:, 8] - w[:, 5] * w[:, 7]) - w[:, 1] * (w[:, 3] * w[:, 8] - w[:, 5] * w[:, 6])
           + w[:, 2] * (w[:, 3] * w[:, 7] - w[:, 4] * w[:, 6]))
    m2 = (w[:, 0] * w[:, 4] - w[:, 1] * w[:, 3]) + (w[:, 0] * w[:, 8] - w[:, 2] * w[:, 6]) \
        + (w[:, 4] * w[:, 8] - w[:, 5] * w[:, 7])
    some = np.flatnonzero((det < reach * (w[:, 0] + w[:, 4] + w[:, 8]) * m2) & np.any(out != 0.0, axis=1))
    if len(some):
        lam, V = np.linalg.eigh(Wd[some])
        weak = lam < reach * lam[:, 2:3]
        along = np.einsum("cik,ci->ck", V, out[some]) * weak
        out[some] -= np.einsum("cik,ck->ci", V, along)
    return out


def contact_velocities(rows: ContactRows, gamma: np.ndarray, b: np.ndarray, r: np.ndarray) -> np.ndarray:
    """``u = W r + b`` for ``W = Z^T Z + diag(gamma)`` given the rows ``Z_i^T``, (C, 3)."""
    return rows.matvec(rows.rmatvec(r)) + b + gamma[:, None] * r


def delassus_blocks(rows: ContactRows, gamma: np.ndarray) -> np.ndarray:
    """The blocks ``W_ii`` of ``W = Z^T Z + diag(gamma)``, (C, 3, 3)."""
    Wd = np.empty((rows.n_contacts, 3, 3))
    diagonal_blocks(rows.ptr, rows.cols, rows.vals, np.ones(rows.n_dofs), gamma, Wd)
    return Wd


def coulomb_problem(rows: ContactRows, gamma: np.ndarray, b: np.ndarray, mu: np.ndarray, strand: np.ndarray,
                    n_strands: int, velocity_scale: float, s: np.ndarray | None = None,
                    part_of: np.ndarray | None = None) -> ConeProblem:
    """A step's contact problem on the factored rows ``Z_i^T`` (:func:`factored_rows`, so ``D = I``): impulses,
    their residual measured as a velocity relative to ``velocity_scale`` (m/s)."""
    return ConeProblem.of(rows, np.ones(rows.n_dofs), gamma, b, mu, strand, n_strands, velocity_scale, velocity=True,
                          s=s, part_of=part_of)


def desaxce_residual(rows: ContactRows, gamma: np.ndarray, b: np.ndarray, mu: np.ndarray, r: np.ndarray,
                     Wd: np.ndarray | None = None) -> float:
    """Largest natural-map residual of the De Saxce problem, in velocity units (:func:`natural_residuals`).

    ``Wd``: the diagonal blocks, if already at hand.
    """
    if rows.n_contacts == 0:
        return 0.0
    problem = coulomb_problem(rows, gamma, b, mu, np.zeros((rows.n_contacts, 2), dtype=np.int64), 0, 1.0)
    return gauss_seidel.residual(problem, COULOMB, r, delassus_blocks(rows, gamma) if Wd is None else Wd)


def strand_groups(rows: ContactRows, gamma: np.ndarray, strand: np.ndarray, Wd: np.ndarray | None = None) -> tuple:
    """A strand's body contacts grouped (hair-hair contacts alone) with their dense blocks of ``W``
    (:func:`hairinv.solver.blocks.strand_blocks`).

    ``Wd``: the blocks ``W_ii`` (:func:`delassus_blocks`), if already at hand.
    """
    return (*strand_blocks(rows, gamma, strand), delassus_blocks(rows, gamma) if Wd is None else Wd)


@dataclasses.dataclass(frozen=True)
class CoulombSettings:
    """How long the contact solve of one step (:func:`solve_coulomb`) runs."""

    tolerance: float
    """on the De Saxce residual in velocity units, relative to the problem's ``scale``"""
    max_sweeps: int
    """sweeps over all contacts in all (a round of the fixed point counts its sweeps)"""
    max_rounds: int = 20
    """rounds of the fixed point of convex problems"""
    stall_rounds: int = 3
    """stop once this many rounds in a row (after the first) have not halved the best residual (0: never)"""


def solve_coulomb(problem: ConeProblem, settings: CoulombSettings, start: np.ndarray,
                  Wd: np.ndarray | None = None) -> SolverResult:
    """Coulomb friction of one step: the De Saxce problem ``K ∋ r ⟂ u + mu |u_T| e_N ∈ K*``.

    As a fixed point of convex problems (Acary, Cadoux et al.): with the
    shift ``s_i = mu_i |u_T,i|`` of the last iterate frozen, the problem is the
    convex cone complementarity problem of ``b + s e_N``, which the
    accelerated Gauss-Seidel of the inversion solves monotonically; its
    solution updates ``s``. At a fixed point the De Saxce conditions hold
    exactly. Gauss-Seidel run directly on the De Saxce problem (local solves
    of the non-convex law) drifts away on hair: on the 300-strand straight
    sample its residual grows from 2e-3 to 1e-2 over 1,000 sweeps, where the
    fixed point meets 1e-6 in 5 sweeps. Fail-safe: if the rounds end above
    the tolerance, direct De Saxce sweeps start from the best iterate, and the
    better of the two is kept. Once ``stall_rounds`` rounds in a row (after
    the first) have not halved the best residual, the solve stops there with
    its best iterate and no fail-safe (0: never): on ruby short's moving groom,
    hair-hair contact by contact, with one stalled round 200 sweeps per step
    become about 50, and the strands' median distance after two frames from a
    1,000-sweep reference is 0.08-0.11 mm, where runs from starts 1e-9 apart
    end 0.04-0.08 mm apart; but from the start of the motion the looser solves
    let errors grow into cascades of halved steps, which three stalled rounds
    (the default) do not (docs/dynamics.md).

    Body contacts only (no hair-hair contact): the strands do not interact,
    so the rounds run strand by strand, in the kernel, on each strand's dense
    block (:func:`hairinv.solver.blocks.group_fixed_point`), after Newton on
    the De Saxce problem itself has solved most strands at once; a round
    counts as one sweep, a strand stops after ``FIXED_POINT_PATIENCE`` rounds
    without a new best (with ``stall_rounds`` 0: once the sweeps are spent),
    and the fail-safe runs only where every strand met the tolerance by its
    own count and the whole does not (round-off), or with ``stall_rounds`` 0.

    ``problem`` is :func:`coulomb_problem` of the factored rows ``Z_i^T``
    (:func:`factored_rows`); ``start`` the warm start (C, 3); ``Wd``: the blocks
    ``W_ii`` (:func:`delassus_blocks`, ``gamma`` included), if already at hand.
    Returns the best iterate; ``sweeps`` counts all rounds.
    """
    started = time.perf_counter()
    rows, gamma, b, mu, strand = problem.rows, problem.gamma, problem.b, problem.mu, problem.strand
    velocity_scale, tolerance, max_sweeps = problem.scale, settings.tolerance, settings.max_sweeps
    max_rounds, stall_rounds = settings.max_rounds, settings.stall_rounds
    ones = np.ones(rows.n_dofs)
    target = tolerance * velocity_scale
    # body contacts only: strand by strand on dense blocks (Newton, then each strand's own fixed point);
    # with hair-hair contact, the accelerated contact-by-contact sweeps of the inversion
    blocks = rows.n_contacts > 0 and not np.any(strand[:, 1] >= 0)
    # frictionless everywhere: the De Saxce shift mu |u_T| is zero, so the first round is the problem itself,
    # solved to the final tolerance at once (no rounds of loose tolerances chasing a shift)
    frictionless = not np.any(mu > 0.0)
    stalled = False
    r = np.array(start, dtype=np.float64, copy=True)
    if Wd is None and rows.n_contacts:
        Wd = delassus_blocks(rows, gamma)
    best_r, best = r.copy(), gauss_seidel.residual(problem, COULOMB, r, Wd)
    history = [(0, best)]
    if not np.isfinite(best):  # non-finite data (b, W or the warm start): nothing to solve
        return SolverResult(r, Status.NUMERICAL_ERROR, 0, best, best / velocity_scale, history,
                            time.perf_counter() - started)
    sweeps = 0
    status = Status.CONVERGED if best <= target else Status.MAX_ITERS
    rounds = 0

    def record(point: np.ndarray) -> float:
        """The De Saxce residual of ``point`` after ``sweeps``, kept if it is the best so far."""
        nonlocal best, best_r, status
        residual = gauss_seidel.residual(problem, COULOMB, point, Wd)
        history.append((sweeps, residual))
        if residual < best:
            best, best_r = residual, point.copy()
        if residual <= target:
            status = Status.CONVERGED
        return residual

    if blocks and status == Status.MAX_ITERS and max_sweeps > 0:
        # first each strand's contacts at once by Newton on the De Saxce problem itself (the strands do
        # not interact): it nearly always meets the tolerance; the few strands it leaves (a contact near
        # the root, whose W_ii is 1e-4 of the others', beside contacts along the strand) are solved as a
        # fixed point of convex problems, strand by strand
        groups = strand_groups(rows, gamma, strand, Wd)
        members, group_ptr, block_ptr, blocks_g, _ = groups
        f = np.empty(rows.n_dofs)
        accumulate_f(rows.ptr, rows.cols, rows.vals, ones, r, f)
        n_groups = len(group_ptr) - 1
        done = np.zeros(n_groups, dtype=np.bool_)
        chunk = max(16, -(-n_groups // 8))
        run_chunks(lambda lo, hi: group_newton(rows.ptr, rows.cols, rows.vals, gamma, b, mu, members, group_ptr,
                                                block_ptr, blocks_g, Wd, r, f, target, GROUP_NEWTON_ITERS, True, True,
                                                lo, hi, done), n_groups, chunk)
        sweeps += 1
        if not done.all() and max_sweeps > 1:
            taken = np.zeros(n_groups, dtype=np.int64)
            patience = FIXED_POINT_PATIENCE if stall_rounds else 0  # (0: every round the sweeps allow)
            run_chunks(lambda lo, hi: group_fixed_point(rows.ptr, rows.cols, rows.vals, gamma, b, mu, members,
                                                         group_ptr, block_ptr, blocks_g, Wd, r, f, target,
                                                         FIXED_POINT_NEWTON_ITERS, max_sweeps - 1, patience,
                                                         lo, hi, done, taken), n_groups, chunk)
            rounds = int(taken.max())
            sweeps += rounds
        record(r)
        # the strands that did not meet the tolerance stopped at their best (stalled, with stall_rounds, or
        # out of sweeps): sweeps over all contacts would not do better; where each did by its own count and
        # the whole does not (round-off), the fail-safe polishes
        stalled = bool(stall_rounds) and not done.all()
    # the rounds solve problems of the same rows and contacts: their update order is made once
    order = None
    if not blocks and status == Status.MAX_ITERS and sweeps < max_sweeps:
        order = sweep_order(problem)
    while not blocks and status == Status.MAX_ITERS and sweeps < max_sweeps and rounds < max_rounds:
        u = contact_velocities(rows, gamma, b, r)
        shifted = b.copy()
        shifted[:, 0] += np.where(mu < np.inf, mu, 0.0) * np.hypot(u[:, 1], u[:, 2])  # (inf: no De Saxce term)
        # each round only as exact as the shift it starts from deserves
        inner_tol = tolerance if frictionless else max(tolerance, 0.1 * best / velocity_scale)
        # and, until it is the final tolerance, at most a tenth of the sweeps: with hair-hair contact
        # Gauss-Seidel is slow, and one round spending every sweep on a stale shift left ruby's moving
        # groom at 0.35 g h for good
        budget = max_sweeps - sweeps if inner_tol <= tolerance else min(max(20, max_sweeps // 10),
                                                                        max_sweeps - sweeps)
        inner = gauss_seidel.solve(dataclasses.replace(problem, b=shifted), CONE,
                                   SweepSettings(inner_tol, budget, check_every=5), start=r, order=order)
        if inner.status == Status.NUMERICAL_ERROR:
            return dataclasses.replace(inner, r=best_r, sweeps=sweeps + inner.sweeps)
        sweeps += inner.sweeps
        rounds += 1
        r = inner.r
        if record(r) <= target:
            break  # (converged)
        if inner.sweeps == 0:
            break  # the shift no longer changes the convex solution: the rounds have stalled
        elif stall_rounds and rounds > stall_rounds and \
                min(h for _, h in history[-stall_rounds:]) > 0.5 * min(h for _, h in history[:-stall_rounds]):
            stalled = True  # rounds without halving the residual: keep the best (see the docstring)
            break
    failsafe = 0
    if status != Status.CONVERGED and sweeps < max_sweeps and not stalled:
        direct = gauss_seidel.solve(problem, COULOMB, SweepSettings(tolerance, max_sweeps - sweeps, check_every=5),
                                    start=best_r, order=order)
        sweeps += direct.sweeps
        failsafe = direct.local_failures
        if direct.status != Status.NUMERICAL_ERROR:
            record(direct.r)
    return SolverResult(best_r, status, sweeps, best, best / velocity_scale, history,
                        time.perf_counter() - started, 0, failsafe, rounds)
