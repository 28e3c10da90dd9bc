"""Ctrl-C: a command leaves nothing and exits 130 with one line, even where a library swallows the interrupt.

The commands run as subprocesses sent a real SIGINT once their output shows they are under way.

Runtime: about 10 s warm (one inversion interrupted).
"""

from __future__ import annotations

import shutil
import signal
import subprocess
import sys
import threading
import time

import pytest

from conftest import ENV, SAMPLES, snapshot
from hairinv._trimesh import held_interrupt

INTERRUPTED = 130


def interrupted(folder, args, sign: str, stream: str = "stdout", env=None) -> subprocess.CompletedProcess:
    """``hairinv *args`` in ``folder``, sent SIGINT once a line of ``stream`` starts with ``sign``."""
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
    process.send_signal(signal.SIGINT)
    process.wait(timeout=120)
    for reader in readers:
        reader.join()
    return subprocess.CompletedProcess(args, process.returncode, "".join(lines["stdout"]), "".join(lines["stderr"]))


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


def test_a_held_interrupt_comes_once_the_block_ends():
    """What trimesh's import runs in: its ``except BaseException`` cannot swallow a Ctrl-C held outside it."""
    reached = []
    with pytest.raises(KeyboardInterrupt):
        with held_interrupt():
            signal.raise_signal(signal.SIGINT)
            time.sleep(0.01)  # a held signal raises nothing here
            reached.append(True)
    assert reached == [True]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_an_interrupt_a_library_swallowed_still_exits_130(monkeypatch, capsys):
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
