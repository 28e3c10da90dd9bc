"""``hairinv export --follow`` / ``--render``: a simulation of guides written as its render groom.

A 16-strand groom is fitted with ``--guides 5``; its simulation is made by hand, the guides moved rigidly (the
body's motion, shapes unchanged), so every render strand must move with the same rigid motion: a closed
form, whatever the guides and weights. Refusals: one sentence naming the file, exit 2, nothing written.
"""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from conftest import FLOAT32_M, assert_refused, hairinv, snapshot
from hairinv import stages
from hairinv.errors import InputError
from hairinv.export import export
from hairinv.formats import read_curves

GRID = 4  # strands per side of the patch, 5 mm apart
FRAMES = 3


def _motion(k: int) -> tuple[np.ndarray, np.ndarray]:
    a = 0.4 * k
    Q = np.array([[np.cos(a), 0.0, np.sin(a)], [0.0, 1.0, 0.0], [-np.sin(a), 0.0, np.cos(a)]])
    b = 0.2 * k
    Q = Q @ np.array([[1.0, 0.0, 0.0], [0.0, np.cos(b), -np.sin(b)], [0.0, np.sin(b), np.cos(b)]])
    return Q, np.array([0.01 * k, -0.02 * k, 0.005 * k])


def _groom(path):
    pieces = []
    for i in range(GRID):
        for j in range(GRID):
            root = np.array([0.005 * i, 1.7, 0.005 * j])
            s = np.linspace(0.0, 0.1 + 0.01 * i, 12 + j)
            pieces.append(root + np.column_stack([0.01 * np.sin(20 * s + i), -s, 0.003 * np.cos(25 * s + j)]))
    points = np.concatenate(pieces)
    offsets = np.concatenate([[0], np.cumsum([len(p) for p in pieces])]).astype(np.int64)
    stages.write_stage(path, [stages.Group(stages.CURVES, {"points": points, "offsets": offsets},
                                           attrs={"source": "test patch", "scale_to_m": 1.0,
                                                  "up": np.array([0.0, 1.0, 0.0])})], "test")
    return points, offsets


def _simulated(fit, out, trimmed=False):
    """``fit`` with a hand-made /frames: every strand carried rigidly by :func:`_motion`."""
    stage = stages.read_stage(fit)
    h = stage[stages.HELICES]
    motions = [_motion(k) for k in range(FRAMES)]
    T = np.tile(np.eye(4), (FRAMES, 1, 1))
    for k, (Q, c) in enumerate(motions):
        T[k, :3, :3], T[k, :3, 3] = Q, c
    data = {"time": np.arange(FRAMES) / 30.0, "omega": np.stack([h["omega"]] * FRAMES),
            "root": np.stack([h["root"] @ Q.T + c for Q, c in motions]),
            "frame0": np.stack([h["frame0"] @ Q.T for Q, c in motions]), "body_transform": T}
    attrs = {"fps": 30.0}
    if trimmed:
        data["offsets"], data["length"] = h["offsets"], h["length"]
        attrs["trimmed"] = True
    groups = [*stage.groups.values(), stages.Group(stages.FRAMES, data, attrs=attrs)]
    stages.write_stage(out, groups, "test")


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    folder = tmp_path_factory.mktemp("follow")
    points, offsets = _groom(folder / "groom.h5")
    for args in (["fit", "groom.h5", "--guides", "5", "-o", "guides.fit.h5"], ["fit", "groom.h5", "-o", "all.fit.h5"]):
        done = hairinv(folder, *args)
        assert done.returncode == 0, done.stderr
    _simulated(folder / "guides.fit.h5", folder / "guides.frames.h5")
    _simulated(folder / "all.fit.h5", folder / "all.frames.h5")
    return folder, points, offsets


def test_the_render_groom_moves_rigidly_with_rigidly_moved_guides(made, tmp_path):
    from pxr import Usd, UsdGeom

    folder, points, offsets = made
    done = hairinv(folder, "export", "guides.frames.h5", "-o", tmp_path / "render.usda", "--follow")
    assert done.returncode == 0, done.stderr
    assert "16 strands (5 of them simulated guides)" in done.stdout
    usd = Usd.Stage.Open(str(tmp_path / "render.usda"))
    curves = UsdGeom.BasisCurves(usd.GetPrimAtPath("/Root/Hair"))
    assert np.array(curves.GetCurveVertexCountsAttr().Get()).tolist() == np.diff(offsets).tolist()
    np.testing.assert_allclose(np.array(curves.GetPointsAttr().Get()), points, rtol=0, atol=FLOAT32_M)
    for k in range(FRAMES):
        Q, c = _motion(k)
        np.testing.assert_allclose(np.array(curves.GetPointsAttr().Get(k)), points @ Q.T + c, rtol=0, atol=FLOAT32_M)
    api = UsdGeom.PrimvarsAPI(curves.GetPrim())
    guide = np.array(api.GetPrimvar("groom_guide").Get())
    fitted = stages.read_stage(folder / "guides.fit.h5")[stages.CURVES]
    is_guide = [any(np.array_equal(points[offsets[s]], r) for r in fitted["points"][fitted["offsets"][:-1]])
                for s in range(GRID * GRID)]
    assert guide.tolist() == [int(x) for x in is_guide] and guide.sum() == 5
    weights = np.array(api.GetPrimvar("guide_weights").Get()).reshape(GRID * GRID, 3)
    np.testing.assert_allclose(weights.sum(axis=1), 1.0, rtol=1e-6)


