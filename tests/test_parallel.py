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


@pytest.mark.parametrize("count", [1, 5, 150, 300, 512, 10_000])
def test_balanced_chunks_cover_every_item_once_in_at_least_eight_chunks_or_full_ones(count):
    """``balanced`` cuts a small count of costly items into at least 8 chunks (so that two workers finish
    together) and a large one into the chunks asked for; ``run_chunks`` then visits every item exactly once."""
    from hairinv._parallel import balanced, run_chunks

    chunk = balanced(count, 64)
    visits = [0] * count
    calls = []

    def work(lo, hi):
        calls.append((lo, hi))
        for i in range(lo, hi):
            visits[i] += 1

    run_chunks(work, count, chunk)
    assert visits == [1] * count
    assert len(calls) >= min(8, count) and max(hi - lo for lo, hi in calls) <= 64
    if count >= 8 * 64:
        assert chunk == 64
