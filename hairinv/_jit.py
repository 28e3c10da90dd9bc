"""The one numba decorator of the project.

Every kernel is compiled with ``cache=True`` so the compile cost is paid once
per machine (the cache lives beside the sources, or in ``NUMBA_CACHE_DIR``).
numba stamps a cached kernel with its own source file only, yet a kernel
compiles in the kernels it calls from other files: after an upgrade it would
keep running their old code. So hairinv's kernels are stamped with a hash of
every source file of the package, and any change recompiles them all.
``fastmath`` stays off: the helix closed forms rely on exact IEEE behaviour
near their series thresholds. Set ``NUMBA_DISABLE_JIT=1`` to run every kernel
as plain Python for coverage or debugging.
"""

from __future__ import annotations

import functools
import hashlib
import os
from pathlib import Path

import numba
from numba.core import caching, config

__all__ = ["jit", "pjit", "prange"]

prange = numba.prange


_PACKAGE = Path(__file__).resolve().parent


@functools.lru_cache(maxsize=None)
def package_stamp(root: Path = _PACKAGE) -> str:
    """sha256 of every source file of the package at ``root`` (path and content)."""
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(path.relative_to(root).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


class _PackageStampedLocator(caching._CacheLocator):
    """numba's places for the cache (``NUMBA_CACHE_DIR``, else ``__pycache__`` beside the source,
    else the user's cache directory), with the whole package's hash as the source stamp; only for
    hairinv's kernels."""

    def __init__(self, py_func, py_file, cache_path):
        self._lineno = py_func.__code__.co_firstlineno
        self._py_file = py_file  # numba names it when a kernel cannot be cached
        self._cache_path = cache_path

    def get_cache_path(self):
        return self._cache_path

    def get_source_stamp(self):
        return package_stamp()

    def get_disambiguator(self):
        return str(self._lineno)

    @classmethod
    def from_function(cls, py_func, py_file):
        try:
            Path(py_file).resolve().relative_to(_PACKAGE)
        except (OSError, ValueError):
            return None  # not one of ours: numba's own locators decide
        if config.CACHE_DIR:
            places = [os.path.join(config.CACHE_DIR, cls.get_suitable_cache_subpath(py_file))]
        else:
            # beside the source, else (a read-only install) in the user's cache directory
            user = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
            places = [os.path.join(os.path.dirname(py_file), "__pycache__"),
                      os.path.join(user, "hairinv", cls.get_suitable_cache_subpath(py_file))]
        for place in places:
            locator = cls(py_func, py_file, place)
            try:
                locator.ensure_cache_path()
            except OSError:
                continue
            return locator
        return None  # nowhere writable: numba's own locators decide


if _PackageStampedLocator not in caching.CacheImpl._locator_classes:
    caching.CacheImpl._locator_classes.insert(0, _PackageStampedLocator)


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
