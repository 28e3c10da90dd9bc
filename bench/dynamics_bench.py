"""Benchmark of the simulation (``hairinv.dynamics``): the paper's experiments and the speed.

Run alone with ``python bench/dynamics_bench.py`` (prints the markdown section),
or through ``bench/run.py``, which writes ``docs/benchmarks.md``.

Measured, in this order:

* the paper's controlled validation (its straightSynthSim): guide strands of
  the straight sample with a straight rest shape (q0 = 0) settle on the
  sample bust by simulation; the settled shape is inverted with target
  ``zero`` and the recovered rest curvature is compared with 0, beside the
  gravity-only inversion's;
* still body: the settled groom simulated for 2 s from the inverted model,
  from the naive model (q0 = the settled shape) and from the gravity-only
  model: the largest displacement of any strand point;
* body removed: the reference (q0 = 0) and the inverted model, both released
  from the settled shape without the body: how far apart they move;
* motion: the ``motion`` scene (head turn and nod) on the inverted model:
  energy, contact count and the deepest point inside the body;
* trim: the ``trim`` scene (strands cut at half length) on the inverted
  model: how much the tips rise;
* speed: seconds of computing per simulated second, against strands and contacts.
"""

from __future__ import annotations

import dataclasses
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from common import DATA, IMG, ROOT, log, smoke, table  # type: ignore
else:
    from .common import DATA, IMG, ROOT, log, smoke, table

sys.path.insert(0, str(ROOT))

from hairinv import config, stages  # noqa: E402
from hairinv._text import counted  # noqa: E402
from hairinv.config import DynamicsSettings  # noqa: E402
from hairinv.contacts import detect_contacts  # noqa: E402
from hairinv.contacts.body import BodyMesh  # noqa: E402
from hairinv.dynamics.run import _samples  # noqa: E402
from hairinv.dynamics.scene import Scene, trim_helices  # noqa: E402
from hairinv.dynamics.simulate import Motion, Simulation  # noqa: E402
from hairinv.gravity import generalized_gravity  # noqa: E402
from hairinv.invert import invert  # noqa: E402
from hairinv.model import Helices, Material, stiffness  # noqa: E402
from hairinv.pipeline import prepare  # noqa: E402

TITLE = "Simulating an inverted groom"
SAMPLES = ROOT / "samples"
GUIDES = smoke(40, 4)
SETTLE_SECONDS = smoke(4.0, 0.05)
SETTLE_AIR = 5.0  # 1/s: the reference settles faster; only the settled shape is kept
STILL_SECONDS = smoke(2.0, 0.05)
GRAVITY_ONLY_SECONDS = smoke(0.5, 0.02)  # it falls apart at once; the strands' fast motion makes its steps costly
RELEASE_SECONDS = smoke(1.0, 0.02)
RELEASE_FINE = 4  # the reference released again with the time step divided by this
MOTION_SECONDS = smoke(3.0, 0.05)
TRIM_SECONDS = smoke(1.0, 0.02)
SPEED_GUIDES = smoke(300, 4)
SPEED_MOTION_SECONDS = smoke(1.0, 0.02)
SPEED_REFERENCE_STEP = 0.0025  # s: the 300-strand motion scene's reference, a quarter of the default step
RUBY_SECONDS = smoke(0.04, 0.01)  # one frame: the drawn groom has strands that no rest shape holds (see speed())
RUBY_STILL_SECONDS = smoke(1.0, 0.05)  # sleeping: the strands at rest sleep after three steps
SLEEP_SPEED = DynamicsSettings().sleep_speed  # the default, for the speed rows
RUBY_MOTION_START = 0.5  # s into the motion scene: the head turns fastest (about 95 degrees/s)
RUBY_MOTION_SECONDS = smoke(0.08, 0.01)  # two frames
RUBY_START_SECONDS = smoke(0.2, 0.01)  # five frames from the scene's start, where the head starts turning
RUBY_TIGHT = dict(max_turn=0.1, stall_rounds=0)  # the tight reference: the default max_turn, every sweep (and
# RUBY_REFERENCE_SWEEPS of them)


def _defaults_label(when: str, changes: dict) -> str:
    """A row's label for earlier defaults: ``when`` they held, and the settings that differ from today's."""
    return f"same, the defaults {when} (dynamics." + ", ".join(f"{k} {v:g}" for k, v in changes.items()) + ")"


RUBY_BEFORE = dict(max_turn=0.05, max_sweeps=200, stall_rounds=3)  # the defaults before 2026-12-07: steps halved
# at half the turn, a solve stopped after three stalled rounds
BEFORE_LABEL = _defaults_label("before 2026-12-07", RUBY_BEFORE)
RUBY_CAPPED = dict(max_sweeps=50, stall_rounds=3)  # the defaults of 2026-12-07 (max_turn 0.1 as now): the sweeps
# capped, a solve stopped after three stalled rounds
CAPPED_LABEL = _defaults_label("of 2026-12-07", RUBY_CAPPED)
RUBY_REFERENCE_SWEEPS = smoke(1000, 20)  # per step, every one of them: the reference the moving rows are measured against
RUBY_NUDGE = 1e-9  # 1/m: the curvatures' perturbation (times a standard normal each) of the run that shows how far
# apart two runs drift that differ only by round-off-sized changes
PLOT_STILL = IMG / "bench_dynamics_still.png"
PLOT_SHAPES = IMG / "bench_dynamics_shapes.png"


