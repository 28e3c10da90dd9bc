"""Every benchmark still runs: each ``bench/*_bench.py`` module as a smoke run.

``HAIRINV_BENCH_SMOKE=1`` makes a benchmark run on tiny inputs, once, without waiting for an idle machine,
with its pictures and work files in a temporary folder (``bench/common.py``). Its figures mean nothing;
what is checked is that it runs to the end as a user would run it (``python bench/NAME.py``), prints its
section (the title, then tables), and leaves ``docs/`` alone: a benchmark that rots fails here instead of
in the hour-long ``make bench``.
"""

from __future__ import annotations

import hashlib
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import REAL

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "bench"
MODULES = sorted(p.stem for p in BENCH.glob("*_bench.py"))
# the benchmarks that read the real grooms (the others generate theirs or use samples/)
NEEDS_REAL = {"fit_bench", "fit_any_bench", "invert_bench", "solver_study_bench", "ipm_linear_algebra_bench",
              "blender_bench", "dynamics_bench", "full_head_bench", "contact_budget_bench",
              "interior_bench", "bounded_forces_bench", "schwarz_bench", "scale_bench"}


def _docs_state() -> dict:
    return {str(p.relative_to(ROOT)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted((ROOT / "docs").rglob("*")) if p.is_file()}


def test_every_benchmark_is_covered():
    assert {"fit_bench", "fit_any_bench", "invert_bench", "still_bench", "dynamics_bench"} <= set(MODULES)


@pytest.mark.parametrize("name", MODULES)
def test_benchmark_smoke_run(name, tmp_path):
    if name in NEEDS_REAL and not REAL.is_dir():
        pytest.skip(f"{name} reads the real grooms, not found at {REAL} (set HAIRINV_REAL_DATA)")
    source = (BENCH / f"{name}.py").read_text()
    title = re.search(r'^TITLE = "(.+)"$', source, re.M)
    assert title, f"bench/{name}.py has no TITLE"
    before = _docs_state()
    env = dict(os.environ, HAIRINV_BENCH_SMOKE="1", HAIRINV_BENCH_WORK=str(tmp_path), HAIRINV_REAL_DATA=str(REAL))
    done = subprocess.run([sys.executable, str(BENCH / f"{name}.py")], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    lines = done.stdout.splitlines()
    assert lines[0] == f"## {title.group(1)}"
    assert any(line.startswith("|---") or line.startswith("|--") for line in lines), "no table in the section"
    assert "Traceback" not in done.stderr
    assert _docs_state() == before, "a smoke run wrote into docs/"
    # what a benchmark draws goes to the smoke run's folder, not docs/img
    drawn = {p.name for p in (tmp_path / "img").glob("*.png")} if (tmp_path / "img").is_dir() else set()
    for png in re.findall(r"\(img/([\w.-]+\.png)\)", done.stdout):
        assert png in drawn, f"the section shows img/{png}, which the smoke run did not draw"
