"""Hair-hair proximity: spatial hashing of sampled segments, then closest points on the centerlines.

Each element's samples form ``n - 1`` segments. A segment's box is its
endpoints' box inflated by ``r = hair_distance / 2 + sag``, where ``sag`` bounds
how far the element's arc strays from its chord (``kappa h^2 / 8`` for the
element's centerline curvature ``kappa = |(kappa1, kappa2)|`` and sample spacing
``h``), so two boxes that do not overlap hold no pair of centerline points
closer than ``hair_distance``. Boxes are hashed into a uniform grid (Teschner
et al. 2003) whose cell is about the size of a typical box; the grid keys are
exact cell coordinates (no hash collisions), sorted, and each pair of boxes is
tested once, in the cell holding the low corner of their overlap; within a cell
the boxes are swept along their narrowest axis (sort and sweep), so a box meets
only those that overlap it on that axis. Pairs on the same strand are never
tested. The search gives the closest segment pair of each pair of elements;
:func:`refine_pairs` refines it on the exact centerlines (Gauss-Newton on the
squared distance, the step solved as a segment-segment problem on the
tangents so it stays inside the elements), for the pairs whose distance the
caller needs (hairinv.contacts.detect).
"""

from __future__ import annotations

import numpy as np

from .._jit import jit
from .._parallel import run_chunks, worker_count
from .._sorting import stable_order
from ._curve import point_tangent

__all__ = ["segment_closest", "hair_pairs", "refine_pairs", "pair_points", "element_sag", "polyline_slack"]

# Grid cell over the median inflated segment box (Teschner et al. suggest about one box). CPU s of the pair
# search on 20,000 synthetic strands x 10 elements for 0.5/0.75/1/1.5/2/3: 3.2/2.1/1.9/2.0/2.3/3.0.
CELL_FACTOR = 1.0
# Grid cells a segment's box enters, on average, beyond which the grid is coarsened (by 2 at a time): boxes of
# one size enter 1-8 each; a search with a per-element reach sizes its cells for the median box, and a few
# boxes thousands of times wider (a strand whipped 0.2 m in a step) would enter millions each.
CELL_ENTRIES = 27
# Gauss-Newton steps of the refinement; it converges in 2-4 from the polyline solution.
REFINE_STEPS = 12
# The refinement stops when a step moves the arc lengths by less than this fraction of the elements' lengths
# (3e-8 m on 3 cm elements: far below a hair's radius; the distance is then exact to its square).
STEP_TOLERANCE = 1e-6
# Step halvings tried before a refinement step is given up.
HALVINGS = 8
# Segments whose angle has a sine below this are taken as parallel by segment_closest (the general formula
# loses its digits there).
PARALLEL_SINE = 1e-7


@jit
def segment_closest(p1, q1, p2, q2):
    """Closest points of segments ``p1 q1`` and ``p2 q2`` (Ericson, Real-Time Collision Detection, 5.1.9).

    Returns ``(u, v, d2)``: the parameters in [0, 1] along each segment (0 and
    1 exactly when clamped) and the squared distance. Parallel segments (within an angle of sine
    ``PARALLEL_SINE``) take ``u = 0`` where the first segment's start projects inside the second: the
    distance may then exceed the least by up to that sine times the longer segment (:func:`polyline_slack`).
    """
    d10, d11, d12 = q1[0] - p1[0], q1[1] - p1[1], q1[2] - p1[2]
    d20, d21, d22 = q2[0] - p2[0], q2[1] - p2[1], q2[2] - p2[2]
    r0, r1, r2 = p1[0] - p2[0], p1[1] - p2[1], p1[2] - p2[2]
    a = d10 * d10 + d11 * d11 + d12 * d12
    e = d20 * d20 + d21 * d21 + d22 * d22
    f = d20 * r0 + d21 * r1 + d22 * r2
    if a <= 0.0 and e <= 0.0:
        u = 0.0
        v = 0.0
    elif a <= 0.0:
        u = 0.0
        v = min(max(f / e, 0.0), 1.0)
    else:
        c = d10 * r0 + d11 * r1 + d12 * r2
        if e <= 0.0:
            v = 0.0
            u = min(max(-c / a, 0.0), 1.0)
        else:
            b = d10 * d20 + d11 * d21 + d12 * d22
            denom = a * e - b * b
            # (nearly) parallel: the solution is a segment of equally close pairs; take u = 0
            u = min(max((b * f - c * e) / denom, 0.0), 1.0) if denom > PARALLEL_SINE * PARALLEL_SINE * a * e else 0.0
            v = (b * u + f) / e
            if v < 0.0:
                v = 0.0
                u = min(max(-c / a, 0.0), 1.0)
            elif v > 1.0:
                v = 1.0
                u = min(max((b - c) / a, 0.0), 1.0)
    x0 = p1[0] + u * d10 - p2[0] - v * d20
    x1 = p1[1] + u * d11 - p2[1] - v * d21
    x2 = p1[2] + u * d12 - p2[2] - v * d22
    return u, v, x0 * x0 + x1 * x1 + x2 * x2


