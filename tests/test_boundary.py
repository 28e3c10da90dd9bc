"""Every number that enters is checked where it is read: exit 2 and one sentence, never an internal error.

First the failures a new user met (a CLI subprocess each, on one small inverted model), then a generator
that feeds every setting, every scene key and every dataset of a stage file values nobody here wrote
(non-finite, negative, zero, huge, wrongly typed), run in-process: each is either accepted with a finite
result or refused with an :class:`InputError` (exit 2).

Runtime: one inversion of samples/settled.h5 (10-20 s with a warm numba cache), a handful of refusals
(about 1 s each, interpreter start-up), and about 1,000 in-process cases (a few seconds).
"""

from __future__ import annotations

import dataclasses
import math
import shutil
import typing

import h5py
import numpy as np
import pytest

from conftest import SAMPLES, hairinv
from hairinv import config, stages
from hairinv.dynamics.scene import Scene
from hairinv.errors import InputError


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    """samples/settled.h5 inverted on the sample body: a folder holding ``model.h5``."""
    folder = tmp_path_factory.mktemp("boundary")
    shutil.copy(SAMPLES / "body.obj", folder / "body.obj")
    result = hairinv(folder, "-q", "invert", SAMPLES / "settled.h5", "body.obj", "-o", "model.h5")
    assert result.returncode == 0, result.stderr
    return folder


def assert_refused(result, *fragments: str) -> None:
    """Exit 2, one line on stderr naming what is wrong (every fragment), no internal error."""
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert "internal error" not in lines[0]
    for fragment in fragments:
        assert fragment in lines[0], lines[0]


def assert_usage_error(result, option: str) -> None:
    """Exit 2 with click's usage error naming ``option`` (its last line), no internal error."""
    assert result.returncode == 2, result.stderr
    assert "internal error" not in result.stderr and "Traceback" not in result.stderr
    last = result.stderr.strip().splitlines()[-1]
    assert f"Invalid value for '{option}'" in last and "finite" in last, result.stderr


# --------------------------------------------------------------------------- what a new user met


def test_an_absurd_frame_rate_in_a_scene_file_is_refused_before_anything_is_allocated(model):
    """fps = 1e12 tried to allocate 7 TiB of frames (an internal error)."""
    (model / "fast.toml").write_text('body = "fixed"\nseconds = 1.0\nfps = 1e12\n')
    result = hairinv(model, "simulate", "model.h5", "--scene", "fast.toml", "-o", "out.h5")
    assert_refused(result, "fast.toml", "fps")
    assert not (model / "out.h5").exists()


def test_a_binary_file_given_as_a_scene_is_refused(model):
    """A UnicodeDecodeError came back as an internal error."""
    (model / "binary.toml").write_bytes(bytes(range(256)) * 4)
    result = hairinv(model, "simulate", "model.h5", "--scene", "binary.toml", "-o", "out.h5")
    assert_refused(result, "binary.toml", "UTF-8")
    assert not (model / "out.h5").exists()


def test_an_infinite_setting_is_refused(model):
    """--set dynamics.time_step=inf ran a simulation and exited 0."""
    result = hairinv(model, "simulate", "model.h5", "--seconds", "0.05", "--set", "dynamics.time_step=inf",
                     "-o", "out.h5")
    assert_refused(result, "--set", "dynamics.time_step", "inf")
    assert not (model / "out.h5").exists()


@pytest.mark.parametrize("option", ["--seconds", "--fps"])
def test_a_nan_duration_or_rate_on_the_command_line_is_refused(model, option):
    """--seconds nan: ValueError cannot convert float NaN to integer, an internal error."""
    result = hairinv(model, "simulate", "model.h5", option, "nan", "-o", "out.h5")
    assert_usage_error(result, option)
    assert not (model / "out.h5").exists()


