"""A consumer other than pxr: Blender (the ``bpy`` module, ``make blender``) imports hairinv's USD export.

Blender runs in its own environment (.venv-blender, or the Python named by ``$HAIRINV_BLENDER_PYTHON``),
in a subprocess running tests/blender_read_usd.py, which imports each file with ``bpy.ops.wm.usd_import``
(default options) into an empty scene and writes what came in (JSON, and every point in world space as
.npz). Without that Python the tests skip, saying how to get it.

The stage files are the hand-made ones of tests/conftest.py (two strands, centimetres, with a model, contacts and
three frames of a moving body), given the sample bust (written in the groom's unit, as hairinv reads a
body by default) as their recorded body, exported five ways: ``z.usda`` (+Z up, stiffened model, frames),
``y.usdc`` (+Y up, frames), ``model.usd`` (+Y up, metres, a model without frames), ``removed.usda`` (the
body hidden during the frames, as the remove-body scene does) and ``catmull.usdc`` (``basis="catmull-rom"``:
pinned Catmull-Rom cubics). What Blender holds is compared with what the stage file holds, read with h5py
and evaluated independently (the closed forms of tests/conftest.py), after the conversion Blender's importer applies:
the stage's ``metersPerUnit`` as a scale on the root object (scene unit scale 1: metres) and, for a +Y up
stage, +90 degrees about X, so that the groom is +Z up as Blender is.

Runtime: about 4 s (Blender's start-up and the five imports: about 1 s).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np
import pytest
from conftest import (FLOAT32_M, FPS, N_FRAMES, RADIUS, ROOT, SAMPLES, body_motion, eight_strand_model, expected_frame,
                      expected_rest, hairinv, make_stage, obj_mesh)

from hairinv import stages
from hairinv.export import export
from hairinv.rod.helix import strand_points

SCRIPT = Path(__file__).resolve().parent / "blender_read_usd.py"
BLENDER_PYTHON = Path(os.environ.get("HAIRINV_BLENDER_PYTHON", ROOT / ".venv-blender" / "bin" / "python"))

# Blender is +Z up: its importer turns a +Y up stage by +90 degrees about X, (x, y, z) -> (x, -z, y).
TO_BLENDER = {"z": np.eye(3), "y": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])}
UP = {"z": (0.0, 0.0, 1.0), "y": (0.0, 1.0, 0.0)}
BLENDER_DEFAULT_FPS = 24
# Blender's matrices are float32: 6e-8 relative, and the quarter turn's cosine is 7.5e-8 instead of 0.
FLOAT32 = 2e-7



@dataclass(frozen=True)
class Spec:
    up: str
    scale: float
    """metres per unit"""
    stiffened: bool = False
    frames: bool = True
    removed: bool = False
    """the scene removed the body"""
    basis: str = "linear"


FILES = {"z.usda": Spec("z", 0.01, stiffened=True), "y.usdc": Spec("y", 0.01),
         "model.usd": Spec("y", 1.0, frames=False), "removed.usda": Spec("z", 0.01, removed=True),
         "catmull.usdc": Spec("y", 0.01, frames=False, basis="catmull-rom")}


def _body_file(folder: Path, scale: float) -> Path:
    """The sample bust (metres) written in the groom's unit, as hairinv reads a body by default."""
    path = folder / f"body_{scale:g}.obj"
    lines = []
    for line in (SAMPLES / "body.obj").read_text().splitlines():
        words = line.split()
        if words and words[0] == "v":
            line = "v " + " ".join(repr(float(w) / scale) for w in words[1:4])
        lines.append(line)
    path.write_text("\n".join(lines) + "\n")
    return path


def _stage_file(folder: Path, name: str) -> tuple[Path, dict]:
    """The hand-made stage file (tests/conftest.py) with the sample bust recorded as its body (the last input of the
    group the export looks in: /frames, else /model)."""
    spec = FILES[name]
    path = folder / (Path(name).stem + ".h5")
    truth = make_stage(path, up=UP[spec.up], scale_to_m=spec.scale, stiffened=spec.stiffened, frames=spec.frames)
    with h5py.File(path, "r+") as fh:
        fh["frames" if spec.frames else "model"].attrs["inputs"] = json.dumps(
            [{"name": "hand-made"}, stages.file_record(_body_file(folder, spec.scale))])
        if spec.removed:
            fh["frames"].attrs["body_removed"] = True
    return path, truth


