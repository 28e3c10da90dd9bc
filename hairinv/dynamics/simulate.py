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

import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np

from .._dense import cholesky
from .._jit import jit
from .._parallel import run_chunks
from ..config import ContactSettings, DynamicsSettings, MaterialSettings
from ..contacts.body import REFINE_ITERATIONS, BodyMesh
from ..contacts.detect import COINCIDENT, contact_frames, detect_contacts
from ..rod.helix import chain, strand_points
from ..errors import InputError
from ..gravity import tolerance_gravity
from ..model import Contacts, Helices, Material, stiffness
from ..rod.statics import gravity_forces, gravity_hessian, point_load_hessian
from ..solver.gauss_seidel import SolverResult, natural_residuals, split_strands
from ..solver.problem import COULOMB
from ..solver.status import Status
from ..contacts.rows import contact_rows
from .contact import (CoulombSettings, back_substitute, contact_keys, coulomb_problem, factored_blocks, factored_rows,
                      forward_substitute, reachable, solve_coulomb)
from .inertia import strand_mass, strand_velocity_forces

__all__ = ["Motion", "Simulation", "StepReport", "strand_dynamics", "validate_settings"]


def validate_settings(settings: DynamicsSettings) -> None:
    """Raise InputError (naming the setting) for a value the integrator cannot use."""
    for name in ("time_step", "max_turn"):
        if not getattr(settings, name) > 0:
            raise InputError(f"dynamics.{name} must be > 0, got {getattr(settings, name)}")
    for name in ("damping", "air_damping", "body_thickness", "hair_thickness", "push_speed", "tolerance",
                 "inertia_radius"):
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


# m: a remembered contact point stays while it is at most this much farther from the surface than
# the point detection finds on the same element
_PERSIST_SLACK = 1e-5
# golden-section steps placing a body contact along its element once the groom moves: 3.1e-3 of the bracket
# between two samples (10-30 um on the samples' elements), where the distance found is off by the square
# of that over twice the radius of curvature (below 1e-8 m); the first detection (the model's own contacts)
# keeps the detector's default
_MOVING_REFINE = 12
# contacts per chunk of the per-step rows and factored rows: a few hundred already pay for a thread handoff
_CONTACT_CHUNK = 256


def points_on(helices: Helices, omega: np.ndarray, strand: np.ndarray, s: np.ndarray) -> np.ndarray:
    """:func:`hairinv.rod.helix.strand_points` of ``helices`` with the curvatures ``omega``, (n, 3)."""
    return strand_points(helices.root, helices.frame0, helices.offsets, omega, helices.length, strand, s)


@jit
def _strand_moves(root, frame0, offsets, q_from, q_to, length, out):
    """Per strand, a bound on how far any of its centerline points has moved from ``q_from`` to ``q_to``, m.

    A point at ``sigma`` along element ``e`` is ``x_e + F_e^T P(sigma; omega_e)``, and ``P`` moves
    by at most ``sigma^2 |d omega_e| / 2`` (its tangent turns by at most ``sigma |d omega_e|``), so
    it moves by at most ``|dx_e| + ||dF_e||_F l_e + l_e^2 |d omega_e| / 2``.
    """
    for k in range(offsets.shape[0] - 1):
        worst = 0.0
        a = offsets[k]
        z = offsets[k + 1]
        n = z - a
        xs0 = np.empty((n + 1, 3))
        Fs0 = np.empty((n + 1, 3, 3))
        xs1 = np.empty((n + 1, 3))
        Fs1 = np.empty((n + 1, 3, 3))
        chain(root[k], frame0[k], q_from[a:z], length[a:z], xs0, Fs0)
        chain(root[k], frame0[k], q_to[a:z], length[a:z], xs1, Fs1)
        for e in range(n + 1):
            dx = 0.0
            for i in range(3):
                dx += (xs1[e, i] - xs0[e, i]) ** 2
            bound = np.sqrt(dx)
            if e < n:
                dF = 0.0
                dw = 0.0
                for i in range(3):
                    dw += (q_to[a + e, i] - q_from[a + e, i]) ** 2
                    for j in range(3):
                        dF += (Fs1[e, i, j] - Fs0[e, i, j]) ** 2
                bound += np.sqrt(dF) * length[a + e] + 0.5 * length[a + e] ** 2 * np.sqrt(dw)
            worst = max(worst, bound)
        out[k] = worst


@jit
def _free_chunk(root, frame0, offsets, length, q, v, q0, stiff, lam, rot, damping, air, h, motion, gx, gw,
                chol, chol_ptr, v_free, kinetic, hess, mass, fresh, factored_h, held, lo, hi):
    for k in range(lo, hi):
        a = offsets[k]
        z = offsets[k + 1]
        kinetic[k] = strand_dynamics(root[k], frame0[k], q[a:z], v[a:z], q0[a:z], stiff[3 * a:3 * z], length[a:z],
                                     lam, rot, damping, air, h, motion[k], gx, gw,
                                     chol[chol_ptr[k]:chol_ptr[k + 1]], v_free[a:z],
                                     hess[chol_ptr[k]:chol_ptr[k + 1]], mass[chol_ptr[k]:chol_ptr[k + 1]],
                                     fresh[k], factored_h[k], held[chol_ptr[k]:chol_ptr[k + 1]])
        factored_h[k] = h


