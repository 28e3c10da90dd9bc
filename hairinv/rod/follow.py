"""Render strands carried by guide strands: the kernels of :mod:`hairinv.follow`.

A render strand's vertex ``i`` at normalized arc length ``u_i`` is bound to each of its guides ``g`` at the
guide's point of the same normalized arc length, ``s = u_i L_g``: its offset from that point in the guide's
material frame there, ``d = F_g(s) (x_i - x_g(s))`` (rows ``t, n1, n2``: ``d`` holds the components along
them). When the guide moves to another shape, the vertex it predicts is ``x_g'(s) + F_g'(s)^T d``, and the
render vertex is the weighted sum of its guides' predictions.

Every kernel takes contiguous float64/int64 arrays and writes into arrays the caller allocated.
"""

from __future__ import annotations

import numpy as np

from .._jit import jit, pjit, prange
from .helix import chain, element_step, helix_coefficients

__all__ = ["guide_chains", "bind_offsets", "curve_distances", "follow_points"]


@pjit
def guide_chains(root, frame0, offsets, omega, length, xs, Fs, starts):
    """Start point, frame and arc length of every element of every guide, and each guide's tip.

    Parameters
    ----------
    root : (G, 3) float64, m
    frame0 : (G, 3, 3) float64, rows (t, n1, n2)
    offsets : (G + 1,) int64, CSR offsets into ``omega`` and ``length``
    omega : (E, 3) float64, 1/m
    length : (E,) float64, m
    xs : (E + G, 3) float64, out: guide ``g``'s element ``e`` (global) starts at ``xs[e + g]``; its tip is
        ``xs[offsets[g + 1] + g]``
    Fs : (E + G, 3, 3) float64, out: the frames at the same places
    starts : (E + G,) float64, out, m: the arc lengths of the same places from the guide's root
    """
    for g in prange(offsets.shape[0] - 1):
        a = offsets[g]
        z = offsets[g + 1]
        chain(root[g], frame0[g], omega[a:z], length[a:z], xs[a + g:z + g + 1], Fs[a + g:z + g + 1])
        starts[a + g] = 0.0
        for e in range(a, z):
            starts[e + g + 1] = starts[e + g] + length[e]


@jit
def _guide_point(xs, Fs, starts, offsets, omega, g, u, at_root, R, P, Q, x, F):
    """Point ``x`` (3,) of guide ``g`` at normalized arc length ``u`` (clamped to [0, 1]), from its chain
    (:func:`guide_chains`), and ``F`` (3, 3) its material frame there, or its root frame if ``at_root``."""
    a = offsets[g]
    z = offsets[g + 1]
    total = starts[z + g]
    s = min(max(u, 0.0), 1.0) * total
    e = a
    while e < z - 1 and starts[e + g + 1] <= s:
        e += 1
    row = e + g
    sigma = s - starts[row]
    if at_root:  # the point alone: P of element_step, without the frame's turn
        w0 = omega[e, 2]
        w1 = omega[e, 0]
        w2 = omega[e, 1]
        ww = w0 * w0 + w1 * w1 + w2 * w2
        s2 = sigma * sigma
        _, B, C, _ = helix_coefficients(ww * s2)
        c3 = s2 * sigma * C
        P[0] = sigma + c3 * (w0 * w0 - ww)
        P[1] = s2 * B * w2 + c3 * w0 * w1
        P[2] = -s2 * B * w1 + c3 * w0 * w2
    else:
        element_step(omega[e, 2], omega[e, 0], omega[e, 1], sigma, R, P, Q)
    for i in range(3):
        acc = 0.0
        for k in range(3):
            acc += Fs[row, k, i] * P[k]
        x[i] = xs[row, i] + acc
    if at_root:
        for i in range(3):
            for j in range(3):
                F[i, j] = Fs[a + g, i, j]
        return
    # F = R^T Fs[row]: the element's start frame turned by the step
    for i in range(3):
        for j in range(3):
            acc = 0.0
            for k in range(3):
                acc += R[k, i] * Fs[row, k, j]
            F[i, j] = acc


