"""Super-helix dynamics with frictional contact (paper section 7, after Daviet et al. 2011).

Everything is computed in the body's frame: the roots are clamped to the
body, and the body moves rigidly, so in its frame the body and the roots
stand still and the motion shows up as the fictitious forces of a moving
frame (its linear acceleration, the Euler, centrifugal and Coriolis terms)
and as gravity turning with the body. Air drag acts against the velocity
in the world.

One step of length ``h`` (linearly implicit Euler, Bertails et al. 2006):

    Mt = M(q) + h D + h^2 K,      D = damping K + air_damping M
    v_f = v + Mt^-1 (h (F(q, v) - K (q - q0)) - (h D + h^2 K) v)
    v+ = v_f + Mt^-1 H^T r,       q+ = q + h v+

with ``F`` gravity (exact, as in the inversion), the fictitious and
velocity-product forces and the drag of the moving frame, and ``r`` the
contact impulses: Coulomb's law on the De Saxce velocities
``u = H v+ + g/h`` where ``g`` is how much closer the contact may come
(docs/dynamics.md). From the inverted model at rest the first step's
answer is ``r = h r_inverse`` and ``v+ = 0``: a still body keeps a still groom.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .._dense import cholesky
from .._jit import jit
from .._parallel import balanced, run_chunks
from ..config import ContactSettings, DynamicsSettings, MaterialSettings
from ..contacts.body import BodyMesh
from ..contacts.rows import contact_rows
from ..errors import InputError
from ..model import BODY, Contacts, Helices, Material
from ..rod.statics import gravity_forces, gravity_hessian, point_load_hessian
from ..solver.gauss_seidel import SolverResult, natural_residuals, split_strands
from ..solver.problem import COULOMB
from ..solver.status import Status
from .contact import (CoulombSettings, coulomb_problem, delassus_blocks, factored_blocks, factored_rows, reachable,
                      solve_coulomb)
from .inertia import strand_mass, strand_velocity_forces
from .rods import RodModel, RodState, StepMatrices
from .sleep import Sleepers, carried, islands
# points_on and _strand_moves are named here too, where callers found them before the tracker had its module
from .tracking import ContactTracker, _strand_moves, points_on  # noqa: F401

__all__ = ["Motion", "PhaseClock", "Simulation", "StepReport", "points_on", "strand_dynamics", "validate_settings"]


def validate_settings(settings: DynamicsSettings) -> None:
    """Raise InputError (naming the setting) for a value the integrator cannot use."""
    for name in ("time_step", "max_turn"):
        if not getattr(settings, name) > 0:
            raise InputError(f"dynamics.{name} must be > 0, got {getattr(settings, name)}")
    for name in ("damping", "air_damping", "body_thickness", "hair_thickness", "push_speed", "tolerance",
                 "inertia_radius", "sleep_speed"):
        value = getattr(settings, name)
        if not (value >= 0 and np.isfinite(value)):
            raise InputError(f"dynamics.{name} must be >= 0 and finite, got {value}")
    if not 0 <= settings.max_substeps <= 12:
        raise InputError(f"dynamics.max_substeps must be between 0 and 12, got {settings.max_substeps}")
    if settings.stall_rounds < 0:
        raise InputError(f"dynamics.stall_rounds must be >= 0, got {settings.stall_rounds}")
    if settings.max_sweeps < 1:
        raise InputError(f"dynamics.max_sweeps must be >= 1, got {settings.max_sweeps}")
    if not 1 <= settings.quadrature <= 8:
        raise InputError(f"dynamics.quadrature must be between 1 and 8, got {settings.quadrature}")


@jit
def _load_hessians(strands, lo, hi, bounds, root, frame0, q, length, offsets, arc, load, chol_ptr, held):
    """:func:`point_load_hessian` of ``strands[lo:hi]``, each strand's loads ``bounds[k]:bounds[k + 1]``
    of ``arc`` and ``load``, written into its block of ``held`` (laid out like the Cholesky blocks)."""
    for w in range(lo, hi):
        k = strands[w]
        a = offsets[k]
        z = offsets[k + 1]
        n = 3 * (z - a)
        out = np.empty((n, n))
        point_load_hessian(root[k], frame0[k], q[a:z], length[a:z], arc[bounds[k]:bounds[k + 1]],
                           load[bounds[k]:bounds[k + 1]], out)
        held[chol_ptr[k]:chol_ptr[k + 1]] = out.ravel()

@dataclass
class StepReport:
    """What one step did."""

    contacts: int
    n_body: int
    sweeps: int
    relative_residual: float
    status: str
    local_failures: int
    seconds: float
    substeps: int = 1
    rejected: int = 0
    """attempts thrown away because they turned an element too far (or their contact solve failed)"""
    depth: int = 0
    """the most halvings of the step any kept substep had"""
    last_depth: int = 0
    """the halvings of the step's last substep"""
    turn: float = 0.0
    """rad, the furthest any element turned in a kept substep"""
    kept_turning: int = 0
    """substeps kept although an element turned further than ``max_turn``: halving had not made the
    turn smaller (it turned more than ``_HALVING_GAIN`` times as far as the attempt it replaced)"""
    turned: int = -1
    """the strand whose element turned furthest in the last attempt thrown away for turning too far
    (-1: none was); a step that starts halved (``Simulation.start_depth``) without throwing an attempt
    away names the strand that last did. Halvings for a failed contact solve name no strand."""
    asleep: int = 0
    """strands asleep after the step (:mod:`hairinv.dynamics.sleep`)"""


