"""Format readers and writers on small hand-built files: decoded values, round trips, bad input."""

from __future__ import annotations

import re
import struct
import time

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hairinv.errors import InputError
from hairinv.formats import read_curves, read_mesh, write_curves
from hairinv.formats.tressfx import read_tfx, read_tfxmesh
from hairinv.formats.usc import read_usc
from hairinv.formats.yuksel import read_hair, write_hair


def fails(path, *fragments: str, strand: int | None = None):
    """``pytest.raises`` for an InputError naming ``path`` (and ``strand``) and containing ``fragments``."""
    pattern = re.escape(path.name) + ": "
    if strand is not None:
        pattern += f"strand {strand}: "
    pattern += "".join(".*" + re.escape(f) for f in fragments)
    return pytest.raises(InputError, match=pattern)


# --------------------------------------------------------------------------- Yuksel .hair


def hair_header(n_strands, n_points, bits, default_segments=0, info=b"") -> bytes:
    return struct.pack("<4s4I2f3f88s", b"HAIR", n_strands, n_points, bits, default_segments, 1.0, 0.0, 1, 1, 1, info)


def test_hair_all_arrays(tmp_path):
    pts = np.arange(15, dtype=np.float32).reshape(5, 3) * 0.5
    body = (
        struct.pack("<2H", 1, 2)  # 2 + 3 points
        + pts.tobytes()
        + struct.pack("<5f", 0.1, 0.2, 0.3, 0.4, 0.5)
        + struct.pack("<5f", 0, 0, 0.25, 0.5, 1)
        + np.full((5, 3), 0.75, np.float32).tobytes()
    )
    path = tmp_path / "a.hair"
    path.write_bytes(hair_header(2, 5, 1 | 2 | 4 | 8 | 16, info=b"hello") + body)
    raw = read_curves(path)
    assert raw.format == "yuksel-hair" and raw.up == "z"
    assert raw.offsets.tolist() == [0, 2, 5]
    assert np.array_equal(raw.points, pts.astype(np.float64))
    assert np.allclose(raw.extras["thickness"], [0.1, 0.2, 0.3, 0.4, 0.5])
    assert raw.extras["transparency"].tolist() == [0, 0, 0.25, 0.5, 1]
    assert raw.extras["color"].shape == (5, 3) and np.all(raw.extras["color"] == 0.75)
    assert raw.extras["info"] == "hello"


def test_hair_default_segments(tmp_path):
    pts = np.arange(18, dtype=np.float32).reshape(6, 3)
    path = tmp_path / "b.hair"
    path.write_bytes(hair_header(2, 6, 2, default_segments=2) + pts.tobytes())
    raw = read_hair(path)
    assert raw.offsets.tolist() == [0, 3, 6]
    assert "thickness" not in raw.extras and "color" not in raw.extras
    assert np.array_equal(raw.points, pts)


def test_hair_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    pts = rng.normal(size=(9, 3)).astype(np.float32).astype(np.float64)
    off = np.array([0, 1, 4, 9])
    thick = np.linspace(0.1, 0.9, 9).astype(np.float32)
    color = rng.random((9, 3)).astype(np.float32)
    path = tmp_path / "rt.hair"
    write_curves(path, pts, off, thickness=thick, color=color, info="written by a test")
    raw = read_curves(path)
    assert raw.offsets.tolist() == off.tolist()
    assert np.array_equal(raw.points, pts)
    assert np.array_equal(raw.extras["thickness"], thick.astype(np.float64))
    assert np.array_equal(raw.extras["color"], color.astype(np.float64))
    assert raw.extras["info"] == "written by a test"
    # scalar thickness and one colour go to the header defaults: no per-point arrays
    write_hair(path, pts, off, thickness=0.5, color=(1, 0, 0))
    raw = read_hair(path)
    assert "thickness" not in raw.extras and "color" not in raw.extras
    assert not list(tmp_path.glob(".*tmp"))


