"""Orders of large arrays of keys: a stable least-significant-digit radix sort.

The contact search orders tens of millions of keys at a time (element pairs, lower bounds, distances).
numpy's comparison sorts take ``n log n`` steps; the radix sort takes one pass to count the digits and
one pass per digit of ``RADIX_BITS`` bits, skipping a digit that all keys share. Each pass moves every
key in the order of the pass before, so equal keys keep their order: the result is that of
``np.argsort(keys, kind="stable")``, bit for bit.
"""

from __future__ import annotations

import numpy as np

from ._jit import jit

__all__ = ["stable_order", "float_order"]

# Bits per pass: 2,048 counters fit the first-level cache with room for the keys streaming through.
RADIX_BITS = 11
# Below this many keys numpy's own sort is as fast (and nothing is compiled for it).
SMALL = 1 << 16


@jit
def _radix_order(keys, bits):
    """Indices that sort ``keys`` (int64, >= 0, below ``2**bits``), equal keys in their order."""
    n = keys.shape[0]
    size = 1 << RADIX_BITS
    mask = size - 1
    passes = max(1, (bits + RADIX_BITS - 1) // RADIX_BITS)
    counts = np.zeros((passes, size), np.int64)
    for i in range(n):
        k = keys[i]
        for p in range(passes):
            counts[p, (k >> (p * RADIX_BITS)) & mask] += 1
    order = np.arange(n)
    current = keys.copy()
    next_keys = np.empty(n, np.int64)
    next_order = np.empty(n, np.int64)
    start = np.empty(size, np.int64)
    for p in range(passes):
        shift = p * RADIX_BITS
        first = 0
        while counts[p, first] == 0:
            first += 1
        if counts[p, first] == n:
            continue  # every key has this digit: the pass would move nothing
        total = 0
        for d in range(size):
            start[d] = total
            total += counts[p, d]
        for i in range(n):
            d = (current[i] >> shift) & mask
            w = start[d]
            start[d] = w + 1
            next_keys[w] = current[i]
            next_order[w] = order[i]
        current, next_keys = next_keys, current
        order, next_order = next_order, order
    return order


def stable_order(keys: np.ndarray) -> np.ndarray:
    """Indices that sort integer keys >= 0, equal keys in their order: ``np.argsort(keys, kind="stable")``."""
    keys = np.ascontiguousarray(keys, dtype=np.int64)
    if len(keys) < SMALL:
        return np.argsort(keys, kind="stable")
    if keys.min() < 0:
        raise ValueError("stable_order takes keys >= 0")
    return _radix_order(keys, int(keys.max()).bit_length())


def float_order(values: np.ndarray) -> np.ndarray:
    """Indices that sort float64 values >= 0 (no NaN), equal values in their order.

    The bit patterns of non-negative doubles order as the values do (IEEE 754: sign, then exponent, then
    mantissa), so they are sorted as integers; ``-0.0`` is taken as ``0.0``.
    """
    values = np.ascontiguousarray(values, dtype=np.float64)
    if len(values) < SMALL:
        return np.argsort(values, kind="stable")
    if not np.all(values >= 0.0):
        raise ValueError("float_order takes values >= 0 and no NaN")
    return stable_order((values + 0.0).view(np.int64))
