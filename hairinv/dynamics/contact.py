"""Frictional contact of one time step: the Delassus operator in factored form.

With the step's mass matrix ``Mt = L L^T`` (one Cholesky factor per strand)
the Delassus operator is ``W = H Mt^-1 H^T = Z^T Z`` with ``Z_i = L^-1 H_i^T``
(one forward substitution per contact side). The cone solver of the
inverse problem then runs unchanged on the rows ``Z_i^T`` with ``D = I``
and ``gamma = 0``: it keeps ``z = Z^T r`` per strand coordinate, so that
``(W r)_i = Z_i^T z``, and the velocity correction of the impulses is
``Mt^-1 H^T r = L^-T z`` (one back substitution per strand). Nothing global
is factorised; hair-hair contacts couple two strands only through ``W``.
"""

from __future__ import annotations

import numpy as np

from .._jit import jit
from ..solver.rows import ContactRows

__all__ = ["back_substitute", "contact_keys", "factored_rows"]


@jit
def _side_columns(strand, offsets):
    return 3 * offsets[strand], 3 * (offsets[strand + 1] - offsets[strand])


@jit
def _count_z(strand, offsets, counts):
    for i in range(strand.shape[0]):
        c = 0
        for side in range(2):
            k = strand[i, side]
            if k >= 0:
                c += 3 * (offsets[k + 1] - offsets[k])
        counts[i] = c


@jit
def _fill_z(ptr, cols, vals, strand, offsets, chol, chol_ptr, zptr, zcols, zvals, lo, hi):
    for i in range(lo, hi):
        j = zptr[i]
        for side in range(2):
            k = strand[i, side]
            if k < 0:
                continue
            a, n = _side_columns(k, offsets)
            x = np.zeros((n, 3))
            for t in range(ptr[i], ptr[i + 1]):
                c = cols[t] - a
                if 0 <= c < n:
                    for row in range(3):
                        x[c, row] += vals[t, row]
            base = chol_ptr[k]
            # forward substitution L x = h, L row-major n x n at chol[base:]
            for r in range(n):
                for row in range(3):
                    acc = x[r, row]
                    for m in range(r):
                        acc -= chol[base + r * n + m] * x[m, row]
                    x[r, row] = acc / chol[base + r * n + r]
            for r in range(n):
                zcols[j] = a + r
                for row in range(3):
                    zvals[j, row] = x[r, row]
                j += 1


def factored_rows(rows: ContactRows, strand: np.ndarray, offsets: np.ndarray, chol: np.ndarray,
                  chol_ptr: np.ndarray, run=None) -> ContactRows:
    """The rows ``Z_i^T = (L^-1 H_i^T)^T`` over every coordinate of the strands contact ``i`` touches.

    Parameters
    ----------
    rows : ContactRows, ``H``
    strand : (C, 2) int64, the strands of each contact (-1: the body)
    offsets : (S + 1,) int64, element offsets of the strands
    chol, chol_ptr : the strands' Cholesky factors, row-major, strand ``k`` at ``chol[chol_ptr[k]:]``
    run : optional ``run(work, count)`` spreading ``work(lo, hi)`` over threads
    """
    n_contacts = rows.n_contacts
    counts = np.zeros(n_contacts, dtype=np.int64)
    _count_z(strand, offsets, counts)
    zptr = np.zeros(n_contacts + 1, dtype=np.int64)
    np.cumsum(counts, out=zptr[1:])
    zcols = np.empty(zptr[-1], dtype=np.int64)
    zvals = np.empty((zptr[-1], 3))

    def work(lo: int, hi: int) -> None:
        _fill_z(rows.ptr, rows.cols, rows.vals, strand, offsets, chol, chol_ptr, zptr, zcols, zvals, lo, hi)

    if run is None or n_contacts == 0:
        work(0, n_contacts)
    else:
        run(work, n_contacts)
    return ContactRows(zptr, zcols, zvals, rows.n_dofs)


@jit
def back_substitute(offsets, chol, chol_ptr, z, out, lo, hi):
    """``out = L^-T z`` strand by strand for strands ``lo:hi`` (``z``, ``out`` over all coordinates)."""
    for k in range(lo, hi):
        a = 3 * offsets[k]
        n = 3 * (offsets[k + 1] - offsets[k])
        base = chol_ptr[k]
        for r in range(n - 1, -1, -1):
            acc = z[a + r]
            for m in range(r + 1, n):
                acc -= chol[base + m * n + r] * out[a + m]
            out[a + r] = acc / chol[base + r * n + r]


def contact_keys(strand: np.ndarray, s: np.ndarray, offsets: np.ndarray, length: np.ndarray) -> np.ndarray:
    """A key per contact that persists from step to step while the contact does, (C,) int64.

    Detection declares at most one body contact per element and one hair-hair
    contact per pair of elements, so the element (pair) names the contact:
    ``e_A`` for a body contact, ``E (1 + e_A) + e_B`` for a hair-hair one.
    """
    n_elements = int(offsets[-1])
    counts = np.diff(offsets)
    strand_of = np.repeat(np.arange(len(counts)), counts)
    cumulative = np.concatenate([[0.0], np.cumsum(length)])
    total = cumulative[offsets[1:]] - cumulative[offsets[:-1]]
    span = np.where(total > 0, total, 1.0) * (1.0 + 1e-9)
    # element starts as (strand + fraction of its length): one sorted array over all strands
    position = strand_of + (cumulative[:-1] - cumulative[offsets[:-1]][strand_of]) / span[strand_of]

    def element(k: np.ndarray, arc: np.ndarray) -> np.ndarray:
        where = k + np.clip(arc, 0.0, total[k]) / span[k]
        return np.clip(np.searchsorted(position, where, side="right") - 1, offsets[k], offsets[k + 1] - 1)

    keys = element(strand[:, 0], s[:, 0])
    hair = strand[:, 1] >= 0
    if hair.any():
        keys[hair] = n_elements * (1 + keys[hair]) + element(strand[hair, 1], s[hair, 1])
    return keys
