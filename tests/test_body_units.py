"""A body file in other units or axes than the hair's: --body-units, --body-scale, --body-up, --body-flip.

The transform is checked against its closed form (a quarter turn about x takes a Z-up file onto a Y-up
groom), then end to end: the sample body written in centimetres and Z-up, read back with the options that
say so, gives the contacts of the sample body itself; read without them, the run says which option would
put the roots back on the body. The transform is recorded with the body, so a later stage (simulate,
export, a rerun of invert) reads the body as it was read, and contacts detected with another one are
detected again.

Runtime: about 20-40 s with a warm numba cache (a few subprocesses fitting 3 guide strands).
"""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest
import trimesh

from conftest import ROUNDOFF, SAMPLES, hairinv
from hairinv import formats, stages
from hairinv.config import BodySettings
from hairinv.errors import InputError
from hairinv.groom import body_to_groom, load_body, recorded_body_transform, simulation_body

Y_UP = np.array([0.0, 1.0, 0.0])
# A Y-up file written as Z-up: the quarter turn about +x that takes +y onto +z, (x, y, z) -> (x, -z, y).
Y_TO_Z = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
# float64 round-off of a vertex multiplied by 100 and read back at 0.01 m per unit, relative to the body's size
UNIT_ROUNDTRIP = 1e-13


def test_transform_closed_forms():
    """A Z-up body in centimetres under a Y-up groom in metres: 0.01 times the quarter turn about -x
    (y -> -z, z -> y); a body in the hair's unit and axes: the hair's scale and flip only; a mirror has a
    negative determinant."""
    M, notes = body_to_groom(BodySettings(units="cm", up="z"), 1.0, Y_UP, "")
    np.testing.assert_allclose(M[:3, :3], 0.01 * Y_TO_Z.T, atol=ROUNDOFF)
    np.testing.assert_array_equal(M[3], [0.0, 0.0, 0.0, 1.0])
    assert any("cm" in n for n in notes) and any("+Z" in n for n in notes)
    same, notes = body_to_groom(BodySettings(), 0.0254, Y_UP, "z")
    np.testing.assert_array_equal(same[:3, :3], np.diag([0.0254, 0.0254, -0.0254]))
    assert notes == []
    np.testing.assert_array_equal(recorded_body_transform({"name": "old.obj"}, 0.0254, "z"), same)
    scaled, _ = body_to_groom(BodySettings(scale=0.00254, flip="none"), 0.0254, Y_UP, "z")
    np.testing.assert_array_equal(scaled[:3, :3], 0.00254 * np.eye(3))
    mirrored, _ = body_to_groom(BodySettings(flip="x"), 1.0, Y_UP, "")
    assert np.linalg.det(mirrored[:3, :3]) < 0
    with pytest.raises(InputError, match="body unit"):
        body_to_groom(BodySettings(units="furlong"), 1.0, Y_UP, "")


def test_a_mirrored_body_keeps_its_outward_normals():
    """Negating an axis turns the winding inside out; the reader turns it back (volume stays positive)."""
    mirrored, _ = body_to_groom(BodySettings(flip="x"), 1.0, Y_UP, "")
    mesh = load_body(SAMPLES / "body.obj", mirrored)
    original = trimesh.load(SAMPLES / "body.obj", process=False)
    assert mesh.volume > 0 and mesh.volume == pytest.approx(original.volume, rel=1e-12)
    np.testing.assert_array_equal(mesh.vertices[:, 0], -np.asarray(original.vertices)[:, 0])


@pytest.fixture(scope="module")
def bodies(tmp_path_factory):
    """The sample body as given (metres, Y-up), in centimetres, and in centimetres Z-up."""
    folder = tmp_path_factory.mktemp("bodies")
    mesh = trimesh.load(SAMPLES / "body.obj", process=False)
    metres = np.asarray(mesh.vertices, dtype=np.float64)
    for name, vertices in (("body_cm.obj", 100.0 * metres), ("body_cm_zup.obj", 100.0 * metres @ Y_TO_Z.T)):
        trimesh.Trimesh(vertices, mesh.faces, process=False).export(folder / name)
    return folder


