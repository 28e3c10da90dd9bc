"""How the inversion's SOCQP is solved: the method, and the forces it starts from.

``solver.method``: the interior-point method (:func:`hairinv.solver.interior.solve`), which
reaches the optimum, on a groom whose factorisation costs at most :data:`AUTO_GFLOP` a step under
``auto``; elsewhere, or with ``sweeps``, block Gauss-Seidel over the contacts
(:func:`hairinv.solver.gauss_seidel.solve`), from the given forces (:func:`warm_start`) or, where
no contact couples two strands, from each strand's contacts solved together by Newton
(:func:`_strands_at_once`). :class:`ContactSolve` makes that choice once per inversion and solves again
at each stiffness stabilisation asks for.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np

from .. import stages
from .._parallel import run_chunks
from ..config import SolverSettings
from ..errors import InputError, RunError
from ..model import Contacts, Material, material_from_group, stiffening_from_group
from ..solver import gauss_seidel, interior
from ..solver.blocks import group_newton, strand_blocks
from ..solver.gauss_seidel import SolverResult, diagonal_blocks, project_forces
from ..solver.interior import mu_in_range
from ..solver.problem import CONE, ConeProblem, InteriorSettings, SweepSettings
from ..solver.rows import ContactRows
from ..solver.status import Status
from .problem import InverseProblem

__all__ = ["AUTO_GFLOP", "METHODS", "ContactSolve", "Solved", "starting_forces", "warm_start"]

METHODS = ("auto", "sweeps", "interior-point")
#: GFlop a step up to which ``solver.method = auto`` takes the interior-point method: ruby short whole (1,867
#: strands, 25,468 contacts) needs 19, 0.4 s a factorisation on 2 cores. Measured on heads of 3,000 to 4,867
#: ruby guides (23 to 128 GFlop) it converged in 17 to 73 s where the sweeps' 2,000 took 47 to 111 s and stopped
#: 0.19 to 0.28 1/m from the optimum (docs/inverse.md); above it the sweeps solve the groom
AUTO_GFLOP = 150.0
#: Newton iterations of a strand's contacts solved together (:func:`_strands_at_once`)
STRAND_NEWTON_ITERS = 50


class Solved(NamedTuple):
    """One solve of the SOCQP."""

    result: SolverResult
    carrying: np.ndarray
    """(C,) bool: the contacts whose normal force is over the solver's tolerance"""
    gammas: np.ndarray
    """(C,) float64: each contact's weight in the objective at this stiffness"""


def starting_forces(start: np.ndarray | None, problem: InverseProblem, settings: SolverSettings) -> np.ndarray | None:
    """The forces the sweeps start from: ``start`` (C, 3), N, projected onto the problem's cones, or None.

    A start for no contacts has nothing to start; the interior-point method takes none (with auto, the
    sweeps take it if the interior-point method declines the groom)."""
    n = problem.contacts.n_contacts
    if start is None or not n or settings.method == "interior-point":
        return None
    start = np.asarray(start, dtype=np.float64)
    if start.shape != (n, 3) or not np.all(np.isfinite(start)):
        raise InputError(f"the starting forces must be finite, one row of 3 per contact ({n}), got shape "
                         f"{start.shape}")
    return project_forces(start, problem.mu)


