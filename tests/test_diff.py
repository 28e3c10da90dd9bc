"""``hairinv diff``: two stage files compared quantity by quantity (docs/diff.md), and the determinism it relies on.

Two kinds of input:

- real runs: ``invert`` and a moving ``simulate`` of 70 guide strands of the wavy sample (70: more than the
  64-strand chunks of detection, the stability check and the dynamics, and than the fit's 32, so that the
  worker threads share the work), three times: twice with two threads, once with one. The two-thread runs
  compared by ``hairinv diff`` must pass with every difference zero; the one-thread run must hold the
  same array contents, dataset by dataset, read with h5py (the computing times excepted).
- the hand-made stage file of tests/conftest.py (two strands, four contacts, three frames), edited with
  h5py: one strand's rest shape, a contact, a force, a frame, a fit error, a stiffening factor. Each edit
  must fail the quantity it touches, on the strand it touches, by the amount computed here with numpy.

Runtime: about 2 minutes on 2 cores with a warm numba cache: a minute for the three real runs and a fourth
invert (about 15 s each), the ~40 other subprocesses 1-5 s each (interpreter start-up and imports, reading two
small files); a first run compiles the kernels the runs use, minutes more.
"""

from __future__ import annotations

import json
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from conftest import ELEMENT_OFFSETS, ENV, LENGTH, N_FRAMES, OMEGA, ROOT, SAMPLES, assert_refused, evaluate, make_stage

# Guide strands of the real runs (see the module docstring).
GUIDES = 70
# Simulated time of the real runs: three frames at the motion scene's rate.
SECONDS = 0.1
# Written by the clock, not computed: never the same twice.
TIMINGS = {"frame_seconds"}
# ... and provenance: what the file was made from, by name and SHA-256 (the simulations read different files).
UNCOMPARED_ATTRS = {"seconds", "inputs", "command"}
# Differences computed here and by hairinv from the same float64 numbers (a norm, a subtraction; the frames
# evaluated by two implementations of the same closed form over a few elements).
ROUNDOFF = 1e-12
ROUNDOFF_MM = 1e-9


def run(cwd: Path, *args: str, threads: int = 2) -> subprocess.CompletedProcess:
    env = dict(ENV)
    env["HAIRINV_THREADS"] = str(threads)
    return subprocess.run([sys.executable, "-m", "hairinv_cli.main", *map(str, args)], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=900)


def diff_json(cwd: Path, old, new, *options) -> tuple[int, dict]:
    result = run(cwd, "diff", old, new, "--json", *options)
    assert result.returncode in (0, 1), result.stderr
    assert "Traceback" not in result.stderr
    return result.returncode, json.loads(result.stdout)


def datasets(path: Path) -> dict[str, np.ndarray]:
    out = {}
    with h5py.File(path, "r") as fh:
        fh.visititems(lambda name, obj: out.__setitem__(name, obj[()]) if isinstance(obj, h5py.Dataset) else None)
    return out


def attributes(path: Path) -> dict[str, object]:
    out = {}
    with h5py.File(path, "r") as fh:
        for name, group in [("", fh), *((k, fh[k]) for k in fh.keys())]:
            for key, value in group.attrs.items():
                if key not in UNCOMPARED_ATTRS:
                    out[f"{name}@{key}"] = value
    return out


# --------------------------------------------------------------------------- real runs


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """invert + simulate --scene motion of the same groom: a and b with two threads, c with one."""
    folder = tmp_path_factory.mktemp("diff")
    for name in ("wavy.h5", "body.obj"):
        if not (SAMPLES / name).exists():
            pytest.skip(f"sample {SAMPLES / name} not found")
        shutil.copyfile(SAMPLES / name, folder / name)  # private copies: the samples may be regenerated meanwhile
    for tag, threads in (("a", 2), ("b", 2), ("c", 1)):
        inverted = run(folder, "invert", "wavy.h5", "body.obj", "--guides", GUIDES, "-o", f"{tag}.model.h5",
                       threads=threads)
        assert inverted.returncode == 0, inverted.stderr
        simulated = run(folder, "simulate", f"{tag}.model.h5", "body.obj", "--scene", "motion", "--seconds",
                        SECONDS, "-o", f"{tag}.frames.h5", threads=threads)
        assert simulated.returncode == 0, simulated.stderr
    return folder


