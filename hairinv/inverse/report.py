"""What an inversion tells the user: :class:`InvertReport`, its notes and warnings, and the settings it
records in the stage file."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from ..config import MaterialSettings, SolverSettings
from ..gravity import tolerance_gravity
from ..model import Material
from ..solver.gauss_seidel import SolverResult
from ..solver.status import Status
from .stability import GROUP_DOFS

__all__ = ["InvertReport", "gravity_notes", "rest_figures", "settings_dict", "status_warnings"]


@dataclass
class InvertReport:
    """Figures of an inversion, for the user."""

    target: str
    contacts: int
    body_contacts: int
    carrying: int
    result: SolverResult
    force_scale: float
    drift_rms: float
    max_rest_curvature: float
    unstable: int
    unstable_gravity_only: int
    strands: int
    seconds: float
    notes: list[str] = field(default_factory=list)
    unstable_held: int = 0
    """Strands unstable even with every declared contact point held: no rest shape can keep them."""
    stiffening: np.ndarray | None = None
    """(S,) the per-strand stiffness factors (None: stabilisation off or not checked)."""
    gravity_only_factor: float = 1.0
    """The one stiffness factor the gravity-only inversion would need for every strand to be stable."""
    youngs_modulus: float = 0.0
    stiffened_rounds: int = 0
    """inversions solved again with stiffened strands"""
    total_sweeps: int = 0
    checked: bool = True
    unstable_groups: int = 0
    """groups of strands joined by loaded hair-hair contacts that are unstable together"""
    unchecked_together: int = 0
    """strands in groups too large for the joint check (``GROUP_DOFS``): checked one by one only"""
    stable_under: str = "forces"
    """what the check held (``solver.stable_under``): the contact forces fixed, or the supports"""

    def _under(self) -> str:
        if not self.contacts:
            return "without contacts"
        return ("under its contact forces held fixed" if self.stable_under == "forces"
                else "with its loaded contact points held")

    def _steps(self) -> str:
        r = self.result
        if r.method != "interior-point":
            return f"{r.sweeps} sweeps"
        steps = f"{r.interior_steps} interior-point steps"
        return steps + (f" and {r.sweeps} sweeps" if r.sweeps else "")

    def lines(self) -> list[str]:
        r = self.result
        if self.contacts == 0:
            lines = [f"inverted {self.strands} strands (target {self.target}) without contacts: "
                     "q0 = q - K^-1 F_g, the gravity-only inversion"]
        else:
            lines = [
                f"inverted {self.strands} strands (target {self.target}) with {self.contacts} contacts "
                f"({self.body_contacts} body, {self.contacts - self.body_contacts} hair-hair); "
                f"{self.carrying} carry force",
                f"solver: {r.status} after {self._steps()} in {r.seconds:.2f} s; "
                f"residual {r.residual:.3g} N = {r.relative_residual:.2g} of the heaviest strand's weight "
                f"({self.force_scale:.3g} N)",
            ]
            if np.isfinite(r.rest_bound):
                whose = "interior-point method's" if r.bound_from == "interior-point" else "forces'"
                lines.append(f"the rest shape is within {r.rest_bound:.2g} 1/m (rms over elements) of the optimum, "
                             f"by the {whose} duality gap")
        lines += [
            f"rest shape: rms drift from the target {self.drift_rms:.4g} 1/m, "
            f"largest rest curvature {self.max_rest_curvature:.4g} 1/m",
        ]
        stiffened = self.stiffening is not None and bool(np.any(self.stiffening > 1.0))
        if stiffened:
            a = self.stiffening[self.stiffening > 1.0]
            again = (f"solved again {self.stiffened_rounds} time{'s' if self.stiffened_rounds != 1 else ''}, "
                     f"{self.total_sweeps} sweeps in all" if self.stable_under != "forces"
                     else "the same forces, the rest shape taken again")
            lines.append(
                f"stiffened {len(a)} of {self.strands} strands to make their equilibrium stable "
                f"{self._under()} (solver.stabilize = stiffen): factor median {np.median(a):.3g}, 90th percentile "
                f"{np.percentile(a, 90):.3g}, max {a.max():.3g} (E up to {a.max() * self.youngs_modulus / 1e9:.3g} "
                f"GPa on those strands); {again}")
        if self.unstable:
            lines.append(f"warning: {self.unstable} of {self.strands} strands rest in an unstable equilibrium "
                         f"{self._under()} (a simulation may let them fall away from the input shape)")
            if self.unstable_groups:
                lines.append(f"{self.unstable_groups} groups of strands leaning on each other are unstable together, "
                             "though each holds with the others in place")
            if self.unstable_held and self.contacts and not stiffened:
                # without contacts the count is the one above
                lines.append(f"{self.unstable_held} of them stay unstable even with every declared contact held "
                             "in place: their input shape cannot be a stable rest on this rod model, whatever the "
                             "rest shape (docs/dynamics.md, Stability)")
            if self.stiffening is None:
                lines.append("solver.stabilize = stiffen (the default) stiffens such strands just enough to hold")
        elif self.checked:
            lines.append(f"every strand rests in a stable equilibrium {self._under()}")
        if self.unchecked_together:
            lines.append(f"note: {self.unchecked_together} strands lean on each other in groups too large to check "
                         f"together (over {GROUP_DOFS} coordinates); each was checked with the others in place")
        if self.contacts and self.checked:
            lines.append(f"for comparison, the gravity-only inversion leaves {self.unstable_gravity_only} "
                         "strands unstable" + (
                             f"; it would need E = {self.gravity_only_factor * self.youngs_modulus / 1e9:.3g} GPa "
                             f"({self.gravity_only_factor:.3g} times) for the whole groom to be stable"
                             if self.gravity_only_factor > 1.0 and self.youngs_modulus else ""))
        lines += self.notes
        if r.local_failures:
            lines.append(f"note: {r.local_failures} local contact solves stopped at their best iterate in the last sweep")
        return lines



def rest_figures(omega_rest: np.ndarray, target: np.ndarray) -> tuple[float, float]:
    """The rms over elements of ``|q0 - t|`` and the largest rest curvature ``|(q0_1, q0_2)|``, 1/m, of the
    rest shape ``omega_rest`` (E, 3) drawn towards ``target`` (E, 3)."""
    drift = omega_rest - target
    curvature = np.hypot(omega_rest[:, 0], omega_rest[:, 1])
    return (float(np.sqrt(np.mean(np.sum(drift ** 2, axis=1)))) if len(drift) else 0.0,
            float(curvature.max()) if len(curvature) else 0.0)


def gravity_notes(material: Material, n_contacts: int, force_scale: float) -> list[str]:
    """The note of a scene without gravity, where the solver's tolerance is relative to another weight."""
    if not np.linalg.norm(material.gravity) > 0.0 and n_contacts:
        return [f"the scene has no gravity: the solver's tolerance is relative to the heaviest strand's weight "
                f"under {tolerance_gravity(material):g} m/s^2 ({force_scale:.3g} N)"]
    return []


