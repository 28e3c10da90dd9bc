"""The law of one contact: Coulomb cone, Fischer-Burmeister function, local solve.

A contact force ``r = (r_N, r_T1, r_T2)`` (contact frame, normal first) lies
in the Coulomb cone ``K_mu = {|r_T| <= mu r_N}``; its dual cone is
``K*_mu = {|u_T| <= u_N / mu}``. One contact's problem is the cone
complementarity problem

    K_mu ∋ r ⟂ u = W r + b ∈ K*_mu        (W 3x3 SPD, b (3,)),

the optimality condition of ``min 1/2 r'Wr + b'r`` over ``K_mu`` (statics,
convex). Dynamics uses the De Saxce-modified velocity
``u~ = u + mu |u_T| e_N`` in place of ``u`` (``desaxce=True``; not convex).

Kernels take float64 arrays the caller allocated and never raise: the local
solve returns one of the status codes ``CODE_OK``, ``CODE_NOT_CONVERGED``,
``CODE_NUMERICAL``. ``mu`` may be ``0`` (normal force only) or ``inf`` (the
half-space ``r_N >= 0``; its dual is the ray ``u_T = 0, u_N >= 0``, and the
De Saxce term vanishes on it, so ``desaxce`` changes nothing there).

Fischer-Burmeister (Daviet, Bertails-Descoubes, Boissieux 2011, appendix A):
with ``m = max(1, mu)`` the scaled pair

    x = (mu r_N, r_T) / m,      y = (u_N, mu u_T) / m

maps ``K_mu`` and ``K*_mu`` onto the self-dual Lorentz cone
``L = {|x_T| <= x_0}`` with ``x.y = mu (r.u) / m^2``, so the Jordan-algebra
function ``phi(x, y) = x + y - sqrt(x^2 + y^2)`` is zero exactly at the
complementary pairs of the Coulomb problem. Its smaller spectral value is
evaluated as a sum of squares (no cancellation), which keeps ``phi`` and its
Jacobian accurate to round-off near the solution of a sliding contact. The
Jacobian is ``d phi / dx = I - L_w^-1 L_x`` with ``w = sqrt(x^2 + y^2)``
(``L_v`` the arrow matrix of ``v``); the ``1/sqrt(lambda_1)`` term is bounded
(its numerator vanishes with it) and dropped when ``lambda_1 = 0``, and at
``x = y = 0`` the element ``(1 - 1/sqrt 2) I`` of the generalized Jacobian is
used. (It is derived here from ``w o w = x o x + y o y`` rather than copied from
the paper's A.1, whose printed Jacobian has a published erratum, and is checked
against finite differences in tests/test_solver_local.py.)

Local solve (``solve_contact``): closed forms first (take-off, ``mu = 0``,
``mu = inf``, sticking); then, for a sliding contact, the slip angle of the
warm start, else of the better of the warm start and the projected sticking
force, refined by scalar Newton steps on the sliding equation ``g(a) = 0``,
kept if its force meets the tolerance (from a Gauss-Seidel warm start it
nearly always does: sweeps on ruby's inverse problem became 1.4 times faster);
else a few FB Newton steps, then a fail-safe that finds every sliding solution
as a root of that degree-2 trigonometric polynomial in the slip angle, then
the rest of the FB Newton steps from the best point. The tolerance applies to ``relative_residual``, the natural-map residual
relative to ``|b| + rho |r|``; ``LOCAL_TOL = eps^(3/4)``.

Numba options: every kernel uses ``error_model="numpy"`` (a division by zero
yields inf/NaN instead of raising; each such case is guarded or ends in a
status code). The few helpers called inside the Newton loop are compiled with
``inline="always"``: 1.8 -> 1.6 us per cold sliding solve (bench quoted in
the commit), for about 1 s more of one-off compilation.
"""

from __future__ import annotations

import numpy as np

from .._jit import jit
from .status import Status

__all__ = [
    "CODE_NOT_CONVERGED",
    "CODE_NUMERICAL",
    "CODE_OK",
    "LOCAL_TOL",
    "STATUS_MAP",
    "fb_coulomb",
    "fb_function",
    "fb_jacobian",
    "natural_residual",
    "natural_scalars",
    "project_cone",
    "project_scalars",
    "relative_residual",
    "solve_contact",
]

CODE_OK = 0
CODE_NOT_CONVERGED = 1  # r holds the best iterate found (smallest natural-map residual)
CODE_NUMERICAL = 2  # NaN/inf in W, b or mu, mu < 0, or W not positive definite; r untouched
#: the local solve's codes as the solver's statuses
STATUS_MAP = {CODE_OK: Status.CONVERGED, CODE_NOT_CONVERGED: Status.MAX_ITERS, CODE_NUMERICAL: Status.NUMERICAL_ERROR}

# Default local tolerance: eps^(3/4), relative (see ``relative_residual``).
LOCAL_TOL = float(np.finfo(np.float64).eps ** 0.75)

_INV_SQRT2 = 0.7071067811865476
_FB_ZERO = 1.0 - _INV_SQRT2  # generalized Jacobian element of phi at x = y = 0
_ARMIJO = 1e-4
_HALVINGS = 30
# W / rho (trace 3) whose smallest eigenvalue is above -_SEMIDEFINITE is positive semidefinite to
# working precision: its entries carry round-off of a few eps per term summed (H D H^T over a strand's
# columns); the local problem is then solved with that eigenvalue raised to _SHIFT, which moves the
# relative residual by at most _SHIFT, far below LOCAL_TOL
_SEMIDEFINITE = 1e-10
_SHIFT = 64.0 * float(np.finfo(np.float64).eps)


# --------------------------------------------------------------------------- cone


@jit(error_model="numpy")
def project_scalars(x0, x1, x2, mu):
    """Projection of ``(x0, x1, x2)`` onto ``K_mu``, as a tuple."""
    if mu == np.inf:
        return max(x0, 0.0), x1, x2
    t = np.hypot(x1, x2)
    if x0 >= 0.0 and t <= mu * x0:
        return x0, x1, x2
    if mu * t <= -x0:
        return 0.0, 0.0, 0.0
    # onto the boundary ray through (cN, cT x_T / t), a unit generator
    h = np.hypot(1.0, mu)
    cn = 1.0 / h
    ct = mu / h
    a = x0 * cn + t * ct
    s = a * ct / t
    return a * cn, s * x1, s * x2


