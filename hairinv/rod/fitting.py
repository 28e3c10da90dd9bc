"""Kernels that fit G1 piecewise super-helices to polylines.

One strand at a time (strands are independent, so the batch runs them in
parallel with deterministic results):

1. Elements chosen along the strand (the adaptive fit): from the root,
   each element is as long as one helix started where the previous one
   ended fits its vertices within the tolerance at their arc lengths (found
   by doubling, then bisection over the vertex count; the helix started from
   the best of the previous element's omega, the polyline's screw rotation
   and a circular arc, refined by a small Levenberg-Marquardt solve that
   also holds its end tangent near the polyline's). The vertices keep their
   arc lengths (exact on circles and helices, :func:`_arc_lengths`), so no
   element winds between vertices, and a curl gets as many elements as it
   needs, never more than the vertices determine (:func:`element_cap`). A
   fixed element count starts instead from equal elements, each aimed at the
   polyline point at its end.
2. Global refinement where the tolerance is not met yet, an orthogonal-distance
   fit: Levenberg-Marquardt on all
   ``(kappa1, kappa2, tau)``, the root tangent (2 angles: the roll about the
   tangent is a gauge freedom of an isotropic rod and stays fixed) and the
   strand length. Interior vertices are matched to their closest curve point
   (Newton on their arc length), the tip vertex to the curve's end, so a
   polyline sampled from a super-helix is recovered exactly even though its
   chord lengths are shorter than the arc. The Jacobian is exact: a change of
   element ``e`` moves everything downstream rigidly about the end of ``e``,
   which also lets the normal equations be summed without forming it
   (:func:`_normal_equations`, O(M + n^2) instead of O(M n^2)).
   Where the vertices need more elements than the strand may carry and noise dominates them (a
   capture's scatter, :func:`_scatter`), the elements aim at what the noise leaves instead, and one
   least-squares solve over the strand puts the curve through the middle of the noise.
3. Adaptive size, if the tolerance is still not met: elements holding a
   vertex farther than the tolerance are split in two. A split element with
   unchanged omega is the same curve, so each refinement starts from the
   previous optimum; a refit from equal elements is kept if it is better.

Kernels return status codes instead of raising.
"""

from __future__ import annotations

import numpy as np

from .._dense import cholesky, cholesky_solve
from .._jit import jit
from .helix import _advance, chain, element_derivatives, element_step

__all__ = ["fit_batch", "fit_adaptive", "closest_distances", "element_cap", "element_caps", "sampling_figures",
           "FIT_OK", "FIT_TOLERANCE_NOT_MET"]

FIT_OK = 0
FIT_TOLERANCE_NOT_MET = 1

# Levenberg-Marquardt stops when an accepted step lowers the cost by less
# than this fraction: zero-residual fits converge quadratically to round-off
# long before, real data stagnate here.
_RELATIVE_DECREASE = 1e-7
_PROJECTION_NEWTON = 8
# Marquardt scaling floor, relative to the largest diagonal entry: parameters
# the data do not see (the twist of a straight element) are damped instead of
# drifting on round-off.
_DAMPING_FLOOR = 1e-6
# Priors that choose, among fits within tolerance, a physically plausible one:
# - least bending: a residual eta * length_e * omega_e (m) per element with
#   eta = _PRIOR_OF_TOLERANCE * tolerance (a one-radian bend or twist across
#   an element weighs like 5% of the tolerance), so the twist the curve does
#   not see (straight parts, inflection points) stays at zero;
# - a curvature cap: a residual _CAP_WEIGHT * tolerance * length_e *
#   max(0, |omega_e| - cap) with cap = _CAP_FACTOR times the strand's largest
#   discrete curvature, so no element winds into a tight corkscrew that draws
#   a nearly straight piece within tolerance.
# With tolerance 0 (exact recovery) both vanish.
_PRIOR_OF_TOLERANCE = 0.05
_CAP_WEIGHT = 10.0
_CAP_FACTOR = 3.0
# Bounds of the arc between consecutive matched points, per unit distance
# between the vertices (a smooth curve sampled at under ~40 degrees per
# vertex has an arc within 2% of the chord).
_MIN_ARC_PER_CHORD = 0.5
_MAX_ARC_PER_CHORD = 1.5
# The look-ahead of the second initial guess, in element lengths.
_LOOK_AHEAD = 0.5
# Elements chosen along the strand hold their end tangent near the polyline's: a tangent off by delta
# weighs like a vertex off by delta times this fraction of the next segment's length.
_TANGENT_WEIGHT = 0.5
# Where the strand coils (chords turning evenly by at least _COIL_TURN rad about a screw axis, the turns
# at consecutive vertices within a factor _EVEN_TURNING), the tangent estimate is exact on a helix and the
# end tangent sets the phase of the whole next element: it is held _COIL_TANGENT_GAIN times as firmly.
_COIL_TURN = 0.35
_EVEN_TURNING = 1.25
_COIL_TANGENT_GAIN = 4.0
_NO_TANGENT = np.zeros(3)
# Each element chosen along the strand fits its vertices within this fraction of the tolerance: the
# largest distance meets the tolerance with room, and the mean stays near a quarter of it.
_GREEDY_WITHIN = 0.5
# An element trial whose Levenberg-Marquardt still leaves a vertex beyond _GIVE_UP times the accepted
# distance after _GIVE_UP_AFTER iterations is abandoned: trials that end within the distance were all
# below 1.7 times it by their third iteration on the test grooms of bench/fit_grooms.py.
_GIVE_UP = 2.0
_GIVE_UP_AFTER = 3
# Vertices that scatter about a smooth curve (a capture's noise): below this correlation of consecutive
# deviations from the chords (:func:`_scatter`: about -2/3 for white noise, cos(2 pi / n) on a coil at n
# points per turn), noise dominates, and the fit follows the smooth curve instead of the noise: its
# elements may pass sigma * sqrt(2 ln M + _NOISE_MARGIN) from a vertex (the largest of M Rayleigh
# distances is sigma sqrt(2 ln M) on average; the margin leaves about one strand in eight over it).
_NOISE_GATE = 0.0
_NOISE_MARGIN = 4.0
# Noise is told from shape only on strands of at least this many vertices: on a coarse guide of 16 (10 mm
# chords), a wiggle's deviations from the chords anticorrelate too, and a median of a dozen third
# differences estimates the wiggle, not a noise.
_NOISE_MIN_VERTICES = 24
# There the least-squares fit stops once a step lowers the cost by less than this fraction: the curve then
# moves by far less than the noise.
_NOISY_DECREASE = 1e-4


@jit
def _cross_add(a, b, out, scale):
    out[0] += scale * (a[1] * b[2] - a[2] * b[1])
    out[1] += scale * (a[2] * b[0] - a[0] * b[2])
    out[2] += scale * (a[0] * b[1] - a[1] * b[0])


@jit
def _locate(starts, s):
    """Element index and local arc length of arc length ``s``."""
    n = starts.shape[0] - 1
    e = np.searchsorted(starts, s, side="right") - 1
    if e > n - 1:
        e = n - 1
    if e < 0:
        e = 0
    return e, s - starts[e]


@jit
def _starts(length, starts):
    starts[0] = 0.0
    for e in range(length.shape[0]):
        starts[e + 1] = starts[e] + length[e]


@jit
def _darboux_world(omega_e, F):
    """World Darboux vector ``Om = tau t + kappa1 n1 + kappa2 n2`` of an element."""
    return omega_e[2] * F[0] + omega_e[0] * F[1] + omega_e[1] * F[2]


@jit
def _projection_step(omega_e, F_start, F, diff):
    """Newton step on the arc length towards the curve point nearest a vertex.

    Stationarity of ``|x(s) - p|^2``: ``g = t . (x - p)``, ``g' = 1 + (Om x t) . (x - p)``
    with ``Om`` the element's world Darboux vector; a gradient step where
    ``g'`` is small (far from a minimum). ``F`` is the frame at the current
    point, ``F_start`` the element's start frame, ``diff = x - p``.
    """
    Om = _darboux_world(omega_e, F_start)
    h = 1.0
    h += (Om[1] * F[0, 2] - Om[2] * F[0, 1]) * diff[0]
    h += (Om[2] * F[0, 0] - Om[0] * F[0, 2]) * diff[1]
    h += (Om[0] * F[0, 1] - Om[1] * F[0, 0]) * diff[2]
    if h < 0.2:
        h = 1.0
    return (F[0] @ diff) / h


@jit
def _residual(root, F0, omega, length, s, p, project, xs, Fs, starts, r, tang):
    """Orthogonal-distance residuals of one strand.

    Interior vertices are projected on the curve (Newton on their arc length
    ``s[j]``, started from its current value, updated in place); the root sits
    at ``s = 0`` and the tip vertex is matched to the curve's end. Writes
    ``r`` (3 (M - 1),) and the unit tangents ``tang`` at the matched points;
    returns the cost ``1/2 |r|^2``.
    """
    m = s.shape[0]
    chain(root, F0, omega, length, xs, Fs)
    _starts(length, starts)
    total = starts[starts.shape[0] - 1]
    x = np.empty(3)
    F = np.empty((3, 3))
    R = np.empty((3, 3))
    P = np.empty(3)
    Q = np.empty(3)
    cost = 0.0
    s[m - 1] = total
    for j in range(1, m):
        sj = min(max(s[j], 0.0), total)
        iterations = project if j < m - 1 else 0
        if project < 0:
            iterations = 0
        for it in range(iterations + 1):
            e, sig = _locate(starts, sj)
            _advance(xs[e], Fs[e], omega[e], sig, x, F, R, P, Q)
            if it == iterations:
                break
            new = min(max(sj - _projection_step(omega[e], Fs[e], F, x - p[j]), 0.0), total)
            if new == sj:
                break
            sj = new
        if project > 0 and j < m - 1:
            # Keep the arc between consecutive matched points near the distance
            # between the vertices: a curve that winds a loop between two
            # close vertices must not be free (the vertices would still be
            # close to it, but the shape between them would be invented).
            d = np.sqrt((p[j, 0] - p[j - 1, 0]) ** 2 + (p[j, 1] - p[j - 1, 1]) ** 2 + (p[j, 2] - p[j - 1, 2]) ** 2)
            lo = s[j - 1] + _MIN_ARC_PER_CHORD * d
            hi = s[j - 1] + _MAX_ARC_PER_CHORD * d
            if sj < lo or sj > hi:
                sj = min(max(sj, lo), min(hi, total))
                e, sig = _locate(starts, sj)
                _advance(xs[e], Fs[e], omega[e], sig, x, F, R, P, Q)
        s[j] = sj
        for i in range(3):
            v = x[i] - p[j, i]
            r[3 * (j - 1) + i] = v
            tang[j, i] = F[0, i]
            cost += 0.5 * v * v
    return cost


