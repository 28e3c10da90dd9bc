"""The pose of an animated body the groom was made on: ``--bind-time`` (a time of the animation) and ``--body-rest``
(a separate mesh of the body in that pose), through invert, simulate and verify; their records, and bad input."""

from __future__ import annotations

import json
import sys

import h5py
import numpy as np
import pytest
import trimesh

from conftest import SAMPLES, hairinv
from hairinv import formats
from hairinv.contacts.body import BodyMesh

sys.path.insert(0, str(SAMPLES))
import make_rigs as mr  # noqa: E402

LIFT = np.array([0.0, 0.05, 0.0])  # m: the mannequin held this far above its bind pose for the whole animation


@pytest.fixture(scope="module")
def lifted(tmp_path_factory):
    """The mannequin held 5 cm above its bind pose for 2.1 s (``lifted.glb``), the same pose as a mesh of its own
    (``lifted.obj``, the animation's vertices at 0 s, in order), and eight strands of the sample straight groom
    lifted with it (``eight.h5``): a groom made on the animation's pose, not on the file's rest pose."""
    folder = tmp_path_factory.mktemp("bind")
    rig, _ = mr.variant("hold")
    motion = mr.sample("lifted", lambda t: (LIFT, {}), 2.1, 30.0, {})
    mr.write_glb(folder / "lifted.glb", rig, motion)
    animated = formats.read_animated_body(folder / "lifted.glb")
    trimesh.Trimesh(animated.vertices_at(animated.start), animated.faces, process=False).export(folder / "lifted.obj")
    curves = formats.read_curves(SAMPLES / "straight.h5")
    keep = np.linspace(0, curves.n_strands - 1, 8).astype(int)
    pieces = [curves.points[curves.offsets[k]:curves.offsets[k + 1]] + LIFT for k in keep]
    formats.write_curves(folder / "eight.h5", np.concatenate(pieces), np.r_[0, np.cumsum([len(p) for p in pieces])])
    return folder


def _root_distances(model, body_vertices, faces):
    with h5py.File(model, "r") as fh:
        roots = fh["helices/root"][()]
    return np.abs(BodyMesh.from_mesh(trimesh.Trimesh(body_vertices, faces, process=False)).closest(roots)[0])


@pytest.fixture(scope="module")
def bound(lifted):
    done = hairinv(lifted, "invert", "eight.h5", "lifted.glb", "--bind-time", "0", "-o", "bound.h5")
    assert done.returncode == 0, done.stderr
    return lifted / "bound.h5", done


def test_a_groom_made_on_a_pose_of_the_animation_is_inverted_on_that_pose(lifted, bound):
    """Inverted on the file's rest pose, the lifted groom's roots float 5 cm above the body, and the user is told
    which pose of the animation they lie on and the option that says it; with ``--bind-time 0`` they sit on it,
    and the model records the pose with the body."""
    model, done = bound
    animated = formats.read_animated_body(lifted / "lifted.glb")
    posed = animated.vertices_at(animated.start)
    assert np.abs(posed - animated.vertices - LIFT).max() < 1e-6  # the animation is the rest pose lifted
    on_pose = _root_distances(model, posed, animated.faces)
    on_rest = _root_distances(model, animated.vertices, animated.faces)
    assert on_pose.max() < 1e-6 and np.median(on_rest) > 0.01, (on_pose.max(), on_rest)
    assert "its pose at 0 s of the animation" in done.stdout + done.stderr
    with h5py.File(model, "r") as fh:
        body_input = json.loads(fh["contacts"].attrs["inputs"])[-1]
    assert body_input["pose"] == {"bind_time": 0.0}
    rest = hairinv(lifted, "invert", "eight.h5", "lifted.glb", "-o", "on_rest.h5")
    said = rest.stdout + rest.stderr
    assert "from the body's pose at 0 s of its animation: if the groom was made on that pose, pass --bind-time 0" \
        in said, said


def test_a_held_pose_of_the_animation_keeps_the_groom_bound_to_it_still(lifted, bound):
    """The model simulated on the animation that holds the pose it was bound on (simulate takes the recorded
    pose): no pre-roll, and no strand point moves more than 0.1 mm in 2 s; verify passes on it."""
    model, _ = bound
    done = hairinv(lifted, "simulate", model, "lifted.glb", "--seconds", "2", "-o", "held.frames.h5")
    assert done.returncode == 0, done.stderr
    with h5py.File(lifted / "held.frames.h5", "r") as fh:
        f = fh["frames"]
        assert float(f["time"][-1]) == pytest.approx(2.0)
        assert float(f["displacement"][()].max()) < 1e-4
        assert float(f.attrs.get("preroll", 0.0)) == 0.0
        assert json.loads(f.attrs["inputs"])[-1]["pose"] == {"bind_time": 0.0}
    verify = hairinv(lifted, "verify", model, "lifted.glb")
    assert verify.returncode == 0, verify.stdout + verify.stderr