@pytest.fixture(scope="module")
def blender(tmp_path_factory):
    """The exports and what Blender read of them: (folder, JSON report, arrays, truths)."""
    if not BLENDER_PYTHON.exists():
        pytest.skip(f"Blender's Python not found at {BLENDER_PYTHON}: `make blender` installs Blender as the bpy "
                    "module in .venv-blender (or set HAIRINV_BLENDER_PYTHON to a Python that has bpy)")
    folder = tmp_path_factory.mktemp("blender")
    truths, outputs = {}, []
    for name in FILES:
        path, truths[name] = _stage_file(folder, name)
        options = {"basis": FILES[name].basis} if FILES[name].basis != "linear" else {}
        report = export(path, folder / name, **options)
        assert not report.warnings, report.warnings  # the body was found
        outputs.append(str(folder / name))
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    frames = ",".join(str(k) for k in range(N_FRAMES))
    result = subprocess.run([str(BLENDER_PYTHON), str(SCRIPT), *outputs, "--frames", frames, "--tessellate",
                             "--json", str(folder / "blender.json"), "--npz", str(folder / "blender.npz")],
                            capture_output=True, text=True, env=env, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    report = json.loads((folder / "blender.json").read_text())
    arrays = dict(np.load(folder / "blender.npz"))
    return folder, report, arrays, truths


def _file(blender, name):
    folder, report, arrays, truths = blender
    index = list(FILES).index(name)
    read = report["files"][index]
    assert Path(read["file"]).name == name and read["result"] == ["FINISHED"]
    return read, {k.split("/", 1)[1]: v for k, v in arrays.items() if k.split("/", 1)[0] == str(index)}, truths[name]


# USD primvar interpolation and type -> Blender attribute domain and type
DOMAIN = {"uniform": "CURVE", "vertex": "POINT"}
DATA_TYPE = {"float[]": "FLOAT", "int[]": "INT", "point3f[]": "FLOAT_VECTOR", "texCoord2f[]": "FLOAT2"}  # groom_root_uv: FLOAT2


def _builtin(spec: Spec) -> dict[str, tuple[str, str]]:
    """Blender's own attributes of the imported curves: positions, radius (from widths) and, for linear curves,
    the curve type (poly); without it every curve is Catmull-Rom, Blender's default type."""
    out = {"position": ("POINT", "FLOAT_VECTOR"), "radius": ("POINT", "FLOAT")}
    if spec.basis == "linear":
        out["curve_type"] = ("CURVE", "INT8")
    return out


def _primvars(path, prim) -> dict[str, tuple[str, str]]:
    """The primvars of ``prim`` as pxr reads the file: name -> (interpolation, value type)."""
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(path))
    return {p.GetPrimvarName(): (p.GetInterpolation(), str(p.GetTypeName()))
            for p in UsdGeom.PrimvarsAPI(stage.GetPrimAtPath(prim)).GetAuthoredPrimvars()}


def _object(read, name):
    found = [o for o in read["objects"] if o["name"] == name]
    assert len(found) == 1, [o["name"] for o in read["objects"]]
    return found[0]


def test_blender_version(blender):
    """Hair curves (the ``Curves`` object type that the importer makes of BasisCurves) need Blender 4 or later."""
    _, report, _, _ = blender
    assert int(report["blender"].split(".")[0]) >= 4, report["blender"]


