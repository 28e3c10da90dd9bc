"""What an absent feature costs: each stage with a feature on and off, on one sample groom.

A scene says what exists (docs/scenes.md, "What a scene models"); what it leaves out should cost
nothing. On the sample wavy groom on the sample bust, each stage runs with a feature on and with it off,
in this process, alternately, and the medians of several runs are compared: detection with and without
hair-hair contact and without a body; the inversion with and without the stability check, with
frictionless contacts (the same contacts, mu = 0), with and without stiffening (the check on in both) and
without gravity; a still simulation of the models inverted with and without hair-hair contact, with
frictionless contacts and without gravity, and the moving and the trim scenes against the still one.

    .venv/bin/python bench/run.py scene      # rewrites this section of docs/benchmarks.md
    .venv/bin/python bench/scene_cost_bench.py   # prints it
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import common  # noqa: E402
from common import ROOT, log, median_time, stiffened_strands, table  # noqa: E402

TITLE = "What an absent feature costs"
SMOKE = getattr(common, "SMOKE", False)
GROOM = ROOT / "samples" / "wavy.h5"
BODY = ROOT / "samples" / "body.obj"
GUIDES = 30 if SMOKE else 120
REPEATS = 1 if SMOKE else 5
SIM_REPEATS = 1 if SMOKE else 3
SIM_SECONDS = 0.1 if SMOKE else 0.5


def _settings(**contacts):
    from hairinv import config

    s = config.resolve(sets=[f"import.guides={GUIDES}"])
    return dataclasses.replace(s, contacts=dataclasses.replace(s.contacts, **contacts))


def _ratio(on, off) -> str:
    return f"{on.median / off.median:.2f}" if off.median > 0 else "–"


def _ms(t) -> str:
    return f"{1e3 * t.median:.1f}"


def _solved(result) -> str:
    """How an inversion's contact problem was solved: its interior-point steps and sweeps."""
    sweeps = f"{result.sweeps} sweeps ({1e3 * result.seconds / max(result.sweeps, 1):.3f} ms each)"
    if result.method != "interior-point":
        return sweeps
    steps = f"{result.interior_steps} interior-point steps"
    return steps + (f" and {result.sweeps} sweeps" if result.sweeps else "") + f" ({1e3 * result.seconds:.0f} ms)"


