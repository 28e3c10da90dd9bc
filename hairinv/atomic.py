"""The one atomic writer every output of hairinv goes through.

A file is written to a temporary file in its destination folder, then renamed
over the destination (``os.replace``, atomic on POSIX and Windows), so a reader
or a killed job sees either the old file or the complete new one. On any error,
interruptions included, the temporary file is removed and the destination is
left as it was.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = ["atomic_path", "write_bytes"]


@contextmanager
def atomic_path(path, suffix: str = ".tmp") -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it over ``path`` if the block succeeds.

    Parameters
    ----------
    path : path-like
        Destination; its folder must exist.
    suffix : str
        End of the temporary file's name, for writers that choose the file format from the
        extension (USD: ``".tmp.usda"``). The temporary file exists (empty) when the block starts.

    Raises
    ------
    OSError
        If the temporary file cannot be created or renamed; whatever the block raises, after
        removing the temporary file.
    """
    path = Path(path)
    fd, name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix, dir=path.parent)
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