def test_hair_bad_inputs(tmp_path):
    pts = np.zeros((3, 3), np.float32)
    good = hair_header(1, 3, 3) + struct.pack("<H", 2) + pts.tobytes()
    path = tmp_path / "bad.hair"

    path.write_bytes(b"HAIX" + good[4:])
    with fails(path, "magic"):
        read_hair(path)
    path.write_bytes(good[:-4])
    with fails(path, "truncated"):
        read_hair(path)
    path.write_bytes(good[:100])
    with fails(path, "too short"):
        read_hair(path)
    path.write_bytes(good + b"\0\0\0\0")
    with fails(path, "bytes after"):
        read_hair(path)
    path.write_bytes(hair_header(1, 3, 1) + struct.pack("<H", 2))
    with fails(path, "no points array"):
        read_hair(path)
    path.write_bytes(hair_header(1, 3, 3) + struct.pack("<H", 1) + pts.tobytes())
    with fails(path, "add up to 2 points", "declares 3"):
        read_hair(path)
    nan = np.zeros((5, 3), np.float32)
    nan[3, 1] = np.nan
    path.write_bytes(hair_header(2, 5, 3) + struct.pack("<2H", 1, 2) + nan.tobytes())
    with fails(path, "NaN or Inf", strand=1):
        read_hair(path)
    # a header claiming 2^32 - 1 strands fails at once, without allocating
    path.write_bytes(hair_header(2**32 - 1, 2**32 - 1, 3) + b"\0" * 64)
    t0 = time.perf_counter()
    with fails(path, "truncated"):
        read_hair(path)
    assert time.perf_counter() - t0 < 0.5
    with fails(path, "65536", strand=1):
        write_hair(path, np.zeros((65538, 3)), [0, 1, 65538])


# --------------------------------------------------------------------------- USC .data


def usc_bytes(strands, n_override=None) -> bytes:
    out = struct.pack("<i", len(strands) if n_override is None else n_override)
    for s in strands:
        s = np.asarray(s, np.float32).reshape(-1, 3)
        out += struct.pack("<i", len(s)) + s.tobytes()
    return out


def test_usc_values_and_short_strands(tmp_path):
    a = [[1, 2, 3], [4, 5, 6], [7, 8, 9.5]]
    path = tmp_path / "h.data"
    path.write_bytes(usc_bytes([a, [], [[0.25, 0, -1]], [[1, 1, 1], [2, 2, 2]]]))
    raw = read_curves(path)
    assert raw.format == "usc-data" and raw.up == "y" and raw.scale_to_m is None
    assert raw.offsets.tolist() == [0, 3, 3, 4, 6]
    assert raw.points.tolist() == a + [[0.25, 0, -1], [1, 1, 1], [2, 2, 2]]


def test_usc_round_trip(tmp_path):
    rng = np.random.default_rng(1)
    pts = rng.normal(size=(12, 3)).astype(np.float32).astype(np.float64)
    off = np.array([0, 5, 6, 6, 12])
    path = tmp_path / "rt.data"
    write_curves(path, pts, off)
    assert path.stat().st_size == 4 + 4 * 4 + 12 * 12
    raw = read_curves(path)
    assert raw.offsets.tolist() == off.tolist() and np.array_equal(raw.points, pts)


def test_usc_bad_inputs(tmp_path):
    path = tmp_path / "bad.data"
    one = [[0, 0, 0], [1, 1, 1]]

    path.write_bytes(usc_bytes([one]) + struct.pack("<i", -3))
    with fails(path, "bytes after"):
        read_usc(path)
    path.write_bytes(usc_bytes([one, one], n_override=-1))
    with fails(path, "negative number of strands"):
        read_usc(path)
    data = bytearray(usc_bytes([one, one, one]))
    struct.pack_into("<i", data, 4 + 28, -2)  # strand 1's count
    path.write_bytes(bytes(data))
    with fails(path, "negative point count", strand=1):
        read_usc(path)
    data = bytearray(usc_bytes([one, one, one]))
    struct.pack_into("<i", data, 4 + 28 + 28, 1000)  # strand 2's count runs past the end
    path.write_bytes(bytes(data))
    with fails(path, "past the end", strand=2):
        read_usc(path)
    path.write_bytes(usc_bytes([one, one])[:-5])
    with fails(path, "past the end", strand=1):
        read_usc(path)
    path.write_bytes(b"\x01\x00")
    with fails(path, "too short"):
        read_usc(path)
    path.write_bytes(usc_bytes([one, [[0, np.inf, 0], [1, 1, 1]]]))
    with fails(path, "NaN or Inf", strand=1):
        read_usc(path)
    # 2^31 - 1 strands claimed by a 20-byte file: refused at once
    path.write_bytes(usc_bytes([[[1, 2, 3]]], n_override=2**31 - 1))
    t0 = time.perf_counter()
    with fails(path, "declares 2147483647 strands"):
        read_usc(path)
    assert time.perf_counter() - t0 < 0.5


