"""The data of a physical hair model: what each stage file group holds, as Python values.

One module for the model's data contract (docs/stage-files.md), apart from the
code that computes it: the fitted strands (:class:`Helices`, ``/helices``), the
declared contacts (:class:`Contacts`, ``/contacts``), the rod material
(:class:`Material`) and the inverted model (:class:`Model`, ``/model``), with
the stiffness ``K`` they define. fit, detect, invert and simulate all read and
write these; none of them needs another stage's code to get them.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from . import stages
from .config import MATERIAL_RANGE, ContactSettings, FitSettings, MaterialSettings, material_range_error
from .errors import InputError

if TYPE_CHECKING:  # the solver's result type, for annotations only
    from .solver.gauss_seidel import SolverResult

__all__ = ["BODY", "Helices", "Contacts", "Material", "Model", "stiffness", "material_from_group",
           "rest_from_group", "stiffening_from_group"]

BODY = -1
"""Side B of a body contact."""


@dataclass
class Helices:
    """Fitted super-helices of a groom (the ``/helices`` group).

    Attributes
    ----------
    root : (S, 3) float64, m
    frame0 : (S, 3, 3) float64, rows (t, n1, n2)
    offsets : (S + 1,) int64, CSR offsets into the element arrays
    length : (E,) float64, m
    omega : (E, 3) float64, (kappa1, kappa2, tau), 1/m
    fit_error : (S, 2) float64, m, mean and max vertex distance
    """

    root: np.ndarray
    frame0: np.ndarray
    offsets: np.ndarray
    length: np.ndarray
    omega: np.ndarray
    fit_error: np.ndarray

    @property
    def n_strands(self) -> int:
        return int(len(self.offsets) - 1)

    @property
    def n_elements(self) -> int:
        return int(self.offsets[-1])

    def group(self, settings: FitSettings, inputs: list[dict], extra_attrs: dict | None = None) -> stages.Group:
        return stages.Group(
            stages.HELICES,
            {
                "root": self.root,
                "frame0": self.frame0,
                "offsets": self.offsets,
                "length": self.length,
                "omega": self.omega,
                "fit_error": self.fit_error,
            },
            attrs=dict(extra_attrs or {}),
            config={"fit": dataclasses.asdict(settings)},
            inputs=inputs,
        )

    @classmethod
    def from_group(cls, group: stages.Group) -> "Helices":
        return cls(*(np.ascontiguousarray(group[k]) for k in ("root", "frame0", "offsets", "length", "omega", "fit_error")))


@dataclass
class Contacts:
    """Declared contacts (the ``/contacts`` group, docs/stage-files.md).

    Attributes
    ----------
    strand : (C, 2) int64
        Strand on side A, strand on side B or -1 for the body. A is the lower index.
    s : (C, 2) float64, m
        Arc length of the contact along A and along B (0 for the body), from the root on the fitted helices.
    point : (C, 3) float64, m
        Contact point on A's centerline.
    frame : (C, 3, 3) float64
        Rows (normal, tangent1, tangent2), right-handed and orthonormal; the
        normal points from B towards A (from the body surface towards the hair).
    mu : (C,) float64
        Coulomb friction coefficient.
    gap : (C,) float64 or None, m
        Distance at detection: signed distance from the body surface (negative
        inside) or between the two centerlines. None for files written before
        it was stored.
    element : (C, 2) int64 or None
        Element (global index) holding each side, -1 for the body; at most one
        contact per element (body) or element pair (hair-hair), so it names
        the contact from one detection to the next. Stored as ``/contacts/element``
        (None for files written before it was, or by tools that do not write it).
    """

    strand: np.ndarray
    s: np.ndarray
    point: np.ndarray
    frame: np.ndarray
    mu: np.ndarray
    gap: np.ndarray | None = None
    element: np.ndarray | None = None

    @property
    def n_contacts(self) -> int:
        return int(len(self.mu))

    @property
    def n_body(self) -> int:
        return int(np.count_nonzero(self.strand[:, 1] == BODY))

    @property
    def n_hair(self) -> int:
        return self.n_contacts - self.n_body

    def group(self, settings: ContactSettings, inputs: list[dict], seconds: float | None = None) -> stages.Group:
        """``seconds``: how long the detection took (the group's ``seconds`` attribute), if known."""
        data = {"strand": self.strand, "s": self.s, "point": self.point, "frame": self.frame, "mu": self.mu}
        if self.gap is not None:
            data["gap"] = self.gap
        if self.element is not None:
            data["element"] = np.asarray(self.element, dtype=np.int64)
        return stages.Group(
            stages.CONTACTS,
            data,
            attrs={} if seconds is None else {"seconds": float(seconds)},
            config={"contacts": dataclasses.asdict(settings)},
            inputs=inputs,
        )

    @classmethod
    def from_group(cls, group: stages.Group) -> "Contacts":
        return cls(
            np.ascontiguousarray(group["strand"], dtype=np.int64).reshape(-1, 2),
            np.ascontiguousarray(group["s"], dtype=np.float64).reshape(-1, 2),
            np.ascontiguousarray(group["point"], dtype=np.float64).reshape(-1, 3),
            np.ascontiguousarray(group["frame"], dtype=np.float64).reshape(-1, 3, 3),
            np.ascontiguousarray(group["mu"], dtype=np.float64).reshape(-1),
            np.ascontiguousarray(group["gap"], dtype=np.float64).reshape(-1) if "gap" in group.datasets else None,
            np.ascontiguousarray(group["element"], dtype=np.int64).reshape(-1, 2) if "element" in group.datasets
            else None,
        )

    @classmethod
    def empty(cls) -> "Contacts":
        return cls(np.zeros((0, 2), np.int64), np.zeros((0, 2)), np.zeros((0, 3)), np.zeros((0, 3, 3)), np.zeros(0),
                   np.zeros(0), np.zeros((0, 2), np.int64))

    def subset(self, mask) -> "Contacts":
        """The contacts selected by a boolean mask (C,) or an index array, in that order."""
        mask = np.asarray(mask)
        arrays = (self.strand, self.s, self.point, self.frame, self.mu)
        gap = None if self.gap is None else np.ascontiguousarray(self.gap[mask])
        element = None if self.element is None else np.ascontiguousarray(self.element[mask])
        return Contacts(*(np.ascontiguousarray(a[mask]) for a in arrays), gap, element)


@dataclass(frozen=True)
class Material:
    """Rod constants derived from :class:`MaterialSettings` (SI)."""

    youngs_modulus: float
    shear_modulus: float
    density: float
    radius: float
    gravity: np.ndarray
    """(3,) m/s^2, pointing down."""

    @classmethod
    def from_settings(cls, settings: MaterialSettings, up: np.ndarray) -> "Material":
        for name in MATERIAL_RANGE:
            problem = material_range_error(name, getattr(settings, name))
            if problem is not None:
                raise InputError(f"material.{problem}")
        if not -1.0 < settings.poisson_ratio <= 0.5:
            raise InputError(f"material.poisson_ratio must be in (-1, 0.5], got {settings.poisson_ratio}")
        lo, hi, _ = MATERIAL_RANGE["shear_modulus"]
        if settings.shear_modulus == 0 and not lo <= settings.shear <= hi:  # derived (a given one is checked above)
            raise InputError(f"the shear modulus E / (2 (1 + poisson_ratio)) is {settings.shear:g} Pa; it must be "
                             f"from {lo:g} to {hi:g} Pa: set material.shear_modulus")
        up = np.asarray(up, dtype=np.float64)
        return cls(float(settings.youngs_modulus), float(settings.shear), float(settings.density),
                   float(settings.radius), -settings.gravity * up / np.linalg.norm(up))

    @property
    def area(self) -> float:
        return np.pi * self.radius ** 2

    @property
    def linear_density(self) -> float:
        """kg/m."""
        return self.density * self.area

    @property
    def bending(self) -> float:
        """EI, N m^2, with I = pi r^4 / 4."""
        return self.youngs_modulus * np.pi * self.radius ** 4 / 4.0

    @property
    def twisting(self) -> float:
        """GJ, N m^2, with J = pi r^4 / 2."""
        return self.shear_modulus * np.pi * self.radius ** 4 / 2.0

    def attrs(self) -> dict:
        return {"youngs_modulus": self.youngs_modulus, "shear_modulus": self.shear_modulus,
                "density": self.density, "radius": self.radius, "gravity": self.gravity}


def stiffness(helices: Helices, material: Material, factor: np.ndarray | None = None) -> np.ndarray:
    """Diagonal of ``K``, (3E,): ``K_e = a_s length_e diag(EI, EI, GJ)``, N m^3.

    ``factor`` : (S,) float64, optional, the per-strand stiffening ``a_s`` (bending and twist alike,
    ``/model/stiffening``); None or all ones is the material's own stiffness.
    """
    per_component = np.array([material.bending, material.bending, material.twisting])
    K = (helices.length[:, None] * per_component[None, :])
    if factor is not None:
        K = K * np.repeat(np.asarray(factor, dtype=np.float64), np.diff(helices.offsets))[:, None]
    return K.ravel()


#: A strand's stability margin (smallest eigenvalue of its scaled Hessian) below this is unstable; above it,
#: up to the round-off of the eigenvalue solve, stable.
UNSTABLE_MARGIN = -1e-6


@dataclass
class Model:
    """The inverted model (the ``/model`` group)."""

    omega_rest: np.ndarray
    omega_target: np.ndarray
    target_weight: np.ndarray
    force: np.ndarray
    material: Material
    gamma: float
    target: str
    result: "SolverResult"
    prior_sweeps: int = 0
    """sweeps of the earlier runs whose forces this one started from (0: it started afresh)"""
    stiffening: np.ndarray | None = None
    """(S,) float64, the factor each strand's bending and twist stiffness was multiplied by so that
    its equilibrium is stable (1: the material's own); None when stabilisation was off"""
    omega_rest_stiffened: np.ndarray | None = None
    """(E, 3) float64, the rest shape of the stiffened strands (``omega_rest`` is the one that holds the
    input with the same forces at the material's own stiffness); None when stabilisation was off"""
    stability_margin: np.ndarray | None = None
    """(S,) float64, each strand's smallest eigenvalue ``lambda`` of ``I + K^-1/2 V'' K^-1/2`` at the
    stiffness it rests with (its stiffening included), on the motions ``solver.stable_under`` allows
    (:func:`hairinv.inverse.stability.stability_margins`): > 0 rests stably, < 0 unstable; ``inf`` where no motion is
    left; below :data:`UNSTABLE_MARGIN` unstable. None when stability was not checked"""
    stable_under: str = ""
    """what ``stability_margin`` holds fixed: ``forces`` or ``supports`` (solver.stable_under)"""
    carrying_threshold: float | None = None
    """N: a contact carries force where its normal force exceeds this (the solver's tolerance times the
    heaviest strand's weight; below it a force is the solver's round-off)"""
    gamma_relative: float = 0.0
    """solver.gamma_relative the forces were found with (0: every contact weighs ``gamma``)"""
    contact_gamma: np.ndarray | None = None
    """(C,) float64, each contact's weight in the objective when ``gamma_relative`` > 0"""

    @property
    def rest(self) -> np.ndarray:
        """(E, 3) the rest shape a simulation of this model uses (with :attr:`stiffening`)."""
        return self.omega_rest if self.omega_rest_stiffened is None else self.omega_rest_stiffened

    def group(self, settings: dict, inputs: list[dict]) -> stages.Group:
        attrs = dict(self.material.attrs())
        attrs.update(gamma=self.gamma, target=self.target, iterations=self.result.sweeps,
                     residual=self.result.residual, seconds=self.result.seconds,
                     status=str(self.result.status), relative_residual=self.result.relative_residual,
                     prior_sweeps=int(self.prior_sweeps), method=self.result.method)
        if self.result.method == "interior-point":
            attrs["interior_steps"] = int(self.result.interior_steps)
        if np.isfinite(self.result.rest_bound):
            attrs["rest_bound"] = float(self.result.rest_bound)
        data = {"omega_rest": self.omega_rest, "omega_target": self.omega_target,
                "target_weight": self.target_weight, "force": self.force,
                "residual_history": np.array(self.result.history, dtype=np.float64).reshape(-1, 2)}
        if self.stiffening is not None:
            data["stiffening"] = np.asarray(self.stiffening, dtype=np.float64)
            data["omega_rest_stiffened"] = np.asarray(self.omega_rest_stiffened, dtype=np.float64)
        if self.carrying_threshold is not None:
            attrs["carrying_threshold"] = float(self.carrying_threshold)
        if self.gamma_relative > 0.0 and self.contact_gamma is not None:
            attrs["gamma_relative"] = float(self.gamma_relative)
            data["contact_gamma"] = np.asarray(self.contact_gamma, dtype=np.float64)
        if self.stability_margin is not None:
            data["stability_margin"] = np.asarray(self.stability_margin, dtype=np.float64)
            attrs["stable_under"] = self.stable_under
        return stages.Group(stages.MODEL, data, attrs=attrs, config=settings, inputs=inputs)


def material_from_group(group: stages.Group) -> Material:
    """The material of a ``/model`` group."""
    a = group.attrs
    return Material(float(a["youngs_modulus"]), float(a["shear_modulus"]), float(a["density"]),
                    float(a["radius"]), np.asarray(a["gravity"], dtype=np.float64))


def rest_from_group(group: stages.Group) -> np.ndarray:
    """The rest shape (E, 3) a simulation of a ``/model`` group uses: ``omega_rest_stiffened`` where the
    model stiffened strands (with :func:`stiffening_from_group`), else ``omega_rest``."""
    name = "omega_rest_stiffened" if "omega_rest_stiffened" in group.datasets else "omega_rest"
    return np.ascontiguousarray(group[name], dtype=np.float64)


def stability_from_group(group: stages.Group, n_strands: int) -> np.ndarray | None:
    """Each strand's stability margin of a ``/model`` group (``stability_margin``, (S,), > 0 stable), or None
    if the file has none (stability not checked, or a version before it was stored)."""
    if "stability_margin" not in group.datasets:
        return None
    margin = np.ascontiguousarray(group["stability_margin"], dtype=np.float64).reshape(-1)
    if margin.shape != (n_strands,) or np.any(np.isnan(margin)):
        raise InputError(f"/model/stability_margin must hold one number per strand ({n_strands}), "
                         f"got shape {margin.shape}")
    return margin


def stiffening_from_group(group: stages.Group, n_strands: int) -> np.ndarray | None:
    """The per-strand stiffening factors of a ``/model`` group, (S,), or None if it has none (a model
    inverted without stabilisation, or by a version before it was stored: the material's own stiffness)."""
    if "stiffening" not in group.datasets:
        return None
    factor = np.ascontiguousarray(group["stiffening"], dtype=np.float64).reshape(-1)
    if factor.shape != (n_strands,) or not np.all(np.isfinite(factor)) or np.any(factor <= 0):
        raise InputError(f"/model/stiffening must hold one finite factor > 0 per strand ({n_strands}), "
                         f"got shape {factor.shape}")
    return factor
