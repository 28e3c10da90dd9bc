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
from hairinv.solver.rows import _fill


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