def test_empty_and_missing_files(tmp_path):
    for name in ("e.hair", "e.data", "e.tfx", "e.obj", "e.usda"):
        path = tmp_path / name
        path.write_bytes(b"")
        with fails(path, "empty"):
            read_curves(path)
    path = tmp_path / "e.ply"
    path.write_bytes(b"")
    with fails(path, "empty"):
        read_mesh(path)
    with fails(tmp_path / "missing.data", "no such file"):
        read_curves(tmp_path / "missing.data")
    path = tmp_path / "x.abc"
    path.write_bytes(b"abc")
    with fails(path, "unknown hairstyle file type"):
        read_curves(path)


# --------------------------------------------------------------------------- TressFX .tfx

ASCII_TFX = """version 2.0
scale 1.0
rotation 0 0 0
translation 0 1 0
bothEndsImmovable 1
maxNumVerticesInStrand 3
numFollowHairsPerGuideHair 4
maxRadiusAroundGuideHair 1.5
numStrands 2
is sorted 1
strand 0 numVerts 3 texcoord 0.000000 000000
1 2 3
4 5 6
7 8 9
strand 1 numVerts 3 texcoord 0.5 junk
-1 -2 -3
-4.5 -5 -6
-7 -8 1e2
"""


def test_tfx_ascii(tmp_path):
    path = tmp_path / "a.tfx"
    path.write_text(ASCII_TFX)
    raw = read_curves(path)
    assert raw.format == "tressfx-v2" and raw.up == "y"
    assert raw.offsets.tolist() == [0, 3, 6]
    assert raw.points.tolist() == [[1, 2, 3], [4, 5, 6], [7, 8, 9], [-1, -2, -3], [-4.5, -5, -6], [-7, -8, 100]]
    assert raw.extras["pinned_tip"].tolist() == [True, True]
    assert raw.extras["translation"] == "0 1 0"  # kept, not applied
    path.write_text(ASCII_TFX.replace("bothEndsImmovable 1", "bothEndsImmovable 0"))
    assert read_tfx(path).extras["pinned_tip"].tolist() == [False, False]


def test_tfx_ascii_bad(tmp_path):
    path = tmp_path / "bad.tfx"
    path.write_text(ASCII_TFX.replace("version 2.0", "version 5.0"))
    with fails(path, "unsupported TressFX version"):
        read_tfx(path)
    path.write_text(ASCII_TFX.replace("numStrands 2", "numStrands 3"))
    with fails(path, "truncated", strand=2):
        read_tfx(path)
    path.write_text(ASCII_TFX.rsplit("\n", 2)[0] + "\n")  # last vertex line gone
    with fails(path, "truncated", strand=1):
        read_tfx(path)
    path.write_text(ASCII_TFX.replace("-4.5 -5 -6", "-4.5 nan -6"))
    with fails(path, "NaN or Inf", strand=1):
        read_tfx(path)
    path.write_text(ASCII_TFX.replace("-4.5 -5 -6", "-4.5 five -6"))
    with fails(path, "not three numbers", strand=1):
        read_tfx(path)
    path.write_text(ASCII_TFX.replace("-4.5 -5 -6", "-4.5 -5"))
    with fails(path, "three coordinates", strand=1):
        read_tfx(path)
    path.write_text(ASCII_TFX.replace("numVerts 3 texcoord 0.5", "numVerts -3 texcoord 0.5"))
    with fails(path, "negative vertex count", strand=1):
        read_tfx(path)
    path.write_text(ASCII_TFX.replace("numStrands 2\n", ""))
    with fails(path, "numStrands"):
        read_tfx(path)