def _contacts(path):
    with h5py.File(path, "r") as fh:
        group = fh["contacts"]
        return {key: group[key][()] for key in ("strand", "s", "gap")}, json.loads(group.attrs["inputs"])


@pytest.fixture(scope="module")
def detected(bodies):
    """detect on 3 guides of the wavy sample against the sample body, and against its cm and cm Z-up copies
    read with the options that say so."""
    runs = {"m": (SAMPLES / "body.obj",), "cm": ("body_cm.obj", "--body-units", "cm"),
            "cm_zup": ("body_cm_zup.obj", "--body-units", "cm", "--body-up", "z")}
    out = {}
    for name, (body, *options) in runs.items():
        result = hairinv(bodies, "detect", SAMPLES / "wavy.h5", body, "--guides", "3", *options,
                         "-o", f"{name}.contacts.h5")
        assert result.returncode == 0, result.stderr
        assert "roots lie" not in result.stdout + result.stderr
        out[name] = (bodies / f"{name}.contacts.h5", result.stdout)
    return out


def test_a_body_in_its_own_units_and_axes_gives_the_same_contacts(detected):
    """The same body given in cm, and in cm Z-up, with the options saying so: the same contacts (strand,
    arc length, gap) as the body in the hair's unit, up to the round-off of the unit conversion."""
    reference, record = _contacts(detected["m"][0])
    assert len(reference["gap"]) > 0 and "to_groom" in record[-1]
    with h5py.File(detected["m"][0], "r") as fh:  # /curves holds the 3 guide strands fitted, not the 280 read
        assert len(fh["curves/offsets"]) == len(fh["helices/root"]) + 1 == 4
    np.testing.assert_array_equal(np.asarray(record[-1]["to_groom"]), np.eye(4))
    for name in ("cm", "cm_zup"):
        found, record = _contacts(detected[name][0])
        np.testing.assert_array_equal(found["strand"], reference["strand"])
        np.testing.assert_allclose(found["s"], reference["s"], atol=1e-9)
        np.testing.assert_allclose(found["gap"], reference["gap"], atol=1e-9)
        assert "body units: cm (as given)" in detected[name][1]
    turned = np.asarray(_contacts(detected["cm_zup"][0])[1][-1]["to_groom"])
    np.testing.assert_allclose(turned[:3, :3], 0.01 * Y_TO_Z.T, atol=ROUNDOFF)


def test_the_recorded_transform_reads_the_body_again(detected, bodies):
    """A later stage finds the body from the provenance and reads it with the recorded transform: the
    cm Z-up file comes back as the sample body in metres; the same file named again with no option
    gets the same transform (same SHA-256), an option given wins."""
    path = detected["cm_zup"][0]
    stage = stages.read_stage(path)
    found, transform, _, _ = simulation_body(BodySettings(), None, stage, path, stage[stages.CURVES])
    assert found.name == "body_cm_zup.obj"
    mesh = load_body(found, transform)
    original = np.asarray(trimesh.load(SAMPLES / "body.obj", process=False).vertices)
    np.testing.assert_allclose(mesh.vertices, original, atol=UNIT_ROUNDTRIP * np.ptp(original))
    _, again, _, unread = simulation_body(BodySettings(), bodies / "body_cm_zup.obj", stage, path,
                                          stage[stages.CURVES])
    np.testing.assert_array_equal(again, transform)
    assert unread is None  # the recorded transform needs no read
    _, given, _, read = simulation_body(BodySettings(units="mm", up="z"), bodies / "body_cm_zup.obj", stage, path,
                                        stage[stages.CURVES])
    np.testing.assert_allclose(given[:3, :3], 0.001 * Y_TO_Z.T, atol=ROUNDOFF)
    # the file read for its size comes back, for load_body to take instead of reading it again
    np.testing.assert_array_equal(read.vertices, formats.read_mesh(bodies / "body_cm_zup.obj").vertices)
    np.testing.assert_array_equal(load_body(None, given, read).vertices,
                                  load_body(bodies / "body_cm_zup.obj", given).vertices)


