"""``hairinv verify``: the still check, end to end, checked against the frames it writes, as a command and
as a library call (:func:`hairinv.simulation.verify`).

Runtime: about 35-60 s warm (one inversion and eight short simulations of 40
strands, a few runs that stop before any numerics).
"""

from __future__ import annotations

import json
import re
import shutil

import h5py
import numpy as np
import pytest

from conftest import ROUNDOFF, SAMPLES, assert_refused, hairinv
from hairinv import simulation
from hairinv.config import Sources
from hairinv.dynamics.verify import StrandMotion, Verdict, parse_length
from hairinv.errors import InputError
from hairinv.rod.helix import points_at
from hairinv_cli.main import VERIFY_ROWS, _verdict_lines

# The default tolerance, m.
TOLERANCE = 1e-4
# Displacements recomputed from the stored frames against those the run reported: the same float64
# arithmetic on the same numbers, up to round-off on centimetre-sized coordinates.
DISPLACEMENT_TOL = 1e-12  # m


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    """``hairinv invert settled_curly.h5 body.obj``: 40 curly strands that rest stably (already fitted, so
    ``--guides`` would not apply)."""
    folder = tmp_path_factory.mktemp("verify")
    shutil.copyfile(SAMPLES / "settled_curly.h5", folder / "settled_curly.h5")
    shutil.copyfile(SAMPLES / "body.obj", folder / "body.obj")
    result = hairinv(folder, "invert", "settled_curly.h5", "body.obj", "-o", "model.h5")
    assert result.returncode == 0, result.stderr
    return folder


def strand_displacements(path) -> np.ndarray:
    """(F, S) m: each strand's largest point distance from frame 0, recomputed from ``/frames`` and
    ``/helices`` of a stage file at the points the run samples (2 per element, evenly along the strand)."""
    with h5py.File(path, "r") as fh:
        offsets, length = fh["helices"]["offsets"][()], fh["helices"]["length"][()]
        omega, root, frame0 = fh["frames"]["omega"][()], fh["frames"]["root"][()], fh["frames"]["frame0"][()]
    F, S = len(omega), len(offsets) - 1
    points = []
    for f in range(F):
        per_strand = []
        for k in range(S):
            a, z = offsets[k], offsets[k + 1]
            s = np.linspace(0.0, length[a:z].sum(), 2 * (z - a) + 1)
            out = np.empty((len(s), 3))
            points_at(root[f, k], frame0[f, k], np.ascontiguousarray(omega[f, a:z]), length[a:z], s, out)
            per_strand.append(out)
        points.append(per_strand)
    return np.array([[np.linalg.norm(points[f][k] - points[0][k], axis=1).max() for k in range(S)]
                     for f in range(F)])


def frames_of(path) -> dict:
    with h5py.File(path, "r") as fh:
        return {name: fh["frames"][name][()] for name in ("time", "omega", "displacement")}


# --------------------------------------------------------------------------- the tolerance


@pytest.mark.parametrize("text, metres", [
    ("0.1mm", 1e-4), ("1e-4m", 1e-4), ("0.01cm", 1e-4), ("100um", 1e-4), ("100µm", 1e-4),
    ("0.1 mm", 1e-4), (" 2mm ", 2e-3), ("1E-3m", 1e-3), (".5mm", 5e-4), ("3cm", 0.03), ("+1mm", 1e-3),
])
def test_parse_length_reads_a_number_and_its_unit(text, metres):
    assert parse_length(text) == pytest.approx(metres, rel=ROUNDOFF, abs=0)


@pytest.mark.parametrize("text, fragment", [
    ("0.1", "no unit"), ("1e-4", "no unit"), ("0.1furlong", "unknown unit"), ("0.1 MM", "unknown unit"),
    ("mm", "not a length"), ("", "not a length"), ("0.1mm 2mm", "not a length"), ("inf mm", "not a length"),
    ("nanmm", "not a length"), ("-1mm", "> 0"), ("0mm", "> 0"), ("1e999m", "> 0"),
])
def test_parse_length_refuses_what_is_not_a_length_with_a_unit(text, fragment):
    with pytest.raises(InputError, match=re.escape(fragment)) as caught:
        parse_length(text, "--tolerance")
    assert str(caught.value).startswith("--tolerance: ")