@jit
def _normal_equations(root, omega, length, s, p, xs, Fs, starts, r, tang, odr, N, g):
    """Gauss-Newton normal matrix ``N = J^T J`` and gradient ``g = J^T r`` of the residuals of
    :func:`_residual`, without forming ``J``.

    Columns as in the Jacobian: the root tangent's two angles, the 3n omegas, the strand length. With
    ``odr``, the rows of interior vertices are projected on the curve's normal plane (``P = I - t t^T``:
    variable projection of their arc length).

    A change of element ``f`` moves every point downstream rigidly: the Jacobian column of parameter
    ``c`` at a point ``x`` beyond element ``f`` is ``a_c + b_c x (x - root)``, the same six numbers
    ``u_c = (a_c, b_c)`` for every such point, applied by ``G(x) = [I | -[x - root]_x]``. So the rows of
    one element sum into a 6x6 matrix ``H_e = sum G^T P G`` and the pairs of columns meet through suffix
    sums of ``H``: O(M + n^2) work instead of the O(M n^2) of ``J^T J``, exactly the same matrix.
    """
    n = omega.shape[0]
    m = s.shape[0]
    total = starts[n]
    npar = 3 + 3 * n
    last = npar - 1
    H = np.zeros((n + 1, 6, 6))       # per element, then suffix sums (H[n] = 0)
    rho = np.zeros((n + 1, 6))        # sum G^T P r, suffix sums
    yl = np.zeros((n + 1, 6))         # sum G^T l (l: the length column's row), suffix sums
    mo = np.zeros((n, 3, 6))          # sum G^T P dx_k over the element's own rows
    own = np.zeros((n, 3, 3))         # sum (P dx_k) . (P dx_l) over the element's own rows
    gown = np.zeros((n, 3))           # sum (P dx_k) . r
    lown = np.zeros((n, 3))           # sum (P dx_k) . l
    N[:, :] = 0.0
    g[:] = 0.0
    # the length column, upstream part, for rows in element e: A_e + B_e x (x - root)
    A = np.zeros((n, 3))
    B = np.zeros((n, 3))
    for f in range(n - 1):
        frac = length[f] / total
        Om = _darboux_world(omega[f], Fs[f])
        rel = xs[f + 1] - root
        for i in range(3):
            A[f + 1, i] = A[f, i] + frac * Fs[f + 1, 0, i]
            B[f + 1, i] = B[f, i] + frac * Om[i]
        _cross_add(Om, rel, A[f + 1], -frac)
    dxj = np.empty((3, 3))
    dthj = np.empty((3, 3))
    PG = np.empty((3, 6))
    Pdx = np.empty((3, 3))
    Pr = np.empty(3)
    ell = np.empty(3)
    y = np.empty(3)
    for j in range(1, m):
        e, sig = _locate(starts, s[j])
        t = tang[j]
        project = odr and j < m - 1
        for i in range(3):
            y[i] = r[3 * (j - 1) + i] + p[j, i] - root[i]
        # G = [I | -[y]x]; PG = P G
        for i in range(3):
            for c in range(6):
                PG[i, c] = 0.0
            PG[i, i] = 1.0
        PG[0, 4] = y[2]
        PG[0, 5] = -y[1]
        PG[1, 3] = -y[2]
        PG[1, 5] = y[0]
        PG[2, 3] = y[1]
        PG[2, 4] = -y[0]
        element_derivatives(omega[e], sig, Fs[e], dxj, dthj)
        for k in range(3):
            Pdx[k, :] = dxj[k]
        for i in range(3):
            Pr[i] = r[3 * (j - 1) + i]
            ell[i] = A[e, i] + (sig / total) * t[i]
        _cross_add(B[e], y, ell, 1.0)
        if project:
            for c in range(6):
                d = t[0] * PG[0, c] + t[1] * PG[1, c] + t[2] * PG[2, c]
                for i in range(3):
                    PG[i, c] -= d * t[i]
            for k in range(3):
                d = t[0] * Pdx[k, 0] + t[1] * Pdx[k, 1] + t[2] * Pdx[k, 2]
                for i in range(3):
                    Pdx[k, i] -= d * t[i]
            d = t[0] * Pr[0] + t[1] * Pr[1] + t[2] * Pr[2]
            d2 = t[0] * ell[0] + t[1] * ell[1] + t[2] * ell[2]
            for i in range(3):
                Pr[i] -= d * t[i]
                ell[i] -= d2 * t[i]
        # G^T P G = (P G)^T (P G), P symmetric and idempotent; G^T v = (P G)^T v for v in P's range
        for a in range(6):
            for b in range(6):
                H[e, a, b] += PG[0, a] * PG[0, b] + PG[1, a] * PG[1, b] + PG[2, a] * PG[2, b]
            rho[e, a] += PG[0, a] * Pr[0] + PG[1, a] * Pr[1] + PG[2, a] * Pr[2]
            yl[e, a] += PG[0, a] * ell[0] + PG[1, a] * ell[1] + PG[2, a] * ell[2]
            for k in range(3):
                mo[e, k, a] += PG[0, a] * Pdx[k, 0] + PG[1, a] * Pdx[k, 1] + PG[2, a] * Pdx[k, 2]
        for k in range(3):
            for l in range(3):
                own[e, k, l] += Pdx[k, 0] * Pdx[l, 0] + Pdx[k, 1] * Pdx[l, 1] + Pdx[k, 2] * Pdx[l, 2]
            gown[e, k] += Pdx[k, 0] * Pr[0] + Pdx[k, 1] * Pr[1] + Pdx[k, 2] * Pr[2]
            lown[e, k] += Pdx[k, 0] * ell[0] + Pdx[k, 1] * ell[1] + Pdx[k, 2] * ell[2]
        N[last, last] += ell[0] * ell[0] + ell[1] * ell[1] + ell[2] * ell[2]
        g[last] += ell[0] * Pr[0] + ell[1] * Pr[1] + ell[2] * Pr[2]
    for e in range(n - 1, -1, -1):
        H[e] += H[e + 1]
        rho[e] += rho[e + 1]
        yl[e] += yl[e + 1]
    # u_c = (a_c, b_c) of every column but the length; fc: the element it belongs to (-1: the root angles)
    u = np.zeros((npar - 1, 6))
    fc = np.empty(npar - 1, dtype=np.int64)
    dxe = np.empty((3, 3))
    dthe = np.empty((3, 3))
    for c in range(2):
        fc[c] = -1
        for i in range(3):
            u[c, 3 + i] = Fs[0, 1 + c, i]
    for f in range(n):
        element_derivatives(omega[f], length[f], Fs[f], dxe, dthe)
        rel = xs[f + 1] - root
        for k in range(3):
            c = 2 + 3 * f + k
            fc[c] = f
            for i in range(3):
                u[c, i] = dxe[k, i]
                u[c, 3 + i] = dthe[k, i]
            _cross_add(dthe[k], rel, u[c, :3], -1.0)
    # v_d = H_{fd+1} u_d (+ the element's own rows: mo), for every column d
    v = np.zeros((npar - 1, 6))
    w = np.zeros((npar - 1, 6))
    for d in range(npar - 1):
        for a in range(6):
            acc = 0.0
            for b in range(6):
                acc += H[fc[d] + 1, a, b] * u[d, b]
            v[d, a] = acc
            w[d, a] = acc
            if fc[d] >= 0:
                w[d, a] += mo[fc[d], d - 2 - 3 * fc[d], a]
    for c in range(npar - 1):
        f = fc[c]
        for d in range(c, npar - 1):
            if fc[d] == f:
                val = _dot6(u[c], v[d])
                if f >= 0:
                    val += own[f, c - 2 - 3 * f, d - 2 - 3 * f]
            else:
                val = _dot6(u[c], w[d])
            N[c, d] = val
            N[d, c] = val
        val = _dot6(u[c], yl[f + 1])
        gc = _dot6(u[c], rho[f + 1])
        if f >= 0:
            val += lown[f, c - 2 - 3 * f]
            gc += gown[f, c - 2 - 3 * f]
        N[c, last] = val
        N[last, c] = val
        g[c] = gc


@jit
def _dot6(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3] + a[4] * b[4] + a[5] * b[5]

