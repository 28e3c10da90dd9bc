"""``hairinv export``: every file read back as other tools (and hairinv's own readers) read it.

Two kinds of stage files:

- a hand-made one (two strands in centimetres, +Z up, with a model, contacts and frames) whose every
  shape has a closed form: each element is a helix whose frame turns about its constant world Darboux
  vector, evaluated with Rodrigues' formula independently of hairinv.rod (tests/conftest.py);
- a real one: ``hairinv invert`` on samples/settled_curly.h5 and body.obj (and its gravity-only
  inversion), then short still simulations from the inverted, naive and gravity-only rest shapes, and
  motion and trim simulations (about 15 s warm in all).

Runtime: about 95 s warm.
"""

from __future__ import annotations

import itertools
import json
import shutil

import h5py
import numpy as np
import pytest
from conftest import (ELEMENT_OFFSETS, FLOAT32_M, FPS, FRAME0, LENGTH, N_FRAMES, OMEGA, OMEGA_REST,
                      OMEGA_REST_STIFFENED, RADIUS, ROOTS, SAMPLES, STABILITY_MARGIN, UP_Z, assert_refused,
                      body_motion, centerline, evaluate, expected_frame, expected_rest, hairinv, make_stage, obj_mesh,
                      snapshot, vertex_arc_lengths)
from pxr import Usd, UsdGeom  # usd-core, a dependency of hairinv

from hairinv import stages
from hairinv.config import ImportSettings
from hairinv.errors import InputError
from hairinv.export import export
from hairinv.formats import read_curves
from hairinv.groom import load_groom

# The closed forms against themselves in float64 (rotations chained over a few elements).
ROUNDOFF_M = 1e-12


def test_independent_evaluation_is_a_circle_for_pure_bending():
    """The helper itself: one element bent by kappa2 is an arc of radius 1/kappa2 in the (t, n1) plane."""
    F = np.eye(3)
    s = np.linspace(0.0, 0.3, 7)
    pts = centerline(np.zeros(3), F, np.array([[0.0, 4.0, 0.0], [0.0, 4.0, 0.0]]), np.array([0.1, 0.2]), s)
    expected = np.stack([np.sin(4 * s) / 4, (1 - np.cos(4 * s)) / 4, 0 * s], axis=1)
    assert np.abs(pts - expected).max() < ROUNDOFF_M


def _open(path):
    stage = Usd.Stage.Open(str(path))
    assert stage is not None
    return stage


def _curves(stage, path="/Root/Hair"):
    prim = stage.GetPrimAtPath(path)
    assert prim and prim.IsA(UsdGeom.BasisCurves), path
    return UsdGeom.BasisCurves(prim)


def _primvar(curves, name):
    primvar = UsdGeom.PrimvarsAPI(curves.GetPrim()).GetPrimvar(name)
    assert primvar, name
    return primvar


# --------------------------------------------------------------------------- USD of the hand-made file


@pytest.mark.parametrize("stiffened", [False, True], ids=["material", "stiffened"])
def test_usd_holds_every_shape_in_the_groom_units(tmp_path, stiffened):
    truth = make_stage(tmp_path / "syn.h5", stiffened=stiffened)
    report = export(tmp_path / "syn.h5", tmp_path / "out.usda")
    assert any("records no body" in w for w in report.warnings)
    stage = _open(tmp_path / "out.usda")
    # the groom's units and up axis, as the stage file records them (centimetres, +Z)
    assert UsdGeom.GetStageMetersPerUnit(stage) == pytest.approx(0.01)
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    cm = UsdGeom.GetStageMetersPerUnit(stage)
    hair = _curves(stage)
    assert hair.GetTypeAttr().Get() == UsdGeom.Tokens.linear
    assert list(hair.GetCurveVertexCountsAttr().Get()) == np.diff(truth["offsets"]).tolist()
    points = np.array(hair.GetPointsAttr().Get(Usd.TimeCode.Default()), dtype=np.float64) * cm
    assert np.abs(points - truth["points"]).max() < FLOAT32_M
    # widths: the rod diameter in stage units, per vertex
    widths = np.array(hair.GetWidthsAttr().Get())
    assert hair.GetWidthsInterpolation() == UsdGeom.Tokens.vertex
    assert widths.shape == (len(points),) and np.allclose(widths * cm, 2 * RADIUS, rtol=1e-6)
    # the rest shape: the second prim and the vertex primvar `rest`, both q0 evaluated without load
    rest_shape = expected_rest(truth, stiffened)
    rest_prim = np.array(_curves(stage, "/Root/Rest").GetPointsAttr().Get(), dtype=np.float64) * cm
    rest = _primvar(hair, "rest")
    assert rest.GetInterpolation() == UsdGeom.Tokens.vertex
    assert np.abs(rest_prim - rest_shape).max() < FLOAT32_M
    assert np.abs(np.array(rest.Get(), dtype=np.float64) * cm - rest_shape).max() < FLOAT32_M
    assert np.abs(rest_shape - truth["points"]).max() > 1e-3  # the rest shape is another shape
    # frames: time samples at the run's frame rate, each the frame's centerlines
    assert stage.GetTimeCodesPerSecond() == FPS and stage.GetFramesPerSecond() == FPS
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0.0, N_FRAMES - 1.0)
    assert hair.GetPointsAttr().GetTimeSamples() == [float(k) for k in range(N_FRAMES)]
    for k in range(N_FRAMES):
        at = np.array(hair.GetPointsAttr().Get(Usd.TimeCode(k)), dtype=np.float64) * cm
        assert np.abs(at - expected_frame(truth, k)).max() < FLOAT32_M
    # Unreal groom primvars, per curve
    for name in ("groom_id", "groom_guide", "id"):
        assert _primvar(hair, name).GetInterpolation() == UsdGeom.Tokens.uniform
    assert list(_primvar(hair, "groom_id").Get()) == [0, 1]
    assert list(_primvar(hair, "groom_guide").Get()) == [1, 1]
    # hairinv's quantities: per strand and per vertex
    assert np.allclose(_primvar(hair, "groom_fit_error_max").Get(), [3e-5, 4e-5])
    if stiffened:
        assert list(_primvar(hair, "groom_stiffening").Get()) == [1.0, 2.0]
        # whether each strand rests stably: the stored margin, and its sign as an int flag
        assert np.allclose(_primvar(hair, "groom_stability_margin").Get(), STABILITY_MARGIN, rtol=1e-6)
        stable = _primvar(hair, "groom_stable")
        assert stable.GetInterpolation() == UsdGeom.Tokens.uniform and list(stable.Get()) == [1, 0]
    else:
        for name in ("groom_stiffening", "groom_stability_margin", "groom_stable"):
            assert not UsdGeom.PrimvarsAPI(hair.GetPrim()).GetPrimvar(name)
    force = _primvar(hair, "groom_contact_force")
    assert force.GetInterpolation() == UsdGeom.Tokens.vertex
    assert np.allclose(force.Get(), truth["contact_force"], rtol=1e-6, atol=0)
    # rest curvature of the element holding each vertex
    assert np.allclose(_primvar(hair, "groom_rest_curvature").Get(), _expected_rest_curvature(truth, stiffened),
                       rtol=1e-6)


def _expected_rest_curvature(truth, stiffened=False):
    """Per vertex, the curvature of the rest shape's element holding it, 1/m."""
    rest_omega = OMEGA_REST_STIFFENED if stiffened else OMEGA_REST
    expected = []
    for k, s in enumerate(vertex_arc_lengths(truth["points"], truth["offsets"], ELEMENT_OFFSETS, LENGTH)):
        a, z = ELEMENT_OFFSETS[k], ELEMENT_OFFSETS[k + 1]
        starts = np.concatenate([[0.0], np.cumsum(LENGTH[a:z])])
        e = np.minimum(np.searchsorted(starts, s, side="right") - 1, z - a - 1) + a
        expected.append(np.hypot(rest_omega[e, 0], rest_omega[e, 1]))
    return np.concatenate(expected)


