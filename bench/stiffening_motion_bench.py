"""Benchmark: does stiffening freeze a groom? Stiffened strands against the others, moving.

Run alone with ``python bench/stiffening_motion_bench.py`` (prints the
markdown section), or through ``bench/run.py stiffening``, which writes the
section "Stiffened strands in motion" of ``docs/benchmarks.md``.

``hairinv invert`` stiffens the strands whose equilibrium would be unstable
(``/model/stiffening``). Stiffening must keep the groom still with the body
still, and must not keep it still once the body moves. For each groom below,
inverted with the default settings, this runs the ``motion`` scene (a head
turn and nod) through the command line::

    hairinv invert STYLE BODY -o model.h5
    hairinv simulate model.h5 BODY --scene motion --seconds S -o frames.h5

and compares, in the body's frame, how far each strand's tip moves from where
it started (its largest distance over the run): the stiffened strands against
the strands that needed no stiffening and whose lengths lie within the
stiffened ones' range (tips of longer strands swing further). It reuses the
models of ``bench/still_bench.py`` (``out/still_bench/``) when they are
there and were made from the same style file, and inverts the groom
otherwise.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from common import ROOT, SMOKE, WORK as BENCH_WORK, log, machine, machine_markdown, smoke, table  # type: ignore
else:
    from .common import ROOT, SMOKE, WORK as BENCH_WORK, log, machine, machine_markdown, smoke, table

sys.path.insert(0, str(ROOT))

from hairinv import stages  # noqa: E402
from hairinv.dynamics.simulate import points_on  # noqa: E402
from hairinv.model import Helices, stiffening_from_group  # noqa: E402

TITLE = "Stiffened strands in motion"
HAIRINV = ROOT / ".venv" / "bin" / "hairinv"
PYTHON = ROOT / ".venv" / "bin" / "python"
WORK = BENCH_WORK / "still_bench"
OUT = BENCH_WORK / "stiffening_motion"
# (name, style, seconds of the motion scene): the generated kinds with most stiffened strands
GROOMS = smoke((("mohawk", 1.0), ("draped_gap6", 0.5), ("updo", 0.5)), (("mohawk", 0.02),))
# a smoke run inverts this many guides of the groom
GUIDES = smoke([], ["--guides", "10"])


def tip_travel(frames_path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Per strand: the largest distance of its tip from where it started, in the body's frame (m); the
    stiffening factors; the strand lengths; the seconds simulated."""
    stage = stages.read_stage(frames_path)
    helices = Helices.from_group(stage[stages.HELICES])
    omega = np.asarray(stage[stages.FRAMES]["omega"], dtype=np.float64)
    t = np.asarray(stage[stages.FRAMES]["time"])
    factor = stiffening_from_group(stage[stages.MODEL], helices.n_strands)
    factor = np.ones(helices.n_strands) if factor is None else factor
    # the body frame: the strands' roots and root frames at rest, each frame's shape
    strands = np.arange(helices.n_strands)
    lengths = np.add.reduceat(helices.length, helices.offsets[:-1])
    start = points_on(helices, omega[0], strands, lengths)
    travel = np.zeros(helices.n_strands)
    for i in range(1, len(omega)):
        travel = np.maximum(travel, np.linalg.norm(points_on(helices, omega[i], strands, lengths) - start, axis=1))
    return travel, factor, lengths, float(t[-1])


def _run(cmd: list[str]) -> float:
    start = time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} exited {done.returncode}: {done.stderr.strip()[-500:]}")
    return time.perf_counter() - start