class ContactSolve:
    """The contact solve of one inversion, from the forces ``start`` (from :func:`starting_forces`):
    :meth:`first`, then :meth:`again` at each stiffness the stabilisation asks for.

    Keeps what the user is told of it (:meth:`notes`): a groom the interior-point method declined (it
    is then not tried again), a start the interior-point method did not take, the sweeps' start."""

    def __init__(self, problem: InverseProblem, settings: SolverSettings, progress=None,
                 start: np.ndarray | None = None):
        self.problem, self.settings, self.progress, self.start = problem, settings, progress, start
        #: the sweeps started from ``start``: False where there was none or the interior-point method took
        #: the groom afresh (``afresh``)
        self.warm = start is not None
        self.afresh = False
        #: the sweeps started from each strand's contacts solved together (:func:`_strands_at_once`)
        self.newton_start = False
        self.first_residual = np.nan
        self._declined: list[str] = []

    def first(self, stiff: np.ndarray) -> Solved:
        """The solve at the stiffness ``stiff`` (3E,) from the start."""
        solved = self._solve(stiff, self.start, True)
        result = solved.result
        self.afresh = self.warm and result.method == "interior-point"  # auto took the interior point
        self.warm = self.warm and not self.afresh
        self.first_residual = result.history[0][1] if result.history else np.nan
        return solved

    def again(self, stiff: np.ndarray, r: np.ndarray) -> Solved:
        """The solve at the stiffness ``stiff`` (3E,) from the forces ``r`` (C, 3) of an earlier one."""
        return self._solve(stiff, r, False)

    def _solve(self, stiff: np.ndarray, r0: np.ndarray | None, first: bool) -> Solved:
        problem, settings, contacts = self.problem, self.settings, self.problem.contacts
        cone = problem.cone(stiff)
        stepped = self._interior(cone)
        if stepped is None and first and r0 is None and contacts.n_contacts \
                and not np.any(contacts.strand[:, 1] >= 0):
            solved = dataclasses.replace(contacts, mu=problem.mu)
            r0 = _strands_at_once(problem.rows, cone.d, cone.gamma, cone.b, solved,
                                  settings.tolerance * problem.force_scale)
            self.newton_start = r0 is not None
        sweeps_cap = settings.max_sweeps
        # friction coefficients outside the steps' range (0 < mu < 1e-3, mu > 1e3, inf) were held within it
        # there: the sweeps then solve the problem as declared, from those forces; otherwise (mu = 0
        # included, solved exactly by the steps) the forces are final and the
        # call below only measures their residual (and projects them onto the cones, a round-off move)
        if stepped is not None and np.all(mu_in_range(problem.mu)):
            sweeps_cap = 0
        sweep_settings = dataclasses.replace(SweepSettings.of(settings), max_sweeps=sweeps_cap)
        result = gauss_seidel.solve(cone, CONE, sweep_settings, start=r0 if stepped is None else stepped.r,
                                    progress=self.progress if stepped is None else None)
        if stepped is not None:
            result.method = "interior-point"
            result.interior_steps = stepped.iterations
            result.seconds += stepped.seconds
            if sweeps_cap == 0:
                # the interior point's statuses as the inversion reports them: its bound met, or not
                result.rest_bound = stepped.rest_bound
                result.bound_from = "interior-point"
                result.status = Status.CONVERGED if stepped.status == Status.CONVERGED else Status.MAX_ITERS
        if result.status != Status.CONVERGED and not np.all(np.isfinite(result.r)):
            raise RunError(f"the contact solver failed ({result.status}) after {result.sweeps} sweeps, "
                           f"residual {result.residual:.3g} N")
        tolerance = settings.tolerance * problem.force_scale
        carrying = result.r[:, 0] > tolerance if len(result.r) else np.zeros(0, bool)
        return Solved(result, carrying, cone.gamma)

    def _interior(self, cone: ConeProblem):
        """The interior-point solve, or None where the method is the sweeps or the groom too costly for it."""
        settings = self.settings
        if settings.method == "sweeps" or not self.problem.contacts.n_contacts or self._declined:
            return None
        found = interior.solve(cone, CONE, InteriorSettings.of(
            settings, max_gflop=None if settings.method == "interior-point" else AUTO_GFLOP),
            progress=_interior_progress(self.progress, settings.max_iterations))
        if found.status != Status.TOO_LARGE:
            return found
        cap = found.gflop
        if settings.method == "interior-point":
            self._declined.append(
                f"the interior-point method's factorisation would cost over {cap:g} GFlop a step on this "
                "groom (very large, or strands touching along much of their length): solved by the "
                "sweeps instead (docs/inverse.md)")
        else:
            self._declined.append(
                f"solver.method = auto: the sweeps solved this groom, whose interior-point factorisation "
                f"would cost over {cap:g} GFlop a step (solver.method = interior-point takes up to "
                f"{interior.MAX_GFLOP:g}; docs/inverse.md)")
        return None

    def notes(self, prior_sweeps: int) -> list[str]:
        """What the report says of the solve: the method declined, the start (``prior_sweeps`` produced it)."""
        notes = list(self._declined)
        if self.afresh:
            notes.append("the interior-point method solved this groom afresh: it takes no starting forces (those "
                         "given were not used)")
        if self.warm:
            notes.append(f"the solver started from the given forces (after {prior_sweeps} earlier sweeps), at "
                         f"relative residual {self.first_residual / self.problem.force_scale:.2g}")
        elif self.newton_start:
            notes.append("no contact couples two strands: each strand's contacts were first solved together "
                         "(Newton on their block), and the sweeps started from those forces")
        return notes


def _interior_progress(progress, max_iterations: int):
    """The progress callable for the interior-point steps, called as (step, rest-shape bound): a bar that
    counts sweeps switches to steps through its ``interior(max_iterations)`` at the first step, so a groom the
    interior-point method declines (solver.method = auto) keeps a bar of sweeps."""
    switch = getattr(progress, "interior", None)
    if progress is None or switch is None:
        return progress
    bar = []

    def report(step: int, bound: float) -> None:
        if not bar:
            bar.append(switch(max_iterations))
        bar[0](step, bound)
    return report