def tfx_v3(pts, n_strands, n_verts, both_ends=0, vertex_offset=296) -> bytes:
    head = bytearray(296)
    struct.pack_into("<f4I", head, 0, 3.0, n_strands, n_verts, 4, both_ends)
    struct.pack_into("<6I", head, 144, vertex_offset, 0, 0, 0, 0, 0)
    return bytes(head) + np.asarray(pts, np.float32).tobytes()


def tfx_v4(xyzw, n_strands, n_verts, uv=None) -> bytes:
    head = bytearray(160)
    uv_offset = 160 + 16 * n_strands * n_verts if uv is not None else 0
    struct.pack_into("<f2I5I", head, 0, 4.0, n_strands, n_verts, 160, uv_offset, 0, 0, 0)
    body = np.asarray(xyzw, np.float32).tobytes()
    if uv is not None:
        body += np.asarray(uv, np.float32).tobytes()
    return bytes(head) + body


def test_tfx_v3(tmp_path):
    pts = np.arange(24, dtype=np.float32).reshape(8, 3) - 5.5
    path = tmp_path / "v3.tfx"
    path.write_bytes(tfx_v3(pts, 2, 4, both_ends=1))
    raw = read_curves(path)
    assert raw.format == "tressfx-v3" and raw.up == "y"
    assert raw.offsets.tolist() == [0, 4, 8]
    assert np.array_equal(raw.points, pts)
    assert raw.extras["pinned_tip"].tolist() == [True, True]
    path.write_bytes(tfx_v3(pts, 2, 4)[:-1])
    with fails(path, "truncated"):
        read_tfx(path)
    path.write_bytes(tfx_v3(pts, 2, 4, vertex_offset=0))
    with fails(path, "vertex array offset"):
        read_tfx(path)
    path.write_bytes(tfx_v3(pts, 2, 4)[:200])
    with fails(path, "too short"):
        read_tfx(path)
    bad = pts.copy()
    bad[5, 0] = np.inf
    path.write_bytes(tfx_v3(bad, 2, 4))
    with fails(path, "NaN or Inf", strand=1):
        read_tfx(path)


def test_tfx_v4(tmp_path):
    xyzw = np.zeros((6, 4), np.float32)
    xyzw[:, :3] = np.arange(18).reshape(6, 3) * 0.25
    xyzw[:, 3] = [0, 1, 1, 0, 0, 1]
    path = tmp_path / "v4.tfx"
    path.write_bytes(tfx_v4(xyzw, 2, 3, uv=[[0.5, 0.25], [1, 0]]))
    raw = read_curves(path)
    assert raw.format == "tressfx-v4" and raw.up == "y"
    assert raw.offsets.tolist() == [0, 3, 6]
    assert np.array_equal(raw.points, xyzw[:, :3])
    assert raw.extras["immovable"].tolist() == [True, False, False, True, True, False]
    assert raw.extras["strand_uv"].tolist() == [[0.5, 0.25], [1, 0]]
    path.write_bytes(tfx_v4(xyzw, 2, 3)[:-16])
    with fails(path, "truncated"):
        read_tfx(path)
    # a header claiming 2^32 - 1 strands of 64 vertices fails at once
    path.write_bytes(tfx_v4(xyzw, 2**32 - 1, 64))
    t0 = time.perf_counter()
    with fails(path, "truncated", "4294967295 strands"):
        read_tfx(path)
    assert time.perf_counter() - t0 < 0.5


def test_tfx_unsupported_versions(tmp_path):
    path = tmp_path / "v5.tfx"
    path.write_bytes(struct.pack("<f", 5.0) + bytes(300))
    with fails(path, "unsupported TressFX version 5"):
        read_curves(path)
    path.write_bytes(bytes(range(200, 256)) * 10)
    with fails(path, "unsupported TressFX version"):
        read_curves(path)
    path.write_bytes(b"\x00\x00")
    with fails(path, "too short"):
        read_curves(path)


TFXMESH = """# TressFX collision mesh
numOfBones 2
0 root
1 head
# vertices
numOfVertices 4
0 0 0 0 0 1 0 0 0 0 0 1 0 0 0
1 1 0 0 0 1 0 0 0 0 0 1 0 0 0
2 0 1 0 0 1 0 1 0 0 0 1 0 0 0
3 0 0 1.5 0 1 0 1 0 0 0 1 0 0 0
numOfTriangles 2
0 0 1 2
1 0 2 3
"""


