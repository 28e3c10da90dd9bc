"""Where a simulation step's time goes: the phases of ``Simulation.step`` on three groom sizes.

Run alone with ``python bench/profile_bench.py`` (prints the markdown section),
or through ``bench/run.py profile``, which writes the section "Where a step's
time goes" of ``docs/benchmarks.md``.

Each scene is stepped in one process after a warm-up step (the compiled
kernels loaded); ``Simulation.clock`` sums the wall time of every attempt at a
step by phase, kept or thrown away for a halved step:

* body: the body's motion for the step (a rigid motion's is given);
* matrices: which strands' mass matrix and gravity Hessian are taken afresh,
  and the contact forces' Hessians for them;
* free motion: each strand's step matrix, its Cholesky factor (where taken
  afresh) and its free velocity;
* detection: the strands' own sweep and contact detection (reused while the
  strands have hardly moved);
* persistence: the remembered contacts measured again, their thickness and
  warm start;
* contact rows: the rows of ``H``, their blocks ``W_ii``, the right-hand side
  and, where the warm start does not meet the tolerance, the factored rows;
* warm start: the last step's impulses checked against the contact law;
* contact solve: the Gauss-Seidel sweeps of the De Saxce fixed point;
* update: the velocities, positions and remembered contacts.

The scenes are those of the dynamics benchmark ("Simulating an inverted
groom", "Speed"): 300 guides of the straight sample settled on the sample
bust without hair-hair contact and inverted, in the ``motion`` scene; ruby
short (1,867 strands, hair-hair contact) inverted, still for one frame with
nothing asleep, and in the ``motion`` scene from 0.5 s for two frames.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from common import ROOT, log, machine, machine_markdown, smoke, table  # type: ignore
else:
    from .common import ROOT, log, machine, machine_markdown, smoke, table

sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from dynamics_bench import _moving, ruby_short, settled_straight  # type: ignore  # noqa: E402

from hairinv.dynamics.simulate import Motion, Simulation  # noqa: E402

TITLE = "Where a step's time goes"
MOTION_SECONDS = smoke(0.5, 0.02)
RUBY_STILL_SECONDS = smoke(0.04, 0.01)
RUBY_MOTION_START = 0.5
RUBY_MOTION_SECONDS = smoke(0.08, 0.01)


def profile(label: str, sim: Simulation, seconds: float, motion_at) -> dict:
    """Step ``sim`` for ``seconds`` after one warm-up step; the clock's phases, per kept step."""
    h = sim.settings.time_step
    sim.step(motion_at(0.0))
    sim.clock = type(sim.clock)()
    steps = int(round(seconds / h))
    sweeps, unconverged, contacts = [], 0, []
    started = time.perf_counter()
    for i in range(steps):
        report = sim.step(motion_at((i + 1) * h))
        sweeps.append(report.sweeps)
        unconverged += report.status != "CONVERGED"
        contacts.append(report.contacts)
    wall = time.perf_counter() - started
    clock = sim.clock
    log(f"profile: {label}: {wall:.2f} s for {steps} steps, {clock.attempts} attempts")
    return {"label": label, "strands": sim.helices.n_strands, "steps": steps, "wall": wall,
            "phases": dict(clock.seconds), "thrown_away": clock.thrown_away, "attempts": clock.attempts,
            "kept": clock.kept, "sweeps": float(np.mean(sweeps)) if sweeps else 0.0, "unconverged": unconverged,
            "contacts": int(np.mean(contacts)) if contacts else 0, "seconds": seconds}


def scenes() -> list[dict]:
    rows = []
    straight, _ = settled_straight()
    rows.append(profile(f"{straight.helices.n_strands} settled straight, motion scene", straight.simulation(),
                        MOTION_SECONDS, _moving(straight.mat, straight.helices.root)))
    ruby = ruby_short()
    if ruby is None:
        return rows
    rows.append(profile(f"ruby short ({ruby.helices.n_strands} strands), still, nothing asleep",
                        ruby.simulation(sleep_speed=0.0), RUBY_STILL_SECONDS, lambda t: Motion.still(ruby.mat.gravity)))
    turning = _moving(ruby.mat, ruby.helices.root)
    rows.append(profile(f"ruby short, motion scene from {RUBY_MOTION_START:g} s", ruby.simulation(),
                        RUBY_MOTION_SECONDS, lambda t: turning(RUBY_MOTION_START + t)))
    return rows


def render(rows: list[dict]) -> str:
    phases = []
    for r in rows:
        phases += [p for p in r["phases"] if p not in phases]
    head = ["phase"] + [r["label"] for r in rows]
    body = []
    for p in phases:
        cells = [p]
        for r in rows:
            s = r["phases"].get(p, 0.0)
            total = sum(r["phases"].values())
            cells.append(f"{1e3 * s / r['steps']:.1f} ms ({100 * s / total:.0f}%)" if total else "-")
        body.append(cells)
    body.append(["**a step, all phases**"] + [f"**{1e3 * sum(r['phases'].values()) / r['steps']:.1f} ms**"
                                              for r in rows])
    body.append(["of it in attempts thrown away"] + [f"{1e3 * r['thrown_away'] / r['steps']:.1f} ms" for r in rows])
    body.append(["attempts per step"] + [f"{r['attempts'] / r['steps']:.2f}" for r in rows])
    body.append(["contacts, mean"] + [f"{r['contacts']:,}" for r in rows])
    body.append(["sweeps per step, mean"] + [f"{r['sweeps']:.0f}" for r in rows])
    body.append(["steps unconverged"] + [f"{r['unconverged']} of {r['steps']}" for r in rows])
    body.append(["wall time per 1/25 s frame"] + [f"{r['wall'] / r['seconds'] / 25:.2f} s" for r in rows])
    info = machine()
    return "\n".join([
        f"## {TITLE}", "",
        "`bench/profile_bench.py`: the wall time of `Simulation.step` by phase (`Simulation.clock`), per kept "
        "10 ms step at the defaults (the still row with nothing asleep: what a step of a still groom costs before "
        "it sleeps, and what `verify` pays), each scene stepped in one process after a warm-up step. A halved step's "
        "attempts all count, and the row below the total says how much of it went to attempts thrown away. "
        "The phases are listed in the module's docstring.", "",
        table(head, body), "",
        machine_markdown(info), ""])


def run() -> str:
    return render(scenes())


if __name__ == "__main__":
    print(run())
