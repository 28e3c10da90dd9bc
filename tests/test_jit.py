"""The kernels' compile cache is invalidated by a change to any source file of the package.

numba's own stamp is the kernel's source file, but a kernel compiles in the
kernels it calls from other files; a change there must not leave old code
running from the cache.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numba
import pytest

from hairinv import _jit
from hairinv.rod.statics import gravity_hessian
from hairinv.contacts.rows import _fill


@pytest.mark.skipif(numba.config.DISABLE_JIT, reason="NUMBA_DISABLE_JIT: the kernels are plain Python, nothing is cached")
def test_kernels_use_the_package_stamped_cache():
    for kernel in (gravity_hessian, _fill):
        locator = kernel._cache._impl.locator
        assert isinstance(locator, _jit._PackageStampedLocator)
        assert locator.get_source_stamp() == _jit.package_stamp()


def test_the_stamp_follows_every_source_file(tmp_path):
    package = Path(_jit.__file__).parent
    one, two, three = (shutil.copytree(package, tmp_path / name, ignore=shutil.ignore_patterns("__pycache__"))
                       for name in ("one", "two", "three"))
    # a kernel file the callers' files do not mention changes everyone's stamp
    helix = three / "rod" / "helix.py"
    helix.write_text(helix.read_text() + "\n# changed\n")
    assert _jit.package_stamp(one) == _jit.package_stamp(two)
    assert _jit.package_stamp(one) != _jit.package_stamp(three)


def test_functions_outside_the_package_keep_numbas_locators(tmp_path):
    def outside():
        return 1

    assert _jit._PackageStampedLocator.from_function(outside, str(tmp_path / "elsewhere.py")) is None


def test_a_read_only_install_caches_in_the_users_cache_directory(tmp_path, monkeypatch):
    """Where the package's ``__pycache__`` cannot be written, the cache goes to ``$XDG_CACHE_HOME/hairinv``,
    still package-stamped; where nothing can be written, numba's own locators decide."""
    monkeypatch.setattr(_jit.config, "CACHE_DIR", "")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    writable = _jit._PackageStampedLocator.ensure_cache_path
    beside = Path(_jit.__file__).parent

    def read_only_package(self):
        if Path(self.get_cache_path()).is_relative_to(beside):
            raise PermissionError(f"read-only: {self.get_cache_path()}")
        writable(self)

    monkeypatch.setattr(_jit._PackageStampedLocator, "ensure_cache_path", read_only_package)
    source = str(beside / "rod" / "statics.py")
    locator = _jit._PackageStampedLocator.from_function(gravity_hessian.py_func, source)
    assert Path(locator.get_cache_path()).is_relative_to(tmp_path / "hairinv")
    assert Path(locator.get_cache_path()).is_dir()
    assert locator.get_source_stamp() == _jit.package_stamp()

    def nowhere(self):
        raise PermissionError(f"read-only: {self.get_cache_path()}")

    monkeypatch.setattr(_jit._PackageStampedLocator, "ensure_cache_path", nowhere)
    assert _jit._PackageStampedLocator.from_function(gravity_hessian.py_func, source) is None
