"""USC-HairSalon ``.data`` files (also Hair20k, Digital Salon, CT2Hair), read and written.

Layout (little-endian): int32 strand count N, then N records, each an int32
point count n_i followed by n_i x 3 float32 (x, y, z), root first. Nothing
else, so the file size must be exactly ``4 + sum(4 + 12 * n_i)``. The USC
data is Y-up and roughly in metres, but the file does not say so.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from ..errors import InputError
from .base import check_strands, register_curves_reader, register_curves_writer, write_atomic

_INT = struct.Struct("<i")


@register_curves_reader(".data")
def read_usc(path: Path):
    """Read a USC-HairSalon ``.data`` file.

    Strands with 0 or 1 points are returned as they are (cleaning happens
    later).

    Returns
    -------
    RawCurves
        ``points`` (P, 3) float64 in the file's units, ``offsets`` (N + 1,)
        int64, ``up="y"``.
    """
    path = Path(path)
    data = path.read_bytes()
    size = len(data)
    if size < 4:
        raise InputError(f"is too short for a .data header ({size} of 4 bytes)", path)
    (n_strands,) = _INT.unpack_from(data, 0)
    if n_strands < 0:
        raise InputError(f"declares a negative number of strands ({n_strands})", path)
    # Every record needs at least its 4-byte count: fail fast on a corrupt header.
    if 4 + 4 * n_strands > size:
        raise InputError(
            f"declares {n_strands} strands but its {size} bytes can hold at most {(size - 4) // 4}", path
        )
    counts = np.empty(n_strands, dtype=np.int64)
    starts = np.empty(n_strands, dtype=np.int64)
    pos = 4
    for s in range(n_strands):
        if pos + 4 > size:
            raise InputError("is cut off before this strand's point count", path, strand=s)
        (n,) = _INT.unpack_from(data, pos)
        if n < 0:
            raise InputError(f"has a negative point count ({n})", path, strand=s)
        if pos + 4 + 12 * n > size:
            raise InputError(
                f"declares {n} points, which run {pos + 4 + 12 * n - size} bytes past the end of the file", path, strand=s
            )
        counts[s], starts[s] = n, pos + 4
        pos += 4 + 12 * n
    if pos != size:
        raise InputError(f"has {size - pos} bytes after its last strand", path)

    offsets = np.zeros(n_strands + 1, dtype=np.int64)
    np.cumsum(counts, out=offsets[1:])
    # Byte positions of every point's x, gathered in one vectorised step.
    point_start = np.repeat(starts - 12 * offsets[:-1], counts) + 12 * np.arange(offsets[-1])
    floats = np.frombuffer(data, "<f4", (size - 4) // 4, 4)  # view, no copy
    index = ((point_start - 4) // 4)[:, None] + np.arange(3)
    points = floats[index] if len(index) else np.zeros((0, 3))
    raw = check_strands(points, offsets, path, "usc-data")
    raw.up = "y"
    return raw


@register_curves_writer(".data")
def write_usc(path: Path, points, offsets) -> None:
    """Write strands to a USC-HairSalon ``.data`` file.

    Parameters
    ----------
    points : (P, 3) float
        Vertices, strand after strand; stored as float32.
    offsets : (S + 1,) int
        CSR offsets.
    """
    path = Path(path)
    raw = check_strands(points, offsets, path, "usc-data")
    counts = np.diff(raw.offsets)
    if counts.size and counts.max() > np.iinfo(np.int32).max // 12:
        s = int(np.argmax(counts))
        raise InputError(f"has {int(counts[s])} points, too many for a .data strand", path, strand=s)
    pts = raw.points.astype("<f4")
    parts = [_INT.pack(len(counts))]
    for s, n in enumerate(counts):
        parts.append(_INT.pack(int(n)))
        parts.append(pts[raw.offsets[s] : raw.offsets[s + 1]].tobytes())
    write_atomic(path, b"".join(parts))