def test_usd_single_shapes(tmp_path):
    truth = make_stage(tmp_path / "syn.h5")
    export(tmp_path / "syn.h5", tmp_path / "rest.usdc", shape="rest")
    export(tmp_path / "syn.h5", tmp_path / "f2.usd", shape="frame:2")
    rest = _open(tmp_path / "rest.usdc")
    assert not rest.GetPrimAtPath("/Root/Rest") and not _curves(rest).GetPointsAttr().GetTimeSamples()
    pts = np.array(_curves(rest).GetPointsAttr().Get(), dtype=np.float64) * 0.01
    assert np.abs(pts - expected_rest(truth)).max() < FLOAT32_M
    frame = _open(tmp_path / "f2.usd")
    pts = np.array(_curves(frame).GetPointsAttr().Get(), dtype=np.float64) * 0.01
    assert np.abs(pts - expected_frame(truth, 2)).max() < FLOAT32_M
    assert (tmp_path / "f2.usd").read_bytes()[:8] == b"PXR-USDC"  # .usd is written as binary crate


def test_usd_up_axis_other_than_y_or_z_is_turned_onto_y(tmp_path):
    truth = make_stage(tmp_path / "syn.h5", up=(1.0, 0.0, 0.0), scale_to_m=1.0, frames=False)
    report = export(tmp_path / "syn.h5", tmp_path / "out.usda")
    assert any("+X to +Y" in line for line in report.lines)
    stage = _open(tmp_path / "out.usda")
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y
    pts = np.array(_curves(stage).GetPointsAttr().Get(), dtype=np.float64)
    # a rotation: distances kept, and the groom's up (+X) became +Y
    d_in = np.linalg.norm(truth["points"][1:] - truth["points"][0], axis=1)
    assert np.allclose(np.linalg.norm(pts[1:] - pts[0], axis=1), d_in, atol=FLOAT32_M)
    R, *_ = np.linalg.lstsq(truth["points"] - truth["points"][0], pts - pts[0], rcond=None)
    assert np.allclose(np.array([1.0, 0.0, 0.0]) @ R, [0.0, 1.0, 0.0], atol=1e-5)


# --------------------------------------------------------------------------- round trips through hairinv's readers

# Turning the groom's up axis onto a format's: the two conventions' rotations, written out by hand.
Z_UP_TO_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])  # (x, y, z) -> (x, z, -y)
Y_UP_TO_Z_UP = Z_UP_TO_Y_UP.T  # (x, y, z) -> (x, -z, y)


@pytest.mark.parametrize("suffix, turn, tolerance", [
    (".usda", np.eye(3), FLOAT32_M), (".usdc", np.eye(3), FLOAT32_M),
    (".hair", np.eye(3), FLOAT32_M),  # Yuksel: +Z up, like the groom
    (".data", Z_UP_TO_Y_UP, FLOAT32_M),
    (".obj", Z_UP_TO_Y_UP, ROUNDOFF_M),  # full float64 text
])
def test_round_trip_through_hairinv_readers(tmp_path, suffix, turn, tolerance):
    """Exported input curves read again by ``load_groom`` (what `hairinv fit` runs): the same strands in
    metres, with gravity along the same physical direction (the format's up is the groom's, turned)."""
    truth = make_stage(tmp_path / "syn.h5")
    out = tmp_path / f"out{suffix}"
    export(tmp_path / "syn.h5", out, shape="input")
    groom, _ = load_groom(out, ImportSettings())
    assert groom.offsets.tolist() == truth["offsets"].tolist()
    assert np.abs(groom.points - truth["points"] @ turn.T).max() < tolerance
    assert np.allclose(groom.up, turn @ UP_Z)


@pytest.mark.parametrize("suffix", [".hair", ".data", ".obj"])
def test_polyline_shapes_are_the_closed_forms(tmp_path, suffix):
    truth = make_stage(tmp_path / "syn.h5")
    turn = np.eye(3) if suffix == ".hair" else Z_UP_TO_Y_UP
    for shape, expected in (("rest", expected_rest(truth)), ("frame:1", expected_frame(truth, 1))):
        out = tmp_path / f"{shape.replace(':', '')}{suffix}"
        export(tmp_path / "syn.h5", out, shape=shape)
        raw = read_curves(out)
        assert raw.offsets.tolist() == truth["offsets"].tolist()
        assert np.abs(raw.points - expected @ turn.T).max() < FLOAT32_M
    if suffix == ".hair":
        raw = read_curves(tmp_path / f"rest{suffix}")
        assert raw.extras["info"].startswith("metres, +Z up; rest shape")


def test_usd_all_reads_back_as_the_input_groom(tmp_path):
    """The rest prim and the time samples are beside the groom: hairinv's reader reads only /Root/Hair."""
    truth = make_stage(tmp_path / "syn.h5")
    export(tmp_path / "syn.h5", tmp_path / "out.usda")
    raw = read_curves(tmp_path / "out.usda")
    assert raw.extras["prims"] == ["/Root/Hair"] and raw.extras["skipped_prims"] == ["/Root/Rest"]
    assert np.abs(raw.points * raw.scale_to_m - truth["points"]).max() < FLOAT32_M


# --------------------------------------------------------------------------- atomic writes, bad input (in-process)


@pytest.mark.parametrize("suffix", [".usda", ".hair", ".data", ".obj"])
def test_failed_export_leaves_an_existing_output_as_it_was(tmp_path, monkeypatch, suffix):
    make_stage(tmp_path / "syn.h5")
    out = tmp_path / f"out{suffix}"
    export(tmp_path / "syn.h5", out, shape="input")
    before = snapshot(tmp_path)

    def interrupted(src, dst):  # the rename is the last step: everything before it was written
        raise KeyboardInterrupt

    monkeypatch.setattr("hairinv.atomic.os.replace", interrupted)
    with pytest.raises(KeyboardInterrupt):
        export(tmp_path / "syn.h5", out, shape="rest")
    assert snapshot(tmp_path) == before  # the old output, and no temporary file
    monkeypatch.undo()
    export(tmp_path / "syn.h5", out, shape="rest")  # succeeding, it replaces the old output
    assert snapshot(tmp_path) != before and sorted(p.name for p in tmp_path.iterdir()) == sorted(before)


@pytest.mark.parametrize("shape, fragment", [
    ("rest", "no /model group"), ("frame:0", "no /frames group"), ("frame:x", "--shape takes"),
])
def test_a_shape_the_file_lacks_is_refused(tmp_path, shape, fragment):
    make_stage(tmp_path / "syn.h5", model=False, frames=False)
    before = snapshot(tmp_path)
    with pytest.raises(InputError, match=fragment):
        export(tmp_path / "syn.h5", tmp_path / "out.usda", shape=shape)
    assert snapshot(tmp_path) == before


# --------------------------------------------------------------------------- the command, on a real model


@pytest.fixture(scope="module")
def real(tmp_path_factory):
    """settled_curly inverted on the sample bust (and its gravity-only inversion), and 0.1-0.2 s of the still
    scene from the model's rest shape, the naive and the gravity-only one, and of the motion and trim scenes."""
    folder = tmp_path_factory.mktemp("export")
    shutil.copyfile(SAMPLES / "settled_curly.h5", folder / "curly.h5")
    shutil.copyfile(SAMPLES / "body.obj", folder / "body.obj")
    for args in (["invert", "curly.h5", "body.obj", "-o", "model.h5"],
                 ["invert", "curly.h5", "body.obj", "--target", "gravity-only", "-o", "gravity.h5"],
                 ["simulate", "model.h5", "--seconds", "0.1", "--fps", "20", "-o", "still.h5"],
                 ["simulate", "model.h5", "--seconds", "0.1", "--fps", "20", "--init", "naive", "-o", "naive.h5"],
                 ["simulate", "model.h5", "--seconds", "0.1", "--fps", "20", "--init", "gravity-only", "-o",
                  "init_gravity.h5"],
                 ["simulate", "model.h5", "--scene", "motion", "--seconds", "0.2", "--fps", "10", "-o", "motion.h5"],
                 ["simulate", "model.h5", "--scene", "trim", "--seconds", "0.1", "--fps", "10", "-o", "trim.h5"]):
        result = hairinv(folder, "-q", *args)
        assert result.returncode == 0, result.stderr
    return folder