def test_a_duration_beyond_the_frames_a_run_holds_is_refused_in_one_sentence(model):
    result = hairinv(model, "simulate", "model.h5", "--seconds", "1e9", "-o", "out.h5")
    assert_refused(result, "--seconds", "at most")
    result = hairinv(model, "simulate", "model.h5", "--seconds", "1000", "--fps", "1e4", "-o", "out.h5")
    assert_refused(result, "frames", "at most 1,000,000")
    assert not (model / "out.h5").exists()


def test_a_curvature_beyond_any_hair_in_a_stage_file_is_refused(model):
    """A finite curvature of 1e300 1/m overflowed to inf in the energies: LinAlgError, an internal error."""
    shutil.copy(model / "model.h5", model / "curled.h5")
    with h5py.File(model / "curled.h5", "r+") as fh:
        fh["helices/omega"][0, 0] = 1e300
    result = hairinv(model, "simulate", "curled.h5", "--seconds", "0.05", "-o", "out.h5")
    assert_refused(result, "curled.h5", "/helices/omega")
    assert not (model / "out.h5").exists()


def test_lengths_take_a_unit_everywhere(model):
    """One rule for lengths: a unit may always be given; a bare number is metres where the help says m."""
    sets = config.resolve(sets=["fit.tolerance=0.2mm", "contacts.body_distance=4 mm"])
    assert sets.fit.tolerance == pytest.approx(2e-4, rel=1e-12, abs=0)
    assert sets.contacts.body_distance == pytest.approx(4e-3, rel=1e-12, abs=0)
    assert config.resolve(sets=["fit.tolerance=2e-4"]).fit.tolerance == 2e-4
    result = hairinv(model, "fit", SAMPLES / "settled.h5", "--guides", "2", "--tolerance", "0.3mm", "-o", "f.h5")
    assert result.returncode == 0, result.stderr
    with h5py.File(model / "f.h5") as fh:
        assert '"tolerance": 0.0003' in fh["helices"].attrs["config"]
    with pytest.raises(InputError, match="unknown unit 'furlong'"):
        config.resolve(sets=["fit.tolerance=0.2furlong"])
    with pytest.raises(InputError, match="solver.gamma"):
        config.resolve(sets=["solver.gamma=1mm"])  # not a length


# --------------------------------------------------------------------------- the generator

#: What nobody here wrote: non-finite, negative, zero, huge, tiny and wrongly typed values.
HOSTILE_VALUES = [float("nan"), float("inf"), float("-inf"), -1.0, -1, 0, 0.0, 1e308, 10**30, 1e-300, True,
                  "abc", "", [1.0], {"a": 1}, "nan", "-inf", "1e999", "0.2mm", "-3mm"]

NUMERIC_SETTINGS = [
    f"{section}.{f.name}"
    for section, attr in config._SECTIONS.items()
    for f in dataclasses.fields(typing.get_type_hints(config.Settings)[attr])
]


def test_every_numeric_setting_has_a_documented_range():
    hints = {key: typing.get_type_hints(typing.get_type_hints(config.Settings)[config._SECTIONS[key.split(".")[0]]])
             [key.split(".")[1]] for key in NUMERIC_SETTINGS}
    numeric = {key for key, typ in hints.items() if typ in (int, float)}
    assert numeric == set(config.SETTING_RANGE)
    defaults = config.Settings().to_dict()
    for key in numeric:  # the defaults lie within their ranges
        section, name = key.split(".")
        assert config.range_error(key, defaults[section][name]) is None, key


@pytest.mark.parametrize("key", NUMERIC_SETTINGS)
def test_every_setting_takes_any_value_or_refuses_it(key):
    """Each value, from a TOML file (a table) and from --set (its text): accepted with a finite number in
    the setting's range, or an InputError naming the setting."""
    section, name = key.split(".")
    for value in HOSTILE_VALUES:
        for source, given in (("file.toml", value), ("--set", str(value))):
            try:
                settings = config.apply(config.Settings(), {section: {name: given}}, source)
            except InputError as error:
                assert key in str(error) and str(error).startswith(source), (value, str(error))
                continue
            got = getattr(getattr(settings, config._SECTIONS[section]), name)
            if isinstance(got, (int, float)) and not isinstance(got, bool):
                assert math.isfinite(got) and config.range_error(key, got) is None, (value, got)


