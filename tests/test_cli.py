"""The ``hairinv`` command run as a subprocess: help, a real fit, ``info``, and bad input.

Runtime: about 15-30 s with a warm numba cache. One ``fit`` subprocess on 20
guide strands of the wavy sample (2-12 s warm, depending on machine load; after
an edit of hairinv/rod/fitting.py numba recompiles, which adds 30-90 s once);
the ~25 other subprocesses stop before any numerics (0.5-1 s each: interpreter
start-up and imports). The interrupted-write checks run in-process.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import shutil
import struct
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from conftest import ENV, SAMPLES, hairinv, real_path, snapshot
from hairinv import __version__, config, stages
from hairinv.formats import write_curves

# Frames of a fitted root: orthonormal to round-off of the fit's rotations.
FRAME_TOL = 1e-9
# The fitted root is clamped to the input root (same float64 numbers, up to round-off).
ROOT_TOL = 1e-12


def sample(name: str) -> Path:
    path = SAMPLES / name
    if not path.exists():
        pytest.skip(f"sample {path} not found")
    return path


def strands(points: np.ndarray, offsets: np.ndarray) -> list[np.ndarray]:
    return [points[a:b] for a, b in zip(offsets[:-1], offsets[1:])]


# --------------------------------------------------------------------------- help


@pytest.mark.parametrize(
    "args, fragments",
    [
        (["--help"], ["fit", "info", "--quiet"]),
        (["-h"], ["fit", "info"]),
        (["fit", "--help"], ["CURVES", "--guides", "--units", "--scale", "--flip", "--up", "--set", "--config", "-o"]),
        (["info", "--help"], ["--json"]),
    ],
)
def test_help(tmp_path, args, fragments):
    result = hairinv(tmp_path, *args)
    assert result.returncode == 0, result.stderr
    for fragment in fragments:
        assert fragment in result.stdout
    assert result.stderr == ""
    assert list(tmp_path.iterdir()) == []


def test_version(tmp_path):
    result = hairinv(tmp_path, "--version")
    assert result.returncode == 0 and __version__ in result.stdout


# --------------------------------------------------------------------------- a real fit


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    """``hairinv fit wavy.h5 -o out.h5 --guides 20`` over an older stage file at ``out.h5``."""
    folder = tmp_path_factory.mktemp("fit")
    source = folder / "wavy.h5"
    shutil.copyfile(sample("wavy.h5"), source)  # a private copy: the samples may be regenerated meanwhile
    old = folder / "out.h5"
    write_curves(old, np.array([[0, 0, 0], [0, -0.1, 0], [1, 0, 0], [1, -0.1, 0]], float), np.array([0, 2, 4]))
    old_bytes = old.read_bytes()
    assert stages.read_stage(old).producer.endswith(" export")
    umask = os.umask(0)
    os.umask(umask)
    result = hairinv(folder, "fit", "wavy.h5", "-o", "out.h5", "--guides", "20")
    return {"folder": folder, "source": source, "out": folder / "out.h5", "old_bytes": old_bytes,
            "result": result, "umask": umask}


def test_fit_succeeds_and_reports(fitted):
    result = fitted["result"]
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr and "error" not in result.stderr
    source = stages.read_stage(fitted["source"])[stages.CURVES]
    n_read = len(source["offsets"]) - 1
    lines = result.stdout.splitlines()
    assert lines[0] == f"read {n_read} strands, {len(source['points'])} points"
    assert any(line.startswith("guides: kept 20 of ") for line in lines)
    assert "kept 20 strands" in lines
    assert lines[-1] == "wrote out.h5"


def test_fit_leaves_only_the_output(fitted):
    assert sorted(p.name for p in fitted["folder"].iterdir()) == ["out.h5", "wavy.h5"]
    assert fitted["out"].stat().st_mode & 0o777 == 0o666 & ~fitted["umask"]


def test_fit_replaces_an_older_stage_file(fitted):
    assert fitted["result"].returncode == 0, fitted["result"].stderr
    assert fitted["out"].read_bytes() != fitted["old_bytes"]
    assert stages.read_stage(fitted["out"]).producer.endswith(" fit")


def test_fit_output_root_attributes(fitted):
    assert fitted["result"].returncode == 0, fitted["result"].stderr
    with h5py.File(fitted["out"], "r") as fh:
        attrs = {k: (v.decode() if isinstance(v, bytes) else v) for k, v in fh.attrs.items()}
        assert sorted(fh.keys()) == ["curves", "helices"]
    assert attrs["format"] == "hairinv"
    assert int(attrs["schema_version"]) == stages.SCHEMA_VERSION == 1
    assert attrs["producer"] == f"hairinv {__version__} fit"
    assert attrs["stages"] == "curves,helices"


def test_fit_output_curves_are_20_input_strands(fitted):
    assert fitted["result"].returncode == 0, fitted["result"].stderr
    stage = stages.read_stage(fitted["out"])
    assert list(stage.groups) == ["curves", "helices"] and stage.schema_version == 1
    curves = stage["curves"]
    src = stages.read_stage(fitted["source"])["curves"]
    assert curves["points"].dtype == np.float64 and curves["offsets"].dtype == np.int64
    assert len(curves["offsets"]) == 21
    by_root = {tuple(s[0]): s for s in strands(src["points"], src["offsets"])}
    got = strands(curves["points"], curves["offsets"])
    assert len({tuple(s[0]) for s in got}) == 20
    for strand in got:  # the file is in metres already: strands are copied unchanged
        assert tuple(strand[0]) in by_root
        np.testing.assert_array_equal(strand, by_root[tuple(strand[0])])
    assert curves.attrs["scale_to_m"] == 1.0
    np.testing.assert_allclose(curves.attrs["up"], np.asarray(src.attrs.get("up", (0, 1, 0)), float), rtol=0, atol=1e-15)


def test_fit_output_provenance(fitted):
    assert fitted["result"].returncode == 0, fitted["result"].stderr
    stage = stages.read_stage(fitted["out"])
    digest = hashlib.sha256(fitted["source"].read_bytes()).hexdigest()
    expected = config.resolve("default")
    import_config = dict(dataclasses.asdict(expected.import_), guides=20)
    assert stage["curves"].config == {"import": import_config}
    assert stage["helices"].config == {"fit": dataclasses.asdict(expected.fit)}
    for name in ("curves", "helices"):
        inputs = stage[name].inputs
        assert len(inputs) == 1
        assert inputs[0]["name"] == "wavy.h5" and inputs[0]["sha256"] == digest
    with h5py.File(fitted["out"], "r") as fh:  # stored as JSON strings, as the contract says
        for name in ("curves", "helices"):
            json.loads(fh[name].attrs["config"])
            json.loads(fh[name].attrs["inputs"])


def test_fit_output_helices(fitted):
    assert fitted["result"].returncode == 0, fitted["result"].stderr
    stage = stages.read_stage(fitted["out"])
    curves, helices = stage["curves"], stage["helices"]
    offsets = helices["offsets"]
    assert len(offsets) == 21 and offsets[0] == 0 and np.all(np.diff(offsets) >= 1)
    n_elements = offsets[-1]
    assert helices["length"].shape == (n_elements,) and np.all(helices["length"] > 0)
    assert helices["omega"].shape == (n_elements, 3)
    np.testing.assert_allclose(helices["root"], curves["points"][curves["offsets"][:-1]], rtol=0, atol=ROOT_TOL)
    frames = helices["frame0"]
    assert frames.shape == (20, 3, 3)
    eye = np.broadcast_to(np.eye(3), frames.shape)
    np.testing.assert_allclose(frames @ frames.transpose(0, 2, 1), eye, rtol=0, atol=FRAME_TOL)
    np.testing.assert_allclose(np.linalg.det(frames), 1.0, rtol=0, atol=FRAME_TOL)
    err = helices["fit_error"]
    assert err.shape == (20, 2) and np.all(err >= 0) and np.all(err[:, 0] <= err[:, 1])


def test_info(fitted):
    assert fitted["result"].returncode == 0, fitted["result"].stderr
    result = hairinv(fitted["folder"], "info", "out.h5")
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert lines[0] == f"out.h5: hairinv {__version__} fit, schema 1, stages curves,helices"
    assert "/curves" in lines and "/helices" in lines
    assert "  strands: 20" in lines


def test_info_json(fitted):
    assert fitted["result"].returncode == 0, fitted["result"].stderr
    result = hairinv(fitted["folder"], "info", "--json", "out.h5")
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    stage = stages.read_stage(fitted["out"])
    assert summary["stages"] == "curves,helices" and summary["schema_version"] == 1
    assert summary["groups"]["curves"]["strands"] == 20
    assert summary["groups"]["curves"]["points"] == len(stage["curves"]["points"])
    assert summary["groups"]["helices"]["elements"] == int(stage["helices"]["offsets"][-1])


# --------------------------------------------------------------------------- bad input


def _usc(strand_points: list[np.ndarray]) -> bytes:
    parts = [struct.pack("<i", len(strand_points))]
    for pts in strand_points:
        parts += [struct.pack("<i", len(pts)), np.asarray(pts, "<f4").tobytes()]
    return b"".join(parts)


def _nan_in_strand_3(folder: Path) -> list[str]:
    pts = [np.arange(12, dtype=float).reshape(4, 3) * 0.01 + s for s in range(5)]
    pts[3][2, 1] = np.nan
    (folder / "nan.data").write_bytes(_usc(pts))
    return ["fit", "nan.data", "-o", "out.h5"]


def _truncated_v4(folder: Path) -> list[str]:
    sintel = real_path("sintel", "GEO-sintel_hair_emit.001-sintel_hair.tfx")
    (folder / "trunc.tfx").write_bytes(sintel.read_bytes()[:1000])
    return ["fit", "trunc.tfx", "-o", "out.h5"]


def _foreign_hdf5(folder: Path) -> list[str]:
    with h5py.File(folder / "foreign.h5", "w") as fh:
        fh["data"] = np.arange(3)
    return ["fit", "wavy.h5", "-o", "foreign.h5"]


def _write(name: str, data: bytes, args: list[str]):
    def setup(folder: Path) -> list[str]:
        (folder / name).write_bytes(data)
        return args

    return setup


def _mkdir(name: str, args: list[str]):
    def setup(folder: Path) -> list[str]:
        (folder / name).mkdir()
        return args

    return setup


def _nothing(args: list[str]):
    return lambda folder: args


# id: (set-up returning the arguments, the name the message must hold, fragments of the message)
BAD = {
    "missing file": (_nothing(["fit", "missing.h5", "-o", "out.h5"]), "missing.h5", ["no such file"]),
    "empty file": (_write("empty.h5", b"", ["fit", "empty.h5", "-o", "out.h5"]), "empty.h5", ["empty"]),
    "truncated tfx v4": (_truncated_v4, "trunc.tfx", ["truncated"]),
    "wrong magic hair": (
        _write("bad.hair", b"HAIX" + bytes(124) + bytes(48), ["fit", "bad.hair", "-o", "out.h5"]),
        "bad.hair", ["magic"]),
    "negative usc count": (
        _write("neg.data", struct.pack("<i", -5) + bytes(16), ["fit", "neg.data", "-o", "out.h5"]),
        "neg.data", ["negative"]),
    "nan in strand 3": (_nan_in_strand_3, "nan.data", ["strand 3", "NaN"]),
    "a strand 100 m long": (
        _write("long.data", _usc([np.column_stack([np.zeros(50), -np.linspace(0.0, 100.0, 50), np.zeros(50)])]),
               ["fit", "long.data", "-o", "out.h5", "--units", "m"]), "long.data", ["strand 0", "100 m long", "--units"]),
    "a coordinate of 1e37": (
        _write("huge.data", _usc([np.column_stack([np.zeros(9), -np.linspace(0.0, 0.2, 9), np.r_[np.zeros(8), 1e37]])]),
               ["fit", "huge.data", "-o", "out.h5", "--units", "m"]), "huge.data", ["strand 0", "longer than any hair"]),
    "a body of degenerate triangles only": (
        _write("flat.obj", b"v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n", ["detect", "wavy.h5", "flat.obj", "-o", "out.h5"]),
        "flat.obj", ["degenerate"]),
    "unknown suffix": (_write("hair.xyz", b"1 2 3\n", ["fit", "hair.xyz", "-o", "out.h5"]), "hair.xyz", [".xyz"]),
    "unknown setting": (_nothing(["fit", "wavy.h5", "-o", "out.h5", "--set", "fit.nope=1"]), "fit.nope", ["unknown"]),
    "setting of the wrong type": (
        _nothing(["fit", "wavy.h5", "-o", "out.h5", "--set", "import.guides=many"]), "import.guides", ["int"]),
    "invalid toml": (
        _write("bad.toml", b"[fit\ntolerance = 1\n", ["fit", "wavy.h5", "-o", "out.h5", "--config", "bad.toml"]),
        "bad.toml", ["TOML"]),
    "missing toml": (
        _nothing(["fit", "wavy.h5", "-o", "out.h5", "--config", "nothere.toml"]), "nothere.toml", ["no such"]),
    "output is the input": (_nothing(["fit", "wavy.h5", "-o", "wavy.h5"]), "wavy.h5", ["input"]),
    "output is the input, other spelling": (
        _mkdir("sub", ["fit", "wavy.h5", "-o", "sub/../wavy.h5"]), "wavy.h5", ["input"]),
    "output is a text file": (
        _write("notes.txt", b"precious\n", ["fit", "wavy.h5", "-o", "notes.txt"]), "notes.txt",
        ["not a hairinv stage file"]),
    "output is a foreign hdf5": (_foreign_hdf5, "foreign.h5", ["not a hairinv stage file"]),
    "output is a folder": (_mkdir("outdir", ["fit", "wavy.h5", "-o", "outdir"]), "outdir", ["folder"]),
    "output folder missing": (_nothing(["fit", "wavy.h5", "-o", "nodir/out.h5"]), "nodir", ["does not exist"]),
    "info on a missing file": (_nothing(["info", "missing.h5"]), "missing.h5", ["no such file"]),
    "info on a text file": (_write("notes.txt", b"precious\n", ["info", "notes.txt"]), "notes.txt", ["HDF5"]),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_input(tmp_path, case):
    setup, name, fragments = BAD[case]
    shutil.copyfile(sample("wavy.h5"), tmp_path / "wavy.h5")
    args = setup(tmp_path)
    before = snapshot(tmp_path)
    dirs_before = sorted(str(p) for p in tmp_path.rglob("*") if p.is_dir())
    result = hairinv(tmp_path, *args)
    assert result.returncode == 2, (result.returncode, result.stderr)
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("hairinv: error: ")
    assert name in lines[0]
    for fragment in fragments:
        assert fragment in lines[0]
    assert "Traceback" not in result.stderr and result.stdout == ""
    # nothing created (no output, no temp file, no folder), every existing file byte-for-byte unchanged
    assert snapshot(tmp_path) == before
    assert sorted(str(p) for p in tmp_path.rglob("*") if p.is_dir()) == dirs_before


# --------------------------------------------------------------------------- interrupted writes (in-process)


class _Interrupt:
    """Stands for a dataset; turning it into an array is where the 'kill' lands."""

    def __array__(self, *args, **kwargs):
        raise KeyboardInterrupt


def _groups(bad) -> list[stages.Group]:
    pts = np.array([[0, 0, 0], [0, -0.1, 0], [1, 0, 0], [1, -0.1, 0]], float)
    good = stages.Group(stages.CURVES, {"points": pts, "offsets": np.array([0, 2, 4])})
    # the failing group comes second, so the temporary file already holds data when it fails
    failing = stages.Group(stages.HELICES, {"root": pts[[0, 2]], "omega": bad})
    return [good, failing]


@pytest.mark.parametrize(
    "bad, error",
    [(np.array([object(), object()], dtype=object), TypeError), (_Interrupt(), KeyboardInterrupt)],
    ids=["h5py-refuses-dataset", "interrupted"],
)
@pytest.mark.parametrize("existing", [True, False], ids=["over-old-file", "new-file"])
def test_failed_write_leaves_destination_unchanged(tmp_path, bad, error, existing):
    out = tmp_path / "out.h5"
    if existing:
        write_curves(out, np.array([[0, 0, 0], [0, 1, 0]], float), np.array([0, 2]))
    before = snapshot(tmp_path)
    with pytest.raises(error):
        stages.write_stage(out, _groups(bad), "fit")
    assert snapshot(tmp_path) == before
    assert out.exists() == existing
    if existing:
        assert stages.read_stage(out).producer.endswith(" export")


def test_write_stage_replaces_atomically_when_it_succeeds(tmp_path):
    out = tmp_path / "out.h5"
    write_curves(out, np.array([[0, 0, 0], [0, 1, 0]], float), np.array([0, 2]))
    stages.write_stage(out, _groups(np.zeros((2, 3)))[:1], "fit")
    assert [p.name for p in tmp_path.iterdir()] == ["out.h5"]
    stage = stages.read_stage(out)
    assert stage.producer.endswith(" fit") and len(stage["curves"]["points"]) == 4


def test_quiet_and_no_progress_after_the_subcommand(tmp_path):
    """``hairinv export ... -q`` (where people type it) is ``hairinv -q export ...``: nothing on stdout, the
    same file; without it the command says what it wrote."""
    loud = hairinv(tmp_path, "export", SAMPLES / "wavy.h5", "-o", "loud.obj")
    assert loud.returncode == 0 and "wrote loud.obj" in loud.stdout
    after = hairinv(tmp_path, "export", SAMPLES / "wavy.h5", "-o", "after.obj", "-q", "--no-progress")
    before = hairinv(tmp_path, "-q", "--no-progress", "export", SAMPLES / "wavy.h5", "-o", "before.obj")
    for result in (after, before):
        assert result.returncode == 0 and result.stdout == "" and result.stderr == ""
    assert (tmp_path / "after.obj").read_bytes() == (tmp_path / "before.obj").read_bytes()
    assert "--quiet" in hairinv(tmp_path, "invert", "--help").stdout


def test_plain_progress_lines_when_stderr_is_not_a_terminal(tmp_path):
    """A farm's log has no terminal: progress comes as plain, parseable lines on stderr
    (``stage: N of M units (P %)``), at most one per HAIRINV_PROGRESS_SECONDS; -q silences them."""
    import re

    env = {**ENV, "HAIRINV_PROGRESS_SECONDS": "0"}
    args = [sys.executable, "-m", "hairinv_cli.main", "invert", str(SAMPLES / "wavy.h5"), str(SAMPLES / "body.obj"),
            "--guides", "6", "-o"]
    run = subprocess.run(args + ["every.model.h5"], cwd=tmp_path, capture_output=True, text=True, env=env,
                         timeout=600, check=False)
    assert run.returncode == 0, run.stderr
    lines = re.findall(r"^(\w+): (\d+) of (\d+) (\w+)s \((\d+) %\)", run.stderr, flags=re.MULTILINE)
    stages_seen = {stage for stage, *_ in lines}
    assert {"fit", "invert"} <= stages_seen, run.stderr
    for stage, n, total, _unit, share in lines:
        assert int(n) <= int(total) and int(share) == round(100 * int(n) / int(total))
    # the count is a cap: each invert line says what stops the method before it
    solver_lines = [line for line in run.stderr.splitlines() if line.startswith("invert: ")]
    assert solver_lines and all("stops within 0.05 1/m" in line and "at most" in line for line in solver_lines)
    # and the run ends by saying what to run next, each a command that takes this model
    last = run.stdout.strip().splitlines()[-1]
    assert last.startswith("next: ") and "hairinv verify every.model.h5 " in last, last
    assert "hairinv simulate every.model.h5 " in last and str(SAMPLES / "body.obj") in last, last
    export = last.split("`hairinv export ")[1].split("`")[0].split()
    done = subprocess.run([sys.executable, "-m", "hairinv_cli.main", "export", *export], cwd=tmp_path,
                          capture_output=True, text=True, env=env, timeout=600, check=False)
    assert done.returncode == 0 and (tmp_path / "every.usda").is_file(), done.stderr
    quiet = subprocess.run(args + ["quiet.model.h5", "-q"], cwd=tmp_path, capture_output=True, text=True, env=env,
                           timeout=600, check=False)
    assert quiet.returncode == 0 and quiet.stderr == "" and quiet.stdout == ""


def test_a_body_no_strand_can_reach_is_refused_with_the_likely_unit_mix_up(tmp_path):
    """A head in centimetres under a groom in metres: every root lies a metre and more from it, farther than
    any strand is long, so the body can carry nothing. The run stops before the fit (exit 2, one line naming
    the body file, the factor that would put the roots back on it, 0.01, and the option that does it,
    --body-units cm) and writes nothing; given that option it runs without a word about the roots."""
    import trimesh

    body = trimesh.load(SAMPLES / "body.obj", process=False)
    body.vertices = np.asarray(body.vertices) * 100.0
    body.export(tmp_path / "body_cm.obj")
    result = hairinv(tmp_path, "detect", SAMPLES / "wavy.h5", "body_cm.obj", "--guides", "3", "-o", "d.h5")
    assert result.returncode == 2 and "Traceback" not in result.stderr, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "body_cm.obj" in lines[0] and "no strand can reach this body" in lines[0], lines
    assert "at 0.01 times its size" in lines[0] and "--body-units cm" in lines[0]
    assert "fit" not in result.stdout and not (tmp_path / "d.h5").exists()
    fine = hairinv(tmp_path, "detect", SAMPLES / "wavy.h5", "body_cm.obj", "--body-units", "cm", "--guides", "3",
                   "-o", "e.h5")
    assert fine.returncode == 0 and "roots lie" not in fine.stdout + fine.stderr, fine.stderr


def test_roots_away_from_a_body_they_can_reach_are_reported_and_the_run_goes_on(tmp_path):
    """The sample head lowered by 5 cm: the roots lie centimetres above it, within reach of the strands
    (30 cm long), so the run warns among the import's lines (ahead of the fit's), says which options to
    check, and goes on (exit 0); the head in place gets no such line."""
    import trimesh

    body = trimesh.load(SAMPLES / "body.obj", process=False)
    body.vertices = np.asarray(body.vertices) - [0.0, 0.05, 0.0]  # the sample is Y-up
    body.export(tmp_path / "body_low.obj")
    result = hairinv(tmp_path, "detect", SAMPLES / "wavy.h5", "body_low.obj", "--guides", "3", "-o", "d.h5")
    assert result.returncode == 0, result.stderr
    warning = [line for line in (result.stdout + result.stderr).splitlines() if "roots lie" in line]
    assert len(warning) == 1 and "body_low.obj" in warning[0] and "--body-scale" in warning[0], warning
    assert warning[0].index("roots lie") < (result.stdout + result.stderr).find("fit error")
    assert (tmp_path / "d.h5").exists()
    fine = hairinv(tmp_path, "detect", SAMPLES / "wavy.h5", SAMPLES / "body.obj", "--guides", "3", "-o", "e.h5")
    assert fine.returncode == 0 and "roots lie" not in fine.stdout + fine.stderr


@pytest.mark.parametrize("where", ["before", "after"])
def test_verbose_prints_the_settings_in_effect_and_the_stage_times(tmp_path, where):
    """-v, before the subcommand or after it: every setting of the sections the command uses, with the
    values the options, --set and the preset gave; then each stage's time, the fit's as /helices records it."""
    args = ["fit", SAMPLES / "wavy.h5", "--guides", "3", "--tolerance", "3e-4", "--set", "fit.max_elements=12",
            "--quality", "draft", "-o", "v.h5"]
    result = hairinv(tmp_path, *(["-v", *args] if where == "before" else [*args, "-v"]))
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    fit_line = next(line for line in lines if line.startswith("  [fit] "))
    assert "tolerance = 0.0003" in fit_line and "max_elements = 12" in fit_line
    draft = config.resolve("draft")
    assert f"max_iterations = {draft.fit.max_iterations}" in fit_line
    assert any(line.startswith("  [import] ") and "guides = 3" in line for line in lines)
    timing = next(line for line in lines if line.startswith("timings: "))
    with h5py.File(tmp_path / "v.h5", "r") as fh:
        seconds = float(fh["helices"].attrs["seconds"])
    assert f"fit {seconds:.3g} s" in timing and "whole command" in timing
    quiet = hairinv(tmp_path, *args[:-1], "w.h5", "-v", "-q")
    assert quiet.returncode == 0 and quiet.stdout == ""


def test_log_json_writes_one_object_per_event(tmp_path):
    """--log-json (before or after the subcommand): every stderr line a JSON object; start first, end last with
    the exit code; progress events with counts that add up; the human lines still on stdout; an error as
    an event with its exit code."""
    env = dict(ENV, HAIRINV_PROGRESS_SECONDS="0")
    run = subprocess.run([sys.executable, "-m", "hairinv_cli.main", "fit", str(SAMPLES / "wavy.h5"), "--guides", "3",
                          "-o", "f.h5", "--log-json"], cwd=tmp_path, env=env, capture_output=True, text=True,
                         timeout=600)
    assert run.returncode == 0, run.stderr
    events = [json.loads(line) for line in run.stderr.splitlines()]
    assert events[0]["event"] == "start" and events[0]["command"] == "fit"
    assert events[-1] == {**events[-1], "event": "end", "command": "fit", "exit": 0}
    progress = [e for e in events if e["event"] == "progress"]
    assert progress and progress[-1]["done"] == progress[-1]["total"] == 3
    assert all(0 <= e["done"] <= e["total"] for e in progress)
    messages = [e["text"] for e in events if e["event"] == "message"]
    assert messages == run.stdout.splitlines()
    bad = subprocess.run([sys.executable, "-m", "hairinv_cli.main", "--log-json", "fit", "missing.h5"],
                         cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    lines = bad.stderr.splitlines()
    assert bad.returncode == 2 and json.loads(lines[-1])["exit"] == 2
    assert json.loads(lines[1]) == {**json.loads(lines[1]), "event": "error", "text": "missing.h5: no such file"}
    assert "hairinv: error: missing.h5: no such file" in lines  # the one sentence, as without --log-json


def test_invert_and_info_count_the_same_contacts_carrying_force(tmp_path):
    """What invert prints ('N carry force') is what the stage file's summary says (hairinv info --json)."""
    import re

    run = hairinv(tmp_path, "invert", SAMPLES / "wavy.h5", SAMPLES / "body.obj", "--guides", "6", "-o", "m.h5")
    assert run.returncode == 0, run.stderr
    printed = int(re.search(r"(\d+) carry force", run.stdout).group(1))
    info = json.loads(hairinv(tmp_path, "info", "--json", "m.h5").stdout)
    assert info["groups"]["model"]["contacts_carrying_force"] == printed
    assert info["groups"]["contacts"]["carrying_force"] == printed
    with h5py.File(tmp_path / "m.h5", "r") as fh:
        normal = fh["model/force"][:, 0]
        assert printed == int((normal > fh["model"].attrs["carrying_threshold"]).sum())


