"""The contact rows ``H_i`` of every contact, stored block-sparse: what the contact solver is handed.

Contact ``i``'s three rows (normal, tangent1, tangent2) act on the coordinates
of the one or two strands it touches (:mod:`hairinv.contacts.rows` builds them
from the rods' kinematics; the solver knows nothing of rods).

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

__all__ = ["ContactRows", "rows_matvec", "rows_rmatvec"]


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
        rows_matvec(self.ptr, self.cols, self.vals, f, out)
        return out

    def rmatvec(self, r: np.ndarray) -> np.ndarray:
        """``H^T r`` for ``r`` (C, 3), as (n,)."""
        out = np.zeros(self.n_dofs)
        rows_rmatvec(self.ptr, self.cols, self.vals, r, out)
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
def rows_matvec(ptr, cols, vals, f, out):
    """``out = H f`` (C, 3) for ``f`` (n,)."""
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
def rows_rmatvec(ptr, cols, vals, r, out):
    """``out += H^T r`` (n,) for ``r`` (C, 3)."""
    for i in range(ptr.shape[0] - 1):
        for j in range(ptr[i], ptr[i + 1]):
            out[cols[j]] += vals[j, 0] * r[i, 0] + vals[j, 1] * r[i, 1] + vals[j, 2] * r[i, 2]
