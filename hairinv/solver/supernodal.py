"""A supernodal Cholesky factorisation on scipy's BLAS, on every core, the same to the bit on any.

The interior point's rod-coordinate system (:mod:`.interior`) is factored once per step with the same
pattern. This module analyses the pattern once: the fill-reducing ordering given, postordered along its
elimination tree; the factor's column counts; supernodes, fundamental (a column joins its parent's
supernode when it is the parent's only child and their patterns nest) and then relaxed by CHOLMOD's rules
(a child merged into its parent while the explicit zeros this adds stay few), so that the many small
supernodes near a strand's tip do not each pay a call; each supernode's rows below its columns; and, for
each supernode, the supernodes below it whose rows reach its columns (its update list).

New values are then factored left-looking: a supernode's panel (its columns, every row of the factor in
them, dense, column-major) gathers the matrix's entries less each update, the product of a lower
supernode's rows (``dgemm``), scattered into the panel or written in place where the rows and columns
are runs of the panel's; its diagonal block is factored (``dpotrf``) and the rows below solved against it
(``dtrsm``). The dense kernels are scipy's (``scipy.linalg.cython_blas``, ``cython_lapack``), called from
compiled code.

Parallel, and the same to the bit on any thread count. The work is cut into pieces by the pattern alone:
the subtrees costing at most ``_SUBTREE_SHARE`` of the whole are one job each (their supernodes in
order); above them, level by level, each supernode's gathering is cut into blocks of columns and its
solve into blocks of rows. Pieces run on the worker threads (:mod:`hairinv._parallel`), each on one thread
with its own buffers, BLAS limited to one thread meanwhile (:func:`hairinv._parallel.blas_pinned`, for the
BLAS libraries threadpoolctl controls: OpenBLAS, MKL, BLIS): OpenBLAS's threaded ``dpotrf``, ``dtrsm``
and, on some shapes, ``dgemm`` round differently from their one-thread runs, so a threaded BLAS would make
the factor depend on the thread count. Which thread runs a piece changes nothing it computes.
"""

from __future__ import annotations

import threading

import llvmlite.binding as llvm
import numpy as np
from numba.core import types
from numba.extending import get_cython_function_address

from .._jit import jit
from .._parallel import blas_pinned, cost_ranges, run_ranges, worker_count

__all__ = ["SupernodalCholesky", "column_counts", "etree", "expanded_flops", "permuted_pattern"]



def _external(symbol: str, address: int, signature):
    """A C function at ``address`` as a compiled-code external function. It is declared by a symbol name
    registered with LLVM, not by its address, so the kernels calling it can be cached."""
    llvm.add_symbol(symbol, address)
    return types.ExternalFunction(symbol, signature)


def _lapack(module: str, name: str, nargs: int):
    """scipy's Fortran-convention ``name`` (every argument a pointer). Pointers are passed as addresses
    (``array.ctypes.data``), which the x86-64 and AArch64 calling conventions pass exactly as pointers."""
    return _external(f"hairinv_{name}", get_cython_function_address(module, name),
                     types.void(*([types.uintp] * nargs)))


_dpotrf = _lapack("scipy.linalg.cython_lapack", "dpotrf", 5)
_dtrsm = _lapack("scipy.linalg.cython_blas", "dtrsm", 11)
_dgemm = _lapack("scipy.linalg.cython_blas", "dgemm", 13)
_dgemv = _lapack("scipy.linalg.cython_blas", "dgemv", 11)
_dtrsv = _lapack("scipy.linalg.cython_blas", "dtrsv", 8)


# CHOLMOD's relaxed amalgamation (cholmod_super.c defaults): merge while the merged supernode has at most
# NRELAX[0] columns, or at most NRELAX[1] columns and a fraction of explicit zeros under ZRELAX[0], or at
# most NRELAX[2] columns and under ZRELAX[1], or any size under ZRELAX[2].
_NRELAX = (4, 16, 48)
# the most columns (gathered) and rows below (solved) of a panel one piece of the factorisation's work covers
# (fixed: the pieces, and so the factor's bits, do not depend on the thread count)
_COLUMNS_PER_TASK = 64
# a subtree costing at most this share of the whole factorisation is one thread's job
_SUBTREE_SHARE = 1.0 / 64
_ROWS_PER_TASK = 256
_ZRELAX = (0.8, 0.1, 0.05)


@jit
def permuted_pattern(n, Sp, Si, inv):
    """The lower triangle (Sp, Si, CSC) permuted (row ``i`` becomes ``inv[i]``): its transpose by rows
    (``Up``, ``Ui``: each column of the upper triangle, unsorted), and by columns with sorted rows (``Lp``,
    ``Li``) with each entry's index in the original (``source``)."""
    nnz = Si.shape[0]
    Up = np.zeros(n + 1, np.int64)
    Lp = np.zeros(n + 1, np.int64)
    for j in range(n):
        for p in range(Sp[j], Sp[j + 1]):
            a, b = inv[Si[p]], inv[j]
            Up[max(a, b) + 1] += 1
            Lp[min(a, b) + 1] += 1
    for k in range(n):
        Up[k + 1] += Up[k]
        Lp[k + 1] += Lp[k]
    Ui = np.empty(nnz, np.int64)
    Us = np.empty(nnz, np.int64)
    fill = Up[:-1].copy()
    for j in range(n):
        for p in range(Sp[j], Sp[j + 1]):
            a, b = inv[Si[p]], inv[j]
            row = max(a, b)
            Ui[fill[row]] = min(a, b)
            Us[fill[row]] = p
            fill[row] += 1
    # rows in increasing order give every column its rows sorted
    Li = np.empty(nnz, np.int64)
    source = np.empty(nnz, np.int64)
    fill = Lp[:-1].copy()
    for i in range(n):
        for q in range(Up[i], Up[i + 1]):
            c = Ui[q]
            Li[fill[c]] = i
            source[fill[c]] = Us[q]
            fill[c] += 1
    return Up, Ui, Lp, Li, source