@jit(error_model="numpy")
def project_cone(x, mu, out):
    """Euclidean projection onto the Coulomb cone ``K_mu``.

    Parameters
    ----------
    x : (3,) float64, (normal, tangent 1, tangent 2)
    mu : float64 >= 0; ``0`` gives the half-line ``r_T = 0, r_N >= 0``,
        ``inf`` the half-space ``r_N >= 0``
    out : (3,) float64, written; may be ``x`` itself
    """
    p0, p1, p2 = project_scalars(x[0], x[1], x[2], mu)
    out[0] = p0
    out[1] = p1
    out[2] = p2


@jit(error_model="numpy")
def _desaxce_normal(u0, u1, u2, mu, desaxce):
    """Normal component of ``u~ = u + mu |u_T| e_N`` (``u_N`` itself if not desaxce)."""
    if desaxce and mu > 0.0 and mu < np.inf:
        return u0 + mu * np.hypot(u1, u2)
    return u0


@jit(error_model="numpy")
def natural_scalars(r0, r1, r2, u0, u1, u2, mu, desaxce):
    """``|r - P_K(r - u~)|``."""
    v0 = _desaxce_normal(u0, u1, u2, mu, desaxce)
    p0, p1, p2 = project_scalars(r0 - v0, r1 - u1, r2 - u2, mu)
    return np.sqrt((r0 - p0) ** 2 + (r1 - p1) ** 2 + (r2 - p2) ** 2)


@jit(error_model="numpy")
def natural_residual(r, u, mu, desaxce=False):
    """Natural-map residual ``|r - P_K(r - u)|`` (Euclidean norm), zero iff ``r, u`` solve the CCP.

    With ``desaxce`` the De Saxce velocity ``u~ = u + mu |u_T| e_N`` replaces ``u``.
    Units mix those of ``r`` and ``u``: scale ``u`` (e.g. by ``3 / trace W``) first for a force.
    """
    return natural_scalars(r[0], r[1], r[2], u[0], u[1], u[2], mu, desaxce)


@jit(error_model="numpy", inline="always")
def _amplification(mu, desaxce):
    """``1 + mu`` with the De Saxce term (it multiplies the round-off of ``u_T`` by ``mu``), else 1."""
    if desaxce and mu < np.inf:
        return 1.0 + mu
    return 1.0


@jit(error_model="numpy")
def relative_residual(W, b, mu, r, desaxce=False):
    """Scale-free residual the local solve compares with its tolerance.

    ``|rho r - P_K(rho r - u~)| / (|b| + rho |r|)`` with ``u = W r + b`` and
    ``rho = trace(W) / 3``; zero at the solution, ``~eps`` is round-off level,
    unchanged when ``W``, ``b`` or ``r`` are multiplied by positive numbers
    consistent with ``W r + b``. With ``desaxce`` it is further divided by
    ``1 + mu``: ``u~_N = u_N + mu |u_T|`` carries ``mu`` times the round-off of
    ``u``, so that is the level a computed solution can reach.
    """
    rho = (W[0, 0] + W[1, 1] + W[2, 2]) / 3.0
    u0 = W[0, 0] * r[0] + W[0, 1] * r[1] + W[0, 2] * r[2] + b[0]
    u1 = W[1, 0] * r[0] + W[1, 1] * r[1] + W[1, 2] * r[2] + b[1]
    u2 = W[2, 0] * r[0] + W[2, 1] * r[1] + W[2, 2] * r[2] + b[2]
    num = natural_scalars(rho * r[0], rho * r[1], rho * r[2], u0, u1, u2, mu, desaxce)
    den = np.sqrt(b[0] ** 2 + b[1] ** 2 + b[2] ** 2) + rho * np.sqrt(r[0] ** 2 + r[1] ** 2 + r[2] ** 2)
    den *= _amplification(mu, desaxce)
    if den == 0.0:
        return num
    return num / den


# --------------------------------------------------------------- Fischer-Burmeister


@jit(error_model="numpy")
def _fb_scalar(a, c):
    """Scalar FB ``a + c - sqrt(a^2 + c^2)`` without cancellation for ``a, c > 0``."""
    h = np.hypot(a, c)
    if a > 0.0 and c > 0.0:
        return 2.0 * a * c / (a + c + h)
    return a + c - h


