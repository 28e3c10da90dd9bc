"""Wavefront OBJ polylines as hairstyles: ``v`` vertices and ``l`` elements.

Each ``l`` element is one strand, in file order, even when it continues the
previous one (its first index equals the previous element's last). Indices
are 1-based, negative ones count back from the last ``v`` defined so far, and
``l 1/1 2/2`` texture forms are accepted (the texture index is ignored).
Numbers after x y z on a ``v`` line (RGB colours, w) are ignored. The body
mesh reader for ``.obj`` lives in :mod:`hairinv.formats.mesh` and shares
:func:`parse_obj`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError
from .base import check_strands, register_curves_reader, register_curves_writer, write_atomic


def parse_obj(path: Path, element: str, texture: bool = False):
    """Read the ``v`` lines and the ``element`` lines (``"l"`` or ``"f"``) of an OBJ file.

    Returns
    -------
    vertices : (V, 3) float64
        Positions of every ``v`` line, in file order.
    elements : list of (line number, 0-based vertex indices)
        One entry per ``element`` line; indices are checked to be in range.
    uvs : (N, 2) float64, only with ``texture``
        Every ``vt`` line's u and v, in file order.
    texture_indices : list of (0-based ``vt`` indices or None), only with ``texture``
        Per element, the texture index of each of its vertices (``f 1/4 2/5 3/6``), or None where the
        element names none for some vertex. Checked to be in range.
    """
    path = Path(path)
    text = path.read_bytes().decode("utf-8", errors="replace").replace("\\\r\n", " ").replace("\\\n", " ")
    coords: list[list[str]] = []
    uv_coords: list[list[str]] = []
    elements: list[tuple[int, list[int]]] = []
    texture_indices: list[list[int] | None] = []
    for number, line in enumerate(text.splitlines(), start=1):
        words = line.split()
        if not words:
            continue
        if words[0] == "v":
            if len(words) < 4:
                raise InputError(f"line {number} has a 'v' with fewer than three coordinates", path)
            coords.append(words[1:4])
        elif words[0] == "vt" and texture:
            if len(words) < 3:
                raise InputError(f"line {number} has a 'vt' with fewer than two coordinates", path)
            uv_coords.append(words[1:3])
        elif words[0] == element:
            n_defined = len(coords)
            indices, tex = [], []
            for token in words[1:]:
                head, _, rest = token.partition("/")
                try:
                    k = int(head)
                except ValueError:
                    raise InputError(f"line {number} has a malformed index {token!r}", path) from None
                k = k - 1 if k > 0 else n_defined + k
                if not 0 <= k < n_defined:
                    raise InputError(f"line {number} refers to vertex {head}, which is not defined before it", path)
                indices.append(k)
                if texture and tex is not None:
                    t_head = rest.partition("/")[0]
                    try:
                        t = int(t_head)
                    except ValueError:
                        tex = None  # no texture index on this vertex (f 1 2 3 or f 1//1 ...)
                        continue
                    t = t - 1 if t > 0 else len(uv_coords) + t
                    if not 0 <= t < len(uv_coords):
                        raise InputError(f"line {number} refers to texture vertex {t_head}, which is not defined "
                                         "before it", path)
                    tex.append(t)
            elements.append((number, indices))
            texture_indices.append(tex)
    try:
        vertices = np.array(coords, dtype=np.float64).reshape(-1, 3)
    except ValueError:
        bad = next(i for i, xyz in enumerate(coords) if not _numeric(xyz))
        raise InputError(f"vertex {bad + 1} has coordinates that are not numbers", path) from None
    if not texture:
        return vertices, elements
    try:
        uvs = np.array(uv_coords, dtype=np.float64).reshape(-1, 2)
    except ValueError:
        bad = next(i for i, uv in enumerate(uv_coords) if not _numeric(uv))
        raise InputError(f"texture vertex {bad + 1} has coordinates that are not numbers", path) from None
    return vertices, elements, uvs, texture_indices


def _numeric(words) -> bool:
    try:
        [float(w) for w in words]
    except ValueError:
        return False
    return True


@register_curves_reader(".obj")
def read_obj_curves(path: Path):
    """Read OBJ polylines, one strand per ``l`` element.

    Returns
    -------
    RawCurves
        ``points`` (P, 3) float64 in the file's units (vertices shared by
        several elements are repeated), ``offsets`` (S + 1,) int64,
        ``up="y"``.
    """
    path = Path(path)
    vertices, lines = parse_obj(path, "l")
    if not lines:
        raise InputError("has no polyline ('l') elements; is it a mesh?", path)
    counts = np.array([len(idx) for _, idx in lines], dtype=np.int64)
    offsets = np.zeros(len(lines) + 1, dtype=np.int64)
    np.cumsum(counts, out=offsets[1:])
    index = np.fromiter((k for _, idx in lines for k in idx), dtype=np.int64, count=int(offsets[-1]))
    raw = check_strands(vertices[index], offsets, path, "obj-lines")
    raw.up = "y"
    return raw


@register_curves_writer(".obj")
def write_obj_curves(path: Path, points, offsets, header=()) -> None:
    """Write strands as OBJ ``v`` lines and one ``l`` element per strand.

    Parameters
    ----------
    points : (P, 3) float
        Vertices, strand after strand (written with full float64 precision).
    offsets : (S + 1,) int
        CSR offsets; every strand needs at least 2 points.
    header : iterable of str
        Comment lines written after the first one (without the ``#``), e.g. the units and up axis.
    """
    path = Path(path)
    raw = check_strands(points, offsets, path, "obj-lines")
    counts = np.diff(raw.offsets)
    if np.any(counts < 2):
        s = int(np.argmax(counts < 2))
        raise InputError(f"has {int(counts[s])} points but an OBJ polyline needs at least 2", path, strand=s)
    out = ["# hairstyle written by hairinv: one 'l' element per strand, root first\n"]
    out += [f"# {line}\n" for text in header for line in str(text).splitlines()]
    out += [f"v {x!r} {y!r} {z!r}\n" for x, y, z in raw.points.tolist()]
    for a, b in zip(raw.offsets[:-1].tolist(), raw.offsets[1:].tolist()):
        out.append("l " + " ".join(map(str, range(a + 1, b + 1))) + "\n")
    write_atomic(path, "".join(out).encode())
