"""Super-helix kinematics: closed-form element steps and strand evaluation.

An element with material Darboux components ``omega = (kappa1, kappa2, tau)``
(1/m) and start frame ``F`` (rows ``t, n1, n2``) has the constant world Darboux
vector ``Om = kappa1 n1 + kappa2 n2 + tau t``. In the element's start frame the
Darboux vector is ``w = (tau, kappa1, kappa2)`` and, with ``[w]`` the cross
product matrix and ``x = |w| sigma``,

    R(sigma) = I + sigma A(x) [w] + sigma^2 B(x) [w]^2            (frame rotation)
    P(sigma) = int_0^sigma R e1 = sigma e1 + sigma^2 B (w x e1) + sigma^3 C (w_0 w - |w|^2 e1)
    Q(sigma) = int_0^sigma P    = sigma^2/2 e1 + sigma^3 C (w x e1) + sigma^4 D (w_0 w - |w|^2 e1)

with A = sin x / x, B = (1 - cos x)/x^2, C = (x - sin x)/x^3 and
D = (x^2/2 - 1 + cos x)/x^4. In world coordinates the end frame is
``R^T F`` and the centerline ``x0 + F^T P``. ``Q`` (the first moment of the
centerline over the element) gives gravity and mass integrals in closed form.

A, B, C, D are evaluated through ``x^2`` with a Taylor series below
``x^2 < 1``, so straight, nearly straight and extremely curly elements are all
exact to round-off. Every function here is written for both float64 and
complex128 inputs: the complex-step derivative ``Im f(w + i h e_k) / h`` of a
step is exact to round-off and gives the Jacobians without a second set of
hand-derived formulas.
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import jit

__all__ = [
    "helix_coefficients",
    "element_step",
    "chain",
    "point_at",
    "points_at",
    "frames_at",
    "strand_points",
]

# Taylor series of A, B, C, D in y = x^2: coefficient k of each is
# (-1)^k / (2k + m)! with m = 1, 2, 3, 4. Ten terms: the first dropped term is
# below 1e-20 relative for y < 1.
_SERIES_TERMS = 10
_SERIES_Y = 1.0
_SERIES = np.array(
    [[(-1.0) ** k / math.factorial(2 * k + m) for k in range(_SERIES_TERMS)] for m in (1, 2, 3, 4)]
)
# d/dy of the B and C series
_SERIES_D = np.array(
    [[(k + 1) * (-1.0) ** (k + 1) / math.factorial(2 * (k + 1) + m) for k in range(_SERIES_TERMS)] for m in (2, 3)]
)


@jit
def helix_coefficients(y):
    """A, B, C, D of the closed forms as functions of ``y = x^2``.

    Parameters
    ----------
    y : float64 or complex128
        Square of the rotation angle ``|w| sigma``.

    Returns
    -------
    A, B, C, D : same type as ``y``
        ``sin x/x``, ``(1-cos x)/x^2``, ``(x-sin x)/x^3``, ``(x^2/2-1+cos x)/x^4``.
    """
    if abs(y) < _SERIES_Y:
        # Horner: sum_k c_k y^k from the highest power down.
        a = y * 0.0
        b = y * 0.0
        c = y * 0.0
        d = y * 0.0
        for k in range(_SERIES_TERMS - 1, -1, -1):
            a = a * y + _SERIES[0, k]
            b = b * y + _SERIES[1, k]
            c = c * y + _SERIES[2, k]
            d = d * y + _SERIES[3, k]
        return a, b, c, d
    x = np.sqrt(y)
    s = np.sin(x)
    h = np.sin(0.5 * x)
    one_minus_cos = 2.0 * h * h
    a = s / x
    b = one_minus_cos / y
    c = (x - s) / (x * y)
    d = (0.5 * y - one_minus_cos) / (y * y)
    return a, b, c, d


@jit
def helix_coefficient_derivatives(y):
    """dB/dy and dC/dy (y = x^2), for the derivatives of an element's step.

    Closed forms ``(A - 2B) / (2y)`` and ``(B - 3C) / (2y)``, series below
    ``y < 1`` where they cancel.
    """
    _, _, _, _, bp, cp = helix_coefficients_and_derivatives(y)
    return bp, cp


@jit
def helix_coefficients_and_derivatives(y):
    """``A, B, C, D`` (:func:`helix_coefficients`) and ``dB/dy, dC/dy``
    (:func:`helix_coefficient_derivatives`) from one evaluation of the sines."""
    A, B, C, D = helix_coefficients(y)
    if abs(y) < _SERIES_Y:
        bp = y * 0.0
        cp = y * 0.0
        for k in range(_SERIES_TERMS - 1, -1, -1):
            bp = bp * y + _SERIES_D[0, k]
            cp = cp * y + _SERIES_D[1, k]
        return A, B, C, D, bp, cp
    return A, B, C, D, (A - 2.0 * B) / (2.0 * y), (B - 3.0 * C) / (2.0 * y)


@jit
def element_step(w0, w1, w2, sigma, R, P, Q):
    """Closed-form step of one element in its start frame.

    Parameters
    ----------
    w0, w1, w2 : float64 or complex128
        Darboux vector in the start frame, ``(tau, kappa1, kappa2)``, 1/m.
    sigma : float64
        Arc length travelled along the element, m.
    R : (3, 3) array, out
        Rotation of the frame after ``sigma`` (local coordinates).
    P : (3,) array, out
        Centerline displacement ``int_0^sigma t`` (local coordinates), m.
    Q : (3,) array, out
        First moment ``int_0^sigma P``, m^2.
    """
    ww = w0 * w0 + w1 * w1 + w2 * w2
    A, B, C, D = helix_coefficients(ww * sigma * sigma)
    sA = sigma * A
    s2B = sigma * sigma * B
    # [w] and [w]^2 = w w^T - |w|^2 I
    R[0, 0] = 1.0 + s2B * (w0 * w0 - ww)
    R[1, 1] = 1.0 + s2B * (w1 * w1 - ww)
    R[2, 2] = 1.0 + s2B * (w2 * w2 - ww)
    R[0, 1] = -sA * w2 + s2B * w0 * w1
    R[1, 0] = sA * w2 + s2B * w0 * w1
    R[0, 2] = sA * w1 + s2B * w0 * w2
    R[2, 0] = -sA * w1 + s2B * w0 * w2
    R[1, 2] = -sA * w0 + s2B * w1 * w2
    R[2, 1] = sA * w0 + s2B * w1 * w2
    # w x e1 = (0, w2, -w1);  w0 w - |w|^2 e1 = (w0^2 - ww, w0 w1, w0 w2)
    s2 = sigma * sigma
    s3 = s2 * sigma
    c3 = s3 * C
    P[0] = sigma + c3 * (w0 * w0 - ww)
    P[1] = s2 * B * w2 + c3 * w0 * w1
    P[2] = -s2 * B * w1 + c3 * w0 * w2
    d4 = s3 * sigma * D
    Q[0] = 0.5 * s2 + d4 * (w0 * w0 - ww)
    Q[1] = c3 * w2 + d4 * w0 * w1
    Q[2] = -c3 * w1 + d4 * w0 * w2


@jit
def _advance(x, F, omega_e, sigma, x_out, F_out, R, P, Q):
    """World-frame step: from (x, F) along ``sigma`` of an element ``omega_e``."""
    element_step(omega_e[2], omega_e[0], omega_e[1], sigma, R, P, Q)
    for i in range(3):
        acc = 0.0
        for k in range(3):
            acc += F[k, i] * P[k]
        x_out[i] = x[i] + acc
    for i in range(3):
        for j in range(3):
            acc = 0.0
            for k in range(3):
                acc += R[k, i] * F[k, j]
            F_out[i, j] = acc


@jit
def chain(root, frame0, omega, length, xs, Fs):
    """Start position and frame of every element of one strand, plus the tip.

    Parameters
    ----------
    root : (3,) float64, m
    frame0 : (3, 3) float64, rows (t, n1, n2)
    omega : (N, 3) float64, (kappa1, kappa2, tau) in 1/m
    length : (N,) float64, m
    xs : (N + 1, 3) float64, out
        ``xs[e]`` is the start of element ``e``; ``xs[N]`` the tip.
    Fs : (N + 1, 3, 3) float64, out
        Frames at the same places.
    """
    R = np.empty((3, 3))
    P = np.empty(3)
    Q = np.empty(3)
    xs[0, :] = root
    Fs[0, :, :] = frame0
    for e in range(omega.shape[0]):
        _advance(xs[e], Fs[e], omega[e], length[e], xs[e + 1], Fs[e + 1], R, P, Q)


@jit
def point_at(xs, Fs, omega, starts, s, out):
    """Centerline point at arc length ``s`` given the chain of a strand.

    ``starts`` (N + 1,) are the cumulative element start arc lengths; ``s``
    is clamped to ``[0, starts[N]]``.
    """
    n = omega.shape[0]
    if s <= 0.0:
        out[:] = xs[0]
        return 0
    e = np.searchsorted(starts, s, side="right") - 1
    if e >= n:
        e = n - 1
    sigma = min(s, starts[n]) - starts[e]
    R = np.empty((3, 3))
    P = np.empty(3)
    Q = np.empty(3)
    element_step(omega[e, 2], omega[e, 0], omega[e, 1], sigma, R, P, Q)
    for i in range(3):
        acc = 0.0
        for k in range(3):
            acc += Fs[e, k, i] * P[k]
        out[i] = xs[e, i] + acc
    return e


@jit
def points_at(root, frame0, omega, length, s, out):
    """Centerline points of one strand at arc lengths ``s`` (any order), m."""
    n = omega.shape[0]
    xs = np.empty((n + 1, 3))
    Fs = np.empty((n + 1, 3, 3))
    chain(root, frame0, omega, length, xs, Fs)
    starts = np.zeros(n + 1)
    for e in range(n):
        starts[e + 1] = starts[e] + length[e]
    for j in range(s.shape[0]):
        point_at(xs, Fs, omega, starts, s[j], out[j])


@jit
def frames_at(root, frame0, omega, length, s, x_out, F_out):
    """Centerline points and material frames of one strand at arc lengths ``s``."""
    n = omega.shape[0]
    xs = np.empty((n + 1, 3))
    Fs = np.empty((n + 1, 3, 3))
    chain(root, frame0, omega, length, xs, Fs)
    starts = np.zeros(n + 1)
    for e in range(n):
        starts[e + 1] = starts[e] + length[e]
    R = np.empty((3, 3))
    P = np.empty(3)
    Q = np.empty(3)
    for j in range(s.shape[0]):
        sj = min(max(s[j], 0.0), starts[n])
        e = np.searchsorted(starts, sj, side="right") - 1
        if e >= n:
            e = n - 1
        if e < 0:
            e = 0
        _advance(xs[e], Fs[e], omega[e], sj - starts[e], x_out[j], F_out[j], R, P, Q)


@jit
def _element_rate(w0, w1, w2, ww, s2, sigma, B, C, Bp, Cp, k):
    """``dP/dw_k`` and ``dphi/dw_k`` (stored component ``k``) of an element after ``sigma``, in its start
    frame, given ``ww = |w|^2``, ``s2 = sigma^2`` and the coefficients at ``ww s2`` (see
    :func:`element_derivatives`). Real or complex."""
    # local index l of stored component k: (kappa1, kappa2, tau) -> (1, 2, 0)
    l = (k + 1) % 3
    wl = w0 if l == 0 else (w1 if l == 1 else w2)
    # w x e1 = (0, w2, -w1), (w0 w - ww e1), and d(w x e1)/dw_l = e_l x e1 = (0, e1, e2)
    a1, a2 = w2, -w1
    c0, c1, c2 = w0 * w0 - ww, w0 * w1, w0 * w2
    e1 = 1.0 if l == 2 else 0.0
    e2 = -1.0 if l == 1 else 0.0
    # d(w0 w - ww e1)/dw_l
    if l == 0:
        g0, g1, g2 = 0.0 * w0, w1, w2
    elif l == 1:
        g0, g1, g2 = -2.0 * w1, w0, 0.0 * w0
    else:
        g0, g1, g2 = -2.0 * w2, 0.0 * w0, w0
    fb = 2.0 * s2 * wl * Bp
    fc = 2.0 * s2 * wl * Cp
    p0 = s2 * sigma * (fc * c0 + C * g0)
    p1 = s2 * (fb * a1 + B * e1) + s2 * sigma * (fc * c1 + C * g1)
    p2 = s2 * (fb * a2 + B * e2) + s2 * sigma * (fc * c2 + C * g2)
    # w x e_l and (w_l w - ww e_l)
    if l == 0:
        x0, x1, x2 = 0.0 * w0, w2, -w1
    elif l == 1:
        x0, x1, x2 = -w2, 0.0 * w0, w0
    else:
        x0, x1, x2 = w1, -w0, 0.0 * w0
    f0 = sigma * ((1.0 if l == 0 else 0.0) + sigma * B * x0 + s2 * C * (wl * w0 - (ww if l == 0 else 0.0)))
    f1 = sigma * ((1.0 if l == 1 else 0.0) + sigma * B * x1 + s2 * C * (wl * w1 - (ww if l == 1 else 0.0)))
    f2 = sigma * ((1.0 if l == 2 else 0.0) + sigma * B * x2 + s2 * C * (wl * w2 - (ww if l == 2 else 0.0)))
    return p0, p1, p2, f0, f1, f2


@jit
def element_derivatives(omega_e, sigma, F, dx, dth):
    """Derivatives of an element's point and frame after ``sigma`` w.r.t. its omega.

    With ``y = |w|^2 sigma^2`` and ``[dphi] = dR R^T`` (the left Jacobian of
    the rotation exponential),

        dP/dw_k   = sigma^2 (2 sigma^2 w_k B'(y) (w x e1) + B (e_k x e1))
                  + sigma^3 (2 sigma^2 w_k C'(y) (w_0 w - |w|^2 e1) + C d(w_0 w - |w|^2 e1)/dw_k)
        dphi/dw_k = sigma (e_k + sigma B (w x e_k) + sigma^2 C (w_k w - |w|^2 e_k)).

    Parameters
    ----------
    omega_e : (3,) float64, (kappa1, kappa2, tau), 1/m
    sigma : float64, arc length along the element, m
    F : (3, 3) float64, the element's start frame (rows t, n1, n2)
    dx : (3, 3) float64, out
        ``dx[k]`` is d(point)/d(omega_e[k]) in world coordinates, m^2.
    dth : (3, 3) float64, out
        ``dth[k]`` is the world rotation vector of the frame per unit
        ``omega_e[k]``, m.
    """
    w0 = omega_e[2]
    w1 = omega_e[0]
    w2 = omega_e[1]
    ww = w0 * w0 + w1 * w1 + w2 * w2
    s2 = sigma * sigma
    y = ww * s2
    A, B, C, D, Bp, Cp = helix_coefficients_and_derivatives(y)
    for k in range(3):
        p0, p1, p2, f0, f1, f2 = _element_rate(w0, w1, w2, ww, s2, sigma, B, C, Bp, Cp, k)
        for i in range(3):
            dx[k, i] = F[0, i] * p0 + F[1, i] * p1 + F[2, i] * p2
            dth[k, i] = F[0, i] * f0 + F[1, i] * f1 + F[2, i] * f2


@jit
def _points_on(root, frame0, offsets, omega, length, strand, s, out):
    """Centerline points of strands ``strand`` at arc lengths ``s``, (n, 3); each strand's element
    chain is made once for its consecutive entries."""
    last = -1
    xs = np.empty((1, 3))
    Fs = np.empty((1, 3, 3))
    starts = np.zeros(1)
    for i in range(strand.shape[0]):
        k = strand[i]
        a = offsets[k]
        z = offsets[k + 1]
        if k != last:
            n = z - a
            xs = np.empty((n + 1, 3))
            Fs = np.empty((n + 1, 3, 3))
            chain(root[k], frame0[k], omega[a:z], length[a:z], xs, Fs)
            starts = np.zeros(n + 1)
            for e in range(n):
                starts[e + 1] = starts[e] + length[a + e]
            last = k
        point_at(xs, Fs, omega[a:z], starts, s[i], out[i])


def strand_points(root, frame0, offsets, omega, length, strand, s) -> np.ndarray:
    """Centerline points of strands ``strand`` (n,) at arc lengths ``s`` (n,) from their roots, (n, 3), m: each
    strand's chain made once (:func:`_points_on`, the entries taken strand by strand)."""
    strand = np.asarray(strand, dtype=np.int64)
    order = np.argsort(strand, kind="stable")
    out = np.empty((len(strand), 3))
    f64 = (lambda a: np.ascontiguousarray(a, dtype=np.float64))
    _points_on(f64(root), f64(frame0), np.ascontiguousarray(offsets, dtype=np.int64), f64(omega), f64(length),
               np.ascontiguousarray(strand[order]), f64(np.asarray(s)[order]), out)
    result = np.empty_like(out)
    result[order] = out
    return result
