"""The atomic writer's temporaries: named by their writer, and removed by the next write of the same
destination once that writer is gone (hairinv.atomic). A real SIGKILLed run is in test_hostile_stages.py;
here the folder is laid out by hand, with real processes for the dead and the live writers.

Runtime: well under a second (no numerical code).
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from hairinv import atomic
from hairinv.atomic import atomic_path, remove_stale_temporaries, temporary_prefix, write_bytes

pytestmark = pytest.mark.skipif(os.name != "posix", reason="stale temporaries are recognised on POSIX only")


def dead_pid() -> int:
    """The PID of a process that has ended (and been waited for)."""
    process = subprocess.Popen([sys.executable, "-c", "pass"])
    process.wait()
    return process.pid


@pytest.fixture
def live_pid():
    """The PID of a running process of this user, ended after the test."""
    process = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)"])
    yield process.pid
    process.kill()
    process.wait()


def temporary(folder, target: str, pid: int, host: str | None = None, suffix: str = ".tmp", random="k3x_9q2a"):
    """A file named as the temporary of ``target`` written by ``pid`` on ``host`` (this one by default)."""
    prefix = temporary_prefix(folder / target, pid)
    if host is not None:
        prefix = f".{target}.hairinv-{pid}-{host}."
    path = folder / f"{prefix}{random}{suffix}"
    path.write_bytes(b"part of an HDF5 file")
    return path


def test_the_temporary_is_named_by_its_writer(tmp_path):
    target = tmp_path / "out.h5"
    with atomic_path(target) as tmp:
        assert tmp.parent == tmp_path
        assert tmp.name.startswith(f".out.h5.hairinv-{os.getpid()}-{atomic._host()}.") and tmp.name.endswith(".tmp")
        assert tmp.exists() and not target.exists()
        tmp.write_bytes(b"new")
    assert target.read_bytes() == b"new" and os.listdir(tmp_path) == ["out.h5"]
    with atomic_path(tmp_path / "scene.usda", suffix=".tmp.usda") as tmp:
        assert atomic._temporary_pattern("scene.usda").fullmatch(tmp.name)
        tmp.write_text("#usda 1.0\n")


def test_the_next_write_removes_only_dead_writers_temporaries(tmp_path, live_pid):
    dead = dead_pid()
    stale = [temporary(tmp_path, "out.h5", dead), temporary(tmp_path, "out.h5", dead, random="a1b2c3d4"),
             temporary(tmp_path, "scene.usda", dead, suffix=".tmp.usda")]
    kept = [
        temporary(tmp_path, "out.h5", live_pid),  # another process is writing it now
        temporary(tmp_path, "out.h5", os.getpid()),  # this process (another thread) is writing it
        temporary(tmp_path, "out.h5", dead, host="render-node-7"),  # another host: its process is not ours to see
        temporary(tmp_path, "other.h5", dead),  # another destination
        temporary(tmp_path, "out", dead),  # a destination whose name starts the same
    ]
    for name in (".out.h5.k3x_9q2a.tmp",  # an older hairinv's name: whose it was cannot be told
                 f"out.h5.hairinv-{dead}-{atomic._host()}.k3x_9q2a.tmp",  # not hidden: the user's
                 f".out.h5.hairinv-{dead}-{atomic._host()}.k3x_9q2a.tmp.bak",
                 "notes.txt"):
        (tmp_path / name).write_text("the user's")
        kept.append(tmp_path / name)
    link = tmp_path / f".out.h5.hairinv-{dead}-{atomic._host()}.linklink.tmp"
    link.symlink_to(tmp_path / "notes.txt")  # a link is never ours
    folder = tmp_path / f".out.h5.hairinv-{dead}-{atomic._host()}.folder00.tmp"
    folder.mkdir()
    kept += [link, folder]
    contents = {p: p.read_bytes() for p in kept if p.is_file() and not p.is_symlink()}

    write_bytes(tmp_path / "out.h5", b"complete")

    assert (tmp_path / "out.h5").read_bytes() == b"complete"
    assert not stale[0].exists() and not stale[1].exists()
    assert stale[2].exists()  # scene.usda's, until scene.usda is written
    assert all(p.exists() or p.is_symlink() for p in kept)
    assert {p: p.read_bytes() for p in contents} == contents
    assert link.is_symlink() and folder.is_dir()
    with atomic_path(tmp_path / "scene.usda", suffix=".tmp.usda") as tmp:
        tmp.write_text("#usda 1.0\n")
    assert not stale[2].exists()
    assert sorted(os.listdir(tmp_path)) == sorted(["out.h5", "scene.usda", *(p.name for p in kept)])


def test_a_temporary_another_user_owns_is_kept(tmp_path, monkeypatch):
    path = temporary(tmp_path, "out.h5", dead_pid())
    monkeypatch.setattr(atomic.os, "geteuid", lambda: os.stat(path).st_uid + 1)
    assert remove_stale_temporaries(tmp_path / "out.h5") == [] and path.exists()
    monkeypatch.undo()
    assert remove_stale_temporaries(tmp_path / "out.h5") == [path] and not path.exists()


def test_a_failed_write_removes_its_own_temporary_and_keeps_the_old_file(tmp_path):
    target = tmp_path / "out.h5"
    target.write_bytes(b"old")
    with pytest.raises(RuntimeError), atomic_path(target) as tmp:
        tmp.write_bytes(b"half")
        raise RuntimeError("interrupted")
    assert target.read_bytes() == b"old" and os.listdir(tmp_path) == ["out.h5"]