@jit
def _gain_ratio(cost, c_try, delta, D, g, lam, nu):
    """Accept or reject a Levenberg-Marquardt step; returns (accepted, lam, nu).

    The damping follows the gain ratio rho = actual / predicted decrease
    (Nielsen 1999): times max(1/3, 1 - (2 rho - 1)^3) on acceptance, times a
    doubling ``nu`` on rejection. The model's predicted decrease for the step
    solving ``(J^T J + lam D) delta = -g`` is ``1/2 delta . (lam D delta - g)``.
    """
    predicted = 0.0
    for i in range(delta.shape[0]):
        predicted += 0.5 * delta[i] * (lam * D[i] * delta[i] - g[i])
    if c_try < cost and predicted > 0.0:
        rho = (cost - c_try) / predicted
        return True, lam * max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3), 2.0
    return False, lam * nu, nu * 2.0


@jit
def _rotate_rows(F, th, out):
    """Rotate the rows of a frame by the rotation vector ``th`` (Rodrigues), re-orthonormalised."""
    angle = np.sqrt(th[0] ** 2 + th[1] ** 2 + th[2] ** 2)
    R = np.eye(3)
    if angle > 0.0:
        k = th / angle
        K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
        R = R + np.sin(angle) * K + (1.0 - np.cos(angle)) * (K @ K)
    for i in range(3):
        for j in range(3):
            out[i, j] = R[j, 0] * F[i, 0] + R[j, 1] * F[i, 1] + R[j, 2] * F[i, 2]
    t = out[0] / np.sqrt(out[0] @ out[0])
    n1 = out[1] - (out[1] @ t) * t
    n1 = n1 / np.sqrt(n1 @ n1)
    out[0] = t
    out[1] = n1
    out[2, 0] = t[1] * n1[2] - t[2] * n1[1]
    out[2, 1] = t[2] * n1[0] - t[0] * n1[2]
    out[2, 2] = t[0] * n1[1] - t[1] * n1[0]


@jit
def _levenberg_marquardt(root, F0, omega, length, s, p, max_iter, odr, target, eta, cap, rel):
    """Refine ``F0`` (root tangent), ``omega`` and ``length`` (scaled as one) in place.

    ``s`` holds the vertices' matched arc lengths, in and out. With ``odr``
    false the vertices keep their fraction of the length (no sliding along
    the curve: a robust first phase); with ``odr`` true they are projected on
    the curve (the exact orthogonal-distance fit). Stops early once every
    vertex residual is at most ``target`` (m). ``eta`` (m) and ``cap``
    (1/m) set the priors; it stops when an accepted step lowers the cost by at most ``rel`` times
    the cost. Returns the final cost. Damping follows the gain ratio (Nielsen 1999): it grows by
    ``nu`` on a rejected step and shrinks by ``max(1/3, 1 - (2 rho - 1)^3)``
    on an accepted one.
    """
    n = omega.shape[0]
    m = s.shape[0]
    npar = 3 + 3 * n
    xs = np.empty((n + 1, 3))
    Fs = np.empty((n + 1, 3, 3))
    starts = np.empty(n + 1)
    r = np.empty(3 * (m - 1))
    tang = np.zeros((m, 3))
    JtJ = np.empty((npar, npar))
    g = np.empty(npar)
    r_try = np.empty(3 * (m - 1))
    tang_try = np.zeros((m, 3))
    s_try = np.empty(m)
    F_try = np.empty((3, 3))
    om_try = np.empty_like(omega)
    len_try = np.empty_like(length)
    th = np.empty(3)
    D = np.empty(npar)
    newton = _PROJECTION_NEWTON if odr else -1
    cost = _residual(root, F0, omega, length, s, p, newton, xs, Fs, starts, r, tang) + _prior_cost(omega, length, eta, cap)
    lam = 1e-4
    nu = 2.0
    iters = 0
    while iters < max_iter and cost > 0.0:
        iters += 1
        _normal_equations(root, omega, length, s, p, xs, Fs, starts, r, tang, odr, JtJ, g)
        total = starts[n]
        for e in range(n):
            _add_prior(JtJ, g, 2 + 3 * e, omega[e], length[e], eta, cap)
        dmax = 0.0
        for i in range(npar):
            dmax = max(dmax, JtJ[i, i])
        floor = _DAMPING_FLOOR * dmax + 1e-300
        accepted = False
        c_try = cost
        for _try in range(30):
            A = JtJ.copy()
            for i in range(npar):
                D[i] = max(JtJ[i, i], floor)
                A[i, i] += lam * D[i]
            delta = np.linalg.solve(A, -g)
            for i in range(3):
                th[i] = delta[0] * F0[1, i] + delta[1] * F0[2, i]
            _rotate_rows(F0, th, F_try)
            for e in range(n):
                for k in range(3):
                    om_try[e, k] = omega[e, k] + delta[2 + 3 * e + k]
            ratio = (total + delta[npar - 1]) / total
            c_try = np.inf
            if ratio > 0.0:
                for e in range(n):
                    len_try[e] = length[e] * ratio
                for j in range(m):
                    s_try[j] = s[j] * ratio
                c_try = _residual(root, F_try, om_try, len_try, s_try, p, 3 if odr else -1, xs, Fs, starts,
                                  r_try, tang_try) + _prior_cost(om_try, len_try, eta, cap)
            accepted, lam, nu = _gain_ratio(cost, c_try, delta, D, g, lam, nu)
            if accepted:
                break
        if not accepted:
            break
        decrease = cost - c_try
        F0[:, :] = F_try
        omega[:, :] = om_try
        length[:] = len_try
        s[:] = s_try
        r[:] = r_try
        tang[:, :] = tang_try
        cost = c_try
        if decrease <= rel * cost:
            break
        worst2 = 0.0
        for j in range(m - 1):
            worst2 = max(worst2, r[3 * j] ** 2 + r[3 * j + 1] ** 2 + r[3 * j + 2] ** 2)
        if worst2 <= target * target:
            break
    return _residual(root, F0, omega, length, s, p, newton, xs, Fs, starts, r, tang)


@jit
def _prior_cost(omega, length, eta, cap):
    """The priors' cost (see the module constants), m^2."""
    c = 0.0
    for e in range(omega.shape[0]):
        a2 = omega[e, 0] ** 2 + omega[e, 1] ** 2 + omega[e, 2] ** 2
        c += 0.5 * (eta * length[e]) ** 2 * a2
        a = np.sqrt(a2)
        if a > cap:
            c += 0.5 * (_CAP_WEIGHT / _PRIOR_OF_TOLERANCE * eta * length[e] * (a - cap)) ** 2
    return c


@jit
def _add_prior(JtJ, g, off, om, ell, eta, cap):
    """Add the priors' Gauss-Newton terms of one element (parameters at ``off``)."""
    w2 = (eta * ell) ** 2
    for k in range(3):
        JtJ[off + k, off + k] += w2
        g[off + k] += w2 * om[k]
    a = np.sqrt(om[0] ** 2 + om[1] ** 2 + om[2] ** 2)
    if a > cap:
        wc = _CAP_WEIGHT / _PRIOR_OF_TOLERANCE * eta * ell
        rho = wc * (a - cap)
        for i in range(3):
            gi = wc * om[i] / a
            g[off + i] += rho * gi
            for j in range(3):
                JtJ[off + i, off + j] += gi * wc * om[j] / a


@jit
def _polyline_at(p, s, S, out):
    """Point of the input polyline at arc length ``S`` (linear interpolation)."""
    m = s.shape[0]
    if S <= 0.0:
        out[:] = p[0]
        return
    if S >= s[m - 1]:
        out[:] = p[m - 1]
        return
    j = np.searchsorted(s, S, side="right") - 1
    a = (S - s[j]) / (s[j + 1] - s[j])
    for i in range(3):
        out[i] = (1.0 - a) * p[j, i] + a * p[j + 1, i]


@jit
def _initial_frame(p, up, F0):
    """Root frame: t along the first segment, n1 towards ``up`` (the roll is a gauge choice)."""
    t = p[1] - p[0]
    t = t / np.sqrt(t @ t)
    ref = up.copy()
    if abs(ref @ t) > 0.99:
        # up is along the root tangent: use the world axis least aligned with it
        ref[:] = 0.0
        ref[np.argmin(np.abs(t))] = 1.0
    n1 = ref - (ref @ t) * t
    n1 = n1 / np.sqrt(n1 @ n1)
    F0[0] = t
    F0[1] = n1
    F0[2, 0] = t[1] * n1[2] - t[2] * n1[1]
    F0[2, 1] = t[2] * n1[0] - t[0] * n1[2]
    F0[2, 2] = t[0] * n1[1] - t[1] * n1[0]


@jit
def _element_residual(x, F, om, sig, tgt, res, tan_tgt, tan_w, R, P, Q):
    """Residuals of one element started at (x, F) against targets; returns the cost. With ``tan_w > 0``,
    three more rows ``tan_w (t(ell) - tan_tgt)``: the tangent at the element's end (``ell``, the largest
    ``sig``) against a unit target. ``R``, ``P``, ``Q``: scratch (3, 3), (3,), (3,)."""
    cost = 0.0
    k = sig.shape[0]
    ell = 0.0
    for i in range(k):
        ell = max(ell, sig[i])
        element_step(om[2], om[0], om[1], sig[i], R, P, Q)
        for a in range(3):
            v = x[a] + F[0, a] * P[0] + F[1, a] * P[1] + F[2, a] * P[2] - tgt[i, a]
            res[3 * i + a] = v
            cost += 0.5 * v * v
    if tan_w > 0.0:
        element_step(om[2], om[0], om[1], ell, R, P, Q)
        for a in range(3):
            v = tan_w * (R[0, 0] * F[0, a] + R[1, 0] * F[1, a] + R[2, 0] * F[2, a] - tan_tgt[a])
            res[3 * k + a] = v
            cost += 0.5 * v * v
    return cost


