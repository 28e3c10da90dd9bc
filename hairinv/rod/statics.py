"""Rod statics kernels: the generalized gravity force of super-helices.

Gravity's potential on a strand of linear density ``lam`` is
``V(q) = -lam * g . int x(s) ds``, and its generalized force is
``F_g = -dV/dq = lam * int g . dx(s)/dq ds``. For element ``e`` of a strand:

- the element itself moves by ``dx(sigma)/d omega_e``; its contribution is
  ``lam g . d/d omega_e int_0^l x dsigma``, the derivative of the element's
  first moment ``F_e^T Q(l)`` (taken by complex step, exact to round-off);
- everything downstream moves rigidly about the element's end ``x_{e+1}``:
  ``dx = dx_end + dth x (x - x_{e+1})``, so its contribution is
  ``lam [ M g . dx_end + dth . ((S - M x_{e+1}) x g) ]`` with ``M`` the
  downstream length and ``S`` the downstream integral of ``x``, both suffix
  sums. The whole strand costs O(N), never O(N^2).
"""

from __future__ import annotations

import numpy as np

from .._jit import jit
from .helix import _advance, chain, element_derivatives, element_step

__all__ = ["gravity_forces", "gravity_hessian", "gravity_potential", "point_jacobian", "point_load_hessian"]

_H = 1e-30  # complex-step size: the derivative is exact for any tiny step


@jit
def _moment_derivatives(omega_e, ell, F, dS):
    """d/d omega_e[k] of the element's world first moment ``F^T Q(ell)`` (rows k), m^3."""
    Rc = np.empty((3, 3), dtype=np.complex128)
    Pc = np.empty(3, dtype=np.complex128)
    Qc = np.empty(3, dtype=np.complex128)
    for k in range(3):
        w0 = complex(omega_e[2])
        w1 = complex(omega_e[0])
        w2 = complex(omega_e[1])
        # stored (kappa1, kappa2, tau) -> local (tau, kappa1, kappa2)
        if k == 0:
            w1 += 1j * _H
        elif k == 1:
            w2 += 1j * _H
        else:
            w0 += 1j * _H
        element_step(w0, w1, w2, ell, Rc, Pc, Qc)
        for i in range(3):
            dS[k, i] = (F[0, i] * Qc[0].imag + F[1, i] * Qc[1].imag + F[2, i] * Qc[2].imag) / _H


@jit
def _element_moment(x0, F, omega_e, ell, out):
    """World first moment ``int_0^ell x dsigma = ell x0 + F^T Q(ell)`` of an element, m^2."""
    R = np.empty((3, 3))
    P = np.empty(3)
    Q = np.empty(3)
    element_step(omega_e[2], omega_e[0], omega_e[1], ell, R, P, Q)
    for i in range(3):
        out[i] = ell * x0[i] + F[0, i] * Q[0] + F[1, i] * Q[1] + F[2, i] * Q[2]


@jit
def gravity_potential(root, frame0, omega, length, lam, gravity):
    """Gravitational potential ``-lam g . int x ds`` of one strand, J.

    Parameters
    ----------
    root : (3,) float64, m
    frame0 : (3, 3) float64, rows (t, n1, n2)
    omega : (N, 3) float64, (kappa1, kappa2, tau), 1/m
    length : (N,) float64, m
    lam : float64, linear density, kg/m
    gravity : (3,) float64, m/s^2 (pointing down)
    """
    n = omega.shape[0]
    xs = np.empty((n + 1, 3))
    Fs = np.empty((n + 1, 3, 3))
    chain(root, frame0, omega, length, xs, Fs)
    moment = np.empty(3)
    v = 0.0
    for e in range(n):
        _element_moment(xs[e], Fs[e], omega[e], length[e], moment)
        v -= lam * (gravity[0] * moment[0] + gravity[1] * moment[1] + gravity[2] * moment[2])
    return v


