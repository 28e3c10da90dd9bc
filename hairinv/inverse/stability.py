"""The stability of an inverted equilibrium: is the input shape a minimum of the energy?

The Hessian of the total energy at ``q`` is ``K + d^2 V_g / dq^2`` (independent of ``q0``), plus the
held contact forces' own share. Per strand (:func:`stability_margins`, a numba kernel per chunk of
strands) the smallest eigenvalue of its scaled Hessian on the motions each check allows; per group of
strands leaning on each other (:func:`group_margins`) the same jointly. :mod:`hairinv.inverse.stabilize`
stiffens the strands these find unstable.
"""

from __future__ import annotations

import numpy as np

from .._jit import jit
from .._parallel import run_chunks
from ..model import UNSTABLE_MARGIN, Contacts, Helices, Material
from ..rod.statics import gravity_hessian, point_load_hessian
from ..contacts.rows import sides_by_strand
from ..solver.rows import ContactRows

__all__ = ["GROUP_DOFS", "group_margins", "stability", "stability_margins"]


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
    larger factor stable (:func:`hairinv.inverse.stabilize.check_and_stiffen`).

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