@jit
def _fit_element(x, F, om, sig, tgt, free_frame, max_iter, eta, cap, tan_tgt, tan_w, give_up):
    """Levenberg-Marquardt on one element's omega (and, for the first element,
    the two angles of its start tangent); updates ``om`` and ``F`` in place.
    ``tan_tgt``, ``tan_w``: an end-tangent target, as in :func:`_element_residual`. From the
    ``_GIVE_UP_AFTER``-th iteration on, it stops once a vertex stays farther than ``give_up`` (m; 0:
    never), which a fit that ends within half that distance does not do."""
    k = sig.shape[0]
    rows = 3 * k + (3 if tan_w > 0.0 else 0)
    npar = 5 if free_frame else 3
    off = 2 if free_frame else 0
    res = np.empty(rows)
    res_try = np.empty(rows)
    Jl = np.zeros((rows, npar))
    om_try = np.empty(3)
    F_try = F.copy()
    th = np.empty(3)
    dx = np.empty((3, 3))
    dth = np.empty((3, 3))
    col = np.empty(3)
    xi = np.empty(3)
    t_end = np.empty(3)
    R = np.empty((3, 3))
    P = np.empty(3)
    Q = np.empty(3)
    D = np.empty(npar)
    JtJ = np.empty((npar, npar))
    A = np.empty((npar, npar))
    L = np.empty((npar, npar))
    g = np.empty(npar)
    minus_g = np.empty(npar)
    d = np.empty(npar)
    ell = 0.0
    for i in range(k):
        ell = max(ell, sig[i])
    ell_a = np.full(1, ell)
    om_a = np.empty((1, 3))
    om_a[0] = om
    cost = _element_residual(x, F, om, sig, tgt, res, tan_tgt, tan_w, R, P, Q) + _prior_cost(om_a, ell_a, eta, cap)
    lam = 1e-4
    nu = 2.0
    for it in range(max_iter):
        for i in range(k):
            element_derivatives(om, sig[i], F, dx, dth)
            for b in range(3):
                for a in range(3):
                    Jl[3 * i + a, off + b] = dx[b, a]
            if free_frame:
                for a in range(3):
                    xi[a] = res[3 * i + a] + tgt[i, a] - x[a]
                for c in range(2):
                    col[:] = 0.0
                    _cross_add(F[1 + c], xi, col, 1.0)
                    for a in range(3):
                        Jl[3 * i + a, c] = col[a]
        if tan_w > 0.0:
            # the end tangent turns with the frame: d t = dtheta x t
            element_step(om[2], om[0], om[1], ell, R, P, Q)
            for a in range(3):
                t_end[a] = R[0, 0] * F[0, a] + R[1, 0] * F[1, a] + R[2, 0] * F[2, a]
            element_derivatives(om, ell, F, dx, dth)
            for b in range(3):
                col[:] = 0.0
                _cross_add(dth[b], t_end, col, tan_w)
                for a in range(3):
                    Jl[3 * k + a, off + b] = col[a]
            if free_frame:
                for c in range(2):
                    col[:] = 0.0
                    _cross_add(F[1 + c], t_end, col, tan_w)
                    for a in range(3):
                        Jl[3 * k + a, c] = col[a]
        for b in range(npar):
            gb = 0.0
            for r in range(rows):
                gb += Jl[r, b] * res[r]
            g[b] = gb
            for c in range(b + 1):
                v = 0.0
                for r in range(rows):
                    v += Jl[r, b] * Jl[r, c]
                JtJ[b, c] = v
                JtJ[c, b] = v
        _add_prior(JtJ, g, off, om, ell, eta, cap)
        dmax = 0.0
        for b in range(npar):
            dmax = max(dmax, JtJ[b, b])
        accepted = False
        c_try = cost
        for b in range(npar):
            minus_g[b] = -g[b]
        for _t in range(30):
            A[:, :] = JtJ
            for b in range(npar):
                D[b] = max(JtJ[b, b], _DAMPING_FLOOR * dmax + 1e-300)
                A[b, b] += lam * D[b]
            if cholesky(A, L):
                cholesky_solve(L, minus_g, d)
            else:
                d[:] = np.linalg.solve(A, minus_g)
            for b in range(3):
                om_try[b] = om[b] + d[off + b]
            if free_frame:
                for a in range(3):
                    th[a] = d[0] * F[1, a] + d[1] * F[2, a]
                _rotate_rows(F, th, F_try)
            else:
                F_try[:, :] = F
            om_a[0] = om_try
            c_try = (_element_residual(x, F_try, om_try, sig, tgt, res_try, tan_tgt, tan_w, R, P, Q)
                     + _prior_cost(om_a, ell_a, eta, cap))
            accepted, lam, nu = _gain_ratio(cost, c_try, d, D, g, lam, nu)
            if accepted:
                break
        if not accepted:
            break
        rel = (cost - c_try) / (cost + 1e-300)
        om[:] = om_try
        F[:, :] = F_try
        res[:] = res_try
        cost = c_try
        if rel < 1e-6:
            break
        if give_up > 0.0 and it + 1 >= _GIVE_UP_AFTER:
            worst = 0.0
            for i in range(k):
                worst = max(worst, res[3 * i] ** 2 + res[3 * i + 1] ** 2 + res[3 * i + 2] ** 2)
            if worst > give_up * give_up:
                break
    return cost


@jit
def _discrete_darboux(p, j0, j1):
    """World Darboux vector of the polyline between vertices ``j0`` and ``j1``.

    For a uniform helix sampled evenly, each chord is the previous one turned
    by the same screw rotation ``exp(h [Om])``; in Cayley form
    ``d_{j+1} - d_j = (h/2) Om' x (d_j + d_{j+1})`` with
    ``|Om'| h = 2 tan(|Om| h / 2)``, linear in ``Om'``. Solved in the least
    squares sense over the chords; zero when there are fewer than 3.
    """
    out = np.zeros(3)
    k = j1 - j0
    if k < 3:
        return out
    A = np.zeros((3, 3))
    b = np.zeros(3)
    h_mean = 0.0
    turning = 0.0
    d0 = np.empty(3)
    d1 = np.empty(3)
    for j in range(j0, j1 - 1):
        for c in range(3):
            d0[c] = p[j + 1, c] - p[j, c]
            d1[c] = p[j + 2, c] - p[j + 1, c]
        l0 = np.sqrt(d0 @ d0)
        l1 = np.sqrt(d1 @ d1)
        if l0 == 0.0 or l1 == 0.0:
            continue
        for c in range(3):
            d0[c] /= l0
            d1[c] /= l1
        turning += np.arccos(min(1.0, max(-1.0, d0 @ d1)))
        h = 0.5 * (l0 + l1)
        h_mean += h
        # (Om' x sm) = M Om' with M = -[sm]_x, sm = h (d0 + d1) / 2: M^T M = |sm|^2 I - sm sm^T,
        # M^T v = sm x v
        sm0 = 0.5 * h * (d0[0] + d1[0])
        sm1 = 0.5 * h * (d0[1] + d1[1])
        sm2 = 0.5 * h * (d0[2] + d1[2])
        ss = sm0 * sm0 + sm1 * sm1 + sm2 * sm2
        A[0, 0] += ss - sm0 * sm0
        A[1, 1] += ss - sm1 * sm1
        A[2, 2] += ss - sm2 * sm2
        A[0, 1] -= sm0 * sm1
        A[1, 0] -= sm0 * sm1
        A[0, 2] -= sm0 * sm2
        A[2, 0] -= sm0 * sm2
        A[1, 2] -= sm1 * sm2
        A[2, 1] -= sm1 * sm2
        v0 = d1[0] - d0[0]
        v1 = d1[1] - d0[1]
        v2 = d1[2] - d0[2]
        b[0] += sm1 * v2 - sm2 * v1
        b[1] += sm2 * v0 - sm0 * v2
        b[2] += sm0 * v1 - sm1 * v0
    # Below a quarter turn the circular-arc start is good and the component
    # of Om along the chords (the torsion) is ill-conditioned here.
    if turning < 0.5 * np.pi:
        return out
    scale = 0.0
    for i in range(3):
        scale = max(scale, A[i, i])
    if not (scale > 0.0 and scale < np.inf):
        return out  # no chord pair that turns less than back on itself (a spike: A = 0), or none finite
    for i in range(3):
        A[i, i] += 1e-6 * scale
    om = np.linalg.solve(A, b)
    h_mean /= (k - 1)
    mag = np.sqrt(om @ om)
    if mag > 0.0:
        out[:] = om * (2.0 * np.arctan(0.5 * mag * h_mean) / h_mean / mag)
    return out


@jit
def _arc_toward(x, F, target, ell, om):
    """``om`` of the circular arc of length ``ell`` from (x, F) aimed at ``target``: chord angle theta,
    curvature 2 theta / ell, no twist (zero if the target is straight ahead)."""
    om[:] = 0.0
    c = target - x
    cn = np.sqrt(c @ c)
    if cn > 0.0:
        c = c / cn
        ax = np.empty(3)
        ax[0] = F[0, 1] * c[2] - F[0, 2] * c[1]
        ax[1] = F[0, 2] * c[0] - F[0, 0] * c[2]
        ax[2] = F[0, 0] * c[1] - F[0, 1] * c[0]
        sn = np.sqrt(ax @ ax)
        if sn > 1e-14:
            theta = np.arctan2(sn, F[0] @ c)
            ax = ax * (2.0 * theta / ell / sn)
            om[0] = ax @ F[1]
            om[1] = ax @ F[2]


