"""The PNG picture's geometry and colours, against what each should be by construction.

- The body is drawn at the frame shown: its triangles under the last frame are the rest mesh moved by a
  rotation and translation built here with Rodrigues' formula, then turned from +Z up to the picture's +Y.
- Depth: which points a ball hides, against the closed form of a sphere; on a drawn picture, a strand
  behind the ball is faded and drawn before the one in front, and its pixels stay the body's grey.
- The colour scale: the bar's limits are numpy's quantiles of the values where a few values would set its
  range, and the bar is logarithmic where those span two decades.

Runtime: a few seconds (the depth kernel compiles once).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh  # a dependency of hairinv

from hairinv import stages
from hairinv.export import export
from hairinv.export.picture import (DEPTH_TOLERANCE, HIDDEN_ALPHA, LOG_SPAN, OUTLIER_SHARE, QUANTILES,
                                    Body, colour_scale, draw, hidden_by)
from hairinv.export.source import ExportSource

# float64 round-off of a rotation and translation of points within a metre of the origin.
ROUNDOFF_M = 1e-12
RADIUS = 0.1  # m, the ball the strands are drawn over
# The polygonal ball (icosphere, subdivision 4: edges of 6 mm on a 0.1 m ball) lies within 0.05 mm of the
# sphere; points nearer than this to the sphere's outline or to the depth test's threshold are not judged.
UNDECIDED_M = 4e-3


def _rodrigues(axis, angle: float) -> np.ndarray:
    """Rotation matrix by ``angle`` about ``axis``: I + sin K + (1 - cos) K^2."""
    k = np.asarray(axis, dtype=np.float64) / np.linalg.norm(axis)
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * K @ K


def _z_up_to_picture(points: np.ndarray) -> np.ndarray:
    """A +Z up groom in the picture's +Y up frame: the quarter turn about -X, (x, y, z) -> (x, z, -y)."""
    return np.stack([points[:, 0], points[:, 2], -points[:, 1]], axis=1)


def _picture_to_z_up(points: np.ndarray) -> np.ndarray:
    return np.stack([points[:, 0], -points[:, 2], points[:, 1]], axis=1)


def _write_obj(path: Path, vertices: np.ndarray, faces: np.ndarray) -> None:
    """OBJ at full float64 precision, so the drawn body can be compared to round-off."""
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in vertices.tolist()]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces.tolist()]
    path.write_text("\n".join(lines) + "\n")


# Three straight strands along +x, 6 cm long, in the picture's frame: F in front of the ball (z = +0.12),
# B behind it and inside its outline from the front, O behind it but beside its outline.
STRANDS = {"F": (-0.03, 0.0, 0.12), "B": (-0.03, 0.02, -0.12), "O": (0.13, 0.0, -0.12)}
STRAND_LENGTH = 0.06
VERTICES_PER_STRAND = 7
# The body's pose at the last frame, in the groom's (+Z up) frame: a turn about a tilted axis and a shift.
TURN_AXIS, TURN_ANGLE = (0.3, -0.2, 1.0), 0.9
SHIFT = np.array([0.01, -0.02, 0.015])


def make_ball_stage(folder: Path, fit_error=None, strands=STRANDS) -> dict:
    """A +Z up stage file in metres: the strands over a ball recorded as the run's body, two frames, the body
    at rest in the first and turned by (TURN_AXIS, TURN_ANGLE) and shifted by SHIFT in the second (the
    strands with it). Returns what the tests compare with, in the groom's frame."""
    ball = trimesh.creation.icosphere(subdivisions=3, radius=RADIUS)
    vertices, faces = np.asarray(ball.vertices, dtype=np.float64), np.asarray(ball.faces, dtype=np.int64)
    _write_obj(folder / "ball.obj", vertices, faces)
    s = np.linspace(0.0, STRAND_LENGTH, VERTICES_PER_STRAND)
    roots_picture = np.array(list(strands.values()), dtype=np.float64)
    points_picture = np.concatenate([root + s[:, None] * np.array([1.0, 0.0, 0.0]) for root in roots_picture])
    points, roots = _picture_to_z_up(points_picture), _picture_to_z_up(roots_picture)
    n = len(strands)
    offsets = np.arange(n + 1, dtype=np.int64) * VERTICES_PER_STRAND
    # rows t, n1, n2 of the root frame: t along the picture's +x (the groom's +x), n1 the groom's +z (up)
    frame0 = np.tile(np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]), (n, 1, 1))
    R = _rodrigues(TURN_AXIS, TURN_ANGLE)
    T = np.stack([np.eye(4), np.eye(4)])
    T[1, :3, :3], T[1, :3, 3] = R, SHIFT
    fit_error = np.full(n, 1e-5) if fit_error is None else np.asarray(fit_error, dtype=np.float64)
    body = {"name": "ball.obj", "path": "ball.obj", "sha256": stages.sha256_file(folder / "ball.obj"),
            "to_groom": np.eye(4).tolist()}
    groups = [
        stages.Group(stages.CURVES, {"points": points, "offsets": offsets},
                     attrs={"source": "hand-made", "scale_to_m": 1.0, "up": np.array([0.0, 0.0, 1.0])},
                     config={"import": {"flip": ""}}),
        stages.Group(stages.HELICES, {"root": roots, "frame0": frame0, "offsets": np.arange(n + 1, dtype=np.int64),
                                      "length": np.full(n, STRAND_LENGTH), "omega": np.zeros((n, 3)),
                                      "fit_error": np.stack([0.5 * fit_error, fit_error], axis=1)}),
        stages.Group(stages.FRAMES, {"time": np.array([0.0, 0.1]), "omega": np.zeros((2, n, 3)),
                                     "root": np.stack([roots, roots @ R.T + SHIFT]),
                                     "frame0": np.stack([frame0, frame0 @ R.T]), "body_transform": T},
                     attrs={"fps": 10.0, "scene": "turn"},
                     inputs=[{"name": "model.h5", "sha256": "0" * 64}, body]),
    ]
    stages.write_stage(folder / "ball.h5", groups, "test")
    return {"vertices": vertices, "faces": faces, "points": points, "offsets": offsets, "R": R}