def test_the_same_command_twice_shows_no_difference(runs):
    result = run(runs, "diff", "a.frames.h5", "b.frames.h5")
    assert result.returncode == 0, result.stdout + result.stderr
    assert "diff: PASS" in result.stdout
    assert "FAIL" not in result.stdout
    code, report = diff_json(runs, "a.frames.h5", "b.frames.h5")
    assert code == 0 and report["verdict"] == "PASS" and report["failed"] == []
    compared = {k: q for k, q in report["quantities"].items() if q["verdict"] != "SKIPPED"}
    # every group of the pipeline is there, so every quantity is compared, each with no difference at all
    assert set(compared) == set(report["quantities"]), report["skipped"]
    for key, q in compared.items():
        assert q["difference"] in (0, None), (key, q)
        assert q["strands"] == []
    assert report["settings_changed"] == []


def test_the_compared_values_are_the_files_own(runs):
    """The old and new values of the report against the files read with h5py."""
    _, report = diff_json(runs, "a.frames.h5", "b.frames.h5")
    q = report["quantities"]
    with h5py.File(runs / "a.frames.h5", "r") as fh:
        strand = fh["contacts/strand"][()]
        assert q["curves.strands"]["old"] == len(fh["curves/offsets"]) - 1 == GUIDES
        assert q["curves.points"]["old"] == len(fh["curves/points"])
        assert q["helices.elements"]["old"] == fh["helices/offsets"][-1] == len(fh["helices/omega"])
        assert q["helices.fit_error_max"]["old"] == pytest.approx(1e3 * fh["helices/fit_error"][:, 1].max(),
                                                                  rel=ROUNDOFF)
        assert q["contacts.hair_body"]["old"] == np.count_nonzero(strand[:, 1] < 0)
        assert q["contacts.hair_hair"]["old"] == np.count_nonzero(strand[:, 1] >= 0) > 0
        assert q["model.sweeps"]["old"] == fh["model"].attrs["iterations"]
        assert q["model.status"]["old"] == fh["model"].attrs["status"]
        assert q["model.residual"]["old"] == pytest.approx(fh["model"].attrs["residual"], rel=ROUNDOFF)
        assert q["model.stiffening"]["old"] == pytest.approx(fh["model/stiffening"][()].max(), rel=ROUNDOFF)
        assert q["frames.count"]["old"] == len(fh["frames/time"]) == round(SECONDS * fh["frames"].attrs["fps"]) + 1
        rest, target = fh["model/omega_rest_stiffened"][()], fh["model/omega_target"][()]
        weight, force = fh["model/target_weight"][()], fh["model/force"][()]
        # each contact's weight (docs/stage-files.md): /model/contact_gamma where written, else gamma
        gamma = fh["model/contact_gamma"][()] if "contact_gamma" in fh["model"] else fh["model"].attrs["gamma"]
    objective = (0.5 * np.sum(weight * np.sum((rest - target) ** 2, axis=1))
                 + 0.5 * np.sum(gamma * np.sum(force ** 2, axis=1)))
    assert q["model.objective"]["old"] == pytest.approx(objective, rel=ROUNDOFF)
    assert len(q["frames.positions"]["per_frame"]) == q["frames.count"]["old"]


def test_results_do_not_depend_on_the_thread_count(runs):
    """One thread and two: every dataset of every group holds the same numbers (HDF5's own bytes may differ)."""
    for stage in ("model", "frames"):
        one, two = runs / f"c.{stage}.h5", runs / f"a.{stage}.h5"
        d1, d2 = datasets(one), datasets(two)
        assert set(d1) == set(d2)
        differing = [name for name in sorted(d1) if name.split("/")[-1] not in TIMINGS
                     and not (d1[name].shape == d2[name].shape and np.array_equal(d1[name], d2[name]))]
        assert differing == [], f"{stage}: arrays that differ between 1 and 2 threads: {differing}"
        a1, a2 = attributes(one), attributes(two)
        assert set(a1) == set(a2)
        differing = [key for key in sorted(a1) if not np.array_equal(np.asarray(a1[key]), np.asarray(a2[key]))]
        assert differing == [], f"{stage}: attributes that differ between 1 and 2 threads: {differing}"
    code, report = diff_json(runs, "a.frames.h5", "c.frames.h5")
    assert code == 0, report["failed"]


