"""Run independent chunks of work on threads.

Kernels are compiled with ``nogil=True``, so Python threads run them truly
in parallel without the compile cost of numba's parallel loops. Each chunk
writes only its own rows of the output arrays, so results do not depend on
the thread count or on scheduling.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from typing import Callable

from threadpoolctl import threadpool_limits


def worker_count() -> int:
    """Threads to use: ``HAIRINV_THREADS`` if set, else the CPU count."""
    value = os.environ.get("HAIRINV_THREADS")
    if value:
        return max(1, int(value))
    return max(1, os.cpu_count() or 1)


def run_chunks(work: Callable[[int, int], None], count: int, chunk: int,
               progress: Callable[[int], None] | None = None) -> None:
    """Call ``work(lo, hi)`` over ``[0, count)`` in chunks, on worker threads.

    The BLAS library is limited to one thread meanwhile: the kernels' small
    matrix products would otherwise start BLAS threads of their own and
    fight our workers for the cores (measured: no speed-up from a second
    worker on the curly sample until BLAS was pinned, 1.9x after).
    """
    with threadpool_limits(limits=1, user_api="blas"):
        _run(work, count, chunk, progress)


def _run(work, count, chunk, progress) -> None:
    bounds = [(lo, min(count, lo + chunk)) for lo in range(0, count, chunk)]
    workers = min(worker_count(), len(bounds))
    if workers <= 1:
        for lo, hi in bounds:
            work(lo, hi)
            if progress is not None:
                progress(hi - lo)
        return
    with ThreadPoolExecutor(max_workers=workers) as pool:
        futures = [pool.submit(work, lo, hi) for lo, hi in bounds]
        for (lo, hi), future in zip(bounds, futures):
            future.result()
            if progress is not None:
                progress(hi - lo)