def _settings(**sections):
    """The defaults with ``sections`` changed; nothing sleeps unless ``dynamics.sleep_speed`` is given: the
    physics is measured step by step (the speed rows say where strands sleep, as they do by default)."""
    sections = {**sections, "dynamics": {"sleep_speed": 0.0, **sections.get("dynamics", {})}}
    return config.apply(config.resolve(), sections)


def _displacement(helices: Helices, q_start: np.ndarray, q: np.ndarray) -> float:
    return max(float(np.max(np.linalg.norm(a - b, axis=1)))
               for a, b in zip(_samples(helices, q), _samples(helices, q_start)))


def _run(sim: Simulation, seconds: float, motion_at, every: float = smoke(0.1, 0.01), watch=None) -> dict:
    """Step ``sim`` for ``seconds``; sample displacement, energy and contacts every ``every`` s."""
    h = sim.settings.time_step
    q_start = sim.q.copy()
    trace = {"t": [0.0], "moved": [0.0], "kinetic": [0.0], "contacts": [], "deepest": 0.0, "sweeps": [],
             "unconverged": 0, "substeps": 0}
    steps = int(round(seconds / h))
    per = max(1, int(round(every / h)))
    started = time.perf_counter()
    for i in range(steps):
        report = sim.step(motion_at(i * h))
        trace["sweeps"].append(report.sweeps)
        trace["unconverged"] += report.status != "CONVERGED"
        trace["substeps"] += report.substeps - 1
        body = sim.contacts.strand[:, 1] < 0
        if body.any() and sim.contacts.gap is not None:
            trace["deepest"] = min(trace["deepest"], float(sim.contacts.gap[body].min()))
        if (i + 1) % per == 0:
            trace["t"].append((i + 1) * h)
            trace["moved"].append(_displacement(sim.helices, q_start, sim.q))
            trace["kinetic"].append(sim.kinetic_energy())
            trace["contacts"].append(sim.contacts.n_contacts)
            if watch is not None:
                watch(trace)
    trace["seconds"] = time.perf_counter() - started
    trace["q"] = sim.q.copy()
    return trace


def settle(helices: Helices, mat: Material, body: BodyMesh, settings) -> tuple[Helices, dict]:
    """The reference: straight rest shape, dropped from the sample's shape onto the bust."""
    dyn = dataclasses.replace(settings.dynamics, air_damping=SETTLE_AIR)
    sim = Simulation(helices, np.zeros_like(helices.omega), mat, body, settings.contacts, dyn)
    trace = _run(sim, SETTLE_SECONDS, lambda t: Motion.still(mat.gravity), every=0.5)
    settled = dataclasses.replace(helices, omega=sim.q.copy())
    return settled, trace


def mean_curvature(q0: np.ndarray, length: np.ndarray) -> tuple[float, float]:
    """Length-weighted mean of |q0| (1/m): all three components, and the two curvatures alone."""
    w = length / length.sum()
    return float(np.sum(np.linalg.norm(q0, axis=1) * w)), float(np.sum(np.linalg.norm(q0[:, :2], axis=1) * w))