def _joined(first: StepReport, second: StepReport) -> StepReport:
    """Two consecutive substeps as one report: the second's contacts, the worse of their solves."""
    second.sweeps = max(first.sweeps, second.sweeps)
    second.relative_residual = max(first.relative_residual, second.relative_residual)
    if second.status == Status.CONVERGED:
        second.status = first.status
    second.local_failures = first.local_failures + second.local_failures
    second.substeps = first.substeps + second.substeps
    second.rejected = first.rejected + second.rejected
    second.depth = max(first.depth, second.depth)
    second.kept_turning = first.kept_turning + second.kept_turning
    second.turn = max(first.turn, second.turn)
    if second.turned < 0:
        second.turned = first.turned
    return second  # its last_depth is the step's


@dataclass
class Motion:
    """The body frame's motion at one instant, in body coordinates.

    Attributes
    ----------
    gravity : (3,) m/s^2, gravity as seen in the body frame
    accel : (3,) m/s^2, acceleration of the body frame's origin
    velocity : (3,) m/s, velocity of the body frame's origin (for the air drag)
    spin : (3,) rad/s, angular velocity of the body
    spin_rate : (3,) rad/s^2, angular acceleration of the body
    """

    gravity: np.ndarray
    accel: np.ndarray = field(default_factory=lambda: np.zeros(3))
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    spin: np.ndarray = field(default_factory=lambda: np.zeros(3))
    spin_rate: np.ndarray = field(default_factory=lambda: np.zeros(3))

    @classmethod
    def still(cls, gravity: np.ndarray) -> "Motion":
        return cls(np.asarray(gravity, dtype=np.float64))

    def packed(self) -> np.ndarray:
        """(5, 3): gravity, accel, velocity, spin, spin_rate, for the kernels."""
        return np.ascontiguousarray(np.stack([self.gravity, self.accel, self.velocity, self.spin, self.spin_rate]))

    def per_strand(self, n: int) -> np.ndarray:
        """(n, 5, 3): :meth:`packed` for each of ``n`` strands, as the kernels take it (a deforming body gives
        each strand its own, :class:`hairinv.dynamics.skin.SkinStep`)."""
        return np.ascontiguousarray(np.broadcast_to(self.packed(), (n, 5, 3)))


class PhaseClock:
    """Seconds spent in each phase of a simulation's steps, summed over every attempt, kept or thrown away.

    Attributes
    ----------
    seconds : dict, phase name -> s (in the order the phases first ran)
    thrown_away : float, s, in attempts thrown away for a halved step (also counted in their phases)
    attempts, kept : int, attempts made and kept
    """

    def __init__(self):
        self.seconds: dict[str, float] = {}
        self.thrown_away = 0.0
        self.attempts = 0
        self.kept = 0
        self._mark = time.perf_counter()

    def start(self) -> float:
        """Start an attempt; returns when."""
        self.attempts += 1
        self._mark = time.perf_counter()
        return self._mark

    def lap(self, phase: str) -> None:
        """The time since the last lap (or start) was spent in ``phase``."""
        now = time.perf_counter()
        self.seconds[phase] = self.seconds.get(phase, 0.0) + now - self._mark
        self._mark = now

    def total(self) -> float:
        return float(sum(self.seconds.values()))


# A halved attempt is kept, although an element turns further than max_turn, when it turns more than
# _HALVING_GAIN times as far as the attempt it replaces (a smooth motion turns half as far in half the
# time) and no further than _FUTILE_CAP times max_turn
#: m/s^2: the weight the velocity products are compared with in a scene without gravity (the solvers'
#: tolerances' weight, :func:`hairinv.gravity.tolerance_gravity`)
_WEIGHTLESS_GRAVITY = MaterialSettings().gravity
_HALVING_GAIN = 0.75
_FUTILE_CAP = 4.0
#: a contact close to the root may be unable to move along one direction (W_ii of rank 2): a compliance
#: of this fraction of its own W_ii (its trace over 3) picks the smallest force along it
COMPLIANCE = 1e-9
#: g h: a warm start is accepted by the contact law without the compliance (see Simulation._warm_start)
#: only while the compliance leaves a residual below this (or below the tolerance, if larger)
_COMPLIANCE_SLACK = 1e-6
#: a push out may move a contact's point by at most this times max_turn times its arc from the root, per
#: time_step (see push_limit)
_PUSH_TURN = 0.05


def push_limit(found: Contacts, settings: DynamicsSettings) -> np.ndarray:
    """(C,) m/s: the fastest each contact found closer than its thickness is pushed back out.

    ``push_speed``, and near a root less: a push bends the elements between the contact and the root, and
    one that turns them past ``max_turn`` in a step turns them as far in a halved step (the push is the
    gap over the step taken), so halving cannot help and the step cascades into halvings. Pushing a point
    at arc ``s`` by ``d`` bends a root element of length ``l`` by about ``2 d l / s^2``: on ruby short a
    contact 11.7 mm along an 18.5 mm root element, pushed at 0.05 m/s, turned it by 0.14 rad in 10 ms,
    and pushes passed on through hair-hair contacts near other strands' roots turn those. A push is
    therefore kept to ``_PUSH_TURN max_turn s`` per ``time_step`` (``s``: the contact's arc from the
    nearer root of its strands): 2.9 mm/s at 11.7 mm, 25 mm/s at 100 mm (docs/dynamics.md)."""
    s = np.where(found.strand[:, 1] == BODY, found.s[:, 0], np.minimum(found.s[:, 0], found.s[:, 1]))
    return np.minimum(settings.push_speed, _PUSH_TURN * settings.max_turn * s / settings.time_step)


