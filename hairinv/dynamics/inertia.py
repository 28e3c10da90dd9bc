"""Inertia of super-helices: mass matrix, node Jacobians and velocity-product terms.

A strand's kinetic energy is the centerline's translational energy plus the
rotational energy of its cross-sections,

    K = 1/2 lam int |x_dot|^2 ds
      + 1/2 rho int (I (W.n1)^2 + I (W.n2)^2 + 2 I (W.t)^2) ds,

with ``lam = rho pi r^2`` (kg/m), ``I = pi r^4 / 4`` and ``W`` the world
angular velocity of the material frame ``(t, n1, n2)``. With ``rot = rho I``
(kg m) the rotational density is ``rot (|W|^2 + (W.t)^2)``. Both integrals
are taken by Gauss-Legendre quadrature, ``order`` nodes per element: node
``e * order + j`` sits at ``sigma = gx[j] length[e]`` in element ``e`` and
carries the weight ``gw[j] length[e]`` (m). At every node

    x_dot = J q_dot,    W = T q_dot,

where ``q = omega.ravel()`` (column ``3 e + k`` is ``omega[e, k]``), ``J``
(3 x 3N, m^2) and ``T`` (3 x 3N, m) built like
:func:`hairinv.rod.statics.point_jacobian`: an element upstream of the node
moves it rigidly about that element's end (``J = dx_end + dth x r``, ``T =
dth_end``), its own element moves it by the derivatives at ``sigma``, and
elements downstream do not move it. Then

    M = sum_nodes w (lam J^T J + rot T^T (1 + t t^T) T)      (kg m^4)

is exactly the Hessian of the quadrature of ``K``, and the equations of motion
``d/dt dK/dq_dot - dK/dq = f`` read ``M q_ddot = f + b`` with the
velocity-product (Coriolis, centripetal, gyroscopic) force

    b = -sum_nodes w (lam J^T a0 + T^T (I_w al0 + W x I_w W)),   I_w = rot (1 + t t^T),

where ``a0`` and ``al0`` are the node's linear and angular accelerations at
``q_ddot = 0`` (the "J-dot q_dot" terms), closed form too
(:func:`node_bias_accelerations`: the upstream elements' twists turning with
their frames, and each element's own second derivative along ``q_dot`` by a
complex step of its closed-form rates); everything is exact to round-off.
Generalized forces are in J m (work per unit curvature), like
:func:`hairinv.rod.statics.gravity_forces`, whose ``(N, 3)`` layout is the
``(3N,)`` vectors here reshaped.

Two evaluations of the same sums:

- from the node Jacobians (:func:`strand_nodes`, :func:`mass_from_nodes`,
  :func:`node_forces_to_generalized`): the definitions, O(N^2 m) storage
  and O(N^3 m) work for ``M``;
- as a composite rigid body (:func:`strand_mass`, :func:`strand_node_loads`,
  :func:`strand_bias_forces`, :func:`strand_velocity_forces`, which adds a
  moving frame's forces): an upstream element ``a`` moves every later
  node by the rigid twist ``x_dot = E_a + Th_a x`` (``Th_a = dth_end``,
  ``E_a = dx_end - Th_a x x_{a+1}``, positions relative to the root), so
  the nodes after element ``b`` act through their spatial inertia
  (``sum w``, ``sum w x``, ``sum w x x^T``, ``sum w I_w``, suffix sums) and
  their loads through one resultant force and moment. ``M`` then costs
  O(N^2 + N m) and a generalized force O(N m), like ``gravity_forces``.

Quadrature accuracy: ``M`` is the exact Hessian of the *quadrature* of
``K``, so it is symmetric, positive semi-definite and consistent with ``b``
at any order; against the exact integral its error ``||M_m - M|| / ||M||``
depends on the largest element angle ``theta = |omega_e| length_e`` (measured
over random strands of 1-7 elements):

    theta (rad)    0.5      1.0      1.5      2.0      3.0
    4 nodes        1e-7     1e-6     7e-6     2e-5     1e-4
    6 nodes        3e-14    7e-12    2e-10    2e-9     6e-8

Relative to ``v^T M v`` itself the error can be larger along the weak twist
directions (whose energy is ~1e-6 of the bending ones).
"""

from __future__ import annotations

import functools

import numpy as np

from .._jit import jit
from ..rod.helix import _advance, _element_rate, chain, element_derivatives, helix_coefficients_and_derivatives

__all__ = [
    "gauss_nodes",
    "strand_nodes",
    "mass_from_nodes",
    "strand_mass",
    "node_forces_to_generalized",
    "node_torques_to_generalized",
    "strand_node_loads",
    "node_bias_accelerations",
    "strand_bias_forces",
    "inertia_terms",
]



