"""The inverse problem of one groom: its targets, its contact weights and its SOCQP (paper, section 6).

With ``q0 = q - K^-1 (F_g + H^T r)`` (eq. 4), minimising ``1/2 sum_e w_e |q0_e - t_e|^2 + gamma/2 |r|^2``
(eq. 6) over the Coulomb cones is the SOCQP ``min 1/2 r^T W r + b^T r`` with

    D = w K^-2 (diagonal),  W = H D H^T + gamma I,  b = H D (F_g - K (q - t)).

:class:`InverseProblem` holds what does not change with the stiffness (``q``, ``t``, ``w``, ``F_g``,
``H``, the cones) and gives the SOCQP, ``D``, ``b`` and the contacts' ``gamma``, for a stiffness ``K``
(:meth:`InverseProblem.cone`), which stabilisation may raise strand by strand. :func:`model_mismatch`
checks eq. (4) on a stored model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import stages
from .._parallel import run_chunks
from ..config import SolverSettings
from ..errors import InputError
from ..gravity import generalized_gravity, tolerance_gravity
from ..model import Contacts, Helices, Material, material_from_group, rest_from_group, stiffening_from_group, stiffness
from ..contacts.rows import contact_rows
from ..solver.gauss_seidel import diagonal_blocks, split_strands
from ..solver.problem import ConeProblem
from ..solver.rows import ContactRows

__all__ = ["TARGETS", "InverseProblem", "contact_diagonal", "contact_gamma", "model_mismatch", "target_shape"]

TARGETS = ("actual", "zero", "uniform", "tip", "gravity-only")


def target_shape(helices: Helices, target: str) -> np.ndarray:
    """The rest shape ``t`` the inversion draws ``q0`` towards, (E, 3).

    actual: the input shape ``q`` (the paper's default); zero: straight;
    uniform: each strand's length-weighted mean of ``q``; tip: each strand's
    last element (its curliness at the free end) along the whole strand;
    gravity-only: ``q`` (there are no contacts to choose).
    """
    q = helices.omega
    if target in ("actual", "gravity-only"):
        return q.copy()
    if target == "zero":
        return np.zeros_like(q)
    counts = np.diff(helices.offsets)
    if target == "uniform":
        starts = helices.offsets[:-1]
        weighted = np.add.reduceat(q * helices.length[:, None], starts, axis=0)
        mean = weighted / np.add.reduceat(helices.length, starts)[:, None]
        return np.repeat(mean, counts, axis=0)
    if target == "tip":
        return np.repeat(q[helices.offsets[1:] - 1], counts, axis=0)
    raise InputError(f"unknown inversion target {target!r}; choose one of {', '.join(TARGETS)}")


def contact_diagonal(rows: ContactRows, d: np.ndarray) -> np.ndarray:
    """``trace(H_i D H_i^T) / 3`` of every contact, (C,): the mean of the diagonal of its 3x3 block of ``W``
    without ``gamma`` (what a force of 1 N on that contact alone moves the rest shape by, squared)."""
    C = rows.n_contacts
    Wd = np.empty((C, 3, 3))
    diagonal_blocks(rows.ptr, rows.cols, rows.vals, d, np.zeros(C), Wd)
    return np.trace(Wd, axis1=1, axis2=2) / 3.0


def contact_gamma(rows: ContactRows, d: np.ndarray, gamma: float, relative: float) -> np.ndarray:
    """Each contact's weight in the objective, (C,): ``max(gamma, relative * contact_diagonal)``
    (``solver.gamma_relative``; docs/inverse.md, "Bounded forces")."""
    if relative <= 0.0 or rows.n_contacts == 0:
        return np.full(rows.n_contacts, float(gamma))
    return np.maximum(float(gamma), relative * contact_diagonal(rows, d))


@dataclass(frozen=True)
class InverseProblem:
    """Eq. (6) on one groom, for any stiffness.

    Attributes
    ----------
    helices : Helices, the fitted shape ``q``
    contacts : Contacts, the contacts solved for (none for the gravity-only target)
    q : (3E,) float64, 1/m, the input shape
    target : (E, 3) float64, 1/m, the rest shape ``t`` drawn towards (:func:`target_shape`)
    weight : (E,) float64, the elements' weights ``w_e``
    gravity : (3E,) float64, J m, ``F_g(q)``
    rows : ContactRows, ``H``
    mu : (C,) float64, the cones the forces are found in: the declared friction less
        ``solver.friction_reserve`` (mu = 0 and inf stay)
    force_scale : float, N, the heaviest strand's weight, the unit of the solver's tolerance
    gamma, gamma_relative : the contacts' weight in the objective (:func:`contact_gamma`)
    """

    helices: Helices
    contacts: Contacts
    q: np.ndarray
    target: np.ndarray
    weight: np.ndarray
    gravity: np.ndarray
    rows: ContactRows
    mu: np.ndarray
    force_scale: float
    gamma: float
    gamma_relative: float

    @classmethod
    def assemble(cls, helices: Helices, contacts: Contacts, material: Material,
                 settings: SolverSettings) -> InverseProblem:
        """The problem of ``helices`` resting on ``contacts``, for the target and weights of ``settings``."""
        rows = contact_rows(helices, contacts, run=lambda work, count: run_chunks(work, count, 2048))
        strand_length = np.add.reduceat(helices.length, helices.offsets[:-1])
        return cls(helices, contacts, helices.omega.ravel(), target_shape(helices, settings.target),
                   np.ones(helices.n_elements), generalized_gravity(helices, material).ravel(), rows,
                   contacts.mu * (1.0 - settings.friction_reserve),
                   material.linear_density * tolerance_gravity(material) * float(strand_length.max()),
                   settings.gamma, settings.gamma_relative)

    def cone(self, stiff: np.ndarray) -> ConeProblem:
        """The SOCQP at the stiffness ``stiff`` (3E,): ``D``, ``b`` and each contact's ``gamma``, with the
        contacts' strands (residuals relative to ``force_scale``)."""
        # D = w K^-2; b = H D (F_g - K (q - t))
        d = np.repeat(self.weight, 3) / stiff ** 2
        b = self.rows.matvec(d * (self.gravity - stiff * (self.q - self.target.ravel())))
        gammas = contact_gamma(self.rows, d, self.gamma, self.gamma_relative)
        contacts = self.contacts
        return ConeProblem.of(self.rows, d, gammas, b, self.mu, contacts.strand, self.helices.n_strands,
                              self.force_scale, s=contacts.s, part_of=split_strands(self.helices.root, contacts.strand))

    def load(self, r: np.ndarray) -> np.ndarray:
        """``F_g + H^T r`` (3E,), J m, for the forces ``r`` (C, 3), N."""
        return self.gravity + self.rows.rmatvec(r)

    def rest_shape(self, load: np.ndarray, stiff: np.ndarray) -> np.ndarray:
        """``q0 = q - K^-1 (F_g + H^T r)`` (E, 3), 1/m, eq. (4), for ``load`` from :meth:`load`."""
        return (self.q - load / stiff).reshape(-1, 3)


#: 1/m: how far a stored rest shape may be from the one its forces give on its helices (eq. 4), plus
#: :data:`MODEL_MISMATCH_RELATIVE` of the curvatures involved; a model read back as written is at round-off
MODEL_MISMATCH = 1e-6
MODEL_MISMATCH_RELATIVE = 1e-9


def model_mismatch(helices: Helices, contacts: Contacts | None, group: stages.Group) -> tuple[float, int]:
    """How far a ``/model`` group's rest shape is from holding ``helices`` with its own forces: the largest
    ``|q0 - (q - K^-1 (F_g + H^T r))|`` over elements (1/m) beyond round-off, and the element where it is
    (-1 where it holds).

    Equation (4) holds for the model :func:`hairinv.invert.invert` writes whatever solved it, so a model whose
    helices or contacts were changed after it was inverted (same sizes) shows here. The rest shape checked is
    the one a simulation takes: ``omega_rest_stiffened`` at the stiffened stiffness where the model has one."""
    material = material_from_group(group)
    # the stiffened rest shape and its factors come together (the stage file's checks), or neither
    factor = stiffening_from_group(group, helices.n_strands)
    stored = rest_from_group(group).reshape(-1)
    q = helices.omega.ravel()
    load = generalized_gravity(helices, material).ravel()
    force = np.asarray(group["force"], dtype=np.float64)
    if contacts is not None and contacts.n_contacts and np.any(force):
        load = load + contact_rows(helices, contacts).rmatvec(force)
    change = load / stiffness(helices, material, factor)
    miss = np.abs(stored - (q - change))
    allowed = MODEL_MISMATCH + MODEL_MISMATCH_RELATIVE * (np.abs(q) + np.abs(change))
    beyond = (miss - allowed).reshape(-1, 3).max(axis=1) if len(miss) else np.zeros(0)
    if not len(beyond) or not np.any(beyond > 0):
        return 0.0, -1
    e = int(np.argmax(beyond))
    return float(miss.reshape(-1, 3)[e].max()), e
