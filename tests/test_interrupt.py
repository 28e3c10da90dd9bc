"""Ctrl-C: ``simulate`` and ``verify -o`` keep the frames computed, in a valid file marked interrupted that
``status`` and ``--if-stale`` take as stale; other commands leave nothing; every one exits 130 with one line.

The commands run as subprocesses sent a real SIGINT once their output shows they are under way.

Runtime: about 30-50 s warm (one small inversion, a few short simulations and one inversion interrupted).
"""

from __future__ import annotations

import re
import shutil
import signal
import subprocess
import sys
import threading
import time

import h5py
import numpy as np
import pytest

from conftest import inverted_settled, ENV, SAMPLES, hairinv, snapshot
from hairinv import simulation, stages
from hairinv._trimesh import held_interrupt
from hairinv.errors import InputError, Interrupted
from hairinv.staleness import check_current, status

INTERRUPTED = 130


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    """``hairinv invert settled.h5 body.obj --guides 12 --target zero``: a groom at rest (about 0.01 s of
    computing per frame of the still scene)."""
    return inverted_settled(tmp_path_factory.mktemp("interrupt"))


def interrupted(folder, args, sign: str, stream: str = "stdout", env=None,
                sent=signal.SIGINT) -> subprocess.CompletedProcess:
    """``hairinv *args`` in ``folder``, sent SIGINT (or ``sent``) once a line of ``stream`` starts with ``sign``."""
    process = subprocess.Popen(
        [sys.executable, "-m", "hairinv_cli.main", *map(str, args)], cwd=folder, env={**ENV, **(env or {})},
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        # a shell without job control starts background jobs with SIGINT ignored: give the command the default
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    lines = {"stdout": [], "stderr": []}
    seen = threading.Event()

    def read(name):
        for line in getattr(process, name):
            lines[name].append(line)
            if name == stream and line.startswith(sign):
                seen.set()

    readers = [threading.Thread(target=read, args=(name,)) for name in lines]
    for reader in readers:
        reader.start()
    while not seen.wait(0.05):
        assert process.poll() is None, f"it ended before {sign!r}: {''.join(lines['stderr'])}"
    process.send_signal(sent)
    process.wait(timeout=120)
    for reader in readers:
        reader.join()
    return subprocess.CompletedProcess(args, process.returncode, "".join(lines["stdout"]), "".join(lines["stderr"]))


def test_simulate_keeps_the_frames_computed_when_interrupted(model):
    result = interrupted(model, ["simulate", "model.h5", "--seconds", "10", "-o", "out.h5"], "frame    1")
    assert result.returncode == INTERRUPTED, result.stderr
    assert "Traceback" not in result.stderr
    line = result.stderr.strip().splitlines()
    assert len(line) == 1, result.stderr
    said = re.fullmatch(r"hairinv: interrupted after (\d+) of 301 frames \((\S+) s of 10 s\): the (\d+) frames "
                        r"computed are in out\.h5, marked interrupted", line[0])
    assert said and said[1] == said[3], line[0]
    done = int(said[1])
    assert 2 <= done < 301  # frame 1 was printed, so frames 0 and 1 at least are whole
    assert float(said[2]) == pytest.approx((done - 1) / 30, abs=1e-3)
    # the frames printed before the interrupt are those written, whole, in a file every reader accepts
    printed = re.findall(r"^frame +(\d+) ", result.stdout, flags=re.M)
    assert [int(k) for k in printed] == list(range(done))
    stage = stages.read_stage(model / "out.h5")
    frames = stage[stages.FRAMES]
    assert len(frames["time"]) == done and np.allclose(frames["time"], np.arange(done) / 30, atol=1e-12)
    assert frames["omega"].shape[0] == frames["root"].shape[0] == frames["displacement"].shape[0] == done
    assert bool(frames.attrs["interrupted"]) and not bool(frames.attrs["stopped"])
    assert int(frames.attrs["frames_requested"]) == 301
    assert frames["displacement"].max() < 1e-6  # m: the inverted groom stays still, as far as it went
    assert sorted(p.name for p in model.iterdir() if p.name.startswith(".")) == []  # no temporary left

    # stale, whatever its record says: status exits 1 naming the interruption, --if-stale computes it again
    current, reasons = check_current(model / "out.h5", _record(model))
    assert not current and reasons == [f"its run was interrupted after {done} of 301 frames"]
    said = hairinv(model, "status", "out.h5")
    assert said.returncode == 1 and f"out.h5: stale: its run was interrupted after {done} of 301 frames" in said.stdout
    again = hairinv(model, "simulate", "model.h5", "--seconds", "10", "-o", "out.h5", "--if-stale")
    assert again.returncode == 0, again.stderr
    assert "out.h5 is stale: its run was interrupted" in again.stdout and "wrote out.h5" in again.stdout
    whole = stages.read_stage(model / "out.h5")[stages.FRAMES]
    assert len(whole["time"]) == 301 and not bool(whole.attrs["interrupted"])
    assert int(whole.attrs["frames_requested"]) == 301
    assert hairinv(model, "status", "out.h5").returncode == 0


def _record(folder) -> dict:
    """The record ``hairinv simulate model.h5 --seconds 10`` writes (the one out.h5 holds)."""
    run = simulation.load(folder / "model.h5", seconds=10)
    return simulation.simulate_record(run, "still")


def test_verify_interrupted_gives_no_verdict_and_keeps_its_frames(model):
    result = interrupted(model, ["verify", "model.h5", "--seconds", "10", "-o", "v.h5"], "still: ", "stderr",
                         env={"HAIRINV_PROGRESS_SECONDS": "0"})
    assert result.returncode == INTERRUPTED, result.stderr
    assert "Traceback" not in result.stderr and "PASS" not in result.stdout
    line = [x for x in result.stderr.splitlines() if x.startswith("hairinv:")]
    assert len(line) == 1 and result.stderr.strip().splitlines()[-1] == line[0], result.stderr
    said = re.fullmatch(r"hairinv: verify interrupted after (\d+) of 301 frames \(\S+ s of 10 s\), no verdict: no "
                        r"strand point had moved more than 0\.1 mm; the (\d+) frames computed are in v\.h5, marked "
                        r"interrupted", line[0])
    assert said and said[1] == said[2], line[0]
    stage = stages.read_stage(model / "v.h5")
    frames = stage[stages.FRAMES]
    assert len(frames["time"]) == int(said[1]) and bool(frames.attrs["interrupted"])
    strands = len(stage[stages.HELICES]["offsets"]) - 1
    assert frames["strand_displacement"].shape == (int(said[1]), strands)
    current, reasons = status(model / "v.h5")
    assert not current and reasons == [f"its run was interrupted after {said[1]} of 301 frames"]


def test_invert_interrupted_leaves_nothing(tmp_path):
    """Ctrl-C in the contact solve: one line, exit 130, no output and no temporary file."""
    shutil.copyfile(SAMPLES / "wavy.h5", tmp_path / "wavy.h5")
    shutil.copyfile(SAMPLES / "body.obj", tmp_path / "body.obj")
    before = snapshot(tmp_path)
    result = interrupted(tmp_path, ["invert", "wavy.h5", "body.obj", "-o", "model.h5"], "invert: ", "stderr",
                         env={"HAIRINV_PROGRESS_SECONDS": "0"})
    assert result.returncode == INTERRUPTED, result.stderr
    assert "Traceback" not in result.stderr
    assert result.stderr.strip().splitlines()[-1] == "hairinv: interrupted; no output was written"
    assert [x for x in result.stderr.splitlines() if x.startswith("hairinv")] == [
        "hairinv: interrupted; no output was written"]
    assert snapshot(tmp_path) == before


def test_run_interrupted_in_process_holds_whole_frames(model, tmp_path):
    """The library call: Ctrl-C (here raised from the frame callback) after frame 3 raises Interrupted, whose
    frames are the 4 done; ``simulate`` writes them, marked interrupted, before the interrupt goes on."""
    def stop(log):
        if log.index == 3:
            raise KeyboardInterrupt

    with pytest.raises(Interrupted) as caught:
        simulation.simulate(model / "model.h5", seconds=1, fps=25, output=tmp_path / "cut.h5", on_frame=stop)
    frames = caught.value.result
    assert frames.interrupted and not frames.stopped and frames.requested == 26
    assert len(frames.log) == 4 and frames.omega.shape[0] == frames.root.shape[0] == len(frames.time) == 4
    written = stages.read_stage(tmp_path / "cut.h5")[stages.FRAMES]
    assert np.allclose(written["time"], np.arange(4) / 25, atol=1e-12) and bool(written.attrs["interrupted"])
    assert np.array_equal(written["omega"], frames.omega)
    assert isinstance(caught.value, KeyboardInterrupt)  # code that does not know it stops as on any Ctrl-C


def test_a_stopped_check_is_not_interrupted(model):
    """``stopped`` keeps its meaning: a check that stopped at its first frame past the tolerance is whole."""
    verdict, run = simulation.verify(model / "model.h5", seconds=0.5, init="naive")
    assert not verdict.passed and run.frames.stopped and not run.frames.interrupted
    group = run.frames.group({}, [])
    assert group.attrs["stopped"] and not group.attrs["interrupted"]
    assert group.attrs["frames_requested"] == 16 > len(run.frames.log)


@pytest.fixture
def python_handlers():
    """Python's own Ctrl-C handler in this process while the test runs, the handlers found put back after: a
    process started as a background job of a shell without job control (``make test &`` in a script, some CI
    runners) starts with SIGINT ignored, and Python then installs no handler."""
    found = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    if found[signal.SIGINT] == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    for sig, handler in found.items():
        signal.signal(sig, handler)


def test_a_held_interrupt_comes_once_the_block_ends(python_handlers):
    """What trimesh's import runs in: its ``except BaseException`` cannot swallow a Ctrl-C held outside it."""
    reached = []
    before = signal.getsignal(signal.SIGINT)  # (a command run in this process may have put the CLI's own there)
    assert callable(before)
    with pytest.raises(KeyboardInterrupt):
        with held_interrupt():
            signal.raise_signal(signal.SIGINT)
            time.sleep(0.01)  # a held signal raises nothing here
            reached.append(True)
    assert reached == [True]
    assert signal.getsignal(signal.SIGINT) is before  # the handler is given back


def test_an_interrupt_a_library_swallowed_still_exits_130(monkeypatch, capsys, python_handlers):
    """A command whose library swallowed Ctrl-C (numba compiling, inside a ctypes callback) runs to its end:
    it still exits 130, with one line saying so."""
    from hairinv_cli.main import handle_errors

    monkeypatch.setattr(sys, "excepthook", sys.excepthook)
    monkeypatch.setattr(sys, "unraisablehook", sys.unraisablehook)

    @handle_errors
    def swallowing():
        try:
            signal.raise_signal(signal.SIGINT)
            time.sleep(0.01)
        except BaseException:  # as a library may
            pass
        return "done"

    try:
        with pytest.raises(SystemExit) as exit:
            swallowing()
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    assert exit.value.code == INTERRUPTED
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["hairinv: interrupted, but Ctrl-C came where it could not stop the command (in compiled code): "
                   "it ran to its end, and what it wrote is complete"]


@pytest.mark.parametrize("attrs, fragment", [
    ({"frames_requested": 1}, "frames_requested is 1, fewer than the 4 frames it holds"),
    ({"frames_requested": -3}, "frames_requested is -3; it must be an integer >= 0"),
    ({"interrupted": "yes"}, "interrupted is 'yes'; it must be true or false"),
])
def test_the_added_attributes_are_checked_where_the_file_is_read(model, tmp_path, attrs, fragment):
    """``interrupted`` and ``frames_requested`` of ``/frames`` are checked as every attribute hairinv reads."""
    def stop(log):
        if log.index == 3:
            raise KeyboardInterrupt

    path = tmp_path / "cut.h5"
    with pytest.raises(Interrupted):
        simulation.simulate(model / "model.h5", seconds=1, fps=25, output=path, on_frame=stop)
    with h5py.File(path, "r+") as fh:
        fh["frames"].attrs.update(attrs)
    with pytest.raises(InputError) as refused:
        stages.read_stage(path)
    assert str(refused.value) == f"{path}: /frames attribute {fragment}"
    with pytest.raises(InputError):
        stages.check_metadata(path)  # what `hairinv status` checks


def test_simulate_stopped_by_a_farm_manager_keeps_its_frames(model):
    """SIGTERM, as Deadline, Tractor or Slurm stop a task: what Ctrl-C keeps, said as terminated, exit 143."""
    result = interrupted(model, ["simulate", "model.h5", "--seconds", "10", "-o", "term.h5"], "frame    1",
                         sent=signal.SIGTERM)
    assert result.returncode == 143, result.stderr
    line = result.stderr.strip().splitlines()
    assert len(line) == 1 and "Traceback" not in result.stderr, result.stderr
    said = re.fullmatch(r"hairinv: terminated \(SIGTERM\) after (\d+) of 301 frames \((\S+) s of 10 s\): the (\d+) "
                        r"frames computed are in term\.h5, marked interrupted", line[0])
    assert said and said[1] == said[3], line[0]
    frames = stages.read_stage(model / "term.h5")[stages.FRAMES]
    assert len(frames["time"]) == int(said[1]) >= 2 and bool(frames.attrs["interrupted"])


def test_invert_stopped_by_a_farm_manager_leaves_nothing(tmp_path):
    """SIGTERM in the contact solve: one line, exit 143, no output and no temporary file."""
    shutil.copyfile(SAMPLES / "wavy.h5", tmp_path / "wavy.h5")
    shutil.copyfile(SAMPLES / "body.obj", tmp_path / "body.obj")
    before = snapshot(tmp_path)
    result = interrupted(tmp_path, ["invert", "wavy.h5", "body.obj", "-o", "model.h5"], "invert: ", "stderr",
                         env={"HAIRINV_PROGRESS_SECONDS": "0"}, sent=signal.SIGTERM)
    assert result.returncode == 143, result.stderr
    assert "Traceback" not in result.stderr
    assert [x for x in result.stderr.splitlines() if x.startswith("hairinv")] == [
        "hairinv: terminated (SIGTERM); no output was written"]
    assert snapshot(tmp_path) == before