@jit(error_model="numpy", inline="always")
def _fb_lorentz(x0, x1, x2, y0, y1, y2, phi, Jx, Jy, jac):
    """``phi(x, y)`` on the Lorentz cone ``{|x_T| <= x_0}``; with ``jac`` also ``dphi/dx``, ``dphi/dy``."""
    zb1 = 2.0 * (x0 * x1 + y0 * y1)
    zb2 = 2.0 * (x0 * x2 + y0 * y2)
    nz = np.sqrt(zb1 * zb1 + zb2 * zb2)  # scaled inputs: no overflow
    if nz > 0.0:
        e1 = zb1 / nz
        e2 = zb2 / nz
    else:
        e1 = 1.0
        e2 = 0.0
    # components along e and along e_perp = (-e2, e1)
    xe = x1 * e1 + x2 * e2
    xp = x2 * e1 - x1 * e2
    ye = y1 * e1 + y2 * e2
    yp = y2 * e1 - y1 * e2
    dx = x0 - xe
    dy = y0 - ye
    # spectral values of z = x^2 + y^2: lambda_2 = z0 + |zb|, lambda_1 = z0 - |zb| as a sum of squares
    z0 = x0 * x0 + x1 * x1 + x2 * x2 + y0 * y0 + y1 * y1 + y2 * y2
    lam1 = dx * dx + xp * xp + dy * dy + yp * yp
    s1 = np.sqrt(lam1)
    s2 = np.sqrt(z0 + nz)
    ssum = s1 + s2
    w0 = 0.5 * ssum
    wb = nz / ssum if ssum > 0.0 else 0.0  # |w_T| = (s2 - s1) / 2
    phi[0] = x0 + y0 - w0
    phi[1] = x1 + y1 - wb * e1
    phi[2] = x2 + y2 - wb * e2
    if not jac:
        return
    if s2 == 0.0:
        for i in range(3):
            for j in range(3):
                v = _FB_ZERO if i == j else 0.0
                Jx[i, j] = v
                Jy[i, j] = v
        return
    # L_w^-1 = p+ p+'/s2 + p- p-'/s1 + q q'/w0, p± = (1, ±e)/sqrt2, q = (0, e_perp)
    ip = 0.5 / s2
    im = 0.5 / s1 if s1 > 0.0 else 0.0
    iq = 1.0 / w0
    for k in range(2):
        if k == 0:
            X0, Xe, Xp, dX, J = x0, xe, xp, dx, Jx
        else:
            X0, Xe, Xp, dX, J = y0, ye, yp, dy, Jy
        # rows a+ = L_X (1, e), a- = L_X (1, -e), aq = L_X q (L_X symmetric)
        ap0 = X0 + Xe
        ap1 = Xe * e1 - Xp * e2 + X0 * e1
        ap2 = Xe * e2 + Xp * e1 + X0 * e2
        am0 = dX
        am1 = -dX * e1 - Xp * e2
        am2 = -dX * e2 + Xp * e1
        aq0 = Xp
        aq1 = -X0 * e2
        aq2 = X0 * e1
        # J = I - [ (1,e) a+ ip + (1,-e) a- im + (0,e_perp) aq iq ]
        J[0, 0] = 1.0 - (ap0 * ip + am0 * im)
        J[0, 1] = -(ap1 * ip + am1 * im)
        J[0, 2] = -(ap2 * ip + am2 * im)
        J[1, 0] = -(e1 * ap0 * ip - e1 * am0 * im - e2 * aq0 * iq)
        J[1, 1] = 1.0 - (e1 * ap1 * ip - e1 * am1 * im - e2 * aq1 * iq)
        J[1, 2] = -(e1 * ap2 * ip - e1 * am2 * im - e2 * aq2 * iq)
        J[2, 0] = -(e2 * ap0 * ip - e2 * am0 * im + e1 * aq0 * iq)
        J[2, 1] = -(e2 * ap1 * ip - e2 * am1 * im + e1 * aq1 * iq)
        J[2, 2] = 1.0 - (e2 * ap2 * ip - e2 * am2 * im + e1 * aq2 * iq)


@jit(error_model="numpy", inline="always")
def fb_coulomb(r0, r1, r2, u0, u1, u2, mu, phi, Jr, Ju, jac):
    """FB function of the Coulomb pair ``(r, u)``; with ``jac`` also ``dphi/dr`` and ``dphi/du``."""
    if mu == 0.0 or mu == np.inf:
        # mu = 0:  (fb(r_N, u_N), r_T);   mu = inf:  (fb(r_N, u_N), u_T)
        phi[0] = _fb_scalar(r0, u0)
        zero_t = mu == 0.0
        phi[1] = r1 if zero_t else u1
        phi[2] = r2 if zero_t else u2
        if jac:
            for i in range(3):
                for j in range(3):
                    Jr[i, j] = 0.0
                    Ju[i, j] = 0.0
            h = np.hypot(r0, u0)
            if h > 0.0:
                Jr[0, 0] = 1.0 - r0 / h
                Ju[0, 0] = 1.0 - u0 / h
            else:
                Jr[0, 0] = _FB_ZERO
                Ju[0, 0] = _FB_ZERO
            if zero_t:
                Jr[1, 1] = 1.0
                Jr[2, 2] = 1.0
            else:
                Ju[1, 1] = 1.0
                Ju[2, 2] = 1.0
        return
    m = max(1.0, mu)
    sxn = mu / m
    sxt = 1.0 / m
    syn = 1.0 / m
    syt = mu / m
    _fb_lorentz(sxn * r0, sxt * r1, sxt * r2, syn * u0, syt * u1, syt * u2, phi, Jr, Ju, jac)
    if jac:
        for i in range(3):
            Jr[i, 0] *= sxn
            Jr[i, 1] *= sxt
            Jr[i, 2] *= sxt
            Ju[i, 0] *= syn
            Ju[i, 1] *= syt
            Ju[i, 2] *= syt


@jit(error_model="numpy")
def fb_function(r, u, mu, out):
    """Fischer-Burmeister function of the Coulomb pair, zero iff ``K_mu ∋ r ⟂ u ∈ K*_mu``.

    Parameters
    ----------
    r : (3,) float64, force
    u : (3,) float64, ``W r + b`` (or the De Saxce ``u~``)
    mu : float64 >= 0 (``0`` and ``inf`` use the scalar FB on the normal pair
        and ``r_T``, resp. ``u_T``, on the tangent)
    out : (3,) float64, written

    Entries must stay below ~1e75 in magnitude (squares are formed unscaled).
    """
    unused = np.empty((1, 1))
    fb_coulomb(r[0], r[1], r[2], u[0], u[1], u[2], mu, out, unused, unused, False)


@jit(error_model="numpy")
def fb_jacobian(r, u, mu, phi, Jr, Ju):
    """FB function and an element of its generalized Jacobian.

    Writes ``phi`` (3,), ``Jr = dphi/dr`` (3, 3) and ``Ju = dphi/du`` (3, 3).
    """
    fb_coulomb(r[0], r[1], r[2], u[0], u[1], u[2], mu, phi, Jr, Ju, True)


# ------------------------------------------------------------------- local solve


@jit(error_model="numpy")
def _solve3(A, rhs, out):
    """Gaussian elimination with partial pivoting on a 3x3 system; False if (nearly) singular.

    ``A`` and ``rhs`` are overwritten.
    """
    scale = 0.0
    for i in range(3):
        for j in range(3):
            scale = max(scale, abs(A[i, j]))
    if not (scale > 0.0) or scale == np.inf:
        return False
    for k in range(3):
        p = k
        for i in range(k + 1, 3):
            if abs(A[i, k]) > abs(A[p, k]):
                p = i
        if not (abs(A[p, k]) > 1e-14 * scale):
            return False
        if p != k:
            for j in range(3):
                A[k, j], A[p, j] = A[p, j], A[k, j]
            rhs[k], rhs[p] = rhs[p], rhs[k]
        for i in range(k + 1, 3):
            f = A[i, k] / A[k, k]
            for j in range(k, 3):
                A[i, j] -= f * A[k, j]
            rhs[i] -= f * rhs[k]
    for k in range(2, -1, -1):
        s = rhs[k]
        for j in range(k + 1, 3):
            s -= A[k, j] * out[j]
        out[k] = s / A[k, k]
    return True


