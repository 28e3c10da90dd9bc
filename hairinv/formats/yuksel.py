"""Cem Yuksel's ``.hair`` files (cyHairFile), read and written.

Layout (little-endian): a 128-byte header (magic ``HAIR``, uint32 strand
count S, uint32 point count P, uint32 bit field of present arrays, uint32
default segment count, float default thickness, float default transparency,
3 floats default colour, 88 bytes of text), then, each only if its bit is
set: segments (S x uint16), points (P x 3 float), thickness (P float),
transparency (P float), colours (P x 3 float). Yuksel's models are Z-up.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from ..errors import InputError
from .base import check_strands, register_curves_reader, register_curves_writer, write_atomic

HEADER_SIZE = 128
_HEADER = struct.Struct("<4s4I2f3f88s")
BIT_SEGMENTS, BIT_POINTS, BIT_THICKNESS, BIT_TRANSPARENCY, BIT_COLOR = 1, 2, 4, 8, 16
MAX_POINTS_PER_STRAND = 65536  # segments are stored as uint16


@register_curves_reader(".hair")
def read_hair(path: Path):
    """Read a ``.hair`` file.

    Returns
    -------
    RawCurves
        ``points`` (P, 3) float64 in the file's units, ``offsets`` (S + 1,)
        int64, ``up="z"``. ``extras`` holds ``thickness`` (P,),
        ``transparency`` (P,) and ``color`` (P, 3) float64 when the file
        stores them, and ``info`` (str), the header text.
    """
    path = Path(path)
    data = path.read_bytes()
    size = len(data)
    if size < HEADER_SIZE:
        raise InputError(f"is too short for a .hair header ({size} of {HEADER_SIZE} bytes)", path)
    magic, n_strands, n_points, bits, default_segments, _thick, _transp, *_rgb, info = _HEADER.unpack_from(data)
    if magic != b"HAIR":
        raise InputError(f"does not start with the .hair magic 'HAIR' (found {magic!r})", path)
    if not bits & BIT_POINTS:
        raise InputError("has no points array (bit 2 of the header bit field is clear)", path)

    # Sizes are checked against the file length before anything is allocated.
    per_point = 12 + 4 * bool(bits & BIT_THICKNESS) + 4 * bool(bits & BIT_TRANSPARENCY) + 12 * bool(bits & BIT_COLOR)
    expected = HEADER_SIZE + (2 * n_strands if bits & BIT_SEGMENTS else 0) + per_point * n_points
    if expected > size:
        raise InputError(
            f"is truncated: the header declares {n_strands} strands and {n_points} points, "
            f"which need {expected} bytes, but the file has {size}",
            path,
        )
    if expected < size:
        raise InputError(f"has {size - expected} bytes after the arrays its header declares", path)

    pos = HEADER_SIZE
    if bits & BIT_SEGMENTS:
        counts = np.frombuffer(data, "<u2", n_strands, pos).astype(np.int64) + 1
        pos += 2 * n_strands
    else:
        counts = np.full(n_strands, int(default_segments) + 1, dtype=np.int64)
    offsets = np.zeros(n_strands + 1, dtype=np.int64)
    np.cumsum(counts, out=offsets[1:])
    if offsets[-1] != n_points:
        raise InputError(
            f"the strands' segment counts add up to {int(offsets[-1])} points but the header declares {n_points}",
            path,
        )
    points = np.frombuffer(data, "<f4", 3 * n_points, pos).reshape(-1, 3)
    pos += 12 * n_points
    raw = check_strands(points, offsets, path, "yuksel-hair")
    extras = raw.extras
    for bit, name, width in ((BIT_THICKNESS, "thickness", 1), (BIT_TRANSPARENCY, "transparency", 1), (BIT_COLOR, "color", 3)):
        if bits & bit:
            arr = np.frombuffer(data, "<f4", width * n_points, pos).astype(np.float64)
            extras[name] = arr.reshape(-1, 3) if width == 3 else arr
            pos += 4 * width * n_points
    extras["info"] = info.split(b"\0", 1)[0].decode("utf-8", errors="replace")
    raw.up = "z"
    return raw


@register_curves_writer(".hair")
def write_hair(path: Path, points, offsets, thickness=None, color=None, info: str = "") -> None:
    """Write strands to a ``.hair`` file (segments and points always stored).

    Parameters
    ----------
    points : (P, 3) float
        Vertices, strand after strand; stored as float32.
    offsets : (S + 1,) int
        CSR offsets; each strand must have at most 65536 points.
    thickness : float or (P,) float, optional
        A scalar becomes the header default; an array is stored per point.
    color : (3,) or (P, 3) float, optional
        A single RGB becomes the header default; an array is stored per point.
    info : str
        Free text, truncated to 88 bytes of UTF-8.
    """
    path = Path(path)
    raw = check_strands(points, offsets, path, "yuksel-hair")
    counts = np.diff(raw.offsets)
    too_long = np.flatnonzero(counts > MAX_POINTS_PER_STRAND)
    if too_long.size:
        s = int(too_long[0])
        raise InputError(
            f"has {int(counts[s])} points but a .hair strand holds at most {MAX_POINTS_PER_STRAND}", path, strand=s
        )
    if np.any(counts < 1):
        raise InputError("has no points but a .hair strand needs at least one", path, strand=int(np.argmax(counts < 1)))
    n_points = len(raw.points)
    bits = BIT_SEGMENTS | BIT_POINTS
    default_thickness, default_color = 1.0, (1.0, 1.0, 1.0)
    arrays = [(counts - 1).astype("<u2").tobytes(), raw.points.astype("<f4").tobytes()]
    if thickness is not None:
        t = np.asarray(thickness, dtype=np.float64)
        if t.ndim == 0:
            default_thickness = float(t)
        elif t.shape == (n_points,):
            bits |= BIT_THICKNESS
            arrays.append(t.astype("<f4").tobytes())
        else:
            raise InputError(f"thickness must be a number or one value per point, not shape {t.shape}", path)
    if color is not None:
        c = np.asarray(color, dtype=np.float64)
        if c.shape == (3,):
            default_color = tuple(float(x) for x in c)
        elif c.shape == (n_points, 3):
            bits |= BIT_COLOR
            arrays.append(c.astype("<f4").tobytes())
        else:
            raise InputError(f"color must be one RGB triple or one per point, not shape {c.shape}", path)
    text = info.encode("utf-8")[:88]
    header = _HEADER.pack(b"HAIR", len(counts), n_points, bits, 0, default_thickness, 0.0, *default_color, text)
    write_atomic(path, b"".join([header, *arrays]))

