"""Time per frame of a moving groom with hair-hair contact against its strand count, log-log.

Run alone with ``python bench/scale_bench.py`` (prints the markdown section), or
through ``bench/run.py scale``, which writes the section "Moving hair against
strand count" of ``docs/benchmarks.md``.

The grooms are the full-head family of ``bench/full_head.py`` below its
4,867 guides (ruby short and long joined on ``ruby_head.obj``, a subset spread
evenly over the scalp, as ``--guides N`` keeps), so a larger groom is a fuller
one on the same head. Each is prepared at the defaults (fitted, contacts
detected with hair-hair contact), inverted (``solver.max_sweeps`` 300, as the
dynamics benchmark inverts ruby short; with the stability check, which
stiffens the strands whose equilibrium is unstable, as ``hairinv invert``
does) and simulated with that stiffening in one process, after a warm-up
step:

* moving: the ``motion`` scene from 0.5 s, where the head turns fastest, for
  one 1/25 s frame (the dynamics benchmark's ruby rows run two); once a frame
  takes longer than ``FRAME_BUDGET``, the larger grooms are not run;
* still: the still scene for 1 s at the defaults (strands at rest sleep).

Recorded: the wall time per frame, the contacts, the sweeps per step and the
steps whose contact solve ended unconverged; and the slope of log time against
log strands (least squares), the exponent.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from common import DATA, IMG, ROOT, log, machine, machine_markdown, smoke, stiffened_strands, table  # type: ignore
else:
    from .common import DATA, IMG, ROOT, log, machine, machine_markdown, smoke, stiffened_strands, table

sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

import full_head  # type: ignore  # noqa: E402
from dynamics_bench import _moving, _settings  # type: ignore  # noqa: E402

from hairinv.config import DynamicsSettings  # noqa: E402
from hairinv.contacts.body import BodyMesh  # noqa: E402
from hairinv.dynamics.simulate import Motion, Simulation  # noqa: E402
from hairinv.invert import invert  # noqa: E402
from hairinv.model import Material  # noqa: E402
from hairinv.pipeline import prepare  # noqa: E402

TITLE = "Moving hair against strand count"
COUNTS = smoke((300, 600, 1200, 2400, 4867), (20, 40))
MOTION_START = 0.5
MOTION_SECONDS = smoke(0.04, 0.01)  # one frame
#: s: a moving frame that took longer ends the series (a larger groom would take longer still)
FRAME_BUDGET = smoke(300.0, 60.0)
STILL_SECONDS = smoke(1.0, 0.05)
PLOT = IMG / "bench_scale.png"


def _frames(sim: Simulation, seconds: float, motion_at) -> dict:
    h = sim.settings.time_step
    sim.step(motion_at(0.0))  # warm-up
    sim.clock = type(sim.clock)()
    steps = int(round(seconds / h))
    sweeps, unconverged = [], 0
    started = time.perf_counter()
    for i in range(steps):
        report = sim.step(motion_at((i + 1) * h))
        sweeps.append(report.sweeps)
        unconverged += report.status != "CONVERGED"
    wall = time.perf_counter() - started
    return {"per_frame": wall / seconds / 25.0, "sweeps": float(np.mean(sweeps)), "unconverged": unconverged,
            "steps": steps, "asleep": int(np.count_nonzero(sim.sleepers.asleep)),
            "attempts": sim.clock.attempts, "phases": dict(sim.clock.seconds)}


def measure(n: int, folder: Path) -> dict:
    path = full_head.write(n, folder / f"head_{n}.h5")
    settings = _settings(**{"contacts": {"hair_hair": True}, "solver": {"max_sweeps": smoke(300, 20)},
                            "body": {"scale": full_head.SCALE},
                            "dynamics": {"sleep_speed": DynamicsSettings().sleep_speed}})
    scene = prepare(path, DATA / "ruby" / "ruby_head.obj", settings)
    mat = Material.from_settings(settings.material, scene.up)
    model, _ = invert(scene.helices, scene.contacts, mat, settings.solver)  # as `hairinv invert` does: checked
    body = BodyMesh.from_mesh(scene.body)

    def sim():
        return Simulation(scene.helices, model.rest, mat, body, settings.contacts, settings.dynamics,
                          initial=scene.contacts, initial_force=model.force, stiffening=model.stiffening)
    turning = _moving(mat, scene.helices.root)
    log(f"scale: {n} strands, {scene.contacts.n_contacts} contacts, moving")
    moving = _frames(sim(), MOTION_SECONDS, lambda t: turning(MOTION_START + t))
    log(f"scale: {n} strands: {moving['per_frame']:.2f} s a frame moving; still")
    still = _frames(sim(), STILL_SECONDS, lambda t: Motion.still(mat.gravity))
    return {"strands": scene.helices.n_strands, "elements": scene.helices.n_elements,
            "contacts": scene.contacts.n_contacts, "hair": scene.contacts.n_hair, "moving": moving, "still": still,
            "stiffened": stiffened_strands(model)}


def _shares(phases: dict) -> str:
    """The three phases that took most of the time, with their shares."""
    total = sum(phases.values()) or 1.0
    top = sorted(phases.items(), key=lambda kv: -kv[1])[:3]
    return ", ".join(f"{name} {100 * seconds / total:.0f}%" for name, seconds in top)


def exponent(x, y) -> float:
    return float(np.polyfit(np.log(x), np.log(y), 1)[0]) if len(x) > 1 else float("nan")


def plot(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = np.array([r["strands"] for r in rows])
    fig, ax = plt.subplots(figsize=(6, 4.2))
    ax.loglog(n, [r["moving"]["per_frame"] for r in rows], "o-", label="moving (motion scene from 0.5 s)")
    ax.loglog(n, [r["still"]["per_frame"] for r in rows], "s-", label="still, 1 s (strands at rest sleep)")
    ax.axhline(5.0, color="grey", ls="--", lw=1)
    ax.text(n[0], 5.4, "5 s a frame", color="grey", fontsize=8)
    ax.set_xticks(n)
    ax.set_xticklabels([f"{k:,}" for k in n])
    ax.minorticks_off()
    ax.set_xlabel("strands (ruby short and long guides on ruby's head)")
    ax.set_ylabel("seconds of computing per 1/25 s frame")
    ax.set_title("Moving hair with hair-hair contact, against strand count")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def run() -> str:
    rows, skipped = [], []
    with tempfile.TemporaryDirectory() as folder:
        for n in COUNTS:
            if rows and rows[-1]["moving"]["per_frame"] > FRAME_BUDGET:
                skipped.append(n)
                continue
            rows.append(measure(n, Path(folder)))
    plot(rows, PLOT)
    n = [r["strands"] for r in rows]
    body = [[f"{r['strands']:,}", f"{r['elements']:,}", f"{r['contacts']:,} ({r['hair']:,})",
             f"{r['stiffened']:,}", f"{r['moving']['per_frame']:.2f} s",
             f"{r['moving']['attempts'] / r['moving']['steps']:.2f}", f"{r['moving']['sweeps']:.0f}",
             f"{r['moving']['unconverged']} of {r['moving']['steps']}",
             _shares(r["moving"]["phases"]), f"{r['still']['per_frame']:.3f} s", f"{r['still']['asleep']:,}"]
            for r in rows]
    moving = exponent(n, [r["moving"]["per_frame"] for r in rows])
    still = exponent(n, [r["still"]["per_frame"] for r in rows])
    info = machine()
    return "\n".join([
        f"## {TITLE}", "",
        "`bench/scale_bench.py`: grooms of 300 to 4,867 strands from the guides of ruby short and long on ruby's "
        "head (`bench/full_head.py`: a subset spread over the scalp), each fitted, detected with hair-hair "
        "contact and inverted as `hairinv invert` does (`solver.max_sweeps` 300; the stability check stiffens the "
        "strands whose equilibrium is unstable, and the simulation runs with their stiffening), then simulated in one "
        "process after a "
        "warm-up step: the `motion` scene from 0.5 s, where the head turns fastest, for one 1/25 s frame (its "
        "attempts per step count the halved steps' attempts, kept or thrown away), and "
        "the still scene for 1 s, at the defaults (strands at rest sleep). Wall time per frame.", "",
        table(["strands", "elements", "contacts (hair-hair)", "strands stiffened", "moving: s a frame",
               "attempts per step", "sweeps per step", "steps unconverged", "moving: largest phases", "still: s a frame",
               "asleep at the end"], body), "",
        f"Exponent (least-squares slope of log time against log strands): moving {moving:.2f}, still {still:.2f}."
        + (f" Not run: {', '.join(f'{n:,}' for n in skipped)} strands, after a moving frame took more than "
           f"{FRAME_BUDGET:.0f} s." if skipped else ""), "",
        f"![time per frame against strands](img/{PLOT.name})", "",
        machine_markdown(info), ""])


if __name__ == "__main__":
    print(run())