def validation() -> dict:
    settings = _settings(**{"import": {"guides": GUIDES}, "solver": {"max_sweeps": 20000, "tolerance": 1e-6}})
    scene = prepare(SAMPLES / "straight.h5", SAMPLES / "body.obj", settings, contacts=False)
    mat = Material.from_settings(settings.material, scene.up)
    body = BodyMesh.from_mesh(scene.body)
    log(f"settling {scene.helices.n_strands} straight strands for {SETTLE_SECONDS} s")
    settled, settle_trace = settle(scene.helices, mat, body, settings)
    contacts, _ = detect_contacts(settled, body, settings.contacts)
    started = time.perf_counter()
    model, report = invert(settled, contacts, mat, dataclasses.replace(settings.solver, target="zero"))
    invert_seconds = time.perf_counter() - started
    gravity_only = settled.omega - generalized_gravity(settled, mat) / stiffness(settled, mat).reshape(-1, 3)
    still = lambda t: Motion.still(mat.gravity)  # noqa: E731
    runs = {}
    for label, rest, initial, force, seconds in (
            ("inverted", model.rest, contacts, model.force, STILL_SECONDS),
            ("naive", settled.omega, contacts, None, STILL_SECONDS),
            ("gravity-only", gravity_only, contacts, None, GRAVITY_ONLY_SECONDS)):
        log(f"still body, {label}, {seconds} s")
        sim = Simulation(settled, rest, mat, body, settings.contacts, settings.dynamics, initial=initial,
                         initial_force=force, stiffening=model.stiffening if label == "inverted" else None)
        runs[label] = _run(sim, seconds, still)
    no_body = dataclasses.replace(settings.contacts, body=False)
    released = {}
    # the reference once more at a quarter of the time step: how far the falling groom's own motion is
    # settled by the step, the scale the gap between reference and inverted is to be read against
    fine = dataclasses.replace(settings.dynamics, time_step=settings.dynamics.time_step / RELEASE_FINE)
    for label, rest, force, dynamics in (
            ("reference", np.zeros_like(settled.omega), None, settings.dynamics),
            ("inverted", model.rest, model.force, settings.dynamics),
            ("reference, fine step", np.zeros_like(settled.omega), None, fine)):
        log(f"body removed, {label}, {RELEASE_SECONDS} s")
        hair_only = contacts.subset(contacts.strand[:, 1] >= 0)
        sim = Simulation(settled, rest, mat, None, no_body, dynamics, initial=hair_only,
                         initial_force=None if force is None else force[contacts.strand[:, 1] >= 0],
                         stiffening=model.stiffening if label == "inverted" else None)
        samples = []
        released[label] = _run(sim, RELEASE_SECONDS, still,
                               watch=lambda tr, sim=sim, samples=samples: samples.append(_samples(settled, sim.q)))
        released[label]["samples"] = samples
    gaps = [max(float(np.max(np.linalg.norm(a - b, axis=1))) for a, b in zip(x, y))
            for x, y in zip(released["reference"]["samples"], released["inverted"]["samples"])]
    step_gaps = [max(float(np.max(np.linalg.norm(a - b, axis=1))) for a, b in zip(x, y))
                 for x, y in zip(released["reference"]["samples"], released["reference, fine step"]["samples"])]
    fallen = [max(float(np.max(np.linalg.norm(a - b, axis=1))) for a, b in
                  zip(x, _samples(settled, settled.omega))) for x in released["reference"]["samples"]]
    # the same groom through its file: samples/settled.h5 holds these centre lines (samples/make_settled.py),
    # refitted at the default 0.2 mm tolerance, detected and inverted as `hairinv invert` does
    file_settings = _settings(**{"solver": {"max_sweeps": 20000, "tolerance": 1e-6, "target": "zero"}})
    with tempfile.TemporaryDirectory() as folder:
        curves_only = Path(folder) / "settled_curves.h5"  # without the file's /helices, so it is fitted again
        stages.write_stage(curves_only, [stages.read_stage(SAMPLES / "settled.h5")[stages.CURVES]], "bench")
        refit = prepare(curves_only, SAMPLES / "body.obj", file_settings)
    refit_model, refit_report = invert(refit.helices, refit.contacts, mat, file_settings.solver)
    log(f"still body, inverted from the refitted file, {STILL_SECONDS} s")
    sim = Simulation(refit.helices, refit_model.rest, mat, body, file_settings.contacts,
                     file_settings.dynamics, initial=refit.contacts, initial_force=refit_model.force,
                     stiffening=refit_model.stiffening)
    runs["inverted, refitted from settled.h5"] = _run(sim, STILL_SECONDS, still)
    runs["inverted, refitted from settled.h5"]["unstable"] = refit_report.unstable
    return {"settings": settings, "mat": mat, "body": body, "scene": scene, "settled": settled,
            "settle": settle_trace, "contacts": contacts, "model": model, "report": report,
            "invert_seconds": invert_seconds,
            "error": mean_curvature(model.rest, settled.length),
            "error_gravity_only": mean_curvature(gravity_only, settled.length),
            "runs": runs, "released": released, "release_gap": gaps, "release_fall": fallen,
            "release_step_gap": step_gaps}


def motion_and_trim(v: dict) -> dict:
    settings, mat, body, settled, model, contacts = (v[k] for k in ("settings", "mat", "body", "settled", "model",
                                                                      "contacts"))
    up = -mat.gravity / np.linalg.norm(mat.gravity)
    scene = Scene.load("motion")
    pivot = scene.pivot_point(settled.root)

    def moving(t: float) -> Motion:
        m = scene.body_motion(t, pivot, up)
        R = m.R
        return Motion(R.T @ mat.gravity, R.T @ m.acceleration, R.T @ m.velocity, R.T @ m.omega, R.T @ m.alpha)

    log(f"motion scene, {MOTION_SECONDS} s")
    sim = Simulation(settled, model.rest, mat, body, settings.contacts, settings.dynamics, initial=contacts,
                     initial_force=model.force, stiffening=model.stiffening)
    motion = _run(sim, MOTION_SECONDS, moving)
    # trim: a curly groom (its own shape as the reference rest shape) settled on the bust, inverted with
    # target actual, then cut at half length: reference and inverted model side by side
    wavy_settings = _settings(**{"import": {"guides": GUIDES}, "solver": {"max_sweeps": 5000}})
    wavy = prepare(SAMPLES / "curly.h5", SAMPLES / "body.obj", wavy_settings, contacts=False)
    log(f"settling {wavy.helices.n_strands} curly strands for {SETTLE_SECONDS} s")
    ref_rest = wavy.helices.omega.copy()
    dyn = dataclasses.replace(wavy_settings.dynamics, air_damping=SETTLE_AIR)
    sim = Simulation(wavy.helices, ref_rest, mat, body, wavy_settings.contacts, dyn)
    _run(sim, SETTLE_SECONDS, lambda t: Motion.still(mat.gravity), every=0.5)
    settled_wavy = dataclasses.replace(wavy.helices, omega=sim.q.copy())
    wavy_contacts, _ = detect_contacts(settled_wavy, body, wavy_settings.contacts)
    wavy_model, wavy_report = invert(settled_wavy, wavy_contacts, mat, wavy_settings.solver)
    trim = Scene.load("trim")
    cut, element_map = trim_helices(settled_wavy, length=trim.trim.length, fraction=trim.trim.fraction)
    tips_before = np.array([p[-1] for p in _samples(cut, cut.omega)])
    rises, trims = {}, {}
    for label, rest in (("reference", ref_rest), ("inverted", wavy_model.rest)):
        log(f"trim scene, {label}, {TRIM_SECONDS} s")
        sim = Simulation(cut, rest[element_map], mat, body, wavy_settings.contacts, wavy_settings.dynamics,
                         stiffening=wavy_model.stiffening if label == "inverted" else None)
        trims[label] = _run(sim, TRIM_SECONDS, lambda t: Motion.still(mat.gravity))
        tips_after = np.array([p[-1] for p in _samples(cut, sim.q)])
        rises[label] = (tips_after - tips_before) @ up
    curly_still = {}
    for label, rest, force in (("inverted", wavy_model.rest, wavy_model.force), ("naive", settled_wavy.omega,
                                                                                      None)):
        log(f"still body, curly, {label}, {STILL_SECONDS} s")
        sim = Simulation(settled_wavy, rest, mat, body, wavy_settings.contacts, wavy_settings.dynamics,
                         initial=wavy_contacts, initial_force=force,
                         stiffening=wavy_model.stiffening if label == "inverted" else None)
        curly_still[label] = _run(sim, STILL_SECONDS, lambda t: Motion.still(mat.gravity))
    w = settled_wavy.length / settled_wavy.length.sum()
    recovered = float(np.sum(np.linalg.norm(wavy_model.rest - ref_rest, axis=1) * w))
    unchanged = float(np.sum(np.linalg.norm(settled_wavy.omega - ref_rest, axis=1) * w))
    return {"motion": motion, "trim": trims, "rise": rises, "cut_strands": cut.n_strands,
            "curly_unstable": wavy_report.unstable, "curly_still": curly_still,
            "wavy_recovered": recovered, "wavy_settled_vs_rest": unchanged}


