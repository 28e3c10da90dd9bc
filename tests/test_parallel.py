"""The thread pool's BLAS pinning: worker threads run kernels side by side, so no BLAS library may
start threads of its own within them."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

_PROBE = """
from hairinv import _parallel
from threadpoolctl import ThreadpoolController
with _parallel.blas_pinned():  # the first use: the library scan happens here
    pass
import scipy.linalg  # later in the run: the LAPACK numba's np.linalg calls into
with _parallel.blas_pinned():
    print(max(i["num_threads"] for i in ThreadpoolController().info() if i["user_api"] == "blas"))
"""


@pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="one core: every BLAS runs one thread anyway")
def test_blas_is_pinned_to_one_thread_including_the_lapack_numba_calls():
    """Every BLAS library is limited within ``blas_pinned``, also scipy's (numba's np.linalg calls
    its LAPACK), even when the first pinning happened before scipy.linalg was imported. Missing it
    made the stability check of a 24,335-strand groom 4 times slower. In a fresh process, so that
    nothing else has loaded scipy's LAPACK first."""
    env = dict(os.environ)
    env.pop("OPENBLAS_NUM_THREADS", None)
    env.pop("OMP_NUM_THREADS", None)
    out = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True, env=env, check=True)
    assert out.stdout.split()[-1] == "1", out.stdout + out.stderr
