"""Contact Jacobian rows ``H_i`` of every contact, from the rods' kinematics.

Contact ``i`` acts on strand A at arc length ``s_A`` and, for a hair-hair
contact, with the opposite force on strand B at ``s_B``. Its three rows
(normal, tangent1, tangent2) are ``H_i = C_i (J_A(s_A) - J_B(s_B))`` where
``C_i`` is the contact frame and ``J(s)`` the Jacobian of the centerline
point w.r.t. the strand's coordinates: non-zero only for the elements up to
the one holding ``s`` (the rigid-downstream property), so a contact near the
root costs a few columns and one at the tip a strand's worth. They are stored
as :class:`hairinv.solver.rows.ContactRows` (its docstring gives the layout),
the form the contact solver takes.
"""

from __future__ import annotations

import numpy as np

from .._jit import jit
from ..rod.helix import chain
from ..rod.statics import chained_point_jacobian
from ..solver.rows import ContactRows

__all__ = ["contact_rows", "sides_by_strand"]


@jit
def _side_width(offsets, length, strand, s):
    """Columns a contact side touches: 3 x (index of the element holding s, + 1)."""
    lo = offsets[strand]
    hi = offsets[strand + 1]
    start = 0.0
    for e in range(hi - lo):
        if s < start + length[lo + e] or e == hi - lo - 1:
            return 3 * (e + 1)
        start += length[lo + e]
    return 3


@jit
def _count(offsets, length, strand, s, counts, first_width):
    for i in range(strand.shape[0]):
        c = _side_width(offsets, length, strand[i, 0], s[i, 0])
        first_width[i] = c
        if strand[i, 1] >= 0:
            c += _side_width(offsets, length, strand[i, 1], s[i, 1])
        counts[i] = c


@jit
def _write_side(J, e_s, lo, frame, sign, ptr_at, cols, vals):
    j = ptr_at
    for e in range(e_s + 1):
        for k in range(3):
            cols[j] = 3 * (lo + e) + k
            for row in range(3):
                vals[j, row] = sign * (frame[row, 0] * J[e, k, 0] + frame[row, 1] * J[e, k, 1]
                                       + frame[row, 2] * J[e, k, 2])
            j += 1
    return j


@jit
def _fill(root, frame0, offsets, omega, length, strand, s, frame, ptr, cols, vals, first_width, order, lo, hi):
    """The entries of the contact sides ``order[lo:hi]`` (:func:`sides_by_strand`: side ``2 i + w`` is contact
    ``i``'s strand A, ``w`` 0, or B, ``w`` 1); consecutive sides on one strand share its element chain and
    element derivatives."""
    last = -1
    xs = np.empty((1, 3))
    Fs = np.empty((1, 3, 3))
    dX = np.empty((1, 3, 3))
    dTh = np.empty((1, 3, 3))
    done = 0
    for t in range(lo, hi):
        i = order[t] // 2
        which = order[t] % 2
        a = strand[i, which]
        first = offsets[a]
        n = offsets[a + 1] - first
        if a != last:
            xs = np.empty((n + 1, 3))
            Fs = np.empty((n + 1, 3, 3))
            chain(root[a], frame0[a], omega[first:first + n], length[first:first + n], xs, Fs)
            dX = np.empty((n, 3, 3))
            dTh = np.empty((n, 3, 3))
            done = 0
            last = a
        J = np.empty((n, 3, 3))
        e_s = chained_point_jacobian(xs, Fs, omega[first:first + n], length[first:first + n], dX, dTh, done,
                                     s[i, which], J)
        done = max(done, e_s)
        if which == 0:
            _write_side(J, e_s, first, frame[i], 1.0, ptr[i], cols, vals)
        else:  # B's columns follow A's, with the opposite force
            _write_side(J, e_s, first, frame[i], -1.0, ptr[i] + first_width[i], cols, vals)


def sides_by_strand(strand: np.ndarray) -> np.ndarray:
    """Every contact side, ordered by its strand (stably: by contact within a strand). Side ``2 i + w`` is
    contact ``i``'s strand A where ``w`` is 0, its strand B where 1 (a body contact has no side B)."""
    flat = np.asarray(strand, dtype=np.int64).ravel()
    sides = np.flatnonzero(flat >= 0)
    return sides[np.argsort(flat[sides], kind="stable")]


def contact_rows(helices, contacts, run=None) -> ContactRows:
    """Assemble ``H`` for ``contacts`` on ``helices`` (see the module docstring).

    ``run(work, count)`` optionally runs ``work(lo, hi)`` over chunks of
    contact sides (on threads); each chunk writes only its own entries.
    """
    n_contacts = len(contacts.mu)
    counts = np.zeros(n_contacts, dtype=np.int64)
    first_width = np.zeros(n_contacts, dtype=np.int64)
    _count(helices.offsets, helices.length, contacts.strand, contacts.s, counts, first_width)
    ptr = np.zeros(n_contacts + 1, dtype=np.int64)
    np.cumsum(counts, out=ptr[1:])
    cols = np.empty(ptr[-1], dtype=np.int64)
    vals = np.empty((ptr[-1], 3))

    # every contact side grouped by strand: a strand's sides share its chain, whichever side of their
    # contacts they are (a hair-hair contact's B once took a chain of its own)
    order = sides_by_strand(contacts.strand)

    def work(lo: int, hi: int) -> None:
        _fill(helices.root, helices.frame0, helices.offsets, helices.omega, helices.length,
              contacts.strand, contacts.s, contacts.frame, ptr, cols, vals, first_width, order, lo, hi)

    if run is None or n_contacts == 0:
        work(0, len(order))
    else:
        run(work, len(order))
    return ContactRows(ptr, cols, vals, 3 * helices.n_elements)