def test_a_changed_setting_is_a_regression(runs):
    """A stiffer material moves the rest shape and the stiffening; the report names the setting."""
    stiffer = run(runs, "invert", "wavy.h5", "body.obj", "--guides", GUIDES, "-o", "stiffer.model.h5",
                  "--set", "material.youngs_modulus=4.2e9")
    assert stiffer.returncode == 0, stiffer.stderr
    result = run(runs, "diff", "a.model.h5", "stiffer.model.h5")
    assert result.returncode == 1, result.stdout + result.stderr
    assert "diff: FAIL" in result.stdout and "material.youngs_modulus" in result.stdout
    _, report = diff_json(runs, "a.model.h5", "stiffer.model.h5")
    assert {"model.youngs_modulus", "model.rest_max", "model.stiffening"} <= set(report["failed"])
    q = report["quantities"]
    assert (q["model.youngs_modulus"]["old"], q["model.youngs_modulus"]["new"]) == (4.0, pytest.approx(4.2))
    with h5py.File(runs / "a.model.h5", "r") as a, h5py.File(runs / "stiffer.model.h5", "r") as b:
        rest = a["model/omega_rest"][()]
        moved = np.linalg.norm(b["model/omega_rest"][()] - rest, axis=1)
        owner = np.repeat(np.arange(GUIDES), np.diff(a["helices/offsets"][()]))
    assert q["model.rest_max"]["difference"] == pytest.approx(moved.max(), rel=ROUNDOFF)
    assert q["model.rest_rms"]["difference"] == pytest.approx(np.sqrt(np.mean(moved ** 2)), rel=ROUNDOFF)
    assert q["model.rest_max"]["strands"][0]["strand"] == owner[np.argmax(moved)]
    # the strands with an element beyond the default tolerance, 1e-4 1/m + 1e-6 of the old curvature
    beyond = moved > 1e-4 + 1e-6 * np.linalg.norm(rest, axis=1)
    assert {s["strand"] for s in q["model.rest_max"]["strands"]} == set(owner[beyond].tolist())
    assert {"group": "model", "key": "material.youngs_modulus", "old": 4e9, "new": 4.2e9} in report["settings_changed"]


# --------------------------------------------------------------------------- the hand-made file, edited


@pytest.fixture
def pair(tmp_path):
    """old.h5 and new.h5: the same hand-made stage file (model and three frames), for the test to edit new.h5."""
    make_stage(tmp_path / "old.h5")
    shutil.copyfile(tmp_path / "old.h5", tmp_path / "new.h5")
    return tmp_path


def edit(path: Path, name: str, change) -> None:
    """Replace the dataset ``name`` by ``change(its array)``."""
    with h5py.File(path, "r+") as fh:
        value = change(fh[name][()].copy())
        del fh[name]
        fh.create_dataset(name, data=value)


def test_identical_hand_made_files_pass(pair):
    result = run(pair, "diff", "old.h5", "new.h5")
    assert result.returncode == 0, result.stdout + result.stderr
    assert result.stdout.splitlines()[-1].startswith("diff: PASS")


def test_one_strand_rest_shape_changed(pair):
    delta = np.array([3e-3, -4e-3, 0.0])  # |delta| = 5e-3 1/m, fifty times the curvature tolerance
    edit(pair / "new.h5", "model/omega_rest", lambda w: w + np.where(np.arange(len(w))[:, None] == 3, delta, 0.0))
    result = run(pair, "diff", "old.h5", "new.h5")
    assert result.returncode == 1
    line = next(l for l in result.stdout.splitlines() if l.startswith("/model rest shape, largest difference"))
    assert "FAIL" in line and line.rstrip().endswith("1 (0.005)")  # element 3 is strand 1's first
    _, report = diff_json(pair, "old.h5", "new.h5")
    assert set(report["failed"]) == {"model.rest_max", "model.rest_rms", "model.objective"}
    q = report["quantities"]
    assert q["model.rest_max"]["difference"] == pytest.approx(np.linalg.norm(delta), rel=ROUNDOFF)
    assert q["model.rest_rms"]["difference"] == pytest.approx(np.linalg.norm(delta) / np.sqrt(len(OMEGA)), rel=ROUNDOFF)
    assert q["model.rest_max"]["strands"] == [{"strand": 1, "difference": pytest.approx(np.linalg.norm(delta))}]
    assert q["model.rest_max"]["unit"] == "1/m"
    # within a looser curvature tolerance it passes, the objective too (its tolerance follows from the curvature's)
    code, report = diff_json(pair, "old.h5", "new.h5", "--atol", "curvature=0.01")
    assert code == 0 and report["failed"] == []


