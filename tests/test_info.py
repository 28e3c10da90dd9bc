"""``hairinv info`` on the files a user has before any stage: static body meshes of every format the registry
reads, and hairstyle files. The counts, bounds and edges are checked against the files as written here.

Runtime: about 10 s (a few subprocesses; no numerical kernel).
"""

from __future__ import annotations

import json
import re

import h5py
import numpy as np
import pytest
import trimesh

from conftest import SAMPLES, assert_refused, hairinv
from hairinv import formats
from hairinv.summary import body_summary, file_summary


def obj_vertices(path) -> np.ndarray:
    """The ``v`` lines of an OBJ file, read here without hairinv."""
    return np.array([[float(x) for x in line.split()[1:4]] for line in open(path) if line.startswith("v ")])


def boundary_edges(mesh) -> int:
    """Edges on one triangle only, after joining coincident vertices: trimesh's own count."""
    merged = mesh.copy()
    merged.merge_vertices()
    return len(trimesh.grouping.group_rows(merged.edges_sorted, require_count=1))


@pytest.fixture(scope="module")
def bodies(tmp_path_factory):
    """The sample bust as OBJ (the repository's), and exported by trimesh as a static GLB and a PLY; a closed box
    as a GLB, and the same box inside out."""
    folder = tmp_path_factory.mktemp("info")
    bust = trimesh.load(SAMPLES / "body.obj", force="mesh", process=False)
    bust.export(folder / "body.glb")
    bust.export(folder / "body.ply")
    box = trimesh.creation.box(extents=(0.2, 0.3, 0.4))
    box.export(folder / "box.glb")
    inside_out = box.copy()
    inside_out.invert()
    inside_out.export(folder / "inside_out.glb")
    return folder


def test_info_on_a_static_glb_of_the_sample_bust(bodies):
    result = hairinv(bodies, "info", "body.glb")
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    vertices = obj_vertices(SAMPLES / "body.obj")
    triangles = sum(1 for line in open(SAMPLES / "body.obj") if line.startswith("f "))  # the bust has triangles only
    assert lines[0] == f"body.glb: body mesh (glTF binary), {len(vertices)} vertices, {triangles} triangles"
    low, high = vertices.min(axis=0), vertices.max(axis=0)
    shown = re.match(r"  bounds: \((.*)\) \.\. \((.*)\) file units, ", lines[1])
    assert shown, lines[1]
    assert np.allclose([float(x) for x in shown[1].split(",")], low, rtol=1e-3, atol=1e-4)
    assert np.allclose([float(x) for x in shown[2].split(",")], high, rtol=1e-3, atol=1e-4)
    assert lines[2].startswith("  units: m (1 m per unit), stated by glTF's specification")
    assert lines[3] == "  up: +Y, stated by glTF's specification"
    edges = boundary_edges(trimesh.load(SAMPLES / "body.obj", force="mesh", process=False))
    assert edges > 0 and lines[4].startswith(f"  surface: open ({edges} boundary edges)")
    assert result.stderr == ""


def test_info_on_the_sample_obj_guesses_its_unit(bodies):
    result = hairinv(bodies, "info", SAMPLES / "body.obj")
    assert result.returncode == 0, result.stderr
    diagonal = np.linalg.norm(np.ptp(obj_vertices(SAMPLES / "body.obj"), axis=0))
    assert f"units: not stated by the file; {diagonal:.3g} across reads as m for a body" in result.stdout
    assert "up: not stated by the file" in result.stdout and "body mesh (OBJ)" in result.stdout


def test_info_json_of_bodies_in_three_formats_agrees(bodies):
    """The OBJ, the GLB and the PLY of one bust: the same vertices, triangles, bounds and boundary."""
    summaries = [body_summary(path) for path in (SAMPLES / "body.obj", bodies / "body.glb", bodies / "body.ply")]
    for summary in summaries[1:]:
        for key in ("vertices", "triangles", "boundary_edges", "closed", "flipped_edges"):
            assert summary[key] == summaries[0][key], key
        assert np.allclose(summary["bounds_min"], summaries[0]["bounds_min"], atol=1e-6)
        assert np.allclose(summary["bounds_max"], summaries[0]["bounds_max"], atol=1e-6)
    assert [s["format"] for s in summaries] == ["OBJ", "glTF binary", "PLY"]
    result = hairinv(bodies, "info", "--json", "body.ply")
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout) == json.loads(json.dumps(summaries[2]))