def _axes(fig, title: str):
    [ax] = [ax for ax in fig.axes if ax.get_title() == title]
    return ax


def _triangles(ax) -> np.ndarray:
    """(T, 6) the drawn body's triangles, each its three corners' screen coordinates in a canonical order."""
    from matplotlib.collections import PolyCollection

    [polys] = [c for c in ax.collections if isinstance(c, PolyCollection)]
    return _canonical(np.array([path.vertices[:3] for path in polys.get_paths()]))


def _canonical(triangles: np.ndarray) -> np.ndarray:
    """(T, 3, 2) -> (T, 6), each triangle's corners sorted, then the triangles sorted: comparable as sets."""
    corners = np.array([t[np.lexsort(t.T[::-1])] for t in triangles]).reshape(len(triangles), 6)
    return corners[np.lexsort(corners.T[::-1])]


@pytest.mark.parametrize("side, screen", [(False, [0, 1]), (True, [2, 1])], ids=["front", "side"])
def test_the_body_is_drawn_at_the_pose_of_the_frame_shown(tmp_path, side, screen):
    truth = make_ball_stage(tmp_path)
    fig, _, rows, lines = draw(ExportSource(tmp_path / "ball.h5"), None, tmp_path / "out.png")
    assert rows == 2
    label = "side" if side else "front"
    rest = _z_up_to_picture(truth["vertices"])
    moved = _z_up_to_picture(truth["vertices"] @ truth["R"].T + SHIFT)  # x -> R x + c, then up to +Y
    for title, vertices in ((f"{label} view", rest), (f"before/after, {label} view", moved)):
        drawn = _triangles(_axes(fig, title))
        expected = _canonical(vertices[truth["faces"]][:, :, screen])
        assert drawn.shape == expected.shape
        assert np.abs(drawn - expected).max() < ROUNDOFF_M, title
    # under the last frame the body is not where it rests: the test tells the two apart
    rest_drawn = _canonical(rest[truth["faces"]][:, :, screen])
    assert np.abs(_triangles(_axes(fig, f"before/after, {label} view")) - rest_drawn).max() > 0.01
    # the input under the last frame is carried with the body; the strands, straight and held at their
    # roots, moved with it too: every strand drawn there (input and last frame) lies at R x + c
    from matplotlib.collections import LineCollection

    carried = _z_up_to_picture(truth["points"] @ truth["R"].T + SHIFT)
    strands = [c for c in _axes(fig, f"before/after, {label} view").collections if isinstance(c, LineCollection)]
    drawn_points = np.concatenate([np.concatenate(c.get_segments()) for c in strands if len(c.get_segments())])
    assert _covers(drawn_points, carried[:, screen])
    [line] = [line for line in lines if line.startswith("before/after")]
    assert "moved with the body" in line
    assert float(line.split("at most ")[1].split(" mm")[0]) < 1e3 * ROUNDOFF_M


def _covers(drawn: np.ndarray, expected: np.ndarray) -> bool:
    """Every drawn segment end is one of the expected points, and every expected point is drawn."""
    d = np.linalg.norm(drawn[:, None, :] - expected[None, :, :], axis=2)
    return bool(d.min(axis=1).max() < ROUNDOFF_M and d.min(axis=0).max() < ROUNDOFF_M)


