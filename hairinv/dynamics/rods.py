"""The groom as the dynamics sees it: what does not change over a run, what each step changes, and the
strands' step matrices kept between steps.

As NVIDIA warp's ``warp/sim`` keeps its ``Model`` (masses, rest shapes, stiffness) apart from its ``State``
(positions, velocities): :class:`RodModel` holds the strands' rest shape, material and stiffness, the
quadrature and the layout of the per-strand blocks; :class:`RodState` holds the curvatures, their rates
and where each strand's frame has been carried; :class:`StepMatrices` holds the mass matrix, the Hessian
of gravity and the Cholesky factor of each strand's step matrix, kept while the strand has hardly turned.
The step itself is :class:`hairinv.dynamics.simulate.Simulation`'s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._parallel import run_chunks
from ..config import ContactSettings, DynamicsSettings
from ..contacts.body import BodyMesh
from ..gravity import tolerance_gravity
from ..model import Helices, Material, stiffness
from ..rod.helix import strand_points
from .contact import back_substitute, forward_substitute

__all__ = ["RodModel", "RodState", "StepMatrices"]


@dataclass
class RodModel:
    """What a run does not change: the strands at the start, their rest shape and material, in the body's frame.

    Attributes
    ----------
    helices : Helices, the strands at the start (their ``omega`` is the initial ``q``), metres, body frame
    rest : (E, 3) float64, the rest shape ``q0``
    material : Material (its ``gravity`` is the world gravity in the body frame at rest)
    body : BodyMesh or None, the body in its own frame, where a rigid motion's step meets it (a deforming
        body's step brings its own, posed at the step's start)
    contact_settings : ContactSettings, how contacts are detected at every step
    settings : DynamicsSettings
    stiff : (3E,) float64, the diagonal of ``K``
    lam : float, kg/m, the linear density
    rot : float, kg m, the cross-sections' rotational inertia per length, ``lam r^2 / 4`` with ``r`` the
        inertia radius (at least the hair's own)
    gx, gw : (Q,) float64, Gauss-Legendre nodes and weights on [0, 1] for the mass matrix
    chol_ptr : (S + 1,) int64, where each strand's ``3N x 3N`` block starts in the flat per-strand matrices
    strand_length : (S,) float64, m
    strand_weight : float, N, the longest strand's weight (1 without strands)
    velocity_scale : float, m/s per s of step: contact velocities are measured against the speed gravity
        adds in one step, ``g h`` (in a scene without gravity, that of the default 9.81 m/s^2: a tolerance
        relative to zero could never be met)
    up : (3,) float64, against gravity at rest (the hair layer's up)
    tips : (S, 3) float64, m, the strands' tips in the starting shape (the reach of a deforming body's sweep)
    """

    helices: Helices
    rest: np.ndarray
    material: Material
    body: BodyMesh | None
    contact_settings: ContactSettings
    settings: DynamicsSettings
    stiff: np.ndarray
    lam: float
    rot: float
    gx: np.ndarray
    gw: np.ndarray
    chol_ptr: np.ndarray
    strand_length: np.ndarray
    strand_weight: float
    velocity_scale: float
    up: np.ndarray
    tips: np.ndarray

    @classmethod
    def build(cls, helices: Helices, rest: np.ndarray, material: Material, body: BodyMesh | None,
              contacts: ContactSettings, settings: DynamicsSettings,
              stiffening: np.ndarray | None = None) -> "RodModel":
        """The model of ``helices`` (see :class:`~hairinv.dynamics.simulate.Simulation` for the parameters)."""
        lam = material.linear_density
        nodes, weights = np.polynomial.legendre.leggauss(settings.quadrature)
        sizes = (3 * np.diff(helices.offsets)) ** 2
        weight = material.linear_density * np.linalg.norm(material.gravity)
        lengths = np.add.reduceat(helices.length, helices.offsets[:-1]) if helices.n_elements else np.zeros(0)
        strand_length = (np.add.reduceat(helices.length, helices.offsets[:-1]) if helices.n_elements
                         else np.zeros(helices.n_strands))
        q = np.ascontiguousarray(helices.omega, dtype=np.float64)
        tips = strand_points(helices.root, helices.frame0, helices.offsets, q, helices.length,
                             np.arange(helices.n_strands, dtype=np.int64), strand_length.copy()) \
            if helices.n_strands else np.zeros((0, 3))
        return cls(helices=helices, rest=np.ascontiguousarray(rest, dtype=np.float64), material=material, body=body,
                   contact_settings=contacts, settings=settings, stiff=stiffness(helices, material, stiffening),
                   lam=lam, rot=lam * max(settings.inertia_radius, material.radius) ** 2 / 4.0,
                   gx=0.5 * (nodes + 1.0), gw=0.5 * weights,
                   chol_ptr=np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
                   strand_length=strand_length,
                   strand_weight=float(weight * lengths.max()) if len(lengths) else 1.0,
                   velocity_scale=tolerance_gravity(material),
                   up=-np.asarray(material.gravity, dtype=np.float64) / max(np.linalg.norm(material.gravity), 1e-300),
                   tips=tips)

    @property
    def n_strands(self) -> int:
        return self.helices.n_strands

    def swing(self, dq: np.ndarray, factor: float = 1.0) -> np.ndarray:
        """(S,) a cheap bound on how far any point of each strand moves for a change ``factor * dq`` (E, 3)
        of its curvatures (or how fast, for rates): every element's turn ``|d omega_e| l_e`` swings the whole
        strand, ``L sum_e factor |dq_e| l_e``. Zeros for a groom without elements."""
        h = self.helices
        if not h.n_elements:
            return np.zeros(h.n_strands)
        return np.add.reduceat(factor * np.linalg.norm(dq, axis=1) * h.length, h.offsets[:-1]) * self.strand_length


@dataclass
class RodState:
    """What each step changes.

    Attributes
    ----------
    q : (E, 3) float64, 1/m, the elements' curvatures and twist
    v : (E, 3) float64, 1/(m s), their rates
    time : float, s
    R, c : (S, 3, 3), (S, 3) float64, each strand's rigid motion from its bind pose, ``x = R x_bind + c``: the
        identity until a deforming body moves the roots; a rigid scene keeps it, the groom in the body's frame
    placed : bool, whether any strand has left its bind pose
    kinetic : (S,) float64, J, each strand's kinetic energy at the start of the last step
    """

    q: np.ndarray
    v: np.ndarray
    time: float
    R: np.ndarray
    c: np.ndarray
    placed: bool
    kinetic: np.ndarray

    @classmethod
    def start(cls, model: RodModel) -> "RodState":
        """At rest in the model's starting shape, at time 0."""
        helices = model.helices
        q = np.ascontiguousarray(helices.omega, dtype=np.float64).copy()
        return cls(q=q, v=np.zeros_like(q), time=0.0, R=np.broadcast_to(np.eye(3), (helices.n_strands, 3, 3)).copy(),
                   c=np.zeros((helices.n_strands, 3)), placed=False, kinetic=np.zeros(helices.n_strands))

    def current(self, model: RodModel) -> Helices:
        """The strands at ``q``: in the body's frame, or, under a deforming body, placed by their own frames."""
        h = model.helices
        if self.placed:
            return self.posed(model, self.R, self.c)
        return Helices(h.root, h.frame0, h.offsets, h.length, self.q, h.fit_error)

    def posed(self, model: RodModel, R: np.ndarray, c: np.ndarray) -> Helices:
        """The strands at ``q``, each carried by its ``(R, c)`` from its bind pose."""
        h = model.helices
        return Helices(np.einsum("nij,nj->ni", R, h.root) + c, np.einsum("nij,nkj->nik", h.frame0, R), h.offsets,
                       h.length, self.q, h.fit_error)


class StepMatrices:
    """Each strand's step matrix and what it was made of, laid out by ``model.chol_ptr`` (row-major blocks).

    Attributes
    ----------
    chol : the lower Cholesky factor of ``Mt``, per strand
    hess : the part of gravity's (and the contact forces') Hessian the factor holds
    mass : the mass matrix ``M``
    factored_h : (S,) float64, s, the step each strand's factor was made for (-1: none yet)
    hess_q, hess_gravity : the shape (E, 3) and gravity (S, 3) the Hessians and masses were taken at
        (None before the first step)
    """

    def __init__(self, model: RodModel):
        size = int(model.chol_ptr[-1])
        self.chol = np.zeros(size)
        self.hess = np.zeros(size)
        self.mass = np.zeros(size)
        self.factored_h = np.full(model.n_strands, -1.0)
        self.hess_q = None
        self.hess_gravity = None

    def stale_strands(self, model: RodModel, q: np.ndarray, gravity: np.ndarray,
                      awake: np.ndarray | None = None) -> np.ndarray:
        """Strands whose gravity Hessian and mass matrix must be taken again, (S,) bool: they only shape
        the implicit matrix, so they (and its factor) are kept while no element has turned by more than
        0.01 rad since, and gravity (in the strand's frame, ``gravity`` (S, 3)) has not turned by more than
        0.01 rad. A still groom then costs a gravity evaluation and two triangular solves per strand and step.
        Only ``awake`` strands (S,) bool are stepped, and so taken afresh (None: all)."""
        helices = model.helices
        n = helices.n_strands
        if self.hess_q is None:
            fresh = np.ones(n, dtype=np.bool_)
            turned = fresh
        else:
            turned = np.linalg.norm(np.cross(gravity, self.hess_gravity), axis=1) > \
                1e-2 * np.linalg.norm(gravity, axis=1) * np.linalg.norm(self.hess_gravity, axis=1)
            turn = np.linalg.norm(q - self.hess_q, axis=1) * helices.length
            fresh = turned.copy()
            if len(turn):
                fresh |= np.maximum.reduceat(turn, helices.offsets[:-1]) > 1e-2
            if awake is not None:
                turned &= awake
                fresh &= awake
        if fresh.any():
            if self.hess_q is None or fresh.all():
                self.hess_q = q.copy()
                self.hess_gravity = np.array(gravity, dtype=np.float64)
            else:
                mask = np.repeat(fresh, np.diff(helices.offsets))
                self.hess_q[mask] = q[mask]
                self.hess_gravity[turned] = gravity[turned]
        return fresh

    def mass_solve(self, model: RodModel, y: np.ndarray, factored: bool = False) -> np.ndarray:
        """``Mt^-1 y`` strand by strand through the factors ``Mt = L L^T`` (``L^-T y`` only, for ``y`` given
        as ``L^-1`` of something: ``factored``)."""
        offsets, n = model.helices.offsets, model.n_strands
        if not factored:
            x = np.zeros_like(y)
            run_chunks(lambda lo, hi: forward_substitute(offsets, self.chol, model.chol_ptr, y, x, lo, hi), n, 64)
            y = x
        out = np.zeros_like(y)
        run_chunks(lambda lo, hi: back_substitute(offsets, self.chol, model.chol_ptr, y, out, lo, hi), n, 64)
        return out
