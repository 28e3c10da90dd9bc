"""Scenes: presets, file validation, the keyframed body motion and trimming.

- every preset loads; every class of bad file is refused with a message naming the file;
- the body passes through its keys (built independently with scipy rotations about
  the world axes), is C1 at the keys, keeps R orthonormal, and its analytic
  derivatives match central finite differences of R(t) and c(t);
- a trimmed strand is the first part of the original curve, with the right length.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from conftest import FINITE_DIFFERENCE, ROUNDOFF
from hairinv.dynamics.scene import SCENE_DIR, Keyframe, Scene, Trim, scene_names, trim_helices
from hairinv.errors import InputError
from hairinv.model import Helices
from hairinv.rod.helix import points_at

# Central difference step for the body motion, s: truncation h^2 |f'''| ~ 1e-12 * 6 / T^3
# and round-off 1e-16 / h ~ 1e-10, both well below FINITE_DIFFERENCE.
H = 1e-6
UPS = {
    "y-up": np.array([0.0, 1.0, 0.0]),
    "z-up": np.array([0.0, 0.0, 1.0]),
    "tilted": np.array([0.3, 0.9, -0.2]) / np.linalg.norm([0.3, 0.9, -0.2]),
}
PRESETS = ("still", "motion", "remove-body", "trim")


# ------------------------------------------------------------------ presets


@pytest.mark.parametrize("name", PRESETS)
def test_presets_load(name):
    scene = Scene.load(name)
    assert scene.source == str(SCENE_DIR / f"{name}.toml")
    assert scene.description
    assert scene.seconds > 0 and scene.fps > 0
    assert name in scene_names() and scene.name == name


def test_preset_contents():
    still, motion, removed, trim = (Scene.load(n) for n in PRESETS)
    assert (still.body, still.seconds, still.trim) == ("fixed", 2.0, None)
    assert (removed.body, removed.seconds, removed.body_contacts) == ("removed", 2.0, False)
    assert (trim.body, trim.seconds, trim.trim) == ("fixed", 2.0, Trim(fraction=0.5, time=0.0))
    assert motion.body == "keyframed" and motion.moving and motion.seconds == 4.0
    yaws = [k.yaw for k in motion.keyframes]
    pitches = [k.pitch for k in motion.keyframes]
    assert 40 <= max(np.abs(yaws)) <= 60 and 15 <= max(np.abs(pitches)) <= 25
    first, last = motion.keyframes[0], motion.keyframes[-1]
    assert (first.yaw, first.pitch, first.roll, first.translate) == (0, 0, 0, (0, 0, 0))
    assert (last.yaw, last.pitch, last.roll, last.translate) == (0, 0, 0, (0, 0, 0))
    assert last.time < motion.seconds  # time left to settle


def test_load_by_path_equals_by_name(tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text((SCENE_DIR / "motion.toml").read_text())
    by_path, by_name = Scene.load(path), Scene.load("motion")
    assert dataclasses.replace(by_path, source=None) == dataclasses.replace(by_name, source=None)
    assert Scene.load(str(path)).source == str(path)


def test_the_example_of_the_docs_loads(tmp_path):
    text = (SCENE_DIR.parents[1] / "docs" / "scenes.md").read_text()
    path = tmp_path / "example.toml"
    path.write_text(text.split("```toml\n", 1)[1].split("```", 1)[0])
    scene = Scene.load(path)
    assert scene.moving and scene.pivot == (0.0, 1.45, 0.0) and scene.trim == Trim(length=0.15, time=3.0)


def test_unknown_preset_lists_the_presets():
    with pytest.raises(InputError, match="unknown scene 'nope'.*still"):
        Scene.load("nope")


def test_defaults_of_a_minimal_file(tmp_path):
    path = tmp_path / "empty.toml"
    path.write_text("")
    scene = Scene.load(path)
    assert (scene.body, scene.keyframes, scene.trim, scene.pivot, scene.forward) == ("fixed", (), None, None, "auto")


# ---------------------------------------------------------------- bad files

KEY = '[[keyframe]]\ntime = {}\n'
BAD = {
    "invalid TOML": ("body = ", "not valid TOML"),
    "unknown key": ("bodi = 'fixed'", "unknown key bodi"),
    "unknown keyframe key": ('body = "keyframed"\n' + KEY.format(0) + "yawn = 3", "unknown key in keyframe 1: yawn"),
    "unknown trim key": ("[trim]\nfraction = 0.5\nat = 1", "unknown key trim.at"),
    "wrong type": ('seconds = "two"', "seconds expects a number"),
    "bool for a number": ("fps = true", "fps expects a number"),
    "string expected": ("description = 3", "description expects a string"),
    "bad translate": ('body = "keyframed"\n' + KEY.format(0) + "translate = [1, 2]", "translate expects three"),
    "bad pivot": ('pivot = "neck"', "pivot"),
    "unknown body": ('body = "dancing"', "body must be one of"),
    "bad forward": ('forward = "north"', "forward must be"),
    "negative duration": ("seconds = -1.0", "seconds must be a duration > 0"),
    "zero fps": ("fps = 0", "fps must be > 0"),
    "keys on a fixed body": (KEY.format(0), "body is 'fixed'"),
    "keyframed without keys": ('body = "keyframed"', "no \\[\\[keyframe\\]\\]"),
    "key without time": ('body = "keyframed"\n[[keyframe]]\nyaw = 3', "keyframe 1 has no time"),
    "negative key time": ('body = "keyframed"\n' + KEY.format(-1.0), "times must be >= 0"),
    "repeated key time": ('body = "keyframed"\n' + KEY.format(1.0) + KEY.format(1.0), "increase strictly"),
    "decreasing key time": ('body = "keyframed"\n' + KEY.format(1.0) + KEY.format(0.5), "increase strictly"),
    "half turn": ('body = "keyframed"\n' + KEY.format(0) + KEY.format(1) + "yaw = 270", "half a turn"),
    "trim fraction 0": ("[trim]\nfraction = 0.0", "trim.fraction must be in \\(0, 1\\]"),
    "trim fraction > 1": ("[trim]\nfraction = 1.5", "trim.fraction must be in \\(0, 1\\]"),
    "trim both": ("[trim]\nfraction = 0.5\nlength = 0.1", "exactly one of"),
    "trim neither": ("[trim]\ntime = 1.0", "exactly one of"),
    "trim negative length": ("[trim]\nlength = -0.1", "trim.length must be > 0"),
    "trim negative time": ("[trim]\nlength = 0.1\ntime = -1", "trim.time must be >= 0"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_file_is_refused_naming_the_file(tmp_path, case):
    text, message = BAD[case]
    path = tmp_path / "bad.toml"
    path.write_text(text + "\n")
    with pytest.raises(InputError, match=message) as info:
        Scene.load(path)
    assert str(info.value).startswith(f"{path}: ")
    assert "\n" not in str(info.value).split("(", 1)[0]  # one sentence (TOML's own detail aside)


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match="no such scene file") as info:
        Scene.load(tmp_path / "absent.toml")
    assert str(tmp_path / "absent.toml") in str(info.value)


# ------------------------------------------------------------- body motion


def random_scene(rng, keys=5, start=0.3) -> Scene:
    times = start + np.cumsum(rng.uniform(0.2, 0.8, keys))
    frames = [Keyframe(float(t), *map(float, rng.uniform(-60, 60, 3)), tuple(map(float, rng.normal(0, 0.05, 3))))
              for t in times]
    return Scene(body="keyframed", keyframes=tuple(frames))


def world_rotation(key: Keyframe, forward, left, up) -> np.ndarray:
    """Independent construction: scipy rotations about the world axes, composed yaw, pitch, roll."""
    turn = [Rotation.from_rotvec(np.radians(angle) * axis) for angle, axis in
            ((key.yaw, up), (key.pitch, left), (key.roll, forward))]
    return (turn[0] * turn[1] * turn[2]).as_matrix()


def test_body_axes_conventions():
    scene = Scene()
    np.testing.assert_array_equal(scene.body_axes([0, 1, 0]), np.column_stack([[0, 0, 1], [1, 0, 0], [0, 1, 0]]))
    np.testing.assert_array_equal(scene.body_axes([0, 0, 1]), np.column_stack([[0, -1, 0], [1, 0, 0], [0, 0, 1]]))
    np.testing.assert_array_equal(Scene(forward="+x").body_axes([0, 0, 1]),
                                  np.column_stack([[1, 0, 0], [0, 1, 0], [0, 0, 1]]))
    with pytest.raises(InputError, match="forward axis -y is along the groom's up axis"):
        Scene(forward="-y").body_axes([0, 1, 0])


def test_signs_of_yaw_pitch_roll():
    """Y-up, face along +Z, left along +X: the documented senses of the three angles."""
    up, forward, left = np.eye(3)[1], np.eye(3)[2], np.eye(3)[0]

    def turned(**angles):
        scene = Scene(body="keyframed", keyframes=(Keyframe(0.0, **angles),))
        return scene.body_motion(0.0, np.zeros(3), up).R

    np.testing.assert_allclose(turned(yaw=90) @ forward, left, atol=ROUNDOFF)  # face turns to its left
    np.testing.assert_allclose(turned(pitch=90) @ forward, -up, atol=ROUNDOFF)  # face tips down
    np.testing.assert_allclose(turned(roll=90) @ left, up, atol=ROUNDOFF)  # left ear up, right ear down


@pytest.mark.parametrize("up", list(UPS))
def test_passes_through_the_keys(rng, up):
    scene = random_scene(rng)
    pivot = rng.normal(size=3)
    forward, left, upv = scene.body_axes(UPS[up]).T
    for key in scene.keyframes:
        motion = scene.body_motion(key.time, pivot, UPS[up])
        R = world_rotation(key, forward, left, upv)
        np.testing.assert_allclose(motion.R, R, atol=ROUNDOFF)
        np.testing.assert_allclose(motion.c, pivot + np.array(key.translate) - R @ pivot, atol=ROUNDOFF)
        # the pivot goes where the key's translation puts it
        np.testing.assert_allclose(motion.points(pivot[None])[0], pivot + key.translate, atol=ROUNDOFF)
        np.testing.assert_allclose(scene.transform_matrix(key.time, pivot, UPS[up]),
                                   np.block([[R, motion.c[:, None]], [np.zeros((1, 3)), np.ones((1, 1))]]),
                                   atol=ROUNDOFF)


def test_rests_before_the_first_key_and_after_the_last(rng):
    scene = random_scene(rng, start=0.5)
    up, pivot = UPS["y-up"], rng.normal(size=3)
    first, last = scene.keyframes[0], scene.keyframes[-1]
    for t, key in ((0.0, first), (first.time - 1e-9, first), (last.time, last), (last.time + 3.0, last)):
        motion = scene.body_motion(t, pivot, up)
        np.testing.assert_allclose(motion.R, scene.body_motion(key.time, pivot, up).R, atol=ROUNDOFF)
        for derivative in motion[2:]:
            np.testing.assert_array_equal(derivative, 0.0)


@pytest.mark.parametrize("body", ["fixed", "removed"])
def test_still_bodies_do_not_move(body):
    motion = Scene(body=body).body_motion(1.0, [0.1, 1.6, 0.0], [0, 1, 0])
    np.testing.assert_array_equal(motion.R, np.eye(3))
    for value in motion[1:]:
        np.testing.assert_array_equal(value, 0.0)


def rotation_rate(R_plus, R_minus, h):
    """omega from (R(t+h) R(t-h)^T) = Exp(2 h omega) + O(h^3)."""
    return Rotation.from_matrix(R_plus @ R_minus.T).as_rotvec() / (2.0 * h)


@pytest.mark.parametrize("up", list(UPS))
def test_derivatives_match_finite_differences(rng, up):
    scene = random_scene(rng)
    pivot = rng.normal(size=3)
    keys = scene.keyframes
    at = lambda t: scene.body_motion(t, pivot, UPS[up])  # noqa: E731
    for k in range(len(keys) - 1):
        for u in (0.05, 0.3, 0.5, 0.77, 0.95):  # inside a segment: alpha and a jump at keys
            t = keys[k].time + u * (keys[k + 1].time - keys[k].time)
            m, plus, minus = at(t), at(t + H), at(t - H)
            scale = 1.0 + np.abs(np.concatenate(m[2:])).max()
            tol = dict(rtol=FINITE_DIFFERENCE, atol=FINITE_DIFFERENCE * scale)
            np.testing.assert_allclose(rotation_rate(plus.R, minus.R, H), m.omega, **tol)
            np.testing.assert_allclose((plus.omega - minus.omega) / (2 * H), m.alpha, **tol)
            np.testing.assert_allclose((plus.c - minus.c) / (2 * H), m.velocity, **tol)
            np.testing.assert_allclose((plus.velocity - minus.velocity) / (2 * H), m.acceleration, **tol)
            # a body point: its velocity and acceleration from the rigid-body formulas
            x = rng.normal(size=(4, 3))
            np.testing.assert_allclose((plus.points(x) - minus.points(x)) / (2 * H), m.point_velocities(x), **tol)
            np.testing.assert_allclose((plus.point_velocities(x) - minus.point_velocities(x)) / (2 * H),
                                       m.point_accelerations(x), **tol)


def test_velocity_is_continuous_at_the_keys(rng):
    """C1: one-sided difference quotients of R and c agree on both sides of every key."""
    scene = random_scene(rng)
    pivot, up = rng.normal(size=3), UPS["tilted"]
    at = lambda t: scene.body_motion(t, pivot, up)  # noqa: E731
    h = 1e-5
    for key in scene.keyframes:
        m, after, before = at(key.time), at(key.time + h), at(key.time - h)
        # one-sided quotients are within h |alpha| / 2, and velocities at t +- h within h |alpha|,
        # of the velocity at the key (alpha jumps there); a velocity jump would be O(1)
        worst = np.abs(np.concatenate([before.alpha, before.acceleration, after.alpha, after.acceleration])).max()
        tol = dict(rtol=0, atol=2 * h * (1.0 + worst))
        w_after = Rotation.from_matrix(after.R @ m.R.T).as_rotvec() / h
        w_before = Rotation.from_matrix(m.R @ before.R.T).as_rotvec() / h
        np.testing.assert_allclose(w_after, w_before, **tol)
        np.testing.assert_allclose(w_after, m.omega, **tol)
        np.testing.assert_allclose((after.c - m.c) / h, (m.c - before.c) / h, **tol)
        np.testing.assert_allclose((after.c - m.c) / h, m.velocity, **tol)
        # the analytic velocities from both sides
        np.testing.assert_allclose(after.omega, before.omega, **tol)
        np.testing.assert_allclose(after.velocity, before.velocity, **tol)


def test_rotation_stays_orthonormal(rng):
    scene = random_scene(rng, keys=8)
    for t in np.linspace(0.0, scene.keyframes[-1].time + 0.5, 97):
        R = scene.body_motion(t, np.zeros(3), UPS["tilted"]).R
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=ROUNDOFF)
        assert abs(np.linalg.det(R) - 1.0) < ROUNDOFF


def test_motion_preset_speeds_are_plausible():
    """Peak head speed of the preset: a brisk but human turn (under 300 degrees/s)."""
    scene = Scene.load("motion")
    speeds = [np.linalg.norm(scene.body_motion(t, [0, 1.6, 0], [0, 1, 0]).omega) for t in np.linspace(0, 4, 401)]
    assert 1.0 < max(speeds) < np.radians(300)


def test_pivot_point(rng):
    roots = rng.normal(size=(10, 3))
    np.testing.assert_allclose(Scene().pivot_point(roots), roots.mean(axis=0), atol=ROUNDOFF)
    np.testing.assert_array_equal(Scene(pivot=(0.0, 1.5, 0.0)).pivot_point(roots), [0.0, 1.5, 0.0])


# -------------------------------------------------------------------- trim


def random_helices(rng, strands=6) -> Helices:
    counts = rng.integers(1, 7, strands)
    offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    frames = np.array([Rotation.random(random_state=rng).as_matrix() for _ in range(strands)])
    return Helices(rng.normal(size=(strands, 3)), frames, offsets, rng.uniform(0.01, 0.05, offsets[-1]),
                   rng.normal(0.0, 20.0, (offsets[-1], 3)), rng.uniform(0, 1e-4, (strands, 2)))


def strand_totals(h: Helices) -> np.ndarray:
    return np.array([h.length[a:z].sum() for a, z in zip(h.offsets[:-1], h.offsets[1:])])


def curve(h: Helices, strand: int, s: np.ndarray) -> np.ndarray:
    a, z = h.offsets[strand], h.offsets[strand + 1]
    out = np.empty((len(s), 3))
    points_at(h.root[strand], h.frame0[strand], h.omega[a:z], h.length[a:z], np.ascontiguousarray(s), out)
    return out


def check_trim(old: Helices, new: Helices, element_map: np.ndarray, cuts: np.ndarray) -> None:
    totals = strand_totals(old)
    np.testing.assert_allclose(strand_totals(new), np.minimum(totals, cuts), rtol=ROUNDOFF, atol=0)
    np.testing.assert_array_equal(new.root, old.root)
    np.testing.assert_array_equal(new.frame0, old.frame0)
    np.testing.assert_array_equal(new.fit_error, old.fit_error)
    assert element_map.dtype == np.int64 and len(element_map) == new.n_elements
    np.testing.assert_array_equal(new.omega, old.omega[element_map])
    assert np.all(new.length > 0) and np.all(new.length <= old.length[element_map])
    for strand in range(old.n_strands):
        a, z = new.offsets[strand], new.offsets[strand + 1]
        assert np.all((element_map[a:z] >= old.offsets[strand]) & (element_map[a:z] < old.offsets[strand + 1]))
        # all but the last kept element are whole
        np.testing.assert_array_equal(new.length[a:z - 1], old.length[element_map[a:z - 1]])
        s = np.linspace(0.0, min(totals[strand], cuts[strand]), 41)
        np.testing.assert_allclose(curve(new, strand, s), curve(old, strand, s), rtol=0, atol=ROUNDOFF)


@pytest.mark.parametrize("fraction", [0.1, 0.5, 0.93, 1.0])
def test_trim_by_fraction_keeps_the_first_part_of_each_curve(rng, fraction):
    old = random_helices(rng)
    new, element_map = trim_helices(old, fraction=fraction)
    check_trim(old, new, element_map, fraction * strand_totals(old))
    if fraction == 1.0:
        np.testing.assert_array_equal(new.length, old.length)
        np.testing.assert_array_equal(element_map, np.arange(old.n_elements))


@pytest.mark.parametrize("length", [0.005, 0.04, 0.1, 1.0])
def test_trim_by_length_keeps_short_strands_whole(rng, length):
    old = random_helices(rng, strands=10)
    new, element_map = trim_helices(old, length=length)
    totals = strand_totals(old)
    check_trim(old, new, element_map, np.full(old.n_strands, length))
    for strand in np.flatnonzero(totals <= length):
        a, z = old.offsets[strand], old.offsets[strand + 1]
        np.testing.assert_array_equal(new.length[new.offsets[strand]:new.offsets[strand + 1]], old.length[a:z])


def test_cut_on_an_element_boundary_leaves_no_empty_element():
    h = Helices(np.zeros((1, 3)), np.eye(3)[None], np.array([0, 4], np.int64), np.array([0.25, 0.25, 0.25, 0.25]),
                np.zeros((4, 3)), np.zeros((1, 2)))
    new, element_map = trim_helices(h, length=0.5)
    np.testing.assert_array_equal(new.length, [0.25, 0.25])
    np.testing.assert_array_equal(element_map, [0, 1])
    np.testing.assert_array_equal(new.offsets, [0, 2])


@pytest.mark.parametrize("kwargs", [{}, {"length": 0.1, "fraction": 0.5}, {"fraction": 0.0}, {"fraction": 1.2},
                                    {"length": 0.0}, {"length": -1.0}])
def test_trim_rejects_bad_arguments(rng, kwargs):
    with pytest.raises(InputError):
        trim_helices(random_helices(rng), **kwargs)