def _sphere_hidden(points: np.ndarray, side: bool) -> tuple[np.ndarray, np.ndarray]:
    """Closed form for the ball at the origin: hidden, and decided (far from the outline and the threshold).

    Front: the viewer at +Z, screen (x, y), depth z; side: the viewer at -X, screen (z, y), depth -x."""
    screen = points[:, [2, 1]] if side else points[:, [0, 1]]
    depth = -points[:, 0] if side else points[:, 2]
    r = np.linalg.norm(screen, axis=1)
    surface = np.sqrt(np.maximum(RADIUS**2 - r**2, 0.0))  # the sphere's near surface over the point
    hidden = (r < RADIUS) & (surface > depth + DEPTH_TOLERANCE)
    decided = (np.abs(r - RADIUS) > UNDECIDED_M) & ((r > RADIUS) | (np.abs(surface - DEPTH_TOLERANCE - depth)
                                                                    > UNDECIDED_M))
    return hidden, decided


@pytest.mark.parametrize("side", [False, True], ids=["front", "side"])
@pytest.mark.parametrize("n", [1, 9, 2000])
def test_the_body_hides_what_a_sphere_hides(rng, side, n):
    ball = trimesh.creation.icosphere(subdivisions=4, radius=RADIUS)
    body = Body(np.asarray(ball.vertices, dtype=np.float64), np.asarray(ball.faces, dtype=np.int64))
    points = rng.uniform(-0.2, 0.2, size=(n, 3))
    expected, decided = _sphere_hidden(points, side)
    got = hidden_by(body, points, side)
    assert np.array_equal(got[decided], expected[decided])
    if n == 2000:
        assert decided.sum() > 0.8 * n and 0.1 * n < expected[decided].sum() < 0.5 * n  # both kinds judged


@pytest.mark.parametrize("side", [False, True], ids=["front", "side"])
def test_points_named_in_front_of_and_behind_the_ball(side):
    ball = trimesh.creation.icosphere(subdivisions=4, radius=RADIUS)
    body = Body(np.asarray(ball.vertices, dtype=np.float64), np.asarray(ball.faces, dtype=np.int64))
    toward = np.array([-1.0, 0.0, 0.0]) if side else np.array([0.0, 0.0, 1.0])  # to the viewer
    across = np.array([0.0, 0.0, 1.0]) if side else np.array([1.0, 0.0, 0.0])   # the screen's horizontal
    points = np.array([1.5 * RADIUS * toward,                      # in front
                       -1.5 * RADIUS * toward,                     # straight behind
                       np.zeros(3),                                # inside, at the centre
                       RADIUS * toward,                            # on the near surface
                       -RADIUS * toward + 0.3 * RADIUS * across,   # on the far surface
                       -1.5 * RADIUS * toward + 1.3 * RADIUS * across])  # behind, beside the outline
    assert hidden_by(body, points, side).tolist() == [False, True, True, False, True, False]
    assert not hidden_by(None, points, side).any()  # no body, nothing hidden


def test_a_strand_behind_the_body_is_faded_and_drawn_first(tmp_path):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.collections import LineCollection

    make_ball_stage(tmp_path)
    fig, _, _, _ = draw(ExportSource(tmp_path / "ball.h5"), None, tmp_path / "out.png")
    ax = _axes(fig, "front view")
    lines = [c for c in ax.collections if isinstance(c, LineCollection)]
    faded = [c for c in lines if c.get_alpha() is not None and c.get_alpha() < 1.0]
    shown = [c for c in lines if c not in faded]
    assert len(faded) == 1 and faded[0].get_alpha() == HIDDEN_ALPHA and len(shown) == 1
    assert faded[0].get_zorder() < shown[0].get_zorder()

    def strand_of(segment) -> str:
        """The strand whose screen span (x from its root along its length, at its height) holds the segment."""
        x, y = segment.mean(axis=0)
        [name] = [k for k, (x0, y0, _) in STRANDS.items() if abs(y - y0) < ROUNDOFF_M and x0 < x < x0 + STRAND_LENGTH]
        return name

    assert {strand_of(s) for s in faded[0].get_segments()} == {"B"}
    order = [strand_of(s) for s in shown[0].get_segments()]
    assert set(order) == {"F", "O"}
    assert max(i for i, k in enumerate(order) if k == "O") < min(i for i, k in enumerate(order) if k == "F")
    # on the pixels: B's middle stays the body's grey (the faded colour adds little), F's is the strand's
    FigureCanvasAgg(fig)
    fig.canvas.draw()
    rgba = np.asarray(fig.canvas.buffer_rgba())[..., :3] / 255.0
    height = rgba.shape[0]

    def colour_near(x, y) -> float:
        """The largest spread of r, g, b (0 for any grey) within 2 pixels of a point of the front view."""
        px, py = ax.transData.transform((x, y))
        row, col = int(round(height - py)), int(round(px))
        patch = rgba[row - 2:row + 3, col - 2:col + 3]
        return float(np.ptp(patch, axis=-1).max())

    middle = 0.5 * STRAND_LENGTH
    assert colour_near(STRANDS["F"][0] + middle, STRANDS["F"][1]) > 0.3
    assert colour_near(STRANDS["B"][0] + middle, STRANDS["B"][1]) < 0.1


