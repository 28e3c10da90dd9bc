"""The interior point's rod-coordinate system ``I + G B^-1 G'``, laid out and assembled by blocks.

A contact's columns are, on each strand it touches, that strand's leading
coordinates (elements ``0..e`` of it: the rigid-downstream property, see
:mod:`.rows`). The coordinates are cut where any contact's run of
consecutive columns starts; between two cuts lies a *segment* (for the
rows' contacts, one strand or several consecutive ones: a run starts at
a strand's start). Each contact is then a few *pieces*, each
the leading columns of one segment, and its share of the system is
``g_p B_c g_q'`` for every ordered pair of its pieces ``(p, q)``, in the
*block* (segment of ``p``, segment of ``q``).

Within a block, column ``j`` holds the rows ``0 .. h_j - 1``, ``h_j`` the
widest row piece among the block's contacts whose column piece is wider
than ``j``: exactly the coordinates some contact touches together with
that column (the union of the contacts' rectangles, all anchored at the
segments' starts). These rows are one run of the lower-triangular CSC
pattern, so a contact's product is added into contiguous runs of the
values, with no map entry per coordinate pair (a contact of ``m`` columns
has ``m (m + 1) / 2``: 205 million on a 16,778-contact draped groom, whose
pattern holds 10.8 million entries), and the blocks own disjoint entries,
so they are assembled in parallel.
"""

from __future__ import annotations

import numpy as np

from .._jit import jit
from .._parallel import cost_ranges, run_ranges, worker_count

__all__ = ["BlockedSystem"]


@jit
def _cut(ptr, cols, n):
    """Segment starts (each run of consecutive columns of a contact starts one; ``0`` and ``n`` too) and
    each contact's pieces: ``piece_ptr`` (C + 1), and per piece its segment, first index into ``cols``
    and width."""
    starts = np.zeros(n + 1, np.bool_)
    starts[0] = True
    starts[n] = True
    for i in range(ptr.shape[0] - 1):
        for j in range(ptr[i], ptr[i + 1]):
            if j == ptr[i] or cols[j] != cols[j - 1] + 1:
                starts[cols[j]] = True
    seg_of = np.empty(n, np.int64)
    seg_start = np.empty(n + 1, np.int64)
    s = -1
    for c in range(n):
        if starts[c]:
            s += 1
            seg_start[s] = c
        seg_of[c] = s
    seg_start[s + 1] = n
    seg_start = seg_start[:s + 2].copy()
    piece_ptr = np.zeros(ptr.shape[0], np.int64)
    count = 0
    for i in range(ptr.shape[0] - 1):
        for j in range(ptr[i], ptr[i + 1]):
            if j == ptr[i] or cols[j] != cols[j - 1] + 1 or starts[cols[j]]:
                count += 1
        piece_ptr[i + 1] = count
    piece_seg = np.empty(count, np.int64)
    piece_at = np.empty(count, np.int64)
    piece_width = np.zeros(count, np.int64)
    k = -1
    for i in range(ptr.shape[0] - 1):
        for j in range(ptr[i], ptr[i + 1]):
            if j == ptr[i] or cols[j] != cols[j - 1] + 1 or starts[cols[j]]:
                k += 1
                piece_seg[k] = seg_of[cols[j]]
                piece_at[k] = j
            piece_width[k] += 1
    return seg_start, piece_ptr, piece_seg, piece_at, piece_width


@jit
def _terms(piece_ptr, piece_seg, n_segments):
    """Every ordered pair ``(p, q)`` of one contact's pieces whose block is on or below the diagonal (the
    segment of ``p`` at or after that of ``q``): contact, row piece, column piece, and the block's key
    ``segment(q) * n_segments + segment(p)`` (column segment first)."""
    count = 0
    for i in range(piece_ptr.shape[0] - 1):
        for p in range(piece_ptr[i], piece_ptr[i + 1]):
            for q in range(piece_ptr[i], piece_ptr[i + 1]):
                if piece_seg[p] >= piece_seg[q]:
                    count += 1
    contact = np.empty(count, np.int64)
    row = np.empty(count, np.int64)
    col = np.empty(count, np.int64)
    key = np.empty(count, np.int64)
    t = 0
    for i in range(piece_ptr.shape[0] - 1):
        for p in range(piece_ptr[i], piece_ptr[i + 1]):
            for q in range(piece_ptr[i], piece_ptr[i + 1]):
                if piece_seg[p] >= piece_seg[q]:
                    contact[t] = i
                    row[t] = p
                    col[t] = q
                    key[t] = piece_seg[q] * n_segments + piece_seg[p]
                    t += 1
    return contact, row, col, key