def _moving(mat: Material, roots: np.ndarray):
    """The ``motion`` scene's body motion as seen in the body's frame, for ``Simulation.step``."""
    up = -mat.gravity / np.linalg.norm(mat.gravity)
    scene = Scene.load("motion")
    pivot = scene.pivot_point(roots)

    def at(t: float) -> Motion:
        m = scene.body_motion(t, pivot, up)
        R = m.R
        return Motion(R.T @ mat.gravity, R.T @ m.acceleration, R.T @ m.velocity, R.T @ m.omega, R.T @ m.alpha)
    return at


def _speed_row(label: str, sim: Simulation, seconds: float, motion_at, hair_hair: bool, mat: Material) -> dict:
    sim.step(motion_at(0.0))  # compile and warm up
    trace = _run(sim, seconds, motion_at, every=seconds)
    return {"label": label, "strands": sim.helices.n_strands, "elements": sim.helices.n_elements,
            "contacts": int(np.mean(trace["contacts"])) if trace["contacts"] else 0, "hair_hair": hair_hair,
            "simulated": seconds, "seconds": trace["seconds"], "per_second": trace["seconds"] / seconds,
            "per_frame": trace["seconds"] / seconds / 25.0, "moved": trace["moved"][-1],
            "sweeps": float(np.mean(trace["sweeps"])) if trace["sweeps"] else 0.0,
            "substeps": trace["substeps"], "steps": len(trace["sweeps"]), "q": trace["q"]}


def _strand_deviation(helices: Helices, q: np.ndarray, q_ref: np.ndarray) -> np.ndarray:
    """m, per strand: the largest distance between a point of ``q`` and the same point of ``q_ref``."""
    return np.array([float(np.max(np.linalg.norm(a - b, axis=1)))
                     for a, b in zip(_samples(helices, q), _samples(helices, q_ref))])


@dataclasses.dataclass
class SpeedGroom:
    """A groom of the speed rows, inverted and ready to simulate at the defaults (strands at rest sleep)."""

    settings: object
    mat: Material
    body: BodyMesh
    helices: Helices
    contacts: object
    model: object

    def simulation(self, **dynamics) -> Simulation:
        """From the inverted model at rest (``dynamics``: settings changed from the groom's)."""
        return Simulation(self.helices, self.model.rest, self.mat, self.body, self.settings.contacts,
                          dataclasses.replace(self.settings.dynamics, **dynamics), initial=self.contacts,
                          initial_force=self.model.force, stiffening=self.model.stiffening)


def settled_straight() -> tuple[SpeedGroom, float]:
    """``SPEED_GUIDES`` strands of the straight sample settled on the bust without hair-hair contact and
    inverted with target zero, and the seconds the settling took."""
    settings = _settings(**{"import": {"guides": SPEED_GUIDES}, "contacts": {"hair_hair": False},
                            "dynamics": {"sleep_speed": SLEEP_SPEED}})
    scene = prepare(SAMPLES / "straight.h5", SAMPLES / "body.obj", settings, contacts=False)
    mat = Material.from_settings(settings.material, scene.up)
    body = BodyMesh.from_mesh(scene.body)
    log(f"speed: settling {SPEED_GUIDES} straight strands without hair-hair contact, {SETTLE_SECONDS} s")
    started = time.perf_counter()
    settled, _ = settle(scene.helices, mat, body, settings)
    settle_seconds = time.perf_counter() - started
    contacts, _ = detect_contacts(settled, body, settings.contacts)
    model, _ = invert(settled, contacts, mat, dataclasses.replace(settings.solver, target="zero"),
                      check_stability=False)
    return SpeedGroom(settings, mat, body, settled, contacts, model), settle_seconds