@jit(error_model="numpy", inline="always")
def _rel(W, b, bnorm, mu, desaxce, r0, r1, r2):
    """Relative residual of the scaled problem (``trace W = 3``): nat / ((|b| + |r|) amp)."""
    u0 = W[0, 0] * r0 + W[0, 1] * r1 + W[0, 2] * r2 + b[0]
    u1 = W[1, 0] * r0 + W[1, 1] * r1 + W[1, 2] * r2 + b[1]
    u2 = W[2, 0] * r0 + W[2, 1] * r1 + W[2, 2] * r2 + b[2]
    den = (bnorm + np.sqrt(r0 * r0 + r1 * r1 + r2 * r2)) * _amplification(mu, desaxce)
    return natural_scalars(r0, r1, r2, u0, u1, u2, mu, desaxce) / den


@jit(error_model="numpy", inline="always")
def _merit(W, b, mu, desaxce, r, phi, G, Jr, Ju, jac):
    """``|phi(r, u~(r))|^2 / 2``; with ``jac`` also ``G = d phi / d r`` (chain rule through u~)."""
    u0 = W[0, 0] * r[0] + W[0, 1] * r[1] + W[0, 2] * r[2] + b[0]
    u1 = W[1, 0] * r[0] + W[1, 1] * r[1] + W[1, 2] * r[2] + b[1]
    u2 = W[2, 0] * r[0] + W[2, 1] * r[1] + W[2, 2] * r[2] + b[2]
    ds = desaxce and mu > 0.0 and mu < np.inf
    nt = np.sqrt(u1 * u1 + u2 * u2)
    v0 = u0 + mu * nt if ds else u0
    fb_coulomb(r[0], r[1], r[2], v0, u1, u2, mu, phi, Jr, Ju, jac)
    if jac:
        # du~/dr = W (+ mu e_N (u_T / |u_T|)' W_T for De Saxce; 0 subgradient at u_T = 0)
        t1 = 0.0
        t2 = 0.0
        if ds and nt > 0.0:
            t1 = mu * u1 / nt
            t2 = mu * u2 / nt
        for j in range(3):
            d0 = W[0, j] + t1 * W[1, j] + t2 * W[2, j]
            for i in range(3):
                G[i, j] = Jr[i, j] + Ju[i, 0] * d0 + Ju[i, 1] * W[1, j] + Ju[i, 2] * W[2, j]
    return 0.5 * (phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2])


@jit(error_model="numpy")
def _newton(W, b, bnorm, mu, desaxce, r, tol, max_iter, best, M, V):
    """Nonsmooth Newton on ``|FB|^2 / 2`` from ``r`` with a descent check and Armijo step halving.

    ``best`` (3,) receives the iterate of smallest relative residual, which is returned.
    ``M`` (>= 5, 3, 3) and ``V`` (>= 5, 3) are scratch.
    """
    G = M[0]
    Gt = M[1]
    Jr = M[2]
    Ju = M[3]
    A = M[4]
    phi = V[0]
    phit = V[1]
    rhs = V[2]
    d = V[3]
    trial = V[4]
    best_res = _rel(W, b, bnorm, mu, desaxce, r[0], r[1], r[2])
    best[0] = r[0]
    best[1] = r[1]
    best[2] = r[2]
    if best_res <= tol:
        return best_res
    f = _merit(W, b, mu, desaxce, r, phi, G, Jr, Ju, True)
    for _ in range(max_iter):
        # gradient of the merit: G' phi
        g0 = G[0, 0] * phi[0] + G[1, 0] * phi[1] + G[2, 0] * phi[2]
        g1 = G[0, 1] * phi[0] + G[1, 1] * phi[1] + G[2, 1] * phi[2]
        g2 = G[0, 2] * phi[0] + G[1, 2] * phi[1] + G[2, 2] * phi[2]
        for i in range(3):
            rhs[i] = -phi[i]
            for j in range(3):
                A[i, j] = G[i, j]
        ok = _solve3(A, rhs, d)
        slope = g0 * d[0] + g1 * d[1] + g2 * d[2] if ok else 0.0
        if not ok or not (slope < 0.0):
            # descent check failed: steepest descent on the merit
            d[0] = -g0
            d[1] = -g1
            d[2] = -g2
            slope = -(g0 * g0 + g1 * g1 + g2 * g2)
            if not (slope < 0.0):
                break
        t = 1.0
        accepted = False
        ft = f
        for _h in range(_HALVINGS):
            trial[0] = r[0] + t * d[0]
            trial[1] = r[1] + t * d[1]
            trial[2] = r[2] + t * d[2]
            # the Jacobian comes with it: the full step is accepted nearly always
            ft = _merit(W, b, mu, desaxce, trial, phit, Gt, Jr, Ju, True)
            if ft <= f + _ARMIJO * t * slope:
                accepted = True
                break
            t *= 0.5
        if not accepted:
            break
        f = ft
        for i in range(3):
            r[i] = trial[i]
            phi[i] = phit[i]
            for j in range(3):
                G[i, j] = Gt[i, j]
        res = _rel(W, b, bnorm, mu, desaxce, r[0], r[1], r[2])
        if res < best_res:
            best_res = res
            best[0] = r[0]
            best[1] = r[1]
            best[2] = r[2]
        if res <= tol or f == 0.0:
            break
    return best_res


@jit(error_model="numpy")
def _cross_dot(a0, a1, a2, c0, c1, c2, b0, b1, b2):
    """``b . (a x c)``, the determinant ``[a, c, b]``."""
    return b0 * (a1 * c2 - a2 * c1) + b1 * (a2 * c0 - a0 * c2) + b2 * (a0 * c1 - a1 * c0)


# sample angles of the fail-safe's root bracketing (between them g is sampled, not assumed)
_NS = 32
_SAMPLE_A = 2.0 * np.pi * np.arange(_NS + 1) / _NS
_SAMPLE_COS = np.cos(_SAMPLE_A)
_SAMPLE_SIN = np.sin(_SAMPLE_A)


