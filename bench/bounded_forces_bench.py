"""Bounded forces: what ``solver.gamma_relative`` costs and buys.

Run alone with ``python bench/bounded_forces_bench.py`` (prints the markdown
section), or ``python bench/run.py bounded`` to write it into
``docs/benchmarks.md``. About 15 minutes.

With the paper's single ``gamma`` (1e-16 to 1e-11 of the diagonal of ``W``),
forces that close into loops between contacts whose effects nearly cancel
cost almost nothing, and the optimum holds such loops at up to millions of
strand weights. ``solver.gamma_relative`` weighs each contact by at least a
fraction of its own diagonal of ``W``. For each fraction, on the same
problem as ``invert`` builds it for ruby short (a seeded 1,000-guide subset,
the friction as declared), in one process:

* the interior-point method to the default ``rest_tolerance`` (steps, time)
  and to 1e-3 1/m (the reference of that problem);
* the sweeps at the default cap of 2,000, and their distance from that
  reference;
* the reference's rest shape: its rms drift from the target (what the
  objective minimises), its distance from the paper's optimum (fraction 0),
  and its largest contact forces in strand weights;
* ``invert`` itself at the default settings with that fraction (friction
  reserve and stabilisation included): the strands it stiffens.

Then ruby short whole through ``invert`` at the defaults, with the paper's
problem and the default fraction.
"""

from __future__ import annotations

import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import invert_bench as ib  # type: ignore
    from common import log, smoke, table  # type: ignore
else:
    from . import invert_bench as ib
    from .common import log, smoke, table

from hairinv.config import SolverSettings  # noqa: E402
from hairinv.invert import invert  # noqa: E402
from hairinv.solver import gauss_seidel, interior  # noqa: E402
from hairinv.solver.problem import CONE, ConeProblem, InteriorSettings, SweepSettings  # noqa: E402
from hairinv.contacts.rows import contact_rows  # noqa: E402
from hairinv.testing import project_cone  # noqa: E402

TITLE = "Bounded forces: solver.gamma_relative"
GUIDES = smoke(1000, 30)
WHOLE = smoke(True, False)
FRACTIONS = smoke((0.0, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2), (0.0, 1e-4))
SWEEPS = smoke(2000, 50)
REFERENCE = 1e-3  # 1/m, the interior point's rest_tolerance for the reference of each problem
HEAVY = 100.0  # strand weights: a contact force above it counts as heavy


def _rms(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1)))) if len(a) else 0.0


def _stiffening(model) -> dict:
    factor = np.asarray(model.stiffening if model.stiffening is not None else np.ones(0))
    stiff = factor[factor > 1.0]
    return {"stiffened": int(len(stiff)), "median": float(np.median(stiff)) if len(stiff) else 1.0,
            "max": float(stiff.max()) if len(stiff) else 1.0}


def _invert(g: dict, fraction: float) -> dict:
    """``invert`` as a user runs it (auto, friction reserve, stabilisation) with this fraction."""
    solver = dataclasses.replace(g["settings"].solver, gamma_relative=fraction,
                                 friction_reserve=SolverSettings().friction_reserve)
    start = time.perf_counter()
    model, report = invert(g["helices"], g["contacts"], g["material"], solver)
    out = {"seconds": time.perf_counter() - start, "method": report.result.method,
           "steps": report.result.interior_steps if report.result.method == "interior-point" else report.result.sweeps,
           "status": report.result.status, "drift": report.drift_rms}
    out.update(_stiffening(model))
    return out