@jit
def _vertex_tangent(p, i, out):
    """Unit tangent estimate at interior vertex ``i``: the chords' directions averaged with the other
    chord's length as weight, exact at the middle of three points evenly spaced on a circle. On a helix
    that average turns too little about the axis: a helix turning phi about its axis per chord has
    its central difference's component across the axis shortened by sin(phi)/phi. Where the strand
    coils at ``i`` (the chords around it determine a screw axis, :func:`_screw_axis`, turn about it by
    at least ``_COIL_TURN`` per chord, and turn evenly: the angles at consecutive vertices within a
    factor ``_EVEN_TURNING``), the component along the axis is scaled by sin(phi)/phi, which makes the
    estimate exact on evenly sampled helices, and the function returns True (False elsewhere)."""
    a = p[i] - p[i - 1]
    b = p[i + 1] - p[i]
    la = np.sqrt(a @ a)
    lb = np.sqrt(b @ b)
    out[:] = 0.0
    if la > 0.0:
        out += (lb / la) * a
    if lb > 0.0:
        out += (la / lb) * b
    n = np.sqrt(out @ out)
    if n == 0.0:
        return False
    out /= n
    m = p.shape[0]
    j = i - 1 if i + 2 <= m - 1 else i - 2
    if j < 0:
        return False
    axis = np.empty(3)
    phi = _screw_axis(p[j], p[j + 1], p[j + 2], p[j + 3], axis)
    if phi < _COIL_TURN:
        return False
    t0 = _turn_at(p, j + 1)
    t1 = _turn_at(p, j + 2)
    if not (t1 < _EVEN_TURNING * t0 and t0 < _EVEN_TURNING * t1):
        return False
    along = out @ axis
    out += (along * (np.sin(phi) / phi - 1.0)) * axis
    out /= np.sqrt(out @ out)
    return True


@jit
def _turn_at(p, i):
    """Angle (rad) between the chords into and out of interior vertex ``i`` (0 at a repeated point)."""
    ax, ay, az, na = _unit_chord(p[i - 1], p[i])
    bx, by, bz, nb = _unit_chord(p[i], p[i + 1])
    if na == 0.0 or nb == 0.0:
        return 0.0
    return np.arccos(min(1.0, max(-1.0, ax * bx + ay * by + az * bz)))


@jit
def _element_trial(x, F, p, s, j, k, om_prev, free_frame, eta, cap, om_out, F_out, tangent_weight, coil_gain,
                   within):
    """One element from (x, F) through vertices ``j+1 .. j+k`` at their arc lengths (``s[j]`` at its start):
    the best of three starts (the previous element's omega, the polyline's screw rotation over those
    vertices, a circular arc aimed at the last), refined by Levenberg-Marquardt (with the start tangent
    when ``free_frame``), its end tangent held near the polyline's there (:func:`_vertex_tangent`) so
    that the next element starts along the strand, ``coil_gain`` times as firmly where the strand coils
    there and the element holds at least 2 vertices. Writes ``om_out`` and ``F_out``; returns the largest
    vertex distance, m. ``within``: the distance the caller accepts; a fit that stays far beyond it is cut
    short (its result is then only an upper bound)."""
    m = p.shape[0]
    sig = np.empty(k)
    tgt = np.empty((k, 3))
    for i in range(k):
        sig[i] = s[j + 1 + i] - s[j]
        tgt[i] = p[j + 1 + i]
    res = np.empty(3 * k + 3)
    R = np.empty((3, 3))
    P = np.empty(3)
    Q = np.empty(3)
    F_out[:, :] = F
    om_out[:] = om_prev
    best = _element_residual(x, F, om_out, sig, tgt, res, _NO_TANGENT, 0.0, R, P, Q)
    om = np.empty(3)
    Om = _discrete_darboux(p, max(j - 1, 0), j + k)
    if Om @ Om > 0.0:
        om[0] = Om @ F[1]
        om[1] = Om @ F[2]
        om[2] = Om @ F[0]
        c = _element_residual(x, F, om, sig, tgt, res, _NO_TANGENT, 0.0, R, P, Q)
        if c < best:
            best = c
            om_out[:] = om
    _arc_toward(x, F, tgt[k - 1], sig[k - 1], om)
    if _element_residual(x, F, om, sig, tgt, res, _NO_TANGENT, 0.0, R, P, Q) < best:
        om_out[:] = om
    tangent = np.zeros(3)
    weight = 0.0
    end = j + k
    if end < m - 1:
        coiling = _vertex_tangent(p, end, tangent)
        d = p[end + 1] - p[end]
        weight = tangent_weight * np.sqrt(d @ d)
        if coiling and k >= 2:
            weight *= coil_gain
    _fit_element(x, F_out, om_out, sig, tgt, free_frame, 10, eta, cap, tangent, weight, _GIVE_UP * within)
    _element_residual(x, F_out, om_out, sig, tgt, res, _NO_TANGENT, 0.0, R, P, Q)
    worst = 0.0
    for i in range(k):
        worst = max(worst, res[3 * i] ** 2 + res[3 * i + 1] ** 2 + res[3 * i + 2] ** 2)
    return np.sqrt(worst)


@jit
def _greedy_elements(root, F0, p, s, up, within, eta, cap, omega, length, tangent_weight, coil_gain, limit):
    """Elements chosen along the strand, each as long as it can be: from where the previous one ended,
    the most vertices one helix fits within ``within`` (m) at their arc lengths ``s``, found from the
    previous element's count (a curl keeps its pace) by steps of 1, 2, 4, ... vertices, then bisection.
    Each element ends at a vertex, so the fitted length is the polyline's estimated arc length. Writes ``F0`` (the root frame, its tangent fitted with the first element) and the first rows
    of ``omega`` (M-1, 3) and ``length`` (M-1,); returns the element count, or stops once it exceeds
    ``limit`` and returns ``limit + 1``. ``coil_gain``: how much more firmly an element's end tangent is
    held where the strand coils (:func:`_element_trial`)."""
    m = p.shape[0]
    _initial_frame(p, up, F0)
    x = root.copy()
    F = F0.copy()
    x_next = np.empty(3)
    F_next = np.empty((3, 3))
    R = np.empty((3, 3))
    P = np.empty(3)
    Q = np.empty(3)
    om_prev = np.zeros(3)
    om_ok = np.empty(3)
    F_ok = np.empty((3, 3))
    om_t = np.empty(3)
    F_t = np.empty((3, 3))
    j = 0
    n = 0
    k_prev = 2
    while j < m - 1:
        first = n == 0
        left = m - 1 - j
        # the search starts at the previous element's vertex count (a curl keeps its pace)
        k_ok = 0
        k_bad = left + 1
        k = min(max(k_prev, 2), left)
        step = 1
        # a chain that has lost the coil's phase (single-vertex elements) finds it again with the usual weight
        gain = coil_gain if k_prev >= 2 else 1.0
        while True:
            if _element_trial(x, F, p, s, j, k, om_prev, first, eta, cap, om_t, F_t, tangent_weight, gain, within) <= within:
                k_ok = k
                om_ok[:] = om_t
                F_ok[:, :] = F_t
                if k == left:
                    break
                k = min(k + step, left)
                step *= 2
            else:
                k_bad = k
                break
        while k_bad - k_ok > 1:
            k = (k_ok + k_bad) // 2
            if _element_trial(x, F, p, s, j, k, om_prev, first, eta, cap, om_t, F_t, tangent_weight, gain, within) <= within:
                k_ok = k
                om_ok[:] = om_t
                F_ok[:, :] = F_t
            else:
                k_bad = k
        if k_ok == 0:
            # not even the next vertex within the distance: an element to it, as near as it comes
            _element_trial(x, F, p, s, j, 1, om_prev, first, eta, cap, om_ok, F_ok, tangent_weight, 1.0, 0.0)
            k_ok = 1
        k_prev = k_ok
        ell = s[j + k_ok] - s[j]
        omega[n] = om_ok
        length[n] = ell
        if first:
            F0[:, :] = F_ok
        _advance(x, F_ok, om_ok, ell, x_next, F_next, R, P, Q)
        x[:] = x_next
        F[:, :] = F_next
        om_prev[:] = om_ok
        j += k_ok
        n += 1
        if n > limit:
            break
    return n


@jit
def _sequential_init(root, F0, p, s, length, omega, look_ahead, eta, cap):
    """Element-by-element initial guess (see the module docstring).

    The first element also refines the root tangent ``F0`` in place: the
    polyline's first chord is off the true tangent by about half the
    curvature times the first segment length.
    """
    n = length.shape[0]
    x = root.copy()
    F = F0.copy()
    x_next = np.empty(3)
    F_next = np.empty((3, 3))
    R = np.empty((3, 3))
    P = np.empty(3)
    Q = np.empty(3)
    target = np.empty(3)
    m = s.shape[0]
    s0 = 0.0
    for e in range(n):
        s1 = s0 + length[e] if e < n - 1 else s[m - 1]
        ell_e = s1 - s0
        # The vertices inside the element and, as a continuation of the same
        # helix, those up to one more element length ahead: they hold the end
        # tangent near the polyline's instead of letting it chase a kink.
        # The polyline point at the end is a target only when the element
        # holds fewer than two vertices (it is a chord, off the curve).
        # (not on the first element, whose free root tangent it would bias)
        ahead = min(s1 + (look_ahead * ell_e if e > 0 else 0.0), s[m - 1])
        j0 = np.searchsorted(s, s0, side="right")
        j1 = np.searchsorted(s, s1, side="left")
        j2 = np.searchsorted(s, ahead, side="right")
        inside = j1 - j0
        extra = 1 if inside < 2 else 0
        k = j2 - j0 + extra
        sig = np.empty(k)
        tgt = np.empty((k, 3))
        for i in range(j2 - j0):
            sig[i] = s[j0 + i] - s0
            tgt[i] = p[j0 + i]
        _polyline_at(p, s, s1, target)
        if extra == 1:
            sig[k - 1] = ell_e
            tgt[k - 1] = target
        om = np.zeros(3)
        _arc_toward(x, F, target, ell_e, om)
        # second start: the polyline's own screw rotation over the element;
        # keep the start that fits better (it wins on multi-turn curls)
        Om = _discrete_darboux(p, j0 - 1, j1)
        if Om @ Om > 0.0:
            om2 = np.empty(3)
            om2[0] = Om @ F[1]
            om2[1] = Om @ F[2]
            om2[2] = Om @ F[0]
            res = np.empty(3 * k)
            if (_element_residual(x, F, om2, sig, tgt, res, _NO_TANGENT, 0.0, R, P, Q)
                    < _element_residual(x, F, om, sig, tgt, res, _NO_TANGENT, 0.0, R, P, Q)):
                om[:] = om2
        _fit_element(x, F, om, sig, tgt, e == 0, 10, eta, cap, _NO_TANGENT, 0.0, 0.0)
        if e == 0:
            F0[:, :] = F
        omega[e] = om
        _advance(x, F, om, ell_e, x_next, F_next, R, P, Q)
        x[:] = x_next
        F[:, :] = F_next
        s0 = s1