@jit(error_model="numpy")
def _trig(c, s, which, A0, A1, B1, A2, B2):
    """``(f, f')`` at angle ``(cos a, sin a)`` for ``f = g`` (which 0) or ``f = g'`` (which 1).

    ``g(a) = A0 + A1 cos a + B1 sin a + A2 cos 2a + B2 sin 2a``.
    """
    c2 = c * c - s * s
    s2 = 2.0 * s * c
    g1 = -A1 * s + B1 * c - 2.0 * A2 * s2 + 2.0 * B2 * c2
    if which == 0:
        return A0 + A1 * c + B1 * s + A2 * c2 + B2 * s2, g1
    return g1, -A1 * c - B1 * s - 4.0 * A2 * c2 - 4.0 * B2 * s2


@jit(error_model="numpy")
def _bracketed_root(lo, hi, flo, which, A0, A1, B1, A2, B2):
    """Root of ``f`` (``g`` or ``g'``) in ``[lo, hi]`` where it changes sign: Newton kept in the bracket."""
    a = 0.5 * (lo + hi)
    for _ in range(100):
        f, df = _trig(np.cos(a), np.sin(a), which, A0, A1, B1, A2, B2)
        if f == 0.0:
            return a
        if (f > 0.0) == (flo > 0.0):
            lo = a
            flo = f
        else:
            hi = a
        an = a - f / df
        if not (lo < an < hi):  # also NaN (df = 0)
            an = 0.5 * (lo + hi)
        if abs(an - a) <= 4e-16 * max(1.0, abs(a)) or hi - lo <= 4e-16 * max(1.0, abs(a)):
            return an
        a = an
    return a


@jit(error_model="numpy")
def _slide_angles(A0, A1, B1, A2, B2, angles):
    """Every root of ``g`` (and every critical point of ``g``, for double roots) in ``[0, 2 pi)``.

    ``g`` is sampled at ``_NS`` angles; a sign change of ``g'`` in an interval is refined to the
    critical point ``c``, which splits the interval into two on which ``g`` is monotone, so each
    sign change of ``g`` holds exactly one root, found by bracketed Newton. Returns the count.
    """
    n = 0
    cap = angles.shape[0]
    g_prev, d_prev = _trig(_SAMPLE_COS[0], _SAMPLE_SIN[0], 0, A0, A1, B1, A2, B2)
    for k in range(_NS):
        lo = _SAMPLE_A[k]
        hi = _SAMPLE_A[k + 1]
        g_next, d_next = _trig(_SAMPLE_COS[k + 1], _SAMPLE_SIN[k + 1], 0, A0, A1, B1, A2, B2)
        if g_prev == 0.0 and n < cap:
            angles[n] = lo
            n += 1
        if (d_prev > 0.0) != (d_next > 0.0) and d_prev != 0.0 and d_next != 0.0:
            c = _bracketed_root(lo, hi, d_prev, 1, A0, A1, B1, A2, B2)
            gc, _ = _trig(np.cos(c), np.sin(c), 0, A0, A1, B1, A2, B2)
            if n < cap:
                angles[n] = c  # a double root if gc ~ 0
                n += 1
            if (g_prev > 0.0) != (gc > 0.0) and g_prev != 0.0 and gc != 0.0 and n < cap:
                angles[n] = _bracketed_root(lo, c, g_prev, 0, A0, A1, B1, A2, B2)
                n += 1
            if (gc > 0.0) != (g_next > 0.0) and gc != 0.0 and g_next != 0.0 and n < cap:
                angles[n] = _bracketed_root(c, hi, gc, 0, A0, A1, B1, A2, B2)
                n += 1
        elif (g_prev > 0.0) != (g_next > 0.0) and g_prev != 0.0 and g_next != 0.0 and n < cap:
            angles[n] = _bracketed_root(lo, hi, g_prev, 0, A0, A1, B1, A2, B2)
            n += 1
        g_prev = g_next
        d_prev = d_next
    return n


@jit(error_model="numpy", inline="always")
def _slide_setup(W, b, mu, desaxce):
    """The sliding equation's terms (see :func:`_slide_failsafe`), as one tuple.

    ``W v(a) = P0 + P1 cos a + P2 sin a`` (``p00..p22``), ``w(a) = (q0, qt cos a, qt sin a)``,
    ``g(a) = A0 + A1 cos a + B1 sin a + A2 cos 2a + B2 sin 2a``; then ``cn``, ``ct``.
    """
    h = np.hypot(1.0, mu)
    cn = 1.0 / h
    ct = mu / h
    p00 = cn * W[0, 0]
    p01 = cn * W[1, 0]
    p02 = cn * W[2, 0]
    p10 = ct * W[0, 1]
    p11 = ct * W[1, 1]
    p12 = ct * W[2, 1]
    p20 = ct * W[0, 2]
    p21 = ct * W[1, 2]
    p22 = ct * W[2, 2]
    if desaxce:
        q0 = 0.0
        qt = -1.0
    else:
        q0 = ct
        qt = -cn
    b0 = b[0]
    b1 = b[1]
    b2 = b[2]
    # m_ij = det[P_i, Q_j, b] with Q0 = (q0, 0, 0), Q1 = (0, qt, 0), Q2 = (0, 0, qt)
    m00 = _cross_dot(p00, p01, p02, q0, 0.0, 0.0, b0, b1, b2)
    m10 = _cross_dot(p10, p11, p12, q0, 0.0, 0.0, b0, b1, b2)
    m20 = _cross_dot(p20, p21, p22, q0, 0.0, 0.0, b0, b1, b2)
    m01 = _cross_dot(p00, p01, p02, 0.0, qt, 0.0, b0, b1, b2)
    m11 = _cross_dot(p10, p11, p12, 0.0, qt, 0.0, b0, b1, b2)
    m21 = _cross_dot(p20, p21, p22, 0.0, qt, 0.0, b0, b1, b2)
    m02 = _cross_dot(p00, p01, p02, 0.0, 0.0, qt, b0, b1, b2)
    m12 = _cross_dot(p10, p11, p12, 0.0, 0.0, qt, b0, b1, b2)
    m22 = _cross_dot(p20, p21, p22, 0.0, 0.0, qt, b0, b1, b2)
    return (m00 + 0.5 * (m11 + m22), m01 + m10, m02 + m20, 0.5 * (m11 - m22), 0.5 * (m12 + m21),
            p00, p01, p02, p10, p11, p12, p20, p21, p22, q0, qt, cn, ct)