# --------------------------------------------------------------------------- the verdict


def test_inverted_model_passes(model):
    result = hairinv(model, "verify", "model.h5", "--seconds", "0.3")
    assert result.returncode == 0, result.stderr
    first = result.stdout.splitlines()[0]
    assert re.fullmatch(r"verify: PASS, no strand point moved more than 0\.1 mm in 0\.3 s "
                        r"\(largest \S+ mm, strand \d+\)", first), first


def test_verify_runs_the_still_scene_of_simulate(model):
    """The same frames as ``simulate --scene still`` where nothing sleeps (verify lets no strand sleep), a JSON
    summary that says so, and nothing past it."""
    verified = hairinv(model, "verify", "model.h5", "--seconds", "0.3", "--json", "-o", "verified.h5")
    assert verified.returncode == 0, verified.stderr
    simulated = hairinv(model, "simulate", "model.h5", "--scene", "still", "--seconds", "0.3", "-o", "simulated.h5",
                        "--set", "dynamics.sleep_speed=0")
    assert simulated.returncode == 0, simulated.stderr
    summary = json.loads(verified.stdout)  # stdout holds the JSON and nothing else
    assert_the_still_scene(summary, model / "verified.h5", model / "simulated.h5")


def test_verify_in_process_runs_the_still_scene_of_simulate(model):
    """The same as library calls: :func:`simulation.verify` and :func:`simulation.simulate`."""
    verdict, run = simulation.verify(model / "model.h5", seconds=0.3, output=model / "verified_call.h5")
    simulation.simulate(model / "model.h5", scene="still", seconds=0.3, output=model / "simulated_call.h5",
                        sources=Sources(sets=("dynamics.sleep_speed=0",)))
    assert verdict.passed and run.scene.name == "still"
    assert_the_still_scene(verdict.as_dict(), model / "verified_call.h5", model / "simulated_call.h5")


def assert_the_still_scene(summary: dict, verified, simulated) -> None:
    """A check of 0.3 s that passed (``summary``, as ``verify --json`` prints it) wrote the frames of the
    still scene (``simulated``) to ``verified``, and nothing past them."""
    ours, theirs = frames_of(verified), frames_of(simulated)
    for name in ours:
        assert np.array_equal(ours[name], theirs[name]), name
    assert summary["verdict"] == "PASS" and not summary["stopped_early"] and summary["strands"] == []
    assert summary["tolerance_m"] == TOLERANCE and summary["seconds_requested"] == 0.3
    assert summary["seconds_simulated"] == pytest.approx(ours["time"][-1], abs=0) == pytest.approx(0.3, rel=1e-12)
    moved = strand_displacements(verified).max(axis=0)
    assert summary["largest"]["displacement_m"] == pytest.approx(moved.max(), abs=DISPLACEMENT_TOL)
    assert moved.max() <= TOLERANCE


def test_naive_model_fails_and_stops_at_the_first_frame_past_the_tolerance(model):
    result = hairinv(model, "verify", "model.h5", "--init", "naive", "--seconds", "0.5", "--json", "-o", "naive.h5")
    assert result.returncode == 1, result.stderr
    summary = json.loads(result.stdout)
    frames = frames_of(model / "naive.h5")
    per_strand = strand_displacements(model / "naive.h5")
    # it stopped at the first frame in which a point was past the tolerance
    assert summary["verdict"] == "FAIL" and summary["stopped_early"]
    assert summary["seconds_simulated"] < summary["seconds_requested"] == 0.5
    assert frames["time"][-1] == summary["seconds_simulated"]
    assert frames["displacement"][-1] > TOLERANCE >= frames["displacement"][:-1].max()
    # the strands listed are those past the tolerance in the stored frames, with their largest displacements
    moved = per_strand.max(axis=0)
    assert sorted(s["index"] for s in summary["strands"]) == list(np.flatnonzero(moved > TOLERANCE))
    for s in summary["strands"]:
        assert s["displacement_m"] == pytest.approx(moved[s["index"]], abs=DISPLACEMENT_TOL)
        assert s["passed_at_s"] == summary["seconds_simulated"]
    assert [s["displacement_m"] for s in summary["strands"]] == sorted(
        (s["displacement_m"] for s in summary["strands"]), reverse=True)
    assert summary["largest"]["displacement_m"] == pytest.approx(frames["displacement"].max(), abs=DISPLACEMENT_TOL)
    assert summary["n_strands"] == per_strand.shape[1] == 40 and summary["n_moved"] == len(summary["strands"])

    # the same run as text: the verdict, then the table of the same strands
    text = hairinv(model, "verify", "model.h5", "--init", "naive", "--seconds", "0.5")
    assert text.returncode == 1, text.stderr
    lines = text.stdout.splitlines()
    first = re.fullmatch(r"verify: FAIL, (\d+) of 40 strands moved more than 0\.1 mm; stopped at (\S+) s", lines[0])
    assert first, lines[0]
    assert int(first[1]) == summary["n_moved"]
    assert float(first[2]) == pytest.approx(summary["seconds_simulated"], rel=1e-3)
    shown = summary["strands"][:VERIFY_ROWS]
    rows = [line.split() for line in lines[2:2 + len(shown)]]
    assert [int(r[0]) for r in rows] == [s["index"] for s in shown]
    assert [float(r[1]) for r in rows] == pytest.approx([1e3 * s["displacement_m"] for s in shown],
                                                        abs=1e-3)  # mm, printed to 3 decimals
    if summary["n_moved"] > VERIFY_ROWS:
        assert lines[2 + VERIFY_ROWS] == f"... and {summary['n_moved'] - VERIFY_ROWS} more strands"