@jit
def _turning_angles(p, turn, span):
    """Turning angle at each interior vertex (0 at the ends, and where a
    segment has zero length) and the mean length of its two segments, m."""
    m = p.shape[0]
    turn[:] = 0.0
    span[:] = 0.0
    for j in range(1, m - 1):
        ax, ay, az, na = _unit_chord(p[j - 1], p[j])
        bx, by, bz, nb = _unit_chord(p[j], p[j + 1])
        span[j] = 0.5 * (na + nb)
        if na > 0.0 and nb > 0.0:
            turn[j] = np.arccos(min(1.0, max(-1.0, ax * bx + ay * by + az * bz)))


@jit
def _max_discrete_curvature(p):
    """Largest turning angle over mean adjacent segment length along a polyline, 1/m."""
    m = p.shape[0]
    turn = np.empty(m)
    span = np.empty(m)
    _turning_angles(p, turn, span)
    worst = 0.0
    for j in range(1, m - 1):
        if turn[j] > 0.0:
            worst = max(worst, turn[j] / span[j])
    return worst


@jit
def _arc_lengths(p, s):
    """Arc-length estimates of the vertices of a smooth curve's polyline.

    A chord of a circle turning by ``alpha`` is shorter than its arc by the
    factor ``sin(alpha/2) / (alpha/2)``; with ``alpha`` the mean discrete
    turning angle at the chord's two ends, the estimate is exact to O(h^4)
    instead of O(h^2), which places the first element joints where the
    curve's own joints are. Angles are capped at 90 degrees (kinks).

    Where the curve is not planar (a coil), the chords turn about a screw
    axis: three consecutive chords ``d0, d1, d2`` of a helix sampled evenly
    are taken one to the next by the same rotation, of axis along
    ``(d1 - d0) x (d2 - d1)`` and angle ``phi``. A chord at angle ``beta`` to
    that axis covers the arc ``chord sqrt(cos^2 beta + sin^2 beta
    ((phi/2) / sin(phi/2))^2)``: exact on a helix (the circle's factor when
    ``beta`` is 90 degrees), where the plain circle factor with the smaller
    turning angle between chords underestimates a coil's length.
    """
    m = p.shape[0]
    s[0] = 0.0
    turn = np.empty(m)
    span = np.empty(m)
    _turning_angles(p, turn, span)
    for j in range(m):
        turn[j] = min(turn[j], 0.5 * np.pi)
    axis = np.empty(3)
    for j in range(1, m):
        dx, dy, dz, chord = _unit_chord(p[j - 1], p[j])
        if j == 1:
            alpha = turn[1] if m > 2 else 0.0
        elif j == m - 1:
            alpha = turn[m - 2]
        else:
            alpha = 0.5 * (turn[j - 1] + turn[j])
        half = 0.5 * alpha
        factor = half / np.sin(half) if half > 1e-8 else 1.0 + half * half / 6.0
        if m >= 4 and chord > 0.0:
            # chords c0-1, c0, c0+1 around this one (chord j-1), kept inside the polyline
            c0 = min(max(j - 1, 1), m - 3)
            factor = _screw_factor(p[c0 - 1], p[c0], p[c0 + 1], p[c0 + 2], dx, dy, dz, factor, axis)
        s[j] = s[j - 1] + chord * factor


@jit
def _unit_chord(a, b):
    """Unit direction and length of the chord from ``a`` to ``b`` (zeros where it has none), as scalars."""
    x = b[0] - a[0]
    y = b[1] - a[1]
    z = b[2] - a[2]
    n = np.sqrt(x * x + y * y + z * z)
    if n == 0.0:
        return 0.0, 0.0, 0.0, 0.0
    return x / n, y / n, z / n, n


@jit
def _screw_axis(a, b, c, e, axis):
    """Axis and turn per chord of the helix through the chords a-b, b-c, c-e: writes the unit axis into
    ``axis`` and returns the angle (rad, at most pi/2) each chord turns about it, or -1 where the chords
    are planar, straight or degenerate (a circle's axis is its normal, but its chords alone do not
    tell a circle from an inflection)."""
    x0, y0, z0, l0 = _unit_chord(a, b)
    x1, y1, z1, l1 = _unit_chord(b, c)
    x2, y2, z2, l2 = _unit_chord(c, e)
    if l0 == 0.0 or l1 == 0.0 or l2 == 0.0:
        return -1.0
    ux, uy, uz = x1 - x0, y1 - y0, z1 - z0
    vx, vy, vz = x2 - x1, y2 - y1, z2 - z1
    ax = uy * vz - uz * vy
    ay = uz * vx - ux * vz
    az = ux * vy - uy * vx
    na = np.sqrt(ax * ax + ay * ay + az * az)
    # planar (u, v parallel), straight or an inflection
    if na <= 1e-3 * np.sqrt((ux * ux + uy * uy + uz * uz) * (vx * vx + vy * vy + vz * vz)) or na == 0.0:
        return -1.0
    ax /= na
    ay /= na
    az /= na
    axis[0] = ax
    axis[1] = ay
    axis[2] = az
    c0 = x0 * ax + y0 * ay + z0 * az
    c1 = x1 * ax + y1 * ay + z1 * az
    w0x, w0y, w0z = x0 - c0 * ax, y0 - c0 * ay, z0 - c0 * az
    w1x, w1y, w1z = x1 - c1 * ax, y1 - c1 * ay, z1 - c1 * az
    n = np.sqrt((w0x * w0x + w0y * w0y + w0z * w0z) * (w1x * w1x + w1y * w1y + w1z * w1z))
    if n == 0.0:
        return -1.0
    cos_phi = (w0x * w1x + w0y * w1y + w0z * w1z) / n
    return min(np.arccos(min(1.0, max(-1.0, cos_phi))), 0.5 * np.pi)


@jit
def _screw_factor(a, b, c, e, dx, dy, dz, fallback, axis):
    """Arc over chord of a chord with unit direction (dx, dy, dz) on the helix through the chords a-b,
    b-c, c-e (see :func:`_arc_lengths`, :func:`_screw_axis`; ``axis``: scratch (3,)); ``fallback`` where
    they are planar, straight or degenerate."""
    phi = _screw_axis(a, b, c, e, axis)
    if phi < 0.0:
        return fallback
    half = 0.5 * phi
    q = half / np.sin(half) if half > 1e-8 else 1.0 + half * half / 6.0
    cb = dx * axis[0] + dy * axis[1] + dz * axis[2]
    return np.sqrt(cb * cb + (1.0 - cb * cb) * q * q)


@jit
def _vertex_errors(root, F0, omega, length, s, p, err):
    """Distance of each vertex to its matched curve point (``err[0] = 0``); returns the max."""
    n = omega.shape[0]
    m = s.shape[0]
    xs = np.empty((n + 1, 3))
    Fs = np.empty((n + 1, 3, 3))
    starts = np.empty(n + 1)
    r = np.empty(3 * (m - 1))
    tang = np.zeros((m, 3))
    _residual(root, F0, omega, length, s, p, _PROJECTION_NEWTON, xs, Fs, starts, r, tang)
    err[0] = 0.0
    worst = 0.0
    for j in range(1, m):
        d = np.sqrt(r[3 * j - 3] ** 2 + r[3 * j - 2] ** 2 + r[3 * j - 1] ** 2)
        err[j] = d
        worst = max(worst, d)
    return worst


@jit
def _start(root, F0, p, s, up, length, omega, eta, bend_cap, err):
    """Initial guess for the given elements: two starts, plain (exact on
    smooth data) and with look-ahead (robust at kinks, where the plain one
    chases the corner); keeps the one that fits better. Writes F0, omega."""
    _initial_frame(p, up, F0)
    _sequential_init(root, F0, p, s, length, omega, 0.0, eta, bend_cap)
    plain = _vertex_errors(root, F0, omega, length, s.copy(), p, err)
    F_ahead = np.empty((3, 3))
    _initial_frame(p, up, F_ahead)
    om_ahead = np.zeros_like(omega)
    _sequential_init(root, F_ahead, p, s, length, om_ahead, _LOOK_AHEAD, eta, bend_cap)
    if _vertex_errors(root, F_ahead, om_ahead, length, s.copy(), p, err) < plain:
        F0[:, :] = F_ahead
        omega[:, :] = om_ahead