@jit(error_model="numpy", inline="always")
def _slide_point(t, b, c, s):
    """``(rho, r0, r1, r2)``: the force on the boundary ray of slip direction ``(c, s) = (cos a, sin a)``
    that solves the sliding equations if ``g(a) = 0`` (``t`` from :func:`_slide_setup`); ``rho <= 0``
    or NaN: none there."""
    p00, p01, p02, p10, p11, p12, p20, p21, p22, q0, qt, cn, ct = t[5:]
    wv0 = p00 + p10 * c + p20 * s
    wv1 = p01 + p11 * c + p21 * s
    wv2 = p02 + p12 * c + p22 * s
    w1 = qt * c
    w2 = qt * s
    # -b = rho Wv - beta w  =>  -b x w = rho (Wv x w)
    n0 = wv1 * w2 - wv2 * w1
    n1 = wv2 * q0 - wv0 * w2
    n2 = wv0 * w1 - wv1 * q0
    nn = n0 * n0 + n1 * n1 + n2 * n2
    bw0 = b[1] * w2 - b[2] * w1
    bw1 = b[2] * q0 - b[0] * w2
    bw2 = b[0] * w1 - b[1] * q0
    rho = -(bw0 * n0 + bw1 * n1 + bw2 * n2) / nn if nn > 0.0 else np.nan
    return rho, rho * cn, rho * ct * c, rho * ct * s


@jit(error_model="numpy")
def _slide_newton(W, b, bnorm, mu, desaxce, c, s, out):
    """The sliding solution nearest the slip direction ``(c, s)`` (a unit vector): Newton on
    ``g(a) = 0`` (a handful of scalar steps from a warm start's direction), its force written to
    ``out``; returns its relative residual (inf if the root gives none). Only a candidate: the
    caller keeps it if it meets the tolerance, which makes it the solution (convex: the only one).

    Each step turns the direction by a rotation, its cos and sin from their Taylor series once the
    step is under 1e-2 rad (to 1.4e-15; to round-off under 1e-8 rad). The iteration ends after a step
    under 1e-8 rad: convergence is quadratic, so the angle is then exact to about 1e-16 (near a
    double root it is not, and the caller's residual check sends it to the FB Newton). Without the
    trigonometric calls and the final confirming step, one pass of local solves over ruby short's
    moving contacts (24,511, 56 % sliding) takes 7.9 ms instead of 9.3 ms, with the same residuals."""
    t = _slide_setup(W, b, mu, desaxce)
    A0, A1, B1, A2, B2 = t[0], t[1], t[2], t[3], t[4]
    for _ in range(12):
        g, dg = _trig(c, s, 0, A0, A1, B1, A2, B2)
        if not (dg != 0.0):
            return np.inf
        step = g / dg  # the angle a becomes a - step
        if abs(step) < 1e-2:
            d2 = step * step
            cd = 1.0 - d2 * (0.5 - d2 * (1.0 / 24.0))
            sd = step * (1.0 - d2 * ((1.0 / 6.0) - d2 * (1.0 / 120.0)))
        else:
            cd = np.cos(step)
            sd = np.sin(step)
        c, s = c * cd + s * sd, s * cd - c * sd
        if abs(step) <= 1e-8:
            break
    norm = np.sqrt(c * c + s * s)
    rho, r0, r1, r2 = _slide_point(t, b, c / norm, s / norm)
    if not (rho > 0.0):
        return np.inf
    out[0] = r0
    out[1] = r1
    out[2] = r2
    return _rel(W, b, bnorm, mu, desaxce, r0, r1, r2)


@jit(error_model="numpy")
def _slide_failsafe(W, b, bnorm, mu, desaxce, best):
    """Sliding solutions on the boundary ray ``r = rho v(a)``, ``v = (cN, cT cos a, cT sin a)``.

    Sliding means ``W rho v(a) + b = beta w(a)`` with ``rho > 0``, ``beta >= 0`` and
    ``w = (cT, -cN cos a, -cN sin a)`` (statics: the dual-cone generator orthogonal to
    ``v``) or ``w = (0, -cos a, -sin a)`` (De Saxce: ``u_N = 0``, ``u_T`` against ``r_T``).
    Then ``-b`` is in the span of ``W v(a)`` and ``w(a)``: ``g(a) = det[W v, w, b] = 0``,
    a trigonometric polynomial of degree 2 (the quartic of Daviet et al. in
    ``tan(a/2)``), whose real roots are bracketed and refined by ``_slide_angles``. The
    candidate of smallest residual is written to ``best`` and its relative residual
    returned (inf if there is none).
    """
    t = _slide_setup(W, b, mu, desaxce)
    A0, A1, B1, A2, B2 = t[0], t[1], t[2], t[3], t[4]
    angles = np.empty(16)
    n = _slide_angles(A0, A1, B1, A2, B2, angles)
    # g may vanish identically (b with a symmetry): then try a few fixed angles
    n_fixed = 8
    if n == 0 or abs(A0) + abs(A1) + abs(B1) + abs(A2) + abs(B2) == 0.0:
        for k in range(n_fixed):
            if n < angles.shape[0]:
                angles[n] = 2.0 * np.pi * k / n_fixed
                n += 1
    best_res = np.inf
    for k in range(n):
        rho, r0, r1, r2 = _slide_point(t, b, np.cos(angles[k]), np.sin(angles[k]))
        if not (rho > 0.0):
            continue
        res = _rel(W, b, bnorm, mu, desaxce, r0, r1, r2)
        if res < best_res:
            best_res = res
            best[0] = r0
            best[1] = r1
            best[2] = r2
    return best_res


#: Newton steps of a sliding contact's local solve before its closed form is tried
_FIRST_NEWTON = 8