class Simulation:
    """A groom's state and its time stepping, in the body's frame.

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
    """

    def __init__(self, helices: Helices, rest: np.ndarray, material: Material, body: BodyMesh | None,
                 contacts: ContactSettings, settings: DynamicsSettings, initial: Contacts | None = None,
                 initial_force: np.ndarray | None = None, stiffening: np.ndarray | None = None):
        validate_settings(settings)
        self.helices = helices
        self.q = np.ascontiguousarray(helices.omega, dtype=np.float64).copy()
        self.v = np.zeros_like(self.q)
        self.rest = np.ascontiguousarray(rest, dtype=np.float64)
        self.material = material
        self.body = body
        self.contact_settings = contacts
        self.settings = settings
        self.stiff = stiffness(helices, material, stiffening)
        self.lam = material.linear_density
        # the cross-sections' rotational inertia, rot = lam r^2 / 4 with r the inertia radius (>= the hair's own)
        self.rot = self.lam * max(settings.inertia_radius, material.radius) ** 2 / 4.0
        nodes, weights = np.polynomial.legendre.leggauss(settings.quadrature)
        self.gx = 0.5 * (nodes + 1.0)
        self.gw = 0.5 * weights
        sizes = (3 * np.diff(helices.offsets)) ** 2
        self.chol_ptr = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        self.chol = np.zeros(int(self.chol_ptr[-1]))
        # gravity's Hessian and the mass matrix per strand, laid out like chol, the shape and gravity they
        # were taken at, and the step each strand's factor was made for
        self.hess = np.zeros(int(self.chol_ptr[-1]))
        self.mass = np.zeros(int(self.chol_ptr[-1]))
        self.factored_h = np.full(helices.n_strands, -1.0)
        self._hess_q = None
        self._hess_gravity = None
        self.kinetic = np.zeros(helices.n_strands)
        weight = material.linear_density * np.linalg.norm(material.gravity)
        lengths = np.add.reduceat(helices.length, helices.offsets[:-1]) if helices.n_elements else np.zeros(0)
        self.strand_weight = float(weight * lengths.max()) if len(lengths) else 1.0
        # contact velocities are measured against the speed gravity adds in one step, g h (in a scene without
        # gravity, that of the default 9.81 m/s^2: a tolerance relative to zero could never be met)
        self.velocity_scale = tolerance_gravity(material)
        # new contacts come from the fixed distances: the hair layer and the wisps describe the input groom
        # (the model's own contacts of those rules persist at their distances, see _persist)
        self._detect_settings = dataclasses.replace(contacts, layer=False, wisp=False)
        self._up = -np.asarray(material.gravity, dtype=np.float64) / max(np.linalg.norm(material.gravity), 1e-300)
        # contact memory: key -> (thickness, impulse in world coordinates: frames may turn between steps)
        self._keys = np.zeros(0, dtype=np.int64)
        self._arc = np.zeros((0, 2))  # where each remembered contact sits on its strands
        self._pair = np.zeros((0, 2), dtype=np.int64)  # its strands
        self._elements = np.zeros((0, 2), dtype=np.int64)  # its elements
        # where each remembered body contact's gap was last measured exactly: point, normal, gap
        self._anchor = (np.full((0, 3), np.nan), np.zeros((0, 3)), np.zeros(0))
        self._mu = np.zeros(0)
        self._thickness = np.zeros(0)
        self._impulse = np.zeros((0, 3))
        self._impulse_step = 1.0  # s: the remembered impulses are forces times this (forces at the start)
        self._first = True
        self._initial = initial if initial is not None and initial.n_contacts else None
        self._initial_impulse = None
        if self._initial is not None:
            force = np.zeros((initial.n_contacts, 3)) if initial_force is None else initial_force
            self._initial_impulse = np.asarray(force, dtype=np.float64)
            keys = self._keys_of(initial)
            order = np.argsort(keys, kind="stable")
            self._keys = keys[order]
            gap = initial.gap if initial.gap is not None else np.zeros(initial.n_contacts)
            self._thickness = gap[order]
            self._arc = initial.s[order]
            self._pair = initial.strand[order]
            self._mu = initial.mu[order]
            self._elements = self._elements_of(initial)[order]
            self._anchor = self._anchors_of(initial, order)
            self._impulse = np.einsum("cji,cj->ci", initial.frame, self._initial_impulse)[order]
        self.contacts = initial if initial is not None else Contacts.empty()
        self._last_found = None
        # which of this step's detected contacts come from an earlier shape (a detection reused, in
        # whole or for the strands that have hardly moved)
        self._stale = np.zeros(0, dtype=np.bool_)
        self._redetected = 0  # strands detected afresh at this step
        used = ([contacts.hair_distance] if contacts.hair_hair else []) + ([contacts.body_distance]
                                                                         if contacts.body and body is not None else [])
        self._detect_distance = min(used) if used else np.inf
        self._q_detected = None
        if self._initial is not None:
            # the starting contacts are those the model was inverted with, on this very shape: they are the
            # first detection, as stored (detecting them again could differ in round-off, or by the version
            # of the rules), provided their elements name them one by one
            elements = self._elements_of(self._initial)
            keys = self._keys_of(dataclasses.replace(self._initial, element=elements))
            if len(np.unique(keys)) == len(keys):
                self._initial = dataclasses.replace(self._initial, element=elements)
                self._last_found = self._initial
                self._q_detected = self.q.copy()
                self._stale = np.zeros(self._initial.n_contacts, dtype=np.bool_)
        self._strand_length = (np.add.reduceat(helices.length, helices.offsets[:-1]) if helices.n_elements
                               else np.zeros(helices.n_strands))
        self.last = None
        # each strand's rigid motion from its bind pose, x = R x_bind + c: the identity until a deforming body
        # moves the roots (a SkinnedBody given to step); a rigid scene keeps it, the groom in the body's frame
        self.R = np.broadcast_to(np.eye(3), (helices.n_strands, 3, 3)).copy()
        self.c = np.zeros((helices.n_strands, 3))
        self.time = 0.0  # s, of the state
        self._skin = None  # the SkinStep of the step being taken, None for a rigid one
        self._margin = (0.0, 0.0)  # m, how much closer than detected the body and strands come within it
        # m, per strand: how far its own motion may carry its points in its frame over the step being taken,
        # where that reaches beyond what the detection rules leave room for (else 0; see _own_sweep)
        self._own = np.zeros(helices.n_strands)
        self._tips = strand_points(helices.root, helices.frame0, helices.offsets, self.q, helices.length,
                                   np.arange(helices.n_strands, dtype=np.int64), self._strand_length.copy()) \
            if helices.n_strands else np.zeros((0, 3))
        self._placed = False  # whether any strand has left its bind pose
        # halvings a step starts with (see step), and the strand that last made a step halve
        self.start_depth = 0
        self._halved_by = -1

    # ------------------------------------------------------------------ geometry
    def current(self) -> Helices:
        """The strands at the current ``q``: in the body's frame, or, under a deforming body, placed by their
        own frames."""
        h = self.helices
        if self._placed:
            return self._posed(self.R, self.c)
        return Helices(h.root, h.frame0, h.offsets, h.length, self.q, h.fit_error)

    def _posed(self, R: np.ndarray, c: np.ndarray) -> Helices:
        h = self.helices
        return Helices(np.einsum("nij,nj->ni", R, h.root) + c, np.einsum("nij,nkj->nik", h.frame0, R), h.offsets,
                       h.length, self.q, h.fit_error)

    def _moving(self) -> bool:
        """Whether the body moves the strands' frames or itself over the step being taken."""
        return self._skin is not None and self._skin.moves

    def _detect(self) -> Contacts:
        """This step's contacts: detected afresh once any strand point may have moved by more than a
        quarter of the smallest contact distance in use (the hair-hair one, or the body's without
        hair-hair contact) since the last detection (bounds: the elements' turns times the strand's
        length, cheap, then :func:`_strand_moves`, tighter); until then the last detection is reused,
        and the remembered contacts are measured again where they are (see :meth:`_persist`).

        A strand whose own motion over the step (see :meth:`_own_sweep`) reaches that far is detected
        again too, and body contacts are searched as far as that motion goes: a strand swinging into the
        body faster than the contact distance a step (hair down a back when the character stops short)
        meets it instead of passing into it.

        Without hair-hair contact the strands are detected one by one: only those that may have moved
        by that much since their own last detection are detected again (the body does not move in its
        frame), and the others keep theirs. In the ``motion`` scene about half the strands of the
        300-strand groom are detected at a step.
        """
        h = self.helices
        S = h.n_strands
        moving = self._moving()
        swings = self._own > 0.0
        if self._last_found is not None and h.n_elements and not moving:
            reach = 0.25 * self._detect_distance
            # first the cheap bound: every element's turn |d omega_e| l_e swings the whole strand
            turn = np.linalg.norm(self.q - self._q_detected, axis=1) * h.length
            redo = np.add.reduceat(turn, h.offsets[:-1]) * self._strand_length >= reach
            if redo.any():
                moves = np.zeros(S)
                _strand_moves(h.root, h.frame0, h.offsets, self._q_detected, self.q, h.length, moves)
                if self.contact_settings.hair_hair:
                    # a pair of strands: the whole groom is detected again, or not at all
                    redo[:] = moves.max() >= reach
                else:
                    redo &= moves >= reach  # either bound will do, strand by strand
            redo |= swings.any() if self.contact_settings.hair_hair else swings
            if not redo.any():
                self._stale = np.ones(self._last_found.n_contacts, dtype=np.bool_)
                self._redetected = 0
                return self._last_found
            if not self.contact_settings.hair_hair and not redo.all():
                return self._detect_strands(np.flatnonzero(redo))
        # the first detection is the model's own, on the starting shape: the same rules as the contacts it was
        # inverted with (the hair layer and wisps included), so the first step meets them again
        # (and so is a first step the body moves: the model's contacts, remembered, are measured again)
        first = self._last_found is None or (self._first and moving)
        rules = self.contact_settings if first and self._initial is not None else self._detect_settings
        own = float(self._own.max(initial=0.0))
        if moving or own:  # what comes within reach during the step: the body's and the frames' sweep, and the
            # strands' own
            rules = dataclasses.replace(rules, body_distance=rules.body_distance + self._margin[0] + own,
                                        hair_distance=rules.hair_distance + self._margin[1])
        found, _ = detect_contacts(self.current(), self.body, rules, up=self._up,
                                   refine_iterations=REFINE_ITERATIONS if first else _MOVING_REFINE)
        if own and rules.layer is False:  # (contacts the hair layer rule declares lie beyond the distance)
            found = self._within_sweep(found)
        self._stale = np.zeros(found.n_contacts, dtype=np.bool_)
        self._redetected = S
        self._last_found, self._q_detected = found, self.q.copy()
        return found

    def _detect_strands(self, which: np.ndarray) -> Contacts:
        """Body contacts only: the strands ``which`` detected afresh, the others' last detection kept."""
        h = self.current()  # placed by their frames, under a deforming body
        counts = np.diff(h.offsets)
        elements = np.concatenate([np.arange(h.offsets[k], h.offsets[k + 1]) for k in which])
        sub = Helices(h.root[which], h.frame0[which], np.r_[0, np.cumsum(counts[which])].astype(np.int64),
                      h.length[elements], self.q[elements], h.fit_error[which])
        rules, own = self._detect_settings, float(self._own[which].max(initial=0.0))
        if own:  # as far as the strands' own motion goes (see _detect)
            rules = dataclasses.replace(rules, body_distance=rules.body_distance + own)
        fresh, _ = detect_contacts(sub, self.body, rules, refine_iterations=_MOVING_REFINE)
        # back to the groom's numbering: strands, and elements (a body contact's second is -1)
        fresh.strand[:, 0] = which[fresh.strand[:, 0]]
        fresh.element[:, 0] = elements[fresh.element[:, 0]]
        if own:
            fresh = self._within_sweep(fresh)
        last = self._last_found
        kept = last.subset(~np.isin(last.strand[:, 0], which))
        merged = Contacts(*(np.concatenate([a, b]) for a, b in zip(
            (kept.strand, kept.s, kept.point, kept.frame, kept.mu, kept.gap, kept.element),
            (fresh.strand, fresh.s, fresh.point, fresh.frame, fresh.mu, fresh.gap, fresh.element))))
        order = np.lexsort((merged.s[:, 0], merged.strand[:, 0]))  # as detect_contacts orders body contacts
        found = merged.subset(order)
        self._stale = (order < kept.n_contacts)
        self._redetected = len(which)
        self._q_detected[elements] = self.q[elements]
        self._last_found = found
        return found

    def _own_sweep(self, h: float) -> np.ndarray:
        """(S,) m: how far each strand's own motion carries its points in its frame over the step, at the velocity
        it starts with (a bound, :func:`_strand_moves` from ``q`` to ``q + h v``), where that reaches a quarter
        of the smallest contact distance in use, beyond which :meth:`_detect` no longer reuses a detection; 0
        elsewhere, where the room between the contact distances and thicknesses already holds it.

        (The velocity the step starts with, not the free one: a strand at rest on its contacts has a free
        velocity, gravity's pull over the step, that those contacts take away; the pull a step adds to a moving
        strand, ``a h``, moves it by ``a h^2`` more, a millimetre for 1 g at 100 steps a second, and is counted
        from the next step on.)"""
        hel = self.helices
        own = np.zeros(hel.n_strands)
        if not hel.n_elements or not np.isfinite(self._detect_distance):
            return own
        reach = 0.25 * self._detect_distance
        cheap = np.add.reduceat(h * np.linalg.norm(self.v, axis=1) * hel.length, hel.offsets[:-1]) * self._strand_length
        if cheap.max() < reach:
            return own
        _strand_moves(hel.root, hel.frame0, hel.offsets, self.q, self.q + h * self.v, hel.length, own)
        own = np.minimum(own, cheap)
        own[own < reach] = 0.0
        return own

    def _within_sweep(self, found: Contacts) -> Contacts:
        """``found`` without the body contacts beyond their own strand's reach this step: detection searched
        as far as the farthest strand's own sweep reaches, for every strand."""
        limit = self._detect_settings.body_distance + self._margin[0] + self._own[found.strand[:, 0]]
        far = (found.strand[:, 1] < 0) & (found.gap >= limit)
        return found.subset(~far) if far.any() else found

    def _keys_of(self, contacts: Contacts) -> np.ndarray:
        """A key per contact naming it from one detection to the next: its element (pair)."""
        if contacts.element is None:
            return contact_keys(contacts.strand, contacts.s, self.helices.offsets, self.helices.length)
        n = self.helices.n_elements
        return np.where(contacts.element[:, 1] < 0, contacts.element[:, 0],
                        n * (1 + contacts.element[:, 0]) + contacts.element[:, 1])

    def _match(self, keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For each key, its index among the remembered contacts' (sorted) keys, and whether it is one."""
        where = np.minimum(np.searchsorted(self._keys, keys), max(len(self._keys) - 1, 0))
        known = self._keys[where] == keys if len(self._keys) else np.zeros(len(keys), bool)
        return where, known

    def _elements_of(self, contacts: Contacts) -> np.ndarray:
        if contacts.element is not None:
            return contacts.element
        keys = self._keys_of(contacts)
        n = self.helices.n_elements
        return np.stack([np.where(keys < n, keys, keys // n - 1), np.where(keys < n, -1, keys % n)], axis=1)

    @staticmethod
    def _anchors_of(contacts: Contacts, order: np.ndarray) -> tuple:
        """Exact gap measurements of body contacts as detected (NaN points: none for hair-hair)."""
        point = contacts.point[order].copy()
        point[contacts.strand[order, 1] >= 0] = np.nan
        gap = contacts.gap[order] if contacts.gap is not None else np.zeros(len(order))
        return point, contacts.frame[order, 0].copy(), gap.copy()

    def _persist(self, found: Contacts, dt: float) -> tuple[Contacts, tuple]:
        """Contacts that persist stay on the same material points of their strands.

        Detection picks each element's closest point afresh; where a strand lies
        along the body (or along another strand) that point jumps along the
        element with the slightest motion (or to the element's end, where no
        contact is declared), and the force warm-started from the last step
        would act somewhere else or vanish. So a remembered contact keeps its
        arc lengths, its gap and normal are measured there, and it is kept as
        long as that gap stays within the detection distance.

        A detection reused from an earlier shape (see :meth:`_detect`), in whole
        or for some strands, was made there: all its contacts are measured again at
        their arc lengths, and none moves to its (stale) detected point.

        A body contact whose point has moved by less than ``tolerance g dt^2 / 4``
        since its gap was last measured exactly (its anchor) takes the gap to first
        order from there, ``gap + n . dx``, and keeps the normal: the signed
        distance is 1-Lipschitz, so the error is under ``2 |dx|``, which moves the
        contact velocity by under half the contact solve's tolerance. A still
        groom then makes no closest-point queries.

        Returns the contacts and their anchors (point, normal, gap; NaN points for
        hair-hair contacts), for :meth:`_step` to remember.
        """
        moving = self._moving()
        if (self._first and not moving) or not (len(self._keys) or self._stale.any()):
            # the first step meets the starting contacts as detected (see _remember), and so does a
            # fresh detection with nothing remembered
            return found, self._anchors_of(found, np.arange(found.n_contacts))
        keys = self._keys_of(found)
        where, known = self._match(keys)
        missing = np.ones(len(self._keys), bool)
        missing[where[known]] = False
        # the union: what detection found, and the remembered contacts it did not find again
        extra = np.flatnonzero(missing)
        strand = np.concatenate([found.strand, self._pair[extra]])
        arc = np.concatenate([found.s, self._arc[extra]])
        arc[np.flatnonzero(known)] = self._arc[where[known]]
        mu = np.concatenate([found.mu, self._mu[extra]])
        element = np.concatenate([self._elements_of(found), self._elements[extra]])
        old_frame = np.concatenate([found.frame, np.zeros((len(extra), 3, 3))])
        # measured again: the remembered contacts, and every contact of a reused detection (its points,
        # gaps and normals are from the shape it was made on)
        redo = np.flatnonzero(np.concatenate([known | self._stale, np.ones(len(extra), dtype=np.bool_)]))
        gap = np.concatenate([found.gap if found.gap is not None else np.zeros(found.n_contacts),
                              np.zeros(len(extra))])
        # each contact's anchor: the remembered one where it is remembered, else none yet
        remembered = np.concatenate([np.where(known, where, -1), extra])
        anchor_point = np.full((len(strand), 3), np.nan)
        anchor_normal = np.zeros((len(strand), 3))
        anchor_gap = np.zeros(len(strand))
        had = remembered >= 0
        anchor_point[had] = self._anchor[0][remembered[had]]
        anchor_normal[had] = self._anchor[1][remembered[had]]
        anchor_gap[had] = self._anchor[2][remembered[had]]
        point = np.concatenate([found.point, np.zeros((len(extra), 3))])
        normal = old_frame[:, 0].copy()  # remembered contacts get theirs measured below
        h = self.current()
        xa = points_on(h, self.q, strand[redo, 0], arc[redo, 0])
        point[redo] = xa
        body = strand[redo, 1] < 0
        limit = np.where(body, self.contact_settings.body_distance + self._margin[0] + self._own[strand[redo, 0]],
                         self.contact_settings.hair_distance + self._margin[1])
        if body.any():
            if self.body is None:
                gap[redo[body]] = np.inf
            else:
                at = redo[body]
                shift = xa[body] - anchor_point[at]
                # NaN (no anchor) compares False: measured
                near = np.linalg.norm(shift, axis=1) <= 0.25 * self.settings.tolerance * self.velocity_scale * dt * dt
                if moving:
                    near[:] = False  # the body has moved under every anchor
                held = at[near]
                normal[held] = anchor_normal[held]
                gap[held] = anchor_gap[held] + np.einsum("ij,ij->i", anchor_normal[held], shift[near])
                measure = at[~near]
                if len(measure):
                    x = xa[body][~near]
                    sd, closest, feature, _ = self.body.closest(x)
                    away = x - closest
                    dist = np.linalg.norm(away, axis=1)
                    flat = dist <= COINCIDENT * self.contact_settings.body_distance
                    side = np.where(sd < 0, -1.0, 1.0)[:, None]
                    normal[measure] = np.where(flat[:, None], feature,
                                               side * away / np.where(flat, 1.0, dist)[:, None])
                    gap[measure] = sd
                    anchor_point[measure], anchor_normal[measure], anchor_gap[measure] = x, normal[measure], sd
        hair = ~body
        if hair.any():
            xb = points_on(h, self.q, strand[redo[hair], 1], arc[redo[hair], 1])
            apart = xa[hair] - xb
            dist = np.linalg.norm(apart, axis=1)
            flat = dist <= COINCIDENT * self.contact_settings.hair_distance
            normal[redo[hair]] = np.where(flat[:, None], normal[redo[hair]], apart / np.where(flat, 1.0, dist)[:, None])
            gap[redo[hair]] = dist
        frame = old_frame
        frame[redo] = contact_frames(normal[redo])
        keep = np.ones(len(strand), bool)
        # a remembered contact that touches beyond the detection distance (declared on a hair layer or
        # between wisps) keeps its own reach: its thickness and the layer tolerance
        thick = np.where(remembered[redo] >= 0, self._thickness[np.maximum(remembered[redo], 0)], 0.0) \
            if len(self._thickness) else np.zeros(len(redo))
        limit = np.where(thick > limit, thick + self.contact_settings.layer_tolerance, limit)
        keep[redo] = gap[redo] < limit  # contacts that have opened beyond reach end here
        # where detection found a point clearly closer than the remembered one (the strand slides or
        # rolls over the surface), the contact moves there: the remembered point would leave the
        # closest one unconstrained
        redetected = np.flatnonzero(known)
        detected_gap = found.gap[redetected] if found.gap is not None else gap[redetected]
        # (not from a reused detection: its closest points are not this shape's)
        moved = redetected[(gap[redetected] > detected_gap + _PERSIST_SLACK) & ~self._stale[redetected]]
        arc[moved], point[moved], frame[moved], gap[moved] = (found.s[moved], found.point[moved], found.frame[moved],
                                                              detected_gap[np.searchsorted(redetected, moved)])
        keep[moved] = True
        moved_body = moved[strand[moved, 1] < 0]
        anchor_point[moved_body] = point[moved_body]
        anchor_normal[moved_body] = frame[moved_body, 0]
        anchor_gap[moved_body] = gap[moved_body]
        merged = Contacts(strand, arc, point, frame, mu, gap, element)
        anchors = (anchor_point, anchor_normal, anchor_gap)
        if keep.all():
            return merged, anchors
        return merged.subset(keep), tuple(a[keep] for a in anchors)

    def _remember(self, found: Contacts, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Keys, thickness and warm-start impulse of this step's contacts."""
        keys = self._keys_of(found)
        gap = found.gap if found.gap is not None else np.zeros(found.n_contacts)
        initial = self._initial
        if self._first and initial is not None and initial.n_contacts == found.n_contacts \
                and np.array_equal(initial.strand, found.strand) and np.allclose(initial.s, found.s, rtol=0, atol=1e-12):
            # the starting shape meets the contacts it was inverted with: their forces, one for one
            return keys, gap.copy(), h * self._initial_impulse
        where, known = self._match(keys)
        fresh = np.where(found.strand[:, 1] < 0, self.settings.body_thickness, self.settings.hair_thickness)
        if self._first:
            # everything touching the starting shape touches at its own distance; what a first step finds beyond
            # the detection distances, brought within reach by the body's sweep or the strand's own (in this
            # attempt, or in a longer one it halves, whose detection it reuses), is new (the contacts the hair
            # layer and wisp rules declare beyond them are the model's, remembered: their thickness is below)
            reach = np.where(found.strand[:, 1] < 0, self.contact_settings.body_distance,
                             self.contact_settings.hair_distance)
            fresh = np.where(gap > reach, fresh, gap)
        # a new contact keeps the room it has, up to its thickness; one found inside is pushed out
        thickness = np.minimum(gap if self._first else np.maximum(gap, 0.0), fresh)
        impulse = np.zeros((found.n_contacts, 3))
        if len(self._keys):
            thickness[known] = self._thickness[where[known]]
            world = self._impulse[where[known]] * (h if self._first else 1.0)
            impulse[known] = np.einsum("cij,cj->ci", found.frame[known], world)
        return keys, thickness, impulse

    def _stale_hessians(self, gravity: np.ndarray) -> np.ndarray:
        """Strands whose gravity Hessian and mass matrix must be taken again, (S,) bool: they only shape
        the implicit matrix, so they (and its factor) are kept while no element has turned by more than
        0.01 rad since, and gravity (in the strand's frame, ``gravity`` (S, 3)) has not turned by more than
        0.01 rad. A still groom then costs a gravity evaluation and two triangular solves per strand and step."""
        n = self.helices.n_strands
        if self._hess_q is None:
            fresh = np.ones(n, dtype=np.bool_)
            turned = fresh
        else:
            turned = np.linalg.norm(np.cross(gravity, self._hess_gravity), axis=1) > \
                1e-2 * np.linalg.norm(gravity, axis=1) * np.linalg.norm(self._hess_gravity, axis=1)
            turn = np.linalg.norm(self.q - self._hess_q, axis=1) * self.helices.length
            fresh = turned.copy()
            if len(turn):
                fresh |= np.maximum.reduceat(turn, self.helices.offsets[:-1]) > 1e-2
        if fresh.any():
            if self._hess_q is None or fresh.all():
                self._hess_q = self.q.copy()
                self._hess_gravity = np.array(gravity, dtype=np.float64)
            else:
                mask = np.repeat(fresh, np.diff(self.helices.offsets))
                self._hess_q[mask] = self.q[mask]
                self._hess_gravity[turned] = gravity[turned]
        return fresh

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
        held = np.zeros_like(self.hess)
        if not len(self._keys) or not fresh.any():
            return held
        force = self._impulse / self._impulse_step
        loaded = np.flatnonzero(np.any(force != 0.0, axis=1))
        if not len(loaded):
            return held
        # each contact side as a load on its strand: +f on the first, -f on the second
        hair = self._pair[loaded, 1] >= 0
        strand = np.concatenate([self._pair[loaded, 0], self._pair[loaded[hair], 1]])
        arc = np.concatenate([self._arc[loaded, 0], self._arc[loaded[hair], 1]])
        load = np.concatenate([force[loaded], -force[loaded[hair]]])
        keep = fresh[strand]
        strand, arc, load = strand[keep], arc[keep], load[keep]
        order = np.lexsort((arc, strand))
        strand, arc, load = strand[order], arc[order], load[order]
        bounds = np.searchsorted(strand, np.arange(self.helices.n_strands + 1))
        # the remembered forces are in the frame the strands were placed in (the body's, or the groom's)
        h = self._posed(self.R, self.c) if self._placed else self.helices
        loaded_strands = np.flatnonzero(np.diff(bounds)).astype(np.int64)
        arc, load = np.ascontiguousarray(arc), np.ascontiguousarray(load)
        run_chunks(lambda lo, hi: _load_hessians(loaded_strands, lo, hi, bounds, h.root, h.frame0, self.q, h.length,
                                                 h.offsets, arc, load, self.chol_ptr, held),
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
        than ``dynamics.max_turn`` within it. An attempt that turns too far is
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
        h = float(self.settings.time_step if h is None else h)
        if t is not None:
            self.time = float(t)
        start = min(self.start_depth, self.settings.max_substeps)
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
        self.start_depth = min(self.start_depth, self.settings.max_substeps)
        report.seconds = time.perf_counter() - started
        self.last = report
        return report

    def _step(self, motion, h: float, depth: int, parent_turn: float = np.inf) -> StepReport:
        helices = self.helices
        offsets = helices.offsets
        v_free = np.zeros_like(self.q)
        skin = None
        if isinstance(motion, Motion):
            packed = motion.per_strand(helices.n_strands)
        else:
            skin = motion.step(self.time, h)
            packed = skin.motion
            if skin.body is not None:
                self.body = skin.body
        self._skin = skin
        self._margin = skin.margins(self.helices.root, self._tips) if skin is not None else (0.0, 0.0)
        fresh = self._stale_hessians(packed[:, 0])

        def free(lo: int, hi: int) -> None:
            _free_chunk(helices.root, helices.frame0, offsets, helices.length, self.q, self.v, self.rest,
                        self.stiff, self.lam, self.rot, self.settings.damping, self.settings.air_damping, h,
                        packed, self.gx, self.gw, self.chol, self.chol_ptr, v_free, self.kinetic, self.hess,
                        self.mass, fresh, self.factored_h, held, lo, hi)

        held = self._contact_hessians(fresh)
        run_chunks(free, helices.n_strands, 64)
        if not np.all(np.isfinite(v_free)):
            raise FloatingPointError("the free velocity is not finite")
        self._own = self._own_sweep(h) if self.body is not None and self.contact_settings.body else \
            np.zeros(helices.n_strands)
        found = self._detect()
        found, anchors = self._persist(found, h)
        keys, thickness, impulse = self._remember(found, h)
        report = StepReport(found.n_contacts, found.n_body, 0, 0.0, Status.CONVERGED, 0, 0.0, depth=depth, last_depth=depth)
        v_new = v_free
        reached = ""  # what the contact solve reached, for the message of a step that fails at every length
        if found.n_contacts:
            contact_run = lambda work, n: run_chunks(work, n, _CONTACT_CHUNK)  # noqa: E731
            rows = contact_rows(self.current(), found, run=contact_run)
            Wd = factored_blocks(rows, found.strand, offsets, self.chol, self.chol_ptr, run=contact_run)
            gap = found.gap if found.gap is not None else np.zeros(found.n_contacts)
            push = np.zeros((found.n_contacts, 3))
            if skin is not None:
                # under a deforming body, a contact on a strand's first element moves with the root's frame: the
                # skin's own motion there relative to that frame (a neck twisting under the roots beside it), in
                # this step or the last, is not asked of the strand, which could meet it only by swinging its
                # whole length about the root
                rooted = self._rooted(found)
                thickness[rooted] = np.minimum(thickness[rooted], gap[rooted])
            push[:, 0] = np.maximum((gap - thickness) / h, -self.settings.push_speed)
            if self._moving():  # and how the frames carry each contact's sides against each other
                push[~rooted] += self._drift(found.subset(~rooted), skin)
            b = rows.matvec(v_free.ravel()) + reachable(Wd, push)
            gamma = compliance(Wd)
            Wd[:, [0, 1, 2], [0, 1, 2]] += gamma[:, None]
            # the last step's impulses may already meet the tolerance (a groom still at its equilibrium):
            # then the factored rows, the step's largest arrays, are never built
            result, correction = self._warm_start(rows, gamma, b, found.mu, Wd, impulse, h)
            if result is None:
                z_rows = factored_rows(rows, found.strand, offsets, self.chol, self.chol_ptr, run=contact_run)
                problem = coulomb_problem(z_rows, gamma, b, found.mu, found.strand, helices.n_strands,
                                          self.velocity_scale * h, s=found.s,
                                          part_of=split_strands(helices.root, found.strand))
                settings = CoulombSettings(self.settings.tolerance, self.settings.max_sweeps,
                                           stall_rounds=self.settings.stall_rounds)
                result = solve_coulomb(problem, settings, impulse, Wd=Wd)
                correction = self._mass_solve(z_rows.rmatvec(result.r), factored=True)
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
        if failed and depth >= self.settings.max_substeps:
            what = "the contact solve failed" if reached and result.status == Status.NUMERICAL_ERROR else "the velocity is not finite"
            raise FloatingPointError(f"{what} at a step of {h:.3g} s, halved {depth} times{reached}")
        # a halved attempt that turns nearly as far as the attempt it replaces shows that halving does
        # not slow the motion down (a push asked within the step, whatever its length): it is kept
        futile = not failed and turn <= _FUTILE_CAP * self.settings.max_turn and turn > _HALVING_GAIN * parent_turn
        if (failed or turn > self.settings.max_turn) and not futile and depth < self.settings.max_substeps:
            # nothing is kept of this attempt: two half steps instead
            replaced = np.inf if failed else turn
            self._skin = None
            first = self._step(motion, 0.5 * h, depth + 1, replaced)
            joined = _joined(first, self._step(motion, 0.5 * h, depth + 1, replaced))
            joined.rejected += 1
            if joined.turned < 0 and not failed:
                joined.turned = int(np.searchsorted(offsets, int(np.argmax(turns)), side="right") - 1)
            return joined
        report.turn = turn
        if futile and turn > self.settings.max_turn:
            report.kept_turning = 1
            report.last_depth = depth - 1  # the attempt it replaced would have done as well
        self._first = False
        order = np.argsort(keys, kind="stable")
        world = np.einsum("cji,cj->ci", found.frame, impulse)
        self._keys, self._thickness, self._impulse = keys[order], thickness[order], world[order]
        self._impulse_step = h
        self._arc, self._pair, self._mu = found.s[order], found.strand[order], found.mu[order]
        self._elements = self._elements_of(found)[order]
        if self._moving():  # measured on the body at the step's start, which has moved since: none is kept
            anchors = (np.full_like(anchors[0], np.nan),) + tuple(anchors[1:])
        self._anchor = tuple(a[order] for a in anchors)
        self.contacts = found
        self.v = v_new
        self.q = self.q + h * v_new
        self.time += h
        if skin is not None:
            self.R, self.c = skin.R, skin.c
            self._placed = True
        self._skin = None
        return report

    def _rooted(self, found: Contacts) -> np.ndarray:
        """(C,) bool: the contacts with a side on its strand's first element."""
        elements = self._elements_of(found)
        first = self.helices.offsets[:-1]
        side0 = elements[:, 0] == first[found.strand[:, 0]]
        hair = found.strand[:, 1] >= 0
        side1 = np.zeros_like(side0)
        side1[hair] = elements[hair, 1] == first[found.strand[hair, 1]]
        return side0 | side1

    def _drift(self, found: Contacts, skin) -> np.ndarray:
        """(C, 3) m/s, in the contacts' frames: how fast the strands' frames carry each contact's first side
        against its second (the skin, for a body contact; the other strand's frame) over the step, from
        where they are at its start."""
        posed = self.current()
        xa = points_on(posed, self.q, found.strand[:, 0], found.s[:, 0])
        world = skin.frame_velocity(found.strand[:, 0], xa)
        body = found.strand[:, 1] < 0
        if body.any() and skin.body is not None:
            _, _, _, face = skin.body.closest(xa[body])
            world[body] -= skin.skin_velocity(face, xa[body])
        hair = np.flatnonzero(~body)
        if len(hair):
            xb = points_on(posed, self.q, found.strand[hair, 1], found.s[hair, 1])
            world[hair] -= skin.frame_velocity(found.strand[hair, 1], xb)
        return np.einsum("cji,ci->cj", found.frame, world)

    def _mass_solve(self, y: np.ndarray, factored: bool = False) -> np.ndarray:
        """``M^-1 y`` strand by strand through the strands' Cholesky factors ``M = L L^T`` (``L^-T y``
        only, for ``y`` given as ``L^-1`` of something: ``factored``)."""
        helices = self.helices
        if not factored:
            x = np.zeros_like(y)
            run_chunks(lambda lo, hi: forward_substitute(helices.offsets, self.chol, self.chol_ptr, y, x, lo, hi),
                       helices.n_strands, 64)
            y = x
        out = np.zeros_like(y)
        run_chunks(lambda lo, hi: back_substitute(helices.offsets, self.chol, self.chol_ptr, y, out, lo, hi),
                   helices.n_strands, 64)
        return out

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
        scale = self.velocity_scale * h
        tolerance = self.settings.tolerance * scale
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
        return float(self.kinetic.sum())

    def elastic_energy(self) -> float:
        """J, ``1/2 (q - q0)^T K (q - q0)``."""
        d = (self.q - self.rest).ravel()
        return float(0.5 * np.dot(d, self.stiff * d))
