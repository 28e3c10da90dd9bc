"""Kernels that evaluate the fitted centerlines for detection: element starts, samples, points and tangents.

Sample ``k`` of an element of length ``l`` with ``n`` samples sits at
``sigma_k = l k / (n - 1)``: both ends are samples, and the last one is the
next element's first.
"""

from __future__ import annotations

import numpy as np

from .._jit import jit
from ..rod.helix import chain, element_step


@jit
def sample_sigma(length, k, n):
    """Arc length of sample ``k`` of ``n`` along an element of ``length`` (the end exactly ``length``)."""
    if k >= n - 1:
        return length
    return length * k / (n - 1)


@jit
def element_starts(root, frame0, offsets, omega, length, lo, hi, xs, Fs, s0):
    """Start point, frame and arc length of every element of strands ``lo:hi``.

    Parameters
    ----------
    root : (S, 3) float64, m
    frame0 : (S, 3, 3) float64, rows (t, n1, n2)
    offsets : (S + 1,) int64
    omega : (E, 3) float64, 1/m
    length : (E,) float64, m
    xs : (E, 3) float64, out, m
    Fs : (E, 3, 3) float64, out
    s0 : (E,) float64, out, m, arc length of each element's start from its root
    """
    for i in range(lo, hi):
        a = offsets[i]
        b = offsets[i + 1]
        n = b - a
        x = np.empty((n + 1, 3))
        F = np.empty((n + 1, 3, 3))
        chain(root[i], frame0[i], omega[a:b], length[a:b], x, F)
        acc = 0.0
        for e in range(n):
            xs[a + e] = x[e]
            Fs[a + e] = F[e]
            s0[a + e] = acc
            acc += length[a + e]


@jit
def point_tangent(x0, F, om, sigma, R, P, Q, x_out, t_out):
    """Centerline point and unit tangent after ``sigma`` along an element starting at ``(x0, F)``.

    ``R`` (3, 3), ``P`` and ``Q`` (3,) are scratch. Same arithmetic as the
    chain's own step, so the end of an element is bit-identical to the start
    of the next.
    """
    element_step(om[2], om[0], om[1], sigma, R, P, Q)
    for i in range(3):
        acc = 0.0
        for k in range(3):
            acc += F[k, i] * P[k]
        x_out[i] = x0[i] + acc
    for j in range(3):
        acc = 0.0
        for k in range(3):
            acc += R[k, 0] * F[k, j]
        t_out[j] = acc


@jit
def sample_elements(xs, Fs, omega, length, lo, hi, out):
    """Centerline samples ``out[e, k]`` (E, n, 3) of elements ``lo:hi``, m."""
    n = out.shape[1]
    R = np.empty((3, 3))
    P = np.empty(3)
    Q = np.empty(3)
    t = np.empty(3)
    for e in range(lo, hi):
        for k in range(n):
            point_tangent(xs[e], Fs[e], omega[e], sample_sigma(length[e], k, n), R, P, Q, out[e, k], t)
