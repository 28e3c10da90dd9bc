"""Contacts solved together: the dense block of a group of contacts, and nonsmooth Newton on it.

Contacts along one strand have nearly parallel rows of ``W``, which makes
contact-by-contact Gauss-Seidel crawl. Where no contact couples two strands
(body contacts only), each strand's contacts form a group whose cone problem
is independent of the others' and small: its dense block
``W_g = Z_g^T Z_g + gamma`` is formed once, and nonsmooth Newton on the
stacked Fischer-Burmeister function solves it in a few iterations. The
simulation (:mod:`hairinv.dynamics.contact`, the De Saxce problem) and the
inversion (:mod:`hairinv.invert`, the convex one) both use it.
"""

from __future__ import annotations

import numpy as np

from .._jit import jit
from .local import CODE_NUMERICAL, LOCAL_TOL, fb_coulomb, natural_scalars, project_scalars, solve_contact
from .rows import ContactRows

__all__ = ["group_fixed_point", "group_newton", "strand_blocks"]

#: Gauss-Seidel sweeps on a group's block where Newton leaves a round's convex problem unsolved
GS_SWEEPS = 200


@jit
def _group_blocks(ptr, cols, vals, gamma, members, group_ptr, block_ptr, blocks, n_dofs):
    """Dense ``W_g = Z_g^T Z_g + gamma`` of every group of contacts, row-major at ``blocks[block_ptr[g]:]``."""
    scratch = np.zeros((n_dofs, 3))
    for g in range(group_ptr.shape[0] - 1):
        lo = group_ptr[g]
        m = group_ptr[g + 1] - lo
        n = 3 * m
        base = block_ptr[g]
        for a in range(m):
            i = members[lo + a]
            for t in range(ptr[i], ptr[i + 1]):
                for row in range(3):
                    scratch[cols[t], row] = vals[t, row]
            for c in range(m):
                j = members[lo + c]
                for t in range(ptr[j], ptr[j + 1]):
                    col = cols[t]
                    for ra in range(3):
                        for rc in range(3):
                            blocks[base + (3 * a + ra) * n + 3 * c + rc] += scratch[col, ra] * vals[t, rc]
            for ra in range(3):
                blocks[base + (3 * a + ra) * n + 3 * a + ra] += gamma[i]
            for t in range(ptr[i], ptr[i + 1]):
                for row in range(3):
                    scratch[cols[t], row] = 0.0


@jit
def _group_load(ptr, cols, vals, gamma, b, r, f, members, lo, m, q, rg):
    """The ``m`` contacts of a group (``members[lo:lo + m]``): ``q = b + gamma r + Z f`` (their velocity
    ``u``, the group's own forces included) and ``rg`` their forces, both flat (3m,)."""
    for a in range(m):
        i = members[lo + a]
        for row in range(3):
            acc = b[i, row] + gamma[i] * r[i, row]
            for t in range(ptr[i], ptr[i + 1]):
                acc += vals[t, row] * f[cols[t]]
            q[3 * a + row] = acc
            rg[3 * a + row] = r[i, row]


@jit
def _group_store(ptr, cols, vals, members, lo, m, x, scale, r, f):
    """The group's new forces ``x[3a:3a + 3] / scale[a]`` (flat, as :func:`_group_load` gives them)
    written into ``r``, and ``f = Z^T r`` moved by the change."""
    for a in range(m):
        i = members[lo + a]
        d0 = x[3 * a] / scale[a] - r[i, 0]
        d1 = x[3 * a + 1] / scale[a] - r[i, 1]
        d2 = x[3 * a + 2] / scale[a] - r[i, 2]
        r[i, 0] += d0
        r[i, 1] += d1
        r[i, 2] += d2
        for t in range(ptr[i], ptr[i + 1]):
            f[cols[t]] += vals[t, 0] * d0 + vals[t, 1] * d1 + vals[t, 2] * d2


