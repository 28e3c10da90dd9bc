"""Inverse statics with frictional contact (paper, section 6).

The shape ``q`` is known (the fit). Find contact forces ``r`` in the Coulomb
cones and the rest shape ``q0`` such that ``q`` is a static equilibrium,

    K (q - q0) = F_g(q) + H(q)^T r,                                  eq. (4)

choosing among all such ``r`` the one that minimises
``1/2 sum_e w_e |q0_e - t_e|^2 + gamma/2 |r|^2`` (eq. 6) for a target
rest shape ``t``: an SOCQP over the cones. :func:`invert` runs the rooms of
:mod:`hairinv.inverse` in turn: the problem (:mod:`~hairinv.inverse.problem`),
its solve by the interior-point method or by the Gauss-Seidel sweeps
(``solver.method``, :mod:`~hairinv.inverse.method`), the stability check and
stiffening (:mod:`~hairinv.inverse.stabilize`) and the report
(:mod:`~hairinv.inverse.report`). Without contacts the minimiser is ``r = 0``
and ``q0 = q - K^-1 F_g``: the gravity-only inversion of Derouet-Jourdan et
al. 2010.
"""

from __future__ import annotations

import time

import numpy as np

from .config import SolverSettings
from .errors import InputError, RunError
from .inverse.method import METHODS, ContactSolve, starting_forces
from .inverse.problem import TARGETS, InverseProblem
from .inverse.report import InvertReport, gravity_notes, rest_figures, status_warnings
from .inverse.stabilize import STABILIZE, STABLE_UNDER, Stability, check_and_stiffen
from .model import Contacts, Helices, Material, Model, stiffness

__all__ = ["invert", "validate_settings"]


def validate_settings(settings: SolverSettings) -> None:
    """Refuse solver settings :func:`invert` cannot take, in a sentence naming the setting."""
    if settings.target not in TARGETS:
        raise InputError(f"unknown inversion target {settings.target!r}; choose one of {', '.join(TARGETS)}")
    if not settings.gamma > 0:
        raise InputError(f"solver.gamma must be > 0 (it makes the problem strictly convex), got {settings.gamma}")
    if not 0.0 <= settings.gamma_relative < 1.0:
        raise InputError(f"solver.gamma_relative must be in [0, 1), got {settings.gamma_relative}")
    if not settings.tolerance > 0:
        raise InputError(f"solver.tolerance must be > 0, got {settings.tolerance}")
    if settings.max_seconds < 0:
        raise InputError(f"solver.max_seconds must be >= 0 (0: no limit), got {settings.max_seconds}")
    if settings.max_sweeps < 1 or settings.check_every < 1:
        raise InputError("solver.max_sweeps and solver.check_every must be >= 1")
    if settings.method not in METHODS:
        raise InputError(f"unknown solver.method {settings.method!r}; choose one of {', '.join(METHODS)}")
    if not (np.isfinite(settings.rest_tolerance) and settings.rest_tolerance > 0):
        raise InputError(f"solver.rest_tolerance must be a finite number > 0 (1/m), got {settings.rest_tolerance}")
    if settings.max_iterations < 1:
        raise InputError(f"solver.max_iterations must be >= 1, got {settings.max_iterations}")
    if settings.stable_under not in STABLE_UNDER:
        raise InputError(f"unknown solver.stable_under {settings.stable_under!r}; choose one of "
                         f"{', '.join(STABLE_UNDER)}")
    if settings.stabilize not in STABILIZE:
        raise InputError(f"unknown solver.stabilize {settings.stabilize!r}; choose one of {', '.join(STABILIZE)}")
    if not (np.isfinite(settings.stiffen_margin) and settings.stiffen_margin > 1.0):
        raise InputError(f"solver.stiffen_margin must be a finite number > 1, got {settings.stiffen_margin}")
    if not (np.isfinite(settings.friction_reserve) and 0.0 <= settings.friction_reserve < 1.0):
        raise InputError(f"solver.friction_reserve must be a number in [0, 1), got {settings.friction_reserve}")
    if not settings.check_stability and settings.stabilize == "stiffen":
        raise InputError("solver.check_stability = false skips the check that stiffening needs: set "
                         "solver.stabilize = off with it (--stabilize off)")