@pytest.mark.parametrize("name", list(FILES))
def test_blender_reads_every_strand_in_metres_z_up(blender, name):
    read, arrays, truth = _file(blender, name)
    spec = FILES[name]
    scale, frames = spec.scale, spec.frames
    to_blender = TO_BLENDER[spec.up]
    assert {o["name"]: o["type"] for o in read["objects"]} == {"Root": "EMPTY", "Hair": "CURVES",
                                                               "Rest": "CURVES", "Body": "MESH"}
    assert read["scene"]["unit_system"] == "METRIC" and read["scene"]["scale_length"] == 1.0
    # the root object carries metersPerUnit (and, for +Y up, the turn onto +Z); its children are the prims
    root = np.array(_object(read, "Root")["matrix_world"])
    assert np.abs(root[:3, :3] - scale * to_blender).max() < FLOAT32 * scale and np.allclose(root[:3, 3], 0)
    assert all(_object(read, n)["parent"] == "Root" for n in ("Hair", "Rest", "Body"))
    # /Root/Hair: as many curves as strands, the same points per curve
    hair = _object(read, "Hair")
    counts = np.diff(truth["offsets"])
    assert hair["curves"] == len(counts) and hair["points"] == len(truth["points"])
    assert arrays["Hair/counts"].tolist() == counts.tolist()
    with h5py.File(Path(read["file"]).with_suffix(".h5"), "r") as fh:  # the stage file's own points, metres
        points = fh["curves/points"][()]
        assert fh["curves"].attrs["scale_to_m"] == scale
    assert np.allclose(points, truth["points"], atol=0)
    if frames:
        # the object's own data is the first time sample (time code 0), not the default value (the input)
        assert np.abs(arrays["Hair/points"] - expected_frame(truth, 0) @ to_blender.T).max() < FLOAT32_M
    else:
        assert np.abs(arrays["Hair/points"] - points @ to_blender.T).max() < FLOAT32_M
    # /Root/Rest: the rest shape as curves of their own
    assert arrays["Rest/counts"].tolist() == counts.tolist()
    rest = expected_rest(truth, spec.stiffened) @ to_blender.T
    assert np.abs(arrays["Rest/points"] - rest).max() < FLOAT32_M


@pytest.mark.parametrize("name", list(FILES))
def test_blender_keeps_the_primvars_as_attributes(blender, name):
    read, arrays, truth = _file(blender, name)
    spec = FILES[name]
    up, scale, stiffened = spec.up, spec.scale, spec.stiffened
    hair = _object(read, "Hair")
    attributes = {a["name"]: (a["domain"], a["data_type"]) for a in hair["attributes"]}
    # every primvar of /Root/Hair (as pxr reads the file) is an attribute: uniform on the curves, vertex on
    # the points; besides them Blender's position, curve type and radius (from widths)
    primvars = _primvars(read["file"], "/Root/Hair")
    assert {"rest", "groom_id", "id", "groom_guide", "groom_fit_error_mean", "groom_fit_error_max",
            "groom_contact_force", "groom_rest_curvature"} <= set(primvars)
    assert ("groom_stiffening" in primvars) == stiffened
    expected = {name: (DOMAIN[interpolation], DATA_TYPE[kind]) for name, (interpolation, kind) in primvars.items()}
    expected.update(_builtin(spec))
    assert attributes == expected
    # widths -> radius: half the rod diameter, in stage units (the root object's scale makes it metres)
    assert np.allclose(arrays["Hair/attr/radius"] * scale, RADIUS, rtol=1e-6)
    # rest: stage units in the object's space, so the object's matrix takes it to the rest shape in metres
    matrix = np.array(hair["matrix_world"])
    rest = arrays["Hair/attr/rest"] @ matrix[:3, :3].T + matrix[:3, 3]
    assert np.abs(rest - expected_rest(truth, stiffened) @ TO_BLENDER[up].T).max() < FLOAT32_M
    assert arrays["Hair/attr/groom_id"].tolist() == arrays["Hair/attr/id"].tolist() == [0, 1]
    assert arrays["Hair/attr/groom_guide"].tolist() == [1, 1]
    assert np.allclose(arrays["Hair/attr/groom_fit_error_max"], [3e-5, 4e-5], rtol=1e-6)  # SI, not rescaled
    assert np.allclose(arrays["Hair/attr/groom_contact_force"], truth["contact_force"], rtol=1e-6, atol=0)
    if stiffened:
        assert arrays["Hair/attr/groom_stiffening"].tolist() == [1.0, 2.0]
    # the rest prim has the strand ids only
    rest_attributes = {a["name"] for a in _object(read, "Rest")["attributes"]}
    assert rest_attributes == set(_builtin(spec)) | set(_primvars(read["file"], "/Root/Rest"))
    assert set(_primvars(read["file"], "/Root/Rest")) == {"groom_id", "id", "groom_guide"}


@pytest.mark.parametrize("name", list(FILES))
def test_blender_reads_the_body_mesh(blender, name):
    read, arrays, truth = _file(blender, name)
    to_blender = TO_BLENDER[FILES[name].up]
    vertices, faces = obj_mesh(SAMPLES / "body.obj")  # metres
    body = _object(read, "Body")
    assert body["vertices"] == len(vertices) and body["faces"] == len(faces)
    assert body["face_sizes"] == {"3": len(faces)}  # triangles, as written
    frames = sorted(int(k) for k in read["frames"])
    for k in frames:  # the body in metres, placed by the frame's rigid motion (none without frames)
        T = body_motion(k) if FILES[name].frames else np.eye(4)
        expected = (vertices @ T[:3, :3].T + T[:3, 3]) @ to_blender.T
        assert np.abs(arrays[f"Body/frame{k}"] - expected).max() < FLOAT32_M, k


