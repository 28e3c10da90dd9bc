"""Run every benchmark and write ``docs/benchmarks.md``.

Every ``bench/*_bench.py`` module with a ``run() -> str`` function is a
benchmark; each returns one markdown section. Usage, from the project root::

    make bench            # or: .venv/bin/python bench/run.py
    .venv/bin/python bench/run.py fit    # only the modules whose name starts with "fit"

``HAIRINV_BENCH_SMOKE=1`` runs a benchmark on tiny inputs (``bench/common.py``, ``SMOKE``); the test
suite runs every one that way (``tests/test_bench_smoke.py``).
"""

from __future__ import annotations

import datetime
import importlib
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from common import DOCS, log, machine, machine_markdown  # noqa: E402

OUTPUT = DOCS / "benchmarks.md"


def discover(prefixes=()) -> list[str]:
    names = sorted(p.stem for p in HERE.glob("*_bench.py"))
    if prefixes:
        names = [n for n in names if any(n.startswith(pre) for pre in prefixes)]
    return names


def _split(page: str) -> list[str]:
    """The ``## `` sections of a page after its "How to reproduce" part, each with its text."""
    parts, current = [], None
    for line in page.splitlines(keepends=True):
        if line.startswith("## "):
            current = [line]
            parts.append(current)
        elif current is not None:
            current.append(line)
    return ["".join(p).rstrip() + "\n" for p in parts if not p[0].startswith("## How to reproduce")]


def merge_sections(page: str, new: list[str]) -> list[str]:
    """The page's sections with those of ``new`` (matched by their title) replaced or appended."""
    old = _split(page)
    titles = {s.splitlines()[0]: s for s in new}
    merged = [titles.pop(s.splitlines()[0], s) for s in old]
    return merged + [s for s in new if s.splitlines()[0] in titles]


def stamp(section: str, when: datetime.datetime, seconds: float, load) -> str:
    """``section`` with a line under its title saying when it ran, for how long, and the load then
    (a page rerun in parts mixes sections from different runs, and machines have good and bad days)."""
    title, _, rest = section.partition("\n")
    line = f"_Run on {when:%Y-%m-%d %H:%M} (UTC), {seconds / 60:.1f} min"
    if load is not None:
        line += ", load average at its start " + " / ".join(f"{v:.2f}" for v in load)
    return f"{title}\n\n{line}._\n{rest}"


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    info = machine()
    started = datetime.datetime.now(datetime.timezone.utc)
    sections, durations = [], []
    for name in discover(argv):
        log(f"== {name}")
        module = importlib.import_module(name)
        when = datetime.datetime.now(datetime.timezone.utc)
        load = machine().get("load")
        start = time.perf_counter()
        text = module.run().rstrip() + "\n"
        durations.append((name, time.perf_counter() - start))
        sections.append(stamp(text, when, durations[-1][1], load))
        log(f"== {name}: {durations[-1][1]:.0f} s")
    total = sum(d for _, d in durations)
    head = [
        "# Benchmarks",
        "",
        "Speed and accuracy of hairinv, measured by `bench/run.py`, which rewrites this page. "
        "Each section states what it measures, on which data, and against which peer. Times are wall clock "
        "and are medians of repeated runs; ratios compare programs run in the same process on the same machine. "
        "Absolute times depend on the machine below and on what else was running on it.",
        "",
        f"Measured on {started:%Y-%m-%d} (UTC); the whole run took {total / 60:.1f} min.",
        "",
        machine_markdown(info),
        "",
        "## How to reproduce",
        "",
        "```sh",
        "make bench        # sets up .venv if needed, runs bench/run.py, rewrites docs/benchmarks.md",
        "```",
        "",
        "One benchmark alone prints its section without writing this page, e.g. `.venv/bin/python bench/fit_bench.py`. "
        "The real hair files are read from `../shared/data/real/` beside the repository, or from the folder named by `HAIRINV_REAL_DATA` (see that folder's README for their origin and units).",
        "",
    ]
    if argv and OUTPUT.exists():
        # a partial run: keep the other benchmarks' sections as they were, in their order
        sections = merge_sections(OUTPUT.read_text(), sections)
        head[4] = (f"Sections rerun on {started:%Y-%m-%d} (UTC): {', '.join(discover(argv))} "
                   f"({total / 60:.1f} min); the others are from earlier runs on the same machine "
                   "(a section rerun says when it ran). The machine table's load average is the last rerun's.")
    OUTPUT.parent.mkdir(parents=True, exist_ok=True)
    OUTPUT.write_text("\n".join(head) + "\n" + "\n".join(sections))
    log(f"wrote {OUTPUT}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