@jit
def _heights(term_ptr, row, col, piece_width):
    """Each block's width (its widest column piece) and its rows per column, ``h_j`` (flat, ``h_ptr``)."""
    nb = term_ptr.shape[0] - 1
    h_ptr = np.zeros(nb + 1, np.int64)
    for b in range(nb):
        w = 0
        for t in range(term_ptr[b], term_ptr[b + 1]):
            w = max(w, piece_width[col[t]])
        h_ptr[b + 1] = h_ptr[b] + w
    h = np.zeros(h_ptr[nb], np.int64)
    for b in range(nb):
        for t in range(term_ptr[b], term_ptr[b + 1]):
            wp = piece_width[row[t]]
            for j in range(piece_width[col[t]]):
                if h[h_ptr[b] + j] < wp:
                    h[h_ptr[b] + j] = wp
    return h_ptr, h


@jit
def _column_sizes(seg_start, block_ptr, block_row, h_ptr, h):
    """The lower-triangular CSC pattern's column pointers ``Sp``. ``block_ptr``: the blocks of each column
    segment, in order of row segment."""
    n = seg_start[-1]
    n_seg = seg_start.shape[0] - 1
    Sp = np.zeros(n + 1, np.int64)
    for s in range(n_seg):
        for j in range(seg_start[s + 1] - seg_start[s]):
            count = 0
            covered = False
            for b in range(block_ptr[s], block_ptr[s + 1]):
                w = h_ptr[b + 1] - h_ptr[b]
                if j >= w:
                    continue
                rows = h[h_ptr[b] + j]
                if block_row[b] == s:
                    if rows > j:
                        count += rows - j
                        covered = True
                else:
                    count += rows
            if not covered:
                count += 1
            c = seg_start[s] + j
            Sp[c + 1] = Sp[c] + count
    return Sp


@jit
def _pattern(seg_start, block_ptr, block_row, h_ptr, h, Sp):
    """The pattern's rows ``Si``, each block column's first position (for a diagonal block, that of its
    diagonal entry) and the diagonal entries no block covers."""
    n = seg_start[-1]
    n_seg = seg_start.shape[0] - 1
    Si = np.empty(Sp[n], np.int64)
    first = np.full(h_ptr[-1], -1, np.int64)
    lonely = np.empty(n, np.int64)
    n_lonely = 0
    for s in range(n_seg):
        for j in range(seg_start[s + 1] - seg_start[s]):
            c = seg_start[s] + j
            at = Sp[c]
            covered = False
            for b in range(block_ptr[s], block_ptr[s + 1]):
                if block_row[b] == s and j < h_ptr[b + 1] - h_ptr[b] and h[h_ptr[b] + j] > j:
                    covered = True
            if not covered:
                lonely[n_lonely] = at
                n_lonely += 1
                Si[at] = c
                at += 1
            for b in range(block_ptr[s], block_ptr[s + 1]):
                w = h_ptr[b + 1] - h_ptr[b]
                if j >= w:
                    continue
                rows = h[h_ptr[b] + j]
                r0 = seg_start[block_row[b]]
                lo = j if block_row[b] == s else 0
                if rows <= lo:
                    continue
                first[h_ptr[b] + j] = at
                for i in range(lo, rows):
                    Si[at] = r0 + i
                    at += 1
    return Si, first, lonely[:n_lonely].copy()