@pytest.mark.parametrize("name", [n for n, spec in FILES.items() if spec.frames])
def test_blender_plays_the_frames(blender, name):
    """The time samples: Blender's scene frame N shows time code N (frames 0, 1, 2 here). The importer sets the
    frame range from the stage but leaves the scene at its own 24 fps (the stage says 25): played in Blender
    the run is 25/24 times slower than it was simulated."""
    read, arrays, truth = _file(blender, name)
    to_blender = TO_BLENDER[FILES[name].up]
    scene = read["scene"]
    assert (scene["frame_start"], scene["frame_end"]) == (0, N_FRAMES - 1)
    assert scene["fps"] == BLENDER_DEFAULT_FPS != FPS and scene["fps_base"] == 1.0
    hair, body, rest = (_object(read, n) for n in ("Hair", "Body", "Rest"))
    # the points come from the file at each frame through a mesh sequence cache modifier, the body's
    # transform through a transform cache constraint; the rest prim (no time samples) gets neither
    assert [(m["type"], m["object_path"]) for m in hair["modifiers"]] == [("MESH_SEQUENCE_CACHE", "/Root/Hair")]
    assert [(c["type"], c["object_path"]) for c in body["constraints"]] == [("TRANSFORM_CACHE", "/Root/Body")]
    assert not rest["modifiers"] and not rest["constraints"]
    assert Path(hair["modifiers"][0]["cache_file"]).name == name
    for k in range(N_FRAMES):
        frame = read["frames"][str(k)]
        assert frame["Hair"]["curves"] == len(truth["offsets"]) - 1
        assert np.abs(arrays[f"Hair/frame{k}"] - expected_frame(truth, k) @ to_blender.T).max() < FLOAT32_M, k
        if k:
            assert frame["Hair"]["moved_since_first"] > 1e-3 and frame["Body"]["moved_since_first"] > 1e-3
            assert frame["Rest"]["moved_since_first"] == 0.0


def _catmull_rom(p0, p1, p2, p3, t):
    """USD's (and Blender's) uniform Catmull-Rom segment from p1 (t = 0) to p2 (t = 1)."""
    t = np.asarray(t, dtype=np.float64)[:, None]
    return 0.5 * (2 * p1 + (p2 - p0) * t + (2 * p0 - 5 * p1 + 4 * p2 - p3) * t ** 2
                  + (3 * p1 - p0 - 3 * p2 + p3) * t ** 3)


@pytest.mark.parametrize("name", list(FILES))
def test_blender_draws_the_curves_the_file_describes(blender, name):
    """The rest prim's curves as Blender draws them (converted to a mesh): linear ones are the straight segments
    through the vertices; pinned Catmull-Rom ones are Blender's Catmull-Rom curves, which agree with USD's
    between the second and the second-last vertex. On the end segments Blender repeats the end vertex where
    USD's pinned wrap takes the phantom point 2 P0 - P1: the same end points, the shape within 3 um here (see
    docs/export.md), the parameter along them otherwise spaced."""
    read, arrays, truth = _file(blender, name)
    spec = FILES[name]
    tessellated = read["tessellated"]["Rest"]
    points, counts = arrays["Rest/points"], arrays["Rest/counts"]
    drawn = arrays["Rest/tessellated"]
    if spec.basis == "linear":
        assert tessellated["curve_types"] == ["POLY"]
        assert np.abs(drawn - points).max() < FLOAT32_M
    else:
        _assert_drawn_as_pinned_catmull_rom(tessellated, points, counts, drawn)