@jit(error_model="numpy", inline="always")
def _cholesky3(W, rho, shift):
    """Cholesky factor of ``W / rho + shift I`` (lower triangle of W): ``(ok, l00, l10, l20, l11, l21, l22)``,
    ``ok`` False where a pivot is not positive."""
    l00 = W[0, 0] / rho + shift
    if not (l00 > 0.0):
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    l00 = np.sqrt(l00)
    l10 = W[1, 0] / rho / l00
    l20 = W[2, 0] / rho / l00
    l11 = W[1, 1] / rho + shift - l10 * l10
    if not (l11 > 0.0):
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    l11 = np.sqrt(l11)
    l21 = (W[2, 1] / rho - l20 * l10) / l11
    l22 = W[2, 2] / rho + shift - l20 * l20 - l21 * l21
    if not (l22 > 0.0):
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    return True, l00, l10, l20, l11, l21, np.sqrt(l22)


@jit(error_model="numpy")
def _scaled_lower(W, rho):
    """``W / rho`` made symmetric from its lower triangle (what the Cholesky reads)."""
    out = np.empty((3, 3))
    for i in range(3):
        for j in range(i + 1):
            out[i, j] = W[i, j] / rho
            out[j, i] = out[i, j]
    return out


@jit(error_model="numpy")
def solve_contact(W, b, mu, r, tol, max_iter, desaxce):
    """Solve one contact's cone complementarity problem ``K_mu ∋ r ⟂ W r + b ∈ K*_mu``.

    Steps (Daviet et al. 2011, appendix A; So-bogus ``SOCLaw``): take-off (``b`` in the
    dual cone: ``r = 0``); ``mu = 0`` (``r_N = max(0, -b_N / W_NN)``); ``mu = inf``
    (the half-space, two closed-form candidates); the sticking candidate
    ``-W^-1 b`` if it lies in ``K_mu``; else the warm start's slip angle refined on the
    sliding equation, kept if it meets the tolerance (the sliding solution nearest the
    contact's last force); else the same from the better of the warm start and
    ``P_K(-W^-1 b)``; then up to ``_FIRST_NEWTON`` steps of a nonsmooth Newton on
    ``|FB|^2 / 2`` from that start, then the sliding fail-safe (roots of a quartic in the
    slip angle), then the rest of the ``max_iter`` Newton steps from the best point so far,
    keeping the best point of all. Works internally on ``W / rho``, ``b / max|b|``
    (``rho = trace W / 3``).

    Parameters
    ----------
    W : (3, 3) float64, symmetric positive definite (symmetry is not checked: the
        Cholesky reads the lower triangle, products use all of W). Positive semidefinite to
        working precision is accepted (a smallest eigenvalue of ``W / rho`` above -1e-10, as
        when a regularisation below the round-off of the rest is lost in the sum): the
        problem is then solved with that eigenvalue raised to 64 eps of ``rho``, and the
        residual returned is that problem's (it differs from W's by at most 64 eps)
    b : (3,) float64
    mu : float64 >= 0, ``inf`` allowed
    r : (3,) float64, in: warm start (ignored if not finite); out: the solution
        (left untouched on ``CODE_NUMERICAL``, and bit for bit when the warm start
        already meets the tolerance)
    tol : float64, on the relative residual (see ``relative_residual``); ``LOCAL_TOL``
        (eps^(3/4)) is the intended value
    max_iter : int, Newton iterations
    desaxce : bool, solve for the De Saxce velocity ``u~ = u + mu |u_T| e_N`` (dynamics)

    Returns
    -------
    status : int, ``CODE_OK``, ``CODE_NOT_CONVERGED`` (r is the best point found) or ``CODE_NUMERICAL``
    residual : float64, the relative residual of the returned ``r`` (inf on error)
    """
    return solve_contact_with(W, b, mu, r, tol, max_iter, desaxce, np.empty((6, 3, 3)), np.empty((8, 3)))


