"""Import pipeline: units, up axis, flips, cleaning, guide selection, settings and the body mesh.

Every input is a small hand-built file in ``tmp_path`` (OBJ polylines and
Yuksel ``.hair`` written byte by byte here, hairinv ``.h5`` through the
project's writer), so expected values are exact. Runtime: about 5 s (mostly the guide-selection spread check).
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

from hairinv import config
from hairinv.config import UNITS, ImportSettings
from hairinv.errors import InputError
from hairinv.formats import write_curves
from hairinv.groom import guess_units, hair_unit_transform, load_body, load_groom, select_guides

# Coordinates of the synthetic strands are small multiples of 1/8, exact in
# float32 and float64; a float64 product with a scale is then reproduced
# bit-for-bit by the same product in the test.
EXACT = 0.0


# --------------------------------------------------------------------------- helpers


def write_obj_lines(path: Path, strands: list[np.ndarray]) -> Path:
    """OBJ polylines written by hand: ``v`` lines with repr() precision, one ``l`` per strand."""
    lines, start = [], 1
    for strand in strands:
        lines += [f"v {x!r} {y!r} {z!r}" for x, y, z in np.asarray(strand, float).tolist()]
    for strand in strands:
        lines.append("l " + " ".join(str(start + k) for k in range(len(strand))))
        start += len(strand)
    path.write_text("\n".join(lines) + "\n")
    return path


def write_hair(path: Path, strands: list[np.ndarray]) -> Path:
    """A Yuksel ``.hair`` file (segments + points arrays), written byte by byte."""
    n_points = sum(len(s) for s in strands)
    header = struct.pack("<4s4I2f3f88s", b"HAIR", len(strands), n_points, 1 | 2, 0, 1.0, 0.0, 1, 1, 1, b"test")
    segments = struct.pack(f"<{len(strands)}H", *[len(s) - 1 for s in strands])
    points = np.concatenate(strands).astype("<f4").tobytes()
    path.write_bytes(header + segments + points)
    return path


def write_h5(path: Path, strands: list[np.ndarray], up=(0.0, 1.0, 0.0)) -> Path:
    """A hairinv stage file holding only /curves (metres, scale_to_m = 1)."""
    counts = [len(s) for s in strands]
    offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    points = np.concatenate(strands).astype(np.float64) if strands else np.zeros((0, 3))
    write_curves(path, points, offsets, up=up, source="test strands")
    return path


def flat(strands) -> np.ndarray:
    return np.concatenate([np.asarray(s, float) for s in strands])


def strands_of(groom) -> list[np.ndarray]:
    return [groom.points[a:b] for a, b in zip(groom.offsets[:-1], groom.offsets[1:])]


def two_strands(size: float) -> list[np.ndarray]:
    """Two 5-point strands whose bounding-box diagonal is ``size`` file units (to the 1/8 grid)."""
    t = np.arange(5)[:, None] / 4.0
    a = np.array([0.0, 0.0, 0.0]) + t * np.array([0.0, 1.0, 0.0])
    b = np.array([1.0, 0.0, 0.0]) + t * np.array([0.0, 1.0, 1.0])
    return [a * size / np.sqrt(3.0), b * size / np.sqrt(3.0)]


def note(report, fragment: str) -> str:
    """The one report line holding ``fragment`` (fails if none does)."""
    hits = [line for line in report.lines() if fragment in line]
    assert hits, f"no report line contains {fragment!r}: {report.lines()}"
    return hits[0]


# --------------------------------------------------------------------------- units


@pytest.fixture
def strands_cm():
    # a ~40-unit hairstyle on the 1/8 grid: exactly representable values
    return [np.round(s * 8) / 8 for s in two_strands(40.0)]


@pytest.mark.parametrize("unit", sorted(UNITS))
def test_explicit_units_scale_exactly(tmp_path, strands_cm, unit):
    strands = [s / 8 for s in strands_cm]  # 5 units across: a hair's length in any of the units (still exact)
    path = write_obj_lines(tmp_path / "h.obj", strands)
    groom, report = load_groom(path, ImportSettings(units=unit))
    expected = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254}[unit]
    assert groom.scale_to_m == expected
    np.testing.assert_allclose(groom.points, flat(strands) * expected, rtol=EXACT, atol=EXACT)
    assert f"units: {unit} (as given)" in report.lines()
    assert not any("guessed" in line for line in report.lines())


def test_units_cm_is_exactly_one_hundredth(tmp_path, strands_cm):
    path = write_obj_lines(tmp_path / "h.obj", strands_cm)
    groom, _ = load_groom(path, ImportSettings(units="cm"))
    assert groom.scale_to_m == 0.01
    np.testing.assert_array_equal(groom.points, flat(strands_cm) * 0.01)


def test_scale_wins_over_units(tmp_path, strands_cm):
    path = write_obj_lines(tmp_path / "h.obj", strands_cm)
    groom, report = load_groom(path, ImportSettings(units="cm", scale=0.00254))
    assert groom.scale_to_m == 0.00254
    np.testing.assert_allclose(groom.points, flat(strands_cm) * 0.00254, rtol=EXACT, atol=EXACT)
    assert "--scale" in note(report, "units:")
    assert not any("(as given)" in line and "units" in line for line in report.lines())


def test_stated_unit_is_used_when_auto(tmp_path):
    # 12 m across (strands under 10 m): a guess would not say m, but the hairinv file states metres
    strands = two_strands(12.0)
    path = write_h5(tmp_path / "h.h5", strands)
    groom, report = load_groom(path, ImportSettings())
    assert groom.scale_to_m == 1.0
    np.testing.assert_allclose(groom.points, flat(strands), rtol=EXACT, atol=EXACT)
    assert "stated by the file" in note(report, "units:")
    assert not any("guessed" in line for line in report.lines())


def test_explicit_unit_overrides_stated_unit_with_a_warning(tmp_path):
    strands = two_strands(0.4)
    path = write_h5(tmp_path / "h.h5", strands)
    groom, report = load_groom(path, ImportSettings(units="cm"))
    assert groom.scale_to_m == 0.01
    np.testing.assert_allclose(groom.points, flat(strands) * 0.01, rtol=1e-15, atol=0.0)
    assert "1 m per unit" in note(report, "warning:")


@pytest.mark.parametrize("unit, size", [("m", 0.4), ("cm", 40.0), ("mm", 400.0)])
def test_auto_guesses_from_the_hair_size_and_says_so(tmp_path, unit, size):
    strands = two_strands(size)
    path = write_obj_lines(tmp_path / "h.obj", strands)
    groom, report = load_groom(path, ImportSettings(units="auto"))
    assert groom.scale_to_m == UNITS[unit]
    np.testing.assert_allclose(groom.points, flat(strands) * UNITS[unit], rtol=1e-15, atol=0.0)
    line = note(report, "units:")
    assert "guessed" in line and f"guessed {unit} " in line and "hairstyle" in line
    assert line.startswith("warning:") and f"pass --units {unit}" in line  # a guess the whole result rests on


def test_auto_guesses_from_the_body_when_given(tmp_path):
    # 0.4 units of hair alone would be metres; a 60-unit body says cm
    path = write_obj_lines(tmp_path / "h.obj", two_strands(0.4))
    groom, report = load_groom(path, ImportSettings(), body_size_native=60.0)
    assert groom.scale_to_m == 0.01
    line = note(report, "guessed")
    assert "guessed cm" in line and "body" in line
    assert line.startswith("warning:") and "pass --units cm" in line


@pytest.mark.parametrize(
    "size, typical, unit",
    [(0.45, 0.45, "m"), (45.0, 0.45, "cm"), (450.0, 0.45, "mm"), (0.45 / 0.0254, 0.45, "in"), (60.0, 0.6, "cm")],
)
def test_guess_units(size, typical, unit):
    assert guess_units(size, typical) == unit


# --------------------------------------------------------------------------- up axis and flips


def test_up_auto_uses_the_format_convention(tmp_path, strands_cm):
    hair, _ = load_groom(write_hair(tmp_path / "h.hair", strands_cm), ImportSettings(units="cm"))
    obj, _ = load_groom(write_obj_lines(tmp_path / "h.obj", strands_cm), ImportSettings(units="cm"))
    np.testing.assert_array_equal(hair.up, [0.0, 0.0, 1.0])
    np.testing.assert_array_equal(obj.up, [0.0, 1.0, 0.0])
    # the axes are not rotated, only the up vector is reported
    np.testing.assert_allclose(hair.points, obj.points, rtol=0.0, atol=EXACT)


def test_up_auto_on_a_hairinv_file_uses_its_stated_vector(tmp_path):
    path = write_h5(tmp_path / "h.h5", two_strands(0.4), up=(0.0, 0.0, 2.0))
    groom, _ = load_groom(path, ImportSettings())
    np.testing.assert_allclose(groom.up, [0.0, 0.0, 1.0], rtol=0.0, atol=1e-15)


@pytest.mark.parametrize("writer, up", [(write_hair, "y"), (write_hair, "x"), (write_obj_lines, "z")])
def test_explicit_up_wins(tmp_path, strands_cm, writer, up):
    suffix = ".hair" if writer is write_hair else ".obj"
    groom, report = load_groom(writer(tmp_path / f"h{suffix}", strands_cm), ImportSettings(units="cm", up=up))
    expected = np.zeros(3)
    expected["xyz".index(up)] = 1.0
    np.testing.assert_array_equal(groom.up, expected)
    assert "(as given)" in note(report, "up:")


def test_bad_up_is_an_input_error(tmp_path, strands_cm):
    with pytest.raises(InputError, match="--up"):
        load_groom(write_obj_lines(tmp_path / "h.obj", strands_cm), ImportSettings(units="cm", up="w"))


@pytest.mark.parametrize("flip, sign", [("z", (1, 1, -1)), ("x", (-1, 1, 1)), ("xz", (-1, 1, -1)), ("x,y", (-1, -1, 1))])
def test_flip_negates_the_named_axes(tmp_path, strands_cm, flip, sign):
    path = write_obj_lines(tmp_path / "h.obj", strands_cm)
    groom, report = load_groom(path, ImportSettings(units="cm", flip=flip))
    np.testing.assert_allclose(groom.points, flat(strands_cm) * 0.01 * np.array(sign, float), rtol=EXACT, atol=EXACT)
    assert f"flipped axes: {flip}" in report.lines()


def test_bad_flip_is_an_input_error_naming_the_file(tmp_path, strands_cm):
    path = write_obj_lines(tmp_path / "h.obj", strands_cm)
    with pytest.raises(InputError, match=r"h\.obj: --flip takes axes"):
        load_groom(path, ImportSettings(units="cm", flip="q"))


# --------------------------------------------------------------------------- cleaning


def test_cleaning_counts_and_kept_points(tmp_path):
    p = np.array
    s0 = p([[0, 0, 0], [0, 0, 0], [0, 0.01, 0], [0, 0.01, 0], [0, 0.01, 0], [0, 0.02, 0]], float)  # 3 repeats
    s1 = p([[1, 0, 0]], float)  # one point: degenerate
    s2 = p([[2, 0, 0], [2, 0, 0], [2, 0, 0]], float)  # one distinct point after merging 2: degenerate
    s3 = p([[3, 0, 0], [3, 0.0005, 0]], float)  # 0.5 mm < min_length 1 mm: short
    s4 = p([[0, 0.02, 0], [0, 0.03, 0], [0, 0.04, 0]], float)  # starts where s0 ends: no merge across strands
    s5 = p([[5, 0, 0], [5, 0.01, 0], [5, 0.01 + 5e-8, 0], [5, 0.02, 0], [5, 0.02, 0]], float)  # near repeat + tip repeat
    s6 = p([[6, 0, 0], [6, 0.0006, 0], [6, 0.0006, 0], [6, 0.0012, 0]], float)  # 1.2 mm, one repeat
    path = write_h5(tmp_path / "c.h5", [s0, s1, s2, s3, s4, s5, s6])
    groom, report = load_groom(path, ImportSettings())
    assert report.strands_read == 7 and report.points_read == 24
    assert report.merged_points == 3 + 2 + 2 + 1
    assert report.dropped_degenerate == 2
    assert report.dropped_short == 1
    assert report.kept == 4 and groom.n_strands == 4
    np.testing.assert_array_equal(groom.index, [0, 4, 5, 6])
    expected = [s0[[0, 2, 5]], s4, s5[[0, 1, 3]], s6[[0, 1, 3]]]
    got = strands_of(groom)
    assert len(got) == len(expected)
    for a, b in zip(got, expected):
        np.testing.assert_allclose(a, b, rtol=0.0, atol=EXACT)
    np.testing.assert_array_equal(groom.offsets, [0, 3, 6, 9, 12])
    lines = report.lines()
    assert "merged 8 repeated points" in lines
    assert "dropped 2 strands with fewer than 2 distinct points" in lines
    assert "dropped 1 strands shorter than the minimum length" in lines
    assert lines[-1] == "kept 4 strands"


def test_cleaning_tolerances_follow_the_settings(tmp_path):
    s0 = np.array([[0, 0, 0], [0, 1e-4, 0], [0, 2e-4, 0], [0, 0.01, 0]], float)  # two 0.1 mm steps
    s1 = np.array([[1, 0, 0], [1, 0.0005, 0]], float)  # 0.5 mm
    path = write_h5(tmp_path / "c.h5", [s0, s1])
    groom, report = load_groom(path, ImportSettings(merge_tolerance=2e-4, min_length=1e-4))
    assert report.merged_points == 2 and report.dropped_short == 0 and report.kept == 2
    np.testing.assert_allclose(strands_of(groom)[0], s0[[0, 3]], rtol=0.0, atol=EXACT)
    groom, report = load_groom(path, ImportSettings(merge_tolerance=0.0, min_length=6e-4))
    assert report.merged_points == 0 and report.dropped_short == 1 and report.kept == 1
    np.testing.assert_array_equal(groom.index, [0])


def test_cleaning_an_empty_strand_in_the_middle(tmp_path):
    a = np.array([[0, 0, 0], [0, 0.01, 0], [0, 0.02, 0]], float)
    path = write_h5(tmp_path / "c.h5", [a, np.zeros((0, 3)), a + 1.0])
    groom, report = load_groom(path, ImportSettings())
    assert report.dropped_degenerate == 1 and report.merged_points == 0 and report.kept == 2
    np.testing.assert_array_equal(groom.index, [0, 2])
    np.testing.assert_allclose(groom.points, np.vstack([a, a + 1.0]), rtol=0.0, atol=EXACT)


def test_cleaning_an_empty_last_strand(tmp_path):
    a = np.array([[0, 0, 0], [0, 0.01, 0], [0, 0.02, 0]], float)
    path = write_h5(tmp_path / "c.h5", [a, np.zeros((0, 3))])
    groom, report = load_groom(path, ImportSettings())
    assert report.dropped_degenerate == 1 and report.kept == 1
    np.testing.assert_allclose(groom.points, a, rtol=0.0, atol=EXACT)


def test_nothing_left_after_cleaning_is_an_input_error(tmp_path):
    path = write_h5(tmp_path / "c.h5", [np.array([[0, 0, 0], [0, 1e-4, 0]], float), np.zeros((1, 3))])
    with pytest.raises(InputError, match=r"c\.h5: no strand is left after cleaning"):
        load_groom(path, ImportSettings())


# --------------------------------------------------------------------------- guide selection


def fibonacci_hemisphere(n: int, radius: float) -> np.ndarray:
    """``n`` roots evenly spread over the upper hemisphere (equal-area Fibonacci grid)."""
    i = np.arange(n) + 0.5
    y = i / n
    phi = i * np.pi * (3.0 - np.sqrt(5.0))
    r = np.sqrt(1.0 - y * y)
    return radius * np.column_stack([r * np.cos(phi), y, r * np.sin(phi)])


@pytest.fixture(scope="module")
def scalp():
    return fibonacci_hemisphere(10_000, 0.1)


@pytest.mark.parametrize("n", [1, 7, 500, 501, 9_999])
def test_select_guides_returns_exactly_n_distinct_sorted_indices(scalp, n):
    chosen = select_guides(scalp, n, seed=0)
    assert len(chosen) == n
    assert np.all(np.diff(chosen) > 0)
    assert chosen.min() >= 0 and chosen.max() < len(scalp)


@pytest.mark.parametrize("n", [0, -3, 10_000, 20_000])
def test_select_guides_keeps_all_when_n_is_zero_or_too_large(scalp, n):
    np.testing.assert_array_equal(select_guides(scalp, n, seed=0), np.arange(len(scalp)))


def test_select_guides_is_deterministic_per_seed(scalp):
    a, b = select_guides(scalp, 500, seed=3), select_guides(scalp, 500, seed=3)
    np.testing.assert_array_equal(a, b)
    c = select_guides(scalp, 500, seed=4)
    assert len(np.intersect1d(a, c)) < 250  # different seeds pick mostly different strands


def test_select_guides_spreads_over_the_scalp(scalp):
    n = 500
    area = 2.0 * np.pi * 0.1**2
    spacing = np.sqrt(area / n)  # side of the square each chosen root should cover
    rng = np.random.default_rng(11)

    def gaps(idx):
        dist, _ = cKDTree(scalp[idx]).query(scalp)
        return dist.max(), float(np.mean(dist > 0.8 * spacing))

    chosen = [gaps(select_guides(scalp, n, seed)) for seed in range(5)]
    random = [gaps(rng.choice(len(scalp), n, replace=False)) for _ in range(5)]
    for worst, far in chosen:
        assert worst < 3.0 * spacing
        assert far < 0.08
    # a uniform random subset leaves about three times as many roots far from any guide
    assert np.mean([far for _, far in random]) > 1.8 * np.mean([far for _, far in chosen])
    assert np.mean([w for w, _ in random]) > np.mean([w for w, _ in chosen])


def test_load_groom_guides_keeps_n_original_strands(tmp_path):
    rng = np.random.default_rng(5)
    roots = fibonacci_hemisphere(200, 0.1)
    strands = [r + np.outer(np.arange(4) * 0.01, [0, -1, 0]) + rng.normal(scale=1e-3, size=(4, 3)) * [1, 0, 1]
               for r in roots]
    path = write_h5(tmp_path / "g.h5", strands)
    groom, report = load_groom(path, ImportSettings(guides=30, seed=2))
    assert groom.n_strands == 30 and report.kept == 30
    assert "guides: kept 30 of 200 strands (seed 2)" in report.lines()
    assert np.all(np.diff(groom.index) > 0)
    for k, got in zip(groom.index, strands_of(groom)):
        np.testing.assert_allclose(got, strands[k], rtol=0.0, atol=EXACT)
    again, _ = load_groom(path, ImportSettings(guides=30, seed=2))
    np.testing.assert_array_equal(again.index, groom.index)
    other, _ = load_groom(path, ImportSettings(guides=30, seed=3))
    assert not np.array_equal(other.index, groom.index)


# --------------------------------------------------------------------------- settings


def test_resolve_toml_then_set(tmp_path):
    toml = tmp_path / "s.toml"
    toml.write_text('[import]\nunits = "cm"\nguides = 12\n\n[fit]\ntolerance = 5e-4\nmax_elements = 30\n')
    settings = config.resolve(config_file=toml, sets=["fit.tolerance=1e-4", "import.seed=3"])
    assert settings.import_.units == "cm" and settings.import_.guides == 12 and settings.import_.seed == 3
    assert settings.fit.tolerance == pytest.approx(1e-4, rel=0.0, abs=0.0)  # --set wins over the file
    assert settings.fit.max_elements == 30 and isinstance(settings.fit.max_elements, int)
    assert settings.to_dict()["import"]["guides"] == 12


def test_resolve_defaults():
    settings = config.resolve()
    assert settings.import_ == ImportSettings()
    assert settings.fit.tolerance == pytest.approx(2e-4, rel=0.0, abs=0.0)


@pytest.mark.parametrize("item", ["fit.nope=1", "import.colour=red"])
def test_set_unknown_key_is_named(item):
    key = item.split("=")[0]
    with pytest.raises(InputError, match=rf"unknown setting {key}\b"):
        config.resolve(sets=[item])


def test_set_unknown_section_is_named():
    with pytest.raises(InputError, match=r"unknown settings section \[simulate\]"):
        config.resolve(sets=["simulate.iterations=3"])


@pytest.mark.parametrize("item", ["fit.tolerance=abc", "import.guides=2.5", "fit.max_elements=many", "tolerance=1"])
def test_set_wrong_type_or_form_is_an_input_error(item):
    with pytest.raises(InputError, match=r"fit\.tolerance|import\.guides|fit\.max_elements|section\.key=value"):
        config.resolve(sets=[item])


@pytest.mark.parametrize(
    "text, fragment",
    [
        ('[fit]\ntolerance = "small"\n', "fit.tolerance expects a float"),
        ("[import]\nguides = 2.5\n", "import.guides expects"),
        ("[fit]\nnope = 1\n", "unknown setting fit.nope"),
        ("fit = 3\n", "[fit] must be a table"),
        ("[fit\n", "is not valid TOML"),
    ],
)
def test_bad_toml_is_an_input_error(tmp_path, text, fragment):
    toml = tmp_path / "bad.toml"
    toml.write_text(text)
    with pytest.raises(InputError) as info:
        config.resolve(config_file=toml)
    assert fragment in str(info.value)
    assert "bad.toml" in str(info.value)


def test_toml_boolean_for_a_number_is_an_input_error(tmp_path):
    toml = tmp_path / "bool.toml"
    toml.write_text("[fit]\nelements = true\n")
    with pytest.raises(InputError, match="fit.elements"):
        config.resolve(config_file=toml)


def test_missing_config_file_is_named(tmp_path):
    with pytest.raises(InputError, match=r"nothere\.toml: no such settings file"):
        config.resolve(config_file=tmp_path / "nothere.toml")


def test_unknown_quality_is_an_input_error():
    with pytest.raises(InputError, match="unknown quality"):
        config.resolve("ultra")


# --------------------------------------------------------------------------- body mesh


def signed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


@pytest.fixture
def ball(tmp_path):
    """A closed, outward-wound icosphere of radius 10 off the origin, as OBJ (1-based faces)."""
    import trimesh

    mesh = trimesh.creation.icosphere(subdivisions=2, radius=10.0)
    vertices = mesh.vertices + [30.0, 50.0, 20.0]
    faces = mesh.faces
    assert signed_volume(vertices, faces) > 0  # the fixture itself is outward
    path = tmp_path / "ball.obj"
    path.write_text(
        "".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in vertices.tolist())
        + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in faces.tolist())
    )
    return path, vertices, faces


@pytest.mark.parametrize(
    "flip, sign",
    [("", (1, 1, 1)), ("z", (1, 1, -1)), ("x", (-1, 1, 1)), ("xz", (-1, 1, -1)), ("x,y,z", (-1, -1, -1))],
)
def test_load_body_scales_flips_and_stays_outward(ball, flip, sign):
    path, vertices, faces = ball
    body = load_body(path, hair_unit_transform(0.01, flip))
    expected = vertices * 0.01 * np.array(sign, float)
    np.testing.assert_allclose(body.vertices, expected, rtol=1e-15, atol=1e-15)
    assert len(body.faces) == len(faces)
    volume = 4.0 / 3.0 * np.pi * 0.1**3
    # inscribed icosphere: a little under the ball's volume, and positive (outward winding)
    assert 0.95 * volume < signed_volume(np.asarray(body.vertices), np.asarray(body.faces)) < volume
    centre = expected.mean(axis=0)
    outward = np.einsum("ij,ij->i", body.triangles_center - centre, body.face_normals)
    assert outward.min() > 0.0


def test_load_body_flip_without_inversion_would_turn_the_mesh_inside_out(ball):
    # the property above can fail: mirrored vertices with the file's winding have a negative volume
    path, vertices, faces = ball
    mirrored = vertices * 0.01 * np.array([1.0, 1.0, -1.0])
    assert signed_volume(mirrored, faces) < 0
    body = load_body(path, hair_unit_transform(0.01, "z"))
    assert not np.array_equal(np.asarray(body.faces), faces)


def test_load_body_bad_flip_names_the_file(ball):
    with pytest.raises(InputError, match=r"ball\.obj: --flip"):
        load_body(ball[0], hair_unit_transform(1.0, "w", ball[0]))