def _assert_drawn_as_pinned_catmull_rom(tessellated, points, counts, drawn):
    """Blender's tessellation of pinned Catmull-Rom curves against USD's curve (see the test above)."""
    assert tessellated["curve_types"] == ["CATMULL_ROM"]
    (resolution,) = tessellated["resolution"]
    assert len(drawn) == tessellated["points"] == int(((counts - 1) * resolution + 1).sum())
    t = np.arange(resolution + 1) / resolution
    dense = np.linspace(0.0, 1.0, 20001)
    start, at, worst_end = 0, 0, 0.0
    for n in counts:
        P = points[start:start + n]
        ext = np.vstack([2 * P[0] - P[1], P, 2 * P[-1] - P[-2]])  # USD's pinned wrap: the phantom points
        for i in range(n - 1):
            blender_segment = drawn[at + i * resolution:at + (i + 1) * resolution + 1]
            if 0 < i < n - 2:
                usd = _catmull_rom(*ext[i:i + 4], t)
                assert np.abs(blender_segment - usd).max() < FLOAT32_M
            else:  # end segments: the same end points, and every drawn point near the pinned curve
                usd = _catmull_rom(*ext[i:i + 4], dense)
                assert np.abs(blender_segment[[0, -1]] - usd[[0, -1]]).max() < FLOAT32_M
                worst_end = max(worst_end, np.linalg.norm(blender_segment[:, None] - usd[None], axis=2).min(1).max())
        start += n
        at += (n - 1) * resolution + 1
    assert worst_end < 5e-6, worst_end  # 3.0e-6 m with Blender 5.0.1


def test_blender_keeps_a_removed_body_visible(blender):
    """The remove-body scene hides /Root/Body from the first frame on (a `visibility` time sample, checked here
    with pxr); Blender's importer does not read animated visibility: the body stays visible at every frame."""
    from pxr import Usd, UsdGeom

    read, _, _ = _file(blender, "removed.usda")
    stage = Usd.Stage.Open(read["file"])
    body = UsdGeom.Imageable(stage.GetPrimAtPath("/Root/Body"))
    assert body.ComputeVisibility(Usd.TimeCode(0)) == UsdGeom.Tokens.invisible
    assert _object(read, "Body")["hidden"] == {"viewport": False, "render": False}
    assert all(read["frames"][str(k)]["Body"]["visible"] for k in range(N_FRAMES))


def test_blender_without_frames_leaves_the_scene_frames_alone(blender):
    read, _, _ = _file(blender, "model.usd")
    hair = _object(read, "Hair")
    assert not hair["modifiers"] and not _object(read, "Body")["constraints"]
    assert read["cache_files"] == []


# ---------------------------------------------------------------------- a shot: the body deforms, the hair follows

SHOT_SECONDS = 0.4  # samples/turn.glb holds its bind pose for 0.2 s, then turns the head by 90 degrees in 0.3 s
SHOT_FRAMES = (0, 6, 9, 12)  # of the 13 at 30 fps: still, turning, two thirds of the turn


def _skip_without_blender():
    if not BLENDER_PYTHON.exists():
        pytest.skip(f"Blender's Python not found at {BLENDER_PYTHON}: `make blender` installs Blender as the bpy "
                    "module in .venv-blender (or set HAIRINV_BLENDER_PYTHON to a Python that has bpy)")


@pytest.fixture(scope="module")
def blender_shot(tmp_path_factory):
    """A shot's USD (eight strands inverted on samples/turn.glb's bind pose, 0.4 s of its head turn simulated,
    `hairinv export FRAMES -o shot.usda`) and what Blender read of it at SHOT_FRAMES: (folder, the file's
    report, arrays)."""
    _skip_without_blender()
    folder = tmp_path_factory.mktemp("blender_shot")
    eight_strand_model(folder)
    done = hairinv(folder, "simulate", "eight.model.h5", str(SAMPLES / "turn.glb"), "--seconds", str(SHOT_SECONDS),
                   "-o", "turn.frames.h5")
    assert done.returncode == 0, done.stderr
    done = hairinv(folder, "export", "turn.frames.h5", "-o", "shot.usda")
    assert done.returncode == 0, done.stderr
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    result = subprocess.run([str(BLENDER_PYTHON), str(SCRIPT), str(folder / "shot.usda"), "--frames",
                             ",".join(map(str, SHOT_FRAMES)), "--json", str(folder / "blender.json"), "--npz",
                             str(folder / "blender.npz")], capture_output=True, text=True, env=env, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    (read,) = json.loads((folder / "blender.json").read_text())["files"]
    assert read["result"] == ["FINISHED"]
    arrays = {k.split("/", 1)[1]: v for k, v in np.load(folder / "blender.npz").items()}
    return folder, read, arrays


def _shot_truth(path: Path) -> dict:
    """What the stage file holds, read with h5py: the frames' body vertices, and the hair's points at every frame
    at the input vertices' arc lengths (docs/export.md: vertex i at s_i = L c_i / c_n, c the cumulative chord
    length of the input polyline, L the fitted length), from /frames' roots, root frames and curvatures."""
    with h5py.File(path, "r") as fh:
        f, h, c = fh["frames"], fh["helices"], fh["curves"]
        out = {key: f[key][()] for key in ("time", "root", "frame0", "omega", "body_vertices", "body_faces")}
        out["fps"] = float(f.attrs["fps"])
        out["scale"], out["up"] = float(c.attrs["scale_to_m"]), np.asarray(c.attrs["up"])
        points, offsets = c["points"][()], c["offsets"][()]
        h_offsets, length = h["offsets"][()], h["length"][()]
    S = len(offsets) - 1
    strand = np.repeat(np.arange(S), np.diff(offsets))
    cum = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))]
    start, end = cum[offsets[:-1]], cum[offsets[1:] - 1]
    s = (cum - start[strand]) / (end - start)[strand] * np.add.reduceat(length, h_offsets[:-1])[strand]
    out["hair"] = np.array([strand_points(out["root"][k], out["frame0"][k], h_offsets, out["omega"][k], length,
                                          strand, s) for k in range(len(out["time"]))])
    out["counts"] = np.diff(offsets)
    return out


