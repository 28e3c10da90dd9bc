"""Typed errors raised by the library; the CLI maps them to exit codes.

``InputError`` (exit 2) is a problem with something the user gave us: a file,
an option, a setting. ``RunError`` (exit 1) is a run that started on valid
input and failed. Each carries one sentence a user can act on.
"""

from __future__ import annotations

import contextlib
from pathlib import Path


class HairinvError(Exception):
    """Base of every error hairinv raises on purpose."""

    exit_code = 1


class InputError(HairinvError):
    """Bad input: names the file and, where it applies, the strand.

    Parameters
    ----------
    message : str
        What is wrong, as one sentence without the file name.
    path : str or Path, optional
        The file the problem is in.
    strand : int, optional
        Index of the offending strand in the file, 0-based.
    """

    exit_code = 2

    def __init__(self, message: str, path: str | Path | None = None, strand: int | None = None):
        self.message = message
        self.path = None if path is None else str(path)
        self.strand = strand
        super().__init__(str(self))

    def __str__(self) -> str:
        where = f"{self.path}: " if self.path else ""
        what = f"strand {self.strand}: " if self.strand is not None else ""
        return f"{where}{what}{self.message}"


@contextlib.contextmanager
def in_file(path):
    """Input errors raised within that name no file are said of ``path`` (a reader's checks that see only
    the data, such as a body mesh's)."""
    try:
        yield
    except InputError as error:
        if error.path is None and path is not None:
            raise InputError(error.message, path, error.strand) from None
        raise


class RunError(HairinvError):
    """A run on valid input that could not finish (solver failure and the like)."""

    exit_code = 1


class Interrupted(KeyboardInterrupt):
    """Ctrl-C (SIGINT) stopped a run that keeps what it had computed: ``result`` (a simulation's frames so far).

    A ``KeyboardInterrupt``, so that code unaware of it stops as on any interrupt; a caller that knows it
    can keep the result (``hairinv simulate`` writes the frames done).
    """

    def __init__(self, result):
        super().__init__()
        self.result = result
