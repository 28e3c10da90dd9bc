"""Run independent chunks of work on threads.

Kernels are compiled with ``nogil=True``, so Python threads run them truly
in parallel without the compile cost of numba's parallel loops. Each chunk
writes only its own rows of the output arrays, so results do not depend on
the thread count or on scheduling.
"""

from __future__ import annotations

import contextlib
import os
import threading
from concurrent.futures import ThreadPoolExecutor
from typing import Callable

import numpy as np
from threadpoolctl import ThreadpoolController

_lock = threading.Lock()
_pool: ThreadPoolExecutor | None = None
_pool_size = 0
_controller: ThreadpoolController | None = None
_pinned = threading.local()
_PREFIX = "hairinv-worker"


def in_worker() -> bool:
    """True on one of the pool's threads: work submitted from there runs inline (no nested waits)."""
    return threading.current_thread().name.startswith(_PREFIX)


def worker_count() -> int:
    """Threads to use: ``HAIRINV_THREADS`` if set, else the CPU count."""
    value = os.environ.get("HAIRINV_THREADS")
    if value:
        return max(1, int(value))
    return _CPUS


_CPUS = max(1, os.cpu_count() or 1)  # os.cpu_count() asks the system each time (tens of microseconds)


def executor(workers: int) -> ThreadPoolExecutor:
    """A thread pool of ``workers`` threads, kept between calls (starting threads costs milliseconds,
    which a simulation step that runs several parallel phases cannot afford)."""
    global _pool, _pool_size
    with _lock:
        if _pool is None or _pool_size != workers:
            if _pool is not None:
                _pool.shutdown(wait=False)
            _pool = ThreadPoolExecutor(max_workers=workers, thread_name_prefix=_PREFIX)
            _pool_size = workers
        return _pool


@contextlib.contextmanager
def blas_pinned():
    """BLAS limited to one thread within the block (re-entrant; the library scan is done once)."""
    global _controller
    if getattr(_pinned, "depth", 0):
        _pinned.depth += 1
        try:
            yield
        finally:
            _pinned.depth -= 1
        return
    with _lock:
        if _controller is None:
            # the scan sees only the libraries loaded by then: load scipy's LAPACK first, which numba's
            # np.linalg calls into (its own OpenBLAS, apart from numpy's). Left out of the scan, it ran
            # two threads inside each worker's small SVDs: the stability check of a 24,335-strand groom
            # took 26 s instead of 6.6 s.
            import scipy.linalg.cython_lapack  # noqa: F401

            _controller = ThreadpoolController()
    _pinned.depth = 1
    try:
        with _controller.limit(limits=1, user_api="blas"):
            yield
    finally:
        _pinned.depth = 0


def run_chunks(work: Callable[[int, int], None], count: int, chunk: int,
               progress: Callable[[int], None] | None = None) -> None:
    """Call ``work(lo, hi)`` over ``[0, count)`` in chunks, on worker threads.

    The BLAS library is limited to one thread meanwhile: the kernels' small
    matrix products would otherwise start BLAS threads of their own and
    fight our workers for the cores (measured: no speed-up from a second
    worker on the curly sample until BLAS was pinned, 1.9x after).
    """
    with blas_pinned():
        _run(work, count, chunk, progress)


def balanced(count: int, chunk: int, parts: int = 8) -> int:
    """A chunk size for :func:`run_chunks` of ``count`` costly items: ``chunk`` (what a large count is cut into),
    or smaller, so that a small count still makes at least ``parts`` chunks. With fewer chunks than a few per
    worker, the last worker waits on its neighbour: 150 strands in chunks of 64 keep two threads 1.5 times
    as long as an even split. (It depends on ``count`` only: the chunks are the same on any number of threads.)"""
    return max(1, min(int(chunk), -(-int(count) // int(parts))))


def run_ranges(work: Callable[[int, int], None], ranges: list[tuple[int, int]]) -> None:
    """Call ``work(lo, hi)`` for each range, on worker threads (inline on one, or from a worker); each call
    must write only its own outputs. BLAS is left as it is (callers pin it where they need to)."""
    workers = worker_count()
    if workers <= 1 or len(ranges) <= 1 or in_worker():
        for lo, hi in ranges:
            work(lo, hi)
        return
    pool = executor(workers)
    futures = [pool.submit(work, lo, hi) for lo, hi in ranges]
    try:
        for future in futures:
            future.result()
    finally:
        for future in futures:
            future.cancel()
        for future in futures:
            if not future.cancelled():
                future.exception()


def cost_ranges(cost: np.ndarray, lo: int, hi: int, parts: int) -> list[tuple[int, int]]:
    """``[lo, hi)`` cut into consecutive runs of about equal cost, ``parts`` at most (for :func:`run_ranges`)."""
    total = float(np.sum(cost[lo:hi]))
    runs, start, acc = [], lo, 0.0
    for k in range(lo, hi):
        acc += cost[k]
        if acc >= total / parts or k == hi - 1:
            runs.append((start, k + 1))
            start, acc = k + 1, 0.0
    return runs


def _run(work, count, chunk, progress) -> None:
    bounds = [(lo, min(count, lo + chunk)) for lo in range(0, count, chunk)]
    workers = min(worker_count(), len(bounds))
    if workers <= 1 or in_worker():
        for lo, hi in bounds:
            work(lo, hi)
            if progress is not None:
                progress(hi - lo)
        return
    pool = executor(workers)
    futures = [pool.submit(work, lo, hi) for lo, hi in bounds]
    try:
        for (lo, hi), future in zip(bounds, futures):
            future.result()
            if progress is not None:
                progress(hi - lo)
    finally:
        for future in futures:  # an error in one chunk: let the others finish before the caller moves on
            future.cancel()
        for future in futures:
            if not future.cancelled():
                future.exception()