def _frames_expected(stage_file, k, layout=None):
    """Frame k of a real stage file, evaluated independently at the vertex arc lengths."""
    s = stages.read_stage(stage_file)
    c, h, f = s["curves"], s["helices"], s["frames"]
    offsets = f["offsets"] if layout == "trimmed" else h["offsets"]
    length = f["length"] if layout == "trimmed" else h["length"]
    s_v = vertex_arc_lengths(c["points"], c["offsets"], h["offsets"], h["length"])
    out = []
    for i in range(len(c["offsets"]) - 1):
        a, z = offsets[i], offsets[i + 1]
        q = s_v[i]
        if layout == "trimmed":
            total = length[a:z].sum()
            q = np.append(q[q < total * (1 - 1e-9)], total)
        out.append(centerline(f["root"][k][i], f["frame0"][k][i], f["omega"][k][a:z], length[a:z], q))
    return out


def test_usd_of_a_real_simulation(real):
    result = hairinv(real, "export", "still.h5", "-o", "still.usda")
    assert result.returncode == 0, result.stderr
    assert result.stderr == ""  # the body was found: no warning
    assert "wrote still.usda" in result.stdout
    s = stages.read_stage(real / "still.h5")
    curves, model, frames = s["curves"], s["model"], s["frames"]
    stage = _open(real / "still.usda")
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0 and UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y
    hair = _curves(stage)
    assert len(hair.GetCurveVertexCountsAttr().Get()) == len(curves["offsets"]) - 1
    assert list(hair.GetCurveVertexCountsAttr().Get()) == np.diff(curves["offsets"]).tolist()
    points = np.array(hair.GetPointsAttr().Get(Usd.TimeCode.Default()), dtype=np.float64)
    assert np.abs(points - curves["points"]).max() < FLOAT32_M
    assert np.allclose(hair.GetWidthsAttr().Get(), 2 * model.attrs["radius"], rtol=1e-6)
    # the rest prim is the model's rest shape (the stiffened one where it has one), evaluated independently
    rest_omega = model["omega_rest_stiffened"] if "omega_rest_stiffened" in model.datasets else model["omega_rest"]
    h = s["helices"]
    expected = evaluate(curves["points"], curves["offsets"], h["offsets"], h["length"], h["root"], h["frame0"],
                        rest_omega)
    assert np.abs(np.array(_curves(stage, "/Root/Rest").GetPointsAttr().Get()) - expected).max() < FLOAT32_M
    # time samples: one per frame at the run's rate, each the frame's centerlines
    fps = float(frames.attrs["fps"])
    assert stage.GetTimeCodesPerSecond() == fps == 20.0
    codes = hair.GetPointsAttr().GetTimeSamples()
    assert codes == [round(t * fps) for t in frames["time"]] == [0.0, 1.0, 2.0]
    for k, code in enumerate(codes):
        at = np.array(hair.GetPointsAttr().Get(Usd.TimeCode(code)), dtype=np.float64)
        assert np.abs(at - np.concatenate(_frames_expected(real / "still.h5", k))).max() < FLOAT32_M
        # a still groom: each frame within the fit tolerance (0.2 mm) of the input vertices
        assert np.abs(at - curves["points"]).max() < 2e-4
    # the body: the recorded mesh, vertex for vertex, triangle for triangle
    body = UsdGeom.Mesh(stage.GetPrimAtPath("/Root/Body"))
    vertices, faces = obj_mesh(real / "body.obj")
    assert np.abs(np.array(body.GetPointsAttr().Get()) - vertices).max() < FLOAT32_M
    assert len(body.GetFaceVertexCountsAttr().Get()) == len(faces)


def test_usd_carries_the_body_motion(real):
    result = hairinv(real, "export", "motion.h5", "-o", "motion.usdc")
    assert result.returncode == 0, result.stderr
    frames = stages.read_stage(real / "motion.h5")["frames"]
    stage = _open(real / "motion.usdc")
    body = UsdGeom.Xformable(stage.GetPrimAtPath("/Root/Body"))
    hair = _curves(stage)
    offsets = stages.read_stage(real / "motion.h5")["curves"]["offsets"]
    for k, T in enumerate(frames["body_transform"]):
        usd = np.array(body.GetLocalTransformation(Usd.TimeCode(k)))
        assert np.allclose(usd.T, T, atol=1e-12)  # USD matrices act on row vectors
        at = np.array(hair.GetPointsAttr().Get(Usd.TimeCode(k)), dtype=np.float64)
        assert np.abs(at[offsets[:-1]] - frames["root"][k]).max() < FLOAT32_M
    assert not np.allclose(frames["body_transform"][-1], np.eye(4))


def test_usd_of_a_trimmed_run_keeps_the_frames_on_their_own_prim(real):
    result = hairinv(real, "export", "trim.h5", "-o", "trim.usda")
    assert result.returncode == 0, result.stderr
    stage = _open(real / "trim.usda")
    trimmed = _curves(stage, "/Root/Frames")
    expected = _frames_expected(real / "trim.h5", 1, layout="trimmed")
    assert list(trimmed.GetCurveVertexCountsAttr().Get()) == [len(p) for p in expected]
    at = np.array(trimmed.GetPointsAttr().Get(Usd.TimeCode(1)), dtype=np.float64)
    assert np.abs(at - np.concatenate(expected)).max() < FLOAT32_M
    assert sum(len(p) for p in expected) < len(stages.read_stage(real / "trim.h5")["curves"]["points"])
    assert not _curves(stage).GetPointsAttr().GetTimeSamples()  # the input prim is not animated


def test_a_removed_body_is_hidden_during_the_frames(real, tmp_path):
    shutil.copyfile(real / "model.h5", tmp_path / "model.h5")
    shutil.copyfile(real / "body.obj", tmp_path / "body.obj")
    result = hairinv(tmp_path, "-q", "simulate", "model.h5", "--scene", "remove-body", "--seconds", "0.1", "--fps",
                     "10", "-o", "removed.h5")
    assert result.returncode == 0, result.stderr
    result = hairinv(tmp_path, "export", "removed.h5", "-o", "removed.usda")
    assert result.returncode == 0, result.stderr
    stage = _open(tmp_path / "removed.usda")  # held: its prims are valid only while the stage lives
    body = UsdGeom.Imageable(stage.GetPrimAtPath("/Root/Body"))
    assert body.ComputeVisibility(Usd.TimeCode.Default()) == UsdGeom.Tokens.inherited  # the input, on its body
    assert body.ComputeVisibility(Usd.TimeCode(0)) == UsdGeom.Tokens.invisible


def test_round_trip_of_a_real_groom_through_fit_input(real, tmp_path):
    """A Y-up groom: .hair turns it onto +Z, the others keep it; `hairinv fit` reads each back."""
    points = stages.read_stage(real / "model.h5")["curves"]["points"]
    for suffix, turn in ((".hair", Y_UP_TO_Z_UP), (".data", np.eye(3)), (".obj", np.eye(3)), (".usda", np.eye(3))):
        out = tmp_path / f"curly{suffix}"
        result = hairinv(real, "export", "model.h5", "-o", out, "--shape", "input")
        assert result.returncode == 0, result.stderr
        groom, _ = load_groom(out, ImportSettings())
        assert np.abs(groom.points - points @ turn.T).max() < FLOAT32_M, suffix


def _copied_with_a_changed_body(real, folder):
    """The real model copied into ``folder`` as if it had been made there against ``folder/body.obj``, which
    has changed since: every recorded body path (as given, and absolute) points at the changed copy, so no
    unchanged body is left to find."""
    shutil.copyfile(real / "model.h5", folder / "model.h5")
    (folder / "body.obj").write_bytes((real / "body.obj").read_bytes() + b"# changed\n")
    with h5py.File(folder / "model.h5", "r+") as fh:
        for group in fh.values():
            inputs = json.loads(group.attrs["inputs"])
            for record in inputs:
                if record.get("name") == "body.obj":
                    record.update(path="body.obj", abspath=str((folder / "body.obj").resolve()))
            group.attrs["inputs"] = json.dumps(inputs)


def test_a_changed_body_is_left_out_with_a_warning(real, tmp_path):
    _copied_with_a_changed_body(real, tmp_path)
    result = hairinv(tmp_path, "export", "model.h5", "-o", "out.usda")
    assert result.returncode == 0, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "warning" in lines[0] and "SHA-256" in lines[0] and "model.h5" in lines[0]
    stage = _open(tmp_path / "out.usda")
    assert stage.GetPrimAtPath("/Root/Hair") and not stage.GetPrimAtPath("/Root/Body")