@jit
def gravity_forces(root, frame0, omega, length, lam, gravity, out):
    """Generalized gravity force ``F_g = -dV/d omega`` of one strand.

    Parameters
    ----------
    root, frame0, omega, length, lam, gravity : as :func:`gravity_potential`
    out : (N, 3) float64, out
        Force conjugate to ``(kappa1, kappa2, tau)`` of each element, J m
        (work per unit change of curvature).
    """
    n = omega.shape[0]
    xs = np.empty((n + 1, 3))
    Fs = np.empty((n + 1, 3, 3))
    chain(root, frame0, omega, length, xs, Fs)
    moment = np.empty(3)
    # suffix sums of length and of int x ds over the elements after e
    mass = 0.0
    first = np.zeros(3)
    dx = np.empty((3, 3))
    dth = np.empty((3, 3))
    dS = np.empty((3, 3))
    arm = np.empty(3)
    for e in range(n - 1, -1, -1):
        # downstream of e (elements e+1 ...): rigid motion about xs[e+1]
        for i in range(3):
            arm[i] = first[i] - mass * xs[e + 1, i]
        # (S - M x_{e+1}) x g
        torque0 = arm[1] * gravity[2] - arm[2] * gravity[1]
        torque1 = arm[2] * gravity[0] - arm[0] * gravity[2]
        torque2 = arm[0] * gravity[1] - arm[1] * gravity[0]
        element_derivatives(omega[e], length[e], Fs[e], dx, dth)
        _moment_derivatives(omega[e], length[e], Fs[e], dS)
        for k in range(3):
            down = mass * (gravity[0] * dx[k, 0] + gravity[1] * dx[k, 1] + gravity[2] * dx[k, 2])
            down += dth[k, 0] * torque0 + dth[k, 1] * torque1 + dth[k, 2] * torque2
            own = gravity[0] * dS[k, 0] + gravity[1] * dS[k, 1] + gravity[2] * dS[k, 2]
            out[e, k] = lam * (down + own)
        # add element e to the suffix sums
        _element_moment(xs[e], Fs[e], omega[e], length[e], moment)
        mass += length[e]
        first += moment


@jit
def _perturbed_end(x, F, omega_e, ell, k, dw, w, x_end, F_end, R, P, Q):
    """An element's end point and frame with its ``omega_e[k]`` moved by ``dw`` (``w``: the moved omega),
    for the central differences of the Hessians' diagonal blocks."""
    for i in range(3):
        w[i] = omega_e[i]
    w[k] += dw
    _advance(x, F, w, ell, x_end, F_end, R, P, Q)


@jit
def gravity_hessian(root, frame0, omega, length, lam, gravity, out):
    """Hessian of the gravity potential, ``-dF_g/d omega``, (3N, 3N), from the rigid-downstream structure.

    With ``D_ek = d/d omega_ek int_{s >= start of e} x ds`` (so that
    ``F_g[e, k] = lam g . D_ek``, see :func:`gravity_forces`) and
    ``dth_ek`` the rotation of everything after element ``e``, an element
    ``b`` after ``a`` only moves points the lever arm of ``a`` integrates,
    so the off-diagonal blocks are closed-form:
    ``H[ak, bk'] = -lam g . (dth_ak x D_bk')``. The diagonal blocks (an
    element against itself) are central differences of ``D_a`` in
    ``omega_a`` with the strand after it carried rigidly, step
    ``1e-5 (1 / L + |omega[a, k]|)``: relative accuracy about 1e-10.
    O(N^2) products plus O(N) element evaluations, where differencing
    :func:`gravity_forces` in every coordinate costs O(N^2) element
    evaluations. Symmetric up to the differences' round-off.
    """
    n = omega.shape[0]
    xs = np.empty((n + 1, 3))
    Fs = np.empty((n + 1, 3, 3))
    chain(root, frame0, omega, length, xs, Fs)
    D = np.empty((n, 3, 3))
    dth_all = np.empty((n, 3, 3))
    arms = np.empty((n, 3))
    masses = np.empty(n)
    dx = np.empty((3, 3))
    dth = np.empty((3, 3))
    dS = np.empty((3, 3))
    moment = np.empty(3)
    first = np.zeros(3)
    mass = 0.0
    total = 0.0
    for e in range(n - 1, -1, -1):
        total += length[e]
        for i in range(3):
            arms[e, i] = first[i] - mass * xs[e + 1, i]
        masses[e] = mass
        element_derivatives(omega[e], length[e], Fs[e], dx, dth)
        _moment_derivatives(omega[e], length[e], Fs[e], dS)
        _lever_derivatives(mass, dx, dth, dS, arms[e], D[e])
        dth_all[e] = dth
        _element_moment(xs[e], Fs[e], omega[e], length[e], moment)
        mass += length[e]
        first += moment
    g = gravity
    for a in range(n):
        for k in range(3):
            t = dth_all[a, k]
            # g x dth_ak
            c0 = g[1] * t[2] - g[2] * t[1]
            c1 = g[2] * t[0] - g[0] * t[2]
            c2 = g[0] * t[1] - g[1] * t[0]
            for b in range(a + 1, n):
                for k2 in range(3):
                    v = -lam * (D[b, k2, 0] * c0 + D[b, k2, 1] * c1 + D[b, k2, 2] * c2)
                    out[3 * a + k, 3 * b + k2] = v
                    out[3 * b + k2, 3 * a + k] = v
    # diagonal blocks: D_a(omega_a) with the strand after a turning with its end frame
    R = np.empty((3, 3))
    P = np.empty(3)
    Q = np.empty(3)
    x_end = np.empty(3)
    F_end = np.empty((3, 3))
    local = np.empty(3)
    arm = np.empty(3)
    w = np.empty(3)
    Dp = np.empty((3, 3))
    Dm = np.empty((3, 3))
    for a in range(n):
        for j in range(3):
            local[j] = Fs[a + 1, j, 0] * arms[a, 0] + Fs[a + 1, j, 1] * arms[a, 1] + Fs[a + 1, j, 2] * arms[a, 2]
        for k2 in range(3):
            h = 1e-5 * (1.0 / total + abs(omega[a, k2]))
            for side in range(2):
                _perturbed_end(xs[a], Fs[a], omega[a], length[a], k2, h if side == 0 else -h, w, x_end, F_end, R, P, Q)
                for i in range(3):
                    arm[i] = local[0] * F_end[0, i] + local[1] * F_end[1, i] + local[2] * F_end[2, i]
                element_derivatives(w, length[a], Fs[a], dx, dth)
                _moment_derivatives(w, length[a], Fs[a], dS)
                _lever_derivatives(masses[a], dx, dth, dS, arm, Dp if side == 0 else Dm)
            for k in range(3):
                out[3 * a + k, 3 * a + k2] = -lam * (g[0] * (Dp[k, 0] - Dm[k, 0]) + g[1] * (Dp[k, 1] - Dm[k, 1])
                                                     + g[2] * (Dp[k, 2] - Dm[k, 2])) / (2.0 * h)