def test_a_contact_removed(pair):
    """Contact 2 is the hair-hair one between strands 0 and 1."""
    with h5py.File(pair / "new.h5", "r") as fh:
        assert fh["contacts/strand"][2].tolist() == [0, 1]
        names = [f"contacts/{k}" for k in fh["contacts"].keys()] + ["model/force"]
    for name in names:
        edit(pair / "new.h5", name, lambda a: np.delete(a, 2, axis=0))
    result = run(pair, "diff", "old.h5", "new.h5")
    assert result.returncode == 1
    assert re.search(r"^/contacts hair-hair contacts\s+contacts\s+1\s+0\s+-1\s+0\s+FAIL", result.stdout, re.M)
    _, report = diff_json(pair, "old.h5", "new.h5")
    q = report["quantities"]
    assert q["contacts.hair_body"]["verdict"] == "PASS"
    assert (q["contacts.set"]["old"], q["contacts.set"]["new"], q["contacts.set"]["difference"]) == (4, 3, 1)
    assert [s["strand"] for s in q["contacts.set"]["strands"]] == [0, 1]
    assert q["model.force"]["verdict"] == "SKIPPED" and "contact sets differ" in q["model.force"]["note"]


def test_a_contact_force_changed(pair):
    """Forces are compared as world vectors, frame.T @ r: the change of contact 1's force, 2e-8 N along its
    tangent, on strand 0 only (contact 1 is a body contact)."""
    change = np.array([0.0, 2e-8, 0.0])
    edit(pair / "new.h5", "model/force", lambda r: r + np.where(np.arange(len(r))[:, None] == 1, change, 0.0))
    with h5py.File(pair / "old.h5", "r") as fh:
        world = fh["contacts/frame"][1].T @ change
        assert fh["contacts/strand"][1].tolist() == [0, -1]
    _, report = diff_json(pair, "old.h5", "new.h5")
    q = report["quantities"]["model.force"]
    assert q["verdict"] == "FAIL" and q["unit"] == "N"
    assert q["difference"] == pytest.approx(np.linalg.norm(world), rel=1e-9)
    assert q["strands"] == [{"strand": 0, "difference": pytest.approx(np.linalg.norm(world), rel=1e-9)}]


def test_a_frame_moved(pair):
    """Frame 2's root of strand 0 moved by 0.05 mm: every point of that strand in that frame moves by exactly that."""
    shift = np.array([3e-5, 0.0, -4e-5])
    edit(pair / "new.h5", "frames/root", lambda x: x + np.where(
        (np.arange(N_FRAMES)[:, None, None] == 2) & (np.arange(2)[None, :, None] == 0), shift, 0.0))
    result = run(pair, "diff", "old.h5", "new.h5")
    assert result.returncode == 1
    row = r"^/frames frame positions, largest distance\s+mm\s+-\s+-\s+0\.05\s+0\.01\d*\s+FAIL\s+0 \(0\.05\)$"
    assert re.search(row, result.stdout, re.M), result.stdout
    _, report = diff_json(pair, "old.h5", "new.h5")
    assert report["failed"] == ["frames.positions"]
    q = report["quantities"]["frames.positions"]
    assert q["difference"] == pytest.approx(1e3 * np.linalg.norm(shift), abs=ROUNDOFF_MM)
    assert [f["largest_mm"] for f in q["per_frame"]] == [0.0, 0.0, pytest.approx(0.05, abs=ROUNDOFF_MM)]
    assert [f["strand"] for f in q["per_frame"]][2] == 0 and q["per_frame"][2]["strands_beyond"] == 1
    # a tolerance of 0.1 mm lets it through
    assert run(pair, "diff", "old.h5", "new.h5", "--atol", "length=0.1mm").returncode == 0


def test_a_frame_bent(pair):
    """Frame 1's second element of strand 0 bent by 0.5 1/m more: the distances against the centerlines evaluated
    here (the closed form of tests/conftest.py, not hairinv's)."""
    edit(pair / "new.h5", "frames/omega", lambda w: w + np.where(
        (np.arange(N_FRAMES)[:, None, None] == 1) & (np.arange(len(OMEGA))[None, :, None] == 1), [0.5, 0, 0], 0.0))
    with h5py.File(pair / "old.h5", "r") as a, h5py.File(pair / "new.h5", "r") as b:
        points, offsets = a["curves/points"][()], a["curves/offsets"][()]
        root, frame0 = a["frames/root"][1], a["frames/frame0"][1]
        before = evaluate(points, offsets, ELEMENT_OFFSETS, LENGTH, root, frame0, a["frames/omega"][1])
        after = evaluate(points, offsets, ELEMENT_OFFSETS, LENGTH, root, frame0, b["frames/omega"][1])
    moved = np.linalg.norm(after - before, axis=1)
    assert moved[offsets[1]:].max() == 0.0 and moved.max() > 1e-4
    _, report = diff_json(pair, "old.h5", "new.h5")
    q = report["quantities"]["frames.positions"]
    assert q["verdict"] == "FAIL" and [s["strand"] for s in q["strands"]] == [0]
    assert q["difference"] == pytest.approx(1e3 * moved.max(), abs=ROUNDOFF_MM)
    assert [f["largest_mm"] for f in q["per_frame"]] == [0.0, pytest.approx(1e3 * moved.max(), abs=ROUNDOFF_MM), 0.0]