def compliance(Wd: np.ndarray) -> np.ndarray:
    """(C,) the compliance of each contact, from its blocks ``W_ii`` (C, 3, 3): ``COMPLIANCE`` of its trace / 3."""
    return COMPLIANCE * np.trace(Wd, axis1=1, axis2=2) / 3.0


@jit
def strand_dynamics(root, frame0, q, v, q0, stiff, length, lam, rot, damping, air, h, motion, gx, gw, chol, v_free,
                    hess, mass, fresh, factored_h, held):
    """The free velocity of one strand and the Cholesky factor of its step matrix.

    ``motion`` is :meth:`Motion.packed`. Writes ``chol`` (row-major lower
    factor of ``Mt = M (1 + h air) + h damping K + h^2 (K + G)``, ``G`` the Hessian of the
    gravity potential, its negative part left out where ``K + G`` is not positive) and ``v_free`` (N, 3);
    returns the kinetic energy ``1/2 v^T M v`` (J) at the start of the step.

    With ``fresh``, the mass matrix ``M`` and ``G`` are taken at ``q`` and kept in ``mass`` and
    ``hess`` (``hess`` holds the part of ``G`` the step used); otherwise the kept ones serve, and
    so does the kept factor ``chol`` if it was made for the same step (``factored_h == h``).
    The velocity-product forces are left out while they are below 1e-9 of the strand's weight
    (bound: ``Omega^2 L`` against ``g``, ``Omega = sum |v_e| l_e`` the fastest frame's angular speed;
    without gravity, the weight under 9.81 m/s^2, as the solvers' tolerances).
    The moving frame's forces act on the centerline only (the cross-sections'
    own rotational inertia, ~1e-9 of it for hair, is not driven by the frame).
    """
    n = q.shape[0]
    nd = 3 * n
    refactor = fresh or factored_h != h
    M = np.empty((nd, nd))
    if fresh:
        strand_mass(root, frame0, q, length, gx, gw, lam, rot, M)
        for r in range(nd):
            for c in range(nd):
                mass[r * nd + c] = M[r, c]
    elif refactor:
        for r in range(nd):
            for c in range(nd):
                M[r, c] = mass[r * nd + c]
    vf = np.empty(nd)
    for c in range(nd):
        vf[c] = v[c // 3, c % 3]
    spin = 0.0
    total = 0.0
    for e in range(n):
        spin += np.sqrt(v[e, 0] ** 2 + v[e, 1] ** 2 + v[e, 2] ** 2) * length[e]
        total += length[e]
    g_norm = np.sqrt(motion[0, 0] ** 2 + motion[0, 1] ** 2 + motion[0, 2] ** 2)
    moving = spin * spin * total > 1e-9 * (g_norm if g_norm > 0.0 else _WEIGHTLESS_GRAVITY)
    force = np.zeros(nd)
    g = np.empty((n, 3))
    gravity_forces(root, frame0, q, length, lam, motion[0], g)
    for c in range(nd):
        force[c] = g[c // 3, c % 3] - stiff[c] * (q[c // 3, c % 3] - q0[c // 3, c % 3])
    # the velocity products and the moving frame's forces: -lam (a0 + A x x + W x (W x x) + 2 W x xdot)
    # and the drag of its own velocity
    extra = np.empty(nd)
    strand_velocity_forces(root, frame0, q, length, v, gx, gw, lam, rot, moving, motion, air, extra)
    for c in range(nd):
        force[c] += extra[c]
    # Mt = M (1 + h air) + h damping K + h^2 S and the right-hand side h F - (h D + h^2 S) v, with
    # S = K + G the stiffness of elasticity and gravity (G the Hessian of the gravity potential): gravity
    # enters implicitly, as twist, resisted by a nearly massless cross-section, cannot follow an explicit
    # gravity. Where S is not positive (a strand resting in an unstable equilibrium) its negative part
    # stays explicit.
    if refactor:
        S = np.empty((nd, nd))
        if fresh:
            gravity_hessian(root, frame0, q, length, lam, motion[0], S)
            for r in range(nd):
                for c in range(r + 1, nd):
                    sym = 0.5 * (S[r, c] + S[c, r])
                    S[r, c] = sym
                    S[c, r] = sym
            for r in range(nd):
                for c in range(nd):
                    S[r, c] += held[r * nd + c]
        else:
            for r in range(nd):
                for c in range(nd):
                    S[r, c] = hess[r * nd + c]
        for r in range(nd):
            S[r, r] += stiff[r]
        L = np.zeros((nd, nd))
        Mt = M * (1.0 + h * air)
        for r in range(nd):
            Mt[r, r] += h * damping * stiff[r]
            for c in range(nd):
                Mt[r, c] += h * h * S[r, c]
        if not cholesky(Mt, L):
            lam_s, V = np.linalg.eigh(S)
            for k in range(nd):
                lam_s[k] = max(lam_s[k], 0.0)
            S = (V * lam_s) @ V.T
            Mt = M * (1.0 + h * air)
            for r in range(nd):
                Mt[r, r] += h * damping * stiff[r]
                for c in range(nd):
                    Mt[r, c] += h * h * S[r, c]
            if not cholesky(Mt, L):
                for r in range(nd):
                    v_free[r // 3, r % 3] = np.nan
                return np.nan
        # keep the part of G this factor holds (its negative part left out if it was)
        for r in range(nd):
            for c in range(nd):
                hess[r * nd + c] = S[r, c] - (stiff[r] if r == c else 0.0)
        for r in range(nd):
            for c in range(nd):
                chol[r * nd + c] = L[r, c]
    # from here on the kept matrices serve (row-major in mass, hess and chol): M v, S v = (G + K) v
    Mv = np.zeros(nd)
    Sv = np.empty(nd)
    for r in range(nd):
        acc_m = 0.0
        acc_s = stiff[r] * vf[r]
        row = r * nd
        for c in range(nd):
            acc_m += mass[row + c] * vf[c]
            acc_s += hess[row + c] * vf[c]
        Mv[r] = acc_m
        Sv[r] = acc_s
    kinetic = 0.5 * np.dot(vf, Mv)
    rhs = np.empty(nd)
    for c in range(nd):
        rhs[c] = h * force[c] - h * damping * stiff[c] * vf[c] - h * h * Sv[c] - h * air * Mv[c]
    # v_free = v + Mt^-1 rhs
    y = np.empty(nd)
    for r in range(nd):
        acc_r = rhs[r]
        row = r * nd
        for c in range(r):
            acc_r -= chol[row + c] * y[c]
        y[r] = acc_r / chol[row + r]
    for r in range(nd - 1, -1, -1):
        acc_r = y[r]
        for c in range(r + 1, nd):
            acc_r -= chol[c * nd + r] * y[c]
        y[r] = acc_r / chol[r * nd + r]
    for c in range(nd):
        v_free[c // 3, c % 3] = vf[c] + y[c]
    return kinetic


# contacts per chunk of the per-step rows and factored rows: a few hundred already pay for a thread handoff
_CONTACT_CHUNK = 256


@jit
def _free_chunk(root, frame0, offsets, length, q, v, q0, stiff, lam, rot, damping, air, h, motion, gx, gw,
                chol, chol_ptr, v_free, kinetic, hess, mass, fresh, factored_h, held, lo, hi):
    """:func:`strand_dynamics` of the strands ``lo:hi``."""
    _free_listed(np.arange(lo, hi), root, frame0, offsets, length, q, v, q0, stiff, lam, rot, damping, air, h, motion,
                 gx, gw, chol, chol_ptr, v_free, kinetic, hess, mass, fresh, factored_h, held, 0, hi - lo)


@jit
def _free_listed(strands, root, frame0, offsets, length, q, v, q0, stiff, lam, rot, damping, air, h, motion, gx, gw,
                 chol, chol_ptr, v_free, kinetic, hess, mass, fresh, factored_h, held, lo, hi):
    """:func:`strand_dynamics` of the strands ``strands[lo:hi]``."""
    for w in range(lo, hi):
        k = strands[w]
        a = offsets[k]
        z = offsets[k + 1]
        kinetic[k] = strand_dynamics(root[k], frame0[k], q[a:z], v[a:z], q0[a:z], stiff[3 * a:3 * z], length[a:z],
                                     lam, rot, damping, air, h, motion[k], gx, gw,
                                     chol[chol_ptr[k]:chol_ptr[k + 1]], v_free[a:z],
                                     hess[chol_ptr[k]:chol_ptr[k + 1]], mass[chol_ptr[k]:chol_ptr[k + 1]],
                                     fresh[k], factored_h[k], held[chol_ptr[k]:chol_ptr[k + 1]])
        factored_h[k] = h



class Simulation:
    """A groom's time stepping, in the body's frame: the driver that steps a :class:`RodModel`'s
    :class:`RodState`, its contacts followed by a :class:`ContactTracker` and its step matrices kept in
    :class:`StepMatrices`.

    The body's motion is an input of each step (:meth:`step`): a rigid motion meets the model's body in
    its frame; a deforming body's step carries the body as it is at the step's start.

    Parameters
    ----------
    helices : Helices, the strands at the start (their ``omega`` is the initial ``q``), metres, body frame
    rest : (E, 3) float64, the rest shape ``q0``
    material : Material (its ``gravity`` is the world gravity in the body frame at rest)
    body : BodyMesh or None, in the body frame
    contacts : ContactSettings, how contacts are detected at every step (``body`` off: none with the body)
    settings : DynamicsSettings
    initial : Contacts, optional, the contacts of the starting shape and ``impulse`` their forces times
        the step, as warm start; they are matched to the first step's contacts element by element
    stiffening : (S,) float64, optional, per-strand factors of the bending and twist stiffness (the
        inverted model's ``/model/stiffening``); None: the material's own

    Attributes
    ----------
    model : RodModel, what the run does not change
    state : RodState, what each step changes
    tracker : ContactTracker, the contacts remembered from step to step
    matrices : StepMatrices, each strand's step matrix and its factor, kept while the strand hardly turns
    last : StepReport or None, the last step's
    start_depth : int, the halvings the next step starts with (see :meth:`step`)
    clock : PhaseClock, the seconds the steps so far spent in each of their phases
    sleepers : Sleepers, the strands at rest that are not stepped (:mod:`hairinv.dynamics.sleep`)
    """

    def __init__(self, helices: Helices, rest: np.ndarray, material: Material, body: BodyMesh | None,
                 contacts: ContactSettings, settings: DynamicsSettings, initial: Contacts | None = None,
                 initial_force: np.ndarray | None = None, stiffening: np.ndarray | None = None):
        validate_settings(settings)
        self.model = RodModel.build(helices, rest, material, body, contacts, settings, stiffening)
        self.state = RodState.start(self.model)
        self.matrices = StepMatrices(self.model)
        self.tracker = ContactTracker(self.model, self.state.q, initial, initial_force)
        self.last = None
        # halvings a step starts with (see step), and the strand that last made a step halve
        self.start_depth = 0
        self._halved_by = -1
        self.clock = PhaseClock()
        self.sleepers = Sleepers(self.model.n_strands, settings.sleep_speed)
        self._packed, self._carried = None, None  # the last attempt's motion per strand, and the frames it carried
        self._swept = False  # whether the last attempt's contacts needed sweeps (its warm start did not do)

    # ------------------------------------------------------------------ the parts, by their former names
    helices = property(lambda self: self.model.helices)
    rest = property(lambda self: self.model.rest)
    material = property(lambda self: self.model.material)
    contact_settings = property(lambda self: self.model.contact_settings)
    stiff = property(lambda self: self.model.stiff)
    lam = property(lambda self: self.model.lam)
    rot = property(lambda self: self.model.rot)
    gx = property(lambda self: self.model.gx)
    gw = property(lambda self: self.model.gw)
    chol_ptr = property(lambda self: self.model.chol_ptr)
    strand_weight = property(lambda self: self.model.strand_weight)
    velocity_scale = property(lambda self: self.model.velocity_scale)
    chol = property(lambda self: self.matrices.chol)
    hess = property(lambda self: self.matrices.hess)
    mass = property(lambda self: self.matrices.mass)
    factored_h = property(lambda self: self.matrices.factored_h)
    kinetic = property(lambda self: self.state.kinetic)
    contacts = property(lambda self: self.tracker.shown())
    _last_found = property(lambda self: self.tracker.last_found)
    _redetected = property(lambda self: self.tracker.redetected)
    _own = property(lambda self: self.tracker.own)
    _margin = property(lambda self: self.tracker.margin)

    @property
    def settings(self) -> DynamicsSettings:
        return self.model.settings

    @settings.setter
    def settings(self, value: DynamicsSettings) -> None:
        self.model.settings = value

    @property
    def body(self) -> BodyMesh | None:
        """The body the last step's contacts met (before any step, the model's)."""
        return self.tracker.body

    @property
    def q(self) -> np.ndarray:
        return self.state.q

    @q.setter
    def q(self, value: np.ndarray) -> None:
        self.state.q = value

    @property
    def v(self) -> np.ndarray:
        return self.state.v

    @v.setter
    def v(self, value: np.ndarray) -> None:
        self.state.v = value

    @property
    def time(self) -> float:
        return self.state.time

    @time.setter
    def time(self, value: float) -> None:
        self.state.time = value

    @property
    def R(self) -> np.ndarray:
        return self.state.R

    @property
    def c(self) -> np.ndarray:
        return self.state.c

    def current(self) -> Helices:
        """The strands at the current ``q``: in the body's frame, or, under a deforming body, placed by their
        own frames."""
        return self.state.current(self.model)

    def _remember(self, found: Contacts, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return self.tracker.remember(found, h)

    def _elements_of(self, contacts: Contacts) -> np.ndarray:
        return self.tracker.elements_of(contacts)

    def _contact_hessians(self, fresh: np.ndarray) -> np.ndarray:
        """The contact forces' share of the step's stiffness for the strands whose Hessians are taken
        afresh (``fresh``), laid out like ``hess``: ``-sum f_i . d^2 x_i / dq^2`` of the remembered
        forces (the last step's impulses over its length) at the points they act on.

        The contact force enters the step as ``H(q)^T r``; as the strand turns about a point that holds
        it, the force does work at second order, which is what holds a strand bent around a support or
        hanging from it. Left explicit, that stiffness sets a step limit: on a groom draped over a
        mannequin at rest, a strand pressed near its root (a few hundred of its own weights) grows fivefold
        per 10 ms step from round-off under unchanged forces, and not at 2.5 ms. It is taken implicitly,
        like gravity's (with it, its negative part stays explicit where the total is not positive).
        """
        model, state, tracker = self.model, self.state, self.tracker
        held = np.zeros_like(self.matrices.hess)
        if not len(tracker.keys) or not fresh.any():
            return held
        force = tracker.impulse / tracker.impulse_step
        loaded = np.flatnonzero(np.any(force != 0.0, axis=1))
        if not len(loaded):
            return held
        # each contact side as a load on its strand: +f on the first, -f on the second
        hair = tracker.pair[loaded, 1] >= 0
        strand = np.concatenate([tracker.pair[loaded, 0], tracker.pair[loaded[hair], 1]])
        arc = np.concatenate([tracker.arc[loaded, 0], tracker.arc[loaded[hair], 1]])
        load = np.concatenate([force[loaded], -force[loaded[hair]]])
        keep = fresh[strand]
        strand, arc, load = strand[keep], arc[keep], load[keep]
        order = np.lexsort((arc, strand))
        strand, arc, load = strand[order], arc[order], load[order]
        bounds = np.searchsorted(strand, np.arange(model.n_strands + 1))
        # the remembered forces are in the frame the strands were placed in (the body's, or the groom's)
        h = state.posed(model, state.R, state.c) if state.placed else model.helices
        loaded_strands = np.flatnonzero(np.diff(bounds)).astype(np.int64)
        arc, load = np.ascontiguousarray(arc), np.ascontiguousarray(load)
        run_chunks(lambda lo, hi: _load_hessians(loaded_strands, lo, hi, bounds, h.root, h.frame0, state.q, h.length,
                                                 h.offsets, arc, load, model.chol_ptr, held),
                   len(loaded_strands), 64)
        return held

    # ------------------------------------------------------------------ stepping
    def step(self, motion, h: float | None = None, t: float | None = None) -> StepReport:
        """Advance by ``h`` (default: the settings' time step) under ``motion``.

        ``motion`` is a :class:`Motion`, the body frame's, for the whole groom; or a
        :class:`~hairinv.dynamics.skin.SkinnedBody`, a deforming body that moves each root with its own
        triangle, asked for each (sub)step from ``t`` (default: where the last step ended).

        The step is linearised at its start, so it is split in halves (up to
        ``dynamics.max_substeps`` times) while any element would turn by more
        than ``dynamics.max_turn`` within it: an attempt that turns ``k`` times
        too far is replaced by ``2^ceil(log2 k)`` substeps at once (a motion
        turns about half as far in half the time). An attempt that turns too far is
        thrown away, and costs as much as a kept one, so a step that needed more
        halvings than it started with makes the next one start with as many
        as its own last substep needed (``start_depth``); a step that needed no
        more makes the next one try one halving fewer. Halvings are needed
        over stretches of time, so this throws fewer attempts away, and it
        halves fewer whole steps than starting from the step's deepest
        substep would.

        Halving helps only a motion that turns less in less time. A push
        asked within the step (a contact found inside the body is moved out
        by its depth over the step, whatever its length) turns as far in
        half the time, or further, and so can a contact solve that ends
        poorly. A halved attempt that turns more than ``_HALVING_GAIN`` times
        as far as the attempt it replaces (and at most ``_FUTILE_CAP`` times
        ``max_turn``) is therefore kept, and counted in ``kept_turning``.
        """
        started = time.perf_counter()
        settings = self.model.settings
        h = float(settings.time_step if h is None else h)
        if t is not None:
            self.time = float(t)
        start = min(self.start_depth, settings.max_substeps)
        report = self._step(motion, h / 2 ** start, start)
        for _ in range(2 ** start - 1):
            report = _joined(report, self._step(motion, h / 2 ** start, start))
        if report.turned >= 0:
            self._halved_by = report.turned
        elif start > 0:
            report.turned = self._halved_by  # halved from the start for what an earlier step's strand needed
        if report.depth > start:
            self.start_depth = report.last_depth
        elif start > 0:
            self.start_depth = start - 1
        self.start_depth = min(self.start_depth, settings.max_substeps)
        self._settle()
        report.asleep = int(np.count_nonzero(self.sleepers.asleep))
        if self.tracker.parked is not None:  # the sleeping strands' contacts hold as they were
            shown = self.tracker.shown()
            report.contacts, report.n_body = shown.n_contacts, shown.n_body
        report.seconds = time.perf_counter() - started
        self.last = report
        return report


    def _step(self, motion, h: float, depth: int, parent_turn: float = np.inf, parent_depth: int = -1) -> StepReport:
        model, state, tracker, matrices = self.model, self.state, self.tracker, self.matrices
        clock = self.clock
        started = clock.start()
        settings = model.settings
        helices = model.helices
        offsets = helices.offsets
        v_free = np.zeros_like(state.q)
        skin = None
        body = model.body
        if isinstance(motion, Motion):
            packed = motion.per_strand(helices.n_strands)
        else:
            skin = motion.step(state.time, h)
            packed = skin.motion
            if skin.body is not None:
                body = skin.body
        tracker.begin(skin, body)
        sleepers = self.sleepers
        self._packed, self._carried = packed, (carried(skin) if skin is not None else None)
        if sleepers.any():
            self._wake(sleepers.stirred(packed, skin, self._carried))
        clock.lap("body")
        fresh = matrices.stale_strands(model, state.q, packed[:, 0], ~sleepers.asleep if sleepers.any() else None)

        def free(strands: np.ndarray) -> None:
            run_chunks(lambda lo, hi: _free_listed(
                strands, helices.root, helices.frame0, offsets, helices.length, state.q, state.v, model.rest,
                model.stiff, model.lam, model.rot, settings.damping, settings.air_damping, h, packed, model.gx,
                model.gw, matrices.chol, model.chol_ptr, v_free, state.kinetic, matrices.hess, matrices.mass, fresh,
                matrices.factored_h, held, lo, hi), len(strands), balanced(len(strands), 64))
            if not np.all(np.isfinite(v_free)):
                raise FloatingPointError("the free velocity is not finite")

        held = self._contact_hessians(fresh)
        clock.lap("matrices")
        free(np.flatnonzero(~sleepers.asleep))
        clock.lap("free motion")
        rules = model.contact_settings
        tracker.own = tracker.own_sweep(state, h) if (body is not None and rules.body) or rules.hair_hair else \
            np.zeros(helices.n_strands)
        found = tracker.detect(state)
        if sleepers.any():
            # a strand awake that touches a sleeping one wakes its island, for this very step
            while True:
                hit = self._hit(found)
                if not hit.any():
                    break
                free(np.flatnonzero(self._wake(hit)))
            found = tracker.awake_only(found, sleepers.asleep)
        clock.lap("detection")
        found, anchors, keys = tracker.persist(state, found, h)
        keys, thickness, impulse = tracker.remember(found, h, keys)
        clock.lap("persistence")
        report = StepReport(found.n_contacts, found.n_body, 0, 0.0, Status.CONVERGED, 0, 0.0, depth=depth, last_depth=depth)
        v_new = v_free
        reached = ""  # what the contact solve reached, for the message of a step that fails at every length
        if found.n_contacts:
            contact_run = lambda work, n: run_chunks(work, n, _CONTACT_CHUNK)  # noqa: E731
            rows = contact_rows(state.current(model), found, run=contact_run)
            factor = lambda: factored_rows(rows, found.strand, offsets, matrices.chol, model.chol_ptr,  # noqa: E731
                                           run=contact_run)
            if self._swept:
                # the last attempt's warm start did not do (a moving groom): the factored rows will be needed, and
                # give the blocks (the same, bit for bit) without a second forward substitution
                z_rows = factor()
                Wd = delassus_blocks(z_rows, np.zeros(found.n_contacts))
            else:
                z_rows = None
                Wd = factored_blocks(rows, found.strand, offsets, matrices.chol, model.chol_ptr, run=contact_run)
            gap = found.gap if found.gap is not None else np.zeros(found.n_contacts)
            push = np.zeros((found.n_contacts, 3))
            if skin is not None:
                # under a deforming body, a contact on a strand's first element moves with the root's frame: the
                # skin's own motion there relative to that frame (a neck twisting under the roots beside it), in
                # this step or the last, is not asked of the strand, which could meet it only by swinging its
                # whole length about the root
                rooted = tracker.rooted(found)
                thickness[rooted] = np.minimum(thickness[rooted], gap[rooted])
            push[:, 0] = np.maximum((gap - thickness) / h, -push_limit(found, settings))
            if tracker.moving:  # and how the frames carry each contact's sides against each other
                push[~rooted] += tracker.drift(state, found.subset(~rooted))
            b = rows.matvec(v_free.ravel()) + reachable(Wd, push)
            gamma = compliance(Wd)
            Wd[:, [0, 1, 2], [0, 1, 2]] += gamma[:, None]
            clock.lap("contact rows")
            # the last step's impulses may already meet the tolerance (a groom still at its equilibrium):
            # then the factored rows, the step's largest arrays, are never built
            result, correction = self._warm_start(rows, gamma, b, found.mu, Wd, impulse, h)
            clock.lap("warm start")
            self._swept = result is None
            if result is None:
                if z_rows is None:
                    z_rows = factor()
                problem = coulomb_problem(z_rows, gamma, b, found.mu, found.strand, helices.n_strands,
                                          model.velocity_scale * h, s=found.s,
                                          part_of=split_strands(helices.root, found.strand))
                clock.lap("contact rows")
                coulomb = CoulombSettings(settings.tolerance, settings.max_sweeps, stall_rounds=settings.stall_rounds)
                result = solve_coulomb(problem, coulomb, impulse, Wd=Wd)
                clock.lap("contact solve")
                correction = self._mass_solve(z_rows.rmatvec(result.r), factored=True)
                clock.lap("contact rows")
            del z_rows
            failed = result.status == Status.NUMERICAL_ERROR
            reached = (f": {result.status} after {result.sweeps} sweeps, relative residual "
                       f"{result.relative_residual:.3g}, {found.n_contacts} contacts")
            if not failed:
                v_new = v_free + correction.reshape(-1, 3)
                impulse = result.r
                report = StepReport(found.n_contacts, found.n_body, result.sweeps, result.relative_residual,
                                    result.status, result.local_failures, 0.0, depth=depth, last_depth=depth)
        else:
            failed = False
        turns = h * np.linalg.norm(v_new, axis=1) * helices.length
        turn = float(np.max(turns)) if helices.n_elements else 0.0
        if not np.isfinite(turn):
            failed = True
        if failed and depth >= settings.max_substeps:
            what = "the contact solve failed" if reached and result.status == Status.NUMERICAL_ERROR else "the velocity is not finite"
            raise FloatingPointError(f"{what} at a step of {h:.3g} s, halved {depth} times{reached}")
        # a halved attempt that turns nearly as far as the attempt it replaces shows that halving does
        # not slow the motion down (a push asked within the step, whatever its length): it is kept
        futile = not failed and turn <= _FUTILE_CAP * settings.max_turn and turn > _HALVING_GAIN * parent_turn
        if (failed or turn > settings.max_turn) and not futile and depth < settings.max_substeps:
            # nothing is kept of this attempt: shorter substeps instead
            clock.lap("update")
            clock.thrown_away += time.perf_counter() - started
            replaced = np.inf if failed else turn
            tracker.skin = None
            # as many halvings at once as the turn asks for (each halving halves it, for a motion that
            # turns less in less time): halving one level at a time throws an attempt away at each
            levels = 1 if failed else max(1, int(np.ceil(np.log2(turn / settings.max_turn))))
            levels = min(levels, settings.max_substeps - depth)
            joined = None
            for _ in range(2 ** levels):
                part = self._step(motion, h / 2 ** levels, depth + levels, replaced, depth)
                joined = part if joined is None else _joined(joined, part)
            joined.rejected += 1
            if joined.turned < 0 and not failed:
                joined.turned = int(np.searchsorted(offsets, int(np.argmax(turns)), side="right") - 1)
            return joined
        report.turn = turn
        if futile and turn > settings.max_turn:
            report.kept_turning = 1
            report.last_depth = parent_depth  # the attempt it replaced would have done as well
        tracker.keep(found, keys, thickness, impulse, anchors, h)
        state.v = v_new
        state.q = state.q + h * v_new
        state.time += h
        if skin is not None:
            state.R, state.c = skin.R, skin.c
            state.placed = True
        tracker.skin = None
        clock.lap("update")
        clock.kept += 1
        return report

    # ------------------------------------------------------------------ sleeping
    def _hit(self, found: Contacts) -> np.ndarray:
        """(S,) bool: the sleeping strands a contact of ``found`` joins to an awake strand."""
        asleep = self.sleepers.asleep
        pair = found.strand
        first = asleep[pair[:, 0]]
        second = np.where(pair[:, 1] >= 0, asleep[np.maximum(pair[:, 1], 0)], first)
        cross = first != second
        hit = np.zeros_like(asleep)
        hit[pair[cross & first, 0]] = True
        hit[pair[cross & second, 1]] = True
        return hit

    def _wake(self, which: np.ndarray) -> np.ndarray:
        """Wake the islands of the sleeping strands ``which`` (S,) bool; returns (S,) bool, the strands woken."""
        woken = self.sleepers.wake(which)
        if woken.any():
            self.tracker.unpark(woken)
        return woken

    def _settle(self) -> None:
        """After a kept step: count the strands at rest, and put to sleep the islands at rest long enough."""
        sleepers, model, state = self.sleepers, self.model, self.state
        if sleepers.speed <= 0 or not model.helices.n_elements:
            return
        hel = model.helices
        speeds = model.swing(state.v)
        moved = self._carried if self._carried is not None else np.zeros(hel.n_strands, dtype=np.bool_)
        sleepers.settle(speeds, self._packed, moved)
        island = islands(hel.n_strands, self.tracker.pair)
        ready = sleepers.ready(island)
        if not ready.any():
            return
        mask = np.repeat(ready, np.diff(hel.offsets))
        state.v[mask] = 0.0
        state.kinetic[ready] = 0.0
        reach = model.contact_settings.body_distance if model.contact_settings.body else 0.0
        sleepers.sleep(ready, island, state.current(model), reach)
        self.tracker.park(sleepers.asleep)

    def _mass_solve(self, y: np.ndarray, factored: bool = False) -> np.ndarray:
        """``M^-1 y`` strand by strand through the strands' Cholesky factors ``M = L L^T`` (``L^-T y``
        only, for ``y`` given as ``L^-1`` of something: ``factored``)."""
        return self.matrices.mass_solve(self.model, y, factored)

    def _warm_start(self, rows, gamma, b, mu, Wd, impulse, h: float):
        """``(result, M^-1 H^T r)`` for the warm start ``impulse`` if it meets the step's tolerance (the
        De Saxce residual of ``solve_coulomb``, from ``H`` and the strands' factors instead of the
        factored rows), else ``(None, None)``.

        The compliance ``gamma`` moves each contact's velocity by ``gamma r``. A groom's contact forces
        are in part statically indeterminate (forces that cancel, ``H^T r = 0``, along directions the
        contacts cannot move), which the sweeps shrink only by about ``gamma / rho`` a sweep; at the
        exact forces of a still groom the compliance alone then leaves a residual of about 1e-9 of the
        loaded contacts' velocities that no sweep removes in practice (40 curly guides rest at 1.1e-8
        of ``g h``, above the final preset's 1e-8, and every step spent its 1,000 sweeps). So the warm
        start is also accepted when it meets the contact law itself, without the compliance, to the
        tolerance, as long as the compliance's residual stays under ``_COMPLIANCE_SLACK`` of ``g h``
        (the forces that cancel stay bounded). The residual reported is then the smaller of the two;
        after sweeps it is always the compliant problem's.
        """
        f = self._mass_solve(rows.rmatvec(impulse))
        per = np.empty(rows.n_contacts)
        # the De Saxce residual in velocity units, f = M^-1 H^T r from the strands' factors
        residual = float(natural_residuals(rows.ptr, rows.cols, rows.vals, f, gamma, Wd, b, mu, impulse,
                                           COULOMB.desaxce, True, per))
        scale = self.model.velocity_scale * h
        tolerance = self.model.settings.tolerance * scale
        if tolerance < residual <= max(tolerance, _COMPLIANCE_SLACK * scale):
            residual = min(residual, float(natural_residuals(rows.ptr, rows.cols, rows.vals, f,
                                                             np.zeros_like(gamma), Wd, b, mu, impulse,
                                                             COULOMB.desaxce, True, per)))
        if not residual <= tolerance:  # (NaN included: solve_coulomb reports it)
            return None, None
        return SolverResult(impulse.copy(), Status.CONVERGED, 0, residual, residual / scale, [(0, residual)], 0.0), f

    # ------------------------------------------------------------------ measures
    def kinetic_energy(self) -> float:
        """J, of the motion relative to the body at the start of the last step (``1/2 v^T M v``)."""
        return float(self.state.kinetic.sum())

    def elastic_energy(self) -> float:
        """J, ``1/2 (q - q0)^T K (q - q0)``."""
        d = (self.state.q - self.model.rest).ravel()
        return float(0.5 * np.dot(d, self.model.stiff * d))
