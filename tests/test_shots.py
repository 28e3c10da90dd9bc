"""A shot end to end: a groom inverted on the mannequin's bind pose, simulated under its animation (the sample
head turn, a hold), from the command line; what /frames keeps checked against the geometry it claims."""

from __future__ import annotations

import sys

import h5py
import numpy as np
import pytest

from conftest import SAMPLES, eight_strand_model, hairinv
from hairinv import formats
from hairinv.contacts.body import BodyMesh
from hairinv.rod.helix import strand_points

sys.path.insert(0, str(SAMPLES))
import make_rigs as mr  # noqa: E402


@pytest.fixture(scope="module")
def shot_model(tmp_path_factory):
    """Eight strands of the sample straight groom inverted on samples/turn.glb (its bind pose)."""
    folder = tmp_path_factory.mktemp("shot")
    eight_strand_model(folder)
    return folder


def _frames(path):
    with h5py.File(path, "r") as fh:
        f = fh["frames"]
        out = {key: f[key][()] for key in f}
        out["attrs"] = dict(f.attrs)
        h = fh["helices"]
        out["helices"] = {key: h[key][()] for key in h}
    return out


def _roots_on_triangles(vertices, faces, triangle, barycentric, offset):
    """The bound roots from the binding's definition (docs/stage-files.md), written out here."""
    a, b, c = (vertices[faces[triangle, i]] for i in range(3))
    p = barycentric[:, :1] * a + barycentric[:, 1:2] * b + barycentric[:, 2:] * c
    e = (b - a) / np.linalg.norm(b - a, axis=1, keepdims=True)
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return p + offset[:, :1] * e + offset[:, 1:2] * np.cross(n, e) + offset[:, 2:] * n


def _points(frames, k, per=12):
    h = frames["helices"]
    S = len(h["offsets"]) - 1
    strand = np.repeat(np.arange(S), per)
    total = np.add.reduceat(h["length"], h["offsets"][:-1])
    s = np.tile(np.linspace(0.0, 1.0, per), S) * total[strand]
    return strand_points(frames["root"][k], frames["frame0"][k], h["offsets"], frames["omega"][k], h["length"],
                         strand, s)