@jit
def _lever_derivatives(mass, dx, dth, dS, arm, out):
    """``out[k] = mass dx_k + dth_k x arm + dS_k``: d/d omega_ek of the first moment of the strand from
    element ``e`` on, given the mass (length) after it and the lever arm ``int (x - x_end) ds`` of it."""
    for k in range(3):
        out[k, 0] = mass * dx[k, 0] + dth[k, 1] * arm[2] - dth[k, 2] * arm[1] + dS[k, 0]
        out[k, 1] = mass * dx[k, 1] + dth[k, 2] * arm[0] - dth[k, 0] * arm[2] + dS[k, 1]
        out[k, 2] = mass * dx[k, 2] + dth[k, 0] * arm[1] - dth[k, 1] * arm[0] + dS[k, 2]


@jit
def point_jacobian(root, frame0, omega, length, s, out):
    """Derivatives of the centerline point at arc length ``s`` w.r.t. every omega.

    A contact at ``s`` moves when an element upstream of it changes (rigidly,
    about that element's end) or when its own element does; elements
    downstream do not move it. With a contact frame ``C`` (rows normal,
    tangent1, tangent2), the contact Jacobian rows are ``H_i = C @ J``.

    Parameters
    ----------
    root, frame0, omega, length : one strand, as :func:`gravity_potential`
    s : float64, arc length of the point, m (clamped to the strand)
    out : (N, 3, 3) float64, out
        ``out[e, k]`` is d x(s) / d omega[e, k] in world coordinates, m^2;
        zero for the elements after the one holding ``s``.

    Returns
    -------
    int
        Index of the element holding ``s``: rows ``0..e`` are the non-zeros.
    """
    n = omega.shape[0]
    xs = np.empty((n + 1, 3))
    Fs = np.empty((n + 1, 3, 3))
    chain(root, frame0, omega, length, xs, Fs)
    dX = np.empty((n, 3, 3))
    dTh = np.empty((n, 3, 3))
    return chained_point_jacobian(xs, Fs, omega, length, dX, dTh, 0, s, out)


