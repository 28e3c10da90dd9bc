"""Orders of large arrays of keys: a stable least-significant-digit radix sort.

The contact search orders tens of millions of keys at a time (element pairs, lower bounds, distances).
numpy's comparison sorts take ``n log n`` steps; the radix sort takes one pass to count the digits and
one pass per digit of ``RADIX_BITS`` bits, skipping a digit that all keys share. Each pass moves every
key in the order of the pass before, so equal keys keep their order: the result is that of
``np.argsort(keys, kind="stable")``, bit for bit.

Memory: besides the ``n`` keys given and the ``n`` indices returned, two passes take two more arrays of
``n`` 8-byte values (the keys in the first pass's order and that pass's indices) and three or more
passes three (24 bytes a key); no copy of the keys is made before the first pass.
"""

from __future__ import annotations

import numpy as np

from ._jit import jit

__all__ = ["stable_order", "float_order"]

# Bits per pass: 2,048 counters fit the first-level cache with room for the keys streaming through.
RADIX_BITS = 11
# Below this many keys numpy's own sort is as fast (and nothing is compiled for it).
SMALL = 1 << 16
# The bits a key is sorted by: all but the sign, which is clear for every key taken (and, for a double's
# bits, set only for -0.0, taken as 0.0)
VALUE_BITS = (1 << 63) - 1


@jit
def _radix_order(keys, bits):
    """Indices that sort ``keys`` (int64; below ``2**bits`` once the sign bit is cleared), equal keys in
    their order."""
    n = keys.shape[0]
    if n == 0:
        return np.empty(0, np.int64)
    size = 1 << RADIX_BITS
    mask = size - 1
    passes = max(1, (bits + RADIX_BITS - 1) // RADIX_BITS)
    counts = np.zeros((passes, size), np.int64)
    for i in range(n):
        k = keys[i] & VALUE_BITS
        for p in range(passes):
            counts[p, (k >> (p * RADIX_BITS)) & mask] += 1
    # the passes whose digit is not the same for every key: only these move anything
    moving = np.zeros(passes, np.int64)
    m = 0
    for p in range(passes):
        if counts[p, ((keys[0] & VALUE_BITS) >> (p * RADIX_BITS)) & mask] != n:
            moving[m] = p
            m += 1
    if m == 0:
        return np.arange(n)
    start = np.empty(size, np.int64)
    order = np.empty(n, np.int64)
    current = np.empty(n if m > 1 else 0, np.int64)  # the keys in the order of the last pass
    if m > 1:
        next_order = np.empty(n, np.int64)
        next_keys = np.empty(n if m > 2 else 0, np.int64)
    else:
        next_order = np.empty(0, np.int64)
        next_keys = np.empty(0, np.int64)
    for j in range(m):
        shift = moving[j] * RADIX_BITS
        total = 0
        for d in range(size):
            start[d] = total
            total += counts[moving[j], d]
        last = j == m - 1
        if j == 0:  # from the keys as given: the index is the position
            for i in range(n):
                k = keys[i] & VALUE_BITS
                d = (k >> shift) & mask
                w = start[d]
                start[d] = w + 1
                order[w] = i
                if not last:
                    current[w] = k
        else:
            for i in range(n):
                k = current[i]
                d = (k >> shift) & mask
                w = start[d]
                start[d] = w + 1
                next_order[w] = order[i]
                if not last:
                    next_keys[w] = k
            order, next_order = next_order, order
            current, next_keys = next_keys, current
    return order


def stable_order(keys: np.ndarray) -> np.ndarray:
    """Indices that sort integer keys >= 0, equal keys in their order: ``np.argsort(keys, kind="stable")``."""
    keys = np.asarray(keys)
    if not (np.issubdtype(keys.dtype, np.integer) or keys.dtype == np.bool_):
        raise TypeError(f"stable_order takes integer keys, not {keys.dtype}")
    if len(keys) and keys.min() < 0:
        raise ValueError("stable_order takes keys >= 0")
    if len(keys) and int(keys.max()) > VALUE_BITS:
        raise ValueError("stable_order takes keys below 2**63")
    if len(keys) < SMALL:
        return np.argsort(keys, kind="stable").astype(np.int64, copy=False)
    keys = np.ascontiguousarray(keys, dtype=np.int64)
    return _radix_order(keys, int(keys.max()).bit_length())


def float_order(values: np.ndarray) -> np.ndarray:
    """Indices that sort float64 values >= 0 (no NaN), equal values in their order.

    The bit patterns of non-negative doubles order as the values do (IEEE 754: sign, then exponent, then
    mantissa), so they are sorted as integers with the sign bit cleared: ``-0.0`` is taken as ``0.0``.
    """
    values = np.ascontiguousarray(values, dtype=np.float64)
    if not np.all(values >= 0.0):
        raise ValueError("float_order takes values >= 0 and no NaN")
    if len(values) < SMALL:
        return np.argsort(values, kind="stable")
    top = np.float64(abs(values.max())).view(np.int64)  # abs: the largest may be -0.0 where all are zeros
    return _radix_order(values.view(np.int64), int(top).bit_length())
