"""The one numba decorator of the project.

Every kernel is compiled with ``cache=True`` so the compile cost is paid once
per machine (the cache lives beside the sources, or in ``NUMBA_CACHE_DIR``).
``fastmath`` stays off: the helix closed forms rely on exact IEEE behaviour
near their series thresholds. Set ``NUMBA_DISABLE_JIT=1`` to run every kernel
as plain Python for coverage or debugging.
"""

from __future__ import annotations

import numba

__all__ = ["jit", "pjit", "prange"]

prange = numba.prange


def jit(fn=None, **overrides):
    """``numba.njit`` with the project's defaults (cache on, fastmath off)."""
    options = {"cache": True, "fastmath": False, "nogil": True}
    options.update(overrides)
    if fn is None:
        return lambda f: numba.njit(**options)(f)
    return numba.njit(**options)(fn)


def pjit(fn=None, **overrides):
    """Like :func:`jit` but compiled with ``parallel=True`` for ``prange`` loops.

    Only for loops whose iterations write disjoint outputs (one strand each),
    so results do not depend on the thread count.
    """
    overrides.setdefault("parallel", True)
    return jit(fn, **overrides)
