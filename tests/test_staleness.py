"""Make-style staleness: the command record, --if-stale, hairinv status and the sample Makefile.

A stage file records what made it (subcommand, each input's SHA-256, settings, options). Whether a file was
made again or left as it was is told by its inode: hairinv writes a new file and renames it into place, so
a file made again has a new inode; a current one is only touched (same inode, newer modification time).

Runtime: about 40-70 s with a warm numba cache (make builds two grooms of 3 guide strands, several times).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import time

import h5py
import numpy as np
import pytest

from conftest import ENV, ROOT, SAMPLES, hairinv
from hairinv import config, stages
from hairinv.errors import InputError
from hairinv.staleness import command_record, differences, status

PYTHON_HAIRINV = f"{os.sys.executable} -m hairinv_cli.main"


def inode(path):
    return os.stat(path).st_ino


def test_differences_name_what_changed(tmp_path):
    a, b = tmp_path / "a.h5", tmp_path / "b.obj"
    shutil.copyfile(SAMPLES / "wavy.h5", a)
    shutil.copyfile(SAMPLES / "body.obj", b)
    settings = config.resolve("default")
    old = command_record("invert", [a, b], settings, ("fit", "solver"), {"x": 1})
    assert differences(old, command_record("invert", [a, b], settings, ("fit", "solver"), {"x": 1})) == []
    changed = config.apply(settings, {"fit": {"tolerance": 1e-4}})
    assert differences(old, command_record("invert", [a, b], changed, ("fit", "solver"), {"x": 1})) == [
        "setting fit.tolerance was 0.0002, now 0.0001"]
    b.write_text(b.read_text() + "\n# edited\n")
    assert differences(old, command_record("invert", [a, b], settings, ("fit", "solver"), {"x": 2})) == [
        "input b.obj changed", "option x was 1, now 2"]
    assert differences(old, command_record("invert", [a, None], settings, ("fit", "solver"), {"x": 1})) == [
        "input b.obj was given then"]
    assert differences(old, command_record("detect", [a, b], settings, ("fit",)))[0].startswith("it was written by")


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    folder = tmp_path_factory.mktemp("stale")
    shutil.copyfile(SAMPLES / "wavy.h5", folder / "wavy.h5")
    shutil.copyfile(SAMPLES / "body.obj", folder / "body.obj")
    result = hairinv(folder, "invert", "wavy.h5", "body.obj", "--guides", "3", "-o", "m.h5")
    assert result.returncode == 0, result.stderr
    return folder


def test_the_record_is_in_the_file(model):
    with h5py.File(model / "m.h5", "r") as fh:
        record = json.loads(fh.attrs["command"])
    assert record["subcommand"] == "invert"
    assert [r["sha256"] for r in record["inputs"]] == [stages.sha256_file(model / n) for n in ("wavy.h5", "body.obj")]
    assert record["settings"]["import"]["guides"] == 3
    assert set(record["settings"]) == {"import", "body", "fit", "contacts", "material", "solver"}


def test_if_stale_leaves_a_current_output_and_remakes_a_stale_one(model):
    before = inode(model / "m.h5")
    old_time = time.time() - 3600
    os.utime(model / "m.h5", (old_time, old_time))
    again = hairinv(model, "invert", "wavy.h5", "body.obj", "--guides", "3", "-o", "m.h5", "--if-stale")
    assert again.returncode == 0 and "is current" in again.stdout and "read" not in again.stdout
    assert inode(model / "m.h5") == before and os.stat(model / "m.h5").st_mtime > old_time + 3000
    other = hairinv(model, "invert", "wavy.h5", "body.obj", "--guides", "3", "--mu", "0.5", "-o", "m2.h5")
    assert other.returncode == 0
    shutil.copyfile(model / "m.h5", model / "m3.h5")
    stale = hairinv(model, "invert", "wavy.h5", "body.obj", "--guides", "3", "--mu", "0.5", "-o", "m3.h5",
                    "--if-stale")
    assert stale.returncode == 0, stale.stderr
    assert "m3.h5 is stale: setting contacts.mu_body was 0.3, now 0.5; setting contacts.mu_hair" in stale.stdout
    with h5py.File(model / "m3.h5", "r") as new, h5py.File(model / "m2.h5", "r") as reference:
        assert (new["model/force"][()] == reference["model/force"][()]).all()


def test_status_of_a_current_a_stale_and_an_unreadable_file(model, tmp_path):
    ok = hairinv(model, "status", "m.h5")
    assert ok.returncode == 0 and ok.stdout.strip() == "m.h5: current (its arrays were not read; --check checks them too)"
    checked = hairinv(model, "status", "m.h5", "--check")
    assert checked.returncode == 0 and checked.stdout.strip() == "m.h5: current"
    # moved to another folder: the inputs are found where they were recorded (relative to the working folder)
    shutil.copyfile(model / "m.h5", tmp_path / "m.h5")
    assert hairinv(model, "status", tmp_path / "m.h5").returncode == 0
    # named explicitly, an edited copy of the body is stale, and named
    shutil.copyfile(model / "body.obj", tmp_path / "body.obj")
    with open(tmp_path / "body.obj", "a") as fh:
        fh.write("# edited\n")
    stale = hairinv(model, "status", "m.h5", "wavy.h5", tmp_path / "body.obj")
    assert stale.returncode == 1 and "body.obj changed since" in stale.stdout
    changed = hairinv(model, "status", "m.h5", "--set", "import.guides=3", "--set", "solver.gamma=0.5")
    assert changed.returncode == 1 and changed.stdout.strip().splitlines() == [
        f"m.h5: stale: setting solver.gamma was {config.SolverSettings().gamma!r}, now 0.5"]
    same = hairinv(model, "status", "m.h5", "--set", "import.guides=3")
    assert same.returncode == 0
    unreadable = tmp_path / "broken.h5"
    unreadable.write_bytes(b"not hdf5")
    bad = hairinv(tmp_path, "status", "broken.h5")
    assert bad.returncode == 2 and "broken.h5" in bad.stderr and len(bad.stderr.strip().splitlines()) == 1
    old = hairinv(tmp_path, "status", SAMPLES / "wavy.h5")
    assert old.returncode == 2 and "records no command" in old.stderr


class DatasetReads:
    """Every read of an h5py dataset's values in this process (through any of h5py's ways of reading), as
    (dataset name, selection, number of values read)."""

    def __init__(self, monkeypatch):
        self.reads = []
        real_getitem, real_read_direct = h5py.Dataset.__getitem__, h5py.Dataset.read_direct
        real_array = h5py.Dataset.__array__

        def getitem(dataset, selection, *args, **kwargs):
            value = real_getitem(dataset, selection, *args, **kwargs)
            self.reads.append((dataset.name, selection, int(np.size(value))))
            return value

        def read_direct(dataset, dest, source_sel=None, dest_sel=None):
            self.reads.append((dataset.name, source_sel, int(np.size(dest))))
            return real_read_direct(dataset, dest, source_sel, dest_sel)

        def array(dataset, *args, **kwargs):
            value = real_array(dataset, *args, **kwargs)
            self.reads.append((dataset.name, "__array__", int(np.size(value))))
            return value

        monkeypatch.setattr(h5py.Dataset, "__getitem__", getitem)
        monkeypatch.setattr(h5py.Dataset, "read_direct", read_direct)
        monkeypatch.setattr(h5py.Dataset, "__array__", array)


def test_status_reads_no_array_of_the_stage_file(model, tmp_path, monkeypatch):
    """status reads the file's attributes, its datasets' shapes and the two ends of each offsets, and no
    other value, however large the file; --check (as every other reader) reads every dataset whole."""
    shutil.copyfile(model / "m.h5", tmp_path / "m.h5")
    shutil.copyfile(model / "m.h5", tmp_path / "huge.h5")
    with h5py.File(tmp_path / "huge.h5", "r+") as fh:
        # 64 GB declared and never written: reading it would take minutes, or more memory than the machine has
        del fh["model/residual_history"]
        fh.create_dataset("model/residual_history", shape=(4 * 10**9, 2), dtype="f8")
    with h5py.File(tmp_path / "m.h5", "r") as fh:
        datasets = []
        fh.visititems(lambda name, obj: datasets.append("/" + name) if isinstance(obj, h5py.Dataset) else None)
    monkeypatch.chdir(model)  # the inputs are recorded relative to the folder the model was made in
    reads = DatasetReads(monkeypatch)
    assert status(tmp_path / "huge.h5") == (True, [])
    values = [(name, size) for name, _, size in reads.reads]
    assert sorted(values) == [("/curves/offsets", 1)] * 2 + [("/helices/offsets", 1)] * 2  # first and last
    with pytest.raises(InputError, match="GB of memory to read"):
        status(tmp_path / "huge.h5", check_data=True)
    del reads.reads[:]
    assert status(tmp_path / "m.h5", check_data=True) == (True, [])
    assert {name for name, _, _ in reads.reads} == set(datasets)


def _make(folder, *args):
    run = subprocess.run(["make", "-f", str(ROOT / "samples" / "Makefile"), f"HAIRINV={PYTHON_HAIRINV}",
                          "SAMPLES=in", "OUT=out", "GROOMS=wavy straight", "OPTIONS=--guides 3", *args],
                         cwd=folder, env=ENV, capture_output=True, text=True, timeout=900)
    assert run.returncode == 0, run.stdout + run.stderr
    return run


def test_the_sample_makefile_rebuilds_only_what_changed(tmp_path):
    (tmp_path / "in").mkdir()
    for name in ("wavy.h5", "straight.h5", "body.obj"):
        shutil.copyfile(SAMPLES / name, tmp_path / "in" / name)
    first = _make(tmp_path, "-j2")
    outputs = sorted((tmp_path / "out").iterdir())
    assert [p.name for p in outputs] == sorted(f"{g}.{s}" for g in ("wavy", "straight")
                                               for s in ("fit.h5", "contacts.h5", "model.h5", "usda", "json",
                                                         "usda.hairinv.json", "json.hairinv.json"))
    assert "hairinv_cli.main invert" in first.stdout
    inodes = {p.name: inode(p) for p in outputs}
    # the second run does nothing
    second = _make(tmp_path)
    assert "hairinv" not in second.stdout and "Nothing to be done" in second.stdout
    # a touched input: only its chain runs, and finds every stage file current (none made again)
    os.utime(tmp_path / "in" / "wavy.h5")
    touched = _make(tmp_path)
    assert "wavy" in touched.stdout and "straight" not in touched.stdout
    assert {p.name: inode(p) for p in sorted((tmp_path / "out").iterdir())} == inodes
    # another setting for every groom, forced: each fit is made again (the settings differ)...
    forced = _make(tmp_path, "-B", "OPTIONS=--guides 4")
    assert forced.stdout.count("fit ") == 2
    assert all(inode(tmp_path / "out" / f"{g}.fit.h5") != inodes[f"{g}.fit.h5"] for g in ("wavy", "straight"))
    # ...and forced again with the same ones, nothing is
    kept = {p.name: inode(p) for p in (tmp_path / "out").iterdir() if p.suffix == ".h5"}
    _make(tmp_path, "-B", "OPTIONS=--guides 4")
    assert {p.name: inode(p) for p in (tmp_path / "out").iterdir() if p.suffix == ".h5"} == kept


def test_export_if_stale_keeps_its_record_beside_the_output(model):
    """An export's record lives in OUTPUT.hairinv.json with the output's SHA-256: a current export is left as
    it is; other options, or an output written over by another export, make it again."""
    usd, sidecar = model / "m.usda", model / "m.usda.hairinv.json"
    first = hairinv(model, "export", "m.h5", "-o", "m.usda", "--if-stale")
    assert first.returncode == 0, first.stderr
    record = json.loads(sidecar.read_text())
    assert record["subcommand"] == "export" and record["output_sha256"] == stages.sha256_file(usd)
    # the stage file and the body it records (USD holds the body)
    assert [r and r["name"] for r in record["inputs"]] == ["m.h5", "body.obj"]
    before = inode(usd)
    again = hairinv(model, "export", "m.h5", "-o", "m.usda", "--if-stale")
    assert again.returncode == 0 and "is current" in again.stdout and inode(usd) == before
    other = hairinv(model, "export", "m.h5", "-o", "m.usda", "--basis", "catmull-rom", "--if-stale")
    assert other.returncode == 0 and "option basis was None, now 'catmull-rom'" in other.stdout
    assert inode(usd) != before and 'uniform token type = "cubic"' in usd.read_text()
    assert hairinv(model, "status", "m.usda").stdout.strip() == "m.usda: current"
    # written over without --if-stale: the record no longer describes the file, so it is made again
    assert hairinv(model, "export", "m.h5", "-o", "m.usda").returncode == 0
    overwritten = hairinv(model, "status", "m.usda")
    assert overwritten.returncode == 1 and "written again or changed since" in overwritten.stdout
    stale = hairinv(model, "export", "m.h5", "-o", "m.usda", "--basis", "catmull-rom", "--if-stale")
    assert stale.returncode == 0 and "written again or changed since" in stale.stdout
    assert 'uniform token type = "cubic"' in usd.read_text()
    lone = hairinv(model, "status", "body.obj")
    assert lone.returncode == 2 and "neither a hairinv stage file nor an export" in lone.stderr
    # a file of the user's where the record would go is not written over
    (model / "m.json.hairinv.json").write_text("my notes\n")
    refused = hairinv(model, "export", "m.h5", "-o", "m.json", "--if-stale")
    assert refused.returncode == 2 and "m.json.hairinv.json" in refused.stderr
    assert len(refused.stderr.strip().splitlines()) == 1 and not (model / "m.json").exists()
    assert (model / "m.json.hairinv.json").read_text() == "my notes\n"


def test_verify_if_stale_reads_the_verdict_back(model):
    """verify -o records its check; with --if-stale a current output is not simulated again and gives the
    same verdict, table and exit code."""
    args = ("verify", "m.h5", "--seconds", "0.2", "--full", "-o", "v.h5")
    first = hairinv(model, *args)
    assert first.returncode in (0, 1), first.stderr
    before = inode(model / "v.h5")
    with h5py.File(model / "v.h5", "r") as fh:
        per_strand = fh["frames/strand_displacement"][()]
        assert per_strand.shape == (len(fh["frames/time"]), 3)
        assert (per_strand.max(axis=1) == fh["frames/displacement"][()]).all()
    again = hairinv(model, *args, "--if-stale")
    assert again.returncode == first.returncode and inode(model / "v.h5") == before
    verdict = [line for line in first.stdout.splitlines() if not line.startswith(("init ", "wrote "))]
    assert [line for line in again.stdout.splitlines()
            if "is current" not in line and "verdict recorded" not in line] == verdict
    tighter = hairinv(model, *args[:-2], "--tolerance", "1um", "-o", "v.h5", "--if-stale")
    assert "option tolerance_m was 0.0001, now 1e-06" in tighter.stdout and inode(model / "v.h5") != before
    lonely = hairinv(model, "verify", "m.h5", "--if-stale")
    assert lonely.returncode == 2 and "--if-stale needs -o" in lonely.stderr