@jit
def etree(n, Up, Ui):
    """The elimination tree (parent, -1 at roots) of the pattern whose upper triangle is (Up, Ui) in CSC
    (rows of each column in any order; entries on or below the diagonal are ignored)."""
    parent = np.full(n, -1, np.int64)
    ancestor = np.full(n, -1, np.int64)
    for k in range(n):
        for p in range(Up[k], Up[k + 1]):
            i = Ui[p]
            while i != -1 and i < k:
                nxt = ancestor[i]
                ancestor[i] = k
                if nxt == -1:
                    parent[i] = k
                i = nxt
    return parent


@jit
def _etree_postorder(n, Up, Ui):
    """The elimination tree of the pattern whose upper triangle is (Up, Ui) (:func:`etree`), and a
    postorder of it (children in increasing order, each subtree contiguous)."""
    parent = etree(n, Up, Ui)
    # children lists (head/next), built backwards so that each list is in increasing order
    head = np.full(n, -1, np.int64)
    nxt = np.full(n, -1, np.int64)
    for j in range(n - 1, -1, -1):
        if parent[j] != -1:
            nxt[j] = head[parent[j]]
            head[parent[j]] = j
    post = np.empty(n, np.int64)
    stack = np.empty(n, np.int64)
    k = 0
    for root in range(n):
        if parent[root] != -1:
            continue
        top = 0
        stack[0] = root
        while top >= 0:
            j = stack[top]
            child = head[j]
            if child == -1:
                top -= 1
                post[k] = j
                k += 1
            else:
                head[j] = nxt[child]
                top += 1
                stack[top] = child
    return parent, post


@jit
def column_counts(n, parent, Up, Ui, limit, weight):
    """Column counts (diagonal included) of the Cholesky factor of the pattern whose upper triangle is
    (Up, Ui), from its elimination tree ``parent``: each row's subtree walked up the tree.

    With ``weight`` (n,) int64, node ``j`` stands for ``weight[j]`` indistinguishable unknowns (the same
    neighbours, each other included, eliminated one after the other) and the count is of unknowns: the
    node's first unknown's column count, ``weight[j]`` plus the weights of the other nodes in its column of
    the factor; its next unknowns' are one less each. Ones for a plain pattern.

    Stops early, returning an empty array, as soon as ``sum c^2`` over the unknowns' columns (the
    factorisation's flops, up to a constant) must pass ``limit``, so that the count costs at most what
    the limit allows."""
    counts = weight.copy()
    mark = np.full(n, -1, np.int64)
    unknowns = 0.0
    entries = 0.0
    for j in range(n):
        unknowns += weight[j]
        entries += 0.5 * weight[j] * (weight[j] + 1)
    for k in range(n):
        mark[k] = k
        for p in range(Up[k], Up[k + 1]):
            i = Ui[p]
            while i < k and mark[i] != k:
                counts[i] += weight[k]
                entries += float(weight[i]) * float(weight[k])
                mark[i] = k
                i = parent[i]
        if entries * entries / unknowns > limit:  # sum c^2 >= (sum c)^2 / unknowns: already over
            return np.zeros(0, np.int64)
    return counts


def expanded_flops(counts: np.ndarray, weight: np.ndarray) -> float:
    """``sum c^2`` over the unknowns' column counts, from the nodes' :func:`column_counts` and weights."""
    W = counts.astype(np.float64)
    s = weight.astype(np.float64)
    return float(np.sum(s * W * W - W * s * (s - 1.0) + (s - 1.0) * s * (2.0 * s - 1.0) / 6.0))