def measure(name: str, seconds: float) -> dict:
    OUT.mkdir(parents=True, exist_ok=True)
    style = WORK / f"{name}.h5"
    body = WORK / "mannequin.obj"
    if not style.exists() or not body.exists():
        subprocess.run([str(PYTHON), str(ROOT / "bench" / "grooms.py"), "-o", str(WORK), name], check=True,
                       stdout=subprocess.DEVNULL, cwd=ROOT)
    model = WORK / f"{name}.model.h5"
    invert_seconds = None
    if not model.exists() or model.stat().st_mtime < style.stat().st_mtime:
        model = OUT / f"{name}.model.h5"
        invert_seconds = _run([str(HAIRINV), "invert", str(style), str(body), "-o", str(model)] + GUIDES)
    frames = OUT / f"{name}.motion.h5"
    frames.unlink(missing_ok=True)
    sim_seconds = _run([str(HAIRINV), "simulate", str(model), str(body), "--scene", "motion", "--seconds",
                        f"{seconds:g}", "-o", str(frames)])
    travel, factor, lengths, simulated = tip_travel(frames)
    stiff = factor > 1.0
    res = {"name": name, "strands": len(factor), "stiffened": int(stiff.sum()), "simulated": simulated,
           "simulate_seconds": sim_seconds, "invert_seconds": invert_seconds}
    if stiff.any():
        lo, hi = lengths[stiff].min(), lengths[stiff].max()
        peers = ~stiff & (lengths >= lo) & (lengths <= hi)
        res.update(length_range_mm=(1e3 * lo, 1e3 * hi), peers=int(peers.sum()),
                   factor_median=float(np.median(factor[stiff])), factor_max=float(factor[stiff].max()),
                   stiff_tip_mm=np.percentile(1e3 * travel[stiff], [10, 50, 90]).tolist(),
                   peer_tip_mm=np.percentile(1e3 * travel[peers], [10, 50, 90]).tolist() if peers.any() else None,
                   all_tip_mm=float(np.median(1e3 * travel)))
    return res


def run() -> str:
    info = machine()
    start = time.perf_counter()
    results = []
    for name, seconds in GROOMS:
        log(f"{name}: motion scene, {seconds:g} s")
        results.append(measure(name, seconds))
    rows = []
    for r in results:
        if r["stiffened"] == 0:
            rows.append([f"`{r['name']}`", r["strands"], 0, "-", "-", "-", "-", "-", f"{r['simulated']:g}",
                         f"{r['simulate_seconds']:.0f}"])
            continue
        fmt = lambda p: "-" if p is None else " / ".join(f"{x:.1f}" for x in p)  # noqa: E731
        rows.append([f"`{r['name']}`", r["strands"], r["stiffened"],
                     f"{r['factor_median']:.2f} / {r['factor_max']:.2f}",
                     f"{r['length_range_mm'][0]:.0f}-{r['length_range_mm'][1]:.0f}", r["peers"],
                     fmt(r["stiff_tip_mm"]), fmt(r["peer_tip_mm"]), f"{r['simulated']:g}",
                     f"{r['simulate_seconds']:.0f}"])
    lines = [
        f"## {TITLE}",
        "",
        "`bench/stiffening_motion_bench.py`. Stiffening keeps an inverted groom still with the body still "
        "(\"Still on any groom\"); it must not keep it still once the body moves. Each groom (generated by "
        "`bench/grooms.py`, inverted with the default settings) runs the `motion` scene through the command line, "
        "`hairinv simulate model.h5 mannequin.obj --scene motion --seconds S -o frames.h5`, and each strand's tip "
        "travel is its largest distance from where it started, in the body's frame. The stiffened strands are set "
        "beside the strands that needed no stiffening and whose lengths lie within the stiffened ones' range "
        "(peers). Single runs; wall clock of the simulate command.",
        "",
        machine_markdown(info),
        "",
        table(["groom", "strands", "stiffened", "factor median / max", "their lengths (mm)", "peers",
               "stiffened tips' travel, mm (10th / median / 90th)", "peers' tips' travel, mm (10th / median / 90th)",
               "simulated (s)", "simulate (s)"], rows),
        "",
        f"The whole benchmark took {(time.perf_counter() - start) / 60:.1f} min.",
        "",
    ]
    return "\n".join(lines)


if __name__ == "__main__":
    print(run())
