"""Inverse statics with frictional contact (paper, section 6).

The shape ``q`` is known (the fit). Find contact forces ``r`` in the Coulomb
cones and the rest shape ``q0`` such that ``q`` is a static equilibrium,

    K (q - q0) = F_g(q) + H(q)^T r,                                  eq. (4)

choosing among all such ``r`` the one that minimises
``1/2 sum_e w_e |q0_e - t_e|^2 + gamma/2 |r|^2`` (eq. 6) for a target
rest shape ``t``. With ``q0 = q - K^-1 (F_g + H^T r)`` this is the SOCQP
``min 1/2 r^T W r + b^T r`` over the cones, with

    D = w K^-2 (diagonal),  W = H D H^T + gamma I,  b = H D (F_g - K (q - t)),

solved by :func:`hairinv.solver.gauss_seidel.solve_cone_qp`. Without
contacts the minimiser is ``r = 0`` and ``q0 = q - K^-1 F_g``: the
gravity-only inversion of Derouet-Jourdan et al. 2010.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np

from . import stages
from ._jit import jit
from ._parallel import run_chunks
from .config import MaterialSettings, SolverSettings
from .errors import InputError, RunError
from .gravity import generalized_gravity, tolerance_gravity
from .model import (UNSTABLE_MARGIN, Contacts, Helices, Material, Model, material_from_group, rest_from_group,
                    stiffening_from_group, stiffness)
from .rod.statics import gravity_hessian, point_load_hessian
from .solver.blocks import group_newton, strand_blocks
from .solver import gauss_seidel, interior
from .solver.gauss_seidel import SolverResult, diagonal_blocks, project_forces, split_strands
from .solver.interior import mu_in_range
from .solver.problem import CONE, ConeProblem, InteriorSettings, SweepSettings
from .solver.status import Status
from .contacts.rows import contact_rows, sides_by_strand
from .solver.rows import ContactRows

__all__ = ["TARGETS", "Material", "Model", "InvertReport", "invert", "stiffness", "generalized_gravity",
           "target_shape", "stability"]

TARGETS = ("actual", "zero", "uniform", "tip", "gravity-only")
STABILIZE = ("stiffen", "off")
METHODS = ("auto", "sweeps", "interior-point")
#: GFlop a step up to which ``solver.method = auto`` takes the interior-point method: ruby short whole (1,867
#: strands, 25,468 contacts) needs 19, 0.4 s a factorisation on 2 cores. Measured on heads of 3,000 to 4,867
#: ruby guides (23 to 128 GFlop) it converged in 17 to 73 s where the sweeps' 2,000 took 47 to 111 s and stopped
#: 0.19 to 0.28 1/m from the optimum (docs/inverse.md); above it the sweeps solve the groom
AUTO_GFLOP = 150.0
#: what the stability check holds: the contact forces fixed (every motion), or the loaded contact points
STABLE_UNDER = ("forces", "supports")
#: inversions with stiffened strands tried before the remaining unstable strands are reported: a
#: strand's factor makes it stable on the supports it had; the new forces may load other contacts
STABILIZE_ROUNDS = 8


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


#: 1/m: how far a stored rest shape may be from the one its forces give on its helices (eq. 4), plus
#: :data:`MODEL_MISMATCH_RELATIVE` of the curvatures involved; a model read back as written is at round-off
MODEL_MISMATCH = 1e-6
MODEL_MISMATCH_RELATIVE = 1e-9


def model_mismatch(helices: Helices, contacts: Contacts | None, group: stages.Group) -> tuple[float, int]:
    """How far a ``/model`` group's rest shape is from holding ``helices`` with its own forces: the largest
    ``|q0 - (q - K^-1 (F_g + H^T r))|`` over elements (1/m) beyond round-off, and the element where it is
    (-1 where it holds).

    Equation (4) holds for the model :func:`invert` writes whatever solved it, so a model whose helices or
    contacts were changed after it was inverted (same sizes) shows here. The rest shape checked is the
    one a simulation takes: ``omega_rest_stiffened`` at the stiffened stiffness where the model has one."""
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


def stability(helices: Helices, material: Material, stiff: np.ndarray, rows: ContactRows | None = None,
              contacts: Contacts | None = None, carrying: np.ndarray | None = None,
              force: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Which strands sit in an unstable equilibrium: (with their supports, without, held, under their
    forces held fixed), each (S,) bool.

    The Hessian of the total energy at ``q`` is ``K + d^2 V_g / dq^2``
    (independent of ``q0``). A strand is stable if it is positive definite on
    the directions that keep the points of its force-carrying contacts in
    place (the supports; the other strand of a hair-hair contact is held
    fixed). The gravity Hessian is taken by central differences of ``F_g``,
    accurate to about 1e-8 relative: enough to tell a sign. The second mask
    ignores the supports (the gravity-only inversion's stability: the
    Hessian does not depend on ``q0``), from the same Hessian. The third
    holds every declared contact point in place, loaded or not: a strand
    unstable even so cannot be made stable by any choice of forces or rest
    shape (its input shape is unstable on this rod model). The fourth holds
    no point: the contact forces stay as they are (dead loads, with their own
    share of the Hessian below) and every motion is allowed. It is the
    strictest (positive on every motion implies positive on the supported
    ones, and for strands leaning on each other, which then no longer
    interact, jointly), and it is what a simulation at rest needs: its
    contact solve answers only once a contact's velocity error passes its
    tolerance, so until then the contacts act as these fixed forces
    (docs/dynamics.md, Stability).

    With ``force`` (C, 3) (the contact forces, in their frames), the Hessian
    also holds the contact forces' own share, ``-sum r_i . d^2 x_i / dq^2``
    (:func:`hairinv.rod.statics.point_load_hessian`): a held point's reaction does
    work at second order as the strand turns about it, which is what keeps a
    strand hanging from, or leaning on, a support upright or taut.
    """
    return tuple(lam < _NEGATIVE
                 for lam in stability_margins(helices, material, stiff, rows, contacts, carrying, force))