def test_help_pages_state_the_defaults_in_effect(tmp_path):
    """The defaults the help pages state are those the default preset resolves to (read here from the settings,
    not from the help's own text), each length with its unit; simulate's --set example is a setting it uses."""
    import re

    settings = config.resolve()
    detect = " ".join(hairinv(tmp_path, "detect", "--help").stdout.split())
    stated = {key: value for key, value in re.findall(r"\[contacts\.(\w+); default ([0-9.]+mm)\]", detect)}
    assert stated.keys() == {"body_distance", "hair_distance"}, detect
    for key, text in stated.items():
        assert config.parse_length(text) == pytest.approx(getattr(settings.contacts, key), rel=1e-12)
    mu = float(re.search(r"default ([0-9.]+) each", detect).group(1))
    assert mu == settings.contacts.mu_body == settings.contacts.mu_hair
    assert f"[import.seed; default {settings.import_.seed}]" in detect and "default: every strand" in detect
    invert = " ".join(hairinv(tmp_path, "invert", "--help").stdout.split())
    assert float(re.search(r"\[solver\.gamma; default ([0-9.e-]+)\]", invert).group(1)) == settings.solver.gamma
    simulate = " ".join(hairinv(tmp_path, "simulate", "--help").stdout.split())
    assert "--set dynamics." in simulate and "--set fit." not in simulate
