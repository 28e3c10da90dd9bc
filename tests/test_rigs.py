"""The rigged mannequin of samples/make_rigs.py: its files (GLB, UsdSkel, OBJ sequence) read back by hairinv's
readers equal the generator's own linear blend skinning, a head turn is a rigid rotation of the skull in closed
form, the motions keep their promises (apex, landing speed, stop), Blender's glTF import poses the GLB the same,
and samples/turn.glb is what the generator writes."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import ROOT, ROUNDOFF, SAMPLES, real_path
from hairinv.formats import read_animated_body

sys.path.insert(0, str(SAMPLES))
import make_rigs as mr  # noqa: E402

# float32 storage (positions, weights, keys, inverse bind matrices; USD skins in float) of coordinates ~2 m
FLOAT32_SKINNING = 1e-6
# Blender keeps f-curves and skins in float32 (as tests/test_animated.py finds on CesiumMan)
BLENDER_SKINNING = 2e-6
BLENDER = next((p for p in (ROOT / ".venv-blender" / "bin" / "python", ROOT.parent / ".venv-blender" / "bin" / "python",
                             Path("/work/main/.venv-blender/bin/python")) if p.exists()), ROOT / ".venv-blender")


def short_turn(angle=90.0, fps=30.0):
    """A quick head turn: 0.1 s still, the turn in 0.3 s, 0.1 s held (16 frames at 30 fps)."""
    return mr.turn(angle=angle, duration=0.3, lead=0.1, hold=0.1, fps=fps)


@pytest.fixture(scope="module")
def rig():
    return mr.mannequin(seed=3)


@pytest.fixture(scope="module")
def turn_files(tmp_path_factory, rig):
    pytest.importorskip("pxr")
    folder = tmp_path_factory.mktemp("turn")
    motion = short_turn()
    files = {"glb": mr.write_glb(folder / "turn.glb", rig, motion),
             "usd": mr.write_usd(folder / "turn.usda", rig, motion),
             "obj": mr.write_obj_sequence(folder / "frames", rig, motion)}
    return motion, files


def test_the_skeleton_and_the_weights():
    rig = mr.mannequin(0)  # (the weights are those of the sample bust; a head seed moves the vertices after)
    assert np.all(rig.weights >= 0)
    np.testing.assert_allclose(rig.weights.sum(axis=1), 1.0, rtol=0, atol=2e-7)  # float32
    top = rig.vertices[:, 1] > 1.62
    assert np.all(rig.weights[top, mr.HEAD] == 1.0)  # the skull is the head's alone
    low = rig.vertices[:, 1] < 1.36
    assert np.all(rig.weights[low, mr.HEAD] == 0.0) and np.all(rig.weights[low, mr.NECK] == 0.0)
    # the neck blends into the chest below y = 1.48 and into the head above y = 1.50, over a few rings each
    for lo, hi in ((1.42, 1.475), (1.505, 1.60)):
        band = (rig.vertices[:, 1] > lo) & (rig.vertices[:, 1] < hi)
        assert np.mean((rig.weights[band] > 0).sum(axis=1) >= 2) > 0.5
    # a closed mesh, outward
    import trimesh

    mesh = trimesh.Trimesh(rig.vertices, rig.faces, process=False)
    assert mesh.is_watertight and mesh.volume > 0


def test_the_bind_pose_is_the_sample_bust():
    """Head seed 0 is samples/body.obj (its vertices in its order, then the cap's centre): the sample grooms sit on
    it. body.obj writes 6 decimals."""
    import trimesh

    body = trimesh.load(SAMPLES / "body.obj", process=False)
    rig = mr.mannequin(0)
    np.testing.assert_allclose(rig.vertices[: len(body.vertices)], body.vertices, rtol=0, atol=6e-7)
    np.testing.assert_array_equal(rig.faces[: len(body.faces)], body.faces)
    assert len(rig.vertices) == len(body.vertices) + 1


@pytest.mark.parametrize("kind", ["glb", "usd", "obj"])
def test_files_read_back_equal_the_generators_posing(turn_files, rig, kind):
    motion, files = turn_files
    body = read_animated_body(files[kind], fps=motion.fps if kind == "obj" else None)
    np.testing.assert_allclose(body.times, motion.times, rtol=0, atol=1e-7)  # (GLB keys are float32 seconds)
    np.testing.assert_array_equal(body.faces, rig.faces)
    np.testing.assert_allclose(body.vertices, rig.vertices, rtol=0, atol=FLOAT32_SKINNING)
    assert body.fps == pytest.approx(motion.fps)
    if kind != "obj":
        assert body.joints == mr.JOINTS
    moved = 0.0
    for k in range(motion.frames):
        posed = mr.pose(rig, motion, k)
        np.testing.assert_allclose(body.vertices_at(k / motion.fps), posed, rtol=0, atol=FLOAT32_SKINNING)
        moved = max(moved, np.abs(posed - rig.vertices).max())
    assert moved > 0.1  # the head turned: the comparison is not of two bind poses


def test_glb_and_usdskel_interpolate_the_same_between_frames(turn_files):
    motion, files = turn_files
    glb, usd = read_animated_body(files["glb"]), read_animated_body(files["usd"])
    for k in (3, 6, 9):  # slerp of the same keys
        t = (k + 0.5) / motion.fps
        np.testing.assert_allclose(glb.vertices_at(t), usd.vertices_at(t), rtol=0, atol=FLOAT32_SKINNING)


def test_a_head_turn_rotates_the_skull_rigidly_by_the_angle(turn_files, rig):
    """Neck and head turn about the same vertical axis (x = z = 0): what is weighted to the head alone turns by the
    whole angle about it, what is weighted to the root and chest does not move."""
    motion, files = turn_files
    body = read_animated_body(files["glb"])
    skull = rig.weights[:, mr.HEAD] == 1.0
    torso = rig.weights[:, mr.NECK] + rig.weights[:, mr.HEAD] == 0.0
    assert skull.sum() > 500 and torso.sum() > 500
    a = np.radians(90.0)
    R = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    end = body.vertices_at(motion.duration)
    np.testing.assert_allclose(end[skull], rig.vertices[skull] @ R.T, rtol=0, atol=FLOAT32_SKINNING)
    np.testing.assert_allclose(end[torso], rig.vertices[torso], rtol=0, atol=FLOAT32_SKINNING)
    face = np.argmax(np.where(skull, rig.vertices[:, 2], -np.inf))  # the front of the face (+Z) turns to +X
    assert end[face, 0] > 0.09
    # the turn is still before its start and done after its duration, with a minimum-jerk profile between: at
    # frame 7 (t = 7/30 s), u = (t - 0.1) / 0.3 of the way in time and 10 u^3 - 15 u^4 + 6 u^5 of the angle
    u = (7 / 30 - 0.1) / 0.3
    b = a * (10 * u**3 - 15 * u**4 + 6 * u**5)
    Rb = np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])
    np.testing.assert_allclose(body.vertices_at(7 / 30)[skull], rig.vertices[skull] @ Rb.T, rtol=0,
                               atol=FLOAT32_SKINNING)
    np.testing.assert_allclose(body.vertices_at(0.1), rig.vertices, rtol=0, atol=FLOAT32_SKINNING)


def test_the_motions_keep_their_promises():
    # jump: apex at the height asked, landing at sqrt(2 g h), back to the start height at rest
    y, (t1, t2, t3, t4), facts = mr.jump_profile(height=0.3)
    ts = np.linspace(0.0, t4 + 0.2, 20001)
    ys = np.array([y(t) for t in ts])
    assert ys.max() == pytest.approx(0.3, abs=1e-6)
    assert facts["landing_speed"] == pytest.approx(np.sqrt(2 * 9.81 * 0.3))
    assert (y(t2 - 1e-7) - y(t2 - 2e-7)) / 1e-7 == pytest.approx(-facts["landing_speed"], rel=1e-4)
    assert t3 - t2 == pytest.approx(0.1) and ys.min() == pytest.approx(-facts["dip"], abs=1e-6)
    assert y(t4) == pytest.approx(0.0, abs=ROUNDOFF) and abs(y(t1) - facts["takeoff_speed"] * 0.06) < 1e-12
    # stop: 1.5 m/s before the stop, still within 0.1 s after
    m = mr.stop(speed=1.5, stop=0.1, fps=100.0)
    z = m.translation[:, 2]
    v = np.diff(z) * m.fps
    t_stop = 0.2 + 0.6 + 0.8
    k = int(round(t_stop * m.fps))
    assert v[k - 10: k].min() == pytest.approx(1.5, rel=1e-4)
    assert np.all(v[k + 10:] == 0.0)
    # nod: down by the angle and back to the bind pose; hold: the bind pose throughout
    nod = mr.nod(angle=30.0, fps=100.0)
    k_down = int(round((0.2 + 0.4) * nod.fps))
    angle = 2 * np.arccos(nod.rotation[k_down, mr.NECK, 3]) + 2 * np.arccos(nod.rotation[k_down, mr.HEAD, 3])
    assert np.degrees(angle) == pytest.approx(30.0, abs=1e-4)
    np.testing.assert_array_equal(nod.rotation[-1], np.tile([0.0, 0, 0, 1], (4, 1)))
    held = mr.hold(fps=24.0)
    assert held.frames == 25 and np.all(held.rotation[..., 3] == 1.0)
    np.testing.assert_array_equal(held.translation, np.tile(mr.JOINT_POSITIONS[0], (25, 1)))


def test_variants_split_and_head_seeds():
    assert set(mr.DEVELOPMENT) | set(mr.HELD_OUT) == set(mr.VARIANTS) and not set(mr.DEVELOPMENT) & set(mr.HELD_OUT)
    kinds = {kind for kind, *_ in mr.VARIANTS.values()}
    assert kinds == set(mr.MOTIONS)
    base, other = mr.mannequin(0), mr.mannequin(5)
    shift = np.linalg.norm(other.vertices - base.vertices, axis=1)
    assert 0.002 < shift.max() < 0.012  # a few per cent of the head
    assert np.all(shift[base.vertices[:, 1] < 1.47] == 0.0)  # nothing below the chin line moves
    # the groom moves with its head: its roots stay on the skin (where the sample groom's are)
    points, offsets = mr.groom(5)
    sample, _ = mr.sample_groom()
    np.testing.assert_array_equal(points[sample[:, 1] < 1.47], sample[sample[:, 1] < 1.47])
    assert np.abs(points - sample).max() > 0.002


def test_sample_turn_glb_is_what_the_generator_writes(tmp_path):
    written = mr.write_sample(tmp_path / "turn.glb")
    assert written.read_bytes() == (SAMPLES / "turn.glb").read_bytes(), "rerun samples/make_rigs.py --sample"


BLENDER_SCRIPT = """
import sys, bpy, numpy as np
path, out, fps, frames = sys.argv[-4], sys.argv[-3], int(sys.argv[-2]), [int(f) for f in sys.argv[-1].split(",")]
bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
scene.render.fps = fps  # the importer turns key times into frames at the scene's rate
bpy.ops.import_scene.gltf(filepath=path)
mesh = [o for o in scene.objects if o.type == "MESH"][0]
res = {}
for f in frames:
    scene.frame_set(f)
    o = mesh.evaluated_get(bpy.context.evaluated_depsgraph_get())
    m = o.to_mesh()
    res[f"f{f}"] = np.array([o.matrix_world @ p.co for p in m.vertices])
    o.to_mesh_clear()
np.savez(out, **res)
"""


@pytest.mark.parametrize("name", ["nod30", "jump20"])
def test_blender_poses_the_glb_as_the_generator_does(tmp_path, name):
    if not BLENDER.exists():
        pytest.skip(f"Blender as a Python module (bpy) not found at {BLENDER}")
    rig, motion = mr.variant(name)
    glb = mr.write_glb(tmp_path / f"{name}.glb", rig, motion)
    frames = sorted({0, motion.frames // 4, motion.frames // 2, (3 * motion.frames) // 4, motion.frames - 1})
    script = tmp_path / "evaluate.py"
    script.write_text(BLENDER_SCRIPT)
    run = subprocess.run([str(BLENDER), str(script), str(glb), str(tmp_path / "blender.npz"), f"{motion.fps:g}",
                          ",".join(map(str, frames))], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    blender = np.load(tmp_path / "blender.npz")
    for k in frames:  # Blender frame k is at k / fps
        ours = mr.pose(rig, motion, k)
        as_z_up = np.c_[ours[:, 0], -ours[:, 2], ours[:, 1]]  # Blender turns glTF's +Y up onto +Z
        np.testing.assert_allclose(blender[f"f{k}"], as_z_up, rtol=0, atol=BLENDER_SKINNING)
    assert np.abs(blender[f"f{frames[2]}"] - blender["f0"]).max() > 0.05  # it moved


def test_a_bob_grown_on_cesiummans_head_sits_on_it():
    """bench/cesiumman_groom.py on the real CesiumMan (skipped without the real data): roots on the head's triangles,
    on the skin; no point inside the body; 10-20 cm strands."""
    path = real_path("cesiumman", "CesiumMan.glb")
    sys.path.insert(0, str(ROOT / "bench"))
    import cesiumman_groom as cg
    import grooms
    import trimesh

    rest = read_animated_body(path)
    body = grooms.Mannequin(trimesh.Trimesh(rest.vertices, rest.faces, process=False))
    head = cg.Head(rest.vertices)
    assert head.r == pytest.approx(0.169, abs=0.002) and head.yc == pytest.approx(1.338, abs=0.002)
    points, offsets = cg.grow(body, head, n_strands=60, seed=2)
    d = body.distance(points)
    roots = points[offsets[:-1]]
    assert np.abs(d[offsets[:-1]]).max() < 1e-6
    assert np.all(head.scalp(roots)) and roots[:, 1].min() > head.yc - 0.07
    assert d.min() > -1e-7
    lengths = np.array([np.linalg.norm(np.diff(points[a:b], axis=0), axis=1).sum()
                        for a, b in zip(offsets[:-1], offsets[1:])])
    assert lengths.min() > 0.099 and lengths.max() < 0.201
