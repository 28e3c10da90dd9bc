"""Shared helpers of the benchmarks: the machine, timing, markdown tables."""

from __future__ import annotations

import os
import platform
import statistics
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
# A smoke run (HAIRINV_BENCH_SMOKE=1, what the test suite does): every benchmark on tiny inputs, once,
# without waiting for an idle machine, its pictures and work files under HAIRINV_BENCH_WORK (default
# out/bench-smoke) instead of docs/img and out/. It shows that a benchmark still runs end to end; its
# figures mean nothing.
SMOKE = os.environ.get("HAIRINV_BENCH_SMOKE", "") not in ("", "0")
WORK = Path(os.environ.get("HAIRINV_BENCH_WORK", ROOT / "out" / "bench-smoke")) if SMOKE else ROOT / "out"
IMG = WORK / "img" if SMOKE else DOCS / "img"
# The real third-party grooms: HAIRINV_REAL_DATA, or shared/data/real beside the repository.
DATA = Path(os.environ.get("HAIRINV_REAL_DATA", Path(__file__).resolve().parents[2] / "shared" / "data" / "real"))


def smoke(full, small):
    """``small`` in a smoke run (see ``SMOKE``), else ``full``: a benchmark's sizes and repeat counts."""
    return small if SMOKE else full


def _cpu_model() -> str:
    model, virtual = None, False
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                key = line.split(":", 1)[0].strip().lower()
                if key == "model name" and model is None:
                    model = line.split(":", 1)[1].strip()
                elif key == "flags" and "hypervisor" in line.split(":", 1)[1].split():
                    virtual = True
    except OSError:
        pass
    model = model or platform.processor() or "unknown CPU"
    return model + (" (virtual machine; the hypervisor hides the exact model)" if virtual and len(model.split()) <= 2 else
                    " (virtual machine)" if virtual else "")


def _ram_gib() -> float | None:
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemTotal:"):
                    return int(line.split()[1]) / 1024 ** 2
    except OSError:
        pass
    return None


def _version(module: str) -> str:
    try:
        mod = __import__(module)
        return str(getattr(mod, "__version__", "?"))
    except ImportError:
        return "not installed"


def machine() -> dict:
    """What the numbers were measured on."""
    ram = _ram_gib()
    try:
        load = os.getloadavg()
    except OSError:
        load = None
    return {
        "cpu": _cpu_model(),
        "cores": os.cpu_count() or 1,
        "ram": f"{ram:.1f} GiB" if ram is not None else "unknown",
        "os": f"{platform.system()} {platform.release()}",
        "python": platform.python_version(),
        "numpy": _version("numpy"),
        "scipy": _version("scipy"),
        "numba": _version("numba"),
        "load": load,
    }


def machine_markdown(info: dict | None = None) -> str:
    info = info or machine()
    rows = [
        ("CPU", info["cpu"]),
        ("Logical cores", str(info["cores"])),
        ("RAM", info["ram"]),
        ("OS", info["os"]),
        ("Python", info["python"]),
        ("numpy / scipy / numba", f"{info['numpy']} / {info['scipy']} / {info['numba']}"),
    ]
    if info.get("load") is not None:
        rows.append(("Load average when the run started (1/5/15 min)", " / ".join(f"{v:.2f}" for v in info["load"])))
    return table(["Machine", ""], rows)


def _cpu_ticks() -> tuple[int, int]:
    """Busy and total jiffies of the whole machine (all cores), from /proc/stat."""
    with open("/proc/stat") as fh:
        values = [int(v) for v in fh.readline().split()[1:]]
    idle = values[3] + (values[4] if len(values) > 4 else 0)
    return sum(values) - idle, sum(values)


def background_load(seconds: float = 0.5) -> float:
    """Share of the machine's CPU time (0-1, all cores) used by other processes over ``seconds``."""
    own = time.process_time()
    busy0, total0 = _cpu_ticks()
    time.sleep(seconds)
    busy1, total1 = _cpu_ticks()
    own = time.process_time() - own
    hz = os.sysconf("SC_CLK_TCK")
    total = max(total1 - total0, 1)
    return max(0.0, ((busy1 - busy0) - own * hz) / total)


# Seconds that all waits of one process may spend in total, so a busy machine
# slows the benchmarks down by a bounded amount.
WAIT_BUDGET = 0.0 if SMOKE else 60.0
_waited = 0.0


def wait_quiet(threshold: float = 0.1, timeout: float = 5.0) -> float:
    """Wait (at most ``timeout`` s, and within ``WAIT_BUDGET``) until other processes use less
    than ``threshold`` of the CPU. Returns the last measured share."""
    global _waited
    start = time.perf_counter()
    limit = min(timeout, max(0.0, WAIT_BUDGET - _waited))
    load = background_load()
    while load > threshold and time.perf_counter() - start < limit:
        load = background_load()
    _waited += time.perf_counter() - start
    return load


@dataclass
class Timing:
    median: float
    """s, median wall-clock time"""
    times: list[float]
    """s, every run"""
    background: list[float]
    """share of the machine's CPU used by other processes during each run (0-1)"""
    cpu: list[float]
    """s, CPU time of this process (all its threads) during each run"""
    result: object = None
    """what the last call returned"""


def median_time(fn: Callable[[], object], repeats: int = 5, quiet: bool = True) -> Timing:
    """Median wall-clock time of ``repeats`` calls of ``fn``.

    With ``quiet``, each run first waits (up to 5 s, see ``wait_quiet``) for the
    machine to be idle; the CPU share other processes used during each run is recorded.
    """
    times, background, cpu = [], [], []
    result = None
    hz = os.sysconf("SC_CLK_TCK")
    for _ in range(repeats):
        if quiet:
            wait_quiet()
        busy0, total0 = _cpu_ticks()
        own = time.process_time()
        start = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - start)
        own = time.process_time() - own
        cpu.append(own)
        busy1, total1 = _cpu_ticks()
        background.append(max(0.0, ((busy1 - busy0) - own * hz) / max(total1 - total0, 1)))
    return Timing(statistics.median(times), times, background, cpu, result)


def table(header: Sequence[str], rows: Sequence[Sequence[object]], align: Sequence[str] | None = None) -> str:
    """A markdown table; ``align`` holds "l" or "r" per column (default: first left, others right)."""
    align = align or ["l"] + ["r"] * (len(header) - 1)
    cells = [[str(c) for c in header]] + [[str(c) for c in row] for row in rows]
    rule = ["---:" if a == "r" else "---" for a in align]
    lines = ["| " + " | ".join(cells[0]) + " |", "|" + "|".join(rule) + "|"]
    lines += ["| " + " | ".join(row) + " |" for row in cells[1:]]
    return "\n".join(lines)


_T0 = time.perf_counter()


def stiffened_strands(inverted) -> int:
    """Strands an inversion stiffened (``inverted``: its model or its report, anything with ``stiffening``)."""
    return 0 if inverted.stiffening is None else int(np.count_nonzero(inverted.stiffening > 1.0))


def log(message: str) -> None:
    """Progress on stderr (with the seconds since start), so stdout stays the markdown."""
    print(f"[{time.perf_counter() - _T0:6.0f} s] {message}", file=sys.stderr, flush=True)
