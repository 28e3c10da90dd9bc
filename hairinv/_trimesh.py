"""trimesh, imported so that a Ctrl-C while it loads is not lost.

trimesh guards the imports of its own dependencies with ``except BaseException`` (trimesh 5.2: ``convex.py``,
``bounds.py``, ``base.py`` and more), so a Ctrl-C (KeyboardInterrupt) landing while it loads is swallowed:
``hairinv invert`` interrupted in the second it spends loading its libraries then ran to the end and exited 0.
:func:`load` holds SIGINT while trimesh is imported and raises the interrupt once the import is done.
"""

from __future__ import annotations

import signal
import threading
from contextlib import contextmanager

__all__ = ["held_interrupt", "load"]


@contextmanager
def held_interrupt():
    """Hold Ctrl-C (SIGINT) during the block; if one came, hand it to the handler in place before (Python's
    own raises KeyboardInterrupt) once the block ends.

    Only in the main thread and where SIGINT has a Python handler (elsewhere the block runs as it is).
    """
    try:
        previous = signal.getsignal(signal.SIGINT)
    except ValueError:
        previous = None
    if threading.current_thread() is not threading.main_thread() or not callable(previous):
        yield
        return
    received = []
    signal.signal(signal.SIGINT, lambda signum, frame: received.append(frame))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
    if received:
        previous(signal.SIGINT, received[0])


def load():
    """The ``trimesh`` module (imported with Ctrl-C held the first time)."""
    with held_interrupt():
        import trimesh
    return trimesh