def ruby_short() -> SpeedGroom | None:
    """Ruby short as drawn (1,867 strands, hair-hair contact), inverted with ``solver.max_sweeps`` 300 and the
    stability check (as ``hairinv invert`` does); None without the real data."""
    ruby = DATA / "ruby" / "ruby_short_hair_16_guide.tfx"
    if not ruby.exists():
        return None
    log("speed: ruby short, 1,867 strands, hair-hair on")
    extra = {"import": {"scale": 0.002, "guides": smoke(0, 10)}, "contacts": {"hair_hair": True},
             "solver": {"max_sweeps": smoke(300, 20)}, "dynamics": {"sleep_speed": SLEEP_SPEED}}
    settings = _settings(**extra)
    scene = prepare(ruby, DATA / "ruby" / "ruby_head.obj", settings)
    mat = Material.from_settings(settings.material, scene.up)
    model, _ = invert(scene.helices, scene.contacts, mat, settings.solver)  # as `hairinv invert` does: checked
    return SpeedGroom(settings, mat, BodyMesh.from_mesh(scene.body), scene.helices, scene.contacts, model)


def speed() -> list[dict]:
    """Seconds per simulated second on grooms at rest (settled by simulation), still and moving.

    A drawn groom is not a fair case: many of its strands rest in an unstable equilibrium whatever
    their rest shape (docs/dynamics.md), so once round-off has grown (about 0.2 s for the drawn
    straight sample) the simulation spends its time on strands falling away, in halved steps.
    """
    points = []
    straight, settle_seconds = settled_straight()
    settings, mat, body, settled, contacts, model = (straight.settings, straight.mat, straight.body,
                                                     straight.helices, straight.contacts, straight.model)
    still = lambda t: Motion.still(mat.gravity)  # noqa: E731
    for label, rest, force, motion_at, seconds in (
            ("settled straight, its own rest shape, still", np.zeros_like(settled.omega), None, still, 1.0),
            ("settled straight, inverted, still", model.omega_rest, model.force, still, 1.0),
            ("same, nothing sleeps (dynamics.sleep_speed 0)", model.omega_rest, model.force, still, 1.0),
            ("settled straight, inverted, motion scene", model.omega_rest, model.force,
             _moving(mat, settled.root), SPEED_MOTION_SECONDS)):
        log(f"speed: {label}")
        dynamics = dataclasses.replace(settings.dynamics, sleep_speed=0.0) if "nothing sleeps" in label else \
            settings.dynamics
        sim = Simulation(settled, rest, mat, body, settings.contacts, dynamics,
                         initial=contacts if force is not None else None, initial_force=force)
        points.append(_speed_row(label, sim, seconds, motion_at, False, mat))
    # the motion scene at the defaults before 2026-12-07, and a reference with a quarter of the step, every sweep
    motion_rows = [points[-1]]
    for label, changes in ((BEFORE_LABEL, RUBY_BEFORE),
                           (f"reference: time_step {SPEED_REFERENCE_STEP:g}, tolerance 1e-08, every sweep",
                            dict(time_step=SPEED_REFERENCE_STEP, tolerance=1e-8, max_sweeps=1000, stall_rounds=0))):
        log(f"speed: settled straight, motion scene, {label}")
        sim = Simulation(settled, model.omega_rest, mat, body, settings.contacts,
                         dataclasses.replace(settings.dynamics, **changes), initial=contacts,
                         initial_force=model.force)
        points.append(_speed_row(label, sim, SPEED_MOTION_SECONDS, _moving(mat, settled.root), False, mat))
        motion_rows.append(points[-1])
    for p in motion_rows[:-1]:
        p["deviation"] = _strand_deviation(settled, p["q"], motion_rows[-1]["q"])
    points[0]["settle_seconds"] = settle_seconds
    ruby = ruby_short()
    if ruby is not None:
        rs, rmat, rscene = ruby.settings, ruby.mat, ruby
        points.append(_speed_row(f"ruby short (as drawn), inverted, still, {RUBY_STILL_SECONDS:g} s",
                                 ruby.simulation(), RUBY_STILL_SECONDS, lambda t: Motion.still(rmat.gravity), True,
                                 rmat))
        sim = ruby.simulation(sleep_speed=0.0)
        points.append(_speed_row("same, one frame, nothing sleeps (dynamics.sleep_speed 0)", sim, RUBY_SECONDS,
                                 lambda t: Motion.still(rmat.gravity), True, rmat))
        turning = _moving(rmat, rscene.helices.root)
        # the defaults; the defaults before 2026-12-07 (half the turn before a step is halved, three stalled
        # rounds before a solve stops); those of 2026-12-07 (50 sweeps at most, three stalled rounds); the defaults
        # with every sweep (no early stop of a stalled contact solve, the sweeps of the
        # defaults before), and the reference: every sweep, RUBY_REFERENCE_SWEEPS of them. Each moving row is
        # measured against the reference. Two more runs show how far apart runs drift that should agree: the
        # default from a start perturbed by round-off-sized curvatures, and the reference at the earlier max_turn
        moving = []
        for label, changes, nudge in (
                (f"ruby short (as drawn), inverted, motion scene from {RUBY_MOTION_START:g} s, "
                 f"{RUBY_MOTION_SECONDS / 0.04:.0f} frames", {}, False),
                (BEFORE_LABEL, RUBY_BEFORE, False),
                (CAPPED_LABEL, RUBY_CAPPED, False),
                (f"same, every sweep (dynamics.stall_rounds 0, max_sweeps {RUBY_BEFORE['max_sweeps']})",
                 dict(stall_rounds=0, max_sweeps=RUBY_BEFORE["max_sweeps"]), False),
                (f"the defaults, the start's curvatures perturbed by {RUBY_NUDGE:g} 1/m", {}, True),
                (f"reference at max_turn {RUBY_BEFORE['max_turn']:g}: every sweep, {RUBY_REFERENCE_SWEEPS} per step",
                 dict(RUBY_TIGHT, max_turn=RUBY_BEFORE["max_turn"], max_sweeps=RUBY_REFERENCE_SWEEPS), False),
                (f"reference: max_turn {RUBY_TIGHT['max_turn']:g}, every sweep, {RUBY_REFERENCE_SWEEPS} per step",
                 dict(RUBY_TIGHT, max_sweeps=RUBY_REFERENCE_SWEEPS), False)):
            log(f"speed: ruby short, motion scene, {label}")
            sim = ruby.simulation(**changes)
            if nudge:
                sim.q = sim.q + RUBY_NUDGE * np.random.default_rng(0).standard_normal(sim.q.shape)
            points.append(_speed_row(label, sim, RUBY_MOTION_SECONDS, lambda t: turning(RUBY_MOTION_START + t),
                                     True, rmat))
            moving.append(points[-1])
        for p in moving[:-1]:
            p["deviation"] = _strand_deviation(rscene.helices, p["q"], moving[-1]["q"])
        default, nudged, fine_reference, reference = moving[0], moving[4], moving[5], moving[6]
        default["spread"] = [
            ("the defaults, and the same from the perturbed start", default, nudged),
            (f"the reference at max_turn {RUBY_TIGHT['max_turn']:g}, and at {RUBY_BEFORE['max_turn']:g}",
             reference, fine_reference),
            (f"the defaults, and the reference at max_turn {RUBY_BEFORE['max_turn']:g}", default, fine_reference)]
        default["spread"] = [(label, _strand_deviation(rscene.helices, a["q"], b["q"]))
                             for label, a, b in default["spread"]]
        # from the scene's start, as a user's run starts: the defaults, the defaults before, and the reference
        frames = f"{RUBY_START_SECONDS / 0.04:.0f} frames"
        started = []
        for label, changes in ((f"the defaults, motion scene from its start, {frames}", {}),
                               (BEFORE_LABEL, RUBY_BEFORE),
                               (CAPPED_LABEL, RUBY_CAPPED),
                               (f"reference from the start: max_turn {RUBY_TIGHT['max_turn']:g}, every sweep, "
                                f"{RUBY_REFERENCE_SWEEPS} per step", dict(RUBY_TIGHT, max_sweeps=RUBY_REFERENCE_SWEEPS))):
            log(f"speed: ruby short, {label}")
            points.append(_speed_row(label, ruby.simulation(**changes), RUBY_START_SECONDS, turning, True, rmat))
            started.append(points[-1])
        for p in started[:-1]:
            p["deviation"] = _strand_deviation(rscene.helices, p["q"], started[-1]["q"])
    return points