def test_a_head_turn_carries_the_roots_on_their_triangles_and_keeps_the_hair_out_of_the_body(shot_model):
    done = hairinv(shot_model, "simulate", "eight.model.h5", str(SAMPLES / "turn.glb"), "--seconds", "0.6",
                   "-o", "turn.frames.h5")
    assert done.returncode == 0, done.stderr
    assert "roots bound to" in done.stdout + done.stderr
    f = _frames(shot_model / "turn.frames.h5")
    assert f["attrs"]["body_animated"] and f["attrs"]["preroll"] == 0.0  # turn.glb starts in its bind pose
    assert len(f["time"]) == round(0.6 * f["attrs"]["fps"]) + 1
    # the body in /frames is the file's animation at those times
    body = formats.read_animated_body(SAMPLES / "turn.glb")
    for k in (0, len(f["time"]) // 2, len(f["time"]) - 1):
        assert np.abs(f["body_vertices"][k] - body.vertices_at(body.start + f["time"][k])).max() < 1e-6
    # every root where its binding puts it on its triangle, at every frame (float32 vertices: 1e-6 m)
    for k in range(len(f["time"])):
        expected = _roots_on_triangles(f["body_vertices"][k].astype(np.float64), f["body_faces"],
                                       f["binding_triangle"], f["binding_barycentric"], f["binding_offset"])
        assert np.abs(f["root"][k] - expected).max() < 1e-6
    # the head turned (the roots moved), and the hair stayed out of the body: no strand point deeper than
    # the contacts' own room allows at any frame
    assert np.linalg.norm(f["root"][-1] - f["root"][0], axis=1).max() > 0.05
    deepest = min(BodyMesh.from_mesh(_Mesh(f["body_vertices"][k], f["body_faces"])).closest(_points(f, k))[0].min()
                  for k in range(len(f["time"])))
    assert deepest > -2e-3, deepest


def test_an_animation_that_holds_its_bind_pose_keeps_the_groom_still(shot_model):
    rig, motion = mr.variant("hold")
    mr.write_glb(shot_model / "hold.glb", rig, motion)
    done = hairinv(shot_model, "simulate", "eight.model.h5", "hold.glb", "--seconds", "2", "-o", "hold.frames.h5")
    assert done.returncode == 0, done.stderr
    f = _frames(shot_model / "hold.frames.h5")
    assert f["time"][-1] == pytest.approx(2.0)
    assert f["displacement"].max() < 1e-4  # 0.1 mm over 2 s
    assert np.abs(f["root"] - f["root"][0]).max() < 1e-6  # the skinning in float32 of the bind pose


def test_the_gif_of_a_shot_shows_every_frame_and_what_moves(shot_model):
    """The animated GIF of the head turn: one image per frame at the run's rate; the head turning shows between
    the first and the last image, and a still run's first and last images are the same below their titles."""
    from PIL import Image

    frames = shot_model / "turn.frames.h5"
    if not frames.exists():
        done = hairinv(shot_model, "simulate", "eight.model.h5", str(SAMPLES / "turn.glb"), "--seconds", "0.6",
                       "-o", "turn.frames.h5")
        assert done.returncode == 0, done.stderr
    done = hairinv(shot_model, "export", "turn.frames.h5", "-o", "turn.gif")
    assert done.returncode == 0, done.stderr
    f = _frames(frames)
    with Image.open(shot_model / "turn.gif") as gif:
        assert gif.n_frames == len(f["time"])
        assert abs(gif.info["duration"] - 1000.0 / f["attrs"]["fps"]) <= 10  # GIF counts in 10 ms
        gif.seek(0)
        first = gif.convert("RGB")
        gif.seek(gif.n_frames - 1)
        last = gif.convert("RGB")
    moved = _changed(first, last)
    assert moved > 0.002  # the head and the hair moved on screen
    rig, motion = mr.variant("hold")
    mr.write_glb(shot_model / "still.glb", rig, motion)
    done = hairinv(shot_model, "simulate", "eight.model.h5", "still.glb", "--seconds", "0.2", "-o", "still.frames.h5")
    assert done.returncode == 0, done.stderr
    done = hairinv(shot_model, "export", "still.frames.h5", "-o", "still.gif")
    assert done.returncode == 0, done.stderr
    with Image.open(shot_model / "still.gif") as gif:
        gif.seek(0)
        first = gif.convert("RGB")
        gif.seek(gif.n_frames - 1)
        last = gif.convert("RGB")
    # below the title (frame and time): the same picture, up to each frame's own palette
    assert _changed(first, last) < 0.05 * moved


def _changed(a, b, top: int = 60) -> float:
    """The fraction of pixels below the title whose grey level differs by more than 40 of 255."""
    from PIL import ImageChops

    return float((np.asarray(ImageChops.difference(a, b).convert("L"))[top:] > 40).mean())


def test_a_scene_that_moves_the_body_is_refused_with_an_animated_body(shot_model):
    before = sorted(p.name for p in shot_model.iterdir())
    done = hairinv(shot_model, "simulate", "eight.model.h5", str(SAMPLES / "turn.glb"), "--scene", "motion",
                   "-o", "refused.h5")
    assert done.returncode == 2
    assert "animated" in done.stderr and "Traceback" not in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1
    assert sorted(p.name for p in shot_model.iterdir()) == before


class _Mesh:
    def __init__(self, vertices, faces):
        self.vertices, self.faces = np.asarray(vertices, dtype=np.float64), faces


@pytest.mark.parametrize("case", ["far", "topology"])
def test_a_shot_body_nowhere_near_the_roots_or_changing_topology_is_refused(shot_model, case):
    """An OBJ sequence 2 m away from the groom, or one whose second frame has other triangles: one sentence
    naming the sequence, exit 2, nothing written."""
    import trimesh

    folder = shot_model / case
    folder.mkdir(exist_ok=True)
    bust = trimesh.load(SAMPLES / "body.obj", process=False)
    for k in range(3):
        vertices = np.asarray(bust.vertices) + ([2.0, 0.0, 0.01 * k] if case == "far" else [0.0, 0.0, 0.0])
        faces = np.asarray(bust.faces)
        if case == "topology" and k == 1:
            faces = faces[:-1]
        trimesh.Trimesh(vertices, faces, process=False).export(folder / f"body.{k:04d}.obj")
    before = sorted(p.name for p in shot_model.iterdir())
    done = hairinv(shot_model, "simulate", "eight.model.h5", f"{case}/body.####.obj", "-o", "refused.h5")
    assert done.returncode == 2, done.stdout + done.stderr
    # the sequence, or its frame that differs
    assert ("body.####.obj" if case == "far" else "body.0001.obj") in done.stderr and "Traceback" not in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1
    assert ("no root is within" in done.stderr) if case == "far" else ("other triangles" in done.stderr)
    assert sorted(p.name for p in shot_model.iterdir()) == before


@pytest.mark.parametrize("key, value, fragment", [("body_faces", 10**6, "body_faces names vertices"),
                                                  ("binding_triangle", -3, "binding_triangle names triangles"),
                                                  ("body_vertices", np.nan, "body_vertices")])
def test_a_shot_file_whose_body_or_binding_is_broken_is_refused(shot_model, tmp_path, key, value, fragment):
    import shutil

    frames = shot_model / "turn.frames.h5"
    if not frames.exists():
        done = hairinv(shot_model, "simulate", "eight.model.h5", str(SAMPLES / "turn.glb"), "--seconds", "0.6",
                       "-o", "turn.frames.h5")
        assert done.returncode == 0, done.stderr
    broken = tmp_path / "broken.h5"
    shutil.copyfile(frames, broken)
    with h5py.File(broken, "r+") as fh:
        data = fh["frames"][key]
        edited = data[()]
        edited.flat[0] = value
        data[...] = edited
    done = hairinv(tmp_path, "export", "broken.h5", "-o", "broken.gif")
    assert done.returncode == 2 and fragment in done.stderr and "broken.h5" in done.stderr, done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and not (tmp_path / "broken.gif").exists()


@pytest.fixture(scope="module")
def lifted_shot(shot_model):
    """A shot whose first frame is not the groom's pose: the mannequin held 5 cm above its bind pose for 0.1 s, so
    a 0.1 s pre-roll carries the body (and the roots) up before frame 0."""
    rig, _ = mr.variant("hold")
    motion = mr.sample("lifted", lambda t: (np.array([0.0, 0.05, 0.0]), {}), 0.1, 30.0, {})
    mr.write_glb(shot_model / "lifted.glb", rig, motion)
    done = hairinv(shot_model, "simulate", "eight.model.h5", "lifted.glb", "--preroll", "0.1", "-o",
                   "lifted.frames.h5")
    assert done.returncode == 0, done.stderr
    return shot_model / "lifted.frames.h5"


def test_the_picture_of_a_shot_carries_the_input_from_the_groom_s_pose(lifted_shot):
    """The before/after row draws the input carried by each root's triangle to the last frame: from the pose the
    groom was made on (the body 5 cm lower), so here 5 cm up. (Carried from frame 0, already lifted by the
    pre-roll, it stayed where the input is, 5 cm under the hair of the last frame.)"""
    from hairinv.export.source import ExportSource

    f = _frames(lifted_shot)
    assert f["attrs"]["preroll"] == pytest.approx(0.1)
    assert np.allclose(f["root"][0], f["helices"]["root"] + [0.0, 0.05, 0.0], atol=1e-6)  # the pre-roll lifted them
    source = ExportSource(lifted_shot)
    last = len(f["time"]) - 1
    assert np.abs(source.carried(last) - (source.points + [0.0, 0.05, 0.0])).max() < 1e-6


def test_the_picture_of_a_pre_rolled_shot_draws_the_input_on_the_groom_s_pose(lifted_shot, tmp_path):
    """The first row draws the input shape: over the body as the groom was made on it (the body file's rest pose,
    read from the recorded body), not over the shot's first frame, which the pre-roll moved."""
    from hairinv.export import export

    report = export(lifted_shot, tmp_path / "lifted.png")
    lines = " ".join(report.lines)
    assert "body: " in lines and "lifted.glb" in lines, report.lines
    assert "as the frames keep it" not in lines, report.lines


def test_a_held_bind_pose_is_the_groom_s_pose_to_the_last_bit(shot_model):
    """A skinned body's first frame at its bind pose is the rest pose only to float32 skinning (5e-8 m here); the
    shot takes it as the pose the groom was inverted on exactly, so the groom's contacts keep their gaps and a
    held pose is as still as the still scene on the rest mesh: round-off. (Played as skinned, the eight strands
    moved 3.4 um in 2 s, and the sample's whole 300-strand groom drifted and fell apart after 1.5 s.)"""
    from hairinv.dynamics.skin import Shot

    rig, motion = mr.variant("hold")
    mr.write_glb(shot_model / "held.glb", rig, motion)
    body = formats.read_animated_body(shot_model / "held.glb")
    assert 0.0 < np.abs(body.vertices_at(body.start) - body.vertices).max() < 1e-6  # float32 skinning's round-off
    shot = Shot(body, 0.0)
    assert np.array_equal(shot.vertices_at(0.0), shot.bind) and np.abs(shot.vertices_at(0.7) - shot.bind).max() < 1e-12
    done = hairinv(shot_model, "simulate", "eight.model.h5", "held.glb", "--seconds", "2", "-o", "held.frames.h5")
    assert done.returncode == 0, done.stderr
    f = _frames(shot_model / "held.frames.h5")
    assert f["displacement"].max() < 1e-9, f["displacement"].max()


def _rising_sequence(folder, frames=3):
    """The bust as an OBJ sequence rising 1 mm a frame (a sequence states no frame rate)."""
    import trimesh

    folder.mkdir(exist_ok=True)
    bust = trimesh.load(SAMPLES / "body.obj", process=False)
    for k in range(frames):
        trimesh.Trimesh(np.asarray(bust.vertices) + [0.0, 0.001 * k, 0.0], np.asarray(bust.faces),
                        process=False).export(folder / f"body.{k:04d}.obj")
    return folder / "body.####.obj"


def test_a_sequence_plays_at_the_frame_rate_given(shot_model):
    """Three frames of a sequence: at the 24 fps assumed (and said) they last 1/12 s; with --body-fps 10,
    0.2 s, written at 10 frames per second, the body's vertices of frame k those of the file k."""
    pattern = _rising_sequence(shot_model / "rising")
    assumed = hairinv(shot_model, "simulate", "eight.model.h5", "rising/body.####.obj", "-o", "assumed.h5")
    assert assumed.returncode == 0, assumed.stderr
    assert "24 fps assumed" in assumed.stdout + assumed.stderr
    given = hairinv(shot_model, "simulate", "eight.model.h5", "rising/body.####.obj", "--body-fps", "10",
                    "-o", "given.h5")
    assert given.returncode == 0, given.stderr
    for name, fps in (("assumed.h5", 24.0), ("given.h5", 10.0)):
        f = _frames(shot_model / name)
        assert f["time"][-1] == pytest.approx(2.0 / fps) and f["attrs"]["fps"] == pytest.approx(fps)
    f = _frames(shot_model / "given.h5")
    rise = f["body_vertices"][:, :, 1] - f["body_vertices"][:1, :, 1]
    assert np.allclose(rise[:, 0], 0.001 * np.arange(3), atol=1e-6)
    assert pattern.parent.is_dir()


@pytest.mark.parametrize("args, fragment", [(["rising/body.####.obj", "--body-fps", "0"], "--body-fps is 0"),
                                            (["body.obj", "--body-fps", "10"], "is a still mesh")])
def test_a_frame_rate_that_cannot_be_played_is_refused(shot_model, args, fragment):
    """A rate of 0, or a rate for a still body: one sentence, exit 2, nothing written."""
    import shutil

    _rising_sequence(shot_model / "rising")
    shutil.copy(SAMPLES / "body.obj", shot_model / "body.obj")
    done = hairinv(shot_model, "simulate", "eight.model.h5", *args, "-o", "refused_fps.h5")
    assert done.returncode == 2, done.stdout + done.stderr
    assert fragment in done.stderr and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert not (shot_model / "refused_fps.h5").exists()


def test_verify_holds_an_animated_body_in_the_groom_s_pose(shot_model):
    """``hairinv verify MODEL turn.glb`` (what ``invert`` suggests next) checks the still promise on the pose the
    groom was inverted on, not the head turn: it passes, says the animation is not played, and the run is 2 s of
    the still scene. (Playing the animation, it failed: every strand moved with the turning head.)"""
    import re

    done = hairinv(shot_model, "verify", "eight.model.h5", str(SAMPLES / "turn.glb"))
    assert done.returncode == 0, done.stdout + done.stderr
    said = re.search(r"verify: PASS, no strand point moved more than 0.1 mm in 2 s \(largest (\S+) mm", done.stdout)
    assert said and float(said[1]) < 1e-6, done.stdout
    assert "turn.glb is animated: held still in the groom's pose" in done.stdout + done.stderr