@jit(error_model="numpy")
def solve_contact_with(W, b, mu, r, tol, max_iter, desaxce, M, V):
    """:func:`solve_contact` with its scratch given, ``M`` (6, 3, 3) and ``V`` (8, 3) float64 (contents
    ignored), for a caller that solves contact after contact: two allocations fewer per contact."""
    # ---- validate
    for i in range(3):
        if not np.isfinite(b[i]):
            return CODE_NUMERICAL, np.inf
        for j in range(3):
            if not np.isfinite(W[i, j]):
                return CODE_NUMERICAL, np.inf
    if not (mu >= 0.0):  # also NaN
        return CODE_NUMERICAL, np.inf
    if not (W[0, 0] > 0.0 and W[1, 1] > 0.0 and W[2, 2] > 0.0):
        return CODE_NUMERICAL, np.inf
    rho = (W[0, 0] + W[1, 1] + W[2, 2]) / 3.0
    if rho == np.inf:
        return CODE_NUMERICAL, np.inf
    # ---- scaled problem: Wh = W / rho, bh = b / sb, rh = r rho / sb
    sb = max(abs(b[0]), max(abs(b[1]), abs(b[2])))
    ds = desaxce and mu < np.inf
    # Cholesky of W / rho = L L' (the positive-definiteness check, before anything else)
    shift = 0.0
    ok, l00, l10, l20, l11, l21, l22 = _cholesky3(W, rho, shift)
    if not ok:
        # semidefinite to working precision (W = H D H^T + gamma I with gamma under the round-off of
        # H D H^T: a soft rod's 1e20 against 1e-3): solved with the smallest eigenvalue of W / rho
        # raised to _SHIFT; a W indefinite beyond round-off is an error
        lam = np.linalg.eigvalsh(_scaled_lower(W, rho))[0]
        if not (lam >= -_SEMIDEFINITE):
            return CODE_NUMERICAL, np.inf
        shift = _SHIFT - lam
        ok, l00, l10, l20, l11, l21, l22 = _cholesky3(W, rho, shift)
        if not ok:
            return CODE_NUMERICAL, np.inf
    # take-off: b in the dual cone (De Saxce: b~ in K* iff b_N >= 0; mu = inf: the ray b_T = 0)
    bt = np.hypot(b[1], b[2])
    if mu == np.inf:
        takeoff = b[0] >= 0.0 and bt == 0.0
    elif ds or mu == 0.0:
        takeoff = b[0] >= 0.0
    else:
        takeoff = mu * bt <= b[0]
    if sb == 0.0 or takeoff:
        r[0] = 0.0
        r[1] = 0.0
        r[2] = 0.0
        return CODE_OK, 0.0
    # scratch: M[0:5], V[0:5] for Newton; Wh = M[5]; bh, rh, best = V[5], V[6], V[7]
    Wh = M[5]
    for i in range(3):
        for j in range(3):
            Wh[i, j] = W[i, j] / rho
        Wh[i, i] += shift
    bh = V[5]
    for i in range(3):
        bh[i] = b[i] / sb
    bnorm = np.sqrt(bh[0] ** 2 + bh[1] ** 2 + bh[2] ** 2)
    back = sb / rho  # r = back * rh
    if mu == 0.0:
        rn = -bh[0] / Wh[0, 0]
        r[0] = back * rn if rn > 0.0 else 0.0
        r[1] = 0.0
        r[2] = 0.0
        return CODE_OK, _rel(Wh, bh, bnorm, mu, desaxce, max(rn, 0.0), 0.0, 0.0)
    # sticking candidate -Wh^-1 bh
    y0 = -bh[0] / l00
    y1 = (-bh[1] - l10 * y0) / l11
    y2 = (-bh[2] - l20 * y0 - l21 * y1) / l22
    s2 = y2 / l22
    s1 = (y1 - l21 * s2) / l11
    s0 = (y0 - l10 * s1 - l20 * s2) / l00
    if mu == np.inf:
        # half-space: u = 0 if s_N >= 0, else r_N = 0 and W_TT r_T = -b_T
        if s0 < 0.0:
            det = Wh[1, 1] * Wh[2, 2] - Wh[1, 2] * Wh[2, 1]
            s0 = 0.0
            s1 = (-bh[1] * Wh[2, 2] + bh[2] * Wh[1, 2]) / det
            s2 = (-bh[2] * Wh[1, 1] + bh[1] * Wh[2, 1]) / det
        r[0] = back * s0
        r[1] = back * s1
        r[2] = back * s2
        return CODE_OK, _rel(Wh, bh, bnorm, mu, desaxce, s0, s1, s2)
    if s0 >= 0.0 and np.hypot(s1, s2) <= mu * s0:
        r[0] = back * s0
        r[1] = back * s1
        r[2] = back * s2
        return CODE_OK, _rel(Wh, bh, bnorm, mu, desaxce, s0, s1, s2)
    # ---- sliding
    rh = V[6]
    best = V[7]
    res = np.inf
    warm = np.isfinite(r[0]) and np.isfinite(r[1]) and np.isfinite(r[2])
    w0 = w1 = w2 = res_w = 0.0
    tried = False  # the slip direction of the warm start refined on the sliding equation
    if warm:
        w0 = r[0] / back
        w1 = r[1] / back
        w2 = r[2] / back
        res_w = _rel(Wh, bh, bnorm, mu, desaxce, w0, w1, w2)
        if res_w <= tol:
            return CODE_OK, res_w  # r untouched
        # first the warm start's own slip angle, refined on the sliding equation: from a Gauss-Seidel
        # sweep's last force a few scalar Newton steps nearly always meet the tolerance, and the sliding
        # solution found is the one nearest the contact's last
        slip = np.hypot(w1, w2)
        if slip > 0.0:
            tried = True
            res = _slide_newton(Wh, bh, bnorm, mu, desaxce, w1 / slip, w2 / slip, best)
    if not (res <= tol):
        # then from the better of the warm start and P_K(stick)
        p0, p1, p2 = project_scalars(s0, s1, s2, mu)
        res_p = _rel(Wh, bh, bnorm, mu, desaxce, p0, p1, p2)
        if warm and res_w <= res_p:
            rh[0] = w0
            rh[1] = w1
            rh[2] = w2
        else:
            rh[0] = p0
            rh[1] = p1
            rh[2] = p2
            tried = False
        if not tried:
            slip = np.hypot(rh[1], rh[2])
            if slip > 0.0:
                d1, d2, dn = rh[1], rh[2], slip
            else:
                d1, d2, dn = -bh[1], -bh[2], np.hypot(bh[1], bh[2])
            if dn > 0.0:
                res = _slide_newton(Wh, bh, bnorm, mu, desaxce, d1 / dn, d2 / dn, best)
    if not (res <= tol):
        # nonsmooth Newton from the start, a few steps at first: where W is well conditioned it converges
        # in about five; on an ill-conditioned one (condition 1e6-1e9, a contact near a root beside one
        # along the strand) it creeps, and every step it takes there is slower than the closed form below
        # (on ruby short's moving groom 260 of 25,000 contacts spent 40 % of a sweep's local solves in
        # 50 steps each; with the closed form after eight, a sweep from the step's warm start took 19 ms
        # instead of 30-39, and 10 ms instead of 11 after 20 sweeps)
        nb = np.empty(3)
        res_n = _newton(Wh, bh, bnorm, mu, desaxce, rh, tol, min(max_iter, _FIRST_NEWTON), nb, M, V)
        if res_n < res:
            res = res_n
            best[0] = nb[0]
            best[1] = nb[1]
            best[2] = nb[2]
        if not (res <= tol):
            # the sliding case in closed form: every root of the sliding equation
            fs = np.empty(3)
            res_fs = _slide_failsafe(Wh, bh, bnorm, mu, desaxce, fs)
            if res_fs < res:
                res = res_fs
                best[0] = fs[0]
                best[1] = fs[1]
                best[2] = fs[2]
        if not (res <= tol) and res < np.inf:
            # and the Newton steps left, from the best point so far
            rh[0] = best[0]
            rh[1] = best[1]
            rh[2] = best[2]
            res_n = _newton(Wh, bh, bnorm, mu, desaxce, rh, tol, max_iter, nb, M, V)
            if res_n < res:
                res = res_n
                best[0] = nb[0]
                best[1] = nb[1]
                best[2] = nb[2]
    if not (res < np.inf):
        return CODE_NOT_CONVERGED, res
    r[0] = back * best[0]
    r[1] = back * best[1]
    r[2] = back * best[2]
    return (CODE_OK if res <= tol else CODE_NOT_CONVERGED), res
