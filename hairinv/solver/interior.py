"""A primal-dual interior-point method for the inverse cone QP.

Solves ``min 1/2 r'W r + b'r`` over the Coulomb cones, ``W = G'G + gamma I``
with ``G = D^1/2 H'`` (one row per coordinate of ``q``), the problem
:func:`hairinv.solver.gauss_seidel.solve` solves by sweeps. Where
the sweeps make slow progress on the part of the error spread over whole
strands and clusters of strands, each step here corrects every force at
once, and 30 to 50 steps reach the optimum.

Variables. Each contact's force is scaled to the standard second-order
cone: ``x_i = sqrt(rho_i) (mu_i r_N, r_T1, r_T2)`` with ``rho_i`` the
diagonal scale of ``W_ii`` (so ``x_0 >= |x_1:3|`` is the Coulomb cone and
the diagonal of the scaled ``W`` is about 1). The dual variable ``z`` (the
contacts' velocities in the same scaling) lies in the same, self-dual cone.

Steps (Mehrotra predictor-corrector, Nesterov-Todd scaling, as in
Vandenberghe's "The CVXOPT linear and quadratic cone program solvers").
Each step solves ``(P + S_nt) dx = v`` with ``P`` the scaled ``W`` and
``S_nt`` block diagonal (3x3 a contact). By the Woodbury identity this is
one system in the rod coordinates,

    (I + G B^-1 G') w = G B^-1 v,    B = S_nt + gamma I (per contact),

``n x n`` with ``n`` the number of coordinates of ``q``, sparse as the
contacts couple the elements (a contact at element ``e`` touches elements
``0..e`` of its strands). Its pattern is fixed once and laid out by blocks
of coordinates, into which each contact's product is added in contiguous
runs (:mod:`.blocked`); it is ordered (AMD or METIS's nested dissection, the one
whose factor costs fewer flops) and analysed once, factored by a supernodal
Cholesky on every core (:mod:`.supernodal`; cvxopt's CHOLMOD and scipy's
SuperLU can be asked for), and solved with one step of iterative refinement
against the force-space operator.

``B^-1`` is formed as ``W_nt (I + W_nt Gamma W_nt)^-1 W_nt`` from the
scaling itself: near the optimum ``S_nt`` spans many orders of magnitude
and inverting it first would lose them.

Accuracy. The rest shape is ``q0 = q - (F_g + H'r)/K``; the objective is
``1/2 |q0 - t|^2`` (plus ``gamma/2 |r|^2``) up to a constant, so for any
``r`` in the cones ``|q0(r) - q0*|^2 <= 2 (f(r) - f*)``. With the iterate's
duality gap ``x'z`` and dual residual ``rd = P x + q - z``, ``f(x) - f* <=
x'z + rd'(x - x*)``; the reported rest-shape bound is
``sqrt(2 (x'z + |rd'x|) / elements)``, rms over elements in 1/m, exact
once the dual residual vanishes (it drops by the step length each step;
below 1e-12 of ``|q|`` it is round-off of ``P x`` and its term is dropped).
The benchmark and the tests measure this bound against the distance from
a tight solve.

The forces this returns are the start of the sweeps (``invert``'s
``solver.method = "interior-point"``), which then meet the natural-map
tolerance and decide the status as they do from any start.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse
import scipy.sparse.linalg

from .._jit import jit
from .._parallel import blas_pinned
from .blocked import BlockedSystem, EntriesOver
from .problem import CONE, ConeProblem, InteriorSettings, Law
from .rows import rows_matvec, rows_rmatvec
from .status import Status
from .supernodal import SupernodalCholesky, etree, expanded_flops, permuted_pattern
from .supernodal import column_counts as supernodal_counts

__all__ = ["MAX_GFLOP", "InteriorResult", "cholesky_backend", "column_counts", "mu_in_range", "solve"]

# The cone is scaled by mu: friction coefficients are held within these bounds in the interior-point
# steps only (mu = inf has no interior in this scaling); the sweeps that follow use mu itself. A frictionless
# contact (mu = 0) is solved exactly instead (solve).
_MU_RANGE = (1e-3, 1e3)
_STEP_FRACTION = 0.99
_REFINEMENT = 1
# a dual residual (relative to |q|) below this is taken as round-off in the rest-shape bound
_ROUND_OFF = 1e-12
# steps without a new smallest bound before the method stops at its best iterate
_PATIENCE = 12
# The most one factorisation may cost, in GFlop (sum of the factor's squared column counts). ruby short's
# 25,468 contacts need 19 (0.4 s a step on 2 cores); the 4,867 guides of ruby short and long (85,961 contacts)
# 128, 3.2 s a step, 73 s in all, where the sweeps' 2,000 took 111 s to a bound of 0.26 1/m (docs/inverse.md).
# A groom whose strands all touch each other along their length (a bun) makes the system nearly dense: its
# factorisation would take minutes a step.
MAX_GFLOP = 150.0
# The most entries the system's lower triangle may have (its pattern, values and the factorisation's copy
# of them: about 40 bytes an entry before the factor's own fill). ruby short has 2.9 million; a full head of
# 100,000 strands far more, whose factorisation would be far over MAX_GFLOP anyway.
_MAX_ENTRIES = 100_000_000
_J = np.diag([1.0, -1.0, -1.0])
_SIGN = np.array([1.0, -1.0, -1.0])


def mu_in_range(mu: np.ndarray) -> np.ndarray:
    """Contacts whose friction coefficient the interior-point steps take as it is (frictionless ones too)."""
    mu = np.asarray(mu, dtype=np.float64)
    return (mu == 0.0) | ((mu >= _MU_RANGE[0]) & (mu <= _MU_RANGE[1]))


@dataclass
class InteriorResult:
    """What the interior-point method reached.

    Attributes
    ----------
    r : (C, 3) float64, forces in the cones (the last iterate, which is strictly inside them)
    iterations : int
    status : Status, CONVERGED (the rest-shape bound met), MAX_ITERS, TIME (max_seconds),
        STALLED (a step made no progress or the factorisation broke down: the best iterate) or
        TOO_LARGE (the factorisation would cost more than ``max_gflop``: nothing solved, ``r`` zero)
    rest_bound : float, 1/m, rms over elements, see the module docstring
    relative_gap : float, ``x'z / max(1, |f|)``
    dual_residual : float, ``|rd| / max(1, |q|)`` in the scaled variables
    seconds : float
    history : list of (iteration, seconds, rest_bound)
    backend : str, the sparse Cholesky used
    gflop : float, the cost of one factorisation (sum of the squared column counts of the factor), 1e9
    """

    r: np.ndarray
    iterations: int
    status: Status
    rest_bound: float
    relative_gap: float
    dual_residual: float
    seconds: float
    history: list = field(default_factory=list)
    backend: str = ""
    gflop: float = float("nan")


def cholesky_backend() -> str:
    """The sparse Cholesky factorisation the method uses unless told otherwise: "supernodal"
    (:mod:`.supernodal`, on scipy's BLAS, every core). "cholmod" (cvxopt's CHOLMOD, one core with the
    wheel's BLAS) and "superlu" (scipy's SuperLU, much slower) can be asked for; they also serve when
    compiled kernels are off (``NUMBA_DISABLE_JIT=1``: the supernodal kernels call BLAS from compiled code
    only)."""
    from numba.core import config

    if not config.DISABLE_JIT:
        return "supernodal"
    try:
        import cvxopt.cholmod  # noqa: F401
    except ImportError:  # pragma: no cover - cvxopt is a dependency; the fallback is for trimmed installs
        return "superlu"
    return "cholmod"


def _jdet(x: np.ndarray) -> np.ndarray:
    return x[:, 0] ** 2 - np.sum(x[:, 1:] ** 2, axis=1)


def _jprod(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Jordan product of the second-order cone, row by row."""
    out = np.empty_like(x)
    out[:, 0] = np.sum(x * y, axis=1)
    out[:, 1:] = x[:, :1] * y[:, 1:] + y[:, :1] * x[:, 1:]
    return out