# --------------------------------------------------------------------------- the colour scale


@pytest.mark.parametrize("n", [50, 500, 5000])
def test_values_spanning_decades_get_a_log_scale_between_the_quantiles(rng, n):
    values = np.exp(rng.normal(0.0, 3.0, size=n))  # 2nd to 98th percentile: e^(+-6.2), five decades
    scale = colour_scale(values)
    lo, hi = np.quantile(values, QUANTILES, method="inverted_cdf")
    assert hi / lo >= LOG_SPAN
    assert scale.log and scale.clipped
    assert (scale.vmin, scale.vmax) == pytest.approx((lo, hi), rel=ROUNDOFF_M)
    assert scale.note == "log scale, 2-98 % quantiles; beyond clipped"


def test_a_few_outliers_clip_the_scale_to_the_quantiles(rng):
    values = np.concatenate([rng.uniform(1.0, 2.0, size=500), [1e3, 2e3, 5e3]])
    scale = colour_scale(values)
    lo, hi = np.quantile(values, QUANTILES, method="inverted_cdf")
    assert hi - lo < OUTLIER_SHARE * np.ptp(values)
    assert not scale.log and scale.clipped
    assert (scale.vmin, scale.vmax) == pytest.approx((lo, hi), rel=ROUNDOFF_M)
    assert scale.note == "2-98 % quantiles; beyond clipped"
    assert scale.extend(values) == "both"


@pytest.mark.parametrize("values", [np.linspace(1.0, 2.0, 101), np.array([1.0, 2.0]), np.array([1.0] * 98 + [2.0, 3.0]),
                                    np.array([0.0, 1e-3, 1.0]), np.array([4.0])],
                         ids=["spread", "two", "most equal", "with zero", "one"])
def test_values_without_outliers_keep_their_whole_range(values):
    scale = colour_scale(values)
    assert not scale.clipped and not scale.log and scale.note == ""
    assert (scale.vmin, scale.vmax) == (values.min(), values.max())
    assert scale.extend(values) == "neither"


def test_the_picture_colour_bar_is_the_quantiles_of_the_strands_values(tmp_path, rng):
    """40 strands side by side over the ball with fit errors spanning decades (per strand, so each counts
    once): the bar's limits are numpy's quantiles of those, in mm, on a log scale, and its label says so."""
    from matplotlib.collections import LineCollection
    from PIL import Image

    n = 40
    strands = {f"s{k}": (-0.18 + 0.009 * k, 0.15, 0.05) for k in range(n)}
    error = np.exp(rng.normal(np.log(1e-4), 2.5, size=n))  # m
    make_ball_stage(tmp_path, fit_error=error, strands=strands)
    report = export(tmp_path / "ball.h5", tmp_path / "out.png", color="fit-error")
    with Image.open(tmp_path / "out.png") as image:
        text = dict(image.text)
    lo, hi = np.quantile(1e3 * error, QUANTILES, method="inverted_cdf")
    assert text["hairinv:scale"] == "log, 2-98 % quantiles"
    assert float(text["hairinv:bar_min"]) == pytest.approx(lo, rel=ROUNDOFF_M)
    assert float(text["hairinv:bar_max"]) == pytest.approx(hi, rel=ROUNDOFF_M)
    assert float(text["hairinv:min"]) == pytest.approx(1e3 * error.min(), rel=ROUNDOFF_M)
    assert float(text["hairinv:max"]) == pytest.approx(1e3 * error.max(), rel=ROUNDOFF_M)
    assert any("log scale, 2-98 % quantiles; beyond clipped" in line for line in report.lines)
    fig, _, _, _ = draw(ExportSource(tmp_path / "ball.h5"), "fit-error", tmp_path / "out.png")
    labels = [ax.get_ylabel() for ax in fig.axes]
    assert any("log scale, 2-98 % quantiles; beyond clipped" in label for label in labels)
    # every segment keeps a colour: values beyond the bar take its end colours, none is left out
    for collection in fig.axes[0].collections:
        if isinstance(collection, LineCollection) and collection.get_array() is not None:
            array = collection.get_array()
            assert not np.ma.is_masked(array) and np.all((array >= lo * (1 - ROUNDOFF_M))
                                                          & (array <= hi * (1 + ROUNDOFF_M)))
