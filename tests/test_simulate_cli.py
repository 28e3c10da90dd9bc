"""``hairinv simulate`` end to end, checked from the files it writes.

Runtime: about 20-40 s warm (one small inversion, four short simulations).
"""

from __future__ import annotations

import shutil

import h5py
import numpy as np
import pytest

from conftest import SAMPLES
from hairinv import stages
from test_cli import assert_refused, hairinv


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    """``hairinv invert settled.h5 body.obj --guides 12 --target zero``: a groom at rest."""
    folder = tmp_path_factory.mktemp("simulate")
    shutil.copyfile(SAMPLES / "settled.h5", folder / "settled.h5")
    shutil.copyfile(SAMPLES / "body.obj", folder / "body.obj")
    result = hairinv(folder, "invert", "settled.h5", "body.obj", "--guides", "12", "--target", "zero",
                     "-o", "model.h5")
    assert result.returncode == 0, result.stderr
    return folder


def test_still_scene_keeps_the_inverted_groom_still(model):
    result = hairinv(model, "simulate", "model.h5", "--seconds", "0.2", "--fps", "25", "-o", "still.h5")
    assert result.returncode == 0, result.stderr
    assert "frame    5" in result.stdout and "wrote" in result.stdout
    assert "halved   0" in result.stdout  # a still groom needs no halved step
    stage = stages.read_stage(model / "still.h5")
    assert list(stage.groups) == ["curves", "helices", "contacts", "model", "frames"]
    with h5py.File(model / "still.h5", "r") as fh:
        frames, helices = fh["frames"], fh["helices"]
        F, E, S = 6, len(helices["omega"]), len(helices["root"])
        assert frames["time"].shape == (F,) and np.allclose(frames["time"][()], np.arange(F) / 25)
        assert frames["omega"].shape == (F, E, 3) and frames["root"].shape == (F, S, 3)
        assert frames["frame0"].shape == (F, S, 3, 3) and frames["body_transform"].shape == (F, 4, 4)
        # the body never moved, the roots neither, and the shape barely
        assert np.allclose(frames["body_transform"][()], np.eye(4))
        assert np.allclose(frames["root"][()], helices["root"][()][None])
        assert np.abs(frames["omega"][()] - helices["omega"][()][None]).max() < 1e-3
        assert frames["displacement"][()].max() < 1e-4  # m
        assert frames.attrs["init"] == "inverted" and frames.attrs["scene"] == "still"


def test_naive_initialisation_sags(model):
    result = hairinv(model, "simulate", "model.h5", "--seconds", "0.2", "--fps", "25", "--init", "naive",
                     "-o", "naive.h5")
    assert result.returncode == 0, result.stderr
    with h5py.File(model / "naive.h5", "r") as fh:
        assert fh["frames"]["displacement"][()].max() > 1e-3  # m: it sags at once


def test_motion_scene_moves_the_roots_with_the_body(model):
    result = hairinv(model, "simulate", "model.h5", "--scene", "motion", "--seconds", "0.4", "--fps", "10",
                     "-o", "motion.h5")
    assert result.returncode == 0, result.stderr
    with h5py.File(model / "motion.h5", "r") as fh:
        frames, helices = fh["frames"], fh["helices"]
        T = frames["body_transform"][()]
        assert not np.allclose(T[-1], np.eye(4))  # the head has turned
        for f in range(len(T)):
            R, c = T[f, :3, :3], T[f, :3, 3]
            assert np.allclose(R @ R.T, np.eye(3), atol=1e-12)
            # roots and root frames are the body-frame ones carried by the body's transform
            assert np.allclose(frames["root"][f], helices["root"][()] @ R.T + c, atol=1e-12)
            assert np.allclose(frames["frame0"][f], helices["frame0"][()] @ R.T, atol=1e-12)
        assert np.all(np.isfinite(frames["omega"][()]))


def test_trim_scene_stores_the_cut_layout(model):
    result = hairinv(model, "simulate", "model.h5", "--scene", "trim", "--seconds", "0.1", "--fps", "10",
                     "-o", "trim.h5")
    assert result.returncode == 0, result.stderr
    with h5py.File(model / "trim.h5", "r") as fh:
        frames, helices = fh["frames"], fh["helices"]
        offsets, length = frames["offsets"][()], frames["length"][()]
        assert frames.attrs["trimmed"]
        assert frames["omega"].shape[1] == len(length) == offsets[-1]
        full = np.add.reduceat(helices["length"][()], helices["offsets"][()][:-1])
        cut = np.add.reduceat(length, offsets[:-1])
        assert np.allclose(cut, 0.5 * full)


BAD = {
    "missing model": (["simulate", "nope.h5"], "nope.h5", "no such file"),
    "raw curves": (["simulate", "settled.h5"], "settled.h5", "invert"),
    "unknown scene": (["simulate", "model.h5", "--scene", "dance"], "dance", "preset"),
    "bad time step": (["simulate", "model.h5", "--set", "dynamics.time_step=-1"], "time_step", "> 0"),
    "output is the model": (["simulate", "model.h5", "-o", "model.h5"], "model.h5", "input"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_input(model, tmp_path, case):
    args, name, fragment = BAD[case]
    for f in ("settled.h5", "body.obj", "model.h5"):
        shutil.copyfile(model / f, tmp_path / f)
    assert_refused(tmp_path, args, name, fragment)