def fractions(g: dict) -> list[dict]:
    h, c, mat = g["helices"], g["contacts"], g["material"]
    rows = contact_rows(h, c)
    length = np.add.reduceat(h.length, h.offsets[:-1])
    weight = mat.linear_density * float(np.linalg.norm(mat.gravity)) * float(length.max())
    out, paper = [], None
    for fraction in FRACTIONS:
        log(f"  gamma_relative {fraction:g}")
        prob = ib.Problem.build(h, c, mat, dataclasses.replace(g["settings"].solver, gamma_relative=fraction))
        run = {"fraction": fraction}
        problem = ConeProblem.of(rows, prob.d, prob.gamma, prob.b, c.mu, c.strand, h.n_strands, weight, s=c.s)
        res = interior.solve(problem, CONE, InteriorSettings(rest_tolerance=g["settings"].solver.rest_tolerance))
        run.update(ip_steps=res.iterations, ip_seconds=res.seconds, ip_status=res.status, ip_bound=res.rest_bound)
        ref = interior.solve(problem, CONE, InteriorSettings(rest_tolerance=REFERENCE, max_iterations=150))
        r = project_cone(ref.r, c.mu)
        rest = prob.rest(r)
        paper = rest if paper is None else paper
        t = time.perf_counter()
        sw = gauss_seidel.solve(problem, CONE, SweepSettings(1e-12, SWEEPS, 5))
        run.update(sw_seconds=time.perf_counter() - t, sw_distance=_rms(prob.rest(sw.r), rest),
                   ref_bound=ref.rest_bound, drift=prob.drift(r), from_paper=_rms(rest, paper))
        force = np.linalg.norm(r, axis=1) / weight
        run.update(force_max=float(force.max(initial=0.0)), force_999=float(np.quantile(force, 0.999)) if len(force) else 0.0,
                   heavy=int(np.count_nonzero(force > HEAVY)))
        run["invert"] = _invert(g, fraction)
        out.append(run)
    return out


def run() -> str:
    started = time.perf_counter()
    log(f"bounded forces: ruby short, {GUIDES} guides")
    g = ib.prepare_groom(GUIDES, 1)
    runs = fractions(g)
    whole = []
    if WHOLE:
        log("bounded forces: ruby short, whole")
        w = ib.prepare_groom(0, 1)
        for fraction in (0.0, SolverSettings().gamma_relative):
            log(f"  invert, gamma_relative {fraction:g}")
            whole.append((fraction, w["helices"].n_strands, w["contacts"].n_contacts, _invert(w, fraction)))
    return render(g, runs, whole, time.perf_counter() - started)


def render(g: dict, runs: list[dict], whole: list, total: float) -> str:
    h, c = g["helices"], g["contacts"]
    parts = [f"## {TITLE}\n",
             "`bench/bounded_forces_bench.py`. Each contact weighs `max(gamma, gamma_relative W_ii)` in the "
             "objective (docs/inverse.md, \"Bounded forces\"); 0 is the paper's problem. Ruby short, "
             f"{h.n_strands:,} guides, {c.n_contacts:,} contacts, the friction as declared, in one process. "
             f"Reference: the interior point to {REFERENCE:g} 1/m on the same problem. Drift: rms over elements "
             "of `|q0 - t|`, what the objective minimises (1/m). Forces in strand weights (the heaviest "
             f"strand's). Heavy: contacts over {HEAVY:g} strand weights. Stiffened: `invert` at the default "
             "settings with that fraction (auto, friction reserve, stabilisation).\n"]
    rows = []
    for r in runs:
        inv = r["invert"]
        rows.append([f"{r['fraction']:g}", f"{r['ip_steps']} ({r['ip_status']})", f"{r['ip_seconds']:.1f} s",
                     f"{r['sw_distance']:.3g} ({r['sw_seconds']:.1f} s)", f"{r['drift']:.3f}", f"{r['from_paper']:.3g}",
                     f"{r['force_max']:.3g}", f"{r['force_999']:.3g}", r["heavy"],
                     f"{inv['stiffened']} (median {inv['median']:.2f}, max {inv['max']:.3g})"])
    parts.append(table(["gamma_relative", "interior point: steps", "time", f"sweeps ({SWEEPS}): distance, 1/m",
                        "drift, 1/m", "from the paper's optimum, 1/m", "largest force", "99.9th pct", "heavy",
                        "stiffened"], rows) + "\n")
    if whole:
        parts.append(f"### Ruby short, whole ({whole[0][1]:,} strands, {whole[0][2]:,} contacts), `invert` at the defaults\n")
        parts.append("Drift here is `invert`'s report: of the rest shape the simulation uses, the stiffened strands' "
                     "(a strand made far stiffer needs its rest shape changed far less, so heavy stiffening "
                     "lowers it).\n")
        rows = [[f"{f:g}", inv["method"], f"{inv['steps']} ({inv['status']})", f"{inv['seconds']:.1f} s",
                 f"{inv['drift']:.3f}", f"{inv['stiffened']} (median {inv['median']:.2f}, max {inv['max']:.3g})"]
                for f, _, _, inv in whole]
        parts.append(table(["gamma_relative", "method", "steps", "invert's time (stability included)",
                            "drift, 1/m", "stiffened"], rows) + "\n")
    parts.append(f"Total {total / 60:.1f} min.\n")
    return "\n".join(parts)


if __name__ == "__main__":
    print(run())