def test_full_runs_to_the_end_and_reports_when_each_strand_passed(model):
    tolerance = 5e-3  # m: naive strands pass it within 0.3 s, at different frames
    result = hairinv(model, "verify", "model.h5", "--init", "naive", "--seconds", "0.3", "--tolerance", "5mm",
                     "--full", "--json", "-o", "full.h5")
    assert result.returncode == 1, result.stderr
    summary = json.loads(result.stdout)
    frames = frames_of(model / "full.h5")
    per_strand = strand_displacements(model / "full.h5")
    assert not summary["stopped_early"] and summary["seconds_simulated"] == pytest.approx(0.3, rel=1e-12)
    assert len(frames["time"]) == 10  # 0.3 s at the still scene's 30 frames per second, and frame 0
    assert sorted(s["index"] for s in summary["strands"]) == list(range(per_strand.shape[1]))  # every strand
    passed_at = set()
    for s in summary["strands"]:
        column = per_strand[:, s["index"]]
        assert s["displacement_m"] == pytest.approx(column.max(), abs=DISPLACEMENT_TOL)
        past = np.flatnonzero(column > tolerance)
        assert s["passed_at_s"] == (frames["time"][past[0]] if len(past) else None)
        passed_at.add(s["passed_at_s"])
    assert len(passed_at - {None}) > 1  # the check is per frame, not once at the end


def test_table_shows_at_most_the_row_limit_and_counts_the_rest():
    n = VERIFY_ROWS + 5
    strands = tuple(StrandMotion(k, 1e-3 * (n - k), 0.1) for k in range(n))
    verdict = Verdict(TOLERANCE, 2.0, 0.1, True, 2 * n, strands)
    lines = _verdict_lines(verdict, every_strand=False)
    assert lines[0] == f"verify: FAIL, {n} of {2 * n} strands moved more than 0.1 mm; stopped at 0.1 s"
    assert len(lines) == 2 + VERIFY_ROWS + 1 and lines[-1] == "... and 5 more strands"
    assert [int(line.split()[0]) for line in lines[2:-1]] == list(range(VERIFY_ROWS))


# --------------------------------------------------------------------------- bad input


BAD = {
    "bare number": (["verify", "model.h5", "--tolerance", "0.1"], "--tolerance", "no unit"),
    "unknown unit": (["verify", "model.h5", "--tolerance", "0.1furlong"], "furlong", "unit"),
    "no model group": (["verify", "settled_curly.h5"], "settled_curly.h5", "has no /model group"),
    "missing model": (["verify", "nope.h5"], "nope.h5", "no such file"),
    "output is the model": (["verify", "model.h5", "-o", "model.h5"], "model.h5", "input"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_input(model, tmp_path, case):
    args, name, fragment = BAD[case]
    for f in ("settled_curly.h5", "body.obj", "model.h5"):
        shutil.copyfile(model / f, tmp_path / f)
    assert_refused(tmp_path, args, name, fragment)