def status_warnings(result: SolverResult, settings: SolverSettings) -> list[str]:
    """The warning of a solve stopped before its tolerance, with what to change (none when it converged)."""
    if result.status != Status.CONVERGED and result.bound_from == "interior-point" and np.isfinite(result.rest_bound):
        return [
            f"warning: the interior-point method stopped at {result.status} with the rest shape within "
            f"{result.rest_bound:.2g} 1/m of the optimum (solver.rest_tolerance {settings.rest_tolerance:g}); the "
            "model is an exact equilibrium, but its forces are not yet the best ones: raise solver.max_iterations "
            "(or solver.max_seconds) or solver.rest_tolerance"]
    if result.status != Status.CONVERGED and np.isfinite(result.rest_bound):
        return [
            f"warning: the sweeps stopped at {result.status} with the rest shape within {result.rest_bound:.2g} "
            f"1/m of the optimum (solver.rest_tolerance {settings.rest_tolerance:g}; relative residual "
            f"{result.relative_residual:.2g}, solver.tolerance {settings.tolerance:g}); the model is an exact "
            "equilibrium, but its forces may not yet be the best ones: invert this model again to continue from "
            "its forces, or raise solver.max_sweeps (or solver.max_seconds) or solver.rest_tolerance, or solve to "
            "the optimum with --set solver.method=interior-point (docs/inverse.md)"]
    if result.status != Status.CONVERGED:
        return [
            f"warning: the solver stopped at {result.status} with relative residual {result.relative_residual:.2g} "
            f"(tolerance {settings.tolerance:g}); the model is an exact equilibrium, but its forces are not yet the "
            "best ones: invert this model again to continue from its forces, or raise solver.max_sweeps "
            "(or solver.max_seconds) or the tolerance, or solve to the optimum with --set solver.method=interior-point "
            "(docs/inverse.md)"]
    return []


def settings_dict(material: MaterialSettings, solver: SolverSettings) -> dict:
    return {"material": dataclasses.asdict(material), "solver": dataclasses.asdict(solver)}