def strand_blocks(rows: ContactRows, gamma: np.ndarray, strand: np.ndarray) -> tuple:
    """Groups of contacts and their dense blocks: a strand's body contacts together, each hair-hair
    contact alone. Returns ``(members, group_ptr, block_ptr, blocks)``: group ``g`` is
    ``members[group_ptr[g]:group_ptr[g + 1]]``, its block row-major at ``blocks[block_ptr[g]:]``."""
    n = rows.n_contacts
    body = strand[:, 1] < 0
    key = np.where(body, strand[:, 0], len(strand) + np.arange(n)) if n else np.zeros(0, np.int64)
    members = np.argsort(key, kind="stable").astype(np.int64)
    sorted_key = key[members]
    starts = np.flatnonzero(np.r_[True, sorted_key[1:] != sorted_key[:-1]]) if n else np.zeros(0, np.int64)
    group_ptr = np.r_[starts, n].astype(np.int64)
    sizes = (3 * np.diff(group_ptr)) ** 2
    block_ptr = np.r_[0, np.cumsum(sizes)].astype(np.int64)
    blocks = np.zeros(int(block_ptr[-1]))
    _group_blocks(rows.ptr, rows.cols, rows.vals, gamma, members, group_ptr, block_ptr, blocks, rows.n_dofs)
    return members, group_ptr, block_ptr, blocks


@jit(error_model="numpy")
def _solve_dense(A, rhs, out, n):
    """Gaussian elimination with partial pivoting on the leading ``n x n`` system; False if (nearly)
    singular. ``A`` and ``rhs`` are overwritten."""
    scale = 0.0
    for i in range(n):
        for j in range(n):
            scale = max(scale, abs(A[i, j]))
    if not (scale > 0.0) or scale == np.inf:
        return False
    for k in range(n):
        p = k
        for i in range(k + 1, n):
            if abs(A[i, k]) > abs(A[p, k]):
                p = i
        if not (abs(A[p, k]) > 1e-14 * scale):
            return False
        if p != k:
            for j in range(n):
                A[k, j], A[p, j] = A[p, j], A[k, j]
            rhs[k], rhs[p] = rhs[p], rhs[k]
        for i in range(k + 1, n):
            f = A[i, k] / A[k, k]
            if f != 0.0:
                for j in range(k, n):
                    A[i, j] -= f * A[k, j]
                rhs[i] -= f * rhs[k]
    for k in range(n - 1, -1, -1):
        s = rhs[k]
        for j in range(k + 1, n):
            s -= A[k, j] * out[j]
        out[k] = s / A[k, k]
    return True