def test_a_rest_mesh_gives_the_model_the_bind_time_gives(lifted, bound):
    """``--body-rest lifted.obj`` (the same pose as a mesh) and ``--bind-time 0``: the same contacts, and the same
    rest shape to the precision of the mesh file."""
    model, _ = bound
    done = hairinv(lifted, "invert", "eight.h5", "lifted.glb", "--body-rest", "lifted.obj", "-o", "rest.h5")
    assert done.returncode == 0, done.stderr
    with h5py.File(model, "r") as a, h5py.File(lifted / "rest.h5", "r") as b:
        assert a["contacts/strand"].shape == b["contacts/strand"].shape
        rest_a, rest_b = a["model/omega_rest"][()], b["model/omega_rest"][()]
        # (the OBJ keeps 8 decimals of the vertices)
        assert np.abs(rest_a - rest_b).max() < 1e-5 * np.abs(rest_a).max()
        pose = json.loads(b["contacts"].attrs["inputs"])[-1]["pose"]
    assert pose["rest_mesh"]["name"] == "lifted.obj" and len(pose["rest_mesh"]["sha256"]) == 64


def test_the_pose_is_part_of_what_makes_a_model_current(lifted, bound):
    """``--if-stale``: the same pose is current, another one is not; a record written before the pose was a
    setting is current at its default."""
    import shutil

    from hairinv.staleness import differences

    again = hairinv(lifted, "invert", "eight.h5", "lifted.glb", "--bind-time", "0", "-o", "bound.h5", "--if-stale")
    assert again.returncode == 0 and "is current" in again.stdout + again.stderr, again.stdout + again.stderr
    shutil.copyfile(lifted / "bound.h5", lifted / "other.h5")
    other = hairinv(lifted, "invert", "eight.h5", "lifted.glb", "--bind-time", "1", "-o", "other.h5", "--if-stale")
    assert other.returncode == 0 and "is current" not in other.stdout + other.stderr, other.stdout + other.stderr
    with h5py.File(lifted / "other.h5", "r") as fh:
        assert json.loads(fh["contacts"].attrs["inputs"])[-1]["pose"] == {"bind_time": 1.0}
    with h5py.File(lifted / "bound.h5", "r") as fh:
        record = json.loads(fh.attrs["command"])
    at_default = json.loads(json.dumps(record))
    at_default["settings"]["body"].update(bind_time="rest", rest_mesh="")
    older = json.loads(json.dumps(at_default))
    for key in ("bind_time", "rest_mesh"):
        older["settings"]["body"].pop(key)
    assert differences(older, at_default) == []
    assert differences(older, record) == ["setting body.bind_time was None, now '0'"]
    moved = json.loads(json.dumps(record))
    moved["settings"]["body"]["bind_time"] = "1"
    assert any("body.bind_time" in d for d in differences(moved, record))


@pytest.mark.parametrize("args, fragment", [
    (("--bind-time", "-1"), "0 or more"),
    (("--bind-time", "soon"), "rest or a time in seconds"),
    (("--bind-time", "5"), "after the animation's end"),
    (("--bind-time", "0", "--body-rest", "lifted.obj"), "give one"),
    (("--body-rest", "missing.obj"), "no such file"),
    (("--body-rest", str(SAMPLES / "body.obj")), "vertices and the animated body"),
])
def test_a_pose_that_cannot_be_read_is_refused(lifted, args, fragment):
    done = hairinv(lifted, "invert", "eight.h5", "lifted.glb", *args, "-o", "refused.h5")
    assert done.returncode == 2, done.stdout + done.stderr
    assert fragment in done.stderr and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert "Traceback" not in done.stderr and not (lifted / "refused.h5").exists()


def test_a_pose_on_a_still_body_is_refused(lifted):
    done = hairinv(lifted, "invert", "eight.h5", str(SAMPLES / "body.obj"), "--bind-time", "0", "-o", "refused.h5")
    assert done.returncode == 2 and "is a still mesh" in done.stderr, done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and not (lifted / "refused.h5").exists()


def test_export_draws_the_body_in_the_groom_s_pose(lifted, bound):
    """The USD export of a model bound on a pose of the animation carries the body in that pose; once the rest mesh
    a model was inverted on is gone, the export still writes, without the body, and says why."""
    import shutil

    from pxr import Usd, UsdGeom

    model, _ = bound
    done = hairinv(lifted, "export", model, "-o", "bound.usda")
    assert done.returncode == 0, done.stderr
    stage = Usd.Stage.Open(str(lifted / "bound.usda"))
    points = np.array(UsdGeom.Mesh(stage.GetPrimAtPath("/Root/Body")).GetPointsAttr().Get())
    animated = formats.read_animated_body(lifted / "lifted.glb")
    assert np.abs(points - animated.vertices_at(animated.start)).max() < 1e-6
    folder = lifted / "moved_rest"
    folder.mkdir()
    shutil.copyfile(lifted / "lifted.obj", folder / "pose.obj")
    made = hairinv(lifted, "invert", "eight.h5", "lifted.glb", "--body-rest", "moved_rest/pose.obj", "-o", "r.h5")
    assert made.returncode == 0, made.stderr
    (folder / "pose.obj").unlink()
    done = hairinv(lifted, "export", "r.h5", "-o", "r.usda")
    assert done.returncode == 0, done.stderr
    assert "rest mesh" in done.stdout + done.stderr and "no body mesh" in done.stdout + done.stderr, done.stderr
