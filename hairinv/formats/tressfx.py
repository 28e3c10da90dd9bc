"""AMD TressFX ``.tfx`` hairstyles (ASCII v1/v2, binary v3 and v4) and ``.tfxmesh`` bodies.

The variant is told from the first 4 bytes: float32 3.0 or 4.0 is a binary
file, text is an ASCII v1/v2 file, anything else is refused.

* ASCII: ``key value`` header lines (``version 2.0``, ``scale``,
  ``rotation``, ``translation``, ``bothEndsImmovable``, ``numStrands`` ...),
  then per strand ``strand <i> numVerts <n> texcoord <u> <v>`` and n lines
  ``x y z``. The texcoord text is often malformed and is not parsed.
* v3: 296-byte header (float version, uint32 numStrands,
  numVerticesPerStrand, numFollowHairsPerGuideHair, bothEndsImmovable, ...,
  byte offset of the vertices at byte 144), float3 positions.
* v4: 160-byte header (float version, uint32 numHairStrands,
  numVerticesPerStrand, byte offsets of vertexPosition and strandUV at bytes
  12 and 16), float4 positions whose w = 0 marks an immovable vertex.

All TressFX data is Y-up. ``scale/rotation/translation`` of ASCII files are
kept in ``extras`` but not applied.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from .._trimesh import load as load_trimesh
from ..errors import InputError
from .base import check_strands, register_curves_reader, register_mesh_reader

V3_HEADER_SIZE = 296
V4_HEADER_SIZE = 160


@register_curves_reader(".tfx")
def read_tfx(path: Path):
    """Read any supported TressFX ``.tfx`` variant.

    Returns
    -------
    RawCurves
        ``points`` (P, 3) float64 in the file's units, ``offsets`` (S + 1,)
        int64, ``up="y"``, ``format`` one of ``tressfx-v2`` (ASCII),
        ``tressfx-v3``, ``tressfx-v4`` (``tressfx-ascii`` without a version
        line). ``extras["pinned_tip"]`` (S,) bool
        for ASCII and v3 (``bothEndsImmovable``); ``extras["immovable"]``
        (P,) bool for v4 (w = 0).
    """
    path = Path(path)
    data = path.read_bytes()
    if len(data) < 4:
        raise InputError(f"is too short for a TressFX file ({len(data)} bytes)", path)
    version = float(np.frombuffer(data, "<f4", 1)[0])
    if version == 3.0:
        raw = _read_v3(data, path)
    elif version == 4.0:
        raw = _read_v4(data, path)
    elif _looks_like_text(data):
        raw = _read_ascii(data, path)
    else:
        raise InputError(f"unsupported TressFX version {version:g} (expected ASCII 1.x/2.x or binary 3.0/4.0)", path)
    raw.up = "y"
    return raw


def _looks_like_text(data: bytes) -> bool:
    head = data[:256]
    return all(32 <= b < 127 or b in (9, 10, 13) for b in head)


def _uniform_offsets(n_strands: int, n_verts: int) -> np.ndarray:
    return np.arange(n_strands + 1, dtype=np.int64) * n_verts


def _check_binary_size(data: bytes, path: Path, header: int, start: int, n_strands: int, n_verts: int, width: int):
    """Refuse a header whose strands x vertices run past the end of the file (before allocating)."""
    if len(data) < header:
        raise InputError(f"is too short for its {header}-byte header ({len(data)} bytes)", path)
    if n_verts == 0 or n_strands == 0:
        raise InputError(f"declares {n_strands} strands of {n_verts} vertices", path)
    if start < header or start % 4:
        raise InputError(f"has an invalid vertex array offset ({start})", path)
    end = start + n_strands * n_verts * 4 * width
    if end > len(data):
        raise InputError(
            f"is truncated: {n_strands} strands of {n_verts} vertices need {end} bytes but the file has {len(data)}",
            path,
        )


def _read_v3(data: bytes, path: Path):
    if len(data) < V3_HEADER_SIZE:
        raise InputError(f"is too short for a TressFX 3 header ({len(data)} of {V3_HEADER_SIZE} bytes)", path)
    n_strands, n_verts, _follow, both_ends = struct.unpack_from("<4I", data, 4)
    (start,) = struct.unpack_from("<I", data, 144)
    _check_binary_size(data, path, V3_HEADER_SIZE, start, n_strands, n_verts, 3)
    points = np.frombuffer(data, "<f4", 3 * n_strands * n_verts, start).reshape(-1, 3)
    raw = check_strands(points, _uniform_offsets(n_strands, n_verts), path, "tressfx-v3")
    raw.extras["pinned_tip"] = np.full(n_strands, bool(both_ends))
    return raw


def _read_v4(data: bytes, path: Path):
    if len(data) < V4_HEADER_SIZE:
        raise InputError(f"is too short for a TressFX 4 header ({len(data)} of {V4_HEADER_SIZE} bytes)", path)
    n_strands, n_verts, start, uv_start = struct.unpack_from("<4I", data, 4)
    _check_binary_size(data, path, V4_HEADER_SIZE, start, n_strands, n_verts, 4)
    xyzw = np.frombuffer(data, "<f4", 4 * n_strands * n_verts, start).reshape(-1, 4)
    raw = check_strands(xyzw[:, :3], _uniform_offsets(n_strands, n_verts), path, "tressfx-v4")
    raw.extras["immovable"] = xyzw[:, 3] == 0.0
    if uv_start and uv_start + 8 * n_strands <= len(data):  # optional: a bad offset only drops the UVs
        raw.extras["strand_uv"] = np.frombuffer(data, "<f4", 2 * n_strands, uv_start).reshape(-1, 2).astype(np.float64)
    return raw


def _read_ascii(data: bytes, path: Path):
    lines = data.decode("ascii", errors="replace").splitlines()
    header: dict[str, str] = {}
    i = 0
    while i < len(lines) and not lines[i].startswith("strand "):
        parts = lines[i].split(None, 1)
        if parts:
            header[parts[0]] = parts[1].strip() if len(parts) > 1 else ""
        i += 1
    version = header.get("version", "2.0")  # TressFX 1 files may lack the line
    try:
        major = float(version)
    except ValueError:
        major = -1.0
    if not 1.0 <= major < 3.0:
        raise InputError(f"unsupported TressFX version {version!r} in an ASCII file (expected 1.x or 2.x)", path)
    try:
        n_strands = int(header["numStrands"])
    except (KeyError, ValueError):
        raise InputError("has no valid 'numStrands' line in its ASCII header", path) from None
    if n_strands < 0:
        raise InputError(f"declares a negative number of strands ({n_strands})", path)

    counts, rows = [], []
    for s in range(n_strands):
        if i >= len(lines):
            raise InputError(f"is truncated: the header declares {n_strands} strands but the file ends", path, strand=s)
        words = lines[i].split()
        if len(words) < 4 or words[0] != "strand" or words[2] != "numVerts":
            raise InputError(f"line {i + 1} should start 'strand {s} numVerts'", path, strand=s)
        try:
            n = int(words[3])
        except ValueError:
            raise InputError(f"line {i + 1} has a malformed vertex count {words[3]!r}", path, strand=s) from None
        if n < 0:
            raise InputError(f"has a negative vertex count ({n})", path, strand=s)
        block = lines[i + 1 : i + 1 + n]
        if len(block) < n:
            raise InputError(f"is truncated: {n} vertices declared but only {len(block)} lines remain", path, strand=s)
        for k, line in enumerate(block):
            xyz = line.split()
            if len(xyz) != 3:
                raise InputError(f"line {i + 2 + k} should hold three coordinates", path, strand=s)
            rows.append(xyz)
        counts.append(n)
        i += 1 + n
    try:
        points = np.array(rows, dtype=np.float64).reshape(-1, 3)
    except ValueError:
        bad = next(k for k, r in enumerate(rows) if not _all_float(r))
        strand = int(np.searchsorted(np.cumsum(counts), bad, side="right"))
        raise InputError("has a vertex line that is not three numbers", path, strand=strand) from None
    offsets = np.zeros(n_strands + 1, dtype=np.int64)
    np.cumsum(counts, out=offsets[1:])
    fmt = f"tressfx-v{int(major)}" if "version" in header else "tressfx-ascii"
    raw = check_strands(points, offsets, path, fmt)
    raw.extras["pinned_tip"] = np.full(n_strands, header.get("bothEndsImmovable", "0").strip() not in ("0", ""))
    for key in ("scale", "rotation", "translation"):
        if key in header:
            raw.extras[key] = header[key]
    raw.extras["header"] = header
    return raw


def _all_float(words) -> bool:
    try:
        [float(w) for w in words]
    except ValueError:
        return False
    return True


@register_mesh_reader(".tfxmesh")
def read_tfxmesh(path: Path):
    """Read a TressFX 4 ASCII collision mesh (bones and normals are ignored).

    Returns
    -------
    trimesh.Trimesh
        ``vertices`` (V, 3) float64 in the file's units, ``faces`` (T, 3)
        int64, unprocessed.
    """
    trimesh = load_trimesh()

    path = Path(path)
    lines = [ln.split() for ln in path.read_text(errors="replace").splitlines()]
    lines = [w for w in lines if w and not w[0].startswith("#")]
    pos = 0

    def block(key: str, min_fields: int) -> list[list[str]]:
        nonlocal pos
        while pos < len(lines) and lines[pos][0] != key:
            pos += 1
        if pos == len(lines):
            raise InputError(f"has no '{key}' line", path)
        try:
            n = int(lines[pos][1])
        except (IndexError, ValueError):
            raise InputError(f"has a malformed '{key}' line", path) from None
        rows = lines[pos + 1 : pos + 1 + max(n, 0)]
        if n < 0 or len(rows) < n:
            raise InputError(f"declares {n} entries after '{key}' but has {len(rows)}", path)
        if any(len(r) < min_fields for r in rows):
            raise InputError(f"has an entry after '{key}' with fewer than {min_fields} fields", path)
        pos += 1 + n
        return rows

    block("numOfBones", 2)
    vert_rows = block("numOfVertices", 4)
    tri_rows = block("numOfTriangles", 4)
    try:
        vertices = np.array([r[1:4] for r in vert_rows], dtype=np.float64).reshape(-1, 3)
        faces = np.array([r[1:4] for r in tri_rows], dtype=np.int64).reshape(-1, 3)
    except ValueError:
        raise InputError("has a vertex or triangle line that is not numeric", path) from None
    if len(faces) == 0:
        raise InputError("has no triangles", path)
    if not np.isfinite(vertices).all():
        raise InputError("has vertex coordinates that are NaN or Inf", path)
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise InputError(f"has a triangle index outside 0..{len(vertices) - 1}", path)
    return trimesh.Trimesh(vertices, faces, process=False)
