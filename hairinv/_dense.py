"""Small dense linear algebra in numba kernels: Cholesky factorisation and solves of the few-by-few
symmetric positive definite systems that per-element and per-strand solves meet, without the overhead of
a LAPACK call per system."""

from __future__ import annotations

import numpy as np

from ._jit import jit


@jit
def cholesky(A, L):
    """Lower Cholesky factor of the symmetric ``A`` into ``L`` (only its lower triangle is read and
    written); False if ``A`` is not positive definite."""
    n = A.shape[0]
    for j in range(n):
        d = A[j, j]
        for k in range(j):
            d -= L[j, k] * L[j, k]
        if not d > 0.0:
            return False
        L[j, j] = np.sqrt(d)
        for i in range(j + 1, n):
            acc = A[i, j]
            for k in range(j):
                acc -= L[i, k] * L[j, k]
            L[i, j] = acc / L[j, j]
    return True


@jit
def cholesky_solve(L, b, out):
    """Solve ``L L^T out = b`` for a lower Cholesky factor ``L``."""
    n = b.shape[0]
    for i in range(n):
        v = b[i]
        for k in range(i):
            v -= L[i, k] * out[k]
        out[i] = v / L[i, i]
    for i in range(n - 1, -1, -1):
        v = out[i]
        for k in range(i + 1, n):
            v -= L[k, i] * out[k]
        out[i] = v / L[i, i]