def _bad(real, folder):
    for name in ("model.h5", "still.h5", "body.obj"):
        shutil.copyfile(real / name, folder / name)
    (folder / "mesh.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (folder / "notes.txt").write_text("precious\n")
    (folder / "notes.json").write_text('{"precious": true}\n')


@pytest.mark.parametrize("args, name, fragment", [
    (["model.h5", "-o", "out.txt"], "out.txt", ".usda"),
    (["model.h5", "-o", "out"], "out", ".hair"),
    (["model.h5", "-o", "out.usda", "--shape", "frame:0"], "model.h5", "no /frames group"),
    (["still.h5", "-o", "out.obj", "--shape", "frame:3"], "still.h5", "no frame 3"),
    (["still.h5", "-o", "out.obj", "--shape", "all"], "out.obj", "one shape"),
    (["still.h5", "-o", "out.usda", "--shape", "sideways"], "sideways", "--shape takes"),
    (["missing.h5", "-o", "out.usda"], "missing.h5", "no such file"),
    (["notes.txt", "-o", "out.usda"], "notes.txt", "not a hairinv stage file"),
    (["model.h5", "-o", "nodir/out.usda"], "nodir", "does not exist"),
    (["model.h5", "-o", "body.obj"], "body.obj", "input"),
    (["model.h5", "-o", "mesh.obj"], "mesh.obj", "refusing to overwrite"),
    (["model.h5", "-o", "notes.json"], "notes.json", "refusing to overwrite"),
    (["model.h5", "-o", "out.json", "--shape", "rest"], "out.json", "--shape does not apply"),
    (["model.h5", "-o", "out.obj", "--color", "fit-error"], "out.obj", "--color applies to"),
], ids=["unknown suffix", "no suffix", "no frames", "frame out of range", "all in OBJ", "bad shape",
        "missing file", "not a stage file", "missing folder", "over the body", "over a mesh", "over a json file",
        "shape of a summary", "colour of a polyline"])
def test_bad_input_exits_2_with_one_sentence_and_writes_nothing(real, tmp_path, args, name, fragment):
    _bad(real, tmp_path)
    assert_refused(tmp_path, ["export", *args], name, fragment)


def test_rest_of_a_fitted_file_is_refused(real, tmp_path):
    shutil.copyfile(real / "curly.h5", tmp_path / "curly.h5")
    assert_refused(tmp_path, ["export", "curly.h5", "-o", "rest.hair", "--shape", "rest"], "curly.h5",
                   "no /model group")


def test_an_existing_hairstyle_output_is_replaced(real, tmp_path):
    shutil.copyfile(real / "model.h5", tmp_path / "model.h5")
    for shape in ("input", "rest"):
        result = hairinv(tmp_path, "export", "model.h5", "-o", "out.obj", "--shape", shape)
        assert result.returncode == 0, result.stderr
    assert "rest shape" in (tmp_path / "out.obj").read_text().splitlines()[1]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model.h5", "out.obj"]


def test_the_docs_export_examples_run_as_written(real, tmp_path):
    """The commands of docs/export.md's examples, on the curly model and a run of it."""
    page = (SAMPLES.parent / "docs" / "export.md").read_text()
    section = page.split("\n## Examples\n", 1)[1].split("```sh", 1)[1].split("```", 1)[0]
    commands = [line.split() for line in section.strip().splitlines()]
    assert len(commands) == 7 and all(c[:2] == ["hairinv", "export"] for c in commands)
    shutil.copyfile(real / "model.h5", tmp_path / "curly.model.h5")
    shutil.copyfile(real / "still.h5", tmp_path / "curly.frames.h5")
    shutil.copyfile(real / "naive.h5", tmp_path / "curly.naive.frames.h5")
    shutil.copyfile(real / "body.obj", tmp_path / "body.obj")
    for command in commands:
        result = hairinv(tmp_path, *command[1:])
        assert result.returncode == 0, (command, result.stderr)
        assert result.stderr == ""
        out = tmp_path / command[command.index("-o") + 1]
        if out.suffix == ".json":
            summary = json.loads(out.read_text())
            assert summary["groups"]["curves"]["strands"] == 40 and summary["groups"]["frames"]["frames"] == 3
        elif out.suffix == ".png" and command.index("-o") > 3:  # several stage files: side by side
            pixels, text = _png(out)
            inits = [column["init"] for column in json.loads(text["hairinv:columns"])]
            assert inits == [_h5(tmp_path / name)["frames"]["attrs"]["init"] for name in command[2:-2]]
            assert _body_pixels(pixels) > 0.05 * pixels.shape[0] * pixels.shape[1]
        elif out.suffix == ".png":
            pixels, text = _png(out)
            assert pixels.shape[:2] == (1300, 1200) and text["hairinv:quantity"] == "contact-force"
            assert _body_pixels(pixels) > 0.05 * pixels.shape[0] * pixels.shape[1]
        elif out.suffix == ".html":
            _assert_offline(out)
            assert _inlined_pngs(out)[0][0] == (1200, 1300)
        else:
            assert read_curves(out).n_strands == 40
    stage = _open(tmp_path / "curly.usda")
    assert stage.GetPrimAtPath("/Root/Body").IsA(UsdGeom.Mesh)


# --------------------------------------------------------------------------- JSON summary

# Statistics recomputed here in float64 from the same datasets: equal to round-off.
SUMMARY_RTOL = 1e-12


def _h5(path):
    """Every dataset and attribute of a stage file, read with h5py alone (not hairinv.stages)."""

    out = {}
    with h5py.File(path, "r") as fh:
        for name, group in fh.items():
            out[name] = {key: group[key][()] for key in group}
            attrs = {key: group.attrs[key] for key in group.attrs}
            attrs["config"] = json.loads(attrs.get("config", "{}"))
            out[name]["attrs"] = attrs
        out["attrs"] = dict(fh.attrs)
    return out


def _assert_stats(stats, values, scale=1.0):
    values = np.asarray(values, dtype=np.float64).ravel() * scale
    expected = {"min": values.min(), "median": np.median(values), "max": values.max(), "mean": values.mean()}
    assert stats.keys() == expected.keys()
    for key, value in expected.items():
        assert stats[key] == pytest.approx(value, rel=SUMMARY_RTOL, abs=0), key


def _assert_summary(summary, path):
    """Every figure of the JSON summary against the file's datasets."""
    f = _h5(path)
    assert summary["schema"] == 1 and summary["file"] == path.name
    assert summary["producer"] == f["attrs"]["producer"] and summary["stages"] == f["attrs"]["stages"]
    assert list(summary["groups"]) == ["curves", "helices", "contacts", "model", "frames"]
    for name in summary["groups"]:
        assert (summary["groups"][name] is None) == (name not in f)
    c = summary["groups"]["curves"]
    offsets, points = f["curves"]["offsets"], f["curves"]["points"]
    assert (c["strands"], c["points"]) == (len(offsets) - 1, len(points))
    _assert_stats(c["points_per_strand"], np.diff(offsets))
    lengths = [np.linalg.norm(np.diff(points[a:z], axis=0), axis=1).sum() for a, z in itertools.pairwise(offsets)]
    _assert_stats(c["length_m"], lengths)
    assert c["bbox_min_m"] == points.min(axis=0).tolist() and c["bbox_max_m"] == points.max(axis=0).tolist()
    h = summary["groups"]["helices"]
    assert h["elements"] == len(f["helices"]["length"]) == f["helices"]["offsets"][-1]
    _assert_stats(h["fit_error_mean_mm"], f["helices"]["fit_error"][:, 0], 1e3)
    _assert_stats(h["fit_error_max_mm"], f["helices"]["fit_error"][:, 1], 1e3)
    omega = f["helices"]["omega"]
    _assert_stats(h["curvature_1_per_m"], np.sqrt(omega[:, 0] ** 2 + omega[:, 1] ** 2))
    tolerance = f["helices"]["attrs"]["config"].get("fit", {}).get("tolerance")
    if tolerance is not None:
        assert h["strands_over_tolerance"] == int((f["helices"]["fit_error"][:, 1] > tolerance).sum())
    if "contacts" in f:
        k = summary["groups"]["contacts"]
        strand, force = f["contacts"]["strand"], f["model"]["force"]
        body = strand[:, 1] == -1
        carrying = force[:, 0] > f["model"]["attrs"].get("carrying_threshold", 0.0)  # as invert counts
        assert (k["contacts"], k["hair_body"], k["hair_hair"]) == (len(strand), body.sum(), (~body).sum())
        assert k["carrying_force"] == carrying.sum() == summary["groups"]["model"]["contacts_carrying_force"]
        settings = f["contacts"]["attrs"]["config"].get("contacts", {})
        for kind, mask, distance, rule in (("hair_body", body, "body_distance", "layer"),
                                           ("hair_hair", ~body, "hair_distance", "wisp")):
            entry = k["by_kind"][kind]
            assert entry["declared"] == mask.sum() and entry["carrying_force"] == (mask & carrying).sum()
            if "gap" in f["contacts"]:
                gap = f["contacts"]["gap"]
                beyond = int((mask & (gap >= settings[distance])).sum())
                assert entry["by_rule"] == {"distance": int(mask.sum()) - beyond, rule: beyond}
            else:
                assert entry["by_rule"] is None and entry["gap_mm"] is None
    if "model" in f:
        m, g = summary["groups"]["model"], f["model"]
        assert m["status"] == g["attrs"].get("status", "") and m["sweeps"] == g["attrs"]["iterations"]
        assert m["residual_N"] == g["attrs"]["residual"] and m["solve_seconds"] == g["attrs"]["seconds"]
        assert summary["timings_s"]["invert"] == g["attrs"]["seconds"]
        assert m["gamma"] == g["attrs"]["gamma"] and m["gamma_relative"] == g["attrs"].get("gamma_relative", 0.0)
        assert m["method"] == g["attrs"].get("method", "sweeps")
        assert m["rest_bound_1_per_m"] == g["attrs"].get("rest_bound")
        rest = g.get("omega_rest_stiffened", g["omega_rest"])
        _assert_stats(m["drift_from_target_1_per_m"], np.linalg.norm(rest - g["omega_target"], axis=1))
        _assert_stats(m["rest_curvature_1_per_m"], np.sqrt(rest[:, 0] ** 2 + rest[:, 1] ** 2))
        if "residual_history" in g:
            assert m["residual_history"] == g["residual_history"].tolist()
        if "stiffening" in g:
            factor = g["stiffening"]
            assert m["stiffened"] == [{"strand": i, "factor": factor[i]} for i in np.flatnonzero(factor > 1)]
            assert m["strands_stiffened"] == int((factor > 1).sum())
        else:
            assert m["stiffened"] is None and m["strands_stiffened"] is None
        if "stability_margin" in g:
            margin = g["stability_margin"]
            assert m["unstable_strands"] == np.flatnonzero(margin < -1e-6).tolist()
            _assert_stats(m["stability_margin"], margin[np.isfinite(margin)])
        else:  # stability not checked, or a file written before the margins were stored
            assert m["unstable_strands"] is None and m["stability_margin"] is None
    # each stage's own computing time where the file records it (files from before: null)
    for stage, group in (("fit", "helices"), ("detect", "contacts"), ("simulate", "frames")):
        recorded = f[group]["attrs"].get("seconds") if group in f else None
        assert summary["timings_s"][stage] == recorded
    if "frames" in f and "frame_seconds" in f["frames"]:
        assert f["frames"]["attrs"]["seconds"] == pytest.approx(f["frames"]["frame_seconds"].sum(), rel=1e-12)
    if "frames" in f:
        r, g = summary["groups"]["frames"], f["frames"]
        assert r["frames"] == len(g["time"]) and r["seconds"] == g["time"][-1]
        assert r["fps"] == g["attrs"]["fps"]
        if "displacement" in g:
            assert r["largest_displacement_mm"] == pytest.approx(1e3 * g["displacement"].max(), rel=SUMMARY_RTOL)
            _assert_stats(r["contacts"], g["contact_count"])
            _assert_stats(r["solver_relative_residual"], g["solver_residual"])


@pytest.mark.parametrize("stiffened", [False, True], ids=["material", "stiffened"])
def test_json_summary_of_the_hand_made_file(tmp_path, stiffened):

    make_stage(tmp_path / "syn.h5", stiffened=stiffened)
    report = export(tmp_path / "syn.h5", tmp_path / "syn.json")
    assert report.lines[0].startswith(f"wrote {tmp_path / 'syn.json'}: JSON summary (schema 1)")
    summary = json.loads((tmp_path / "syn.json").read_text())
    _assert_summary(summary, tmp_path / "syn.h5")
    assert summary["groups"]["contacts"]["by_kind"]["hair_hair"]["declared"] == 1
    if stiffened:
        assert summary["groups"]["model"]["stiffened"] == [{"strand": 1, "factor": 2.0}]
        assert any("1 strand was stiffened" in w for w in summary["warnings"])


def test_json_summary_of_a_fitted_file_has_every_key(tmp_path):
    """The keys are the same whatever the file holds: a group the file lacks is null."""

    make_stage(tmp_path / "full.h5", frames=True)
    make_stage(tmp_path / "fit.h5", model=False, frames=False)
    export(tmp_path / "full.h5", tmp_path / "full.json")
    export(tmp_path / "fit.h5", tmp_path / "fit.json")
    full, fit = (json.loads((tmp_path / f"{n}.json").read_text()) for n in ("full", "fit"))
    assert list(full) == list(fit)
    assert [k for k, v in fit["groups"].items() if v is None] == ["contacts", "model", "frames"]
    assert fit["timings_s"] == {"fit": None, "detect": None, "invert": None, "simulate": None}
    assert list(full["groups"]["helices"]) == list(fit["groups"]["helices"])
    _assert_summary(fit, tmp_path / "fit.h5")


@pytest.mark.parametrize("name", ["curly.h5", "model.h5", "still.h5", "trim.h5"])
def test_json_summary_of_real_files(real, tmp_path, name):

    result = hairinv(real, "export", name, "-o", tmp_path / "out.json")
    assert result.returncode == 0, result.stderr
    summary = json.loads((tmp_path / "out.json").read_text())
    _assert_summary(summary, real / name)
    # the same summary as `hairinv info --json`
    info = hairinv(real, "info", "--json", name)
    assert info.returncode == 0, info.stderr
    assert json.loads(info.stdout) == summary
    if name != "curly.h5":
        rules = summary["groups"]["contacts"]["by_kind"]["hair_body"]["by_rule"]
        assert rules["layer"] > 0 and rules["distance"] > 0  # the sample groom has a hair layer
        # the sample's /helices were fitted elsewhere (copied, no time); detect and simulate ran here
        assert summary["timings_s"]["fit"] is None and summary["timings_s"]["detect"] > 0
        assert (summary["timings_s"]["simulate"] is None) == (name == "model.h5")


# --------------------------------------------------------------------------- PNG


def _png(path):
    """(height, width, channels) of the PNG read back by matplotlib, and its text chunks read by Pillow."""
    import matplotlib.image
    from PIL import Image  # a dependency of matplotlib

    pixels = matplotlib.image.imread(path, format="png")
    with Image.open(path) as image:
        assert image.format == "PNG"
        text = dict(image.text)
    return pixels, text


def _body_pixels(pixels) -> int:
    """Pixels of the light grey the body is drawn in (r = g = b between its two shades)."""
    rgb = pixels[..., :3]
    grey = (np.ptp(rgb, axis=-1) < 1e-3) & (rgb[..., 0] >= 0.72 - 1e-3) & (rgb[..., 0] <= 0.9 + 1e-3)
    return int(grey.sum())


@pytest.mark.parametrize("color, unit, expected", [
    ("contact-force", "mN", lambda truth: 1e3 * truth["contact_force"]),
    ("rest-curvature", "1/m", lambda truth: _expected_rest_curvature(truth, stiffened=True)),
    ("stiffening", "x material stiffness", lambda truth: np.array([1.0, 2.0])),
    ("fit-error", "mm", lambda truth: 1e3 * np.array([3e-5, 4e-5])),  # /helices/fit_error[:, 1] of make_stage
])
def test_png_colour_range_is_the_quantity_range(tmp_path, color, unit, expected):
    truth = make_stage(tmp_path / "syn.h5", stiffened=True)
    report = export(tmp_path / "syn.h5", tmp_path / "out.png", color=color)
    pixels, text = _png(tmp_path / "out.png")
    assert pixels.shape[:2] == (1300, 1200)  # two rows of views: the file has /frames
    values = expected(truth)
    assert text["hairinv:quantity"] == color and text["hairinv:unit"] == unit
    assert float(text["hairinv:min"]) == pytest.approx(values.min(), rel=1e-9, abs=1e-15)
    assert float(text["hairinv:max"]) == pytest.approx(values.max(), rel=1e-9)
    assert any(line.startswith("colour: ") and unit in line for line in report.lines)
    assert _body_pixels(pixels) < 0.01 * pixels.shape[0] * pixels.shape[1]  # no body: only the lines' edges


def test_png_defaults_and_size(tmp_path):
    make_stage(tmp_path / "model.h5", frames=False)
    make_stage(tmp_path / "fit.h5", model=False, frames=False)
    for name, default in (("model", "contact-force"), ("fit", "fit-error")):
        export(tmp_path / f"{name}.h5", tmp_path / f"{name}.png")
        pixels, text = _png(tmp_path / f"{name}.png")
        assert pixels.shape[:2] == (700, 1200) and text["hairinv:quantity"] == default
    export(tmp_path / "model.h5", tmp_path / "model.png", color="rest-curvature")  # a PNG is replaced
    assert _png(tmp_path / "model.png")[1]["hairinv:quantity"] == "rest-curvature"


def test_png_of_a_real_simulation(real, tmp_path):
    result = hairinv(real, "export", "still.h5", "-o", tmp_path / "still.png", "--color", "fit-error")
    assert result.returncode == 0, result.stderr
    assert result.stderr == "" and "body: body.obj" in result.stdout
    pixels, text = _png(tmp_path / "still.png")
    assert pixels.shape[:2] == (1300, 1200)
    error = 1e3 * _h5(real / "still.h5")["helices"]["fit_error"][:, 1]
    assert float(text["hairinv:min"]) == pytest.approx(error.min(), rel=1e-12)
    assert float(text["hairinv:max"]) == pytest.approx(error.max(), rel=1e-12)
    assert _body_pixels(pixels) > 0.05 * pixels.shape[0] * pixels.shape[1]  # the bust, drawn behind the hair


def test_png_of_a_turning_head_carries_the_input_with_the_body(real, tmp_path):
    """The motion scene turns the head: the before/after row carries the input with the body to the last
    frame's pose, and the distance it prints is the last frame's from the input so carried."""
    result = hairinv(real, "export", "motion.h5", "-o", tmp_path / "motion.png")
    assert result.returncode == 0, result.stderr
    [line] = [line for line in result.stdout.splitlines() if line.startswith("before/after")]
    assert "moved with the body" in line
    f = _h5(real / "motion.h5")
    last = len(f["frames"]["time"]) - 1
    T = f["frames"]["body_transform"][last]
    assert np.linalg.norm(T[:3, :3] - np.eye(3)) > 0.1  # the head has turned
    carried = f["curves"]["points"] @ T[:3, :3].T + T[:3, 3]
    frame = np.concatenate(_frames_expected(real / "motion.h5", last))
    expected = 1e3 * np.linalg.norm(frame - carried, axis=1).max()
    printed = float(line.split("at most ")[1].split(" mm")[0])
    assert printed == pytest.approx(expected, rel=5e-3)  # printed to 3 significant digits
    # the distance in the world frame, which adds the turn (8 degrees at 0.2 s), is not the one printed
    world = 1e3 * np.linalg.norm(frame - f["curves"]["points"], axis=1).max()
    assert abs(world - printed) > 1.0


def test_png_contact_force_scale_is_the_quantiles_of_the_dotted_forces(real, tmp_path):
    """The dots are the vertices whose net force exceeds the model's carrying threshold; the colour bar runs
    between numpy's 2nd and 98th percentiles of their forces (the forces read from the USD export)."""
    assert hairinv(real, "export", "model.h5", "-o", tmp_path / "model.png").returncode == 0
    assert hairinv(real, "export", "model.h5", "-o", tmp_path / "model.usda").returncode == 0
    usd = _open(tmp_path / "model.usda")
    force = 1e3 * np.array(_primvar(_curves(usd), "groom_contact_force").Get(), dtype=np.float64)
    floor = 1e3 * _h5(real / "model.h5")["model"]["attrs"]["carrying_threshold"]
    dotted = force[force > floor]
    lo, hi = np.quantile(dotted, [0.02, 0.98], method="inverted_cdf")
    _, text = _png(tmp_path / "model.png")
    assert hi >= 100 * lo and text["hairinv:scale"] == "log, 2-98 % quantiles"  # forces spanning decades
    # float32 in USD: 1e-7 relative
    assert float(text["hairinv:bar_min"]) == pytest.approx(lo, rel=1e-6)
    assert float(text["hairinv:bar_max"]) == pytest.approx(hi, rel=1e-6)
    assert float(text["hairinv:max"]) == pytest.approx(force.max(), rel=1e-6)


@pytest.mark.parametrize("args, name, fragment", [
    (["model.h5", "-o", "out.png", "--color", "curliness"], "out.png", "--color takes contact-force"),
    (["curly.h5", "-o", "out.png", "--color", "contact-force"], "curly.h5", "no /model group"),
    (["fit.h5", "-o", "out.png", "--color", "stiffening"], "fit.h5", "no stiffening factors"),
    (["model.h5", "-o", "notes.png"], "notes.png", "refusing to overwrite"),
    (["model.h5", "-o", "out.png", "--shape", "rest"], "out.png", "--shape does not apply"),
], ids=["unknown quantity", "force of a fitted file", "stiffening of a fitted file", "over a text file",
        "shape of a picture"])
def test_bad_png_input_exits_2_and_writes_nothing(real, tmp_path, args, name, fragment):
    _bad(real, tmp_path)
    shutil.copyfile(real / "curly.h5", tmp_path / "curly.h5")
    make_stage(tmp_path / "fit.h5", model=False, frames=False)
    (tmp_path / "notes.png").write_text("precious\n")
    assert_refused(tmp_path, ["export", *args], name, fragment)


# --------------------------------------------------------------------------- HTML report


def _html(path):
    """Every tag's attributes and the text of an HTML file, parsed by the standard library."""
    from html.parser import HTMLParser

    class Parser(HTMLParser):
        def __init__(self):
            super().__init__()
            self.tags, self.text = [], []

        def handle_starttag(self, tag, attrs):
            self.tags.append((tag, dict(attrs)))

        def handle_data(self, data):
            self.text.append(data)

    parser = Parser()
    parser.feed(path.read_text(encoding="utf-8"))
    parser.close()
    return parser.tags, " ".join(parser.text)


def _assert_offline(path):
    """No attribute points outside the file (only data: URLs), and nothing names a remote address."""
    tags, _ = _html(path)
    for tag, attrs in tags:
        for name in ("src", "href", "srcset", "action", "data", "poster"):
            if name in attrs:
                assert attrs[name].startswith("data:") or attrs[name].startswith("#"), (tag, attrs)
        assert tag not in ("script", "link", "iframe", "object", "embed"), tag
    raw = path.read_text(encoding="utf-8")
    assert "http:" not in raw and "https:" not in raw and "url(" not in raw and "@import" not in raw


def _inlined_pngs(path):
    """(size, text chunks) of every image of an HTML file, each a PNG inlined as a data: URL, in page order."""
    import base64
    import io

    from PIL import Image

    out = []
    for tag, attrs in _html(path)[0]:
        if tag == "img":
            assert attrs["src"].startswith("data:image/png;base64,")
            data = base64.b64decode(attrs["src"].split(",", 1)[1], validate=True)
            with Image.open(io.BytesIO(data)) as image:
                image.load()  # decodes every pixel
                assert (int(attrs["width"]), int(attrs["height"])) == image.size
                out.append((image.size, dict(image.text)))
    return out


def test_html_report_of_a_real_simulation(real, tmp_path):
    result = hairinv(real, "export", "still.h5", "-o", tmp_path / "still.html", "--color", "rest-curvature")
    assert result.returncode == 0, result.stderr
    assert result.stderr == ""
    out = tmp_path / "still.html"
    _assert_offline(out)
    (size, text), (plot_size, plot_text) = _inlined_pngs(out)  # the groom, then the solver's convergence
    assert size == (1200, 1300) and text["hairinv:quantity"] == "rest-curvature"
    assert plot_size == (1000, 600) and plot_text["hairinv:plot"] == "convergence"
    history = _h5(real / "still.h5")["model"]["residual_history"]
    assert json.loads(plot_text["hairinv:sweeps"]) == history[:, 0].tolist()
    # the tables hold the JSON summary: every group, and its figures
    summary = json.loads(hairinv(real, "info", "--json", "still.h5").stdout)
    _, words = _html(out)
    for name in ("curves", "helices", "contacts", "model", "frames"):
        assert f"/{name}" in words
    f = _h5(real / "still.h5")
    assert summary["sha256"] in words and f["attrs"]["producer"] in words
    assert f"{len(f['contacts']['mu'])}" in words and f"{len(f['frames']['time'])}" in words


def test_html_report_of_the_hand_made_file(tmp_path):
    make_stage(tmp_path / "syn.h5", stiffened=True)
    report = export(tmp_path / "syn.h5", tmp_path / "syn.html")
    assert report.lines[0].startswith(f"wrote {tmp_path / 'syn.html'}: HTML report")
    _assert_offline(tmp_path / "syn.html")
    [(size, text)] = _inlined_pngs(tmp_path / "syn.html")
    assert size == (1200, 1300) and text["hairinv:quantity"] == "contact-force"
    _, words = _html(tmp_path / "syn.html")
    assert "1 strand was stiffened" in words  # the summary's warning
    # the hand-made model stores no residual history: said, and no plot
    assert "No convergence plot: syn.h5 records no residual history" in words
    export(tmp_path / "syn.h5", tmp_path / "syn.html", color="fit-error")  # a report it wrote is replaced
    assert _inlined_pngs(tmp_path / "syn.html")[0][1]["hairinv:quantity"] == "fit-error"


@pytest.mark.parametrize("args, name, fragment", [
    (["model.h5", "-o", "notes.html"], "notes.html", "refusing to overwrite"),
    (["model.h5", "-o", "out.html", "--shape", "input"], "out.html", "--shape does not apply"),
    (["model.h5", "-o", "out.html", "--color", "heat"], "out.html", "--color takes"),
], ids=["over another page", "shape of a report", "unknown quantity"])
def test_bad_html_input_exits_2_and_writes_nothing(real, tmp_path, args, name, fragment):
    _bad(real, tmp_path)
    (tmp_path / "notes.html").write_text("<html><body>precious</body></html>\n")
    assert_refused(tmp_path, ["export", *args], name, fragment)


def test_a_changed_body_is_left_out_of_the_picture_with_a_warning(real, tmp_path):
    _copied_with_a_changed_body(real, tmp_path)
    result = hairinv(tmp_path, "export", "model.h5", "-o", "out.png")
    assert result.returncode == 0, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "warning" in lines[0] and "SHA-256" in lines[0] and "picture has no body" in lines[0]
    pixels, _ = _png(tmp_path / "out.png")
    assert _body_pixels(pixels) < 0.01 * pixels.shape[0] * pixels.shape[1]


# --------------------------------------------------------------------------- several simulations side by side

# hairinv.rod against the closed forms here, along a real strand of up to a hundred elements: round-off
# chained over the elements' rotations, well below a nanometre.
CHAINED_MM = 1e-6


def _columns(text) -> list[dict]:
    return json.loads(text["hairinv:columns"])


def _moved_hand_made(truth, growth) -> np.ndarray:
    """mm per vertex: the hand-made file's last frame against frame 0 in the body's frame, where the roots and
    root frames stay put and only the shape grows (``OMEGA * (1 + growth k)``)."""
    frames = np.stack([FRAME0, FRAME0])
    at = [evaluate(truth["points"], truth["offsets"], ELEMENT_OFFSETS, LENGTH, ROOTS, frames,
                   OMEGA * (1.0 + growth * k)) for k in (0, N_FRAMES - 1)]
    return 1e3 * np.linalg.norm(at[1] - at[0], axis=1)


def _moved_real(path) -> np.ndarray:
    """mm per vertex: a real run's last frame against its frame 0, in the body's frame (each frame undone by the
    inverse of its /frames/body_transform), evaluated independently of hairinv."""
    f = _h5(path)["frames"]

    def in_body(k):
        world = np.concatenate(_frames_expected(path, k))
        return (np.c_[world, np.ones(len(world))] @ np.linalg.inv(f["body_transform"][k]).T)[:, :3]

    return 1e3 * np.linalg.norm(in_body(len(f["time"]) - 1) - in_body(0), axis=1)


def test_comparison_colours_by_displacement_in_the_body_frame(tmp_path):
    """Two hand-made runs of one groom whose body moves and turns: each column's displacement is the shape's
    change alone (the body's motion undone), and the colour scale is the larger run's."""
    a = make_stage(tmp_path / "a.h5", growth=0.05, init="inverted")
    b = make_stage(tmp_path / "b.h5", growth=0.3, init="naive")
    moved = [_moved_hand_made(a, 0.05), _moved_hand_made(b, 0.3)]
    report = export([tmp_path / "a.h5", tmp_path / "b.h5"], tmp_path / "ab.png")
    assert report.lines[0].startswith(f"wrote {tmp_path / 'ab.png'}: PNG") and "2 simulations" in report.lines[0]
    pixels, text = _png(tmp_path / "ab.png")
    columns = _columns(text)
    assert [c["file"] for c in columns] == ["a.h5", "b.h5"] and [c["init"] for c in columns] == ["inverted", "naive"]
    assert [c["target"] for c in columns] == ["actual", "actual"]
    for column, expected in zip(columns, moved):
        assert column["largest_displacement_mm"] == pytest.approx(expected.max(), rel=1e-9)
        assert column["time_s"] == pytest.approx((N_FRAMES - 1) / FPS, rel=1e-12)
    assert text["hairinv:quantity"] == "displacement" and text["hairinv:unit"] == "mm"
    assert float(text["hairinv:min"]) == 0.0
    assert float(text["hairinv:max"]) == pytest.approx(max(m.max() for m in moved), rel=1e-9)
    # the distance in the world frame, which adds the body's motion (a turn and 4.5 mm), is not what is shown
    T = body_motion(N_FRAMES - 1)
    world = evaluate(b["points"], b["offsets"], ELEMENT_OFFSETS, LENGTH, ROOTS @ T[:3, :3].T + T[:3, 3],
                     np.stack([FRAME0 @ T[:3, :3].T] * 2), OMEGA * (1.0 + 0.3 * (N_FRAMES - 1)))
    start = evaluate(b["points"], b["offsets"], ELEMENT_OFFSETS, LENGTH, ROOTS, np.stack([FRAME0] * 2), OMEGA)
    assert abs(1e3 * np.linalg.norm(world - start, axis=1).max() - float(text["hairinv:max"])) > 1.0


def test_comparison_grows_by_one_column_per_file(tmp_path):
    for name, growth in (("a", 0.05), ("b", 0.2), ("c", 0.3)):
        make_stage(tmp_path / f"{name}.h5", growth=growth)
    sizes = []
    for names in (["a", "b"], ["a", "b", "c"], ["a", "b", "c", "a"]):
        export([tmp_path / f"{n}.h5" for n in names], tmp_path / "out.png")
        pixels, text = _png(tmp_path / "out.png")
        sizes.append(pixels.shape[:2])
        assert [c["file"] for c in _columns(text)] == [f"{n}.h5" for n in names]
    (h2, w2), (h3, w3), (h4, w4) = sizes
    assert h2 == h3 == h4 and w3 - w2 == w4 - w3 > 300  # the same views, one column wider each time


def test_comparison_of_real_runs(real, tmp_path):
    """The inverted, gravity-only and naive initialisations of the curly model, 0.1 s of the still scene."""
    names = ["still.h5", "init_gravity.h5", "naive.h5"]
    result = hairinv(real, "export", *names, "-o", tmp_path / "compare.png")
    assert result.returncode == 0, result.stderr
    assert result.stderr == ""  # the body was found for every column
    pixels, text = _png(tmp_path / "compare.png")
    columns = _columns(text)
    files = [_h5(real / name) for name in names]
    assert [c["init"] for c in columns] == [f["frames"]["attrs"]["init"] for f in files] == ["inverted",
                                                                                              "gravity-only", "naive"]
    assert [c["target"] for c in columns] == [f["model"]["attrs"]["target"] for f in files]
    moved = [_moved_real(real / name) for name in names]
    for column, expected in zip(columns, moved):
        assert column["largest_displacement_mm"] == pytest.approx(expected.max(), rel=1e-9, abs=CHAINED_MM)
    # one colour scale: 0 to the largest displacement of any run, which is the naive one's
    assert float(text["hairinv:min"]) == 0.0
    assert float(text["hairinv:max"]) == pytest.approx(max(m.max() for m in moved), rel=1e-9)
    assert moved[2].max() > 1.0 and moved[0].max() < CHAINED_MM  # the naive hair sags, the inverted stays
    for column, f in zip(columns, files):  # and the run's own measure, at its sample points, agrees
        assert column["largest_displacement_mm"] == pytest.approx(1e3 * f["frames"]["displacement"][-1],
                                                                  rel=0.05, abs=CHAINED_MM)
    assert _body_pixels(pixels) > 0.05 * pixels.shape[0] * pixels.shape[1]
    for name, column in zip(names, columns):
        assert f"{name}: init {column['init']}, model target actual" in result.stdout

    result = hairinv(real, "export", *names, "-o", tmp_path / "compare.html")
    assert result.returncode == 0, result.stderr
    _assert_offline(tmp_path / "compare.html")
    [(size, page_text)] = _inlined_pngs(tmp_path / "compare.html")
    assert size == tuple(pixels.shape[1::-1]) and _columns(page_text) == columns
    _, words = _html(tmp_path / "compare.html")
    for name, f in zip(names, files):
        assert name in words and f["frames"]["attrs"]["init"] in words


@pytest.mark.parametrize("args, name, fragment", [
    (["still.h5", "naive.h5", "-o", "out.obj"], "out.obj", "holds one stage file"),
    (["still.h5", "naive.h5", "-o", "out.json"], "out.json", "compared only in HTML report or PNG output"),
    (["still.h5", "model.h5", "-o", "out.png"], "model.h5", "no /frames group"),
    (["still.h5", "syn.h5", "-o", "out.html"], "syn.h5", "another groom than still.h5"),
    (["still.h5", "naive.h5", "-o", "out.png", "--color", "fit-error"], "out.png", "--color does not apply"),
    (["still.h5", "naive.h5", "-o", "out.png", "--plot", "convergence"], "out.png", "--plot does not apply"),
    (["still.h5", "missing.h5", "-o", "out.png"], "missing.h5", "no such file"),
], ids=["polylines", "summary", "no frames", "another groom", "colour", "plot", "missing file"])
def test_bad_comparison_exits_2_and_writes_nothing(real, tmp_path, args, name, fragment):
    for copied in ("still.h5", "naive.h5", "model.h5", "body.obj"):
        shutil.copyfile(real / copied, tmp_path / copied)
    make_stage(tmp_path / "syn.h5")
    assert_refused(tmp_path, ["export", *args], name, fragment)


# --------------------------------------------------------------------------- the solver's convergence


def _force_scale(f) -> float:
    """N, the heaviest strand's weight: linear density (rho pi r^2) times |g| times the longest fitted strand."""
    a, h = f["model"]["attrs"], f["helices"]
    longest = max(h["length"][i:j].sum() for i, j in itertools.pairwise(h["offsets"]))
    return a["density"] * np.pi * a["radius"] ** 2 * np.linalg.norm(a["gravity"]) * longest


def test_convergence_plot_is_the_residual_history(real, tmp_path):
    result = hairinv(real, "export", "model.h5", "-o", tmp_path / "conv.png", "--plot", "convergence")
    assert result.returncode == 0, result.stderr
    f = _h5(real / "model.h5")
    history, a = f["model"]["residual_history"], f["model"]["attrs"]
    scale = _force_scale(f)
    # the relative residual the model reports is its last residual over the heaviest strand's weight
    assert history[-1, 1] / scale == pytest.approx(a["relative_residual"], rel=1e-12)
    pixels, text = _png(tmp_path / "conv.png")
    assert pixels.shape[:2] == (600, 1000) and text["hairinv:plot"] == "convergence"
    assert json.loads(text["hairinv:sweeps"]) == history[:, 0].tolist()
    np.testing.assert_allclose(json.loads(text["hairinv:relative_residual"]), history[:, 1] / scale, rtol=1e-12)
    assert float(text["hairinv:tolerance"]) == f["model"]["attrs"]["config"]["solver"]["tolerance"]
    assert text["hairinv:status"] == a["status"] == "CONVERGED"
    if a["method"] == "interior-point" and a["iterations"] == 0:
        # the steps' forces were final: the report names the criterion that method stopped on, the rest-shape
        # bound the model records, not "0 sweeps" beside a residual tolerance it never used
        assert f"CONVERGED after {a['interior_steps']} interior-point steps, rest shape within " \
               f"{a['rest_bound']:.2g} 1/m" in result.stdout and "after 0 sweeps" not in result.stdout
    else:
        assert f"CONVERGED after {a['iterations']} sweeps" in result.stdout


def test_convergence_figure_draws_the_history_on_a_log_scale(real):
    """The figure itself: the line's points, the y scale and the tolerance line, read back from matplotlib."""
    from hairinv.export.convergence import convergence_figure, convergence_of
    from hairinv.export.source import ExportSource

    f = _h5(real / "model.h5")
    history, tolerance = f["model"]["residual_history"], f["model"]["attrs"]["config"]["solver"]["tolerance"]
    c, why = convergence_of(ExportSource(real / "model.h5"))
    assert why == ""
    fig, _ = convergence_figure(c, "model.h5")
    ax = fig.axes[0]
    assert ax.get_yscale() == "log"
    residual, line = ax.get_lines()
    np.testing.assert_array_equal(residual.get_xdata(), history[:, 0])
    np.testing.assert_allclose(residual.get_ydata(), history[:, 1] / _force_scale(f), rtol=1e-12)
    assert np.all(np.asarray(line.get_ydata()) == tolerance)
    assert "CONVERGED" in ax.get_title()
    # the right-hand axis reads the same points in newtons
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig).draw()
    [right] = ax.child_axes
    assert right.get_yscale() == "functionlog"  # log, through the conversion to newtons
    assert right.get_ylim() == pytest.approx(tuple(np.array(ax.get_ylim()) * _force_scale(f)), rel=1e-9)