def invert(helices: Helices, contacts: Contacts | None, material: Material, settings: SolverSettings,
           progress=None, check_stability: bool = True, start: np.ndarray | None = None,
           prior_sweeps: int = 0, stiffening: np.ndarray | None = None) -> tuple[Model, InvertReport]:
    """Solve the inverse problem for ``helices`` resting on ``contacts``.

    With ``settings.stabilize == "stiffen"`` (and ``check_stability``), a strand whose equilibrium is
    unstable is stiffened just enough to hold (:func:`hairinv.inverse.stabilize.check_and_stiffen`, under
    the contact forces held fixed or on the supports, ``settings.stable_under``); the factors are the
    model's ``stiffening``.

    Parameters
    ----------
    helices : Helices, the fitted shape ``q``
    contacts : Contacts or None; ignored for the gravity-only target
    material : Material
    settings : SolverSettings
    progress : callable(sweeps, relative residual, rest-shape bound in 1/m), optional; with
        ``settings.method = "interior-point"`` called as (step, rest-shape bound in 1/m)
    start : (C, 3) float64, optional, forces to start the solver from (an earlier model's, one per
        contact), projected onto the cones first; the problem is convex, so the answer is the same
        optimum to the tolerance, reached sooner from a good start
    prior_sweeps : int, the sweeps that produced ``start``, recorded in the model
    stiffening : (S,) float64, optional, per-strand stiffness factors to start from (an earlier
        model's, with ``start``); stabilisation only raises them

    Raises
    ------
    RunError
        If the solver meets a numerical error (NaN): the message names the residual reached.
    """
    validate_settings(settings)
    started = time.perf_counter()
    # no stability check when the settings ask for none (solver.check_stability = false)
    check_stability = check_stability and settings.check_stability
    declared = 0 if contacts is None else contacts.n_contacts
    if settings.target == "gravity-only" or contacts is None:
        contacts = Contacts.empty()
    # the gravity-only inversion is the baseline of Derouet-Jourdan et al. 2010: the material as it is
    stabilize = check_stability and settings.stabilize == "stiffen" and settings.target != "gravity-only"
    S = helices.n_strands
    factor = None
    if stabilize:
        factor = np.ones(S) if stiffening is None else np.asarray(stiffening, dtype=np.float64).copy()
        if factor.shape != (S,) or not np.all(np.isfinite(factor)) or np.any(factor < 1.0):
            raise InputError(f"the starting stiffening must hold one finite factor >= 1 per strand ({S})")
    problem = InverseProblem.assemble(helices, contacts, material, settings)
    solve = ContactSolve(problem, settings, progress, starting_forces(start, problem, settings))
    stiff = stiffness(helices, material, factor)
    solved = solve.first(stiff)
    first_sweeps = solved.result.sweeps
    found = Stability()
    if check_stability:
        found, solved, stiff = check_and_stiffen(problem, material, settings, solved, stiff, factor, solve.again)
    result = solved.result
    # q0 = q - K^-1 (F_g + H^T r), eq. (4), with the stiffness the strands were inverted with
    load = problem.load(result.r)
    omega_rest = problem.rest_shape(load, stiff)
    if not np.all(np.isfinite(omega_rest)):
        raise RunError("the inverted rest shape is not finite; check the material settings")
    # /model/omega_rest keeps its meaning for every reader: the rest shape that holds the input with these
    # forces at the material's own stiffness; the stiffened model's is stored beside it
    material_rest = omega_rest if factor is None else problem.rest_shape(load, stiffness(helices, material))
    # gravity-only: every declared contact carries no force
    r = result.r if declared == contacts.n_contacts else np.zeros((declared, 3))
    prior = int(prior_sweeps) if solve.warm else 0
    force_scale = problem.force_scale
    model = Model(material_rest, problem.target, problem.weight, r, material, float(settings.gamma), settings.target,
                  result, prior, factor, None if factor is None else omega_rest, stability_margin=found.margin,
                  stable_under=settings.stable_under, carrying_threshold=settings.tolerance * force_scale)
    if declared == contacts.n_contacts and settings.gamma_relative > 0.0:
        model.gamma_relative, model.contact_gamma = float(settings.gamma_relative), solved.gammas
    drift_rms, max_rest_curvature = rest_figures(omega_rest, problem.target)
    report = InvertReport(
        settings.target, contacts.n_contacts, contacts.n_body, int(solved.carrying.sum()), result, force_scale,
        drift_rms, max_rest_curvature, found.unstable, found.unstable_gravity_only, S,
        time.perf_counter() - started,
        notes=(gravity_notes(material, contacts.n_contacts, force_scale) + solve.notes(prior)
               + status_warnings(result, settings)),
        unstable_held=found.unstable_held, stiffening=factor, gravity_only_factor=found.gravity_only_factor,
        youngs_modulus=material.youngs_modulus, stiffened_rounds=found.rounds,
        total_sweeps=first_sweeps + found.sweeps, checked=check_stability, unstable_groups=found.unstable_groups,
        unchecked_together=found.unchecked_together, stable_under=settings.stable_under)
    return model, report
