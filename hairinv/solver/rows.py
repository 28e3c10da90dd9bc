"""Contact Jacobian rows ``H_i`` of every contact, stored block-sparse.

Contact ``i`` acts on strand A at arc length ``s_A`` and, for a hair-hair
contact, with the opposite force on strand B at ``s_B``. Its three rows
(normal, tangent1, tangent2) are ``H_i = C_i (J_A(s_A) - J_B(s_B))`` where
``C_i`` is the contact frame and ``J(s)`` the Jacobian of the centerline
point w.r.t. the strand's coordinates: non-zero only for the elements up to
the one holding ``s`` (the rigid-downstream property), so a contact near the
root costs a few columns and one at the tip a strand's worth.

Layout: ``ptr`` (C + 1,) int64 offsets into ``cols`` (int64, a column of
the global coordinate vector ``q``: element ``e``, component ``k`` is
``3 e + k``) and ``vals`` ((nnz, 3) float64, the three rows' entries for that
column). All rows of a contact share the same columns, so the diagonal block
``W_ii = H_i D H_i^T + gamma I`` and the products ``H_i f`` and
``H_i^T d`` are short loops over one list of columns.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse

from .._jit import jit
from .._parallel import run_chunks
from ..rod.helix import chain
from ..rod.statics import chained_point_jacobian

__all__ = ["ContactRows", "contact_rows", "sides_by_strand"]


class ContactRows:
    """Block-sparse ``H`` (3C x n): ``ptr``, ``cols``, ``vals`` as in the module docstring."""

    def __init__(self, ptr: np.ndarray, cols: np.ndarray, vals: np.ndarray, n_dofs: int):
        self.ptr = ptr
        self.cols = cols
        self.vals = vals
        self.n_dofs = int(n_dofs)

    @property
    def n_contacts(self) -> int:
        return len(self.ptr) - 1

    def to_sparse(self) -> scipy.sparse.csr_matrix:
        """The same matrix as scipy CSR (3C x n), for reference solvers and tests."""
        counts = np.diff(self.ptr)
        rows = (3 * np.repeat(np.arange(self.n_contacts), counts))[:, None] + np.arange(3)[None, :]
        cols = np.repeat(self.cols[:, None], 3, axis=1)
        return scipy.sparse.csr_matrix(
            (self.vals.ravel(), (rows.ravel(), cols.ravel())), shape=(3 * self.n_contacts, self.n_dofs)
        )

    def matvec(self, f: np.ndarray) -> np.ndarray:
        """``H f`` as (C, 3)."""
        out = np.zeros((self.n_contacts, 3))
        _rows_matvec(self.ptr, self.cols, self.vals, f, out)
        return out

    def rmatvec(self, r: np.ndarray) -> np.ndarray:
        """``H^T r`` for ``r`` (C, 3), as (n,)."""
        out = np.zeros(self.n_dofs)
        _rows_rmatvec(self.ptr, self.cols, self.vals, r, out)
        return out

    def take(self, order: np.ndarray) -> "ContactRows":
        """The rows of the contacts ``order`` (1-D integer indices: a permutation, or any selection), stored in
        that order: contact ``t`` of the result is contact ``order[t]`` of this one."""
        order = np.asarray(order)
        if order.ndim != 1 or not np.issubdtype(order.dtype, np.integer):
            raise TypeError(f"contact indices must be a 1-D integer array, got {order.dtype} of shape {order.shape}")
        order = np.ascontiguousarray(order, dtype=np.int64)
        if len(order) and (order.min() < 0 or order.max() >= self.n_contacts):
            raise IndexError(f"contact indices must lie in [0, {self.n_contacts}), got {order.min()} to {order.max()}")
        ptr = np.zeros(len(order) + 1, dtype=np.int64)
        np.cumsum(np.diff(self.ptr)[order], out=ptr[1:])
        cols = np.empty(ptr[-1], dtype=np.int64)
        vals = np.empty((ptr[-1], 3))
        # on the worker threads: the copy is bound by memory (and by first touching the new pages), not by
        # arithmetic; one million synthetic contacts' rows, new pages: 3.0 s on one thread, 1.7 s on two
        run_chunks(lambda lo, hi: _take_rows(order, lo, hi, self.ptr, self.cols, self.vals, ptr, cols, vals),
                   len(order), 65536)
        return ContactRows(ptr, cols, vals, self.n_dofs)


@jit
def _rows_matvec(ptr, cols, vals, f, out):
    for i in range(ptr.shape[0] - 1):
        a0 = 0.0
        a1 = 0.0
        a2 = 0.0
        for j in range(ptr[i], ptr[i + 1]):
            fj = f[cols[j]]
            a0 += vals[j, 0] * fj
            a1 += vals[j, 1] * fj
            a2 += vals[j, 2] * fj
        out[i, 0] = a0
        out[i, 1] = a1
        out[i, 2] = a2


@jit
def _take_rows(order, lo, hi, ptr, cols, vals, new_ptr, new_cols, new_vals):
    """Rows ``lo:hi`` of the result: the rows of contacts ``order[lo:hi]``, at ``new_ptr``."""
    for t in range(lo, hi):
        i = order[t]
        at = new_ptr[t]
        for j in range(ptr[i], ptr[i + 1]):
            new_cols[at] = cols[j]
            new_vals[at, 0] = vals[j, 0]
            new_vals[at, 1] = vals[j, 1]
            new_vals[at, 2] = vals[j, 2]
            at += 1


@jit
def _rows_rmatvec(ptr, cols, vals, r, out):
    for i in range(ptr.shape[0] - 1):
        for j in range(ptr[i], ptr[i + 1]):
            out[cols[j]] += vals[j, 0] * r[i, 0] + vals[j, 1] * r[i, 1] + vals[j, 2] * r[i, 2]


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