@jit
def _segment_boxes(samples, radius, lo, hi):
    """Inflated boxes (M, 3) of the segments ``m = e (n - 1) + k`` between samples k and k + 1 of element e."""
    n = samples.shape[1]
    for e in range(samples.shape[0]):
        for k in range(n - 1):
            m = e * (n - 1) + k
            for i in range(3):
                a = samples[e, k, i]
                b = samples[e, k + 1, i]
                lo[m, i] = min(a, b) - radius[e]
                hi[m, i] = max(a, b) + radius[e]


@jit
def _cell(x, origin, inv_cell):
    return np.int64(np.floor((x - origin) * inv_cell))


@jit
def _count_cells(lo, hi, origin, inv_cell, counts):
    for m in range(lo.shape[0]):
        c = 1
        for i in range(3):
            c *= _cell(hi[m, i], origin[i], inv_cell) - _cell(lo[m, i], origin[i], inv_cell) + 1
        counts[m] = c


@jit
def _fill_cells(lo, hi, origin, inv_cell, shift_i, shift_j, seg_bits, starts, packed):
    """``packed[w] = key << seg_bits | m`` for every cell ``key`` that segment ``m``'s box overlaps."""
    for m in range(lo.shape[0]):
        i0 = _cell(lo[m, 0], origin[0], inv_cell)
        j0 = _cell(lo[m, 1], origin[1], inv_cell)
        k0 = _cell(lo[m, 2], origin[2], inv_cell)
        i1 = _cell(hi[m, 0], origin[0], inv_cell)
        j1 = _cell(hi[m, 1], origin[1], inv_cell)
        k1 = _cell(hi[m, 2], origin[2], inv_cell)
        w = starts[m]
        for i in range(i0, i1 + 1):
            for j in range(j0, j1 + 1):
                for k in range(k0, k1 + 1):
                    packed[w] = (((i << shift_i) | (j << shift_j) | k) << seg_bits) | m
                    w += 1


@jit
def _best_per_pair(order, pair_key, dist2, first, second):
    """Index of the closest hit of each run of equal ``pair_key`` (in ``order``); ties to the lowest segments."""
    out = np.empty(order.shape[0], np.int64)
    count = 0
    x = 0
    while x < order.shape[0]:
        best = order[x]
        y = x + 1
        while y < order.shape[0] and pair_key[order[y]] == pair_key[best]:
            h = order[y]
            if (dist2[h] < dist2[best] or (dist2[h] == dist2[best] and (first[h] < first[best] or (
                    first[h] == first[best] and second[h] < second[best])))):
                best = h
            y += 1
        out[count] = best
        count += 1
        x = y
    return out[:count]


@jit
def _grow(a, size):
    out = np.empty(size, a.dtype)
    out[:a.shape[0]] = a
    return out


