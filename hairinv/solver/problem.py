"""What a contact solve is asked: the problem, the law of its contacts, and each method's settings.

Every method solves ``K_mu ∋ r_i ⟂ u_i ∈ K*_mu`` for each contact ``i``, with

    W = H diag(d) H^T + diag(gamma),     u = W r + b,

``H`` the contact rows (3 per contact), ``d`` a positive diagonal operator on the strands'
coordinates (``K^-2`` for the inversion, the identity on the factored rows of a time step), ``gamma``
a regularisation per contact and ``mu`` the friction coefficients. The law says which ``u`` enters
the cones (:data:`CONE`: ``u`` itself, the convex problem of the inversion; :data:`COULOMB`: De
Saxce's ``u + mu |u_T| e_N``, the dynamic Coulomb law). The methods, each with one entry point
``solve(problem, law, settings, start)``:

- :func:`hairinv.solver.gauss_seidel.solve`, block Gauss-Seidel over the contacts (both laws);
- :func:`hairinv.solver.interior.solve`, a primal-dual interior point (:data:`CONE` only: the De
  Saxce problem is not convex).

The kernels inside keep flat signatures of plain arrays; these values are what a caller builds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .rows import ContactRows

__all__ = ["CONE", "COULOMB", "ConeProblem", "InteriorSettings", "Law", "SweepSettings"]


@dataclass(frozen=True)
class Law:
    """The law of one contact: which velocity the complementarity pairs with the force.

    The sweeps hand ``desaxce`` to the local solve of each contact (:func:`hairinv.solver.local.solve_contact`,
    So-bogus's ``SOCLaw``/``Coulomb3D`` in one kernel) and to the natural-map residual that stops them.
    """

    name: str
    desaxce: bool
    """De Saxce's change of variable ``u~ = u + mu |u_T| e_N``: the dynamic Coulomb law, not convex"""

    @property
    def convex(self) -> bool:
        """Whether the problem is the optimality condition of ``min 1/2 r'Wr + b'r`` over the cones (it has
        an objective, so a duality gap and momentum guarded by it)."""
        return not self.desaxce


#: the static cone complementarity problem: the optimality conditions of the inversion's convex QP (paper, eq. 11)
CONE = Law("cone", desaxce=False)
#: Coulomb's law with De Saxce's change of variable, for the impulses of a time step (not convex)
COULOMB = Law("coulomb", desaxce=True)


@dataclass(frozen=True)
class ConeProblem:
    """One cone complementarity problem (module docstring), the strands' layout beside it.

    Build it with :meth:`of`, which converts and checks the arrays once.
    """

    rows: ContactRows
    """``H`` (3C x n)"""
    d: np.ndarray
    """(n,) float64, positive, the diagonal operator ``D``"""
    gamma: np.ndarray
    """(C,) float64, the regularisation added to ``W``'s diagonal, one per contact"""
    b: np.ndarray
    """(C, 3) float64"""
    mu: np.ndarray
    """(C,) float64, friction coefficients (0 and inf allowed)"""
    strand: np.ndarray
    """(C, 2) int64, the strands each contact touches (-1: none); contacts sharing no strand are swept at once"""
    n_strands: int
    scale: float
    """the residual's scale: tolerances are relative to it (N for forces; m/s with ``velocity``)"""
    velocity: bool = False
    """``r`` are impulses and the residual is measured as a velocity (``rho_i`` times the force residual,
    ``rho_i = trace W_ii / 3``): in a time step, a contact with a large ``W_ii`` turns a small impulse error
    into a large velocity one"""
    s: np.ndarray | None = None
    """(C, 2) float64, optional, the contacts' arc lengths: the sweeps then run from the tips to the roots"""
    part_of: np.ndarray | None = None
    """(S,) int64, optional, two halves of the strands (:func:`hairinv.solver.gauss_seidel.split_strands`)
    swept at the same time"""

    @classmethod
    def of(cls, rows: ContactRows, d, gamma, b, mu, strand, n_strands: int, scale: float, *, velocity: bool = False,
           s=None, part_of=None) -> "ConeProblem":
        """The problem with its arrays as the kernels take them (contiguous float64 and int64; a scalar
        ``gamma`` given to every contact), their shapes checked against ``rows``."""
        C = rows.n_contacts
        d = np.ascontiguousarray(d, dtype=np.float64)
        gamma = np.ascontiguousarray(np.broadcast_to(np.asarray(gamma, dtype=np.float64), (C,)))
        b = np.ascontiguousarray(b, dtype=np.float64)
        mu = np.ascontiguousarray(mu, dtype=np.float64)
        strand = np.ascontiguousarray(strand, dtype=np.int64)
        if d.shape != (rows.n_dofs,):
            raise ValueError(f"d must have one entry per coordinate ({rows.n_dofs}), got shape {d.shape}")
        if b.shape != (C, 3) or mu.shape != (C,) or strand.shape != (C, 2):
            raise ValueError(f"b, mu and strand must be (C, 3), (C,) and (C, 2) for C = {C} contacts, got "
                             f"{b.shape}, {mu.shape} and {strand.shape}")
        if s is not None:
            s = np.ascontiguousarray(s, dtype=np.float64)
        if part_of is not None:
            part_of = np.ascontiguousarray(part_of, dtype=np.int64)
        return cls(rows, d, gamma, b, mu, strand, int(n_strands), float(scale), bool(velocity), s, part_of)

    @property
    def n_contacts(self) -> int:
        return self.rows.n_contacts

    @property
    def elements(self) -> int:
        """The elements the rows act on (a third of ``H``'s columns): the rest-shape bound is rms over them."""
        return self.rows.n_dofs // 3


@dataclass(frozen=True)
class SweepSettings:
    """How long the sweeps (:func:`hairinv.solver.gauss_seidel.solve`) run and when they stop."""

    tolerance: float = 1e-6
    """stop when the largest natural-map residual is below ``tolerance * problem.scale``"""
    max_sweeps: int = 2000
    check_every: int = 5
    """sweeps between two residual checks (each costs one product with ``W``)"""
    accelerate: bool = True
    """Nesterov momentum over sweeps with an adaptive restart (O'Donoghue and Candes 2015): each sweep
    starts from ``P_K(x_k + beta_k (x_k - x_{k-1}))`` and the momentum is dropped whenever a sweep raises
    the objective, so the iterates' objective never increases. Each sweep then costs about twice as much
    (``f`` is rebuilt for the extrapolated point) and far fewer are needed on real grooms
    (docs/benchmarks.md). Convex laws only: the De Saxce problem has no objective to guard it."""
    max_seconds: float = 0.0
    """s, stop (MAX_ITERS) once this much time has passed, checked with the residual; 0: no limit"""
    rest_tolerance: float = 0.0
    """1/m, stop too when the rest-shape bound ``sqrt(2 gap / elements)``
    (:func:`hairinv.solver.gauss_seidel.rest_gap`) is below it; 0: the residual alone (the bound is then
    measured once, at the forces returned, or at every check with ``progress``; never for a law that is not
    convex, which has no objective)"""

    @classmethod
    def of(cls, settings) -> "SweepSettings":
        """The sweeps' part of the inversion's settings (:class:`hairinv.config.SolverSettings`)."""
        return cls(float(settings.tolerance), int(settings.max_sweeps), int(settings.check_every),
                   bool(settings.accelerate), float(settings.max_seconds), float(settings.rest_tolerance))


@dataclass(frozen=True)
class InteriorSettings:
    """How long the interior point (:func:`hairinv.solver.interior.solve`) runs and what it may cost."""

    rest_tolerance: float = 1e-3
    """1/m, stop once the rest-shape bound (:mod:`hairinv.solver.interior`) is below it"""
    max_iterations: int = 80
    max_seconds: float = 0.0
    """s, stop at the next step after this much time (TIME); 0: no limit"""
    backend: str | None = None
    """"supernodal", "cholmod" or "superlu"; None: :func:`hairinv.solver.interior.cholesky_backend`"""
    max_gflop: float | None = None
    """the most a factorisation may cost, counted first from the ordering's elimination tree; above it
    nothing is solved (TOO_LARGE). None: :data:`hairinv.solver.interior.MAX_GFLOP`"""

    @classmethod
    def of(cls, settings, max_gflop: float | None = None) -> "InteriorSettings":
        """The interior point's part of the inversion's settings (:class:`hairinv.config.SolverSettings`)."""
        return cls(float(settings.rest_tolerance), int(settings.max_iterations), float(settings.max_seconds),
                   None, max_gflop)