@jit
def _supernodes(n, parent, counts, nrelax0, nrelax1, nrelax2, zrelax0, zrelax1, zrelax2):
    """Supernodes of a postordered tree: fundamental, then relaxed. Returns the first column of each
    supernode (``super_ptr``, length S + 1)."""
    children = np.zeros(n, np.int64)
    for j in range(n):
        if parent[j] != -1:
            children[parent[j]] += 1
    # fundamental: j + 1 continues j's supernode if it is j's parent, j its only child, and counts nest
    start = np.zeros(n + 1, np.int64)
    S = 0
    for j in range(n):
        if j > 0 and parent[j - 1] == j and children[j] == 1 and counts[j - 1] == counts[j] + 1:
            continue
        start[S] = j
        S += 1
    start[S] = n
    first = start[:S + 1].copy()
    # supernode tree
    sparent = np.full(S, -1, np.int64)
    of = np.empty(n, np.int64)
    for s in range(S):
        for j in range(first[s], first[s + 1]):
            of[j] = s
    for s in range(S):
        last = first[s + 1] - 1
        if parent[last] != -1:
            sparent[s] = of[parent[last]]
    ncols = np.empty(S, np.int64)
    nrows = np.empty(S, np.int64)  # rows of the supernode's first column (its columns included)
    zeros = np.zeros(S, np.float64)
    for s in range(S):
        ncols[s] = first[s + 1] - first[s]
        nrows[s] = counts[first[s]]
    # relaxed amalgamation: in postorder the last child of s ends right before s; merge it into s when
    # the zeros allow (as cholmod_super's relaxed merge of a supernode with its last child)
    merged = np.zeros(S, np.bool_)
    for s in range(1, S):
        c = s - 1  # the last child of s, if any (supernode c is not merged yet: merges go to c + 1)
        if sparent[c] != s:
            continue
        nscol = ncols[c] + ncols[s]
        # the merged supernode's first column has the child's columns plus the parent's rows
        total_rows = ncols[c] + nrows[s]
        lnz_merged = nscol * (nscol + 1) // 2 + nscol * (total_rows - nscol)
        lnz_c = ncols[c] * (ncols[c] + 1) // 2 + ncols[c] * (nrows[c] - ncols[c])
        lnz_s = ncols[s] * (ncols[s] + 1) // 2 + ncols[s] * (nrows[s] - ncols[s])
        new_zeros = zeros[c] + zeros[s] + (lnz_merged - lnz_c - lnz_s)
        z = new_zeros / lnz_merged
        if (nscol <= nrelax0 or (nscol <= nrelax1 and z < zrelax0) or (nscol <= nrelax2 and z < zrelax1)
                or z < zrelax2):
            merged[c] = True
            ncols[s] = nscol
            nrows[s] = total_rows
            zeros[s] = new_zeros
            first[s] = first[c]
    keep = 0
    for s in range(S):
        if not merged[s]:
            first[keep] = first[s]
            keep += 1
    first[keep] = n
    return first[:keep + 1].copy()


@jit
def _structure(n, super_ptr, Lp, Li):
    """Each supernode's rows below its columns (sorted), from the lower pattern (Lp, Li) and its children.
    Returns (rows_ptr, rows, sparent)."""
    S = super_ptr.shape[0] - 1
    of = np.empty(n, np.int64)
    for s in range(S):
        for j in range(super_ptr[s], super_ptr[s + 1]):
            of[j] = s
    mark = np.full(n, -1, np.int64)
    # pass 1: count with marks, keeping per-supernode row lists in a growing buffer
    rows_ptr = np.zeros(S + 1, np.int64)
    sparent = np.full(S, -1, np.int64)
    buf = np.empty(max(16, Lp[n]), np.int64)
    used = 0
    for s in range(S):
        lo, hi = super_ptr[s], super_ptr[s + 1]
        k = 0
        if used + n > buf.shape[0]:
            grown = np.empty(max(2 * buf.shape[0], used + n), np.int64)
            grown[:used] = buf[:used]
            buf = grown
        for j in range(lo, hi):
            for p in range(Lp[j], Lp[j + 1]):
                i = Li[p]
                if i >= hi and mark[i] != s:
                    mark[i] = s
                    buf[used + k] = i
                    k += 1
        rows_ptr[s + 1] = used + k
        used += k
    # children's rows: children come before parents, so fold each supernode's rows into its parent's list
    # (the parent is the supernode of the first row below it); repeated marking in a second pass
    final_ptr = np.zeros(S + 1, np.int64)
    out = np.empty(max(16, used), np.int64)
    out_used = 0
    child_head = np.full(S, -1, np.int64)
    child_next = np.full(S, -1, np.int64)
    mark[:] = -1
    for s in range(S):
        lo, hi = super_ptr[s], super_ptr[s + 1]
        if out_used + n > out.shape[0]:
            grown = np.empty(max(2 * out.shape[0], out_used + n), np.int64)
            grown[:out_used] = out[:out_used]
            out = grown
        k = 0
        for p in range(rows_ptr[s], rows_ptr[s + 1]):
            i = buf[p]
            mark[i] = s
            out[out_used + k] = i
            k += 1
        c = child_head[s]
        while c != -1:
            for p in range(final_ptr[c], final_ptr[c + 1]):
                i = out[p]
                if i >= hi and mark[i] != s:
                    mark[i] = s
                    out[out_used + k] = i
                    k += 1
            c = child_next[c]
        rows = out[out_used:out_used + k]
        rows.sort()
        final_ptr[s + 1] = out_used + k
        out_used += k
        if k > 0:
            sparent[s] = of[rows[0]]
            child_next[s] = child_head[sparent[s]]
            child_head[sparent[s]] = s
    return final_ptr, out[:out_used].copy(), sparent


