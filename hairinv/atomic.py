"""The one atomic writer every output of hairinv goes through.

A file is written to a temporary file in its destination folder, then renamed
over the destination (``os.replace``, atomic on POSIX and Windows), so a reader
or a killed job sees either the old file or the complete new one. On any error,
interruptions included, the temporary file is removed and the destination is
left as it was.

A job killed outright (SIGKILL, a farm's time limit, the machine's OOM killer)
runs no clean-up, so its temporary file stays beside the destination. The
temporary's name says whose it is: ``.NAME.hairinv-PID-HOST.XXXXXXXX.tmp``
(NAME the destination's name, PID the writing process, HOST this machine's name,
XXXXXXXX random). The next write of the same destination removes the
temporaries of that destination whose writer is gone: written on this host by a
process that no longer exists, owned by this user (:func:`remove_stale_temporaries`).
A temporary another running process is writing, one written on another host
(a shared folder of a farm: its process cannot be seen from here), and any file
of another name are never touched. A recycled PID can only keep a stale
temporary a little longer, never remove a live one.
"""

from __future__ import annotations

import os
import re
import socket
import stat
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = ["atomic_path", "remove_stale_temporaries", "temporary_prefix", "write_bytes"]

#: Longest host name kept in a temporary's name (a file name holds 255 bytes; the rest is the destination's).
_HOST_CHARS = 40


def _host() -> str:
    """This machine's name as it appears in a temporary's name: letters, digits and ``-`` only."""
    try:
        name = socket.gethostname()
    except OSError:
        name = ""
    return re.sub(r"[^A-Za-z0-9-]", "-", name)[:_HOST_CHARS] or "localhost"


def temporary_prefix(path, pid: int | None = None) -> str:
    """The start of the name of a temporary file written for ``path`` by process ``pid`` (this one by default)
    on this host: ``.NAME.hairinv-PID-HOST.``; a random part and the suffix follow."""
    return f".{Path(path).name}.hairinv-{os.getpid() if pid is None else int(pid)}-{_host()}."


def _temporary_pattern(name: str) -> re.Pattern:
    """The names :func:`atomic_path` gives the temporaries of a destination called ``name`` (suffix ``.tmp``,
    or ``.tmp`` and the destination's extension); groups ``pid`` and ``host``."""
    extension = re.escape(Path(name).suffix)
    return re.compile(rf"\.{re.escape(name)}\.hairinv-(?P<pid>[0-9]+)-(?P<host>[A-Za-z0-9-]+)\.[A-Za-z0-9_]+"
                      rf"\.tmp(?:{extension})?")


def _running(pid: int) -> bool:
    """Whether process ``pid`` exists on this host (True when that cannot be told: a file is kept, not lost)."""
    if pid <= 0:
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (OSError, OverflowError):  # PermissionError: another user's process, alive
        return True
    return True


def remove_stale_temporaries(path) -> list[Path]:
    """Remove the temporary files a killed writer of ``path`` left beside it; return those removed.

    A file is removed only if all of these hold: its name is one :func:`atomic_path` gives the temporaries
    of ``path`` (:func:`temporary_prefix`); it was written on this host; its process no longer exists; it is
    a regular file (not a link) owned by this user. Anything else in the folder is left alone, and a file
    that cannot be removed is skipped: this never fails a write. Only on POSIX systems (on others no
    temporary is removed).
    """
    path = Path(path)
    if os.name != "posix":  # os.kill(pid, 0) is a liveness test on POSIX only
        return []
    pattern, host, me = _temporary_pattern(path.name), _host(), os.geteuid()
    removed = []
    try:
        names = os.listdir(path.parent)
    except OSError:
        return []
    for name in names:
        match = pattern.fullmatch(name)
        if match is None or match["host"] != host:
            continue
        candidate = path.parent / name
        try:
            info = os.lstat(candidate)
        except OSError:
            continue
        if not stat.S_ISREG(info.st_mode) or info.st_uid != me or _running(int(match["pid"])):
            continue
        try:
            candidate.unlink()
        except OSError:  # removed by another writer meanwhile, or not ours to remove
            continue
        removed.append(candidate)
    return removed


@contextmanager
def atomic_path(path, suffix: str = ".tmp") -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it over ``path`` if the block succeeds.

    Temporaries that killed writers of ``path`` left behind are removed first
    (:func:`remove_stale_temporaries`), before this one takes disk space.

    Parameters
    ----------
    path : path-like
        Destination; its folder must exist.
    suffix : str
        End of the temporary file's name: ``.tmp``, or ``.tmp`` and the destination's extension for writers
        that choose the file format from it (USD: ``".tmp.usda"``; a temporary with another suffix is not
        recognised as stale by later writes). The temporary file exists (empty) when the block starts.

    Raises
    ------
    OSError
        If the temporary file cannot be created or renamed; whatever the block raises, after
        removing the temporary file.
    """
    path = Path(path)
    remove_stale_temporaries(path)
    fd, name = tempfile.mkstemp(prefix=temporary_prefix(path), suffix=suffix, dir=path.parent)
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
        # mkstemp creates 0600; give the file the permissions a plain open() would
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_bytes(path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_path`)."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)