@jit
def _assemble(lo, hi, block_ptr_t, block_row, block_col, term_contact, term_row, term_col, piece_at, piece_width,
              h_ptr, h, first, g, Binv, Sx):
    """Blocks ``lo:hi`` of ``I + G Binv G'`` into ``Sx``: each block's entries zeroed (its diagonal set to
    one), then every term's ``g_p Binv_c g_q'`` added column by column into contiguous runs."""
    F = np.empty((3, 64))
    for b in range(lo, hi):
        diagonal = block_row[b] == block_col[b]
        for j in range(h_ptr[b + 1] - h_ptr[b]):
            at = first[h_ptr[b] + j]
            if at < 0:
                continue
            rows = h[h_ptr[b] + j] - (j if diagonal else 0)
            for i in range(rows):
                Sx[at + i] = 0.0
            if diagonal:
                Sx[at] = 1.0
        for t in range(block_ptr_t[b], block_ptr_t[b + 1]):
            c = term_contact[t]
            pa = piece_at[term_row[t]]
            wp = piece_width[term_row[t]]
            qa = piece_at[term_col[t]]
            wq = piece_width[term_col[t]]
            if wp > F.shape[1]:
                F = np.empty((3, wp))
            for i in range(wp):
                for k in range(3):
                    F[k, i] = g[pa + i, 0] * Binv[c, 0, k] + g[pa + i, 1] * Binv[c, 1, k] + g[pa + i, 2] * Binv[c, 2, k]
            for j in range(wq):
                g0 = g[qa + j, 0]
                g1 = g[qa + j, 1]
                g2 = g[qa + j, 2]
                at = first[h_ptr[b] + j]
                i0 = 0
                if diagonal:
                    i0 = j
                    at -= j
                for i in range(i0, wp):
                    Sx[at + i] += F[0, i] * g0 + F[1, i] * g1 + F[2, i] * g2


class EntriesOver(Exception):
    """The system's lower triangle would hold more entries than allowed (``args[0]``: how many)."""


class BlockedSystem:
    """The pattern of ``I + G B^-1 G'`` for contacts with columns ``cols[ptr[i]:ptr[i + 1]]`` among ``n``
    coordinates (in any order; a column repeated within a contact adds, as in ``G``), and its assembly.
    Raises :class:`EntriesOver` once the entries are counted, before they are laid out, if over ``max_entries``.

    Attributes: ``Sp``, ``Si`` (the lower triangle, CSC, rows sorted, the diagonal first in each column),
    ``entries`` (its length), ``blocks`` (their count).
    """

    def __init__(self, ptr: np.ndarray, cols: np.ndarray, n: int, max_entries: float = np.inf):
        ptr = np.ascontiguousarray(ptr, dtype=np.int64)
        cols = np.ascontiguousarray(cols, dtype=np.int64)
        seg_start, piece_ptr, piece_seg, self._piece_at, self._piece_width = _cut(ptr, cols, n)
        n_seg = len(seg_start) - 1
        contact, row, col, key = _terms(piece_ptr, piece_seg, n_seg)
        order = np.argsort(key, kind="stable")
        self._contact, self._row, self._col, key = contact[order], row[order], col[order], key[order]
        heads = np.flatnonzero(np.r_[True, key[1:] != key[:-1]]) if len(key) else np.zeros(0, np.int64)
        self._term_ptr = np.r_[heads, len(key)].astype(np.int64)
        block_key = key[heads]
        self._block_col = (block_key // max(n_seg, 1)).astype(np.int64)
        self._block_row = (block_key % max(n_seg, 1)).astype(np.int64)
        self._h_ptr, self._h = _heights(self._term_ptr, self._row, self._col, self._piece_width)
        column_blocks = np.searchsorted(self._block_col, np.arange(n_seg + 1)).astype(np.int64)
        self.Sp = _column_sizes(seg_start, column_blocks, self._block_row, self._h_ptr, self._h)
        self.entries = int(self.Sp[-1])
        if self.entries > max_entries:  # counted before the rows are laid out
            raise EntriesOver(self.entries)
        self.Si, self._first, self._lonely = _pattern(seg_start, column_blocks, self._block_row, self._h_ptr,
                                                      self._h, self.Sp)
        self.blocks = len(self._block_row)
        # the blocks in ranges of about equal work (multiply-adds), a few per worker
        work = np.zeros(self.blocks)
        if len(key):
            per_term = self._piece_width[self._row] * self._piece_width[self._col]
            work = np.add.reduceat(per_term.astype(np.float64), heads)
        self._ranges = cost_ranges(work, 0, len(work), 4 * worker_count())

    def assemble(self, g: np.ndarray, Binv: np.ndarray, Sx: np.ndarray) -> None:
        """``Sx`` (``entries``): the lower triangle of ``I + G Binv G'``, ``G`` by contact (``g``, as the
        rows' values), ``Binv`` (C, 3, 3) symmetric."""
        Sx[self._lonely] = 1.0

        def work(lo: int, hi: int) -> None:
            _assemble(lo, hi, self._term_ptr, self._block_row, self._block_col, self._contact, self._row,
                      self._col, self._piece_at, self._piece_width, self._h_ptr, self._h, self._first, g, Binv, Sx)

        run_ranges(work, self._ranges)