@jit
def _updates(n, super_ptr, rows_ptr, rows):
    """For each supernode ``s``, the supernodes below it whose rows reach its columns, as (``d``, first and
    end index into ``d``'s rows below of the rows in ``s``'s columns): ``upd_ptr`` (S + 1), ``upd`` (U, 3);
    and the largest product a factorisation forms (rows x columns). Each supernode's list is in the order a
    left-looking factorisation meets them (fixed by the pattern, so the sums' order is too)."""
    S = super_ptr.shape[0] - 1
    of = np.empty(n, np.int64)
    for s in range(S):
        of[super_ptr[s]:super_ptr[s + 1]] = s
    head = np.full(S, -1, np.int64)
    nxt = np.full(S, -1, np.int64)
    at = np.zeros(S, np.int64)
    count = 0
    for s in range(S):
        nr = rows_ptr[s + 1] - rows_ptr[s]
        # every row below reaches one supernode's columns once per distinct supernode it passes
        count += nr
    upd = np.empty((count, 3), np.int64)
    upd_ptr = np.zeros(S + 1, np.int64)
    k = 0
    most = 0
    for s in range(S):
        hi = super_ptr[s + 1]
        d = head[s]
        while d != -1:
            dn = nxt[d]
            dr = rows_ptr[d]
            nd = rows_ptr[d + 1] - dr
            q0 = at[d]
            q1 = q0
            while q1 < nd and rows[dr + q1] < hi:
                q1 += 1
            upd[k, 0] = d
            upd[k, 1] = q0
            upd[k, 2] = q1
            k += 1
            size = (q1 - q0) * (nd - q0)
            if size > most:
                most = size
            at[d] = q1
            if q1 < nd:
                t = of[rows[dr + q1]]
                nxt[d] = head[t]
                head[t] = d
            d = dn
        upd_ptr[s + 1] = k
        if rows_ptr[s + 1] > rows_ptr[s]:
            t = of[rows[rows_ptr[s]]]
            nxt[s] = head[t]
            head[t] = s
    return upd_ptr, upd[:k].copy(), most


@jit
def _tasks(super_ptr, rows_ptr, columns_per_task, rows_per_task):
    """The factorisation's pieces of work, supernode by supernode (``node_ptr``: each one's range), as
    (supernode, kind, first, end) in ``tasks``: kind 0 gathers a block of at most ``columns_per_task`` of its
    columns (every row on or below the diagonal), kind 1 solves a block of at most ``rows_per_task`` of its
    rows below the diagonal block (positions in its panel). The split depends on the pattern alone."""
    S = super_ptr.shape[0] - 1
    node_ptr = np.zeros(S + 1, np.int64)
    for s in range(S):
        ns = super_ptr[s + 1] - super_ptr[s]
        nr = rows_ptr[s + 1] - rows_ptr[s]
        node_ptr[s + 1] = node_ptr[s] + (ns + columns_per_task - 1) // columns_per_task + (
            nr + rows_per_task - 1) // rows_per_task
    tasks = np.empty((node_ptr[S], 4), np.int64)
    k = 0
    for s in range(S):
        ns = super_ptr[s + 1] - super_ptr[s]
        m = ns + rows_ptr[s + 1] - rows_ptr[s]
        for c0 in range(0, ns, columns_per_task):
            tasks[k, 0] = s
            tasks[k, 1] = 0
            tasks[k, 2] = c0
            tasks[k, 3] = min(c0 + columns_per_task, ns)
            k += 1
        for g0 in range(ns, m, rows_per_task):
            tasks[k, 0] = s
            tasks[k, 1] = 1
            tasks[k, 2] = g0
            tasks[k, 3] = min(g0 + rows_per_task, m)
            k += 1
    return node_ptr, tasks


@jit
def _schedule(sparent, node_cost, threshold):
    """Where the work's parallelism lies. The subtrees whose whole cost is at most ``threshold`` (and whose
    parent's is not) are independent jobs, each a contiguous run of supernodes (a postorder), as ``jobs``
    (first, end) with their costs; the supernodes above them (``top``) are grouped by height among
    themselves (``level_ptr``), each level's supernodes depending only on earlier levels and jobs."""
    S = sparent.shape[0]
    first = np.arange(S)
    total = node_cost.copy()
    for s in range(S):
        p = sparent[s]
        if p != -1:
            total[p] += total[s]
            if first[s] < first[p]:
                first[p] = first[s]
    top = total > threshold
    jobs = np.empty((S, 2), np.int64)
    job_cost = np.empty(S)
    J = 0
    for s in range(S):
        if not top[s] and (sparent[s] == -1 or top[sparent[s]]):
            jobs[J, 0] = first[s]
            jobs[J, 1] = s + 1
            job_cost[J] = total[s]
            J += 1
    height = np.zeros(S, np.int64)
    for s in range(S):
        p = sparent[s]
        if top[s] and p != -1 and height[s] + 1 > height[p]:
            height[p] = height[s] + 1
    levels = 0
    for s in range(S):
        if top[s] and height[s] + 1 > levels:
            levels = height[s] + 1
    level_ptr = np.zeros(levels + 1, np.int64)
    for s in range(S):
        if top[s]:
            level_ptr[height[s] + 1] += 1
    for h in range(levels):
        level_ptr[h + 1] += level_ptr[h]
    fill = level_ptr[:-1].copy()
    nodes = np.empty(level_ptr[levels], np.int64)
    for s in range(S):
        if top[s]:
            nodes[fill[height[s]]] = s
            fill[height[s]] += 1
    return jobs[:J].copy(), job_cost[:J].copy(), level_ptr, nodes