def test_options_that_do_not_match_the_body_are_caught(detected, bodies):
    """The Z-up cm body read in the hair's unit: the roots lie farther from it than any strand is long, so it
    is refused in one line naming both options that put them back; contacts detected with the body read
    otherwise are detected again."""
    result = hairinv(bodies, "detect", SAMPLES / "wavy.h5", "body_cm_zup.obj", "--guides", "3", "-o", "x.h5")
    assert result.returncode == 2 and not (bodies / "x.h5").exists(), result.stderr
    refusal = result.stderr.strip().splitlines()
    assert len(refusal) == 1 and "body_cm_zup.obj" in refusal[0], refusal
    assert "--body-units cm" in refusal[0] and "--body-up z" in refusal[0], refusal
    rerun = hairinv(bodies, "detect", detected["cm_zup"][0], "body_cm_zup.obj", "--body-scale", "0.0102",
                    "--body-up", "z", "-o", "y.h5")  # 2 % larger than in cm: within the strands' reach
    assert rerun.returncode == 0, rerun.stderr
    assert "were detected with the body in other units or axes; detecting them again" in rerun.stdout
    kept = hairinv(bodies, "detect", detected["cm_zup"][0], "body_cm_zup.obj", "--body-units", "cm",
                   "--body-up", "z", "-o", "z.h5")
    assert kept.returncode == 0 and "using the" in kept.stdout and "detecting them again" not in kept.stdout


def test_a_bad_body_option_is_refused(bodies):
    result = hairinv(bodies, "detect", SAMPLES / "wavy.h5", "body_cm.obj", "--body-flip", "q", "-o", "q.h5")
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert "body_cm.obj" in result.stderr and "--flip" in result.stderr
    assert not (bodies / "q.h5").exists()


def test_a_model_written_to_another_folder_finds_its_body(tmp_path):
    """invert from the project folder writes out/m.h5 recording samples/body.obj; simulate run from inside
    out/ finds the body neither relative to its working folder nor to the stage file's, but at the absolute
    path it had, with the same SHA-256; a body changed since is refused in one sentence."""
    project = tmp_path / "project"
    (project / "samples").mkdir(parents=True)
    (project / "out").mkdir()
    for name in ("wavy.h5", "body.obj"):
        (project / "samples" / name).write_bytes((SAMPLES / name).read_bytes())
    made = hairinv(project, "detect", "samples/wavy.h5", "samples/body.obj", "--guides", "3", "-o", "out/m.h5")
    assert made.returncode == 0, made.stderr
    stage = stages.read_stage(project / "out" / "m.h5")
    import os

    cwd = os.getcwd()
    try:
        os.chdir(project / "out")
        found_here, _, _, _ = simulation_body(BodySettings(), None, stage, "m.h5", stage[stages.CURVES])
        assert found_here.resolve() == (project / "samples" / "body.obj").resolve()
        with open(project / "samples" / "body.obj", "a") as fh:
            fh.write("# changed\n")
        with pytest.raises(InputError, match="has changed since"):
            simulation_body(BodySettings(), None, stage, "m.h5", stage[stages.CURVES])
    finally:
        os.chdir(cwd)


@pytest.mark.parametrize("case", ["one strand reaches", "none reaches", "roots deep inside"])
def test_a_body_is_refused_only_when_no_strand_can_reach_it(case):
    """A ball of radius 0.1 m; three roots straight above it at 0.3, 0.4 and 0.5 m from its surface. With
    reaches of 0.35 m for the first (its strand is long enough) the roots only warn; with reaches of 0.25 m
    each, none can touch it and the body is refused, naming the strand that comes closest (strand 0, 300 mm
    away with 250 mm); roots 6 cm deep inside it, with 3 cm strands, are in contact: no refusal."""
    from hairinv.contacts.body import BodyMesh
    from hairinv.pipeline import root_distance_lines

    ball = BodyMesh.from_mesh(trimesh.creation.icosphere(subdivisions=4, radius=0.1))
    up = np.array([0.0, 1.0, 0.0])
    heights = np.array([0.3, 0.4, 0.5])
    roots = np.outer(0.1 + heights, up)
    reach = {"one strand reaches": np.array([0.35, 0.25, 0.25]), "none reaches": np.full(3, 0.25)}.get(case)
    if case == "roots deep inside":
        roots, reach = np.outer(np.array([0.04, 0.035, 0.03]), up), np.full(3, 0.03)
    run = lambda: root_distance_lines(roots, ball, "ball.obj", up, BodySettings(), np.eye(4), reach=reach)  # noqa: E731
    if case == "none reaches":
        with pytest.raises(InputError) as refused:
            run()
        message = str(refused.value)
        assert message.startswith("ball.obj: no strand can reach this body") and "strand 0, 300 mm away" in message
        assert "250 mm of strand" in message and "--body-units" in message, message
    else:
        lines = run()
        assert len(lines) == 1 and "roots lie" in lines[0]  # far from it (median over 2 cm), so said