@jit
def chained_point_jacobian(xs, Fs, omega, length, dX, dTh, done, s, out):
    """:func:`point_jacobian` given the strand's element chain ``xs, Fs`` (:func:`chain`).

    ``dX, dTh`` (N, 3, 3) hold each element's whole-length derivatives
    (:func:`element_derivatives`) for the first ``done`` elements and are
    extended as far as this point needs, so several points of one strand
    share them. Returns the index of the element holding ``s`` (as
    :func:`point_jacobian`); the elements before it are then done.
    """
    n = omega.shape[0]
    start = 0.0
    e_s = n - 1
    for e in range(n):
        if s < start + length[e] or e == n - 1:
            e_s = e
            break
        start += length[e]
    sigma = min(max(s - start, 0.0), length[e_s])
    R = np.empty((3, 3))
    P = np.empty(3)
    Q = np.empty(3)
    element_step(omega[e_s, 2], omega[e_s, 0], omega[e_s, 1], sigma, R, P, Q)
    x = np.empty(3)
    for i in range(3):
        x[i] = xs[e_s, i] + Fs[e_s, 0, i] * P[0] + Fs[e_s, 1, i] * P[1] + Fs[e_s, 2, i] * P[2]
    out[:, :, :] = 0.0
    for e in range(done, e_s):
        element_derivatives(omega[e], length[e], Fs[e], dX[e], dTh[e])
    for e in range(e_s):
        dx = dX[e]
        dth = dTh[e]
        for k in range(3):
            r0 = x[0] - xs[e + 1, 0]
            r1 = x[1] - xs[e + 1, 1]
            r2 = x[2] - xs[e + 1, 2]
            out[e, k, 0] = dx[k, 0] + dth[k, 1] * r2 - dth[k, 2] * r1
            out[e, k, 1] = dx[k, 1] + dth[k, 2] * r0 - dth[k, 0] * r2
            out[e, k, 2] = dx[k, 2] + dth[k, 0] * r1 - dth[k, 1] * r0
    dx = np.empty((3, 3))
    dth = np.empty((3, 3))
    element_derivatives(omega[e_s], sigma, Fs[e_s], dx, dth)
    for k in range(3):
        for i in range(3):
            out[e_s, k, i] = dx[k, i]
    return e_s