@jit
def _first_at_least(a, lo, hi, value):
    """The first index in ``a[lo:hi]`` (sorted) whose value is at least ``value`` (``hi`` if none)."""
    while lo < hi:
        mid = (lo + hi) >> 1
        if a[mid] < value:
            lo = mid + 1
        else:
            hi = mid
    return lo


@jit
def _gather(s, c0, c1, super_ptr, rows_ptr, rows, upd_ptr, upd, Lp, Li, Lx, x_ptr, X, C, where, rmap):
    """Columns ``c0:c1`` of supernode ``s``'s panel (rows: its columns, then its rows below), on and below
    the diagonal: the matrix's entries, less the updates of the supernodes below it, in the order of its
    update list (``C``: each update's product, one ``dgemm``, then scattered, or written in place where its
    rows and columns are runs of the panel's)."""
    chars = np.empty(2, np.uint8)
    chars[0] = ord("N")
    chars[1] = ord("T")
    ints = np.empty(5, np.int32)
    scal = np.empty(3)
    scal[0] = 1.0
    scal[1] = 0.0
    scal[2] = -1.0
    lo, hi = super_ptr[s], super_ptr[s + 1]
    ns = hi - lo
    r0 = rows_ptr[s]
    nr = rows_ptr[s + 1] - r0
    m = ns + nr
    L = X[x_ptr[s]:x_ptr[s + 1]]
    for c in range(c0, c1):
        L[c * m + c0:(c + 1) * m] = 0.0
    for q in range(c0, m):
        where[lo + q if q < ns else rows[r0 + q - ns]] = q
    for j in range(lo + c0, lo + c1):
        col = (j - lo) * m
        for p in range(_first_at_least(Li, Lp[j], Lp[j + 1], lo + c0), Lp[j + 1]):
            L[col + where[Li[p]]] += Lx[p]
    for u in range(upd_ptr[s], upd_ptr[s + 1]):
        d = upd[u, 0]
        q0 = upd[u, 1]
        q1 = upd[u, 2]
        nsd = super_ptr[d + 1] - super_ptr[d]
        dr = rows_ptr[d]
        nd = rows_ptr[d + 1] - dr
        md = nsd + nd
        # d's rows in this block's columns (a contiguous range: every row list is sorted), and all of its
        # rows from there on
        i0 = _first_at_least(rows, dr + q0, dr + q1, lo + c0) - dr
        i1 = _first_at_least(rows, dr + i0, dr + q1, lo + c1) - dr
        if i1 <= i0:
            continue
        j0 = i0
        kc = i1 - i0
        kr = nd - j0
        Ld = X[x_ptr[d]:x_ptr[d + 1]]
        ints[0] = kr
        ints[1] = kc
        ints[2] = nsd
        ints[3] = md
        for ii in range(kr):
            rmap[ii] = where[rows[dr + j0 + ii]]
        if rmap[kr - 1] - rmap[0] == kr - 1 and rows[dr + i1 - 1] - rows[dr + i0] == kc - 1:
            # d's rows and columns are runs of s's: L[rows, columns] -= L_d[rows j0:j1] L_d[rows i0:i1]' in
            # place (entries above the diagonal block's diagonal are written too, and never read)
            ints[4] = m
            _dgemm(chars[0:].ctypes.data, chars[1:].ctypes.data, ints[0:].ctypes.data, ints[1:].ctypes.data,
                   ints[2:].ctypes.data, scal[2:].ctypes.data, Ld[nsd + j0:].ctypes.data, ints[3:].ctypes.data,
                   Ld[nsd + i0:].ctypes.data, ints[3:].ctypes.data, scal[0:].ctypes.data,
                   L[(rows[dr + i0] - lo) * m + rmap[0]:].ctypes.data, ints[4:].ctypes.data)
            continue
        # C (kr x kc) = L_d[rows j0:j1] L_d[rows i0:i1]', scattered
        _dgemm(chars[0:].ctypes.data, chars[1:].ctypes.data, ints[0:].ctypes.data, ints[1:].ctypes.data,
               ints[2:].ctypes.data, scal[0:].ctypes.data, Ld[nsd + j0:].ctypes.data, ints[3:].ctypes.data,
               Ld[nsd + i0:].ctypes.data, ints[3:].ctypes.data, scal[1:].ctypes.data, C.ctypes.data,
               ints[0:].ctypes.data)
        for jj in range(kc):
            base = (rows[dr + i0 + jj] - lo) * m
            cb = jj * kr
            for ii in range(jj, kr):  # on or below the diagonal only
                L[base + rmap[ii]] -= C[cb + ii]


@jit
def _pivot(s, super_ptr, rows_ptr, x_ptr, X):
    """Factor supernode ``s``'s diagonal block in place (``dpotrf``); 0, or the 1-based column (in the
    factorisation's order) of a non-positive pivot."""
    chars = np.empty(1, np.uint8)
    chars[0] = ord("L")
    ints = np.empty(2, np.int32)
    res = np.zeros(1, np.int32)
    lo = super_ptr[s]
    ns = super_ptr[s + 1] - lo
    ints[0] = ns
    ints[1] = ns + rows_ptr[s + 1] - rows_ptr[s]
    L = X[x_ptr[s]:x_ptr[s + 1]]
    _dpotrf(chars.ctypes.data, ints[0:].ctypes.data, L.ctypes.data, ints[1:].ctypes.data, res.ctypes.data)
    return 0 if res[0] == 0 else lo + res[0]


