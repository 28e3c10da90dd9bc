"""``hairinv export -o OUT.png --plot render``: a still of the groom on its body rendered by Blender.

The render runs where Blender's Python is at hand (.venv-blender from ``make blender``, or
``$HAIRINV_BLENDER_PYTHON``), as tests/test_blender.py finds it, and skips otherwise, saying how to get it.
The PNG is checked by its pixels: brown hair, a light grey body and the grey sky, the hair where a pinhole
camera of the lens and place hairinv asked for puts it (projected here with numpy, not by Blender). Without
Blender the export is refused in one sentence, and nothing is written.

Runtime: about 20-40 s with Blender (one detection, one render), 2 s without.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from conftest import ENV, ROOT, SAMPLES, assert_refused, hairinv, snapshot
from hairinv.errors import InputError
from hairinv.export import export, render
from hairinv.export.source import ExportSource, OutputAxes

BLENDER_PYTHON = Path(os.environ.get("HAIRINV_BLENDER_PYTHON", ROOT / ".venv-blender" / "bin" / "python"))


@pytest.fixture(scope="module")
def contacts(tmp_path_factory):
    """``hairinv detect settled.h5 body.obj``: 40 strands on the sample bust, the body recorded."""
    folder = tmp_path_factory.mktemp("render")
    shutil.copyfile(SAMPLES / "settled.h5", folder / "settled.h5")
    shutil.copyfile(SAMPLES / "body.obj", folder / "body.obj")
    result = hairinv(folder, "detect", "settled.h5", "body.obj", "-o", "contacts.h5")
    assert result.returncode == 0, result.stderr
    return folder


def pixels(path) -> np.ndarray:
    """(H, W, 3) float in [0, 1]: the PNG's colours."""
    from PIL import Image

    with Image.open(path) as image:
        return np.asarray(image.convert("RGB"), dtype=np.float64) / 255.0


def projected(source: ExportSource, size) -> np.ndarray:
    """(P, 2) pixel coordinates (column, row) of the input strands' vertices through the camera the render
    asks for: a pinhole at its location looking at its target, +Z up (Blender's frame), its lens over its
    sensor across the image's width."""
    axes = OutputAxes.onto(source.up, "z")
    points = axes.points(source.points)
    front = axes.rotation @ OutputAxes.onto(source.up, "y").rotation.T @ np.array([0.0, 0.0, 1.0])
    view = render.camera(points, front, np.array([0.0, 0.0, 1.0]), size)
    forward = view["target"] - view["location"]
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    d = points - view["location"]
    depth = d @ forward
    scale = render.LENS_MM / render.SENSOR_MM * size[0]
    return np.stack([0.5 * size[0] + scale * (d @ right) / depth, 0.5 * size[1] - scale * (d @ up) / depth], axis=1)


def test_a_render_shows_brown_hair_on_a_grey_body_where_the_camera_puts_it(contacts, monkeypatch):
    if not BLENDER_PYTHON.exists():
        pytest.skip(f"Blender's Python not found at {BLENDER_PYTHON}: `make blender` installs Blender as the bpy "
                    "module in .venv-blender (or set HAIRINV_BLENDER_PYTHON to a Python that has bpy)")
    monkeypatch.setitem(ENV, "HAIRINV_BLENDER_PYTHON", str(BLENDER_PYTHON))
    result = hairinv(contacts, "export", "contacts.h5", "-o", "still.png", "--plot", "render")
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert lines[0].startswith("wrote still.png: PNG, 640 x 640 px, rendered by Blender ")
    assert lines[1].startswith("shows the input shape on the body body.obj; strands drawn ")
    assert result.stderr == ""
    image = pixels(contacts / "still.png")
    assert image.shape == (640, 640, 3)
    r, g, b = image[..., 0], image[..., 1], image[..., 2]
    hair = (r > g + 0.06) & (g > b + 0.03)  # brown: red over green over blue
    corners = np.array([np.median(image[rows, columns].reshape(-1, 3), axis=0)
                        for rows in (slice(0, 16), slice(-16, None)) for columns in (slice(0, 16), slice(-16, None))])
    corner = corners[0]
    assert np.abs(corners - corner).max() < 0.02, corners  # the sky in every corner
    sky = np.abs(image - corner).max(axis=2) < 0.03
    assert corner[2] > corner[0] and np.ptp(corner) < 0.05  # a bluish grey
    body = (np.ptp(image, axis=2) < 0.04) & (r > corner[0] + 0.05)  # grey, lighter than the sky
    assert hair.mean() > 0.002, hair.mean()
    assert body.mean() > 0.15 and sky.mean() > 0.2, (body.mean(), sky.mean())
    # the camera frames the strands: every vertex falls inside the image, away from its edges, and the brown
    # pixels lie over them (within a few pixels of a projected vertex)
    where = projected(ExportSource(contacts / "contacts.h5"), (640, 640))
    assert where.min() > 16 and where.max() < 640 - 16, (where.min(), where.max())
    rows, columns = np.nonzero(hair)
    assert columns.min() >= where[:, 0].min() - 8 and columns.max() <= where[:, 0].max() + 8
    assert rows.min() >= where[:, 1].min() - 8 and rows.max() <= where[:, 1].max() + 8
    # most brown pixels lie in a cell of 8 px, or one of its 8 neighbours, that a vertex projects to
    cells = {(int(x) // 8 + dx, int(y) // 8 + dy) for x, y in where for dx in (-1, 0, 1) for dy in (-1, 0, 1)}
    near = np.array([(c // 8, rr // 8) in cells for rr, c in zip(rows, columns)])
    assert near.mean() > 0.9, near.mean()
    # the hair spans a good part of the image: framed, not a speck
    assert np.ptp(columns) > 160 and np.ptp(rows) > 160


def test_without_blender_the_render_is_refused_saying_how_to_get_it(contacts, monkeypatch):
    monkeypatch.delenv("HAIRINV_BLENDER_PYTHON", raising=False)
    monkeypatch.setattr(render, "BLENDER_VENV", ".no-such-venv-blender")
    monkeypatch.setattr(render, "_has_bpy", lambda: False)
    before = snapshot(contacts)
    with pytest.raises(InputError) as refused:
        export(contacts / "contacts.h5", contacts / "none.png", plot="render")
    message = str(refused.value)
    assert message.startswith(f"{contacts / 'none.png'}: a render needs Blender") and "`make blender`" in message
    assert snapshot(contacts) == before


def test_a_blender_python_that_is_not_there_is_refused_in_one_sentence(contacts, tmp_path, monkeypatch):
    for name in ("contacts.h5", "body.obj", "settled.h5"):
        shutil.copyfile(contacts / name, tmp_path / name)
    monkeypatch.setitem(ENV, "HAIRINV_BLENDER_PYTHON", str(tmp_path / "no" / "python"))
    assert_refused(tmp_path, ["export", "contacts.h5", "-o", "still.png", "--plot", "render"], "still.png",
                   "HAIRINV_BLENDER_PYTHON")
    assert_refused(tmp_path, ["export", "contacts.h5", "-o", "still.png", "--plot", "render", "--color",
                              "fit-error"], "still.png", "--color")