SCENE_KEYS = [(None, key) for key in ("description", "body", "seconds", "fps", "pivot", "forward")] + \
    [("keyframe", key) for key in ("time", "yaw", "pitch", "roll", "translate")] + \
    [("trim", key) for key in ("length", "fraction", "time")]


def _scene_text(table, key, value) -> str:
    import json

    literal = {float("nan"): "nan", float("inf"): "inf", float("-inf"): "-inf"}.get(value) \
        if isinstance(value, float) and not math.isfinite(value) else None
    if literal is None:
        literal = "true" if value is True else json.dumps(value) if not isinstance(value, dict) else "{ a = 1 }"
    if table is None:
        return f"{key} = {literal}\n"
    if table == "keyframe":
        base = {"time": "0.0"}
        base[key] = literal
        keys = "\n".join(f"{k} = {v}" for k, v in base.items())
        return f'body = "keyframed"\n[[keyframe]]\n{keys}\n[[keyframe]]\ntime = 1.0\n'
    base = {"fraction": "0.5"} if key != "length" else {}
    base[key] = literal
    return "[trim]\n" + "\n".join(f"{k} = {v}" for k, v in base.items()) + "\n"


@pytest.mark.parametrize("table, key", SCENE_KEYS)
def test_every_scene_key_takes_any_value_or_refuses_it(tmp_path, table, key):
    """Each value in a scene file: a scene whose run is finite and bounded, or an InputError naming the file."""
    from hairinv.dynamics.scene import MAX_FRAMES

    path = tmp_path / "scene.toml"
    for value in HOSTILE_VALUES:
        path.write_text(_scene_text(table, key, value))
        try:
            scene = Scene.load(path)
        except InputError as error:
            assert str(error).startswith(str(path)), (value, str(error))
            continue
        assert math.isfinite(scene.seconds) and math.isfinite(scene.fps), value
        assert scene.seconds * scene.fps <= MAX_FRAMES, value
        motion = scene.body_motion(0.5, np.zeros(3), np.array([0.0, 1.0, 0.0]))
        assert all(np.all(np.isfinite(part)) for part in motion), value


def _datasets(path):
    with h5py.File(path) as fh:
        return [f"{g}/{k}" for g in fh for k in fh[g] if fh[g][k].dtype.kind == "f"]


@pytest.mark.parametrize("dataset", _datasets(SAMPLES / "settled.h5"))
def test_every_stage_dataset_takes_any_value_or_refuses_it(tmp_path, dataset):
    """Each hostile value written into one entry of a dataset of samples/settled.h5: read with finite
    strands (their centre lines), or an InputError naming the file and the dataset."""
    from hairinv.model import Helices
    from hairinv.rod.helix import points_at

    for value in (float("nan"), float("inf"), float("-inf"), -1.0, 0.0, 1e300, -1e300, 1e12, 1e-300):
        path = tmp_path / "hostile.h5"
        shutil.copy(SAMPLES / "settled.h5", path)
        with h5py.File(path, "r+") as fh:
            data = fh[dataset][...]
            data.reshape(-1)[data.size // 2] = value
            fh[dataset][...] = data
        try:
            stage = stages.read_stage(path)
            helices = Helices.from_group(stage[stages.HELICES])
            a, z = int(helices.offsets[0]), int(helices.offsets[1])
            s = np.linspace(0.0, float(helices.length[a:z].sum()), 7)
            points = np.empty((len(s), 3))
            points_at(np.ascontiguousarray(helices.root[0]), np.ascontiguousarray(helices.frame0[0]),
                      np.ascontiguousarray(helices.omega[a:z]), np.ascontiguousarray(helices.length[a:z]), s, points)
        except InputError as error:
            assert str(error).startswith(str(path)) and f"/{dataset}" in str(error), (value, str(error))
            continue
        assert np.all(np.isfinite(points)), (dataset, value)