@jit
def _below(s, c0, c1, super_ptr, rows_ptr, x_ptr, X):
    """Rows ``c0:c1`` (below the diagonal block) of supernode ``s``'s panel solved against its factored
    diagonal block: ``L21 = A21 L11^-T`` (``dtrsm``)."""
    chars = np.empty(4, np.uint8)
    chars[0] = ord("R")
    chars[1] = ord("L")
    chars[2] = ord("T")
    chars[3] = ord("N")
    ints = np.empty(3, np.int32)
    scal = np.ones(1)
    ns = super_ptr[s + 1] - super_ptr[s]
    ints[0] = c1 - c0
    ints[1] = ns
    ints[2] = ns + rows_ptr[s + 1] - rows_ptr[s]
    L = X[x_ptr[s]:x_ptr[s + 1]]
    _dtrsm(chars[0:].ctypes.data, chars[1:].ctypes.data, chars[2:].ctypes.data, chars[3:].ctypes.data,
           ints[0:].ctypes.data, ints[1:].ctypes.data, scal.ctypes.data, L.ctypes.data, ints[2:].ctypes.data,
           L[c0:].ctypes.data, ints[2:].ctypes.data)


@jit
def _run_tasks(index, lo, hi, kind, tasks, super_ptr, rows_ptr, rows, upd_ptr, upd, Lp, Li, Lx, x_ptr, X, C,
               where, rmap):
    """The pieces ``tasks[index[lo:hi]]`` of the given kind (0 gather, 1 solve), in order."""
    for i in range(lo, hi):
        k = index[i]
        if tasks[k, 1] != kind:
            continue
        s = tasks[k, 0]
        if kind == 0:
            _gather(s, tasks[k, 2], tasks[k, 3], super_ptr, rows_ptr, rows, upd_ptr, upd, Lp, Li, Lx, x_ptr, X,
                    C, where, rmap)
        else:
            _below(s, tasks[k, 2], tasks[k, 3], super_ptr, rows_ptr, x_ptr, X)


@jit
def _pivot_nodes(lo, hi, nodes, super_ptr, rows_ptr, x_ptr, X, failed):
    """The diagonal blocks of supernodes ``nodes[lo:hi]`` factored; ``failed[s]``: 0 or a pivot's column."""
    for i in range(lo, hi):
        failed[nodes[i]] = _pivot(nodes[i], super_ptr, rows_ptr, x_ptr, X)


@jit
def _run_jobs(lo, hi, jobs, node_ptr, tasks, super_ptr, rows_ptr, rows, upd_ptr, upd, Lp, Li, Lx, x_ptr, X, C,
              where, rmap, failed):
    """Jobs ``lo:hi``: each a subtree's supernodes factored in order, each with all its pieces on this thread
    (a subtree stops at a non-positive pivot, ``failed``)."""
    for j in range(lo, hi):
        for s in range(jobs[j, 0], jobs[j, 1]):
            for k in range(node_ptr[s], node_ptr[s + 1]):
                if tasks[k, 1] == 0:
                    _gather(s, tasks[k, 2], tasks[k, 3], super_ptr, rows_ptr, rows, upd_ptr, upd, Lp, Li, Lx,
                            x_ptr, X, C, where, rmap)
            failed[s] = _pivot(s, super_ptr, rows_ptr, x_ptr, X)
            if failed[s] != 0:
                break
            for k in range(node_ptr[s], node_ptr[s + 1]):
                if tasks[k, 1] == 1:
                    _below(s, tasks[k, 2], tasks[k, 3], super_ptr, rows_ptr, x_ptr, X)


@jit
def _task_costs(tasks, super_ptr, rows_ptr, upd_ptr, upd):
    """A rough cost of each piece of work (the products' multiply-adds, plus its entries for the overheads),
    to hand out pieces of about equal cost to the threads."""
    cost = np.empty(tasks.shape[0])
    for k in range(tasks.shape[0]):
        s = tasks[k, 0]
        ns = super_ptr[s + 1] - super_ptr[s]
        m = ns + rows_ptr[s + 1] - rows_ptr[s]
        if tasks[k, 1] == 1:
            rows = tasks[k, 3] - tasks[k, 2]
            cost[k] = float(rows) * ns * ns + rows
            continue
        width = tasks[k, 3] - tasks[k, 2]
        rows = m - tasks[k, 2]
        total = 0.0
        for u in range(upd_ptr[s], upd_ptr[s + 1]):
            d = upd[u, 0]
            total += (super_ptr[d + 1] - super_ptr[d]) * min(width, upd[u, 2] - upd[u, 1])
        cost[k] = total * rows + float(rows) * width + (float(width) ** 3 if tasks[k, 2] == 0 else 0.0)
    return cost