def gauss_nodes(order: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre nodes and weights on ``[0, 1]``.

    Parameters
    ----------
    order : int
        Nodes per element; exact for polynomials of degree ``2 order - 1``.

    Returns
    -------
    gx, gw : (order,) float64
        Node positions (fraction of the element) and weights, ``sum gw = 1``.
    """
    gx, gw = _gauss_nodes(int(order))
    return gx.copy(), gw.copy()


@functools.lru_cache(maxsize=None)
def _gauss_nodes(order):
    # leggauss costs ~0.1 ms (an eigenvalue problem): computed once per order
    if order < 1:
        raise ValueError(f"quadrature order must be at least 1, got {order}")
    x, w = np.polynomial.legendre.leggauss(order)
    return 0.5 * (x + 1.0), 0.5 * w


@jit
def strand_nodes(root, frame0, omega, length, gx, gw, x_out, F_out, w_out, J_out, T_out):
    """Quadrature nodes of one strand with their Jacobians.

    Parameters
    ----------
    root : (3,) float64, m
    frame0 : (3, 3) float64, rows (t, n1, n2)
    omega : (N, 3) float64, (kappa1, kappa2, tau), 1/m
    length : (N,) float64, m
    gx, gw : (m,) float64
        Nodes and weights on ``[0, 1]`` (:func:`gauss_nodes`).
    x_out : (N m, 3) float64, out
        Node positions, m. Node ``e m + j`` is at ``gx[j] length[e]`` in element ``e``.
    F_out : (N m, 3, 3) float64, out
        Material frames at the nodes (rows t, n1, n2).
    w_out : (N m,) float64, out
        Quadrature weights ``gw[j] length[e]``, m.
    J_out : (N m, 3, 3N) float64, out
        ``J_out[n, :, 3 e + k]`` is d x_n / d omega[e, k] in world coordinates, m^2;
        zero for the elements after the node's.
    T_out : (N m, 3, 3N) float64, out
        ``T_out[n, :, 3 e + k]`` is the world rotation vector of the node's
        frame per unit omega[e, k], m; zero for the elements after the node's.
    """
    n = omega.shape[0]
    m = gx.shape[0]
    xs = np.empty((n + 1, 3))
    Fs = np.empty((n + 1, 3, 3))
    chain(root, frame0, omega, length, xs, Fs)
    # whole-element derivatives: what every node downstream of e sees
    Dx = np.empty((n, 3, 3))
    Dth = np.empty((n, 3, 3))
    for e in range(n):
        element_derivatives(omega[e], length[e], Fs[e], Dx[e], Dth[e])
    R = np.empty((3, 3))
    P = np.empty(3)
    Q = np.empty(3)
    dx = np.empty((3, 3))
    dth = np.empty((3, 3))
    J_out[:, :, :] = 0.0
    T_out[:, :, :] = 0.0
    for e in range(n):
        for j in range(m):
            node = e * m + j
            sigma = gx[j] * length[e]
            w_out[node] = gw[j] * length[e]
            _advance(xs[e], Fs[e], omega[e], sigma, x_out[node], F_out[node], R, P, Q)
            for a in range(e):
                r0 = x_out[node, 0] - xs[a + 1, 0]
                r1 = x_out[node, 1] - xs[a + 1, 1]
                r2 = x_out[node, 2] - xs[a + 1, 2]
                for k in range(3):
                    c = 3 * a + k
                    J_out[node, 0, c] = Dx[a, k, 0] + Dth[a, k, 1] * r2 - Dth[a, k, 2] * r1
                    J_out[node, 1, c] = Dx[a, k, 1] + Dth[a, k, 2] * r0 - Dth[a, k, 0] * r2
                    J_out[node, 2, c] = Dx[a, k, 2] + Dth[a, k, 0] * r1 - Dth[a, k, 1] * r0
                    for i in range(3):
                        T_out[node, i, c] = Dth[a, k, i]
            element_derivatives(omega[e], sigma, Fs[e], dx, dth)
            for k in range(3):
                for i in range(3):
                    J_out[node, i, 3 * e + k] = dx[k, i]
                    T_out[node, i, 3 * e + k] = dth[k, i]


@jit
def mass_from_nodes(F, w, J, T, lam, rot, out):
    """Mass matrix ``sum_n w_n (lam J_n^T J_n + rot T_n^T (1 + t_n t_n^T) T_n)``.

    The definition, for node data at hand; :func:`strand_mass` gives the same
    matrix in O(N^2) instead of O(N^3 m).

    Parameters
    ----------
    F, w, J, T : node frames, weights and Jacobians of :func:`strand_nodes`
        (node ``n`` belongs to element ``n // m``, whose columns end at ``3 (e + 1)``).
    lam : float64
        Linear density ``rho pi r^2``, kg/m.
    rot : float64
        Cross-section rotational density ``rho pi r^4 / 4``, kg m; may be 0.
    out : (3N, 3N) float64, out
        Symmetric mass matrix, kg m^4.
    """
    nodes = J.shape[0]
    ncols = J.shape[2]
    m = nodes // (ncols // 3)
    tT = np.empty(ncols)
    out[:, :] = 0.0
    for node in range(nodes):
        end = 3 * (node // m + 1)
        wl = w[node] * lam
        wr = w[node] * rot
        for i in range(end):
            tT[i] = F[node, 0, 0] * T[node, 0, i] + F[node, 0, 1] * T[node, 1, i] + F[node, 0, 2] * T[node, 2, i]
        for i in range(end):
            a0 = wl * J[node, 0, i]
            a1 = wl * J[node, 1, i]
            a2 = wl * J[node, 2, i]
            b0 = wr * T[node, 0, i]
            b1 = wr * T[node, 1, i]
            b2 = wr * T[node, 2, i]
            bt = wr * tT[i]
            for j in range(i, end):
                out[i, j] += (a0 * J[node, 0, j] + a1 * J[node, 1, j] + a2 * J[node, 2, j]
                              + b0 * T[node, 0, j] + b1 * T[node, 1, j] + b2 * T[node, 2, j] + bt * tT[j])
    for i in range(ncols):
        for j in range(i):
            out[i, j] = out[j, i]


@jit
def node_forces_to_generalized(J, f, out):
    """Generalized force ``sum_n J_n^T f_n`` of point forces at the nodes.

    Parameters
    ----------
    J : (nodes, 3, 3N) float64, m^2 (:func:`strand_nodes`)
    f : (nodes, 3) float64
        World force at each node, N (already multiplied by the weight and any
        density the caller wants: a field ``g`` gives ``f_n = lam w_n g``).
    out : (3N,) float64, out
        J m; ``out.reshape(N, 3)`` has the layout of ``omega``.

    See :func:`strand_node_loads` for the same sum in O(N m) without ``J``.
    """
    out[:] = 0.0
    for node in range(J.shape[0]):
        for c in range(J.shape[2]):
            out[c] += J[node, 0, c] * f[node, 0] + J[node, 1, c] * f[node, 1] + J[node, 2, c] * f[node, 2]


@jit
def node_torques_to_generalized(T, torque, out):
    """Generalized force ``sum_n T_n^T torque_n`` of point torques at the nodes.

    Parameters
    ----------
    T : (nodes, 3, 3N) float64, m (:func:`strand_nodes`)
    torque : (nodes, 3) float64, world torques, N m
    out : (3N,) float64, out, J m
    """
    out[:] = 0.0
    for node in range(T.shape[0]):
        for c in range(T.shape[2]):
            out[c] += T[node, 0, c] * torque[node, 0] + T[node, 1, c] * torque[node, 1] + T[node, 2, c] * torque[node, 2]


@jit
def _kinematics(frame0, omega, length, gx, xs, Fs, Th, E, x, F, dX, dTh):
    """Chain, element twists and node data of one strand, positions relative to the root.

    ``Th[e, k]`` and ``E[e, k]``: the rigid twist of everything after element
    ``e`` per unit ``omega[e, k]`` (a point ``x`` moves by ``E + Th x x``).
    ``x``, ``F``: node positions and frames; ``dX``, ``dTh``: the node's
    derivatives w.r.t. its own element's omega (rows k).
    """
    n = omega.shape[0]
    m = gx.shape[0]
    R = np.empty((3, 3))
    P = np.empty(3)
    Q = np.empty(3)
    chain(np.zeros(3), frame0, omega, length, xs, Fs)
    for e in range(n):
        element_derivatives(omega[e], length[e], Fs[e], E[e], Th[e])
        p0 = xs[e + 1, 0]
        p1 = xs[e + 1, 1]
        p2 = xs[e + 1, 2]
        for k in range(3):
            # E = dx_end - Th x p_end
            E[e, k, 0] -= Th[e, k, 1] * p2 - Th[e, k, 2] * p1
            E[e, k, 1] -= Th[e, k, 2] * p0 - Th[e, k, 0] * p2
            E[e, k, 2] -= Th[e, k, 0] * p1 - Th[e, k, 1] * p0
        for j in range(m):
            node = e * m + j
            sigma = gx[j] * length[e]
            _advance(xs[e], Fs[e], omega[e], sigma, x[node], F[node], R, P, Q)
            element_derivatives(omega[e], sigma, Fs[e], dX[node], dTh[node])


@jit
def _strand_kinematics(frame0, omega, length, gx):
    """:func:`_kinematics` into freshly allocated arrays: ``(xs, Fs, Th, E, x, F, dX, dTh)``."""
    n = omega.shape[0]
    nodes = n * gx.shape[0]
    xs = np.empty((n + 1, 3))
    Fs = np.empty((n + 1, 3, 3))
    Th = np.empty((n, 3, 3))
    E = np.empty((n, 3, 3))
    x = np.empty((nodes, 3))
    F = np.empty((nodes, 3, 3))
    dX = np.empty((nodes, 3, 3))
    dTh = np.empty((nodes, 3, 3))
    _kinematics(frame0, omega, length, gx, xs, Fs, Th, E, x, F, dX, dTh)
    return xs, Fs, Th, E, x, F, dX, dTh


@jit
def strand_mass(root, frame0, omega, length, gx, gw, lam, rot, out):
    """Mass matrix of one strand as a composite rigid body, kg m^4.

    The same ``M`` as :func:`mass_from_nodes` (to round-off) without the
    node Jacobians, in O(N^2 + N m). Block ``(a, b)``, ``a < b``, is
    ``S_a^T (I_b S_b + L_b)`` with ``S`` the element twists ``(Th, E)``,
    ``I_b`` the spatial inertia of the nodes after element ``b`` and ``L_b``
    the momentum (moment, force) of ``b``'s own nodes per unit ``omega_b``;
    block ``(b, b)`` is ``S_b^T I_b S_b`` plus the own nodes' terms.
    Positions are taken relative to the root, so the cancellation in
    ``S^T I S`` costs at most ~(strand length / tail length)^2 eps.

    Parameters
    ----------
    root : (3,) float64, m
        Unused (``M`` does not depend on it); every strand kernel takes it.
    frame0, omega, length, gx, gw : as :func:`strand_nodes`
    lam : float64
        Linear density ``rho pi r^2``, kg/m.
    rot : float64
        Cross-section rotational density ``rho pi r^4 / 4``, kg m; 0 drops
        the rotational energy.
    out : (3N, 3N) float64, out
        Symmetric mass matrix.

    Notes
    -----
    ``M`` is positive definite when ``rot > 0``. With ``rot = 0`` it is
    singular exactly when some twist moves no point: the twist of a straight
    element whose downstream strand lies on its axis (a perfectly straight
    tail), to round-off.
    """
    n = omega.shape[0]
    m = gx.shape[0]
    xs, Fs, Th, E, x, F, dX, dTh = _strand_kinematics(frame0, omega, length, gx)
    out[:, :] = 0.0
    # composite of the nodes after element b: sum w, sum w x, sum w x x^T, sum w (1 + t t^T)
    c0 = 0.0
    c1 = np.zeros(3)
    c2 = np.zeros((3, 3))
    cI = np.zeros((3, 3))
    IS = np.empty((3, 6))  # (moment, force) of the composite per unit omega[b, k]
    L = np.empty((3, 6))  # the same plus b's own nodes
    for b in range(n - 1, -1, -1):
        tr = c2[0, 0] + c2[1, 1] + c2[2, 2]
        for k in range(3):
            t0 = Th[b, k, 0]
            t1 = Th[b, k, 1]
            t2 = Th[b, k, 2]
            e0 = E[b, k, 0]
            e1 = E[b, k, 1]
            e2 = E[b, k, 2]
            # moment: lam (tr c2 - c2) Th + rot cI Th + lam c1 x E
            for i in range(3):
                IS[k, i] = (lam * (tr * Th[b, k, i] - (c2[i, 0] * t0 + c2[i, 1] * t1 + c2[i, 2] * t2))
                            + rot * (cI[i, 0] * t0 + cI[i, 1] * t1 + cI[i, 2] * t2))
            IS[k, 0] += lam * (c1[1] * e2 - c1[2] * e1)
            IS[k, 1] += lam * (c1[2] * e0 - c1[0] * e2)
            IS[k, 2] += lam * (c1[0] * e1 - c1[1] * e0)
            # force: lam (c0 E + Th x c1)
            IS[k, 3] = lam * (c0 * e0 + t1 * c1[2] - t2 * c1[1])
            IS[k, 4] = lam * (c0 * e1 + t2 * c1[0] - t0 * c1[2])
            IS[k, 5] = lam * (c0 * e2 + t0 * c1[1] - t1 * c1[0])
        L[:, :] = IS
        base = 3 * b
        for j in range(m):
            node = b * m + j
            wn = gw[j] * length[b]
            wl = wn * lam
            wr = wn * rot
            tx = F[node, 0, 0]
            ty = F[node, 0, 1]
            tz = F[node, 0, 2]
            for k in range(3):
                dx0 = dX[node, k, 0]
                dx1 = dX[node, k, 1]
                dx2 = dX[node, k, 2]
                tk = tx * dTh[node, k, 0] + ty * dTh[node, k, 1] + tz * dTh[node, k, 2]
                # own momentum: moment x w lam dX + w rot I_w dTh, force w lam dX
                L[k, 0] += wl * (x[node, 1] * dx2 - x[node, 2] * dx1) + wr * (dTh[node, k, 0] + tx * tk)
                L[k, 1] += wl * (x[node, 2] * dx0 - x[node, 0] * dx2) + wr * (dTh[node, k, 1] + ty * tk)
                L[k, 2] += wl * (x[node, 0] * dx1 - x[node, 1] * dx0) + wr * (dTh[node, k, 2] + tz * tk)
                L[k, 3] += wl * dx0
                L[k, 4] += wl * dx1
                L[k, 5] += wl * dx2
                for l in range(k, 3):
                    tl = tx * dTh[node, l, 0] + ty * dTh[node, l, 1] + tz * dTh[node, l, 2]
                    out[base + k, base + l] += (
                        wl * (dx0 * dX[node, l, 0] + dx1 * dX[node, l, 1] + dx2 * dX[node, l, 2])
                        + wr * (dTh[node, k, 0] * dTh[node, l, 0] + dTh[node, k, 1] * dTh[node, l, 1]
                                + dTh[node, k, 2] * dTh[node, l, 2] + tk * tl))
        for k in range(3):
            for l in range(k, 3):
                acc = 0.0
                for i in range(3):
                    acc += Th[b, k, i] * IS[l, i] + E[b, k, i] * IS[l, 3 + i]
                out[base + k, base + l] += acc
                out[base + l, base + k] = out[base + k, base + l]
        for a in range(b):
            for k in range(3):
                for l in range(3):
                    acc = 0.0
                    for i in range(3):
                        acc += Th[a, k, i] * L[l, i] + E[a, k, i] * L[l, 3 + i]
                    out[3 * a + k, base + l] = acc
                    out[base + l, 3 * a + k] = acc
        # element b joins the composite
        for j in range(m):
            node = b * m + j
            wn = gw[j] * length[b]
            c0 += wn
            for i in range(3):
                c1[i] += wn * x[node, i]
                ti = F[node, 0, i]
                for r in range(3):
                    c2[i, r] += wn * x[node, i] * x[node, r]
                    cI[i, r] += wn * ti * F[node, 0, r]
                cI[i, i] += wn


@jit
def _project_loads(Th, E, x, dX, dTh, m, f, torque, out):
    """``out = sum_n J_n^T f_n + T_n^T torque_n`` by suffix sums of the resultant (O(N m))."""
    n = Th.shape[0]
    force = np.zeros(3)
    moment = np.zeros(3)  # about the root
    for b in range(n - 1, -1, -1):
        for k in range(3):
            acc = 0.0
            for i in range(3):
                acc += Th[b, k, i] * moment[i] + E[b, k, i] * force[i]
            for j in range(m):
                node = b * m + j
                for i in range(3):
                    acc += dX[node, k, i] * f[node, i] + dTh[node, k, i] * torque[node, i]
            out[3 * b + k] = acc
        for j in range(m):
            node = b * m + j
            moment[0] += x[node, 1] * f[node, 2] - x[node, 2] * f[node, 1] + torque[node, 0]
            moment[1] += x[node, 2] * f[node, 0] - x[node, 0] * f[node, 2] + torque[node, 1]
            moment[2] += x[node, 0] * f[node, 1] - x[node, 1] * f[node, 0] + torque[node, 2]
            for i in range(3):
                force[i] += f[node, i]


@jit
def strand_node_loads(root, frame0, omega, length, gx, f, torque, out):
    """Generalized force of point forces and torques at the nodes, O(N m), J m.

    ``out = sum_n J_n^T f_n + T_n^T torque_n`` (as :func:`node_forces_to_generalized`
    plus :func:`node_torques_to_generalized`) without the Jacobians: the
    loads after element ``b`` enter through their resultant force and moment.

    Parameters
    ----------
    root : (3,) float64, m; unused (the result does not depend on it)
    frame0, omega, length, gx : as :func:`strand_nodes`
    f : (N m, 3) float64
        World force at each node, N (weights and densities included).
    torque : (N m, 3) float64
        World torque at each node, N m.
    out : (3N,) float64, out
    """
    m = gx.shape[0]
    xs, Fs, Th, E, x, F, dX, dTh = _strand_kinematics(frame0, omega, length, gx)
    _project_loads(Th, E, x, dX, dTh, m, f, torque, out)


@jit
def _own_rates(omega_e, velocity_e, sigma, dp, dphi):
    """``dp = sum_k v_k dP/dw_k`` and ``dphi = sum_k v_k dphi/dw_k`` after ``sigma`` of one element, in its
    start frame: the velocity of its point and the angular velocity of its frame at the rates
    ``velocity_e`` (:func:`hairinv.rod.helix._element_rate`, summed over k).
    Real or complex ``omega_e`` (the complex step of :func:`_own_accelerations`)."""
    w0 = omega_e[2]
    w1 = omega_e[0]
    w2 = omega_e[1]
    ww = w0 * w0 + w1 * w1 + w2 * w2
    s2 = sigma * sigma
    A, B, C, D, Bp, Cp = helix_coefficients_and_derivatives(ww * s2)
    for i in range(3):
        dp[i] = 0.0 * w0
        dphi[i] = 0.0 * w0
    for k in range(3):
        vk = velocity_e[k]
        if vk == 0.0:
            continue
        p0, p1, p2, f0, f1, f2 = _element_rate(w0, w1, w2, ww, s2, sigma, B, C, Bp, Cp, k)
        dp[0] += vk * p0
        dp[1] += vk * p1
        dp[2] += vk * p2
        dphi[0] += vk * f0
        dphi[1] += vk * f1
        dphi[2] += vk * f2


_STEP = 1e-30  # complex step: exact first derivatives of the (analytic) rates


@jit
def _own_accelerations(omega_e, velocity_e, sigma, F, wc, pc, phic, acc, ang):
    """The element's own share of the acceleration at zero generalized acceleration, world coordinates:
    ``acc = F^T d/dt(dP v)`` and ``ang = F^T d/dt(dphi v)`` along ``omega + t v`` (the start frame held),
    by complex step of :func:`_own_rates`. ``wc``, ``pc``, ``phic``: complex work arrays (3,)."""
    for k in range(3):
        wc[k] = omega_e[k] + 1j * _STEP * velocity_e[k]
    _own_rates(wc, velocity_e, sigma, pc, phic)
    for i in range(3):
        acc[i] = (F[0, i] * pc[0].imag + F[1, i] * pc[1].imag + F[2, i] * pc[2].imag) / _STEP
        ang[i] = (F[0, i] * phic[0].imag + F[1, i] * phic[1].imag + F[2, i] * phic[2].imag) / _STEP


@jit
def _cross_add(a, b, out):
    """``out += a x b``."""
    out[0] += a[1] * b[2] - a[2] * b[1]
    out[1] += a[2] * b[0] - a[0] * b[2]
    out[2] += a[0] * b[1] - a[1] * b[0]


@jit
def node_bias_accelerations(root, frame0, omega, length, velocity, gx, a_out, alpha_out):
    """Node accelerations at zero generalized acceleration ("J-dot q_dot"), closed form.

    A node of element ``e`` moves at ``p_dot = U_e + W_e x p + dX v_e`` and turns
    at ``W_e + dTh v_e``, with ``W_e = sum_{a<e} Th_a v_a`` the angular velocity of
    the element's start frame and ``U_e = sum_{a<e} E_a v_a`` (positions relative
    to the root). ``Th_a``, ``E_a``, ``dX``, ``dTh`` are world vectors: their local
    parts depend on their own element's omega, and their frames turn at the start
    frame's angular velocity. With ``v`` held,

        a0  = C_e + B_e x p + W_e x p_dot + W_e x (dX v_e) + F_e^T d/dt(dP v_e),
        al0 = B_e + W_e x (dTh v_e) + F_e^T d/dt(dphi v_e),

    where ``B_e = sum_{a<e} d/dt(Th_a v_a)`` and ``C_e = sum_{a<e} d/dt(E_a v_a)``
    accumulate element by element (``E_a = Dx_a - Th_a x x_{a+1}``), and the
    elements' own second derivatives along ``v`` are complex steps of their
    closed-form rates (exact to round-off). Both are exactly zero when
    ``v = 0``. O(N m).

    Parameters
    ----------
    root : (3,) float64, m; unused (positions are taken relative to it)
    frame0 : (3, 3) float64, rows (t, n1, n2)
    omega : (N, 3) float64, 1/m
    length : (N,) float64, m
    velocity : (N, 3) float64
        ``q_dot = d omega / dt``, 1/(m s).
    gx : (m,) float64, nodes on ``[0, 1]``
    a_out : (N m, 3) float64, out, m/s^2
    alpha_out : (N m, 3) float64, out, rad/s^2
    """
    xs, Fs, Th, E, x, F, dX, dTh = _strand_kinematics(frame0, omega, length, gx)
    _bias_accelerations(omega, length, velocity, gx, xs, Fs, Th, E, x, dX, dTh, a_out, alpha_out)


@jit
def _bias_accelerations(omega, length, velocity, gx, xs, Fs, Th, E, x, dX, dTh, a_out, alpha_out):
    """:func:`node_bias_accelerations` given the strand's kinematics (:func:`_kinematics`)."""
    n = omega.shape[0]
    m = gx.shape[0]
    W = np.zeros(3)  # angular velocity of the current element's start frame
    U = np.zeros(3)  # sum E_a v_a
    Bs = np.zeros(3)  # sum d/dt (Th_a v_a)
    Cs = np.zeros(3)  # sum d/dt (E_a v_a)
    wc = np.empty(3, np.complex128)
    pc = np.empty(3, np.complex128)
    phic = np.empty(3, np.complex128)
    acc = np.empty(3)
    ang = np.empty(3)
    own = np.empty(3)
    turn = np.empty(3)
    pd = np.empty(3)
    for e in range(n):
        v = velocity[e]
        for j in range(m):
            node = e * m + j
            for i in range(3):
                own[i] = dX[node, 0, i] * v[0] + dX[node, 1, i] * v[1] + dX[node, 2, i] * v[2]
                turn[i] = dTh[node, 0, i] * v[0] + dTh[node, 1, i] * v[1] + dTh[node, 2, i] * v[2]
                pd[i] = U[i] + own[i]
            _cross_add(W, x[node], pd)
            _own_accelerations(omega[e], v, gx[j] * length[e], Fs[e], wc, pc, phic, acc, ang)
            for i in range(3):
                a_out[node, i] = Cs[i] + acc[i]
                alpha_out[node, i] = Bs[i] + ang[i]
            _cross_add(Bs, x[node], a_out[node])
            _cross_add(W, pd, a_out[node])
            _cross_add(W, own, a_out[node])
            _cross_add(W, turn, alpha_out[node])
        # element e as an upstream element of what follows: Th_e v_e, Dx_e v_e and their rates
        thv = np.zeros(3)
        dxv = np.zeros(3)
        for i in range(3):
            for k in range(3):
                thv[i] += Th[e, k, i] * v[k]
                dxv[i] += E[e, k, i] * v[k]
        ev = dxv.copy()  # E_e v_e
        _cross_add(thv, xs[e + 1], dxv)  # Dx_e v_e = E_e v_e + Th_e v_e x x_{e+1}
        _own_accelerations(omega[e], v, length[e], Fs[e], wc, pc, phic, acc, ang)
        dthv = ang.copy()  # d/dt (Th_e v_e) = W x Th_e v_e + F_e^T d/dt(dphi v_e)
        _cross_add(W, thv, dthv)
        ddxv = acc.copy()  # d/dt (Dx_e v_e)
        _cross_add(W, dxv, ddxv)
        end_velocity = U + dxv  # velocity of x_{e+1}
        _cross_add(W, xs[e + 1], end_velocity)
        # d/dt (E_e v_e) = d/dt(Dx_e v_e) - d/dt(Th_e v_e) x x_{e+1} - Th_e v_e x x_{e+1}_dot
        for i in range(3):
            Cs[i] += ddxv[i]
        _cross_add(xs[e + 1], dthv, Cs)
        _cross_add(end_velocity, thv, Cs)
        for i in range(3):
            Bs[i] += dthv[i]
            W[i] += thv[i]
            U[i] += ev[i]


@jit
def strand_bias_forces(root, frame0, omega, length, velocity, gx, gw, lam, rot, out):
    """Velocity-product generalized force ``b`` of one strand (``M q_ddot = f + b``), J m.

    ``b = -sum_n w_n (lam J_n^T a_n + T_n^T (I_w al_n + W_n x I_w W_n))`` with
    ``a_n, al_n`` from :func:`node_bias_accelerations`, ``W_n = T_n q_dot``
    and ``I_w = rot (1 + t_n t_n^T)``; O(N m) after the accelerations.

    Parameters
    ----------
    root, frame0, omega, length, gx, gw : as :func:`strand_nodes` (root unused)
    velocity : (N, 3) float64, ``d omega / dt``, 1/(m s)
    lam : float64, kg/m
    rot : float64, kg m
    out : (3N,) float64, out
    """
    strand_velocity_forces(root, frame0, omega, length, velocity, gx, gw, lam, rot, True, _NO_FRAME, 0.0, out)


_NO_FRAME = np.zeros((5, 3))


@jit
def strand_velocity_forces(root, frame0, omega, length, velocity, gx, gw, lam, rot, bias, motion, air, out):
    """Generalized force of one strand's motion: the velocity products and a moving frame's, J m.

    With ``bias``, the velocity-product force of :func:`strand_bias_forces`. With ``motion`` (the
    (5, 3) array of ``Motion.packed``: gravity, unused here, then the frame's acceleration ``a0``,
    velocity ``u``, spin ``W`` and spin rate ``A``) not all zero, the forces of the moving frame on
    the centerline, ``-lam w (a0 + A x p + W x (W x p) + 2 W x p_dot + air (u + W x p))`` at each
    node ``p`` (the frame's own velocity dragged by the air, at ``air`` 1/s). The node velocities
    ``p_dot`` accumulate the upstream elements' rigid twists, O(N m), like the loads' projection:
    one evaluation of the strand's kinematics serves both forces.
    """
    n = omega.shape[0]
    m = gx.shape[0]
    nodes = n * m
    out[:] = 0.0
    acc = motion[1]
    vel = motion[2]
    W = motion[3]
    A = motion[4]
    framed = False
    for i in range(3):
        if acc[i] != 0.0 or vel[i] != 0.0 or W[i] != 0.0 or A[i] != 0.0:
            framed = True
    if not (bias or framed):
        return
    xs, Fs, Th, E, x, F, dX, dTh = _strand_kinematics(frame0, omega, length, gx)
    f = np.zeros((nodes, 3))
    torque = np.zeros((nodes, 3))
    if bias:
        a = np.empty((nodes, 3))
        alpha = np.empty((nodes, 3))
        _bias_accelerations(omega, length, velocity, gx, xs, Fs, Th, E, x, dX, dTh, a, alpha)
        Wup = np.zeros(3)  # angular velocity of the frames after the elements so far
        for e in range(n):
            for j in range(m):
                node = e * m + j
                wn = gw[j] * length[e]
                for i in range(3):
                    f[node, i] = -wn * lam * a[node, i]
                if rot != 0.0:
                    W0 = Wup[0]
                    W1 = Wup[1]
                    W2 = Wup[2]
                    for k in range(3):
                        W0 += dTh[node, k, 0] * velocity[e, k]
                        W1 += dTh[node, k, 1] * velocity[e, k]
                        W2 += dTh[node, k, 2] * velocity[e, k]
                    t0 = F[node, 0, 0]
                    t1 = F[node, 0, 1]
                    t2 = F[node, 0, 2]
                    ta = t0 * alpha[node, 0] + t1 * alpha[node, 1] + t2 * alpha[node, 2]
                    tW = t0 * W0 + t1 * W1 + t2 * W2
                    # I_w al + W x I_w W, with I_w W = rot (W + t (t.W)): W x I_w W = rot (t.W) W x t
                    torque[node, 0] = -wn * rot * (alpha[node, 0] + t0 * ta + tW * (W1 * t2 - W2 * t1))
                    torque[node, 1] = -wn * rot * (alpha[node, 1] + t1 * ta + tW * (W2 * t0 - W0 * t2))
                    torque[node, 2] = -wn * rot * (alpha[node, 2] + t2 * ta + tW * (W0 * t1 - W1 * t0))
            for k in range(3):
                for i in range(3):
                    Wup[i] += Th[e, k, i] * velocity[e, k]
    if framed:
        Eup = np.zeros(3)  # the upstream elements' twists times their rates: p_dot = Eup + Wup x p + own
        Wup = np.zeros(3)
        p = np.empty(3)
        pd = np.empty(3)
        for e in range(n):
            for j in range(m):
                node = e * m + j
                for i in range(3):
                    pd[i] = Eup[i] + dX[node, 0, i] * velocity[e, 0] + dX[node, 1, i] * velocity[e, 1] \
                        + dX[node, 2, i] * velocity[e, 2]
                    p[i] = x[node, i] + root[i]
                pd[0] += Wup[1] * x[node, 2] - Wup[2] * x[node, 1]
                pd[1] += Wup[2] * x[node, 0] - Wup[0] * x[node, 2]
                pd[2] += Wup[0] * x[node, 1] - Wup[1] * x[node, 0]
                Wx0 = W[1] * p[2] - W[2] * p[1]
                Wx1 = W[2] * p[0] - W[0] * p[2]
                Wx2 = W[0] * p[1] - W[1] * p[0]
                scale = -lam * gw[j] * length[e]
                f[node, 0] += scale * (acc[0] + A[1] * p[2] - A[2] * p[1] + W[1] * Wx2 - W[2] * Wx1
                                       + 2.0 * (W[1] * pd[2] - W[2] * pd[1]) + air * (vel[0] + Wx0))
                f[node, 1] += scale * (acc[1] + A[2] * p[0] - A[0] * p[2] + W[2] * Wx0 - W[0] * Wx2
                                       + 2.0 * (W[2] * pd[0] - W[0] * pd[2]) + air * (vel[1] + Wx1))
                f[node, 2] += scale * (acc[2] + A[0] * p[1] - A[1] * p[0] + W[0] * Wx1 - W[1] * Wx0
                                       + 2.0 * (W[0] * pd[1] - W[1] * pd[0]) + air * (vel[2] + Wx2))
            for k in range(3):
                for i in range(3):
                    Eup[i] += E[e, k, i] * velocity[e, k]
                    Wup[i] += Th[e, k, i] * velocity[e, k]
    _project_loads(Th, E, x, dX, dTh, m, f, torque, out)


def inertia_terms(root, frame0, omega, length, velocity, lam, rot, order=4):
    """Mass matrix and velocity-product force of one strand: ``M q_ddot = f + b``.

    Parameters
    ----------
    root : (3,) m;  frame0 : (3, 3) rows (t, n1, n2)
    omega : (N, 3) 1/m;  length : (N,) m;  velocity : (N, 3) 1/(m s)
    lam : float, kg/m;  rot : float, kg m
    order : int, Gauss nodes per element

    Returns
    -------
    M : (3N, 3N) float64, kg m^4
    b : (3N,) float64, J m
    """
    root = np.ascontiguousarray(root, dtype=np.float64)
    frame0 = np.ascontiguousarray(frame0, dtype=np.float64)
    omega = np.ascontiguousarray(omega, dtype=np.float64)
    length = np.ascontiguousarray(length, dtype=np.float64)
    velocity = np.ascontiguousarray(velocity, dtype=np.float64)
    gx, gw = gauss_nodes(order)
    n = omega.shape[0]
    M = np.empty((3 * n, 3 * n))
    strand_mass(root, frame0, omega, length, gx, gw, float(lam), float(rot), M)
    b = np.empty(3 * n)
    strand_bias_forces(root, frame0, omega, length, velocity, gx, gw, float(lam), float(rot), b)
    return M, b