def test_fit_error_and_stiffening_changed(tmp_path):
    make_stage(tmp_path / "old.h5", stiffened=True)
    shutil.copyfile(tmp_path / "old.h5", tmp_path / "new.h5")
    edit(tmp_path / "new.h5", "helices/fit_error", lambda e: e + [[0.0, 0.0], [0.0, 2e-5]])
    edit(tmp_path / "new.h5", "model/stiffening", lambda f: f + [0.0, 1e-3])
    _, report = diff_json(tmp_path, "old.h5", "new.h5")
    q = report["quantities"]
    assert set(report["failed"]) == {"helices.fit_error_max", "model.stiffening"}
    assert q["helices.fit_error_max"]["difference"] == pytest.approx(0.02, rel=1e-9)  # mm
    assert (q["helices.fit_error_max"]["old"], q["helices.fit_error_max"]["new"]) == (pytest.approx(0.04),
                                                                                   pytest.approx(0.06))
    assert q["helices.fit_error_max"]["strands"] == [{"strand": 1, "difference": pytest.approx(0.02, rel=1e-9)}]
    assert q["model.stiffening"]["difference"] == pytest.approx(1e-3, rel=1e-9)
    assert [s["strand"] for s in q["model.stiffening"]["strands"]] == [1]


def test_a_group_in_one_file_only(tmp_path):
    make_stage(tmp_path / "old.h5", frames=False)
    make_stage(tmp_path / "new.h5")
    result = run(tmp_path, "diff", "old.h5", "new.h5")
    assert result.returncode == 1
    assert "file.groups: /frames only in new.h5" in result.stdout
    _, report = diff_json(tmp_path, "old.h5", "new.h5")
    assert report["failed"] == ["file.groups"]
    assert report["quantities"]["frames.positions"]["verdict"] == "SKIPPED"


def test_additions_of_another_version_are_skipped_and_said(tmp_path):
    """The stiffening datasets are an addition: absent from an older version's file they are skipped; between
    two files of the same version, one without them is a difference (the settings changed)."""
    make_stage(tmp_path / "old.h5")
    make_stage(tmp_path / "new.h5", stiffened=True)
    _, report = diff_json(tmp_path, "old.h5", "new.h5")
    assert {"model.stiffening", "model.rest_stiffened_max"} <= set(report["failed"])
    assert "only in new.h5" in report["quantities"]["model.stiffening"]["note"]
    with h5py.File(tmp_path / "old.h5", "r+") as fh:
        fh.attrs["producer"] = "hairinv 0.0.1 invert"
    code, report = diff_json(tmp_path, "old.h5", "new.h5")
    assert code == 0, report["failed"]
    skipped = {s["quantity"]: s["reason"] for s in report["skipped"]}
    assert {"model.stiffening", "model.rest_stiffened_rms", "model.rest_stiffened_max"} <= set(skipped)
    assert "/model dataset stiffening is only in new.h5" in skipped["model.stiffening"]
    result = run(tmp_path, "diff", "old.h5", "new.h5")
    assert result.returncode == 0 and "model.stiffening: /model dataset stiffening is only in new.h5" in result.stdout