def _jdiv(lam: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``u`` with ``lam o u = v`` (lam in the interior)."""
    u = np.empty_like(v)
    u[:, 0] = (lam[:, 0] * v[:, 0] - np.sum(lam[:, 1:] * v[:, 1:], axis=1)) / _jdet(lam)
    u[:, 1:] = (v[:, 1:] - u[:, :1] * lam[:, 1:]) / lam[:, :1]
    return u


def _max_step(u: np.ndarray, v: np.ndarray) -> float:
    """Largest ``a >= 0`` with ``u + a v`` in every cone (``u`` interior); inf when unbounded."""
    a = _jdet(v)
    b = u[:, 0] * v[:, 0] - np.sum(u[:, 1:] * v[:, 1:], axis=1)
    c = _jdet(u)
    disc = b * b - a * c
    root = np.sqrt(np.maximum(disc, 0.0))
    best = np.inf
    with np.errstate(divide="ignore", invalid="ignore"):
        lin = np.where(b != 0.0, -c / (2.0 * b), np.inf)
        for t in (np.where(a != 0.0, (-b - root) / a, lin), np.where(a != 0.0, (-b + root) / a, lin)):
            ok = (disc >= 0.0) & (t > 0.0) & np.isfinite(t)
            if ok.any():
                best = min(best, float(t[ok].min()))
        down = v[:, 0] < 0.0
        if down.any():
            best = min(best, float((-u[down, 0] / v[down, 0]).min()))
    return best


def _nt_scaling(s: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Nesterov-Todd scaling ``W`` (and its inverse) of each cone: ``W z = W^-1 s``, both symmetric."""
    sn = np.sqrt(_jdet(s))
    zn = np.sqrt(_jdet(z))
    sb = s / sn[:, None]
    zb = z / zn[:, None]
    g = np.sqrt((1.0 + np.sum(sb * zb, axis=1)) / 2.0)
    w = (sb + zb * _SIGN) / (2.0 * g[:, None])
    v = w.copy()
    v[:, 0] += 1.0
    v /= np.sqrt(2.0 * v[:, :1])
    beta = np.sqrt(sn / zn)
    W = beta[:, None, None] * (2.0 * v[:, :, None] * v[:, None, :] - _J)
    Jv = v * _SIGN
    Winv = (1.0 / beta)[:, None, None] * (2.0 * Jv[:, :, None] * Jv[:, None, :] - _J)
    return W, Winv


def _mv(M: np.ndarray, x: np.ndarray) -> np.ndarray:
    return np.einsum("cij,cj->ci", M, x)


def column_counts(n, Up, Ui, limit):
    """Column counts (diagonal included) of the Cholesky factor of the symmetric pattern whose upper
    triangle is (Up, Ui), by columns: the elimination tree, then each row's subtree; an empty array as soon
    as ``sum c_j^2`` must pass ``limit`` (:func:`.supernodal.column_counts`)."""
    return supernodal_counts(n, etree(n, Up, Ui), Up, Ui, float(limit), np.ones(n, np.int64))


def nested_dissection(pattern) -> np.ndarray | None:
    """METIS's nested-dissection ordering of a symmetric pattern (pymetis), or None without pymetis.
    On ruby short's rod-coordinate system it needs about a fifth fewer flops than AMD."""
    try:
        import pymetis
    except ImportError:
        return None
    graph = scipy.sparse.csr_matrix(pattern, copy=True)
    graph.setdiag(0)
    graph.eliminate_zeros()
    graph.sort_indices()
    if graph.nnz == 0:
        return np.arange(pattern.shape[0], dtype=np.int64)
    order, _ = pymetis.nested_dissection(pymetis.CSRAdjacency(graph.indptr.astype(np.int32),
                                                              graph.indices.astype(np.int32)))
    return np.array(order, dtype=np.int64)


def _grouped_flops(gSp: np.ndarray, gSi: np.ndarray, node_order: np.ndarray, sizes: np.ndarray,
                   limit: float) -> float:
    """``sum c_j^2`` over the column counts of the system's Cholesky factor (its flops up to a constant) in
    the coordinates' order that ``node_order`` expands to, or inf once it must pass ``limit``. Counted on a
    pattern of nodes (lower triangle ``gSp``, ``gSi``), node ``k`` standing for ``sizes[k]`` consecutive
    coordinates that must have the same neighbours, each other included (a group some contact touches; a
    coordinate no contact touches is a node of its own), eliminated one after the other, so that the
    factor's structure is the nodes' expanded (:func:`.supernodal.column_counts` with the sizes as weights)."""
    m = len(gSp) - 1
    inv = np.empty(m, np.int64)
    inv[node_order] = np.arange(m)
    Up, Ui, _, _, _ = permuted_pattern(m, gSp, gSi, inv)
    weight = np.ascontiguousarray(sizes[node_order], dtype=np.int64)
    counts = supernodal_counts(m, etree(m, Up, Ui), Up, Ui, min(limit, 1e300), weight)
    if len(counts) == 0:
        return np.inf
    return expanded_flops(counts, weight)


def _groups(incidence, n: int) -> np.ndarray:
    """The first coordinate of each run of consecutive coordinates that the same contacts touch (columns of
    the contacts' incidence, CSC with sorted rows, that are equal), and ``n`` last."""
    incidence.sort_indices()
    return _group_starts(incidence.indptr.astype(np.int64), incidence.indices.astype(np.int64), n)


@jit
def _group_starts(ptr, idx, n):
    starts = np.empty(n + 1, np.int64)
    g = 0
    for j in range(n):
        same = j > 0 and ptr[j + 1] - ptr[j] == ptr[j] - ptr[j - 1]
        if same:
            a, b = ptr[j - 1], ptr[j]
            for k in range(ptr[j + 1] - ptr[j]):
                if idx[a + k] != idx[b + k]:
                    same = False
                    break
        if not same:
            starts[g] = j
            g += 1
    starts[g] = n
    return starts[:g + 1].copy()


def _expand(group_order: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """A permutation of the groups as one of the coordinates, each group's in increasing order."""
    sizes = np.diff(starts)[group_order]
    first = np.repeat(starts[group_order], sizes)
    offset = np.arange(len(first)) - np.repeat(np.cumsum(sizes) - sizes, sizes)
    return (first + offset).astype(np.int64)


class TooLarge(Exception):
    """The rod-coordinate system's factorisation would cost more than the method allows."""


class _Factor:
    """The rod-coordinate system ``I + G B^-1 G'``: its pattern, analysis and numeric factor."""

    def __init__(self, ptr, cols, n: int, backend: str, max_flops: float = np.inf):
        self.backend = backend
        C = len(ptr) - 1
        counts = np.diff(ptr)
        limit = float(max_flops) if np.isfinite(max_flops) else 1e300
        # the factor holds the system's entries, so under any ordering sum c^2 >= (sum c)^2 / n >= entries^2 / n:
        # a system with more entries than sqrt(limit n) is declined as soon as they are counted
        try:
            self.system = BlockedSystem(ptr, cols, n, min(_MAX_ENTRIES, np.sqrt(limit * max(n, 1))))
        except EntriesOver as over:
            raise TooLarge(f"{over.args[0]} entries in the system's lower triangle") from None
        self.Sp, self.Si = self.system.Sp, self.system.Si
        self.Sx = np.zeros(len(self.Si))
        self.n = n
        incidence = scipy.sparse.csr_matrix((np.ones(len(cols)), (np.repeat(np.arange(C), counts), cols)),
                                            shape=(C, n))
        # the fill-reducing orderings at hand, each counted before any factorisation; the cheapest kept. They
        # order the coordinates' groups with the same contacts (an element's three, often a few elements:
        # ruby short's 38,391 coordinates are 11,403 groups), each group's coordinates kept together: on
        # ruby short the same fill (18.9 GFlop under METIS either way), for a sixth of the ordering's time.
        by_coordinate = incidence.tocsc()
        starts = _groups(by_coordinate, n)
        members = scipy.sparse.csr_matrix(by_coordinate[:, starts[:-1]])
        grouped = (members.T @ members + scipy.sparse.eye(len(starts) - 1, format="csr")).tocsc()
        # counted on the groups too, but a group no contact touches is not a clique (its coordinates are not
        # neighbours of each other): those are counted coordinate by coordinate
        touched = np.diff(by_coordinate.indptr)[starts[:-1]] > 0
        nodes = np.where(touched, 1, np.diff(starts))
        sizes = np.ones(int(np.sum(nodes)), np.int64)  # each node's coordinates
        sizes[np.cumsum(nodes)[touched] - 1] = np.diff(starts)[touched]
        node_starts = np.r_[0, np.cumsum(nodes)].astype(np.int64)
        # (the groups' pattern with each group renumbered as its first node; the split ones' nodes are alone)
        m = int(node_starts[-1])
        lower = scipy.sparse.tril(grouped, format="coo")
        counted = scipy.sparse.csc_matrix((np.ones(lower.nnz + m), (np.r_[node_starts[lower.row], np.arange(m)],
                                                                     np.r_[node_starts[lower.col], np.arange(m)])),
                                          shape=(m, m))
        counted.sort_indices()
        cSp, cSi = counted.indptr.astype(np.int64), counted.indices.astype(np.int64)
        self.order, self.flops, self.ordering = None, np.inf, ""
        self.candidates = {}
        for name, group_order in self._orderings(grouped, backend):
            order = _expand(group_order, starts)
            flops = _grouped_flops(cSp, cSi, _expand(group_order, node_starts), sizes, min(limit, self.flops))
            self.candidates[name] = (order, flops)
            if flops < self.flops:
                self.order, self.flops, self.ordering = order, flops, name
        if self.order is None or self.flops > limit:
            raise TooLarge(f"over {max_flops / 1e9:.3g} GFlop")
        if backend == "cholmod":
            import cvxopt
            import cvxopt.cholmod

            self._cvxopt = cvxopt
            self._cholmod = cvxopt.cholmod
            cvxopt.cholmod.options["supernodal"] = 2
            columns = np.repeat(np.arange(n), np.diff(self.Sp))
            self.A = cvxopt.spmatrix(np.ones(len(self.Si)), cvxopt.matrix(self.Si), cvxopt.matrix(columns), (n, n))
            self.F = cvxopt.cholmod.symbolic(self.A, p=cvxopt.matrix(self.order))
        elif backend == "supernodal":
            self.supernodal = SupernodalCholesky(self.Sp, self.Si, self.order)

    @staticmethod
    def _orderings(pattern, backend: str):
        """Fill-reducing orderings of the pattern, as (name, permutation): for the Cholesky factorisations,
        AMD (cvxopt's, where installed) and METIS's nested dissection (pymetis, where installed), else
        reverse Cuthill-McKee; for SuperLU, reverse Cuthill-McKee."""
        n = pattern.shape[0]
        found = False
        if backend != "superlu":
            try:
                import cvxopt
                import cvxopt.amd
            except ImportError:
                pass
            else:
                lower = scipy.sparse.tril(pattern, format="coo")
                A = cvxopt.spmatrix(np.ones(lower.nnz), cvxopt.matrix(lower.row.astype(np.int64)),
                                    cvxopt.matrix(lower.col.astype(np.int64)), (n, n))
                found = True
                yield "amd", np.asarray(cvxopt.amd.order(A), dtype=np.int64).ravel()
            dissection = nested_dissection(pattern)
            if dissection is not None:
                found = True
                yield "metis", dissection
        if not found:
            from scipy.sparse.csgraph import reverse_cuthill_mckee

            yield "rcm", np.asarray(reverse_cuthill_mckee(pattern.tocsr(), symmetric_mode=True), dtype=np.int64)

    def factor(self, g, Binv) -> None:
        self.system.assemble(g, Binv, self.Sx)
        if self.backend == "supernodal":
            sn = self.supernodal
            try:
                sn.factor(self.Sx)
            except ArithmeticError:
                # round-off made a pivot non-positive (the system is I + a positive semidefinite matrix, so
                # mathematically never): a relative shift of the diagonal, corrected by the refinement
                sn.values[sn.Lp[:-1]] *= 1.0 + 1e-10
                sn.factor_values()
            return
        if self.backend == "cholmod":
            self.A.V = self._cvxopt.matrix(self.Sx)
            try:
                self._cholmod.numeric(self.A, self.F)
            except ArithmeticError:  # as above
                self.Sx[self.Sp[:-1]] *= 1.0 + 1e-10
                self.A.V = self._cvxopt.matrix(self.Sx)
                self._cholmod.numeric(self.A, self.F)
        else:
            lower = scipy.sparse.csc_matrix((self.Sx, self.Si, self.Sp), shape=(self.n, self.n))
            full = (lower + lower.T - scipy.sparse.diags(lower.diagonal())).tocsc()
            self.lu = scipy.sparse.linalg.splu(full, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                                               options={"SymmetricMode": True})

    def solve(self, w: np.ndarray) -> np.ndarray:
        if self.backend == "cholmod":
            b = self._cvxopt.matrix(w)
            self._cholmod.solve(self.F, b)
            return np.asarray(b).ravel()
        if self.backend == "supernodal":
            return self.supernodal.solve(w)
        return self.lu.solve(w)


def solve(problem: ConeProblem, law: Law = CONE, settings: InteriorSettings = InteriorSettings(),
          start: np.ndarray | None = None, progress=None) -> InteriorResult:
    """Minimise ``1/2 r'W r + b'r`` over the cones, ``W = H diag(d) H' + diag(gamma)``, by interior point.

    Parameters
    ----------
    problem : ConeProblem (its strands' layout and scale are not used: the steps treat every contact at once,
        and stop on the rest-shape bound, in 1/m)
    law : Law, :data:`hairinv.solver.problem.CONE` only (the De Saxce problem is not convex)
    settings : InteriorSettings, the rest-shape tolerance, the steps and time allowed, the factorisation
    start : None: the method starts from the centre of the cones (it takes no warm start)
    progress : callable(iteration, rest_bound), optional

    Friction coefficients 0 and inf are allowed (see ``_MU_RANGE``). Above ``settings.max_gflop`` (counted first,
    from the ordering's elimination tree; default ``MAX_GFLOP``) nothing is solved, the status is TOO_LARGE and
    ``gflop`` is that cap.
    """
    if law.desaxce:
        raise ValueError("the interior-point method solves the convex cone problem only, not De Saxce's")
    if start is not None:
        raise ValueError("the interior-point method takes no warm start: it starts from the centre of the cones")
    rows, d, gamma, b, mu = problem.rows, problem.d, problem.gamma, problem.b, problem.mu
    rest_tolerance, max_iterations, max_seconds = settings.rest_tolerance, settings.max_iterations, settings.max_seconds
    backend, max_gflop = settings.backend, settings.max_gflop
    started = time.perf_counter()
    C = rows.n_contacts
    n = rows.n_dofs
    backend = backend or cholesky_backend()
    if C == 0:
        return InteriorResult(np.zeros((0, 3)), 0, Status.CONVERGED, 0.0, 0.0, 0.0, 0.0, [], backend, 0.0)
    d = np.asarray(d, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64).reshape(C, 3)
    gamma = np.broadcast_to(np.asarray(gamma, dtype=np.float64), (C,))
    mu = np.asarray(mu, dtype=np.float64)
    # a frictionless contact (r_T = 0) is a contact of any cone whose tangential rows of H and b are zero:
    # its tangential force then costs gamma |r_T|^2 / 2 and buys nothing, so it is 0 at the optimum, and the
    # normal forces solve the frictionless problem; the cone taken is mu = 1 and r_T is set to 0 at the end
    frictionless = mu == 0.0
    m = np.clip(np.where(frictionless, 1.0, mu), *_MU_RANGE)
    sqd = np.sqrt(d)
    ptr, cols = rows.ptr, rows.cols
    contact_of = np.repeat(np.arange(C), np.diff(ptr))
    vals = rows.vals
    if frictionless.any():
        vals = vals.copy()
        vals[frictionless[contact_of], 1:] = 0.0
        b = b.copy()
        b[frictionless, 1:] = 0.0
    # G~ = D^1/2 H' with each contact's columns scaled to the standard cone
    rho = np.zeros(C)
    np.add.at(rho, contact_of, np.sum(vals ** 2, axis=1) * d[cols])
    rho = rho / 3.0 + gamma
    rho = np.where(rho > 0.0, rho, 1.0)
    scale = np.stack([1.0 / m, np.ones(C), np.ones(C)], axis=1) / np.sqrt(rho)[:, None]  # r = scale * x
    g = np.ascontiguousarray(vals * sqd[cols][:, None] * scale[contact_of])
    q = b * scale
    gam = gamma[:, None] * scale ** 2
    max_gflop = MAX_GFLOP if max_gflop is None else float(max_gflop)
    try:
        factor = _Factor(ptr, cols, n, backend, max_gflop * 1e9)
    except TooLarge:
        return InteriorResult(np.zeros((C, 3)), 0, Status.TOO_LARGE, np.nan, np.nan, np.nan,
                              time.perf_counter() - started, [], backend, max_gflop)
    problem = _Scaled(ptr, cols, g, gam, q, n, factor)
    start = max(1.0, float(np.sqrt(np.mean(q ** 2))))
    x = np.zeros((C, 3))
    x[:, 0] = start
    history = []
    # numpy's BLAS on one thread: its idle threads would spin, taking the cores from the factorisation's
    with np.errstate(all="ignore"), blas_pinned():
        status, it, best = _iterate(problem, x, x.copy(), rest_tolerance, max_iterations, max_seconds, started,
                                    history, progress)
    bound, xb, relgap, dres, _ = best
    r = xb * scale
    r[frictionless, 1:] = 0.0  # lowers the objective by gamma |r_T|^2 / 2: the bound still holds
    return InteriorResult(r, it, status, bound, relgap, dres, time.perf_counter() - started, history,
                          backend, factor.flops / 1e9)


class _Scaled:
    """The problem in the scaled variables: ``min 1/2 x'P x + q'x`` over the standard cones,
    ``P = G'G + diag(gam)`` with ``G`` stored per contact (``ptr``, ``cols``, ``g``: (nnz, 3))."""

    def __init__(self, ptr, cols, g, gam, q, n: int, factor: _Factor):
        self.ptr, self.cols, self.g, self.gam, self.q = ptr, cols, g, gam, q
        self.n = n
        self.C = len(q)
        self.elements = max(n // 3, 1)
        self.factor = factor
        self._y = np.empty(n)
        self._Px = np.empty((self.C, 3))
        self._back = np.empty((self.C, 3))

    def _G(self, x: np.ndarray) -> np.ndarray:
        """``G x`` (n,) for scaled forces ``x`` (C, 3): the rows' transposed product (:mod:`.rows`)."""
        self._y[:] = 0.0
        rows_rmatvec(self.ptr, self.cols, self.g, x, self._y)
        return self._y

    def _Gt(self, y: np.ndarray, out: np.ndarray) -> np.ndarray:
        """``G' y`` (C, 3) into ``out``."""
        rows_matvec(self.ptr, self.cols, self.g, y, out)
        return out

    def P(self, x: np.ndarray) -> np.ndarray:
        return self._Gt(self._G(x), self._Px) + self.gam * x

    def factor_step(self, Binv: np.ndarray) -> None:
        self.factor.factor(self.g, Binv)

    def newton(self, Binv: np.ndarray, D: np.ndarray, v: np.ndarray, refine: int = _REFINEMENT) -> np.ndarray:
        """``(P + D) dx = v`` (``D`` the cones' scaling, ``Binv = (D + diag(gam))^-1``) by Woodbury through
        the factored rod-coordinate system, then ``refine`` rounds of refinement against the operator itself."""
        def once(v):
            t = _mv(Binv, v)
            return t - _mv(Binv, self._Gt(self.factor.solve(self._G(t)), self._back))

        dx = once(v)
        for _ in range(refine):
            dx = dx + once(v - (self.P(dx) + _mv(D, dx)))
        return dx


def _iterate(problem: _Scaled, x, z, rest_tolerance, max_iterations, max_seconds, started, history, progress):
    """The predictor-corrector steps from ``(x, z)``; returns (status, steps, (bound, x, relgap, dres, step) of
    the best iterate)."""
    C, q, gam = problem.C, problem.q, problem.gam
    e = np.zeros((C, 3))
    e[:, 0] = 1.0
    status = Status.MAX_ITERS
    best = (np.inf, x, 0.0, np.inf, 0)
    it = 0
    for it in range(max_iterations + 1):
        P = problem.P(x)
        rd = P + q - z
        gap = float(np.sum(x * z))
        f = 0.5 * float(np.sum(x * P)) + float(np.sum(q * x))
        relgap = gap / max(1.0, abs(f))
        dres = float(np.linalg.norm(rd)) / max(1.0, float(np.linalg.norm(q)))
        # the dual residual's term, until that residual is round-off of the product P x (forces the rest
        # shape does not feel, fixed by gamma alone, may grow large enough to make that round-off dominate)
        slack = abs(float(np.sum(rd * x))) if dres > _ROUND_OFF else 0.0
        bound = float(np.sqrt(2.0 * max(gap + slack, 0.0) / problem.elements))
        if not np.isfinite(bound):
            status = Status.STALLED
            break
        history.append((it, time.perf_counter() - started, bound))
        if bound < best[0]:
            best = (bound, x.copy(), relgap, dres, it)
        if progress is not None:
            progress(it, bound)
        if bound <= rest_tolerance:
            status = Status.CONVERGED
            break
        if it == max_iterations:
            break
        if it - best[4] >= _PATIENCE:
            # no new best for that many steps: the steps wander along forces the rest shape barely feels
            # (fixed by gamma alone, below round-off of the Newton systems); keep the best iterate
            status = Status.STALLED
            break
        if not (np.all(_jdet(x) > 0.0) and np.all(_jdet(z) > 0.0) and np.all(x[:, 0] > 0.0) and np.all(z[:, 0] > 0.0)):
            status = Status.STALLED  # round-off put an iterate on a cone's boundary: no scaling exists there
            break
        if max_seconds and time.perf_counter() - started > max_seconds:
            status = Status.TIME
            break
        Wm, Wi = _nt_scaling(x, z)
        lam = _mv(Wm, z)
        D = Wi @ Wi  # (batched 3x3 products: matmul is several times faster than einsum here)
        # (D + diag(gam))^-1 from the scaling itself: W (I + W diag(gam) W)^-1 W
        inner = np.eye(3) + (Wm * gam[:, None, :]) @ Wm
        Binv = Wm @ np.linalg.inv(inner) @ Wm
        Binv = 0.5 * (Binv + Binv.transpose(0, 2, 1))
        try:
            problem.factor_step(Binv)
        except (ArithmeticError, RuntimeError):
            status = Status.STALLED
            break

        def direction(t: np.ndarray, refine: int = _REFINEMENT):
            Wt = _mv(Wi, t)
            dx = problem.newton(Binv, D, Wt - rd, refine)
            return dx, Wt - _mv(D, dx)

        # the predictor only sets the step's centring and the corrector's second-order term: unrefined
        dxa, dza = direction(-lam, 0)
        aa = min(1.0, _max_step(x, dxa), _max_step(z, dza))
        sigma = min(1.0, max(0.0, float(np.sum((x + aa * dxa) * (z + aa * dza))) / gap)) ** 3
        rc = -_jprod(lam, lam) - _jprod(_mv(Wi, dxa), _mv(Wm, dza)) + sigma * (gap / C) * e
        dx, dz = direction(_jdiv(lam, rc))
        a = min(1.0, _STEP_FRACTION * min(_max_step(x, dx), _max_step(z, dz)))
        if not (a > 0.0) or not np.all(np.isfinite(dx)) or not np.all(np.isfinite(dz)):
            status = Status.STALLED
            break
        x = x + a * dx
        z = z + a * dz
    return status, it, best
