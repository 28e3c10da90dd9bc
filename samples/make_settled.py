#!/usr/bin/env python
"""Make ``samples/settled.h5`` and ``samples/settled_curly.h5``: grooms at rest, settled on the sample bust by simulation.

The drawn sample grooms are not at rest: many of their strands would be in an
unstable equilibrium whatever rest shape they got. This one is made by
physics, as the paper's straightSynthSim: 40 guide strands of
``straight.h5`` (the same seeded selection as ``--guides 40``) get a
straight rest shape (q0 = 0) and are simulated on ``body.obj`` under
gravity, with body and hair-hair contact, for 4 s (air drag 5 /s so they
settle quickly). ``settled_curly.h5`` is the same with 40 guides of
``curly.h5``, whose drawn shape is their rest shape. The settled centre lines
are written as ``/curves``, 2 mm apart, and the simulator's own
super-helices as ``/helices``, so that ``hairinv invert`` uses them as they
are rather than fitting the curves again. Inverting the straight one with
``--target zero`` should give back a nearly straight rest shape; simulating
an inverted model should keep the groom still::

    cd <project root> && .venv/bin/python samples/make_settled.py

It takes about two minutes (part of it the first compile of the kernels).
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[0]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from hairinv import config, stages  # noqa: E402
from hairinv.contacts.body import BodyMesh  # noqa: E402
from hairinv.dynamics.simulate import Motion, Simulation  # noqa: E402
from hairinv.model import Material  # noqa: E402
from hairinv.pipeline import prepare  # noqa: E402
from hairinv.rod.helix import points_at  # noqa: E402

GUIDES = 40
SECONDS = 4.0
AIR = 5.0
SPACING = 2e-3


def settle(style: str, straight_rest: bool, out: Path, guides: int = GUIDES) -> None:
    """Settle ``guides`` strands of ``style`` on the bust (0: every strand) and write them to ``out``."""
    settings = config.apply(config.resolve(), {"import": {"guides": guides}})
    scene = prepare(HERE / style, HERE / "body.obj", settings, contacts=False)
    mat = Material.from_settings(settings.material, scene.up)
    helices = scene.helices
    rest = np.zeros_like(helices.omega) if straight_rest else helices.omega.copy()
    dynamics = dataclasses.replace(settings.dynamics, air_damping=AIR)
    sim = Simulation(helices, rest, mat, BodyMesh.from_mesh(scene.body), settings.contacts, dynamics)
    steps = int(round(SECONDS / dynamics.time_step))
    for i in range(steps):
        sim.step(Motion.still(mat.gravity))
        if (i + 1) % 100 == 0:
            print(f"{out.name}: t {(i + 1) * dynamics.time_step:.1f} s: kinetic energy {sim.kinetic_energy():.2e} J, "
                  f"{sim.contacts.n_contacts} contacts", flush=True)
    strands = []
    for k in range(helices.n_strands):
        a, z = helices.offsets[k], helices.offsets[k + 1]
        total = float(helices.length[a:z].sum())
        s = np.linspace(0.0, total, max(2, int(np.ceil(total / SPACING)) + 1))
        pts = np.empty((len(s), 3))
        points_at(helices.root[k], helices.frame0[k], sim.q[a:z], helices.length[a:z], s, pts)
        strands.append(pts)
    points = np.concatenate(strands)
    offsets = np.concatenate([[0], np.cumsum([len(p) for p in strands])]).astype(np.int64)
    rest_name = "straight-rest" if straight_rest else "own-shape-rest"
    group = stages.Group(
        stages.CURVES, {"points": points, "offsets": offsets},
        attrs={"source": f"hairinv sample groom '{out.stem}': {helices.n_strands} {rest_name} strands of {style} "
                         f"settled on body.obj for {SECONDS:g} s (samples/make_settled.py)",
               "scale_to_m": 1.0, "up": np.array([0.0, 1.0, 0.0])},
    )
    settled = dataclasses.replace(helices, omega=sim.q.copy())
    helix_group = settled.group(settings.fit, [])
    helix_group.attrs["note"] = "the simulator's own super-helices of the settled groom (not a fit of /curves)"
    stages.write_stage(out, [group, helix_group], "samples")
    print(f"wrote {out}: {helices.n_strands} strands, {len(points)} points")


def main() -> int:
    settle("straight.h5", True, HERE / "settled.h5")
    settle("curly.h5", False, HERE / "settled_curly.h5")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