@jit
def _solve(super_ptr, rows_ptr, rows, x_ptr, X, y, work):
    """``y <- L^-T L^-1 y`` in place (the permuted system), a supernode's block at a time (``dtrsv``,
    ``dgemv``); ``work`` holds the largest supernode's rows below."""
    S = super_ptr.shape[0] - 1
    chars = np.empty(3, np.uint8)
    chars[0] = ord("L")
    chars[1] = ord("N")
    chars[2] = ord("T")
    ints = np.empty(4, np.int32)
    ints[3] = 1
    scal = np.empty(3)
    scal[0] = 1.0
    scal[1] = 0.0
    scal[2] = -1.0
    for s in range(S):
        lo, hi = super_ptr[s], super_ptr[s + 1]
        ns = hi - lo
        r0 = rows_ptr[s]
        nr = rows_ptr[s + 1] - r0
        m = ns + nr
        L = X[x_ptr[s]:x_ptr[s + 1]]
        ints[0] = ns
        ints[1] = m
        ints[2] = nr
        # y1 <- L11^-1 y1; then y2 -= L21 y1
        _dtrsv(chars[0:].ctypes.data, chars[1:].ctypes.data, chars[1:].ctypes.data, ints[0:].ctypes.data,
               L.ctypes.data, ints[1:].ctypes.data, y[lo:].ctypes.data, ints[3:].ctypes.data)
        if nr > 0:
            _dgemv(chars[1:].ctypes.data, ints[2:].ctypes.data, ints[0:].ctypes.data, scal[0:].ctypes.data,
                   L[ns:].ctypes.data, ints[1:].ctypes.data, y[lo:].ctypes.data, ints[3:].ctypes.data,
                   scal[1:].ctypes.data, work.ctypes.data, ints[3:].ctypes.data)
            for q in range(nr):
                y[rows[r0 + q]] -= work[q]
    for s in range(S - 1, -1, -1):
        lo, hi = super_ptr[s], super_ptr[s + 1]
        ns = hi - lo
        r0 = rows_ptr[s]
        nr = rows_ptr[s + 1] - r0
        m = ns + nr
        L = X[x_ptr[s]:x_ptr[s + 1]]
        ints[0] = ns
        ints[1] = m
        ints[2] = nr
        # y1 -= L21' y2; then y1 <- L11^-T y1
        if nr > 0:
            for q in range(nr):
                work[q] = y[rows[r0 + q]]
            _dgemv(chars[2:].ctypes.data, ints[2:].ctypes.data, ints[0:].ctypes.data, scal[2:].ctypes.data,
                   L[ns:].ctypes.data, ints[1:].ctypes.data, work.ctypes.data, ints[3:].ctypes.data,
                   scal[0:].ctypes.data, y[lo:].ctypes.data, ints[3:].ctypes.data)
        _dtrsv(chars[0:].ctypes.data, chars[2:].ctypes.data, chars[1:].ctypes.data, ints[0:].ctypes.data,
               L.ctypes.data, ints[1:].ctypes.data, y[lo:].ctypes.data, ints[3:].ctypes.data)


@jit
def _take(Sx, source, values, lo, hi):
    for k in range(lo, hi):
        values[k] = Sx[source[k]]


