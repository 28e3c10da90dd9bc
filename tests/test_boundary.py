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

from conftest import SAMPLES
from hairinv import config, stages
from hairinv.dynamics.scene import Scene
from hairinv.errors import InputError
from test_cli import hairinv


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