def test_tfxmesh(tmp_path):
    path = tmp_path / "body.tfxmesh"
    path.write_text(TFXMESH)
    mesh = read_mesh(path)
    assert mesh.vertices.tolist() == [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.5]]
    assert mesh.faces.tolist() == [[0, 1, 2], [0, 2, 3]]
    path.write_text(TFXMESH.replace("1 0 2 3", "1 0 2 4"))
    with fails(path, "triangle index outside"):
        read_tfxmesh(path)
    path.write_text(TFXMESH.replace("numOfTriangles 2", "numOfTriangles 3"))
    with fails(path, "declares 3 entries"):
        read_tfxmesh(path)
    path.write_text(TFXMESH.split("numOfTriangles")[0])
    with fails(path, "no 'numOfTriangles'"):
        read_tfxmesh(path)


# --------------------------------------------------------------------------- OBJ polylines

OBJ_LINES = """# hair
o hair
v 0 0 0 1 0 0
v 1 0 0 1 0 0
v 2 0 0
v 3 0.5 0
vt 0 0
l 1 2 3
l 3 4
v 0 1 0
v 0 2 0
l -2/1 -1/1
l 1 2 4 3
"""


def test_obj_curves(tmp_path):
    path = tmp_path / "h.obj"
    path.write_text(OBJ_LINES)
    raw = read_curves(path)
    assert raw.format == "obj-lines" and raw.up == "y"
    # the second 'l' continues the first but stays a separate strand
    assert raw.offsets.tolist() == [0, 3, 5, 7, 11]
    assert raw.points.tolist() == [
        [0, 0, 0], [1, 0, 0], [2, 0, 0],
        [2, 0, 0], [3, 0.5, 0],
        [0, 1, 0], [0, 2, 0],
        [0, 0, 0], [1, 0, 0], [3, 0.5, 0], [2, 0, 0],
    ]  # fmt: skip


def test_obj_curves_round_trip(tmp_path):
    rng = np.random.default_rng(2)
    pts = rng.normal(size=(7, 3)) * 1e3
    off = np.array([0, 2, 7])
    path = tmp_path / "rt.obj"
    write_curves(path, pts, off)
    raw = read_curves(path)
    assert raw.offsets.tolist() == off.tolist() and np.array_equal(raw.points, pts)
    with fails(path, "at least 2", strand=1):
        write_curves(path, pts[:3], [0, 2, 3])


def test_obj_curves_bad(tmp_path):
    path = tmp_path / "mesh.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with fails(path, "has no polyline ('l') elements; is it a mesh?"):
        read_curves(path)
    path.write_text("v 0 0 0\nv 1 0 0\nl 1 2 3\n")
    with fails(path, "line 3", "vertex 3"):
        read_curves(path)
    path.write_text("v 0 0 0\nl 1 2\nv 1 0 0\n")  # index used before its 'v'
    with fails(path, "line 2"):
        read_curves(path)
    path.write_text("v 0 0 0\nv 1 0 0\nv 1 nan 0\nl 1 2\nl 2 3\n")
    with fails(path, "NaN or Inf", strand=1):
        read_curves(path)
    path.write_text("v 0 0 0\nv 1 zero 0\nl 1 2\n")
    with fails(path, "vertex 2", "not numbers"):
        read_curves(path)
    path.write_text("v 0 0\nl 1 1\n")
    with fails(path, "line 1", "three coordinates"):
        read_curves(path)


# --------------------------------------------------------------------------- USD