def test_the_json_keys_are_stable(tmp_path):
    """Every quantity is in every report, with the same keys, whatever the files hold."""
    make_stage(tmp_path / "full.h5", stiffened=True)
    make_stage(tmp_path / "bare.h5", model=False, frames=False)
    reports = [diff_json(tmp_path, a, b)[1] for a, b in (("full.h5", "full.h5"), ("bare.h5", "bare.h5"),
                                                         ("bare.h5", "full.h5"))]
    keys = [list(r["quantities"]) for r in reports]
    assert keys[0] == keys[1] == keys[2]
    for r in reports:
        assert set(r) == {"schema", "verdict", "old", "new", "tolerances", "quantities", "failed", "skipped",
                          "settings_changed"}
        for q in r["quantities"].values():
            assert set(q) == {"label", "group", "unit", "old", "new", "difference", "tolerance", "verdict", "note",
                              "strands", "per_frame"}
    assert reports[0]["tolerances"] == {"rtol": 1e-6, "atol": {"length_m": 1e-5, "curvature_1_per_m": 1e-4,
                                                               "force_N": 1e-9, "factor": 1e-6, "time_s": 1e-9,
                                                               "sweeps": 0}}


# --------------------------------------------------------------------------- bad input


def test_unreadable_input_is_refused(tmp_path):
    make_stage(tmp_path / "good.h5")
    (tmp_path / "text.h5").write_text("not HDF5\n")
    with h5py.File(tmp_path / "other.h5", "w") as fh:
        fh["x"] = np.zeros(3)
    assert_refused(tmp_path, ["diff", "good.h5", "text.h5"], "text.h5", "is not a readable HDF5 file")
    assert_refused(tmp_path, ["diff", "other.h5", "good.h5"], "other.h5", "not a hairinv stage file")
    assert_refused(tmp_path, ["diff", "good.h5", "missing.h5"], "missing.h5", "no such file")
    assert_refused(tmp_path, ["diff", "good.h5", "missing.h5", "--json"], "missing.h5", "no such file")


@pytest.mark.parametrize("args, fragment", [
    (["--atol", "1e-5"], "--atol takes KIND=VALUE"),
    (["--atol", "angle=1"], "unknown kind 'angle'"),
    (["--atol", "length=1e-5"], "has no unit"),
    (["--atol", "force=-1"], "must be a finite number >= 0"),
    (["--rtol", "-1"], "--rtol must be"),
])
def test_bad_tolerances_are_refused(tmp_path, args, fragment):
    make_stage(tmp_path / "good.h5")
    assert_refused(tmp_path, ["diff", "good.h5", "good.h5", *args], "--", fragment)


# --------------------------------------------------------------------------- the example of docs/diff.md


def test_the_docs_example_runs_as_written(tmp_path):
    """The commands of docs/diff.md's example, in a folder laid out like a checkout."""
    text = (ROOT / "docs" / "diff.md").read_text()
    section = re.search(r"^## Example\n(.*?)^##", text, flags=re.S | re.M)
    assert section, "docs/diff.md has no section 'Example'"
    commands = [line.strip() for block in re.findall(r"```sh\n(.*?)```", section.group(1), flags=re.S)
                for line in block.splitlines() if line.strip()]
    assert any(c.startswith("hairinv diff ") for c in commands)
    (tmp_path / "samples").symlink_to(SAMPLES)
    for command in commands:
        argv = shlex.split(command)
        assert argv[0] == "hairinv"
        result = run(tmp_path, *argv[1:])
        assert result.returncode == 0, f"{command}: exit {result.returncode}\n{result.stdout[-2000:]}{result.stderr}"


def test_a_strand_turned_unstable(pair):
    """/model/stability_margin below -1e-6 marks a strand unstable at rest: a strand that turns unstable is a
    regression, named; the carrying threshold is compared as a force."""
    for name in ("old.h5", "new.h5"):
        with h5py.File(pair / name, "r+") as fh:
            strands = len(fh["curves/offsets"]) - 1
            fh["model"].create_dataset("stability_margin", data=np.full(strands, 0.25))
            fh["model"].attrs["carrying_threshold"] = 1e-9
    edit(pair / "new.h5", "model/stability_margin", lambda m: np.where(np.arange(len(m)) == 1, -0.5, m))
    code, report = diff_json(pair, "old.h5", "new.h5")
    q = report["quantities"]
    assert code == 1 and report["failed"] == ["model.unstable"]
    assert (q["model.unstable"]["old"], q["model.unstable"]["new"]) == (0, 1)
    assert [s["strand"] for s in q["model.unstable"]["strands"]] == [1]
    assert q["model.carrying_threshold"]["verdict"] == "PASS" and q["model.carrying_threshold"]["old"] == 1e-9
    # within round-off of zero (above -1e-6) a strand still rests stably
    edit(pair / "new.h5", "model/stability_margin", lambda m: np.where(np.arange(len(m)) == 1, -1e-7, m))
    assert diff_json(pair, "old.h5", "new.h5")[0] == 0