def test_blender_plays_a_shot_the_body_deforming_and_the_hair_following(blender_shot):
    """The shot's body is a deforming mesh: its points are time samples (no transform), which Blender's importer
    reads through a mesh sequence cache modifier, as it does the hair's. At each frame set, the evaluated body
    is /frames/body_vertices and the evaluated hair is the frame's strands, in metres, +Z up."""
    from pxr import Usd, UsdGeom

    folder, read, arrays = blender_shot
    truth = _shot_truth(folder / "turn.frames.h5")
    n_frames = len(truth["time"])
    assert n_frames == round(SHOT_SECONDS * truth["fps"]) + 1
    # the file as pxr reads it: the body's points sampled at every frame's time code, no transform op
    stage = Usd.Stage.Open(str(folder / "shot.usda"))
    body_prim = UsdGeom.Mesh(stage.GetPrimAtPath("/Root/Body"))
    assert body_prim.GetPointsAttr().GetTimeSamples() == [float(k) for k in range(n_frames)]
    assert not UsdGeom.Xformable(body_prim).GetOrderedXformOps()
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y and truth["up"].tolist() == [0.0, 1.0, 0.0]
    to_blender = TO_BLENDER["y"]
    scale = truth["scale"]
    assert {o["name"]: o["type"] for o in read["objects"]} == {"Root": "EMPTY", "Hair": "CURVES", "Rest": "CURVES",
                                                               "Body": "MESH"}
    root = np.array(_object(read, "Root")["matrix_world"])
    assert np.abs(root[:3, :3] - scale * to_blender).max() < FLOAT32 * scale and np.allclose(root[:3, 3], 0)
    assert (read["scene"]["frame_start"], read["scene"]["frame_end"]) == (0, n_frames - 1)
    hair, body = _object(read, "Hair"), _object(read, "Body")
    assert [(m["type"], m["object_path"]) for m in hair["modifiers"]] == [("MESH_SEQUENCE_CACHE", "/Root/Hair")]
    assert [(m["type"], m["object_path"]) for m in body["modifiers"]] == [("MESH_SEQUENCE_CACHE", "/Root/Body")]
    assert not body["constraints"]
    assert body["vertices"] == truth["body_vertices"].shape[1] and body["faces"] == len(truth["body_faces"])
    assert arrays["Hair/counts"].tolist() == truth["counts"].tolist()
    for k in SHOT_FRAMES:
        expected_body = truth["body_vertices"][k].astype(np.float64) @ to_blender.T
        assert np.abs(arrays[f"Body/frame{k}"] - expected_body).max() < FLOAT32_M, k
        assert np.abs(arrays[f"Hair/frame{k}"] - truth["hair"][k] @ to_blender.T).max() < FLOAT32_M, k
    # and the frames differ: the head turned, the body and the hair with it (centimetres by frame 12)
    last = read["frames"][str(SHOT_FRAMES[-1])]
    assert last["Body"]["moved_since_first"] > 0.02 and last["Hair"]["moved_since_first"] > 0.02
    assert read["frames"]["6"]["Body"]["moved_since_first"] < 1e-6  # still in the bind pose until 0.2 s


if __name__ == "__main__":
    sys.exit(pytest.main([__file__, "-q"]))