def test_usd_round_trip(tmp_path):
    rng = np.random.default_rng(3)
    pts = rng.normal(size=(10, 3)).astype(np.float32).astype(np.float64)
    off = np.array([0, 4, 10])
    for suffix in (".usda", ".usdc", ".usd"):
        path = tmp_path / f"rt{suffix}"
        write_curves(path, pts, off, widths=np.full(10, 0.5), up="z", meters_per_unit=0.01)
        raw = read_curves(path)
        assert raw.format == "usd-basiscurves"
        assert raw.offsets.tolist() == off.tolist() and np.array_equal(raw.points, pts)
        assert raw.up == "z" and raw.scale_to_m == pytest.approx(0.01)
        assert raw.extras["widths"].tolist() == [0.5] * 10
        assert raw.extras["prims"] == ["/Root/Hair"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rt.usd", "rt.usda", "rt.usdc"]
    with fails(tmp_path / "x.usda", "at least 2", strand=0):
        write_curves(tmp_path / "x.usda", pts[:1], [0, 1])


def test_usdz(tmp_path):
    from pxr import UsdUtils

    pts = np.arange(12, dtype=np.float64).reshape(4, 3)
    write_curves(tmp_path / "h.usdc", pts, [0, 4])
    assert UsdUtils.CreateNewUsdzPackage(str(tmp_path / "h.usdc"), str(tmp_path / "h.usdz"))
    raw = read_curves(tmp_path / "h.usdz")
    assert raw.points.tolist() == pts.tolist() and raw.up == "y"


USDA_CURVES = """#usda 1.0
(
    upAxis = "Y"
)

def Xform "Groom"
{
    double3 xformOp:translate = (10, 0, 0)
    uniform token[] xformOpOrder = ["xformOp:translate"]

    def BasisCurves "lin"
    {
        uniform token type = "linear"
        int[] curveVertexCounts = [2, 3]
        point3f[] points = [(0, 0, 0), (0, 1, 0), (1, 0, 0), (1, 1, 0), (1, 2, 0)]
    }
    def BasisCurves "bez"
    {
        uniform token type = "cubic"
        uniform token basis = "bezier"
        int[] curveVertexCounts = [4]
        point3f[] points = [(0, 0, 0), (0, 3, 0), (0, 6, 0), (0, 9, 0)]
    }
    def BasisCurves "bsp"
    {
        uniform token type = "cubic"
        uniform token basis = "bspline"
        int[] curveVertexCounts = [5]
        point3f[] points = [(0, 0, 0), (0, 6, 0), (0, 12, 0), (0, 18, 0), (6, 24, 0)]
    }
    def BasisCurves "cr"
    {
        uniform token type = "cubic"
        uniform token basis = "catmullRom"
        uniform token wrap = "pinned"
        int[] curveVertexCounts = [2]
        point3f[] points = [(0, 0, 5), (0, 1, 5)]
    }
}
"""


def test_usd_bases_and_transform(tmp_path):
    path = tmp_path / "groom.usda"
    path.write_text(USDA_CURVES)
    raw = read_curves(path)
    assert raw.up == "y" and raw.scale_to_m is None  # metersPerUnit not authored
    assert raw.offsets.tolist() == [0, 2, 5, 9, 12, 14]
    x = 10.0  # the parent's translation
    assert raw.points[:5].tolist() == [[x, 0, 0], [x, 1, 0], [x + 1, 0, 0], [x + 1, 1, 0], [x + 1, 2, 0]]
    # straight bezier with evenly spaced controls: curve points at t = 0, 1/3, 2/3, 1
    assert np.allclose(raw.points[5:9], [[x, 0, 0], [x, 3, 0], [x, 6, 0], [x, 9, 0]])
    # uniform B-spline at its knots: (P[i] + 4 P[i+1] + P[i+2]) / 6
    assert np.allclose(raw.points[9:12], [[x, 6, 0], [x, 12, 0], [x + 1, 18, 0]])
    assert np.allclose(raw.points[12:14], [[x, 0, 5], [x, 1, 5]])  # pinned Catmull-Rom: the controls
    assert "widths" not in raw.extras


def test_usd_bad(tmp_path):
    path = tmp_path / "empty.usda"
    path.write_text('#usda 1.0\n\ndef Mesh "m"\n{\n}\n')
    with fails(path, "has no BasisCurves prims"):
        read_curves(path)
    path = tmp_path / "garbage.usda"
    path.write_text("#usda 1.0\n(((garbage")
    with fails(path, "could not be opened as a USD stage"):
        read_curves(path)
    path = tmp_path / "garbage.usdc"
    path.write_bytes(bytes(100))
    with fails(path, "could not be opened as a USD stage"):
        read_curves(path)
    path = tmp_path / "counts.usda"
    path.write_text(USDA_CURVES.replace("[2, 3]", "[2, 4]"))
    with fails(path, "/Groom/lin", "do not add up"):
        read_curves(path)
    path = tmp_path / "bez.usda"
    path.write_text(USDA_CURVES.replace("int[] curveVertexCounts = [4]", "int[] curveVertexCounts = [2, 2]"))
    with fails(path, "3k + 1", strand=2):
        read_curves(path)
    path = tmp_path / "nan.usda"
    path.write_text(USDA_CURVES.replace("(1, 2, 0)", "(1, nan, 0)"))
    with fails(path, "NaN or Inf", strand=1):
        read_curves(path)


# --------------------------------------------------------------------------- body meshes

OBJ_MESH = """mtllib nowhere.mtl
o first
v 0 0 0 0.5 0.5 0.5
v 1 0 0 0.5 0.5 0.5
v 1 1 0
v 0 1 0
v 0.5 1.5 0
vt 0 0
vn 0 0 1
g quad_and_pentagon
usemtl a
f 1/1/1 2/1/1 3/1/1 4/1/1
f 1//1 2//1 3//1 5//1 4//1
o second
g tri
usemtl b
v 5 5 5
f -1 1 2
"""


def test_obj_mesh(tmp_path):
    path = tmp_path / "body.obj"
    path.write_text(OBJ_MESH)
    mesh = read_mesh(path)
    assert len(mesh.vertices) == 6  # one per 'v' line, nothing split or merged
    assert mesh.vertices[5].tolist() == [5, 5, 5]
    assert len(mesh.faces) == 2 + 3 + 1  # quad, pentagon, triangle from two objects
    assert mesh.faces.tolist()[-1] == [5, 0, 1]
    path.write_text(OBJ_LINES)
    with fails(path, "no faces; is it a hairstyle?"):
        read_mesh(path)
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 inf 0\nf 1 2 3\n")
    with fails(path, "NaN or Inf"):
        read_mesh(path)
    path.write_text("v 0 0 0\nv 1 0 0\nf 1 2\n")
    with fails(path, "line 3", "fewer than 3"):
        read_mesh(path)
    path.write_text("v 0 0 0\nv 1 0 0\nf 1 2 7\n")
    with fails(path, "line 3", "vertex 7"):
        read_mesh(path)


@pytest.mark.parametrize("suffix", [".ply", ".stl", ".off", ".glb"])
def test_trimesh_formats(tmp_path, suffix):
    import trimesh

    box = trimesh.creation.box(extents=(1, 2, 3))
    path = tmp_path / f"box{suffix}"
    box.export(path)
    mesh = read_mesh(path)
    assert len(mesh.faces) == 12
    assert np.allclose(mesh.bounds, [[-0.5, -1, -1.5], [0.5, 1, 1.5]])


def test_trimesh_formats_bad(tmp_path):
    path = tmp_path / "bad.off"
    path.write_text("OFF\n3 1 0\n0 0 0\n1 0\n")
    with pytest.raises(InputError, match=re.escape(path.name)):
        read_mesh(path)
    path = tmp_path / "bad.glb"
    path.write_bytes(b"glTF" + bytes(40))
    with pytest.raises(InputError, match=re.escape(path.name)):
        read_mesh(path)
    path = tmp_path / "points.ply"
    path.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                    "end_header\n0 0 0\n1 0 0\n0 1 0\n")  # fmt: skip
    with pytest.raises(InputError, match=re.escape(path.name) + ".*(no triangle mesh|no faces)"):
        read_mesh(path)


# --------------------------------------------------------------------------- property: every writer round-trips

@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    counts=st.lists(st.integers(2, 6), min_size=1, max_size=5),
    seed=st.integers(0, 2**32 - 1),
    suffix=st.sampled_from([".hair", ".data", ".obj", ".usda", ".usdc"]),
)
def test_writers_round_trip(tmp_path, counts, seed, suffix):
    pts = np.random.default_rng(seed).normal(scale=50, size=(sum(counts), 3)).astype(np.float32).astype(np.float64)
    off = np.concatenate([[0], np.cumsum(counts)])
    path = tmp_path / f"h{suffix}"
    write_curves(path, pts, off)
    raw = read_curves(path)
    assert raw.offsets.tolist() == off.tolist()
    assert np.array_equal(raw.points, pts)