@jit
def point_load_hessian(root, frame0, omega, length, s, force, out):
    """Hessian of the potential of dead point loads, ``-sum_k f_k . x(s_k)``, w.r.t. omega, (3N, 3N).

    A contact force held fixed in the world while its material point moves does
    work at second order, ``-f . d^2 x``: this is the contact forces' share of the
    Hessian of the Lagrangian whose restriction to the motions that keep the
    contact points in place decides the stability of a supported equilibrium
    (the gravity share is :func:`gravity_hessian`, built the same way).

    An element ``a`` moves the points after it rigidly about its end, by
    ``dx = Dx_ak + Dth_ak x (x - x_{a+1})``, and ``Dx_a``, ``Dth_a``, ``x_{a+1}``
    do not depend on the elements after ``a``; so for ``b > a``
    ``d^2 x / d omega_ak d omega_bk' = Dth_ak x J_bk'`` (``J_bk'`` the point's
    Jacobian column) and the off-diagonal blocks are closed-form,
    ``H[ak, bk'] = -Dth_ak . M_bk'`` with ``M_bk' = sum_k J_k,bk' x f_k`` over
    the loads at or after element ``b``'s start. The diagonal blocks (an
    element against itself) are central differences of the element's own
    generalized force with the strand after it carried rigidly, step
    ``1e-5 (1 / L + |omega[a, k]|)``, then symmetrised. O(N K) products and
    O(N (1 + K)) element evaluations for K loads, where differencing the whole
    generalized force costs O(N^2 K).

    Parameters
    ----------
    root, frame0, omega, length : one strand, as :func:`gravity_potential`
    s : (K,) float64, arc lengths of the loads, m, sorted ascending
    force : (K, 3) float64, world forces, N
    out : (3N, 3N) float64, out, J
    """
    n = omega.shape[0]
    K = s.shape[0]
    out[:, :] = 0.0
    if K == 0 or n == 0:
        return
    total = 0.0
    for e in range(n):
        total += length[e]
    xs = np.empty((n + 1, 3))
    Fs = np.empty((n + 1, 3, 3))
    chain(root, frame0, omega, length, xs, Fs)
    # each load's element (the one holding s, as chained_point_jacobian finds it) and its place on it
    elem = np.empty(K, np.int64)
    sigma = np.empty(K)
    xl = np.empty((K, 3))
    Fl = np.empty((3, 3))
    R = np.empty((3, 3))
    P = np.empty(3)
    Q = np.empty(3)
    start = 0.0
    e = 0
    for k in range(K):
        while e < n - 1 and not s[k] < start + length[e]:
            start += length[e]
            e += 1
        elem[k] = e
        sigma[k] = min(max(s[k] - start, 0.0), length[e])
        _advance(xs[e], Fs[e], omega[e], sigma[k], xl[k], Fl, R, P, Q)
    Dx = np.empty((n, 3, 3))
    Dth = np.empty((n, 3, 3))
    for a in range(n):
        element_derivatives(omega[a], length[a], Fs[a], Dx[a], Dth[a])
    # M[b, k'] = sum over the loads on or after b of J_{l, bk'} x f_l
    M = np.zeros((n, 3, 3))
    dx = np.empty((3, 3))
    dth = np.empty((3, 3))
    J = np.empty(3)
    for l in range(K):
        f = force[l]
        for b in range(elem[l] + 1):
            if b < elem[l]:
                r0 = xl[l, 0] - xs[b + 1, 0]
                r1 = xl[l, 1] - xs[b + 1, 1]
                r2 = xl[l, 2] - xs[b + 1, 2]
            else:
                element_derivatives(omega[b], sigma[l], Fs[b], dx, dth)
            for k in range(3):
                if b < elem[l]:
                    J[0] = Dx[b, k, 0] + Dth[b, k, 1] * r2 - Dth[b, k, 2] * r1
                    J[1] = Dx[b, k, 1] + Dth[b, k, 2] * r0 - Dth[b, k, 0] * r2
                    J[2] = Dx[b, k, 2] + Dth[b, k, 0] * r1 - Dth[b, k, 1] * r0
                else:
                    J[0] = dx[k, 0]
                    J[1] = dx[k, 1]
                    J[2] = dx[k, 2]
                M[b, k, 0] += J[1] * f[2] - J[2] * f[1]
                M[b, k, 1] += J[2] * f[0] - J[0] * f[2]
                M[b, k, 2] += J[0] * f[1] - J[1] * f[0]
    for a in range(n):
        for k in range(3):
            for b in range(a + 1, n):
                for k2 in range(3):
                    v = -(Dth[a, k, 0] * M[b, k2, 0] + Dth[a, k, 1] * M[b, k2, 1] + Dth[a, k, 2] * M[b, k2, 2])
                    out[3 * a + k, 3 * b + k2] = v
                    out[3 * b + k2, 3 * a + k] = v
    # diagonal blocks: the element's own generalized force, the loads after it carried with its end frame
    local = np.empty((K, 3))
    x_end = np.empty(3)
    F_end = np.empty((3, 3))
    arm = np.empty(3)
    w = np.empty(3)
    Gp = np.empty(3)
    Gm = np.empty(3)
    first = 0  # the first load on or after element a
    for a in range(n):
        while first < K and elem[first] < a:
            first += 1
        if first == K:
            break
        for l in range(first, K):
            if elem[l] > a:
                for j in range(3):
                    local[l, j] = Fs[a + 1, j, 0] * (xl[l, 0] - xs[a + 1, 0]) \
                        + Fs[a + 1, j, 1] * (xl[l, 1] - xs[a + 1, 1]) + Fs[a + 1, j, 2] * (xl[l, 2] - xs[a + 1, 2])
        for k2 in range(3):
            h = 1e-5 * (1.0 / total + abs(omega[a, k2]))
            for side in range(2):
                G = Gp if side == 0 else Gm
                G[:] = 0.0
                _perturbed_end(xs[a], Fs[a], omega[a], length[a], k2, h if side == 0 else -h, w, x_end, F_end, R, P, Q)
                element_derivatives(w, length[a], Fs[a], dx, dth)
                for l in range(first, K):
                    f = force[l]
                    if elem[l] > a:
                        for i in range(3):
                            arm[i] = local[l, 0] * F_end[0, i] + local[l, 1] * F_end[1, i] + local[l, 2] * F_end[2, i]
                        for k in range(3):
                            # f . (dx_k + dth_k x arm)
                            G[k] += f[0] * (dx[k, 0] + dth[k, 1] * arm[2] - dth[k, 2] * arm[1]) \
                                + f[1] * (dx[k, 1] + dth[k, 2] * arm[0] - dth[k, 0] * arm[2]) \
                                + f[2] * (dx[k, 2] + dth[k, 0] * arm[1] - dth[k, 1] * arm[0])
                if elem[first] == a:
                    for l in range(first, K):
                        if elem[l] != a:
                            break
                        f = force[l]
                        element_derivatives(w, sigma[l], Fs[a], Dx[a], Dth[a])  # (Dx[a], Dth[a] no longer needed)
                        for k in range(3):
                            G[k] += f[0] * Dx[a, k, 0] + f[1] * Dx[a, k, 1] + f[2] * Dx[a, k, 2]
            for k in range(3):
                out[3 * a + k, 3 * a + k2] = -(Gp[k] - Gm[k]) / (2.0 * h)
        for k in range(3):
            for k2 in range(k + 1, 3):
                v = 0.5 * (out[3 * a + k, 3 * a + k2] + out[3 * a + k2, 3 * a + k])
                out[3 * a + k, 3 * a + k2] = v
                out[3 * a + k2, 3 * a + k] = v