class SupernodalCholesky:
    """Cholesky factorisation ``P A P' = L L'`` of symmetric positive definite matrices sharing one pattern.

    Parameters
    ----------
    Sp, Si : the lower triangle's pattern, CSC (sorted rows, diagonal present in every column)
    order : (n,) int, a fill-reducing permutation (row ``order[k]`` of ``A`` is row ``k`` of ``P A P'``);
        the analysis postorders its elimination tree, which changes neither the fill nor the flops
    """

    def __init__(self, Sp: np.ndarray, Si: np.ndarray, order: np.ndarray):
        n = len(Sp) - 1
        self.n = n
        nnz = len(Si)
        Sp, Si = np.asarray(Sp, dtype=np.int64), np.asarray(Si, dtype=np.int64)
        inv = np.empty(n, np.int64)
        inv[order] = np.arange(n)
        # the etree of the matrix permuted by order, to postorder it
        Up, Ui, _, _, _ = permuted_pattern(n, Sp, Si, inv)
        parent, post = _etree_postorder(n, Up, Ui)
        self.perm = np.asarray(order, dtype=np.int64)[post]  # postordered permutation
        inv[self.perm] = np.arange(n)
        # entry k of the permuted lower triangle (Lp, Li) is Sx[source[k]]
        Up, Ui, self.Lp, self.Li, self.source = permuted_pattern(n, Sp, Si, inv)
        parent, post = _etree_postorder(n, Up, Ui)
        self.counts = column_counts(n, parent, Up, Ui, np.inf, np.ones(n, np.int64))
        self.super_ptr = _supernodes(n, parent, self.counts, *_NRELAX, *_ZRELAX)
        self.rows_ptr, self.rows, self.sparent = _structure(n, self.super_ptr, self.Lp, self.Li)
        ns = np.diff(self.super_ptr)
        m = ns + np.diff(self.rows_ptr)
        self.x_ptr = np.concatenate([[0], np.cumsum(ns * m)]).astype(np.int64)
        self.X = np.zeros(int(self.x_ptr[-1]))  # (entries above a panel's diagonal are never read)
        self.upd_ptr, self.upd, most = _updates(n, self.super_ptr, self.rows_ptr, self.rows)
        self.node_ptr, self.tasks = _tasks(self.super_ptr, self.rows_ptr, _COLUMNS_PER_TASK, _ROWS_PER_TASK)
        cost = _task_costs(self.tasks, self.super_ptr, self.rows_ptr, self.upd_ptr, self.upd)
        node_cost = np.add.reduceat(cost, self.node_ptr[:-1]) if len(cost) else np.zeros(len(ns))
        self.jobs, job_cost, self.level_ptr, self.nodes = _schedule(self.sparent, node_cost,
                                                                    float(np.sum(cost)) * _SUBTREE_SHARE)
        parts = 4 * max(1, worker_count())  # how the pieces are handed out (not what they compute)
        self._job_runs = cost_ranges(job_cost, 0, len(job_cost), parts)
        # the pieces of the supernodes above the jobs, level by level
        self._index = np.concatenate([np.arange(self.node_ptr[t], self.node_ptr[t + 1]) for t in self.nodes]
                                     ).astype(np.int64) if len(self.nodes) else np.zeros(0, np.int64)
        level_tasks = np.cumsum(np.concatenate([[0], np.diff(self.node_ptr)[self.nodes]]))[self.level_ptr]
        self._level_runs = [cost_ranges(cost[self._index], int(level_tasks[h]), int(level_tasks[h + 1]), parts)
                            for h in range(len(self.level_ptr) - 1)]
        self._pivot_runs = [cost_ranges(np.ones(len(self.nodes)), int(self.level_ptr[h]), int(self.level_ptr[h + 1]),
                                  parts) for h in range(len(self.level_ptr) - 1)]
        widest = int(np.max(np.diff(self.rows_ptr), initial=0))
        self._c_size = max(1, min(int(most), _COLUMNS_PER_TASK * (widest + _COLUMNS_PER_TASK)))
        self._rmap_size = max(1, widest + _COLUMNS_PER_TASK)
        self._buffers = threading.local()
        self._failed = np.zeros(len(self.sparent), np.int64)
        self.flops = float(np.sum(ns * m.astype(np.float64) ** 2))
        self.values = np.empty(nnz)
        # the values gathered into the permuted order in equal ranges (a random read each: memory-bound)
        cuts = np.linspace(0, nnz, parts + 1).astype(np.int64)
        self._take_runs = [(int(a), int(b)) for a, b in zip(cuts[:-1], cuts[1:]) if b > a]
        self._work = np.empty(max(1, widest))

    def _scratch(self):
        """This thread's buffers for the gathering pieces (product, row positions, row map)."""
        b = self._buffers
        if getattr(b, "C", None) is None:
            b.C = np.empty(self._c_size)
            b.where = np.empty(self.n, np.int64)
            b.rmap = np.empty(self._rmap_size, np.int64)
        return b

    @property
    def supernodes(self) -> int:
        return len(self.super_ptr) - 1

    def factor(self, Sx: np.ndarray) -> None:
        """Factor the matrix with lower-triangle values ``Sx`` (in the pattern given at construction);
        raises ArithmeticError at a non-positive pivot."""
        run_ranges(lambda lo, hi: _take(Sx, self.source, self.values, lo, hi), self._take_runs)
        self.factor_values()

    def factor_values(self) -> None:
        """Factor the matrix whose permuted lower triangle (``Lp``, ``Li``) has the values ``self.values``
        (entry ``k`` is ``Sx[source[k]]``): :meth:`factor` after its gather, and a retry with those values
        changed."""
        with blas_pinned():
            self._factor_values()

    def _factor_values(self) -> None:
        self._failed[:] = 0
        args = (self.super_ptr, self.rows_ptr, self.rows, self.upd_ptr, self.upd, self.Lp, self.Li, self.values,
                self.x_ptr, self.X)

        def jobs(lo, hi):
            b = self._scratch()
            _run_jobs(lo, hi, self.jobs, self.node_ptr, self.tasks, *args, b.C, b.where, b.rmap, self._failed)

        def pieces(kind):
            def run(lo, hi):
                b = self._scratch()
                _run_tasks(self._index, lo, hi, kind, self.tasks, *args, b.C, b.where, b.rmap)
            return run

        run_ranges(jobs, self._job_runs)
        for h in range(len(self.level_ptr) - 1):
            if np.any(self._failed):
                break
            run_ranges(pieces(0), self._level_runs[h])
            run_ranges(lambda a, b: _pivot_nodes(a, b, self.nodes, self.super_ptr, self.rows_ptr, self.x_ptr,
                                                 self.X, self._failed), self._pivot_runs[h])
            if not np.any(self._failed):
                run_ranges(pieces(1), self._level_runs[h])
        bad = self._failed[self._failed != 0]
        if len(bad):
            raise ArithmeticError(f"non-positive pivot at column {int(bad.min())} of the factorisation's order")

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``A^-1 b`` from the factor."""
        y = np.asarray(b, dtype=np.float64)[self.perm]
        with blas_pinned():
            _solve(self.super_ptr, self.rows_ptr, self.rows, self.x_ptr, self.X, y, self._work)
        out = np.empty_like(y)
        out[self.perm] = y
        return out