@pytest.mark.parametrize("case", ["metres under a scaled hair", "cm and Z-up", "mm", "another body",
                                  "mirrored by the hair's flip"])
def test_a_suggested_fix_puts_the_roots_on_the_body(case):
    """The options a warning suggests are tried here as a user would give them: built into the body's
    transform by ``body_to_groom`` (not by the suggestion's own arithmetic), the body so read has the roots'
    median within ROOTS_FAR of it. Roots on the top of the sample bust (metres, +Y up); the bust written in
    metres under a hair file of 8 mm units (the Sintel case: ``--scale 0.008``, whose first hint was a scale
    of 8 and a turn, which then refused the body), in cm and Z-up, in mm; and a body the roots are not on
    (the bust moved 1 m aside), for which no option is offered; and a bust 10 cm in front of the origin whose file
    is already in the hair's axes, under a hair read with ``--flip z`` (which mirrors the body too, 20 cm behind
    the roots, unless ``--body-flip none``)."""
    from hairinv.contacts.body import BodyMesh
    from hairinv.pipeline import ROOTS_FAR, root_distance_lines

    bust = trimesh.load(SAMPLES / "body.obj", process=False)
    points, faces = trimesh.sample.sample_surface(bust, 4000, seed=3)
    roots = points[bust.face_normals[faces] @ Y_UP > 0.8][:200]  # the scalp
    assert len(roots) >= 50
    groom_scale, file_vertices, right = {
        "metres under a scaled hair": (0.008, bust.vertices, "--body-units m"),
        "cm and Z-up": (1.0, 100.0 * bust.vertices @ Y_TO_Z.T, "--body-units cm --body-up z"),
        "mm": (1.0, 1000.0 * bust.vertices, "--body-units mm"),
        "another body": (1.0, bust.vertices + [1.0, 0.0, 0.0], None),
        "mirrored by the hair's flip": (1.0, bust.vertices + [0.0, 0.0, 0.1], "--body-flip none")}[case]
    hair_flip = "z" if case == "mirrored by the hair's flip" else ""
    if hair_flip:
        roots = roots + [0.0, 0.0, 0.1]

    def body_read_with(settings: BodySettings) -> tuple[BodyMesh, np.ndarray]:
        to_groom, _ = body_to_groom(settings, groom_scale, "y", hair_flip)
        mesh = trimesh.Trimesh(file_vertices @ to_groom[:3, :3].T + to_groom[:3, 3], bust.faces, process=False)
        return BodyMesh.from_mesh(mesh), to_groom

    as_hair, to_groom = body_read_with(BodySettings())
    lines = root_distance_lines(roots, as_hair, "bust.obj", Y_UP, BodySettings(), to_groom)
    assert len(lines) == 1 and "roots lie" in lines[0], lines
    if right is None:  # no option puts the roots on a body they are not on: none is offered
        assert "(try" not in lines[0] and "check that the groom and the body share" in lines[0], lines[0]
    else:
        suggested = lines[0].split("(try ")[1].split(")")[0]
        assert suggested == right, lines[0]
        words = suggested.split()
        options = dict(zip((w.removeprefix("--body-") for w in words[::2]), words[1::2]))
        fixed, _ = body_read_with(BodySettings(**options))
        assert np.median(np.abs(fixed.closest(np.ascontiguousarray(roots))[0])) <= ROOTS_FAR
        assert root_distance_lines(roots, fixed, "bust.obj", Y_UP, BodySettings(**options), None) == []