def stability_margins(helices: Helices, material: Material, stiff: np.ndarray, rows: ContactRows | None = None,
                      contacts: Contacts | None = None, carrying: np.ndarray | None = None,
                      force: np.ndarray | None = None, strands: np.ndarray | None = None,
                      previous: tuple | None = None, supported: bool = True
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The smallest eigenvalue ``lambda`` of each strand's scaled Hessian ``I + K^-1/2 V'' K^-1/2`` on
    the motions :func:`stability` allows (with the supports, without, with every declared contact held,
    with the forces held fixed), each (S,) float64; ``inf`` where the held points leave no motion. A strand is unstable where
    ``lambda < 0``.

    Scaling the strand's stiffness by ``a`` scales ``K^-1/2 V'' K^-1/2`` by ``1/a``, so its smallest
    eigenvalue becomes ``1 - (1 - lambda) / a``: exactly ``a = 1 - lambda`` makes it singular, and any
    larger factor stable (:func:`critical_stiffening`).

    ``strands`` (indices) checks only those strands; the others keep the values of ``previous`` (an
    earlier result of this function, for the same contacts and forces), as they are where only the
    stiffness of ``strands`` changed since.

    ``supported`` False leaves the first margin out (NaN on strands with contacts): the default
    stabilisation works on the forces held fixed, and the supports' margin costs a null space and an
    eigenvalue problem per strand.
    """
    S = helices.n_strands
    # each strand's contact sides (a hair-hair contact counts on both its strands), strand by strand
    if rows is not None and contacts is not None and rows.n_contacts:
        side_index = sides_by_strand(contacts.strand)
        incident = side_index // 2
        incident_ptr = np.searchsorted(contacts.strand.ravel()[side_index], np.arange(S + 1)).astype(np.int64)
        loaded = np.zeros(rows.n_contacts, bool) if carrying is None else np.asarray(carrying, bool)
        ptr, cols, vals = rows.ptr, rows.cols, rows.vals
        # the load each side takes: the world force on A at s_A, its opposite on B at s_B
        load_s = np.ascontiguousarray(contacts.s.ravel()[side_index])
        slip_kind = np.zeros(rows.n_contacts, np.int64)
        slip_dir = np.zeros((rows.n_contacts, 2))
        if force is None:
            load_f = np.zeros((len(side_index), 3))
        else:
            r = np.asarray(force, dtype=np.float64)
            tangential = np.hypot(r[:, 1], r[:, 2])
            edge = loaded & _on_cone_edge(tangential, contacts.mu, r[:, 0])
            slip_kind[edge] = np.where(tangential[edge] > 0.0, 1, 2)  # 2: frictionless, both tangents free
            moving = edge & (tangential > 0.0)
            slip_dir[moving] = r[moving, 1:] / tangential[moving, None]
            world = np.einsum("cji,cj->ci", contacts.frame, np.asarray(force, dtype=np.float64))
            load_f = np.ascontiguousarray(world[side_index // 2] * np.where(side_index % 2 == 0, 1.0, -1.0)[:, None])
    else:
        incident, incident_ptr = np.zeros(0, np.int64), np.zeros(S + 1, np.int64)
        loaded = np.zeros(0, bool)
        ptr, cols, vals = np.zeros(1, np.int64), np.zeros(0, np.int64), np.zeros((0, 3))
        load_s, load_f = np.zeros(0), np.zeros((0, 3))
        slip_kind, slip_dir = np.zeros(0, np.int64), np.zeros((0, 2))
    if previous is None:
        unstable, free, always, fixed = (np.zeros(S) for _ in range(4))
    else:
        unstable, free, always, fixed = (np.array(a, dtype=np.float64) for a in previous)
    which = np.arange(S, dtype=np.int64) if strands is None else np.asarray(strands, dtype=np.int64)

    def check(lo: int, hi: int) -> None:
        _stability_chunk(helices.root, helices.frame0, helices.offsets, helices.omega, helices.length,
                         material.linear_density, material.gravity, stiff, incident_ptr, incident, loaded, ptr,
                         cols, vals, load_s, load_f, force is not None, slip_kind, slip_dir, supported, which, lo,
                         hi, unstable, free, always, fixed)

    run_chunks(check, len(which), 64)
    return unstable, free, always, fixed


# an eigenvalue of the scaled Hessian I + K^-1/2 V'' K^-1/2 below this is a direction of instability
_NEGATIVE = UNSTABLE_MARGIN
# a contact whose friction force is at least this fraction of mu r_N is on the edge of its cone: sliding
SLIDING = 1.0 - 1e-4


def _on_cone_edge(tangential: np.ndarray, mu: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Which contacts' friction force ``tangential`` (C,) is on the edge of its cone, ``SLIDING mu r_N``
    or more. Infinite friction (the half-space ``r_N >= 0``) never slides: no edge, and no ``inf * 0``."""
    mu = np.asarray(mu, dtype=np.float64)
    finite = np.isfinite(mu)
    bound = SLIDING * np.where(finite, mu, 0.0) * np.asarray(normal, dtype=np.float64)
    return finite & (tangential >= bound)


@jit
def _stability_chunk(root, frame0, offsets, omega, length, lam, gravity, stiff, incident_ptr, incident, loaded,
                     ptr, cols, vals, load_s, load_f, with_loads, slip_kind, slip_dir, supported, which, lo, hi,
                     unstable, free, always, fixed):
    """:func:`stability` for strands ``which[lo:hi]``."""
    for w in range(lo, hi):
        s = which[w]
        e0 = offsets[s]
        e1 = offsets[s + 1]
        c0 = 3 * e0
        m = 3 * (e1 - e0)
        hess = np.empty((m, m))
        gravity_hessian(root[s], frame0[s], omega[e0:e1], length[e0:e1], lam, gravity, hess)
        # scaled by K^-1/2, so the test reads "eigenvalue of I + K^-1/2 V'' K^-1/2 below zero"
        scale = 1.0 / np.sqrt(stiff[c0:c0 + m])
        A = np.empty((m, m))
        for i in range(m):
            for j in range(m):
                A[i, j] = 0.5 * (hess[i, j] + hess[j, i]) * scale[i] * scale[j]
            A[i, i] += 1.0
        free[s] = np.linalg.eigvalsh(A)[0]
        n = incident_ptr[s + 1] - incident_ptr[s]
        if n == 0:
            unstable[s] = free[s]
            always[s] = free[s]
            fixed[s] = free[s]
            continue
        # the rows of H on this strand's columns: those of the contacts carrying force first, then the others.
        # A loaded contact on the edge of its friction cone holds its point along the normal and across the
        # friction force only: along the direction the friction resists it slides as soon as it is pushed
        # (the friction then acts as a dead load, which the reaction's Hessian share below accounts for)
        C = np.zeros((3 * n, m))
        j = 0
        n_loaded = 0
        rows_loaded = 0
        for first in (True, False):
            for k in range(incident_ptr[s], incident_ptr[s + 1]):
                i = incident[k]
                if loaded[i] != first:
                    continue
                kind = slip_kind[i] if first else 0
                for t in range(ptr[i], ptr[i + 1]):
                    c = cols[t] - c0
                    if 0 <= c < m:
                        C[j, c] = vals[t, 0] * scale[c]
                        if kind == 0:
                            C[j + 1, c] = vals[t, 1] * scale[c]
                            C[j + 2, c] = vals[t, 2] * scale[c]
                        elif kind == 1:  # across the friction force (cos, sin) in the tangent plane
                            C[j + 1, c] = (-slip_dir[i, 1] * vals[t, 1] + slip_dir[i, 0] * vals[t, 2]) * scale[c]
                j += 3 if kind == 0 else (2 if kind == 1 else 1)
                n_loaded += first
                if first:
                    rows_loaded = j
        C = C[:j]
        if with_loads and n_loaded > 0:
            # the held points' reactions: their share -sum r . d^2 x of the Lagrangian's Hessian
            ks = np.empty(n_loaded, np.int64)
            j = 0
            for k in range(incident_ptr[s], incident_ptr[s + 1]):
                if loaded[incident[k]]:
                    ks[j] = k
                    j += 1
            ks = ks[np.argsort(load_s[ks])]
            s_sorted = np.ascontiguousarray(load_s[ks])
            f_sorted = np.ascontiguousarray(load_f[ks])
            point_load_hessian(root[s], frame0[s], omega[e0:e1], length[e0:e1], s_sorted, f_sorted, hess)
            for i in range(m):
                for j in range(m):
                    A[i, j] += hess[i, j] * scale[i] * scale[j]
        # the forces held fixed: every motion, the loads' share in A (without loads, the gravity-only margin)
        fixed[s] = free[s] if not (with_loads and n_loaded > 0) else np.linalg.eigvalsh(A)[0]
        if not supported:
            unstable[s] = np.nan
        else:
            unstable[s] = free[s] if n_loaded == 0 else _lowest_held(A, C[:rows_loaded])
        always[s] = _lowest_held(A, C)


#: the joint check of strands coupled by loaded hair-hair contacts is dense: groups of up to this many
#: coordinates (an eigen-decomposition of at most 3,000 x 3,000, a few seconds); larger groups keep the
#: per-strand check and are reported
GROUP_DOFS = 3000


def group_margins(helices: Helices, material: Material, stiff: np.ndarray, rows: ContactRows, contacts: Contacts,
                  carrying: np.ndarray, force: np.ndarray) -> tuple[list[np.ndarray], np.ndarray, int]:
    """The joint stability of strands that lean on each other: per group of strands joined by loaded
    hair-hair contacts, the smallest eigenvalue of their scaled Hessian on the motions that keep every
    loaded contact in place, both sides moving (the per-strand check holds the other strand fixed, and
    misses two wisps leaning on each other that fall over together).

    Returns (the groups, as arrays of strand indices; their eigenvalues (G,); the strands in groups too
    large to check, over ``GROUP_DOFS`` coordinates). Groups of one strand are left to :func:`stability`.
    """
    S = helices.n_strands
    loaded = np.asarray(carrying, bool) & (contacts.strand[:, 1] >= 0)
    if not loaded.any():
        return [], np.zeros(0), 0
    # connected components of the loaded hair-hair graph
    parent = np.arange(S)

    def find(k):
        while parent[k] != k:
            parent[k] = parent[parent[k]]
            k = parent[k]
        return k

    for a, b in contacts.strand[loaded]:
        ra, rb = find(a), find(b)
        if ra != rb:
            parent[max(ra, rb)] = min(ra, rb)
    roots = np.array([find(k) for k in range(S)])
    members = [np.flatnonzero(roots == r) for r in np.unique(roots)]
    members = [g for g in members if len(g) > 1]
    counts = np.diff(helices.offsets)
    world = np.einsum("cji,cj->ci", contacts.frame, np.asarray(force, dtype=np.float64))
    tangential = np.hypot(force[:, 1], force[:, 2])
    edge = np.asarray(carrying, bool) & _on_cone_edge(tangential, contacts.mu, force[:, 0])
    checked, lams, too_large = [], [], 0
    for g in members:
        dofs = 3 * int(counts[g].sum())
        if dofs > GROUP_DOFS:
            too_large += len(g)
            continue
        cols = np.concatenate([np.arange(3 * helices.offsets[k], 3 * helices.offsets[k + 1]) for k in g])
        index = np.full(3 * helices.n_elements, -1, dtype=np.int64)
        index[cols] = np.arange(len(cols))
        scale = 1.0 / np.sqrt(stiff[cols])
        A = np.zeros((dofs, dofs))
        in_group = np.isin(contacts.strand, g) & (contacts.strand >= 0)
        for k in g:
            a, z = helices.offsets[k], helices.offsets[k + 1]
            m = 3 * (z - a)
            hess = np.empty((m, m))
            gravity_hessian(helices.root[k], helices.frame0[k], helices.omega[a:z], helices.length[a:z],
                            material.linear_density, material.gravity, hess)
            hess = 0.5 * (hess + hess.T)
            sides = np.argwhere((contacts.strand == k) & np.asarray(carrying, bool)[:, None])
            if len(sides):
                load_s = contacts.s[sides[:, 0], sides[:, 1]]
                load_f = world[sides[:, 0]] * np.where(sides[:, 1] == 0, 1.0, -1.0)[:, None]
                order = np.argsort(load_s)
                extra = np.empty((m, m))
                point_load_hessian(helices.root[k], helices.frame0[k], helices.omega[a:z], helices.length[a:z],
                                   np.ascontiguousarray(load_s[order]), np.ascontiguousarray(load_f[order]), extra)
                hess += extra
            at = index[3 * a:3 * z]
            A[np.ix_(at, at)] = hess * np.outer(scale[at], scale[at])
            A[at, at] += 1.0
        rows_out = []
        for i in np.flatnonzero(np.asarray(carrying, bool) & in_group.any(axis=1)):
            row = np.zeros((3, dofs))
            for t in range(rows.ptr[i], rows.ptr[i + 1]):
                j = index[rows.cols[t]]
                if j >= 0:
                    row[:, j] = rows.vals[t] * scale[j]
            if edge[i]:  # on the edge of its cone: held along the normal and across the friction force only
                if tangential[i] > 0:
                    c, s_ = force[i, 1] / tangential[i], force[i, 2] / tangential[i]
                    row = np.stack([row[0], -s_ * row[1] + c * row[2]])
                else:
                    row = row[:1]
            rows_out.append(row)
        lams.append(float(_lowest_held(A, np.ascontiguousarray(np.concatenate(rows_out)))))
        checked.append(g)
    return checked, np.asarray(lams), too_large


@jit
def _lowest_held(A, C):
    """The smallest eigenvalue of the scaled Hessian ``A`` on the motions that keep the contact points
    whose rows of H (on the strand's columns, scaled as ``A``) are ``C`` in place (inf: none is left)."""
    # rows of unit length first: a contact near the root moves little, and its rows would otherwise
    # read as rank-deficient next to a far one's (on samples/settled.h5 that counted 4 stable strands
    # as unstable); what remains below 1e-12 is true dependence (two contacts on one spot, ~1e-17)
    m = A.shape[0]
    U = np.empty(C.shape)
    k = 0
    for i in range(C.shape[0]):
        norm = np.sqrt(np.sum(C[i] ** 2))
        if norm > 0.0:
            U[k] = C[i] / norm
            k += 1
    if k == 0:
        return np.linalg.eigvalsh(A)[0]
    # only the right singular vectors are used: with more rows than columns the thin decomposition has
    # them all (and skips the k x k left ones), with fewer the full one is needed for the null space
    _, sv, vt = np.linalg.svd(U[:k], k < m)
    rank = 0
    for x in sv:
        rank += x > 1e-12 * sv[0]
    if rank == m:
        return np.inf
    Z = np.ascontiguousarray(vt[rank:].T)
    return np.linalg.eigvalsh(Z.T @ A @ Z)[0]


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


#: Newton iterations of a strand's contacts solved together (:func:`_strands_at_once`)
STRAND_NEWTON_ITERS = 50


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


def validate_settings(settings: SolverSettings) -> None:
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
    unstable gets its stiffness multiplied by ``stiffen_margin`` times the critical factor
    (:func:`stability_margins`); the factors are the model's ``stiffening``. Unstable under its
    contact forces held fixed (``settings.stable_under == "forces"``, the default): the forces are
    kept, they hold the input at any stiffness, and the rest shape is taken again with the factor, so
    one round makes every strand stable. Unstable on its supports (``"supports"``): the problem is
    solved again with the factor, from the last forces, until every strand is stable or
    ``STABILIZE_ROUNDS`` rounds are done.

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
    q = helices.omega.ravel()
    weight = np.ones(helices.n_elements)
    target = target_shape(helices, settings.target)
    F_g = generalized_gravity(helices, material).ravel()
    rows = contact_rows(helices, contacts, run=lambda work, count: run_chunks(work, count, 2048))
    # the cones the forces are found in: the declared friction less its reserve (mu = 0 and inf stay)
    mu = contacts.mu * (1.0 - settings.friction_reserve)
    solved = dataclasses.replace(contacts, mu=mu)
    strand_length = np.add.reduceat(helices.length, helices.offsets[:-1])
    force_scale = material.linear_density * tolerance_gravity(material) * float(strand_length.max())
    r0 = None
    # a start for no contacts has nothing to start; the interior-point method takes none (with auto, the
    # sweeps take it if the interior-point method declines the groom)
    warm = start is not None and contacts.n_contacts > 0 and settings.method != "interior-point"
    if warm:
        start = np.asarray(start, dtype=np.float64)
        if start.shape != (contacts.n_contacts, 3) or not np.all(np.isfinite(start)):
            raise InputError(f"the starting forces must be finite, one row of 3 per contact "
                             f"({contacts.n_contacts}), got shape {start.shape}")
        r0 = project_forces(start, mu)

    notes: list[str] = []
    declined: list[float] = []

    def steps(problem: ConeProblem):
        """The interior-point solve, or None where the method is the sweeps or the groom too costly for it."""
        if settings.method == "sweeps" or not contacts.n_contacts or declined:
            return None
        found = interior.solve(problem, CONE, InteriorSettings.of(
            settings, max_gflop=None if settings.method == "interior-point" else AUTO_GFLOP),
            progress=_interior_progress(progress, settings.max_iterations))
        if found.status != Status.TOO_LARGE:
            return found
        cap = found.gflop
        declined.append(cap)
        if settings.method == "interior-point":
            notes.append(f"the interior-point method's factorisation would cost over {cap:g} GFlop a step on this "
                         "groom (very large, or strands touching along much of their length): solved by the "
                         "sweeps instead (docs/inverse.md)")
        else:
            notes.append(f"solver.method = auto: the sweeps solved this groom, whose interior-point factorisation "
                         f"would cost over {cap:g} GFlop a step (solver.method = interior-point takes up to "
                         f"{interior.MAX_GFLOP:g}; docs/inverse.md)")
        return None

    def solve(stiff: np.ndarray, r0: np.ndarray | None, first: bool):
        # D = w K^-2; b = H D (F_g - K (q - t))
        d = np.repeat(weight, 3) / stiff ** 2
        b = rows.matvec(d * (F_g - stiff * (q - target.ravel())))
        gammas = contact_gamma(rows, d, settings.gamma, settings.gamma_relative)
        problem = ConeProblem.of(rows, d, gammas, b, mu, contacts.strand, S, force_scale, s=contacts.s,
                                 part_of=split_strands(helices.root, contacts.strand))
        stepped = steps(problem)
        if stepped is None and first and r0 is None and contacts.n_contacts \
                and not np.any(contacts.strand[:, 1] >= 0):
            r0 = _strands_at_once(rows, d, gammas, b, solved, settings.tolerance * force_scale)
        sweeps_cap = settings.max_sweeps
        # friction coefficients outside the steps' range (0 < mu < 1e-3, mu > 1e3, inf) were held within it
        # there: the sweeps then solve the problem as declared, from those forces; otherwise (mu = 0
        # included, solved exactly by the steps) the forces are final and the
        # call below only measures their residual (and projects them onto the cones, a round-off move)
        if stepped is not None and np.all(mu_in_range(mu)):
            sweeps_cap = 0
        sweep_settings = dataclasses.replace(SweepSettings.of(settings), max_sweeps=sweeps_cap)
        result = gauss_seidel.solve(problem, CONE, sweep_settings, start=r0 if stepped is None else stepped.r,
                                    progress=progress if stepped is None else None)
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
        carrying = result.r[:, 0] > settings.tolerance * force_scale if len(result.r) else np.zeros(0, bool)
        return result, carrying, r0, gammas

    stiff = stiffness(helices, material, factor)
    newton_start = r0 is None
    result, carrying, r0, gammas = solve(stiff, r0, True)
    afresh = warm and result.method == "interior-point"  # auto took the interior point: the start went unused
    warm = warm and not afresh
    first_residual = result.history[0][1] if result.history else np.nan
    newton_start = newton_start and r0 is not None
    unstable = unstable_g = unstable_held = 0
    unstable_groups = too_large = 0
    gravity_only_factor = 1.0
    stiffened_rounds = 0
    sweeps = result.sweeps
    # the margin stabilisation works on: the forces held fixed (default), or the supports held
    by_forces = settings.stable_under == "forces"

    last: dict = {}

    def margins(stiff: np.ndarray, carrying: np.ndarray, force: np.ndarray, changed=None) -> tuple:
        """(the margin stabilisation works on, free, always, groups, their margins, strands unchecked);
        ``changed``: only these strands' stiffness changed since the last call, with the same forces"""
        checked = stability_margins(helices, material, stiff, rows, contacts, carrying, force,
                                    strands=changed, previous=last.get("margins") if changed is not None else None,
                                    supported=not by_forces)
        last["margins"] = checked
        supported, free, always, fixed = checked
        if by_forces:  # stable on every motion is stable together too: no joint check of the groups
            groups, group_lam, too_large = [], np.zeros(0), 0
        else:
            groups, group_lam, too_large = group_margins(helices, material, stiff, rows, contacts, carrying, force)
        return (fixed if by_forces else supported), free, always, groups, group_lam, too_large

    if check_stability:
        margin, free, always, groups, group_lam, too_large = margins(stiff, carrying, result.r)
        base = np.ones(S) if factor is None else factor
        # the gravity-only inversion with the material's own stiffness: stable where base (1 - free) <= 1
        needed_free = base * np.maximum(1.0 - free, 0.0)
        unstable_g = int(np.count_nonzero(needed_free > 1.0 - _NEGATIVE)) if factor is not None \
            else int(np.count_nonzero(free < _NEGATIVE))
        gravity_only_factor = float(needed_free.max()) if S else 1.0
        unstable_held = int(np.count_nonzero(always < _NEGATIVE))
        if stabilize:
            for _ in range(STABILIZE_ROUNDS):
                weak = margin < _NEGATIVE
                weak_groups = [(g, lam) for g, lam in zip(groups, group_lam) if lam < _NEGATIVE]
                if not weak.any() and not weak_groups:
                    break
                before = factor.copy()
                factor[weak] *= (1.0 - margin[weak]) * settings.stiffen_margin
                # the groups that fall over together are stiffened uniformly, so that the closed form holds
                # for the group as for one strand (from the factors the check saw)
                for g, lam in weak_groups:
                    factor[g] = np.maximum(factor[g], before[g] * (1.0 - lam) * settings.stiffen_margin)
                stiff = stiffness(helices, material, factor)
                if by_forces:
                    # the margin depends on the stiffness and the forces alone, and these forces hold the
                    # input exactly at any stiffness (the rest shape below follows it): one round makes every
                    # strand stable. Solving again would move forces onto other strands and stiffen those in
                    # turn (a draped groom: 26 strands, factors up to 41, 8 times the sweeps, against 16 up
                    # to 4.3 this way)
                    changed = np.flatnonzero(factor != before)
                    margin, _, always, groups, group_lam, too_large = margins(stiff, carrying, result.r, changed)
                    continue
                result, carrying, _, gammas = solve(stiff, result.r, False)
                sweeps += result.sweeps
                stiffened_rounds += 1
                margin, _, always, groups, group_lam, too_large = margins(stiff, carrying, result.r)
        weak_together = np.zeros(S, dtype=bool)
        for g, lam in zip(groups, group_lam):
            if lam < _NEGATIVE:
                weak_together[g] = True
        unstable_groups = int(np.count_nonzero(group_lam < _NEGATIVE))
        unstable = int(np.count_nonzero((margin < _NEGATIVE) | weak_together))
        for g, lam in zip(groups, group_lam):  # a strand of a group unstable together is unstable
            margin[g] = np.minimum(margin[g], lam)
    r = result.r
    # q0 = q - K^-1 (F_g + H^T r), eq. (4), with the stiffness the strands were inverted with
    load = F_g + rows.rmatvec(r)
    omega_rest = (q - load / stiff).reshape(-1, 3)
    if not np.all(np.isfinite(omega_rest)):
        raise RunError("the inverted rest shape is not finite; check the material settings")
    # /model/omega_rest keeps its meaning for every reader: the rest shape that holds the input with these
    # forces at the material's own stiffness; the stiffened model's is stored beside it
    material_rest = omega_rest if factor is None else (q - load / stiffness(helices, material)).reshape(-1, 3)
    drift = omega_rest - target
    curvature = np.hypot(omega_rest[:, 0], omega_rest[:, 1])
    if declared != contacts.n_contacts:  # gravity-only: every declared contact carries no force
        r = np.zeros((declared, 3))
    prior = int(prior_sweeps) if warm else 0
    model = Model(material_rest, target, weight, r, material, float(settings.gamma), settings.target, result, prior,
                  factor, None if factor is None else omega_rest,
                  stability_margin=margin if check_stability else None, stable_under=settings.stable_under,
                  carrying_threshold=settings.tolerance * force_scale)
    if declared == contacts.n_contacts and settings.gamma_relative > 0.0:
        model.gamma_relative, model.contact_gamma = float(settings.gamma_relative), gammas
    report = InvertReport(
        settings.target, contacts.n_contacts, contacts.n_body, int(carrying.sum()), result, force_scale,
        float(np.sqrt(np.mean(np.sum(drift ** 2, axis=1)))) if len(drift) else 0.0,
        float(curvature.max()) if len(curvature) else 0.0, unstable, unstable_g, helices.n_strands,
        time.perf_counter() - started,
    )
    report.unstable_held = unstable_held
    report.stiffening = factor
    report.gravity_only_factor = gravity_only_factor
    report.youngs_modulus = material.youngs_modulus
    report.stiffened_rounds = stiffened_rounds
    report.total_sweeps = sweeps
    report.checked = check_stability
    report.unstable_groups = unstable_groups
    report.unchecked_together = too_large
    report.stable_under = settings.stable_under
    if not np.linalg.norm(material.gravity) > 0.0 and contacts.n_contacts:
        report.notes.append(f"the scene has no gravity: the solver's tolerance is relative to the heaviest strand's "
                            f"weight under {tolerance_gravity(material):g} m/s^2 ({force_scale:.3g} N)")
    report.notes += sorted(set(notes), key=notes.index)
    if afresh:
        report.notes.append("the interior-point method solved this groom afresh: it takes no starting forces (those "
                            "given were not used)")
    if warm:
        report.notes.append(f"the solver started from the given forces (after {prior} earlier sweeps), at relative "
                            f"residual {first_residual / force_scale:.2g}")
    elif newton_start:
        report.notes.append("no contact couples two strands: each strand's contacts were first solved together "
                            "(Newton on their block), and the sweeps started from those forces")
    if result.status != Status.CONVERGED and result.bound_from == "interior-point" and np.isfinite(result.rest_bound):
        report.notes.append(
            f"warning: the interior-point method stopped at {result.status} with the rest shape within "
            f"{result.rest_bound:.2g} 1/m of the optimum (solver.rest_tolerance {settings.rest_tolerance:g}); the "
            "model is an exact equilibrium, but its forces are not yet the best ones: raise solver.max_iterations "
            "(or solver.max_seconds) or solver.rest_tolerance")
    elif result.status != Status.CONVERGED and np.isfinite(result.rest_bound):
        report.notes.append(
            f"warning: the sweeps stopped at {result.status} with the rest shape within {result.rest_bound:.2g} "
            f"1/m of the optimum (solver.rest_tolerance {settings.rest_tolerance:g}; relative residual "
            f"{result.relative_residual:.2g}, solver.tolerance {settings.tolerance:g}); the model is an exact "
            "equilibrium, but its forces may not yet be the best ones: invert this model again to continue from "
            "its forces, or raise solver.max_sweeps (or solver.max_seconds) or solver.rest_tolerance, or solve to "
            "the optimum with --set solver.method=interior-point (docs/inverse.md)")
    elif result.status != Status.CONVERGED:
        report.notes.append(
            f"warning: the solver stopped at {result.status} with relative residual {result.relative_residual:.2g} "
            f"(tolerance {settings.tolerance:g}); the model is an exact equilibrium, but its forces are not yet the "
            "best ones: invert this model again to continue from its forces, or raise solver.max_sweeps "
            "(or solver.max_seconds) or the tolerance, or solve to the optimum with --set solver.method=interior-point "
            "(docs/inverse.md)")
    return model, report


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


def settings_dict(material: MaterialSettings, solver: SolverSettings) -> dict:
    return {"material": dataclasses.asdict(material), "solver": dataclasses.asdict(solver)}