def test_a_closed_box_and_the_same_box_inside_out(bodies):
    box, inside_out = body_summary(bodies / "box.glb"), body_summary(bodies / "inside_out.glb")
    assert box["closed"] and box["normals_outward"] is True and box["boundary_edges"] == 0
    assert inside_out["closed"] and inside_out["normals_outward"] is False
    assert np.allclose(box["size"], [0.2, 0.3, 0.4], atol=1e-6)
    said = hairinv(bodies, "info", "inside_out.glb")
    assert said.returncode == 0 and "closed (watertight), its triangles facing in: inside out" in said.stdout


def test_triangles_wound_opposite_ways_are_counted(tmp_path):
    box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    faces = np.array(box.faces)
    faces[0] = faces[0][::-1]  # one triangle turned: its three edges now run the way their neighbours' do
    trimesh.Trimesh(box.vertices, faces, process=False).export(tmp_path / "turned.ply")
    summary = body_summary(tmp_path / "turned.ply")
    assert summary["closed"] and summary["flipped_edges"] == 3 and summary["normals_outward"] is None


def test_info_on_a_static_usd_mesh(tmp_path):
    """A USD stage in centimetres, +Z up, its sphere placed by a transform: read in the world, as stated."""
    Usd = pytest.importorskip("pxr.Usd")
    UsdGeom = pytest.importorskip("pxr.UsdGeom")
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=12.0)
    stage = Usd.Stage.CreateNew(str(tmp_path / "head.usda"))
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.Xform.Define(stage, "/Body").AddTranslateOp().Set((0.0, 0.0, 150.0))
    mesh = UsdGeom.Mesh.Define(stage, "/Body/Head")
    mesh.GetPointsAttr().Set([tuple(map(float, p)) for p in sphere.vertices])
    mesh.GetFaceVertexCountsAttr().Set([3] * len(sphere.faces))
    mesh.GetFaceVertexIndicesAttr().Set([int(i) for i in sphere.faces.ravel()])
    stage.GetRootLayer().Save()
    read = formats.read_mesh(tmp_path / "head.usda")
    assert np.allclose(read.vertices, sphere.vertices + [0.0, 0.0, 150.0], atol=1e-4)
    result = hairinv(tmp_path, "info", "head.usda")
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert lines[0] == f"head.usda: body mesh (USD), {len(sphere.vertices)} vertices, {len(sphere.faces)} triangles"
    assert "units: cm (0.01 m per unit), stated by the USD stage" in lines[2]
    assert lines[3] == "  up: +Z, stated by the USD stage"
    assert "closed (watertight), its triangles facing out" in lines[4]


def test_info_on_hairstyle_files(tmp_path):
    """A polyline OBJ (the suffix of a body too) and a Yuksel .hair, exported from the sample groom."""
    for name in ("wavy.obj", "wavy.hair"):
        assert hairinv(tmp_path, "export", SAMPLES / "wavy.h5", "-o", name).returncode == 0
    with h5py.File(SAMPLES / "wavy.h5", "r") as fh:
        offsets = fh["curves"]["offsets"][()]
    counts = np.diff(offsets)
    for name in ("wavy.obj", "wavy.hair"):
        summary = file_summary(tmp_path / name)
        assert summary["kind"] == "hairstyle" and summary["strands"] == len(counts)
        assert summary["points"] == offsets[-1] and summary["points_per_strand"]["max"] == counts.max()
        result = hairinv(tmp_path, "info", name)
        assert result.returncode == 0, result.stderr
        assert result.stdout.startswith(f"{name}: hairstyle (") and f"{len(counts)} strands" in result.stdout


def test_a_file_info_does_not_read_is_refused_in_one_sentence(tmp_path):
    (tmp_path / "notes.txt").write_text("a groom, some day\n")
    assert_refused(tmp_path, ["info", "notes.txt"], "notes.txt", "is not a kind of file hairinv reads")
    (tmp_path / "broken.glb").write_bytes(b"not a glb at all")
    assert_refused(tmp_path, ["info", "broken.glb"], "broken.glb", "GLB")
    (tmp_path / "empty.obj").write_text("# nothing\n")
    assert_refused(tmp_path, ["info", "empty.obj"], "empty.obj", "no faces")