def plot(v: dict, path_still: Path, path_shapes: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    for label, style in (("inverted", "-"), ("naive", "--"), ("gravity-only", ":")):
        run = v["runs"][label]
        moved = np.maximum(np.array(run["moved"]) * 1e3, 1e-9)
        ax.semilogy(run["t"], moved, style, label=label)
    ax.axhline(0.1, color="grey", lw=0.8)
    ax.text(1.55, 0.15, "0.1 mm", color="grey")
    ax.set_xlabel("simulated time (s)")
    ax.set_ylabel("largest displacement (mm)")
    ax.set_title(f"Still body: {v['settled'].n_strands} settled strands, three rest shapes")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path_still, dpi=120)
    plt.close(fig)

    settled = v["settled"]
    up = -v["mat"].gravity / np.linalg.norm(v["mat"].gravity)
    side = np.array([0.0, 0.0, 1.0]) if abs(up[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    horizontal = np.cross(up, side)
    fig, axes = plt.subplots(1, 3, figsize=(10, 4.2), sharex=True, sharey=True)
    shapes = (("input (settled)", settled.omega), ("inverted, after 2 s", v["runs"]["inverted"]["q"]),
              ("naive, after 2 s", v["runs"]["naive"]["q"]))
    verts = np.asarray(v["scene"].body.vertices)
    start = _samples(settled, settled.omega, per_element=4)
    for index, (ax, (title, q)) in enumerate(zip(axes, shapes)):
        ax.scatter(verts @ horizontal, verts @ up, s=0.2, color="0.85")
        if index:
            for pts in start:
                ax.plot(pts @ horizontal, pts @ up, lw=1.6, color="0.75")
        for pts in _samples(settled, q, per_element=4):
            ax.plot(pts @ horizontal, pts @ up, lw=0.7)
        ax.set_title(title)
        ax.set_aspect("equal")
        ax.set_xlabel("side (m)")
    axes[0].set_ylabel("up (m)")
    fig.suptitle("The groom on the sample bust (grey: the input)")
    fig.tight_layout()
    fig.savefig(path_shapes, dpi=120)
    plt.close(fig)


def run() -> str:
    v = validation()
    mt = motion_and_trim(v)
    points = speed()
    IMG.mkdir(parents=True, exist_ok=True)
    plot(v, PLOT_STILL, PLOT_SHAPES)
    return render(v, mt, points)


def _mm(x: float) -> str:
    if x == 0:
        return "0"
    return f"{1e3 * x:.3g}" if x >= 1e-6 else f"{1e3 * x:.1e}"


def render(v: dict, mt: dict, points: list[dict]) -> str:
    runs, rep = v["runs"], v["report"]
    lines = [f"## {TITLE}", "",
             "`bench/dynamics_bench.py`. Sample bust, default settings (time step 10 ms, the contact solve to "
             "1e-6 of g h), unless stated. Single runs: each simulation is deterministic and takes seconds to "
             "minutes.", "",
             "### The paper's controlled validation", "",
             f"{v['settled'].n_strands} guide strands of the straight sample, with a straight rest shape "
             f"(q0 = 0), were dropped on the bust and simulated for {SETTLE_SECONDS:g} s (air drag "
             f"{SETTLE_AIR:g} /s, to settle faster) into a resting groom with {v['contacts'].n_contacts} contacts "
             f"({v['contacts'].n_body} on the body). That groom was inverted with target `zero`. The paper "
             "recovered a mean rest curvature of 0.9 1/m against 9.9 1/m without contacts; the target here was "
             "under 0.3 1/m.", ""]
    e, g = v["error"], v["error_gravity_only"]
    lines += [table(["inversion", "mean |q0| (1/m), all three", "mean curvature (1/m), bending only"],
                    [("with contacts (hairinv, target zero)", f"{e[0]:.3g}", f"{e[1]:.3g}"),
                     ("gravity only", f"{g[0]:.3g}", f"{g[1]:.3g}")]), "",
              f"The inversion took {v['invert_seconds']:.1f} s ({rep.result.sweeps} sweeps, status {rep.result.status}, relative "
              f"residual {rep.result.relative_residual:.1e}); {rep.unstable} of {v['settled'].n_strands} strands are flagged "
              f"unstable, against {rep.unstable_gravity_only} for the gravity-only inversion.", "",
              "### Still body", "",
              "The settled groom, simulated from three rest shapes with the body still. The largest "
              "displacement is over every strand point, from where it started.", ""]
    rows = []
    for label in ("inverted", "naive", "gravity-only", "inverted, refitted from settled.h5"):
        r = runs[label]
        rows.append((label, f"{r['t'][-1]:g}", _mm(max(r["moved"])), f"{r['seconds']:.1f}",
                     f"{r['unconverged']} of {len(r['sweeps'])}"))
    lines += [table(["rest shape", "simulated (s)", "largest displacement (mm)", "wall time (s)",
                     "steps at the sweep cap"], rows), "",
              f"The last row is the same groom's centre lines (the `/curves` of `samples/settled.h5`, written by "
              "`samples/make_settled.py`) fitted again at the default 0.2 mm tolerance, as `hairinv invert` does "
              "with curves: "
              f"{runs['inverted, refitted from settled.h5']['unstable']} strands are then left unstable after "
              "stabilisation, and the groom moves by at most "
              f"{_mm(max(runs['inverted, refitted from settled.h5']['moved']))} mm. The refitted shape is no longer "
              "exactly the simulator's own equilibrium, but the inversion makes it one, stable strand by strand "
              "under its contact forces held fixed.", "",
              f"![displacement against time](img/{PLOT_STILL.name})", "",
              f"![the groom after 2 s](img/{PLOT_SHAPES.name})", "",
              "### Body removed", "",
              f"Both the reference (q0 = 0) and the inverted model released from the settled shape without the "
              f"body for {RELEASE_SECONDS:g} s: the hair falls by up to {_mm(max(v['release_fall']))} mm; the two "
              f"stay within {_mm(max(v['release_gap']))} mm of each other (largest distance between the same "
              "strand point in the two runs, over the run). The reference run itself, repeated with a "
              f"{RELEASE_FINE}x shorter time step, ends up to {_mm(max(v['release_step_gap']))} mm from the first "
              "(strands falling against each other are sensitive to small differences): "
              + ("the gap between the two models is no larger than the motion's own sensitivity to the step."
                 if max(v['release_gap']) <= max(v['release_step_gap']) else
                 "the gap between the two models is larger than the motion's own sensitivity to the step."), "",
              "### Motion and trim", ""]
    m = mt["motion"]
    lines += [f"The `motion` scene (a 50 degree head turn and a 20 degree nod, back by 2.2 s) for "
              f"{MOTION_SECONDS:g} s on the inverted model: kinetic energy at most {max(m['kinetic']):.3g} J and "
              f"{m['kinetic'][-1]:.3g} J at the end; contacts {min(m['contacts'])}-{max(m['contacts'])}; "
              + (f"the deepest body contact {_mm(-m['deepest'])} mm inside the surface" if m['deepest'] < 0 else
                 "no body contact inside the surface")
              + f" (the contact radius is {_mm(v['settings'].contacts.body_distance)} mm); {m['substeps']} extra "
              f"substeps (from halved steps); wall time "
              f"{m['seconds']:.1f} s.", "",
              f"Trim: {mt['cut_strands']} strands of the curly sample with their drawn shape as the rest shape "
              f"(the reference) were settled on the bust for {SETTLE_SECONDS:g} s and inverted with target "
              f"`actual`: the inverted rest shape is {mt['wavy_recovered']:.3g} 1/m from the reference's (mean "
              f"|q0 - q0_ref|; the settled shape itself is {mt['wavy_settled_vs_rest']:.3g} 1/m from it; "
              f"{mt['curly_unstable']} strands flagged unstable). With the body still, for {STILL_SECONDS:g} s, "
              "from its inverted model and from the naive one:", "",
              table(["rest shape", "largest displacement (mm)", "wall time (s)"],
                    [(label, _mm(max(mt["curly_still"][label]["moved"])), f"{mt['curly_still'][label]['seconds']:.1f}")
                     for label in ("inverted", "naive")]), "",
              f"Both the reference and the inverted model cut at half length (the `trim` scene) and simulated "
              f"for {TRIM_SECONDS:g} s; the rise of the new tips:", "",
              table(["rest shape", "median rise (mm)", "strands whose tip rose by over 0.1 mm", "wall time (s)"],
                    [(label, f"{1e3 * float(np.median(mt['rise'][label])):.3g}",
                      f"{int(np.sum(mt['rise'][label] > 1e-4))} of {len(mt['rise'][label])}",
                      f"{mt['trim'][label]['seconds']:.1f}") for label in ("reference", "inverted")]), "",
              "### Speed", "",
              f"{SPEED_GUIDES} strands of the straight sample settled on the bust by simulation "
              f"({SETTLE_SECONDS:g} s, straight rest shape, no hair-hair contact; the settling itself took "
              f"{points[0].get('settle_seconds', float('nan')):.0f} s), then simulated from their own rest shape "
              "and from the model inverted with target zero, with the body still and in the `motion` scene "
              "(head turn and lean); and ruby short as drawn, inverted as `hairinv invert` does (its stability check "
              "stiffens the strands whose equilibrium no rest shape makes stable, and the simulation runs with their "
              "stiffening), still, over one frame with nothing asleep "
              f"and over {RUBY_STILL_SECONDS:g} s at the defaults, where the strands at rest sleep, and in the `motion` scene over {RUBY_MOTION_SECONDS / 0.04:.0f} frames from "
              f"{RUBY_MOTION_START:g} s, where the head turns fastest (the simulation starts there from the "
              "inverted model at rest on the body, so the hair is jerked into the turn), and over "
              f"{RUBY_START_SECONDS / 0.04:.0f} frames from the scene's start, as a user's run starts, where the head "
              "starts turning. Each run starts after one "
              "warm-up step; `moved` is the largest displacement of any strand point at the end. The small case is "
              "a settled groom, whose strands rest stably without stiffening; many of a drawn groom's need it "
              "(docs/dynamics.md). The speed rows run at the defaults, where strands at rest "
              "sleep (`dynamics.sleep_speed`, docs/dynamics.md) unless the row says otherwise; the other sections of this "
              "benchmark measure the physics with nothing asleep. Targets: 300 strands without hair-hair "
              "contact faster than real time (1 s per simulated second), 2,000 strands with hair-hair "
              "contact under 5 s per 1/25 s frame.", ""]
    rows = [(p["label"], str(p["strands"]), str(p["elements"]), "on" if p["hair_hair"] else "off", str(p["contacts"]),
             f"{p['simulated']:g}", _mm(p["moved"]), f"{p['sweeps']:.0f}", str(p["substeps"]),
             f"{p['per_second']:.2f}", f"{p['per_frame']:.2f}",
             " / ".join(_mm(x) for x in np.percentile(p["deviation"], [50, 90, 100])) if "deviation" in p else "")
            for p in points]
    lines += [table(["groom", "strands", "elements", "hair-hair", "contacts", "simulated (s)", "moved (mm)",
                     "sweeps per step", "extra substeps", "s per simulated s", "s per 1/25 s frame",
                     "from the reference (mm): median / 90% / largest"], rows), "",
              "The last column: for each strand, the largest distance between a point at the end of the run and "
              "the same point at the end of the reference run from the same start (the rows `reference: max_turn ...` and "
              "`reference from the start: ...`), then the median, 90th percentile "
              "and largest over the strands. Dense moving hair-hair contact solved contact by contact rarely "
              "meets the tolerance: each step runs until its residual stops halving (`dynamics.stall_rounds`: "
              f"{counted(DynamicsSettings().stall_rounds, 'round')} that did not halve it) or all its sweeps are spent.", ""]
    spread = next((p["spread"] for p in points if "spread" in p), None)
    if spread:
        lines += ["How far apart runs drift that should agree, measured the same way (the two runs of each line against "
                  "each other): the moving groom is sensitive, to its start and to how each step is solved, so a "
                  "distance from the reference means something only against these.", "",
                  table(["runs", "apart (mm): median / 90% / largest"],
                        [(label, " / ".join(_mm(x) for x in np.percentile(d, [50, 90, 100]))) for label, d in spread]),
                  ""]
    return "\n".join(lines)


if __name__ == "__main__":
    print(run())