@jit(error_model="numpy")
def _group_merit(W, n, q, rho, mu, x, u, phi, G, Jr, Ju, jac, desaxce, velocity):
    """The stacked FB function of one group at scaled forces ``x_i = rho_i r_i``:
    ``phi_i = FB(x_i, u_i)`` with ``u = W r + q`` (with ``desaxce``, the De Saxce velocity
    ``u_i + mu_i |u_T,i| e_N`` in place of ``u_i``); with ``jac`` also ``G = d phi / d x``.
    Returns ``|phi|^2 / 2`` and the largest natural-map residual ``|x_i - P_K(x_i - u~_i)|``
    in velocity units, or divided by ``rho_i`` (force units) without ``velocity``."""
    m = n // 3
    for a in range(n):
        acc = q[a]
        for c in range(n):
            acc += W[a, c] * x[c] / rho[c // 3]
        u[a] = acc
    merit = 0.0
    worst = 0.0
    for a in range(m):
        k = 3 * a
        mk = mu[a]
        u0, u1, u2 = u[k], u[k + 1], u[k + 2]
        ds = desaxce and mk > 0.0 and mk < np.inf
        nt = np.sqrt(u1 * u1 + u2 * u2)
        v0 = u0 + mk * nt if ds else u0
        e = natural_scalars(x[k], x[k + 1], x[k + 2], u0, u1, u2, mk, desaxce)
        if not velocity:
            e /= rho[a]
        if not (e <= worst):
            worst = e
        fb_coulomb(x[k], x[k + 1], x[k + 2], v0, u1, u2, mk, phi[k:k + 3], Jr, Ju, jac)
        merit += 0.5 * (phi[k] ** 2 + phi[k + 1] ** 2 + phi[k + 2] ** 2)
        if jac:
            # d u~_a / d x_c = T_a W_ac / rho_c, T_a = I + e_N (mu u_T / |u_T|)' (0 at u_T = 0)
            t1 = mk * u1 / nt if ds and nt > 0.0 else 0.0
            t2 = mk * u2 / nt if ds and nt > 0.0 else 0.0
            for c in range(n):
                s = 1.0 / rho[c // 3]
                d0 = (W[k, c] + t1 * W[k + 1, c] + t2 * W[k + 2, c]) * s
                d1 = W[k + 1, c] * s
                d2 = W[k + 2, c] * s
                for i in range(3):
                    G[k + i, c] = Ju[i, 0] * d0 + Ju[i, 1] * d1 + Ju[i, 2] * d2
            for i in range(3):
                for j in range(3):
                    G[k + i, k + j] += Jr[i, j]
    return merit, worst


@jit(error_model="numpy")
def _projected_worst(W, n, q, rho, mu, x, xp, u, phi, G, Jr, Ju, desaxce, velocity):
    """``xp = P_K(x)`` contact by contact (scaled forces: the cones are scale-free) and the largest
    natural-map residual there (see :func:`_group_merit`): the Newton iterates meet the cones only in the
    limit, and what is stored, and measured against the target, is the admissible point."""
    for a in range(n // 3):
        k = 3 * a
        xp[k], xp[k + 1], xp[k + 2] = project_scalars(x[k], x[k + 1], x[k + 2], mu[a])
    _, worst = _group_merit(W, n, q, rho, mu, xp, u, phi, G, Jr, Ju, False, desaxce, velocity)
    return worst


@jit(error_model="numpy")
def _newton_scratch(big):
    """Work arrays of :func:`_block_newton` for groups of up to ``big`` contacts."""
    nb = 3 * big
    return (np.empty((nb, nb)), np.empty((nb, nb)), np.empty((nb, nb)), np.empty((3, 3)), np.empty((3, 3)),
            np.empty(nb), np.empty(nb), np.empty(nb), np.empty(nb), np.empty(nb), np.empty(nb), np.empty(nb),
            np.empty(nb), np.empty(nb), np.empty(nb), np.empty((3, 3)), np.empty(3), np.empty(3))


@jit(error_model="numpy")
def _block_newton(W, n, q, rho, mug, x, xbest, target, max_iter, desaxce, velocity, scratch):
    """Nonsmooth Newton on one group's dense block (see :func:`group_newton`) from the scaled forces
    ``x`` (overwritten). ``xbest`` receives the projection onto the cones of the iterate with the
    smallest largest natural-map residual, the start included. Returns that residual and whether
    ``xbest`` differs from the start."""
    G, Gt, A, Jr, Ju, xt, xp, up, phip, u, phi, phit, rhs, d, grad, _, _, _ = scratch
    merit, worst = _group_merit(W, n, q, rho, mug, x, u, phi, G, Jr, Ju, True, desaxce, velocity)
    best = _projected_worst(W, n, q, rho, mug, x, xbest, up, phip, Gt, Jr, Ju, desaxce, velocity)
    improved = False
    for a in range(n):
        improved = improved or xbest[a] != x[a]  # the start was off the cones: store its projection
    for _ in range(max_iter):
        if best <= target or not np.isfinite(merit):
            break
        for a in range(n):
            acc = 0.0
            for c in range(n):
                acc += G[c, a] * phi[c]
            grad[a] = acc
            rhs[a] = -phi[a]
            for c in range(n):
                A[a, c] = G[a, c]
        ok = _solve_dense(A, rhs, d, n)
        slope = 0.0
        if ok:
            for a in range(n):
                slope += grad[a] * d[a]
        if not ok or not (slope < 0.0):
            slope = 0.0
            for a in range(n):
                d[a] = -grad[a]
                slope -= grad[a] * grad[a]
        t = 1.0
        accepted = False
        mt = merit
        wt = worst
        if slope < 0.0:
            for _h in range(30):
                for a in range(n):
                    xt[a] = x[a] + t * d[a]
                mt, wt = _group_merit(W, n, q, rho, mug, xt, u, phit, Gt, Jr, Ju, True, desaxce, velocity)
                if mt <= merit + 1e-4 * t * slope:
                    accepted = True
                    break
                t *= 0.5
        if accepted:
            merit = mt
            worst = wt
            for a in range(n):
                x[a] = xt[a]
                phi[a] = phit[a]
                for c in range(n):
                    G[a, c] = Gt[a, c]
        else:
            # a kink of the FB function or of |u_T| stops the descent: one Gauss-Seidel pass of exact
            # local solves moves off it
            _block_gauss_seidel(W, n, q, rho, mug, x, 1, desaxce, scratch)
            merit, worst = _group_merit(W, n, q, rho, mug, x, u, phi, G, Jr, Ju, True, desaxce, velocity)
        projected = _projected_worst(W, n, q, rho, mug, x, xp, up, phip, Gt, Jr, Ju, desaxce, velocity)
        if projected < best:
            best = projected
            improved = True
            for a in range(n):
                xbest[a] = xp[a]
    return best, improved


@jit(error_model="numpy")
def _block_gauss_seidel(W, n, q, rho, mug, x, max_sweeps, desaxce, scratch):
    """Gauss-Seidel on one group's dense block (exact local solves, contact after contact) from the scaled
    forces ``x`` (updated in place), until they stop changing (1e-12 relative) or ``max_sweeps``. On a
    convex problem each local solve lowers the objective: slow where the block is ill-conditioned, but
    it never goes astray where the Newton steps of :func:`_block_newton` stall."""
    Wk, bl, rk = scratch[15], scratch[16], scratch[17]
    m = n // 3
    for _ in range(max_sweeps):
        change = 0.0
        size = 0.0
        for a in range(m):
            k = 3 * a
            for ra in range(3):
                acc = q[k + ra]
                for c in range(n):
                    if c // 3 != a:
                        acc += W[k + ra, c] * x[c] / rho[c // 3]
                bl[ra] = acc
                rk[ra] = x[k + ra] / rho[a]
                for rc in range(3):
                    Wk[ra, rc] = W[k + ra, k + rc]
            status, _ = solve_contact(Wk, bl, mug[a], rk, LOCAL_TOL, 50, desaxce)
            if status == CODE_NUMERICAL:
                continue
            for ra in range(3):
                value = rho[a] * rk[ra]
                change = max(change, abs(value - x[k + ra]))
                size = max(size, abs(value))
                x[k + ra] = value
        if change <= 1e-12 * size:
            break


@jit(error_model="numpy")
def _group_setup(ptr, cols, vals, gamma, b, mu, members, lo, m, blocks, base, Wd, r, f, W, rho, mug, q, x):
    """One group's dense block ``W``, scales ``rho``, friction ``mug``, what it sees of the rest ``q`` and
    its scaled forces ``x`` (see :func:`group_newton`); False if a contact has no finite positive scale."""
    n = 3 * m
    for a in range(n):
        for c in range(n):
            W[a, c] = blocks[base + a * n + c]
    for a in range(m):
        i = members[lo + a]
        rho[a] = (Wd[i, 0, 0] + Wd[i, 1, 1] + Wd[i, 2, 2]) / 3.0
        if not (rho[a] > 0.0 and rho[a] < np.inf):
            return False
    _group_load(ptr, cols, vals, gamma, b, r, f, members, lo, m, q, x)
    for a in range(m):
        mug[a] = mu[members[lo + a]]
        for row in range(3):
            x[3 * a + row] *= rho[a]
    # q = u - W_g r_g: what the group sees of b and of the other groups
    for a in range(n):
        acc = 0.0
        for c in range(n):
            acc += W[a, c] * x[c] / rho[c // 3]
        q[a] -= acc
    return True


@jit(error_model="numpy")
def group_newton(ptr, cols, vals, gamma, b, mu, members, group_ptr, block_ptr, blocks, Wd, r, f, target,
                  max_iter, desaxce, velocity, g_lo, g_hi, done):
    """Each group's cone problem ``K ∋ r_g ⟂ u_g`` (with ``desaxce`` the De Saxce one, ``u~_g``) solved
    at once, the other groups frozen: nonsmooth Newton on the stacked FB function of the scaled forces
    ``x_i = rho_i r_i`` (``rho_i = trace W_ii / 3``, so that ``x`` and ``u`` share velocity units), with
    Armijo steps on ``|phi|^2 / 2`` and steepest descent where the Newton direction does not descend.
    A group keeps the iterate whose projection onto the cones has the smallest largest natural-map
    residual (velocity units with ``velocity``, else force units), the start included, and stores that
    projection; ``done[g]``: whether it meets ``target``.
    ``f = Z^T r`` is kept up to date (rows ``Z`` without a weight)."""
    big = 0
    for g in range(g_lo, g_hi):
        big = max(big, group_ptr[g + 1] - group_ptr[g])
    nb = 3 * big
    W = np.empty((nb, nb))
    q = np.empty(nb)
    x = np.empty(nb)
    xbest = np.empty(nb)
    rho = np.empty(big)
    mug = np.empty(big)
    scratch = _newton_scratch(big)
    for g in range(g_lo, g_hi):
        lo = group_ptr[g]
        m = group_ptr[g + 1] - lo
        if not _group_setup(ptr, cols, vals, gamma, b, mu, members, lo, m, blocks, block_ptr[g], Wd, r, f, W, rho,
                            mug, q, x):
            done[g] = False
            continue  # a contact no coordinate moves (or a non-finite W): left unsolved, and reported so
        best, improved = _block_newton(W, 3 * m, q, rho, mug, x, xbest, target, max_iter, desaxce, velocity, scratch)
        done[g] = best <= target
        if not improved:
            continue  # r untouched, bit for bit
        _group_store(ptr, cols, vals, members, lo, m, xbest, rho, r, f)


@jit(error_model="numpy")
def group_fixed_point(ptr, cols, vals, gamma, b, mu, members, group_ptr, block_ptr, blocks, Wd, r, f, target,
                       max_iter, max_rounds, patience, g_lo, g_hi, done, rounds):
    """The De Saxce problem of each group not yet ``done`` as a fixed point of convex ones, group by
    group (the other groups frozen): with the shift ``s_i = mu_i |u_T,i|`` of the current forces held,
    the convex cone problem of ``u + s e_N`` is solved by :func:`_block_newton` to a tenth of the
    group's best De Saxce residual, and where Newton stops short of that, by
    :func:`_block_gauss_seidel`; its answer gives the next shift (Acary, Cadoux et al.; at a fixed
    point the De Saxce conditions hold exactly). Each group keeps its iterate of smallest De Saxce
    residual (velocity units) and stops once it meets ``target``, after ``max_rounds`` rounds, or
    after ``patience`` rounds in a row without a new best (0: never). ``rounds[g]``: the rounds it
    took; ``done[g]``: whether it meets ``target``. Groups :func:`_group_setup` rejects are skipped."""
    big = 0
    for g in range(g_lo, g_hi):
        if not done[g]:
            big = max(big, group_ptr[g + 1] - group_ptr[g])
    if big == 0:
        return
    nb = 3 * big
    W = np.empty((nb, nb))
    q = np.empty(nb)
    qs = np.empty(nb)
    x = np.empty(nb)
    xs = np.empty(nb)
    xbest = np.empty(nb)
    xp = np.empty(nb)
    u = np.empty(nb)
    phi = np.empty(nb)
    rho = np.empty(big)
    mug = np.empty(big)
    scratch = _newton_scratch(big)
    Gt, Jr, Ju = scratch[1], scratch[3], scratch[4]
    for g in range(g_lo, g_hi):
        if done[g]:
            continue
        lo = group_ptr[g]
        m = group_ptr[g + 1] - lo
        n = 3 * m
        if not _group_setup(ptr, cols, vals, gamma, b, mu, members, lo, m, blocks, block_ptr[g], Wd, r, f, W, rho,
                            mug, q, x):
            continue
        best = _projected_worst(W, n, q, rho, mug, x, xbest, u, phi, Gt, Jr, Ju, True, True)
        improved = False
        last_best = 0  # the round that found the best so far
        k = 0
        for k in range(1, max_rounds + 1):
            # the shift of the current forces' velocities
            for a in range(n):
                acc = q[a]
                for c in range(n):
                    acc += W[a, c] * x[c] / rho[c // 3]
                u[a] = acc
            for a in range(m):
                qs[3 * a] = q[3 * a]
                qs[3 * a + 1] = q[3 * a + 1]
                qs[3 * a + 2] = q[3 * a + 2]
                if mug[a] > 0.0 and mug[a] < np.inf:
                    qs[3 * a] += mug[a] * np.sqrt(u[3 * a + 1] ** 2 + u[3 * a + 2] ** 2)
            inner, _ = _block_newton(W, n, qs, rho, mug, x, xs, 0.1 * best, max_iter, False, True, scratch)
            for a in range(n):
                x[a] = xs[a]
            if inner > 0.1 * best:
                _block_gauss_seidel(W, n, qs, rho, mug, x, GS_SWEEPS, False, scratch)
            residual = _projected_worst(W, n, q, rho, mug, x, xp, u, phi, Gt, Jr, Ju, True, True)
            if residual < best:
                best = residual
                improved = True
                for a in range(n):
                    xbest[a] = xp[a]
            if best <= target:
                break
            if best == residual:
                last_best = k
            elif patience > 0 and k - last_best >= patience:
                break
        rounds[g] = k
        done[g] = best <= target
        if improved:
            _group_store(ptr, cols, vals, members, lo, m, xbest, rho, r, f)