def _strands_at_once(rows: ContactRows, d: np.ndarray, gamma, b: np.ndarray, contacts: Contacts,
                     target: float) -> np.ndarray:
    """Body contacts only: the strands do not interact, so each strand's contacts are solved together,
    by nonsmooth Newton on their dense block of ``W`` (:mod:`hairinv.solver.blocks`) to the natural-map
    residual ``target`` (N). The forces are the Gauss-Seidel's warm start, which then has little or
    nothing left to do: 300 settled strands (target zero, tolerance 1e-4) need 5 sweeps instead of
    1,420 (0.02 s instead of 0.63 s), and at 1e-6 converge in 1,530 where 2,000 sweeps stopped at 8e-5;
    a few strands (2 to 19 of the 300) have blocks too ill-conditioned for the Newton steps."""
    n = contacts.n_contacts
    scaled = ContactRows(rows.ptr, rows.cols, rows.vals * np.sqrt(d[rows.cols])[:, None], rows.n_dofs)
    gammas = np.array(np.broadcast_to(np.asarray(gamma, dtype=np.float64), (n,)))
    members, group_ptr, block_ptr, blocks = strand_blocks(scaled, gammas, contacts.strand)
    Wd = np.empty((n, 3, 3))
    diagonal_blocks(scaled.ptr, scaled.cols, scaled.vals, np.ones(rows.n_dofs), gammas, Wd)
    r = np.zeros((n, 3))
    f = np.zeros(rows.n_dofs)
    done = np.zeros(len(group_ptr) - 1, dtype=np.bool_)
    run_chunks(lambda lo, hi: group_newton(scaled.ptr, scaled.cols, scaled.vals, gammas, b, contacts.mu, members,
                                           group_ptr, block_ptr, blocks, Wd, r, f, target, STRAND_NEWTON_ITERS,
                                           CONE.desaxce, False, lo, hi, done), len(done), 16)
    return r



def warm_start(group: stages.Group, material: Material, settings: SolverSettings,
               source: str, n_strands: int | None = None) -> tuple[np.ndarray | None, int, str, np.ndarray | None]:
    """The forces of an earlier model (``group``, for the same contacts, read from ``source``) to start from.

    Returns (forces or None, the sweeps that produced them, a line for the user, the model's per-strand
    stiffening or None). The forces are used only if the model solved the same problem: the same
    target, gamma and material, and stiffened strands only when stabilisation is on (its forces are
    then a point near this problem's optimum; those of another problem may be a worse start than zero).
    With stabilisation on, the model's stiffening factors are the start of this run's.
    """
    if not settings.warm_start or settings.target == "gravity-only":
        return None, 0, "", None
    a = group.attrs
    differ = [] if a.get("target") == settings.target else ["target"]
    if not np.isclose(float(a["gamma"]), settings.gamma, rtol=1e-12, atol=0.0):
        differ.append("gamma")
    if not np.isclose(float(a.get("gamma_relative", 0.0)), settings.gamma_relative, rtol=1e-12, atol=0.0):
        differ.append("solver.gamma_relative")
    stored = material_from_group(group).attrs()
    differ += [f"material ({key})" for key, value in material.attrs().items()
               if not np.allclose(stored[key], value, rtol=1e-12, atol=0.0)]
    factor = stiffening_from_group(group, n_strands) if n_strands is not None else None
    if factor is not None and settings.stabilize != "stiffen" and np.any(factor != 1.0):
        differ.append("stiffness (its strands were stiffened; solver.stabilize is off)")
    if differ:
        return None, 0, f"the model in {source} was inverted with another {', '.join(differ)}: starting afresh", None
    prior = int(a.get("prior_sweeps", 0)) + int(a.get("iterations", 0))
    if settings.method == "auto":  # the sweeps take them if the interior-point method declines the groom
        return (np.asarray(group["force"], dtype=np.float64), prior, "",
                factor if settings.stabilize == "stiffen" else None)
    if settings.method == "interior-point":
        return (None, 0, f"the interior-point method starts afresh: it takes no starting forces (the model in "
                f"{source} has some)", factor if settings.stabilize == "stiffen" else None)
    line = (f"starting from the forces of the model in {source} ({prior} sweeps, {a.get('status', 'status unknown')}, "
            f"relative residual {float(a.get('relative_residual', np.nan)):.2g}); --set solver.warm_start=false "
            "starts afresh")
    return (np.asarray(group["force"], dtype=np.float64), prior, line,
            factor if settings.stabilize == "stiffen" else None)