@jit
def _pairs_in_cells(run_start, r0, r1, keys, segs, lo, hi, radius, strand_of, wide, samples, origin, inv_cell,
                    shift_i, shift_j):
    """Close segment pairs of the cells ``r0:r1``, each pair tested once (in the cell of its overlap's low corner),
    of elements on different strands at least one of which is ``wide``.

    Each cell's boxes are copied out in the order of their low sides along the
    axis where they are narrowest, and swept: a box meets only the boxes after
    it whose low side is below its high side (sweep and prune, within the cell).
    A pair is the cell's when, on each axis, one of the two low sides lies in
    it. Cells without a ``wide`` element are skipped.

    Returns ``(count, first, second, d2, u, v)``: segment indices with the
    lower strand first, squared polyline distance and segment parameters.
    """
    n1 = samples.shape[1] - 1
    cap = 1024
    first = np.empty(cap, np.int64)
    second = np.empty(cap, np.int64)
    dist2 = np.empty(cap)
    pu = np.empty(cap)
    pv = np.empty(cap)
    count = 0
    mask_j = (np.int64(1) << (shift_i - shift_j)) - 1
    mask_k = (np.int64(1) << shift_j) - 1
    longest = 0
    for r in range(r0, r1):
        longest = max(longest, run_start[r + 1] - run_start[r])
    # the cell's boxes, sorted along the sweep axis: contiguous, so the inner loop reads memory in order
    blo = np.empty((longest, 3))
    bhi = np.empty((longest, 3))
    bseg = np.empty(longest, np.int64)
    bstrand = np.empty(longest, np.int64)
    bwide = np.empty(longest, np.bool_)
    bown = np.empty(longest, np.int64)  # bit d: the box's low side on axis d lies in this cell
    sweep = np.empty(longest)
    cell = np.empty(3, np.int64)
    width = np.empty(3)
    for r in range(r0, r1):
        a = run_start[r]
        b = run_start[r + 1]
        m = b - a
        if m < 2:
            continue
        any_wide = False
        for x in range(a, b):
            if wide[segs[x] // n1]:
                any_wide = True
                break
        if not any_wide:
            continue
        key = keys[a]
        cell[0] = key >> shift_i
        cell[1] = (key >> shift_j) & mask_j
        cell[2] = key & mask_k
        width[:] = 0.0
        for x in range(a, b):
            i = segs[x]
            for d in range(3):
                width[d] += hi[i, d] - lo[i, d]
        ax = 0
        for d in range(1, 3):
            if width[d] < width[ax]:
                ax = d
        for x in range(m):
            sweep[x] = lo[segs[a + x], ax]
        order = np.argsort(sweep[:m])
        for t in range(m):
            i = segs[a + order[t]]
            own = 0
            for d in range(3):
                blo[t, d] = lo[i, d]
                bhi[t, d] = hi[i, d]
                if _cell(lo[i, d], origin[d], inv_cell) == cell[d]:
                    own |= 1 << d
            bseg[t] = i
            bstrand[t] = strand_of[i // n1]
            bwide[t] = wide[i // n1]
            bown[t] = own
        # the overlap's low corner is max(lo) per axis; along the sweep axis that is the later box's low side,
        # so the later box of a pair of this cell is one whose low side is in it: the sorted suffix from `inside`
        inside = 0
        while inside < m and not (bown[inside] & (1 << ax)):
            inside += 1
        for x in range(m):
            i = bseg[x]
            si = bstrand[x]
            top = bhi[x, ax]
            for y in range(max(x + 1, inside), m):
                if blo[y, ax] > top:
                    break
                sj = bstrand[y]
                if si == sj or not (bwide[x] or bwide[y]) or (bown[x] | bown[y]) != 7:
                    continue
                if (blo[x, 0] > bhi[y, 0] or blo[y, 0] > bhi[x, 0] or blo[x, 1] > bhi[y, 1] or blo[y, 1] > bhi[x, 1]
                        or blo[x, 2] > bhi[y, 2] or blo[y, 2] > bhi[x, 2]):
                    continue
                j = bseg[y]
                ei = i // n1
                ej = j // n1
                if si < sj:
                    sa, sb = i, j
                    ea, eb = ei, ej
                else:
                    sa, sb = j, i
                    ea, eb = ej, ei
                ka = sa - ea * n1
                kb = sb - eb * n1
                u, v, d2 = segment_closest(samples[ea, ka], samples[ea, ka + 1], samples[eb, kb], samples[eb, kb + 1])
                limit = radius[ea] + radius[eb]
                if d2 >= limit * limit:
                    continue
                if count == cap:
                    cap *= 2
                    first = _grow(first, cap)
                    second = _grow(second, cap)
                    dist2 = _grow(dist2, cap)
                    pu = _grow(pu, cap)
                    pv = _grow(pv, cap)
                first[count] = sa
                second[count] = sb
                dist2[count] = d2
                pu[count] = u
                pv[count] = v
                count += 1
    return count, first[:count], second[:count], dist2[:count], pu[:count], pv[:count]


@jit
def _distance_at(ea, a, eb, b, xs, Fs, omega, xa, ta, xb, tb, R, P, Q):
    point_tangent(xs[ea], Fs[ea], omega[ea], a, R, P, Q, xa, ta)
    point_tangent(xs[eb], Fs[eb], omega[eb], b, R, P, Q, xb, tb)
    return np.sqrt((xa[0] - xb[0]) ** 2 + (xa[1] - xb[1]) ** 2 + (xa[2] - xb[2]) ** 2)


@jit
def refine_pairs(lo, hi, elem_a, elem_b, sigma_a, sigma_b, xs, Fs, omega, length, dist):
    """Closest points of the centerlines of element pairs ``lo:hi``, from the polyline solution.

    Each step solves the segment-segment problem between the tangent lines
    at the current points, spanning each element's arc-length range, so the
    new arc lengths stay in ``[0, length]`` (exactly the bound when clamped);
    a step that does not reduce the distance is halved, at most HALVINGS times.

    ``sigma_a``, ``sigma_b`` (P,) are updated in place and ``dist`` (P,) is
    written; the closest points and tangents are :func:`pair_points` at the
    new arc lengths (the same evaluation, so the same values), computed
    only for the pairs kept: a dense head has many times more candidates.
    """
    R = np.empty((3, 3))
    P = np.empty(3)
    Q = np.empty(3)
    xa = np.empty(3)
    xb = np.empty(3)
    ta = np.empty(3)
    tb = np.empty(3)
    ya = np.empty(3)
    yb = np.empty(3)
    sa_ = np.empty(3)
    sb_ = np.empty(3)
    p1 = np.empty(3)
    q1 = np.empty(3)
    p2 = np.empty(3)
    q2 = np.empty(3)
    for p in range(lo, hi):
        ea = elem_a[p]
        eb = elem_b[p]
        la = length[ea]
        lb = length[eb]
        a = sigma_a[p]
        b = sigma_b[p]
        d = _distance_at(ea, a, eb, b, xs, Fs, omega, xa, ta, xb, tb, R, P, Q)
        for _ in range(REFINE_STEPS):
            for i in range(3):
                p1[i] = xa[i] - a * ta[i]
                q1[i] = xa[i] + (la - a) * ta[i]
                p2[i] = xb[i] - b * tb[i]
                q2[i] = xb[i] + (lb - b) * tb[i]
            u, v, _d2 = segment_closest(p1, q1, p2, q2)
            na = la if u >= 1.0 else u * la
            nb = lb if v >= 1.0 else v * lb
            if na == a and nb == b:
                break
            accepted = False
            for _h in range(HALVINGS):
                dn = _distance_at(ea, na, eb, nb, xs, Fs, omega, ya, sa_, yb, sb_, R, P, Q)
                if dn < d:
                    accepted = True
                    break
                na = 0.5 * (a + na)
                nb = 0.5 * (b + nb)
            if not accepted:
                break
            moved = abs(na - a) + abs(nb - b)
            a = na
            b = nb
            d = dn
            for i in range(3):
                xa[i] = ya[i]
                xb[i] = yb[i]
                ta[i] = sa_[i]
                tb[i] = sb_[i]
            if moved <= STEP_TOLERANCE * (la + lb):
                break
        sigma_a[p] = a
        sigma_b[p] = b
        dist[p] = d


@jit
def pair_points(lo, hi, elem_a, elem_b, sigma_a, sigma_b, xs, Fs, omega, point_a, point_b, tangent_a, tangent_b):
    """Centerline points and unit tangents (P, 3) of element pairs ``lo:hi`` at arc lengths ``sigma_*``."""
    R = np.empty((3, 3))
    P = np.empty(3)
    Q = np.empty(3)
    for p in range(lo, hi):
        point_tangent(xs[elem_a[p]], Fs[elem_a[p]], omega[elem_a[p]], sigma_a[p], R, P, Q, point_a[p], tangent_a[p])
        point_tangent(xs[elem_b[p]], Fs[elem_b[p]], omega[elem_b[p]], sigma_b[p], R, P, Q, point_b[p], tangent_b[p])


def element_sag(omega: np.ndarray, length: np.ndarray, n: int) -> np.ndarray:
    """(E,) m: how far an element's centre line strays from the chords between its ``n`` samples.

    An arc of curvature ``kappa`` and length ``h`` lies within ``kappa h^2 / 8`` of its chord (the
    circle's sagitta bounds it), and never farther than ``h / 2``.
    """
    spacing = length / (n - 1)
    return np.minimum(np.hypot(omega[:, 0], omega[:, 1]) * spacing**2 / 8.0, 0.5 * spacing)


def polyline_slack(length: np.ndarray, n: int) -> np.ndarray:
    """(E,) m: how far :func:`segment_closest` may overstate the distance from one of an element's segments
    (``n`` samples) to another segment, for the element's share: on segments nearly parallel it takes one end
    of the first, where the distance may be larger, by at most the angle's sine (``PARALLEL_SINE``) times
    the longer segment (twice that here, for the rounding of the angle's test). A pair's polyline gap
    exceeds the polylines' least distance by at most the sum of its two elements' values."""
    return 2.0 * PARALLEL_SINE * length / (n - 1)


def hair_pairs(samples: np.ndarray, omega: np.ndarray, length: np.ndarray, strand_of: np.ndarray,
               hair_distance, wide: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                                       np.ndarray, np.ndarray, int]:
    """Closest segment pair of every pair of elements (on different strands) whose polylines may be close.

    Parameters
    ----------
    samples : (E, n, 3) float64, m, centerline samples of every element
    omega : (E, 3) float64, 1/m
    length : (E,) float64, m
    strand_of : (E,) int64, strand of each element
    hair_distance : float, or (E,) float64 per element, m: a pair of elements is searched to the mean of
        their two values (to the value itself when it is one float)
    wide : (E,) bool, optional: only pairs with at least one of these elements (default: every pair)

    Returns
    -------
    elem_a, elem_b : (P,) int64, element pairs, ``strand_of[elem_a] < strand_of[elem_b]``, sorted
    sigma_a, sigma_b : (P,) float64, m, arc lengths along the elements of the closest polyline points
    gap : (P,) float64, m, the polylines' distance there; the centre lines' own closest points are at least
        ``gap - sag[elem_a] - sag[elem_b] - slack[elem_a] - slack[elem_b]`` apart (:func:`element_sag`,
        :func:`polyline_slack`; a search that must find every pair of centre lines within a reach searches
        that much farther)
    close : int, segment pairs found within reach (before keeping one per element pair)
    """
    count, n = samples.shape[0], samples.shape[1]
    n1 = n - 1
    spacing = length / n1
    sag = element_sag(omega, length, n)
    radius = np.ascontiguousarray(0.5 * np.asarray(hair_distance, dtype=np.float64) + sag)
    segments = count * n1
    empty = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0), np.zeros(0), np.zeros(0), 0)
    if segments == 0 or len(np.unique(strand_of)) < 2:
        return empty
    wide = np.ones(count, dtype=np.bool_) if wide is None else np.ascontiguousarray(wide, dtype=np.bool_)
    lo = np.empty((segments, 3))
    hi = np.empty((segments, 3))
    _segment_boxes(samples, radius, lo, hi)
    origin = lo.min(axis=0)
    extent = hi.max(axis=0) - origin
    # Cell about a typical box (Teschner et al.): a box then spans 1-2 cells per axis.
    cell = max(CELL_FACTOR * float(np.median(np.max(hi - lo, axis=1))), float(np.min(hair_distance)))
    # key = (i, j, k) packed with just the bits the grid needs, and the segment index below it: one plain
    # sort of int64 instead of an argsort (measured 5x faster, gathers included, on 6.6 million entries).
    # A grid too fine to pack (strands metres apart), or whose boxes would enter more than CELL_ENTRIES cells
    # each on average (a few boxes far wider than the median), is coarsened: slower, never wrong.
    seg_bits = max(1, int(segments - 1).bit_length())
    cells = np.empty(segments, np.int64)
    while True:
        inv_cell = 1.0 / cell
        dims = np.floor(extent * inv_cell).astype(np.int64) + 1  # as _cell computes the largest index
        bits = [max(1, int(d - 1).bit_length()) for d in dims]
        if sum(bits) + seg_bits <= 63:
            _count_cells(lo, hi, origin, inv_cell, cells)
            if int(cells.sum()) <= CELL_ENTRIES * segments:
                break
        cell *= 2.0
    shift_j, shift_i = bits[2], bits[1] + bits[2]
    starts = np.concatenate([[0], np.cumsum(cells)]).astype(np.int64)
    packed = np.empty(starts[-1], np.int64)
    _fill_cells(lo, hi, origin, inv_cell, shift_i, shift_j, seg_bits, starts, packed)
    packed.sort()
    keys = packed >> seg_bits
    segs = packed & ((np.int64(1) << seg_bits) - 1)
    del packed
    run_start = np.concatenate([[0], np.flatnonzero(np.diff(keys)) + 1, [len(keys)]]).astype(np.int64)
    # chunks of cells with about equal work (pairs per cell), so threads finish together
    size = np.diff(run_start).astype(np.float64)
    work = np.cumsum(size * (size - 1) / 2 + 1)
    chunks = max(1, min(len(size), 8 * worker_count()))
    bounds = np.searchsorted(work, work[-1] * np.arange(1, chunks) / chunks, side="right")
    bounds = np.unique(np.concatenate([[0], bounds, [len(size)]])).astype(np.int64)
    results: dict[int, tuple] = {}

    def best(first, second, dist2, pu, pv):
        """The closest segment pair of each element pair (ties to the lowest segments), sorted by element pair."""
        pair_key = (first // n1) * count + second // n1
        # _best_per_pair breaks ties itself, so any order of equal keys will do
        keep = _best_per_pair(stable_order(pair_key), pair_key, dist2, first, second)
        return first[keep], second[keep], dist2[keep], pu[keep], pv[keep]

    def pairs_chunk(lo_c: int, hi_c: int) -> None:
        for c in range(lo_c, hi_c):
            found = _pairs_in_cells(run_start, bounds[c], bounds[c + 1], keys, segs, lo, hi, radius,
                                    strand_of, wide, samples, origin, inv_cell, shift_i, shift_j)
            # each chunk keeps its best segment pair per element pair, so memory holds element pairs, not
            # the (many times more) segment pairs of dense grooms; the best of the bests is the best
            results[c] = (found[0], *best(*found[1:]))

    run_chunks(pairs_chunk, len(bounds) - 1, 1)
    parts = [results.pop(c) for c in range(len(bounds) - 1)]
    close = sum(int(p[0]) for p in parts)
    first, second, dist2, pu, pv = (np.concatenate([p[k] for p in parts]) for k in range(1, 6))
    del parts
    if len(first) == 0:
        return empty
    first, second, dist2, pu, pv = best(first, second, dist2, pu, pv)
    ea = first // n1
    eb = second // n1
    ka, kb = first - ea * n1, second - eb * n1
    sigma_a = np.minimum((ka + pu) * spacing[ea], length[ea])
    sigma_b = np.minimum((kb + pv) * spacing[eb], length[eb])
    # a clamped end of the last segment is exactly the element's end
    sigma_a = np.where((ka == n1 - 1) & (pu >= 1.0), length[ea], sigma_a)
    sigma_b = np.where((kb == n1 - 1) & (pv >= 1.0), length[eb], sigma_b)
    return ea, eb, sigma_a, sigma_b, np.sqrt(dist2), close