def test_a_polyline_frame_of_the_render_groom(made, tmp_path):
    folder, points, offsets = made
    done = hairinv(folder, "export", "guides.frames.h5", "-o", tmp_path / "f2.obj", "--shape", "frame:2",
                   "--render", "groom.h5")
    assert done.returncode == 0, done.stderr
    raw = read_curves(tmp_path / "f2.obj")
    Q, c = _motion(2)
    assert raw.offsets.tolist() == offsets.tolist()
    np.testing.assert_allclose(raw.points, points @ Q.T + c, rtol=0, atol=1e-12)


def test_every_strand_simulated_writes_the_frames_as_they_are(made, tmp_path):
    folder, _, _ = made
    lines = export(folder / "all.frames.h5", tmp_path / "follow.obj", "frame:1", follow=True).lines
    assert any("are the simulated ones; the frames are written as they are" in line for line in lines)
    export(folder / "all.frames.h5", tmp_path / "plain.obj", "frame:1")
    assert (tmp_path / "follow.obj").read_text() == (tmp_path / "plain.obj").read_text()


def test_a_changed_or_gone_input_groom_is_refused(made, tmp_path):
    folder, _, _ = made
    shutil.copy(folder / "groom.h5", tmp_path / "groom.h5")
    done = hairinv(tmp_path, "fit", "groom.h5", "--guides", "5", "-o", "fit.h5")
    assert done.returncode == 0, done.stderr
    _simulated(tmp_path / "fit.h5", tmp_path / "frames.h5")
    with open(tmp_path / "groom.h5", "ab") as fh:
        fh.write(b"\0")
    assert_refused(tmp_path, ["export", "frames.h5", "-o", "out.usda", "--follow"], "frames.h5",
                   "has changed since (its SHA-256 differs from the recorded one): that hairstyle is its render "
                   "groom; name it with --render STYLE")
    (tmp_path / "groom.h5").unlink()
    assert_refused(tmp_path, ["export", "frames.h5", "-o", "out.usda", "--follow"], "frames.h5",
                   "the hairstyle 'groom.h5' it was made with is not there any more")


@pytest.mark.parametrize("case, fragment", [
    ("picture", "--follow applies to the groom formats"),
    ("no frames", "has no /frames group, so it has no simulated guides"),
    ("render missing", "no such file (the render groom, --render)"),
    ("two files", "--follow writes one stage file's render groom; give one stage file"),
    ("trimmed", "is a trimmed simulation"),
    ("elsewhere", "from the nearest guide's (median)"),
    ("no record", "records no hairstyle file its strands were read from"),
])
def test_refusals_name_the_file_and_write_nothing(made, tmp_path, case, fragment):
    folder, points, offsets = made
    out = tmp_path / ("out.png" if case == "picture" else "out.usda")
    stage, render = folder / "guides.frames.h5", None
    follow = True
    if case == "no frames":
        stage = folder / "guides.fit.h5"
    elif case == "render missing":
        render = tmp_path / "missing.h5"
    elif case == "two files":
        stage = [stage, stage]
    elif case == "trimmed":
        stage = tmp_path / "trimmed.h5"
        _simulated(folder / "guides.fit.h5", stage, trimmed=True)
    elif case == "elsewhere":
        render = tmp_path / "far.h5"
        far = {"points": points + [1.0, 0.0, 0.0], "offsets": offsets}
        stages.write_stage(render, [stages.Group(stages.CURVES, far, attrs={"source": "far", "scale_to_m": 1.0,
                                                                            "up": np.array([0.0, 1.0, 0.0])})], "test")
    elif case == "no record":
        fitted = stages.read_stage(folder / "guides.frames.h5")
        curves = fitted[stages.CURVES]
        groups = [stages.Group(stages.CURVES, curves.datasets, curves.attrs, curves.config, []),
                  *[g for name, g in fitted.groups.items() if name != stages.CURVES]]
        stage = tmp_path / "unrecorded.h5"
        stages.write_stage(stage, groups, "test")
    with pytest.raises(InputError, match=fragment.replace("(", r"\(").replace(")", r"\)")):
        export(stage, out, follow=follow, render=render)
    assert not out.exists()


def test_if_stale_records_the_render_groom(made, tmp_path):
    """``--if-stale`` with ``--render``: the render groom's file is an input of the record, ``follow`` an
    option; a current export is left as it is, a changed render groom or the plain export make it again."""
    import json

    folder, _, _ = made
    for name in ("groom.h5", "guides.frames.h5"):
        shutil.copy(folder / name, tmp_path / name)
    args = ["export", "guides.frames.h5", "-o", "r.obj", "--shape", "frame:1", "--render", "groom.h5", "--if-stale"]
    assert hairinv(tmp_path, *args).returncode == 0
    record = json.loads((tmp_path / "r.obj.hairinv.json").read_text())
    assert record["options"]["follow"] is True
    assert [r and r["name"] for r in record["inputs"]] == ["guides.frames.h5", None, "groom.h5"]
    again = hairinv(tmp_path, *args)
    assert again.returncode == 0 and "is current" in again.stdout
    plain = hairinv(tmp_path, "export", "guides.frames.h5", "-o", "r.obj", "--shape", "frame:1", "--if-stale")
    assert plain.returncode == 0 and "is current" not in plain.stdout
