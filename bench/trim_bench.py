"""Benchmark: a drawn groom cut at half length (the ``trim`` scene): which strands rise, and by how much.

Run alone with ``python bench/trim_bench.py`` (prints the markdown section),
or through ``bench/run.py``, which writes ``docs/benchmarks.md``.

The paper's trim experiment: hair whose rest shape carries its weight lifts
once its lower part is cut away, where hair simulated from its drawn shape
(the naive rest shape) sags. ``bench/dynamics_bench.py`` measures it on a
groom settled by simulation from a known rest shape; here the drawn samples
(wavy and straight guides lying on the bust), inverted at the default settings,
are cut and simulated as ``hairinv simulate --scene trim`` runs them, from the
inverted model and from the naive one. Reported per strand: the rise of the
new tip (along up) and the largest displacement of any of its points, then
median, 90th percentile and largest over the strands; for the inverted model,
split between the strands the inversion stiffened (unstable under their
contact forces held fixed) and the others.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from common import ROOT, log, smoke, table  # type: ignore
else:
    from .common import ROOT, log, smoke, table

sys.path.insert(0, str(ROOT))

from hairinv import config  # noqa: E402
from hairinv.dynamics.run import _samples, run_scene  # noqa: E402
from hairinv.dynamics.scene import Scene  # noqa: E402
from hairinv.invert import invert  # noqa: E402
from hairinv.model import Material  # noqa: E402
from hairinv.pipeline import prepare  # noqa: E402

TITLE = "Trimming a drawn groom: which strands rise"
SAMPLES = ROOT / "samples"
GROOMS = ("wavy", "straight")
GUIDES = smoke(120, 8)
SECONDS = smoke(0.5, 0.04)


def _per_strand(frames, up: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """m, per strand of the cut groom: the rise of its tip along ``up`` and the largest displacement of a point."""
    cut = frames.helices
    start, end = _samples(cut, np.asarray(frames.omega[0])), _samples(cut, np.asarray(frames.omega[-1]))
    rise = np.array([(b[-1] - a[-1]) @ up for a, b in zip(start, end)])
    moved = np.array([float(np.max(np.linalg.norm(b - a, axis=1))) for a, b in zip(start, end)])
    return rise, moved


def _mm(x: np.ndarray) -> str:
    return " / ".join(f"{1e3 * v:.2f}" if abs(1e3 * v) < 10 else f"{1e3 * v:.1f}"
                      for v in (np.median(x), np.percentile(x, 90), np.max(x))) if len(x) else ""


def run() -> str:
    started = time.perf_counter()
    scene = Scene.load("trim")
    how = f"fraction {scene.trim.fraction:g}" if scene.trim.fraction is not None else f"length {scene.trim.length:g} m"
    rows, notes = [], []
    for name in GROOMS:
        settings = config.apply(config.resolve(), {"import": {"guides": GUIDES}})
        log(f"trim: {name}, inverting {GUIDES} guides")
        prepared = prepare(SAMPLES / f"{name}.h5", SAMPLES / "body.obj", settings)
        material = Material.from_settings(settings.material, prepared.up)
        model, report = invert(prepared.helices, prepared.contacts, material, settings.solver)
        group = model.group({}, [])
        stiffened = (np.asarray(model.stiffening) > 1.0 if model.stiffening is not None
                     else np.zeros(prepared.helices.n_strands, dtype=bool))
        up = -material.gravity / np.linalg.norm(material.gravity)
        if not rows:  # compile the simulation's kernels before the first timed run
            run_scene(prepared.helices, group, prepared.contacts, prepared.body, scene, settings,
                      seconds=2.0 / scene.fps, fps=scene.fps)
        for init in ("inverted", "naive"):
            log(f"trim: {name}, {init}, {SECONDS} s")
            began = time.perf_counter()
            frames = run_scene(prepared.helices, group, prepared.contacts, prepared.body, scene, settings, init=init,
                               seconds=SECONDS, fps=scene.fps)
            wall = time.perf_counter() - began
            rise, moved = _per_strand(frames, up)
            split = ""
            if init == "inverted":
                split = (f"stiffened ({int(stiffened.sum())}): {_mm(rise[stiffened])}; "
                         f"others ({int((~stiffened).sum())}): {_mm(rise[~stiffened])}")
            rows.append([f"{name}, {prepared.helices.n_strands} guides", init, _mm(rise), _mm(moved), split,
                         f"{wall:.1f}"])
            if init == "inverted":
                notes.append((name, rise, stiffened))
    lines = [
        f"## {TITLE}",
        "",
        f"`bench/trim_bench.py`. The drawn wavy and straight samples ({GUIDES} guides each, lying on the sample "
        f"bust), inverted at the default settings, then cut ({how}, the `trim` scene) and simulated for "
        f"{SECONDS:g} s with the body still, as `hairinv simulate --scene trim` runs them: from the inverted model "
        "(the stiffened strands with their own stiffness and rest shape) and from the naive one (the drawn shape "
        "as the rest shape). Per strand: the rise of its new tip along up, and the largest displacement of any of "
        "its points; then median / 90th percentile / largest over the strands, in mm. The inverted model's rise "
        "is split between the strands the inversion stiffened (unstable under their contact forces held fixed) "
        "and the others. Wall time: the whole run, one process.",
        "",
        table(["groom", "rest shape", "tip rise (mm)", "largest displacement (mm)",
               "inverted: tip rise of the stiffened strands / the others (mm)", "wall time (s)"], rows),
        "",
    ]
    for name, rise, stiffened in notes:
        lifted = rise > 1e-3
        lines.append(f"{name}: {int(lifted.sum())} of {len(rise)} inverted strands rise by over 1 mm, "
                     f"{int((lifted & stiffened).sum())} of them stiffened.")
        lines.append("")
    lines.append(f"This section took {(time.perf_counter() - started) / 60:.1f} min.")
    return "\n".join(lines)


if __name__ == "__main__":
    print(run())