@jit
def element_cap(p, n_max):
    """The most elements the adaptive fit gives a polyline (M, 3): as many as its vertices determine,
    ``3 n + 3`` parameters (each element's omega, the root tangent and the length) for the ``2 (M - 1)``
    distances of the vertices to the curve, so ``n <= (2 M - 5) / 3``; and at most ``n_max`` when it is
    above 0."""
    m = p.shape[0]
    determined = max(1, (2 * m - 5) // 3)
    return min(n_max, determined) if n_max > 0 else determined


@jit
def sampling_figures(points, offsets, out_arc, out_sagitta, out_smooth, out_noise):
    """Per strand of a CSR polyline set: the arc length of a smooth curve through its vertices
    (:func:`_arc_lengths`, m); the largest distance such a curve may pass from a chord, half way between
    two vertices, ``h alpha / 8`` for a chord ``h`` with turning ``alpha`` at its ends (m): above the
    tolerance, the vertices do not determine the curve between them to the tolerance; how smooth the
    vertices are, the correlation of consecutive deviations from the chords (:func:`_scatter`): near 1
    on a smooth curve however coarsely or unevenly sampled, about -2/3 where the vertices scatter
    (noise); and, where noise dominates (the correlation below zero), its estimated standard deviation
    per coordinate (m, else 0)."""
    for i in range(offsets.shape[0] - 1):
        p = points[offsets[i]:offsets[i + 1]]
        m = p.shape[0]
        s = np.zeros(m)
        _arc_lengths(p, s)
        out_arc[i] = s[m - 1]
        turn = np.empty(m)
        span = np.empty(m)
        _turning_angles(p, turn, span)
        worst = 0.0
        for j in range(1, m):
            chord = _unit_chord(p[j - 1], p[j])[3]
            alpha = min(max(turn[j - 1], turn[j] if j < m - 1 else 0.0), 0.5 * np.pi)
            worst = max(worst, chord * alpha / 8.0)
        out_sagitta[i] = worst
        out_smooth[i], out_noise[i] = _scatter(p)


@jit
def _scatter(p):
    """How the vertices scatter about a smooth curve: ``(rho, sigma)``.

    ``e_j = p_j - (w p_{j-1} + (1 - w) p_{j+1})``, the vertex's deviation from its chord at the chord
    fraction of its arc length (zero on a straight line however unevenly sampled; about
    ``kappa h_{j-1} h_j / 2`` on a curve). ``rho = sum e_j . e_{j+1} / sum |e_j|^2``: near 1 on a smooth
    curve, ``cos(2 pi / n)`` on a coil at ``n`` points per turn, about -2/3 for white noise. Where
    ``rho < _NOISE_GATE`` (noise dominates), ``sigma`` estimates the noise's standard deviation per
    coordinate from ``e_j - e_{j+1}`` (a third difference, in which a smooth curve nearly cancels): for
    noise ``n_j`` of deviation sigma it is ``(1 + w_{j+1}) n_j - w_j n_{j-1} - (2 - w_j) n_{j+1} +
    (1 - w_{j+1}) n_{j+2}``, normal to the chords (the chord fractions absorb the tangential part), so
    ``|e_j - e_{j+1}|^2 / (c_j sigma^2)`` (``c_j`` the sum of the squared weights) is chi-squared with 2
    degrees of freedom, whose median is ``2 ln 2``: ``sigma^2`` is the median of
    ``|e_j - e_{j+1}|^2 / c_j`` over ``2 ln 2`` (a median, so a few kinks do not count). Otherwise
    ``sigma`` is 0, and so it is on strands of fewer than ``_NOISE_MIN_VERTICES`` vertices. Strands of
    fewer than 6 vertices give ``(1, 0)``."""
    m = p.shape[0]
    if m < 6:
        return 1.0, 0.0
    e = np.empty((m - 2, 3))
    w = np.empty(m - 2)
    num = 0.0
    den = 0.0
    for j in range(1, m - 1):
        la = _unit_chord(p[j - 1], p[j])[3]
        lb = _unit_chord(p[j], p[j + 1])[3]
        wj = lb / (la + lb) if la + lb > 0.0 else 0.5
        w[j - 1] = wj
        for c in range(3):
            e[j - 1, c] = p[j, c] - (wj * p[j - 1, c] + (1.0 - wj) * p[j + 1, c])
            den += e[j - 1, c] * e[j - 1, c]
            if j > 1:
                num += e[j - 2, c] * e[j - 1, c]
    rho = num / den if den > 0.0 else 1.0
    if not rho < _NOISE_GATE or m < _NOISE_MIN_VERTICES:
        return rho, 0.0
    q = np.empty(m - 3)
    for j in range(m - 3):
        c = (1.0 + w[j + 1]) ** 2 + w[j] ** 2 + (2.0 - w[j]) ** 2 + (1.0 - w[j + 1]) ** 2
        dd = 0.0
        for i in range(3):
            dd += (e[j, i] - e[j + 1, i]) ** 2
        q[j] = dd / c
    return rho, np.sqrt(np.median(q) / (2.0 * np.log(2.0)))


@jit
def element_caps(points, offsets, n_max):
    """:func:`element_cap` of every strand of a CSR polyline set, (S,) int64."""
    out = np.empty(offsets.shape[0] - 1, dtype=np.int64)
    for i in range(out.shape[0]):
        out[i] = element_cap(points[offsets[i]:offsets[i + 1]], n_max)
    return out


@jit
def fit_adaptive(p, up, tolerance, fixed, n_min, n_max, max_iter, F0, omega_out, length_out):
    """Fit one strand, splitting elements until the tolerance is met.

    Parameters
    ----------
    p : (M, 3) float64, m, the polyline (M >= 2)
    up : (3,) float64, world up (fixes the roll of the root frame)
    tolerance : float64, m, target for the largest vertex distance
    fixed : int64, a fixed element count (equal lengths), or 0 for adaptive
    n_min, n_max : int64, bounds of the adaptive count (``n_max`` 0: as many as the vertices determine,
        :func:`element_cap`)
    max_iter : int64, Levenberg-Marquardt iterations per refinement
    F0 : (3, 3) float64, out, root frame
    omega_out : (K, 3) float64, out, first ``n`` rows used; K at least ``element_cap(p, n_max)``, or
        ``fixed`` when it is given
    length_out : (K,) float64, out, first ``n`` entries used

    Returns
    -------
    n, worst, status : number of elements, largest vertex distance (m), FIT_*

    Where the vertices need more elements than the strand may carry, noise dominates them
    (:func:`_scatter`) and what it leaves exceeds the tolerance, the elements aim at
    ``sigma sqrt(2 ln M + _NOISE_MARGIN)`` instead: the strand is fitted by the smooth curve and
    reported off the tolerance.
    """
    m = p.shape[0]
    s = np.zeros(m)
    _arc_lengths(p, s)
    cap = element_cap(p, n_max)
    root = p[0].copy()
    err = np.zeros(m)
    eta = _PRIOR_OF_TOLERANCE * tolerance
    bend_cap = _CAP_FACTOR * _max_discrete_curvature(p)
    target = tolerance
    noisy = False
    if fixed > 0:
        n = min(fixed, m - 1)
        length = np.full(n, s[m - 1] / n)
        omega = np.zeros((n, 3))
        _start(root, F0, p, s, up, length, omega, eta, bend_cap, err)
        from_init = True
    else:
        # Elements as long as one helix fits the vertices within the tolerance; where that takes more
        # elements than the strand may carry (noise, kinks), that distance is doubled until it does not.
        omega_g = np.zeros((m - 1, 3))
        length_g = np.zeros(m - 1)
        within = max(_GREEDY_WITHIN * tolerance, 1e-9 * s[m - 1])
        n = _greedy_elements(root, F0, p, s, up, within, eta, bend_cap, omega_g, length_g, _TANGENT_WEIGHT,
                             _COIL_TANGENT_GAIN, cap)
        if n > cap:
            # Where noise dominates the vertices, the elements follow the smooth curve through them: the
            # distance they aim for is what the noise leaves, and no effort goes into following the noise.
            noise = _scatter(p)[1]
            if noise * np.sqrt(2.0 * np.log(m) + _NOISE_MARGIN) > tolerance:
                target = noise * np.sqrt(2.0 * np.log(m) + _NOISE_MARGIN)
                within = target
                noisy = True
            # held firmly, coarsely sampled or uneven curls can lose their phase: the usual weight
            n = _greedy_elements(root, F0, p, s, up, within, eta, bend_cap, omega_g, length_g, _TANGENT_WEIGHT,
                                 1.0, cap)
        for _ in range(40):
            if n <= cap:
                break
            within *= 2.0
            n = _greedy_elements(root, F0, p, s, up, within, eta, bend_cap, omega_g, length_g, _TANGENT_WEIGHT,
                                 1.0, cap)
        if n < n_min and m - 1 >= n_min:
            # fewer than asked for: split the longest until there are n_min
            while n < n_min:
                longest = np.argmax(length_g[:n])
                for e in range(n, longest + 1, -1):
                    length_g[e] = length_g[e - 1]
                    omega_g[e] = omega_g[e - 1]
                length_g[longest] *= 0.5
                length_g[longest + 1] = length_g[longest]
                omega_g[longest + 1] = omega_g[longest]
                n += 1
        omega = omega_g[:n].copy()
        length = length_g[:n].copy()
        from_init = _vertex_errors(root, F0, omega, length, s.copy(), p, err) > target
    if noisy and n <= cap:
        # least squares over the whole strand, the vertices at their arc lengths: the curve through the
        # middle of the noise (elements laid one after the other drift by up to the distance they aim for)
        _levenberg_marquardt(root, F0, omega, length, s, p, max_iter, False, 0.0, eta, bend_cap,
                             _NOISY_DECREASE)
        from_init = False
    while True:
        # Vertices first keep their fraction of the length (robust from a
        # rough start); the orthogonal-distance phase runs only if that is
        # not already within tolerance (fixed-fraction residuals bound the
        # true distances from above).
        if from_init:
            _levenberg_marquardt(root, F0, omega, length, s, p, max_iter, False, target, eta, bend_cap,
                                 _RELATIVE_DECREASE)
            from_init = False
        worst = _vertex_errors(root, F0, omega, length, s, p, err)
        if worst > target:
            _levenberg_marquardt(root, F0, omega, length, s, p, max_iter, True, target, eta, bend_cap,
                                 _RELATIVE_DECREASE)
            worst = _vertex_errors(root, F0, omega, length, s, p, err)
        if fixed > 0 or worst <= target or n >= cap or noisy:
            break
        # split the elements that hold a vertex beyond the tolerance, worst
        # first, between their middle vertices so each half keeps data
        starts = np.empty(n + 1)
        _starts(length, starts)
        badness = np.zeros(n)
        first = np.full(n, -1)
        count_in = np.zeros(n, dtype=np.int64)
        for j in range(1, m - 1):
            e = np.searchsorted(starts, s[j], side="right") - 1
            e = min(max(e, 0), n - 1)
            if first[e] < 0:
                first[e] = j
            count_in[e] += 1
        for j in range(1, m):
            if err[j] > target:
                e = np.searchsorted(starts, s[j], side="right") - 1
                e = min(max(e, 0), n - 1)
                badness[e] = max(badness[e], err[j])
                # a vertex near a joint is shaped by both neighbours
                if e > 0 and s[j] - starts[e] < 0.25 * length[e]:
                    badness[e - 1] = max(badness[e - 1], err[j])
                if e < n - 1 and starts[e + 1] - s[j] < 0.25 * length[e]:
                    badness[e + 1] = max(badness[e + 1], err[j])
        for e in range(n):
            if count_in[e] < 2:
                badness[e] = 0.0
        room = cap - n
        order = np.argsort(-badness)
        cut = np.full(n, -1.0)
        count = 0
        for i in range(n):
            e = order[i]
            if badness[e] <= 0.0 or count >= room:
                break
            mid = first[e] + count_in[e] // 2
            c = 0.5 * (s[mid - 1] + s[mid]) - starts[e]
            # matched arc lengths need not be ordered after sliding: keep the cut inside
            if not (0.1 * length[e] < c < 0.9 * length[e]):
                c = 0.5 * length[e]
            cut[e] = c
            count += 1
        if count == 0:
            break
        new_omega = np.empty((n + count, 3))
        new_length = np.empty(n + count)
        k = 0
        for e in range(n):
            new_omega[k] = omega[e]
            if cut[e] > 0.0:
                new_length[k] = cut[e]
                k += 1
                new_omega[k] = omega[e]
                new_length[k] = length[e] - cut[e]
            else:
                new_length[k] = length[e]
            k += 1
        n += count
        omega = new_omega
        length = new_length
    if fixed == 0 and worst > target and not noisy:
        # Splitting stalled in a local minimum: refit from scratch with the
        # largest allowed count of equal elements and keep the better fit.
        F_u = np.empty((3, 3))
        s_u = np.zeros(m)
        _arc_lengths(p, s_u)
        length_u = np.full(cap, s_u[m - 1] / cap)
        omega_u = np.zeros((cap, 3))
        _start(root, F_u, p, s_u, up, length_u, omega_u, eta, bend_cap, err)
        _levenberg_marquardt(root, F_u, omega_u, length_u, s_u, p, max_iter, False, target, eta, bend_cap,
                             _RELATIVE_DECREASE)
        _levenberg_marquardt(root, F_u, omega_u, length_u, s_u, p, max_iter, True, target, eta, bend_cap,
                             _RELATIVE_DECREASE)
        worst_u = _vertex_errors(root, F_u, omega_u, length_u, s_u, p, err)
        if worst_u < worst:
            worst = worst_u
            n = cap
            F0[:, :] = F_u
            omega = omega_u
            length = length_u
    omega_out[:n] = omega
    length_out[:n] = length
    status = FIT_OK if (fixed > 0 or worst <= tolerance) else FIT_TOLERANCE_NOT_MET
    return n, worst, status


@jit
def fit_batch(points, offsets, up, tolerance, fixed, n_min, n_max, max_iter,
              out_n, out_frame, out_omega, out_length, out_worst, out_status):
    """Fit every strand of a CSR polyline set (see :func:`fit_adaptive`).

    Parameters
    ----------
    points : (P, 3) float64, m
    offsets : (S + 1,) int64
    out_n : (S,) int64, out, elements used per strand
    out_frame : (S, 3, 3) float64, out, root frames
    out_omega : (S, n_max, 3) float64, out
    out_length : (S, n_max) float64, out, element lengths, m
    out_worst : (S,) float64, out, largest vertex distance, m
    out_status : (S,) int64, out, FIT_OK or FIT_TOLERANCE_NOT_MET
    """
    for i in range(offsets.shape[0] - 1):
        p = points[offsets[i]:offsets[i + 1]]
        n, worst, status = fit_adaptive(p, up, tolerance, fixed, n_min, n_max, max_iter,
                                        out_frame[i], out_omega[i], out_length[i])
        out_n[i] = n
        out_worst[i] = worst
        out_status[i] = status


@jit
def closest_distances(points, offsets, roots, frames, helix_offsets, omega, length, out_mean, out_max):
    """Distance from every input vertex to the fitted centerline.

    For each vertex the curve is scanned at 8 points per element, more on an
    element that turns by more than half a turn (16 per turn: a global start,
    so no far local minimum is taken), then Newton's method on the arc
    length polishes the nearest one (stationarity ``t . (x - p) = 0``,
    derivative ``1 + (Om x t) . (x - p)``). The scan skips the elements whose
    scan points all lie, by a ball around them, farther than the nearest one
    found so far (the element nearest the previous vertex is scanned first):
    the same nearest scan point as a scan of them all. Writes the per-strand
    mean and max, m.
    """
    scan_per_element = 8
    for i in range(offsets.shape[0] - 1):
        p = points[offsets[i]:offsets[i + 1]]
        om = omega[helix_offsets[i]:helix_offsets[i + 1]]
        ln = length[helix_offsets[i]:helix_offsets[i + 1]]
        n = om.shape[0]
        xs = np.empty((n + 1, 3))
        Fs = np.empty((n + 1, 3, 3))
        chain(roots[i], frames[i], om, ln, xs, Fs)
        starts = np.empty(n + 1)
        _starts(ln, starts)
        total = starts[n]
        x = np.empty(3)
        F = np.empty((3, 3))
        R = np.empty((3, 3))
        P = np.empty(3)
        Q = np.empty(3)
        # at least 8 points per element, and one per 1/16 turn of an element that winds (a coil)
        counts = np.empty(n, dtype=np.int64)
        for e in range(n):
            turning = np.sqrt(om[e, 0] ** 2 + om[e, 1] ** 2 + om[e, 2] ** 2) * ln[e]
            counts[e] = max(scan_per_element, int(np.ceil(turning / (np.pi / 8.0))))
        k = counts.sum() + 1
        scan_s = np.empty(k)
        scan_x = np.empty((k, 3))
        idx = 0
        for e in range(n):
            for h in range(counts[e]):
                scan_s[idx] = starts[e] + ln[e] * h / counts[e]
                _advance(xs[e], Fs[e], om[e], scan_s[idx] - starts[e], scan_x[idx], F, R, P, Q)
                idx += 1
        scan_s[k - 1] = total
        scan_x[k - 1] = xs[n]
        # a ball around each element's scan points (its own and the next element's first): an element
        # whose ball lies farther than the nearest scan point found so far holds no nearer one
        first = np.empty(n + 1, dtype=np.int64)
        first[0] = 0
        for e in range(n):
            first[e + 1] = first[e] + counts[e]
        centre = np.zeros((n, 3))
        radius = np.zeros(n)
        for e in range(n):
            for idx in range(first[e], first[e + 1] + 1):
                for a in range(3):
                    centre[e, a] += scan_x[idx, a]
            for a in range(3):
                centre[e, a] /= counts[e] + 1
            for idx in range(first[e], first[e + 1] + 1):
                d2 = 0.0
                for a in range(3):
                    d2 += (scan_x[idx, a] - centre[e, a]) ** 2
                radius[e] = max(radius[e], np.sqrt(d2))
        acc = 0.0
        worst = 0.0
        hint = 0
        for j in range(p.shape[0]):
            best = 1e300
            sig = 0.0
            # the element nearest the previous vertex first (vertices follow the curve), then the others
            for step in range(n + 1):
                e = hint if step == 0 else step - 1
                if step > 0:
                    if e == hint:
                        continue
                    d2 = 0.0
                    for a in range(3):
                        d2 += (centre[e, a] - p[j, a]) ** 2
                    gap = np.sqrt(d2) - radius[e]
                    if gap > 0.0 and gap * gap >= best:
                        continue
                for idx in range(first[e], first[e + 1] + 1):
                    d2 = 0.0
                    for a in range(3):
                        d2 += (scan_x[idx, a] - p[j, a]) ** 2
                    if d2 < best:
                        best = d2
                        sig = scan_s[idx]
            best = np.sqrt(best)
            for _ in range(12):
                e, local = _locate(starts, sig)
                _advance(xs[e], Fs[e], om[e], local, x, F, R, P, Q)
                diff = x - p[j]
                best = min(best, np.sqrt(diff @ diff))
                new = min(max(sig - _projection_step(om[e], Fs[e], F, diff), 0.0), total)
                if abs(new - sig) <= 1e-12 * (total + 1.0):
                    break
                sig = new
            acc += best
            worst = max(worst, best)
            hint = _locate(starts, sig)[0]
        out_mean[i] = acc / p.shape[0]
        out_max[i] = worst