@pjit
def bind_offsets(xs, Fs, starts, offsets, omega, r_offsets, u, points, guide, at_root, local):
    """Each render vertex's offset from each of its guides in the guide's frame: ``F_g(s) (x_i - x_g(s))``.

    Parameters
    ----------
    xs, Fs, starts : the guides' chains (:func:`guide_chains`) in the pose the render strands are bound in
    offsets : (G + 1,) int64, the guides' element offsets
    omega : (E, 3) float64, the guides' shapes in that pose, 1/m
    r_offsets : (R + 1,) int64, CSR offsets of the render vertices
    u : (P,) float64, each render vertex's normalized arc length along its strand, in [0, 1]
    points : (P, 3) float64, m, the render vertices in that pose
    guide : (R, K) int64, each render strand's guides (-1: none in that slot)
    local : (P, K, 3) float64, out, m: the offsets (0 where the slot holds no guide)
    """
    K = guide.shape[1]
    for r in prange(r_offsets.shape[0] - 1):
        R = np.empty((3, 3))
        P = np.empty(3)
        Q = np.empty(3)
        x = np.empty(3)
        F = np.empty((3, 3))
        for i in range(r_offsets[r], r_offsets[r + 1]):
            for j in range(K):
                g = guide[r, j]
                if g < 0:
                    for c in range(3):
                        local[i, j, c] = 0.0
                    continue
                _guide_point(xs, Fs, starts, offsets, omega, g, u[i], at_root, R, P, Q, x, F)
                for c in range(3):
                    local[i, j, c] = (F[c, 0] * (points[i, 0] - x[0]) + F[c, 1] * (points[i, 1] - x[1])
                                      + F[c, 2] * (points[i, 2] - x[2]))


@pjit
def follow_points(xs, Fs, starts, offsets, omega, r_offsets, u, guide, weight, at_root, local, out):
    """The render vertices carried by their guides in another pose: ``sum_g w_g (x_g(s) + F_g(s)^T d_g)``.

    Parameters
    ----------
    xs, Fs, starts : the guides' chains (:func:`guide_chains`) in the new pose
    offsets, omega : the guides' element offsets and shapes in the new pose
    r_offsets, u, guide : as for :func:`bind_offsets`
    weight : (R, K) float64, each guide's weight (summing to 1 over a strand's guides)
    local : (P, K, 3) float64, m, the offsets :func:`bind_offsets` gave
    out : (P, 3) float64, out, m
    """
    K = guide.shape[1]
    for r in prange(r_offsets.shape[0] - 1):
        R = np.empty((3, 3))
        P = np.empty(3)
        Q = np.empty(3)
        x = np.empty(3)
        F = np.empty((3, 3))
        for i in range(r_offsets[r], r_offsets[r + 1]):
            o0 = 0.0
            o1 = 0.0
            o2 = 0.0
            for j in range(K):
                g = guide[r, j]
                w = weight[r, j]
                if g < 0 or w == 0.0:
                    continue
                _guide_point(xs, Fs, starts, offsets, omega, g, u[i], at_root, R, P, Q, x, F)
                d0 = local[i, j, 0]
                d1 = local[i, j, 1]
                d2 = local[i, j, 2]
                o0 += w * (x[0] + F[0, 0] * d0 + F[1, 0] * d1 + F[2, 0] * d2)
                o1 += w * (x[1] + F[0, 1] * d0 + F[1, 1] * d1 + F[2, 1] * d2)
                o2 += w * (x[2] + F[0, 2] * d0 + F[1, 2] * d1 + F[2, 2] * d2)
            out[i, 0] = o0
            out[i, 1] = o1
            out[i, 2] = o2


@pjit
def curve_distances(xs, Fs, starts, offsets, omega, r_offsets, u, points, candidate, out):
    """Each render strand's mean distance to each of its candidate guides, point by point at the same
    normalized arc length: ``mean_i |x_i - x_g(u_i L_g)|``.

    Parameters
    ----------
    xs, Fs, starts, offsets, omega, r_offsets, u, points : as for :func:`bind_offsets`
    candidate : (R, M) int64, the guides to measure each render strand against
    out : (R, M) float64, out, m
    """
    M = candidate.shape[1]
    for r in prange(r_offsets.shape[0] - 1):
        R = np.empty((3, 3))
        P = np.empty(3)
        Q = np.empty(3)
        x = np.empty(3)
        F = np.empty((3, 3))
        count = r_offsets[r + 1] - r_offsets[r]
        for j in range(M):
            g = candidate[r, j]
            total = 0.0
            for i in range(r_offsets[r], r_offsets[r + 1]):
                _guide_point(xs, Fs, starts, offsets, omega, g, u[i], True, R, P, Q, x, F)
                total += np.sqrt((points[i, 0] - x[0]) ** 2 + (points[i, 1] - x[1]) ** 2 + (points[i, 2] - x[2]) ** 2)
            out[r, j] = total / max(count, 1)