def test_a_gravity_only_model_has_no_convergence_plot(real, tmp_path):
    assert _h5(real / "gravity.h5")["model"]["attrs"]["target"] == "gravity-only"
    shutil.copyfile(real / "gravity.h5", tmp_path / "gravity.h5")
    assert_refused(tmp_path, ["export", "gravity.h5", "-o", "conv.png", "--plot", "convergence"], "gravity.h5",
                   "is a gravity-only model: its inversion solves for no contact force")
    result = hairinv(tmp_path, "export", "gravity.h5", "-o", "gravity.html")
    assert result.returncode == 0, result.stderr
    [(size, _)] = _inlined_pngs(tmp_path / "gravity.html")  # the groom only: no empty axes
    assert size == (1200, 700)
    assert "No convergence plot: gravity.h5 is a gravity-only model" in _html(tmp_path / "gravity.html")[1]


@pytest.mark.parametrize("args, name, fragment", [
    (["curly.h5", "-o", "conv.png", "--plot", "convergence"], "curly.h5", "no /model group"),
    (["model.h5", "-o", "conv.png", "--plot", "residuals"], "conv.png", "--plot takes groom, convergence or render"),
    (["model.h5", "-o", "conv.png", "--plot", "convergence", "--color", "fit-error"], "conv.png",
     "--color applies to the picture of the groom"),
    (["model.h5", "-o", "conv.html", "--plot", "convergence"], "conv.html", "--plot applies to PNG"),
], ids=["fitted file", "unknown plot", "colour of a plot", "plot of a report"])
def test_bad_convergence_input_exits_2_and_writes_nothing(real, tmp_path, args, name, fragment):
    for copied in ("curly.h5", "model.h5", "body.obj"):
        shutil.copyfile(real / copied, tmp_path / copied)
    assert_refused(tmp_path, ["export", *args], name, fragment)