def run() -> str:
    from hairinv.contacts.body import BodyMesh
    from hairinv.contacts.detect import detect_contacts
    from hairinv.dynamics.run import run_scene
    from hairinv.dynamics.scene import Scene
    from hairinv.invert import invert
    from hairinv.model import Material
    from hairinv.pipeline import prepare

    base = _settings()
    log(f"fitting {GUIDES} guides of {GROOM.name}")
    scene = prepare(GROOM, BODY, base)
    helices, up = scene.helices, scene.up
    mesh = BodyMesh.from_mesh(scene.body)
    rows = []

    # ---- detect
    def detect(settings, body):
        return lambda: detect_contacts(helices, body, settings.contacts, up=up)

    detect(base, mesh)()  # compiled and warm
    on = median_time(detect(base, mesh), REPEATS)
    for what, settings, body in (("hair-hair contact off (contacts.hair_hair = false)", _settings(hair_hair=False), mesh),
                                 ("no body (no mesh given)", base, None),
                                 ("both off", _settings(hair_hair=False), None)):
        off = median_time(detect(settings, body), REPEATS)
        found = off.result[0]
        rows.append(["detect", what, _ms(on), _ms(off), _ratio(on, off),
                     f"{on.result[0].n_body} body + {on.result[0].n_hair} hair-hair → {found.n_body} + {found.n_hair}"])

    # ---- invert
    contacts = scene.contacts
    material = Material.from_settings(base.material, up)
    plain = dataclasses.replace(base.solver, stabilize="off")
    unchecked = dataclasses.replace(base.solver, stabilize="off", check_stability=False)
    log("invert: stability check on and off")
    on = median_time(lambda: invert(helices, contacts, material, plain), REPEATS)
    off = median_time(lambda: invert(helices, contacts, material, unchecked), REPEATS)
    same = np.array_equal(on.result[0].force, off.result[0].force)
    rows.append(["invert", "stability check off (solver.check_stability = false; stabilize off in both)", _ms(on),
                 _ms(off), _ratio(on, off), f"forces {'identical' if same else 'DIFFER'}"])
    log("invert: friction 0.3 and frictionless, the same contacts")
    smooth = dataclasses.replace(contacts, mu=np.zeros(contacts.n_contacts))
    on = median_time(lambda: invert(helices, contacts, material, unchecked), REPEATS)
    off = median_time(lambda: invert(helices, smooth, material, unchecked), REPEATS)
    ron, roff = on.result[1].result, off.result[1].result
    # mu = 0 lies outside the friction the interior-point steps take as it is: the sweeps finish that problem
    finished = roff.method == "interior-point" and roff.sweeps > 0
    frictionless_saves = on.median > off.median
    rows.append(["invert", "frictionless (mu = 0 on the same contacts; no stability check)", _ms(on), _ms(off),
                 _ratio(on, off), f"{_solved(ron)} → {_solved(roff)}; r_T max "
                 f"{np.abs(off.result[0].force[:, 1:]).max():.0e} N"])
    log("invert: stiffening on and off, the stability check on in both")
    on = median_time(lambda: invert(helices, contacts, material, base.solver), REPEATS)
    off = median_time(lambda: invert(helices, contacts, material, plain), REPEATS)
    factor = on.result[1].stiffening
    stiffened = factor[factor > 1.0] if factor is not None else np.zeros(0)
    rows.append(["invert", "stiffening off (solver.stabilize = off; stability check on in both)", _ms(on), _ms(off),
                 _ratio(on, off), f"{len(stiffened)} of {helices.n_strands} strands stiffened (largest factor "
                 f"{stiffened.max() if len(stiffened) else 1.0:.3g}) → none; unstable strands left "
                 f"{on.result[1].unstable} → {off.result[1].unstable}"])
    log("invert: gravity 9.81 and 0 m/s^2, default solver settings")
    weightless = dataclasses.replace(base, material=dataclasses.replace(base.material, gravity=0.0))
    material0 = Material.from_settings(weightless.material, up)
    on = median_time(lambda: invert(helices, contacts, material, base.solver), REPEATS)
    off = median_time(lambda: invert(helices, contacts, material0, weightless.solver), REPEATS)
    ron, roff = on.result[1], off.result[1]
    left = np.abs(off.result[0].force).max() / ron.force_scale if roff.contacts else 0.0
    rows.append(["invert", "gravity 0 (material.gravity = 0; stabilisation on in both)", _ms(on), _ms(off),
                 _ratio(on, off), f"{ron.carrying} of {ron.contacts} contacts carrying force → {roff.carrying}; "
                 f"largest force {np.abs(on.result[0].force).max():.2g} → {np.abs(off.result[0].force).max():.2g} N "
                 f"({left:.2g} of the heaviest strand's weight under "
                 f"9.81 m/s²); {_solved(ron.result)} → {_solved(roff.result)}; {stiffened_strands(ron)} strands "
                 f"stiffened → {stiffened_strands(roff)}"])

    # ---- simulate (the still scene unless said)
    def model_group(settings, contacts):
        model, _ = invert(helices, contacts, material, dataclasses.replace(settings.solver))
        return model.group({}, []), contacts

    def simulate(settings, group, contacts, name="still"):
        scene_ = Scene.load(name)
        return lambda: run_scene(helices, group, contacts, scene.body, scene_, settings, seconds=SIM_SECONDS,
                                 fps=scene_.fps)

    log("simulate: models with every feature, without hair-hair contact, frictionless, without gravity")
    full = model_group(base, contacts)
    no_hair = _settings(hair_hair=False)
    body_only = model_group(no_hair, contacts.subset(contacts.strand[:, 1] < 0))
    smooth_settings = _settings(mu_body=0.0, mu_hair=0.0)
    frictionless = model_group(smooth_settings, smooth)
    model0, _ = invert(helices, contacts, material0, weightless.solver)
    no_gravity = model0.group({}, []), contacts
    simulate(base, *full)()  # compiled and warm
    on = median_time(simulate(base, *full), SIM_REPEATS)
    weightless_ratio = None
    for what, settings, (group, c) in (("hair-hair contact off (its own model)", no_hair, body_only),
                                       ("frictionless (its own model)", smooth_settings, frictionless),
                                       ("gravity 0 (its own model)", weightless, no_gravity)):
        off = median_time(simulate(settings, group, c), SIM_REPEATS)
        moved = max(f.displacement for f in off.result.log)
        if settings is weightless:
            weightless_ratio = on.median / off.median
        rows.append([f"simulate {SIM_SECONDS:g} s still", what, _ms(on), _ms(off), _ratio(on, off),
                     f"largest displacement {1e3 * moved:.2g} mm (all on: "
                     f"{1e3 * max(f.displacement for f in on.result.log):.2g})"])
    log("simulate: the moving scene against the still one")
    moving = median_time(simulate(base, *full, name="motion"), SIM_REPEATS)
    rows.append([f"simulate {SIM_SECONDS:g} s", "body fixed (still) against keyframed (motion): the motion is the "
                 "feature", _ms(moving), _ms(on), _ratio(moving, on), "the still scene reuses detections while no "
                 "strand moves"])
    log("simulate: the trim scene against the still one")
    simulate(base, *full, name="trim")()  # compiled and warm
    cut = median_time(simulate(base, *full, name="trim"), SIM_REPEATS)
    trim_ratio = cut.median / on.median
    trim = Scene.load("trim").trim
    how = f"fraction {trim.fraction:g}" if trim.fraction is not None else f"length {trim.length:g} m"
    rows.append([f"simulate {SIM_SECONDS:g} s", f"no trim (still) against trim ({how}, the `trim` scene): the cut "
                 "is the feature", _ms(cut), _ms(on), _ratio(cut, on),
                 f"{helices.n_elements} elements → {cut.result.helices.n_elements}; largest displacement "
                 f"{1e3 * max(f.displacement for f in cut.result.log):.2g} mm (still: "
                 f"{1e3 * max(f.displacement for f in on.result.log):.2g}); contacts at the end "
                 f"{on.result.log[-1].contacts} → {cut.result.log[-1].contacts}"])

    header = ["stage", "feature switched off", "on (ms)", "off (ms)", "on / off", "what changed"]
    return "\n".join([
        f"## {TITLE}",
        "",
        f"`bench/scene_cost_bench.py`: each stage with one feature on and off (docs/scenes.md, \"What a scene "
        f"models\"), on {GUIDES} guides of the sample wavy groom ({helices.n_strands} strands, "
        f"{helices.n_elements} elements) on the sample bust, in one process, medians of {REPEATS} runs "
        f"({SIM_REPEATS} for the simulations of {SIM_SECONDS:g} s). A ratio above 1 is what the feature costs "
        "when present, so what leaving it out saves.",
        "",
        table(header, rows, ["l", "l", "r", "r", "r", "l"]),
        "",
        "Detection without a body queries nothing (and `detect` and `invert` then build no search tree of "
        "the mesh, not timed here); without hair-hair contact it runs no pair search. The inversion without the stability check runs no eigen-decomposition and gives the "
        "same forces bit for bit. Frictionless contacts are solved for their normal force alone, tangential "
        "forces exactly 0: by the sweeps on one row of `H` per contact, by the interior-point method with their "
        "tangential rows of `H` taken as zero and no sweeps after its steps"
        + ("; but with `solver.method = auto` the interior-point method solves both problems, and mu = 0 lies "
           "outside the friction its steps take as it is, so the sweeps finish the frictionless one from its "
           "forces" + ("" if frictionless_saves else ": there frictionless contacts save nothing") + ". "
           if finished else ". ")
        + "A simulation's cost follows the contacts its model has.",
        "",
        "Stiffening adds the margins taken again for the strands it stiffens and their rest shape taken again "
        "(the forces are kept); without it those strands stay unstable and are only reported. Without gravity "
        "the optimum holds no force at all (the input is its own rest shape), so the inversion has less to do "
        "and stiffens nothing; the solver still stops at its tolerance with some force "
        f"left on the contacts (at most {left:.2g} of the heaviest strand's weight under 9.81 m/s²), which the "
        "count of contacts carrying force, a threshold relative to that weight, includes. "
        + (f"A still simulation of the model inverted without gravity saves nothing: it takes "
           f"{1 / weightless_ratio:.2f} times as long as the one with gravity."
           if weightless_ratio is not None and weightless_ratio < 1.0 else
           "A still simulation of the model inverted without gravity costs less than the one with it."),
        "",
        "The trimmed groom has fewer elements, but it starts unloaded from its own contacts and moves (the cut "
        "ends no longer weigh on the rest), so its contacts are detected again where strands moved"
        + (f", and the cut run takes {trim_ratio:.1f} times as long as the still one: like the motion, the trim "
           "costs what the movement it causes costs, not what its elements cost."
           if trim_ratio > 1.0 else f"; it takes {trim_ratio:.2f} times as long as the still one."),
    ]) + "\n"


if __name__ == "__main__":
    print(run())
