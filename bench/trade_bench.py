"""Speed against accuracy, stage by stage: every knob that trades time for accuracy, against an error users see.

Each stage is run over a sweep of its knobs on the same grooms, and each point is a time against an error:

* fit: ``fit.tolerance`` and ``fit.max_elements`` on the sample wavy and curly grooms and 400 strands of
  ruby long: time of ``hairinv.fit.fit_groom`` against the mean and largest vertex distance and the fitted
  length over the polyline's;
* invert: ``solver.rest_tolerance`` of the interior-point method, and ``solver.tolerance``, ``solver.max_sweeps``
  and ``solver.max_seconds`` of the sweeps, on 200 guides of the sample
  wavy groom on the sample bust and 300 guides of ruby short on its head: time of ``invert`` against the
  rms distance of the rest shape ``q0`` from the exact optimum's (Clarabel, an interior-point solver, at
  a tight tolerance, polished by sweeps), 1/m over elements;
* simulate: ``dynamics.time_step``, ``dynamics.max_turn``, ``dynamics.max_sweeps``, ``dynamics.tolerance`` (at a
  cap of sweeps that rarely stops it first) and ``dynamics.stall_rounds`` on 40 inverted guides of the wavy and
  of the curly sample in the ``motion`` scene's first 0.5 s: wall time against the distance of the strands'
  points at the end from a reference run at finer settings than ``final``;
* detect: ``contacts.samples_per_element`` and ``contacts.max_hair_per_element`` on the wavy sample: time
  against the contacts declared.

The quality presets (``configs/quality/{draft,default,final}.toml``) are placed on each stage's curve.

    .venv/bin/python bench/run.py trade      # rewrites this section of docs/benchmarks.md
    .venv/bin/python bench/trade_bench.py    # prints it
    .venv/bin/python bench/trade_bench.py --stage simulate           # runs one stage, prints its subsection
    .venv/bin/python bench/trade_bench.py --stage simulate --write   # and replaces that subsection alone
"""

from __future__ import annotations

import dataclasses
import datetime
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from common import DATA, DOCS, IMG, ROOT, SMOKE, WORK, log, median_time, smoke, table  # noqa: E402

sys.path.insert(0, str(ROOT))

from hairinv import config  # noqa: E402
from hairinv.config import QUALITIES  # noqa: E402

TITLE = "Speed against accuracy, stage by stage"
SAMPLES = ROOT / "samples"
BODY = SAMPLES / "body.obj"
RUBY_LONG = DATA / "ruby" / "ruby_long_hair_16_guide.tfx"
RUBY_SHORT = DATA / "ruby" / "ruby_short_hair_16_guide.tfx"
RUBY_HEAD = DATA / "ruby" / "ruby_head.obj"
RUBY_SCALE = 0.002  # m per file unit (data README)
QUICK = 2.0  # s: runs shorter than this are repeated (median of REPEATS); longer ones run once
REPEATS = smoke(3, 1)

# fit
FIT_TOLERANCES = smoke((5e-5, 1e-4, 2e-4, 5e-4, 1e-3), (2e-4, 1e-3))
FIT_CAPS = smoke((16, 0), (16, 0))  # 16: the draft preset's cap; 0: what the tolerance needs
FIT_STRANDS = smoke(0, 8)  # 0: every strand of the samples
RUBY_FIT_STRANDS = smoke(400, 8)
# invert
INV_GUIDES = smoke(200, 12)
RUBY_INV_GUIDES = smoke(300, 10)
INV_TOLERANCES = smoke((1e-2, 1e-3, 1e-4, 1e-5), (1e-2, 1e-4))  # 1e-6: the final preset
INV_SWEEPS = smoke((20, 50, 100, 200, 500, 1000, 2000, 5000), (10, 50))
INV_BUDGETS = smoke((0.01, 0.03, 0.1, 0.3), (0.01,))
INV_REST = smoke((1.0, 0.5, 0.2, 0.05, 0.02, 0.005, 0.001), (0.5, 0.05))  # 1/m, the interior-point method
INV_SWEEPS_REST = smoke((1.0, 0.5, 0.2, 0.05, 0.02, 0.005), (0.5,))  # 1/m, the sweeps stopped by their own bound
RESIDUAL_ONLY = 1e-300  # solver.rest_tolerance below any bound: the residual, the cap or the budget stops the sweeps
UNCAPPED = 100_000  # sweeps: a tolerance run stops on its tolerance
TINY = 1e-12  # a run to a sweep count or a time budget: no tolerance stops it first
REFERENCE_CLARABEL = 1e-10
REFERENCE_POLISH = 1e-10  # relative residual the reference's forces are polished to by sweeps
REFERENCE_POLISH_SWEEPS = smoke(20_000, 200)
# simulate
SIM_GROOMS = (("wavy", "wavy.h5"), ("curly", "curly.h5"))  # the samples' first SIM_GUIDES guides of each
SIM_GUIDES = smoke(40, 4)
SIM_SECONDS = smoke(0.5, 0.04)
SIM_STEPS = smoke((0.02, 0.01, 0.005, 0.0025), (0.02, 0.01))
SIM_TURNS = smoke((0.2, 0.1, 0.05, 0.025), (0.1,))
SIM_SWEEPS = smoke((20, 40, 50, 200, 1000, 5000), (40, 200))  # at the default tolerance and stall_rounds
SIM_TOLERANCES = smoke((1e-4, 1e-6, 1e-8), (1e-4,))
SIM_TOLERANCE_CAP = smoke(20_000, 1000)  # sweeps a step for the tolerance rows: the cap rarely stops them first
SIM_STALL_CAPS = smoke((200,), (200,))  # stall_rounds 0 (never stop on a stall) at these caps
SIM_REFERENCE = dict(time_step=smoke(0.00125, 0.005), max_turn=0.0125, tolerance=1e-9, max_sweeps=smoke(2000, 100),
                     stall_rounds=0)
STILL_SECONDS = smoke(0.5, 0.04)
# detect
DET_SAMPLES = smoke((2, 4, 8, 16), (2, 8))
DET_CAPS = smoke((1, 2, 4, 8, 16, 0), (8, 0))
DET_STRANDS = smoke(0, 12)

CAP_COLOURS = {8: "tab:red", 16: "tab:brown", 0: "tab:blue"}
PRESET_STYLE = {"draft": ("o", "tab:orange"), "default": ("s", "tab:green"), "final": ("D", "tab:purple")}


def _preset(quality: str):
    return config.resolve(quality)


# share of the machine's CPU other processes used during each timed run of the current stage (0-1)
BACKGROUND: list[float] = []


def _load():
    """The 1, 5 and 15 minute load averages now, or None."""
    try:
        return tuple(os.getloadavg())
    except OSError:
        return None


def _timed(fn, repeats: int = REPEATS):
    """Median time of ``fn``: ``repeats`` runs when the first is under ``QUICK`` s, else that one."""
    first = median_time(fn, 1, quiet=not SMOKE)
    BACKGROUND.extend(first.background)
    if repeats <= 1 or first.median >= QUICK:
        return first.median, first.result, 1
    rest = median_time(fn, repeats - 1, quiet=not SMOKE)
    BACKGROUND.extend(rest.background)
    return float(np.median(first.times + rest.times)), rest.result, repeats


def _g(x: float, digits: int = 2) -> str:
    return f"{x:.{digits}g}"


def _mm(x: float, digits: int = 3) -> str:
    return f"{1e3 * x:.{digits}f}"


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _log_axes(ax, x=True, y=True):
    """Log scales with plain tick labels (call after plotting: the labels depend on the range)."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    for on, axis, scale, limits in ((x, ax.xaxis, ax.set_xscale, ax.get_xlim),
                                    (y, ax.yaxis, ax.set_yscale, ax.get_ylim)):
        if on:
            scale("log")
            lo, hi = limits()  # of the log scale
            few = 0 < lo and hi < 300 * lo  # 1, 2 and 5 labelled over two and a half decades or less, else 1 alone
            axis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0) if few else (1.0,)))
            axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
            axis.set_minor_formatter(NullFormatter())


def _mark_presets(ax, points, x, y, floor=0.0):
    """The three presets as large labelled markers at (x(p), y(p)); presets at one spot share a label."""
    spots = {}
    for p in points:
        spots.setdefault((round(x(p), 12), round(max(y(p), floor), 15)), []).append(p["preset"])
    for (px, py), names in spots.items():
        marker, colour = PRESET_STYLE[names[0]]
        ax.plot(px, py, marker=marker, ms=12, mfc="none", mec=colour, mew=2.2, zorder=5, ls="none")
        ax.annotate(" = ".join(names), (px, py), textcoords="offset points", xytext=(8, 6), color=colour,
                    fontsize=9, fontweight="bold", zorder=6)


# ---------------------------------------------------------------------------------------------------------------
# fit


def _fit_grooms():
    from hairinv.groom import load_groom

    base = config.resolve()
    out = []
    for name, path, extra in (("wavy", SAMPLES / "wavy.h5", {"guides": FIT_STRANDS}),
                              ("curly", SAMPLES / "curly.h5", {"guides": FIT_STRANDS}),
                              ("ruby long", RUBY_LONG, {"scale": RUBY_SCALE, "up": "y", "guides": RUBY_FIT_STRANDS})):
        if not path.exists():
            log(f"fit: {path} not found, skipped")
            continue
        settings = config.apply(base, {"import": extra})
        groom, _ = load_groom(path, settings.import_)
        out.append((name, groom))
    return out


def fit_stage() -> dict:
    from hairinv.fit import fit_groom

    base = config.resolve().fit
    grooms = _fit_grooms()
    rows = []
    for name, groom in grooms:
        log(f"fit: {name}, {groom.n_strands} strands")
        fit_groom(groom, base)  # kernels loaded and warm
        runs = [dict(tolerance=t, max_elements=c, preset=None) for c in FIT_CAPS for t in FIT_TOLERANCES]
        runs += [dict(tolerance=_preset(q).fit.tolerance, max_elements=_preset(q).fit.max_elements, preset=q)
                 for q in QUALITIES]
        for run in runs:
            fs = _preset(run["preset"]).fit if run["preset"] else dataclasses.replace(
                base, tolerance=run["tolerance"], max_elements=run["max_elements"])
            seconds, (helices, report), n = _timed(lambda: fit_groom(groom, fs))
            err = helices.fit_error
            rows.append(dict(groom=name, strands=groom.n_strands, points=len(groom.points), seconds=seconds, runs=n,
                             mean=float(err[:, 0].mean()), max=float(err[:, 1].max()),
                             p95=float(np.percentile(err[:, 1], 95)),
                             ratio=(float(report.length_ratio.min()), float(report.length_ratio.max())),
                             elements=float(report.elements.mean()), missed=int(report.tolerance_missed),
                             max_iterations=fs.max_iterations, **run))
    return {"rows": rows, "grooms": [(n, g.n_strands, len(g.points)) for n, g in grooms]}


def _save(fig, path: Path) -> None:
    """Lay out ``fig``, write it to ``path`` (its folder made if needed) and free it."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def fit_plot(result: dict, path: Path) -> None:
    plt = _plt()
    names = [g[0] for g in result["grooms"]]
    fig, axes = plt.subplots(1, len(names), figsize=(5.2 * len(names), 4.6), squeeze=False)
    for ax, name in zip(axes[0], names):
        rows = [r for r in result["rows"] if r["groom"] == name]
        for cap in FIT_CAPS:
            colour = CAP_COLOURS.get(cap, "tab:gray")
            line = [r for r in rows if r["preset"] is None and r["max_elements"] == cap]
            ax.plot([1e3 * r["seconds"] for r in line], [1e3 * r["mean"] for r in line], "-o", ms=4, color=colour,
                    label=f"max_elements {cap or 'auto (0)'}")
            for r in line:
                if cap == FIT_CAPS[-1]:
                    ax.annotate(f"{1e3 * r['tolerance']:g}", (1e3 * r["seconds"], 1e3 * r["mean"]),
                                textcoords="offset points", xytext=(-4, -12), fontsize=7, color=colour)
        _mark_presets(ax, [r for r in rows if r["preset"]], lambda r: 1e3 * r["seconds"], lambda r: 1e3 * r["mean"])
        _log_axes(ax)
        strands = next(g[1] for g in result["grooms"] if g[0] == name)
        ax.set_title(f"{name}, {strands} strands", fontsize=10)
        ax.set_xlabel("fit time (ms, median)")
        ax.grid(True, which="both", alpha=0.3)
    axes[0][0].set_ylabel("mean vertex distance (mm)")
    axes[0][0].legend(fontsize=8, loc="lower left")
    fig.suptitle("fit: fit.tolerance (labels, mm) and fit.max_elements against the fit error", fontsize=11)
    _save(fig, path)


def fit_section(result: dict) -> list[str]:
    rows = []
    for r in result["rows"]:
        what = (f"**{r['preset']}**" if r["preset"] else "") + (
            f" {1e3 * r['tolerance']:g} mm, cap {r['max_elements'] or 'auto'}"
            + (f", {r['max_iterations']} iterations" if r["preset"] else ""))
        rows.append([r["groom"], what.strip(), f"{1e3 * r['seconds']:.0f}", _mm(r["mean"], 4), _mm(r["max"]),
                     f"{r['ratio'][0]:.4f} – {r['ratio'][1]:.4f}", f"{r['elements']:.1f}", r["missed"]])
    grooms = ", ".join(f"{n} ({s} strands, {p:,} points)" for n, s, p in result["grooms"])
    return [
        "### fit: `fit.tolerance` and `fit.max_elements`",
        "",
        f"`hairinv.fit.fit_groom` on {grooms}, every other fit setting the default's "
        f"(the presets use their own: draft 20 Levenberg-Marquardt iterations, final 100). Time: median of "
        f"{REPEATS} runs when under {QUICK:g} s, else one (both threads). Mean error: mean over strands of each strand's mean vertex distance "
        "(`helices.fit_error[:, 0]`); max: the largest vertex distance of any strand; length ratio: fitted length "
        "over the polyline's, smallest and largest strand; missed: strands the fitter reports above the tolerance.",
        "",
        "![fit: time against mean fit error](img/bench_trade_fit.png)",
        "",
        table(["groom", "tolerance, element cap", "time (ms)", "mean error (mm)", "max error (mm)", "length ratio",
               "elements / strand", "missed"], rows, ["l", "l", "r", "r", "r", "r", "r", "r"]),
    ]


# ---------------------------------------------------------------------------------------------------------------
# invert


def _invert_problems():
    from hairinv.model import Material
    from hairinv.pipeline import prepare

    out = []
    for name, path, body, extra in (
            ("wavy", SAMPLES / "wavy.h5", BODY, {"guides": INV_GUIDES}),
            ("ruby short", RUBY_SHORT, RUBY_HEAD, {"scale": RUBY_SCALE, "up": "y", "guides": RUBY_INV_GUIDES})):
        if not path.exists() or not body.exists():
            log(f"invert: {path} not found, skipped")
            continue
        settings = config.apply(config.resolve(), {"import": extra})
        scene = prepare(path, body, settings)
        out.append((name, scene.helices, scene.contacts, Material.from_settings(settings.material, scene.up),
                    settings.solver))
    return out


def invert_stage() -> dict:
    from invert_bench import Problem

    from hairinv.invert import invert
    from hairinv.solver.reference import solve_socqp_clarabel

    out = {"rows": [], "problems": []}
    for name, helices, contacts, material, solver in _invert_problems():
        # every run and the reference solve the problem as declared: the friction reserve (which the
        # still benchmark measures) would otherwise move each run's optimum away from Clarabel's
        solver = dataclasses.replace(solver, friction_reserve=0.0)
        prob = Problem.build(helices, contacts, material, solver)
        log(f"invert: {name}, {helices.n_strands} strands, {contacts.n_contacts} contacts: the reference")
        started = time.perf_counter()
        r_ref, info = solve_socqp_clarabel(prob.H, prob.d, prob.gamma, prob.b.ravel(), contacts.mu,
                                           tol=REFERENCE_CLARABEL)
        clarabel_seconds = time.perf_counter() - started
        polish = dataclasses.replace(solver, method="sweeps", tolerance=REFERENCE_POLISH,
                                     max_sweeps=REFERENCE_POLISH_SWEEPS, rest_tolerance=RESIDUAL_ONLY)
        polished, report = invert(helices, contacts, material, polish, check_stability=False, start=r_ref)
        candidates = [(prob.objective(r_ref), "Clarabel", r_ref), (prob.objective(polished.force), "polished",
                                                                   polished.force)]
        # the reference: the one closer to optimality (its natural-map residual; Clarabel's answer may lie a
        # hair outside the cones, which lowers its objective)
        _, which, r_star = min(candidates, key=lambda c: prob.natural_residual(c[2]))
        f_star = min(c[0] for c in candidates)
        q0_star = prob.rest(r_star)
        scale = report.force_scale

        def distance(r):
            dq = prob.rest(r) - q0_star
            return float(np.sqrt(np.mean(np.sum(dq ** 2, axis=1)))), float(np.max(np.linalg.norm(dq, axis=1)))

        gravity_only = distance(np.zeros_like(r_star))
        out["problems"].append(dict(
            groom=name, strands=helices.n_strands, elements=helices.n_elements, contacts=contacts.n_contacts,
            body=contacts.n_body, clarabel_seconds=clarabel_seconds, clarabel_iterations=info["iterations"],
            clarabel_status=info["status"], polish_sweeps=int(report.result.sweeps),
            polish_relres=float(report.result.relative_residual), reference=which,
            reference_relres=prob.natural_residual(r_star) / scale, clarabel_gap=(prob.objective(r_ref) - f_star),
            f_star=f_star, drift=prob.drift(r_star), gravity_only=gravity_only))
        invert(helices, contacts, material, solver, check_stability=False)  # warm
        sweeps = dict(method="sweeps", rest_tolerance=RESIDUAL_ONLY)
        runs = ([dict(kind="rest", method="interior-point", rest_tolerance=t, tolerance=solver.tolerance,
                      max_sweeps=solver.max_sweeps, max_seconds=0.0) for t in INV_REST]
                + [dict(kind="sweeps rest", method="sweeps", rest_tolerance=t, tolerance=TINY, max_sweeps=UNCAPPED,
                        max_seconds=0.0) for t in INV_SWEEPS_REST]
                + [dict(kind="tolerance", tolerance=t, max_sweeps=UNCAPPED, max_seconds=0.0, **sweeps)
                   for t in INV_TOLERANCES]
                + [dict(kind="sweeps", tolerance=TINY, max_sweeps=s, max_seconds=0.0, **sweeps) for s in INV_SWEEPS]
                + [dict(kind="budget", tolerance=TINY, max_sweeps=UNCAPPED, max_seconds=b, **sweeps)
                   for b in INV_BUDGETS]
                + [dict(kind="preset", preset=q, method=_preset(q).solver.method,
                        rest_tolerance=_preset(q).solver.rest_tolerance, tolerance=_preset(q).solver.tolerance,
                        max_sweeps=_preset(q).solver.max_sweeps, max_seconds=_preset(q).solver.max_seconds)
                   for q in QUALITIES])
        for run in runs:
            ss = dataclasses.replace(solver, method=run["method"], rest_tolerance=run["rest_tolerance"],
                                     tolerance=run["tolerance"], max_sweeps=run["max_sweeps"],
                                     max_seconds=run["max_seconds"])
            log(f"invert: {name}, {run}")
            seconds, (model, rep), n = _timed(lambda: invert(helices, contacts, material, ss, check_stability=False))
            rms, worst = distance(model.force)
            res = rep.result
            out["rows"].append(dict(groom=name, seconds=seconds, runs=n, solver_seconds=float(res.seconds),
                                    sweeps=int(res.sweeps), status=str(res.status), used=str(res.method),
                                    steps=int(res.interior_steps), bound=float(res.rest_bound),
                                    relres=float(res.relative_residual), rms=rms, max=worst,
                                    gap=(prob.objective(model.force) - f_star) / abs(f_star) if f_star else 0.0,
                                    **{"preset": None, **run}))
    return out


def invert_plot(result: dict, path: Path) -> None:
    plt = _plt()
    names = [p["groom"] for p in result["problems"]]
    floor = 1e-6
    fig, axes = plt.subplots(1, len(names), figsize=(6.0 * len(names), 4.8), squeeze=False)
    for ax, problem in zip(axes[0], result["problems"]):
        rows = [r for r in result["rows"] if r["groom"] == problem["groom"]]
        for kind, colour, label, tag in (
                ("rest", "tab:green", "solver.rest_tolerance (interior point)", lambda r: f"{r['rest_tolerance']:g}"),
                ("sweeps rest", "tab:purple", "solver.rest_tolerance (sweeps, max_sweeps unlimited)",
                 lambda r: f"{r['rest_tolerance']:g}"),
                ("tolerance", "tab:blue", "solver.tolerance (max_sweeps unlimited)", lambda r: f"{r['tolerance']:g}"),
                ("sweeps", "tab:red", "solver.max_sweeps (no tolerance)", lambda r: f"{r['max_sweeps']}"),
                ("budget", "tab:gray", "solver.max_seconds (no tolerance)", lambda r: f"{r['max_seconds']:g} s")):
            line = [r for r in rows if r["kind"] == kind]
            ax.plot([r["seconds"] for r in line], [max(r["rms"], floor) for r in line], "-o", ms=4, color=colour,
                    label=label)
            for r in line:
                ax.annotate(tag(r), (r["seconds"], max(r["rms"], floor)), textcoords="offset points",
                            xytext=(4, 4 if kind != "sweeps" else -11), fontsize=7, color=colour)
        _mark_presets(ax, [r for r in rows if r["kind"] == "preset"], lambda r: r["seconds"], lambda r: r["rms"],
                      floor)
        ax.axhline(problem["gravity_only"][0], color="k", ls=":", lw=1)
        ax.text(0.02, problem["gravity_only"][0], "no contact forces (the gravity-only rest shape)",
                transform=ax.get_yaxis_transform(), va="top", fontsize=7)
        _log_axes(ax)
        ax.set_title(f"{problem['groom']}: {problem['strands']} guides, {problem['contacts']:,} contacts", fontsize=10)
        ax.set_xlabel("invert time (s, median, no stability check)")
        ax.grid(True, which="both", alpha=0.3)
    axes[0][0].set_ylabel("rest shape: rms |q0 - q0*| over elements (1/m)")
    axes[0][0].legend(fontsize=8, loc="lower left")
    fig.suptitle("invert: the solvers' knobs against the rest shape's distance from the exact optimum", fontsize=11)
    _save(fig, path)


def invert_section(result: dict) -> list[str]:
    rows = []
    for r in result["rows"]:
        what = {"rest": f"interior point, rest_tolerance {r['rest_tolerance']:g}",
                "sweeps rest": f"sweeps, rest_tolerance {r['rest_tolerance']:g}",
                "tolerance": f"sweeps, tolerance {r['tolerance']:g}",
                "sweeps": f"sweeps, max_sweeps {r['max_sweeps']}",
                "budget": f"sweeps, max_seconds {r['max_seconds']:g}",
                "preset": f"**{r['preset']}** (method {r['method']}, rest_tolerance {r['rest_tolerance']:g}; sweeps: "
                          f"tolerance {r['tolerance']:g}, max_sweeps {r['max_sweeps']})"}[r["kind"]]
        work = (f"{r['steps']} steps, bound {_g(r['bound'], 2)}" if r["used"] == "interior-point"
                else f"{r['sweeps']} sweeps, bound {_g(r['bound'], 2)}")
        rows.append([r["groom"], what, f"{1e3 * r['seconds']:.0f}", f"{work} ({r['status']})",
                     f"{r['relres']:.1e}", f"{r['gap']:.1e}", _g(r["rms"], 3), _g(r["max"], 3)])
    probs = []
    for p in result["problems"]:
        probs.append(
            f"{p['groom']}: {p['strands']} guides, {p['elements']:,} elements, {p['contacts']:,} contacts "
            f"({p['body']:,} hair-body); Clarabel at tolerance {REFERENCE_CLARABEL:g} took {p['clarabel_seconds']:.2f} s "
            f"({p['clarabel_iterations']} iterations, {p['clarabel_status']}), the sweeps started from its forces "
            f"reached a relative residual of {p['polish_relres']:.1e} in {p['polish_sweeps']} sweeps; the reference is "
            f"the one of the two closer to optimality by its natural-map residual ({p['reference']}, relative "
            f"residual {p['reference_relres']:.1e}; Clarabel's objective is {p['clarabel_gap']:.1e} above the "
            f"lowest, its answer may lie a little outside the cones). "
            f"Its rest shape lies {_g(p['drift'], 3)} 1/m (rms) from the input curvature; the gravity-only rest shape "
            f"(no contact forces) lies {_g(p['gravity_only'][0], 3)} 1/m from it")
    return [
        "### invert: `solver.rest_tolerance`, `solver.tolerance`, `solver.max_sweeps`, `solver.max_seconds`",
        "",
        "`invert` (the `default` settings otherwise, without the stability check, so that the rest shape is the "
        "one the forces give at the material's stiffness, and with the friction as declared, "
        "`solver.friction_reserve = 0`, so that every run solves the reference's problem) on guide subsets (`import.guides`) of two grooms: "
        + "; ".join(probs) + ". "
        "The error is the rms over elements of `|q0 - q0*|`, 1/m, between the rest shape of the run and the "
        "reference's (`q0 = q - K^-1 (F_g + H^T r)`, docs/inverse.md): the rest shape is what the simulation "
        "starts from, so this is what changes the hair's behaviour; the largest element's distance is given too, "
        "and the objective gap `(f - f*) / |f*|`. The interior-point runs (`solver.method = interior-point`) stop on "
        "their bound on that distance (`rest_tolerance`, the bound reached in the table); the sweeps' runs "
        "(`solver.method = sweeps`) on their knobs: tolerance runs have no sweep cap; sweep-cap and time-budget "
        f"runs have a tolerance of {TINY:g} so that nothing else stops them. Time: the whole `invert` call, median "
        f"of {REPEATS} runs when under {QUICK:g} s, else one.",
        "",
        "![invert: time against the rest shape's distance from the optimum](img/bench_trade_invert.png)",
        "",
        table(["groom", "setting", "time (ms)", "work (status)", "relative residual", "objective gap",
               "rms ‖q0 − q0*‖ (1/m)", "largest ‖q0 − q0*‖ (1/m)"], rows, ["l", "l", "r", "r", "r", "r", "r", "r"]),
    ]


# ---------------------------------------------------------------------------------------------------------------
# simulate


def _sim_groom(name: str, file: str):
    """``file``'s first ``SIM_GUIDES`` guides on the sample bust, inverted with the default settings."""
    from hairinv.invert import invert
    from hairinv.model import Material
    from hairinv.pipeline import prepare

    settings = config.apply(config.resolve(), {"import": {"guides": SIM_GUIDES}})
    scene = prepare(SAMPLES / file, BODY, settings)
    material = Material.from_settings(settings.material, scene.up)
    model, _ = invert(scene.helices, scene.contacts, material, settings.solver)
    return settings, scene, model.group({}, [])


def _sim_runs(base) -> list[dict]:
    """The runs of one groom: each knob changed alone from ``base`` (the default dynamics), then the presets."""
    rep = dataclasses.replace
    return ([dict(kind="time_step", dynamics=rep(base, time_step=h)) for h in SIM_STEPS]
            + [dict(kind="max_turn", dynamics=rep(base, max_turn=t)) for t in SIM_TURNS]
            + [dict(kind="max_sweeps", dynamics=rep(base, max_sweeps=c)) for c in SIM_SWEEPS]
            + [dict(kind="tolerance", dynamics=rep(base, tolerance=t, max_sweeps=SIM_TOLERANCE_CAP))
               for t in SIM_TOLERANCES]
            + [dict(kind="stall_rounds", dynamics=rep(base, stall_rounds=0, max_sweeps=c)) for c in SIM_STALL_CAPS]
            + [dict(kind="preset", preset=q, dynamics=_preset(q).dynamics) for q in QUALITIES])


def _frames_summary(frames) -> dict:
    """What the contact solve did over a run: its steps that missed the tolerance, the most sweeps one step
    took, the largest relative residual one step ended at, and the steps split by max_turn."""
    log_ = frames.log
    return dict(unconverged=int(sum(f.unconverged_steps for f in log_)), sweeps=int(max(f.sweeps for f in log_)),
                residual=float(max(f.relative_residual for f in log_)), halved=int(sum(f.halved for f in log_)))


def _distances(points, reference) -> np.ndarray:
    """m: each strand's largest point distance from the same point of ``reference``."""
    return np.array([float(np.max(np.linalg.norm(a - b, axis=1))) for a, b in zip(points, reference)])


def simulate_stage() -> dict:
    from hairinv.dynamics.run import _samples, run_scene
    from hairinv.dynamics.scene import Scene

    out = {"grooms": [], "load": _load()}
    for name, file in SIM_GROOMS:
        if not (SAMPLES / file).exists():
            log(f"simulate: {file} not found, skipped")
            continue
        log(f"simulate: {name}, inverting {SIM_GUIDES} guides")
        settings, scene, group = _sim_groom(name, file)
        helices = scene.helices
        g = {"groom": name, "file": file, "strands": helices.n_strands, "elements": helices.n_elements,
             "contacts": scene.contacts.n_contacts, "body": scene.contacts.n_body, "rows": [], "still": []}

        def simulate(scene_name, dynamics, seconds):
            s = dataclasses.replace(settings, dynamics=dynamics)
            sc = Scene.load(scene_name)
            return lambda: run_scene(helices, group, scene.contacts, scene.body, sc, s, seconds=seconds, fps=sc.fps)

        def points(frames):
            return _samples(helices, np.asarray(frames.omega[-1]))

        simulate("motion", settings.dynamics, 2 * SIM_STEPS[0])()  # warm
        log(f"simulate: {name}, the reference {SIM_REFERENCE}")
        started = time.perf_counter()
        ref = simulate("motion", dataclasses.replace(settings.dynamics, **SIM_REFERENCE), SIM_SECONDS)()
        g["reference_seconds"] = time.perf_counter() - started
        g["reference"] = _frames_summary(ref)
        g["reference_moved"] = max(f.displacement for f in ref.log)
        ref_points = points(ref)
        g["rows"].append(dict(kind="reference", seconds=g["reference_seconds"], runs=1, max=0.0, mean=0.0,
                              **g["reference"], **SIM_REFERENCE, preset=None))
        done, ends = {}, {}  # a setting met before (the default is a row of several knobs and a preset): run once
        for run in _sim_runs(settings.dynamics):
            d = run["dynamics"]
            if d not in done:
                log(f"simulate: {name}, {run['kind']} {run.get('preset') or ''} h {d.time_step} turn {d.max_turn} "
                    f"tol {d.tolerance} sweeps {d.max_sweeps} stall {d.stall_rounds}")
                seconds, frames, n = _timed(simulate("motion", d, SIM_SECONDS))
                ends[d] = points(frames)
                dev = _distances(ends[d], ref_points)
                done[d] = dict(seconds=seconds, runs=n, max=float(dev.max()), mean=float(dev.mean()),
                               **_frames_summary(frames))
            g["rows"].append(dict(done[d], time_step=d.time_step, max_turn=d.max_turn, tolerance=d.tolerance,
                                  max_sweeps=d.max_sweeps, stall_rounds=d.stall_rounds, kind=run["kind"],
                                  preset=run.get("preset")))
        # the contact solve's own error: the rows at the default step and max_turn against the tightest contact
        # solve at that step (the tolerance row of the smallest tolerance), whose time-step error they share
        base = settings.dynamics
        tight = dataclasses.replace(base, tolerance=min(SIM_TOLERANCES), max_sweeps=SIM_TOLERANCE_CAP)
        for r in g["rows"]:
            if (r["kind"] != "reference" and (r["time_step"], r["max_turn"]) == (base.time_step, base.max_turn)
                    and tight in ends):
                d = dataclasses.replace(base, tolerance=r["tolerance"], max_sweeps=r["max_sweeps"],
                                        stall_rounds=r["stall_rounds"])
                r["contact_mean"] = float(_distances(ends[d], ends[tight]).mean())
        for q in QUALITIES:
            log(f"simulate: {name}, still, {q}")
            seconds, frames, n = _timed(simulate("still", _preset(q).dynamics, STILL_SECONDS))
            g["still"].append(dict(preset=q, seconds=seconds, runs=n, moved=max(f.displacement for f in frames.log),
                                   steps=round(STILL_SECONDS / _preset(q).dynamics.time_step),
                                   max_sweeps=_preset(q).dynamics.max_sweeps, tolerance=_preset(q).dynamics.tolerance,
                                   **_frames_summary(frames)))
        out["grooms"].append(g)
    return out


SIM_LINES = (  # kind, colour, legend, label of a point, label offset
    ("time_step", "tab:blue", "dynamics.time_step (s)", lambda r: f"{r['time_step']:g}", (4, 4)),
    ("max_turn", "tab:red", "dynamics.max_turn (rad)", lambda r: f"{r['max_turn']:g}", (4, -11)),
    ("max_sweeps", "tab:cyan", "dynamics.max_sweeps", lambda r: f"{r['max_sweeps']}", (4, 4)),
    ("tolerance", "tab:gray", None, lambda r: f"{r['tolerance']:g}", (-30, 6)),
    ("stall_rounds", "black", None, lambda r: f"{r['max_sweeps']}", (4, -11)),
)


def simulate_plot(result: dict, path: Path) -> None:
    """Above: every row's distance from the reference against its time; below: the contact solve's rows (at the
    default step) against the tightest contact solve at that step."""
    plt = _plt()
    grooms = result["grooms"]
    fig, axes = plt.subplots(2, len(grooms), figsize=(6.4 * len(grooms), 9.4), squeeze=False)
    floor = 1e-7
    contact_kinds = ("max_sweeps", "tolerance", "stall_rounds")
    for col, g in enumerate(grooms):
        top, bottom = axes[0][col], axes[1][col]
        for kind, colour, label, tag, offset in SIM_LINES:
            line = [r for r in g["rows"] if r["kind"] == kind]
            if not line:
                continue
            label = label or {"tolerance": f"dynamics.tolerance, max_sweeps {SIM_TOLERANCE_CAP:,}",
                              "stall_rounds": "stall_rounds 0, max_sweeps"}[kind]
            style = "-o" if kind != "stall_rounds" else "s"
            top.plot([r["seconds"] for r in line], [max(1e3 * r["mean"], floor) for r in line], style, ms=4,
                     color=colour, label=label)
            if kind not in contact_kinds:  # (their labels are on the plot below)
                for r in line:
                    top.annotate(tag(r), (r["seconds"], max(1e3 * r["mean"], floor)), textcoords="offset points",
                                 xytext=offset, fontsize=7, color=colour)
                continue
            own = [r for r in line if r.get("contact_mean", 0.0) > 0.0]  # (the tightest solve itself: 0)
            bottom.plot([r["seconds"] for r in own], [1e3 * r["contact_mean"] for r in own], style, ms=4,
                        color=colour, label=label)
            for r in own:
                bottom.annotate(tag(r), (r["seconds"], 1e3 * r["contact_mean"]), textcoords="offset points",
                                xytext=offset, fontsize=7, color=colour)
        _mark_presets(top, [r for r in g["rows"] if r["kind"] == "preset"], lambda r: r["seconds"],
                      lambda r: 1e3 * r["mean"], floor)
        _mark_presets(bottom, [r for r in g["rows"] if r["kind"] == "preset" and r.get("contact_mean", 0) > 0],
                      lambda r: r["seconds"], lambda r: 1e3 * r["contact_mean"])
        for ax in (top, bottom):
            _log_axes(ax)
            ax.set_xlabel(f"wall time of {SIM_SECONDS:g} s simulated (s)")
            ax.grid(True, which="both", alpha=0.3)
        top.set_title(f"{g['strands']} inverted {g['groom']} guides ({g['contacts']} contacts): every knob",
                      fontsize=10)
        bottom.set_title(f"{g['groom']}: the contact solve alone, at the default time_step and max_turn",
                         fontsize=10)
    axes[0][0].set_ylabel("distance from the reference at the end (mm), mean over strands")
    axes[1][0].set_ylabel(f"distance from the tolerance {min(SIM_TOLERANCES):g} run (mm), mean over strands")
    axes[0][0].legend(fontsize=8, loc="lower left")
    axes[1][0].legend(fontsize=8, loc="lower left")
    fig.suptitle(f"simulate: the motion scene's first {SIM_SECONDS:g} s, each knob changed alone from the default",
                 fontsize=11)
    _save(fig, path)


def _sim_findings(result: dict) -> list[str]:
    """What the rows show, groom by groom, read from the figures: which knob decides the accuracy, and what stops
    each contact solve (the cap, the stall or the tolerance)."""
    out = []
    for g in result["grooms"]:
        rows = g["rows"]

        def by(kind):
            return [r for r in rows if r["kind"] == kind]

        base = next(r for r in by("preset") if r["preset"] == "default")
        steps = by("time_step")
        contact = [r for r in rows if "contact_mean" in r]
        if not steps or not contact:
            continue
        fine = min(steps, key=lambda r: r["time_step"])
        coarse = max(steps, key=lambda r: r["time_step"])
        lo, hi = min(r["mean"] for r in contact), max(r["mean"] for r in contact)
        tight = next(r for r in by("tolerance") if r["tolerance"] == min(SIM_TOLERANCES))
        n = round(SIM_SECONDS / base["time_step"])

        def cost(r):
            return f"{r['seconds'] / base['seconds']:.1f}x the default's time"

        def stop(r):
            if r["unconverged"] == 0:
                return "every step meets the tolerance"
            why = (f"the cap stops some (a step takes all {r['max_sweeps']:,} sweeps)"
                   if r["sweeps"] >= r["max_sweeps"]
                   else f"the stall stops them (no step takes more than {r['sweeps']:,} sweeps)")
            return f"{r['unconverged']} of {n} steps end above the tolerance (largest residual {r['residual']:.0e}); {why}"

        decides = coarse["mean"] - fine["mean"] > 3 * (hi - lo)
        text = [
            f"**{g['groom']}**: " + ("the time step decides the accuracy" if decides else
                                     "the contact settings move the result as much as the time step does")
            + f": from the reference, {_mm(coarse['mean'], 2)} mm (mean over strands) at time_step "
              f"{coarse['time_step']:g} s, {_mm(base['mean'], 2)} at the default {base['time_step']:g}, "
              f"{_mm(fine['mean'], 2)} at {fine['time_step']:g} ({cost(fine)}), while every contact setting at the "
              f"default step ends {_mm(lo, 2)}–{_mm(hi, 2)} mm from it.",
            (f"The contact solve alone changes little: the default's strands end {_mm(base['contact_mean'], 3)} mm "
             f"(mean) from the tightest solve at the same step, against {_mm(base['mean'], 2)} mm from the reference."
             if base["contact_mean"] < 0.05 * base["mean"] else
             f"The contact solve alone leaves the default's strands {_mm(base['contact_mean'], 2)} mm (mean) from the "
             f"tightest solve at the same step, {100 * base['contact_mean'] / base['mean']:.0f} % of their distance "
             f"from the reference, "
             + (f"but the tighter solves end no closer to the reference ({_mm(tight['mean'], 2)} mm against "
                f"{_mm(base['mean'], 2)}): they take another path, and the step's own error is the larger."
                if tight["mean"] >= base["mean"] else
                f"and the tightest solve ends {_mm(tight['mean'], 2)} mm from the reference against "
                f"{_mm(base['mean'], 2)}.")),
            "max_sweeps at the default tolerance: " + "; ".join(
                f"{r['max_sweeps']:,}: {stop(r)}, {cost(r)}" for r in by("max_sweeps")) + ".",
            f"tolerance at {SIM_TOLERANCE_CAP:,} sweeps: " + "; ".join(
                f"{r['tolerance']:g}: {stop(r)}, {cost(r)}" for r in by("tolerance")) + ".",
        ]
        if by("stall_rounds"):
            text.append("stall_rounds 0: " + "; ".join(
                f"at {r['max_sweeps']:,} sweeps {stop(r)}, {cost(r)}" for r in by("stall_rounds")) + ".")
        caps = by("max_sweeps")
        worse = [(a, b) for a, b in zip(caps, caps[1:]) if b["unconverged"] > a["unconverged"]]
        if worse:
            a, b = worse[0]
            text.append(
                f"More sweeps do not always leave fewer steps unconverged ({a['max_sweeps']:,} → {b['max_sweeps']:,}: "
                f"{a['unconverged']} → {b['unconverged']}): each round of the friction fixed point gets a tenth of "
                "the cap until its inner tolerance is the final one, so the cap changes the rounds' path and "
                "where the stall test stops them.")
        ref = next(r for r in rows if r["kind"] == "reference")
        others = [r["residual"] for r in rows if r["kind"] != "reference"]
        ref_steps = round(SIM_SECONDS / ref["time_step"])
        text.append(
            f"The reference: {ref['unconverged']} of its {ref_steps} steps stop on its cap of {ref['max_sweeps']:,} "
            f"sweeps short of its tolerance, " if ref["unconverged"] else "The reference meets its tolerance at "
            "every step, ")
        text[-1] += (f"and its largest residual ({ref['residual']:.0e}) is still the smallest of any run "
                     f"(the next {min(others):.0e}), with the finest step: the tightest run."
                     if ref["residual"] <= min(others) else
                     f"and its largest residual ({ref['residual']:.0e}) is above another run's ({min(others):.0e}).")
        out += [" ".join(text), ""]
    return out


def _still_note(g: dict) -> str:
    """A sentence on a preset whose run at rest costs ten times the default's or more, and why, or ''."""
    final = next((s for s in g["still"] if s["preset"] == "final"), None)
    default = next((s for s in g["still"] if s["preset"] == "default"), None)
    if not final or not default or final["seconds"] <= 10 * default["seconds"]:
        return ""
    return (f" On {g['groom']} the final preset takes {final['seconds'] / default['seconds']:.0f}x the default's time "
            "at rest" + (f": {final['unconverged']} of its {final['steps']} steps end "
                         f"{'just ' if final['residual'] < 10 * final['tolerance'] else ''}above its tolerance "
                         f"{final['tolerance']:g} (largest residual {final['residual']:.1e}), and with stall_rounds "
                         f"0 each runs to its cap of {final['max_sweeps']:,} sweeps, while the strands do not move."
                         if "unconverged" in final and final["unconverged"] else "."))


def simulate_section(result: dict) -> list[str]:
    rows = []
    for g in result["grooms"]:
        for r in g["rows"]:
            what = {"reference": f"reference (time_step {r['time_step']:g}, max_turn {r['max_turn']:g}, "
                                 f"tolerance {r['tolerance']:g}, max_sweeps {r['max_sweeps']}, stall_rounds 0)",
                    "time_step": f"time_step {r['time_step']:g} s", "max_turn": f"max_turn {r['max_turn']:g} rad",
                    "max_sweeps": f"max_sweeps {r['max_sweeps']}",
                    "tolerance": f"tolerance {r['tolerance']:g}, max_sweeps {r['max_sweeps']}",
                    "stall_rounds": f"stall_rounds 0, max_sweeps {r['max_sweeps']}",
                    "preset": f"**{r['preset']}** (time_step {r['time_step']:g}, tolerance {r['tolerance']:g}, "
                              f"max_sweeps {r['max_sweeps']}, stall_rounds {r['stall_rounds']})"}[r["kind"]]
            rows.append([g["groom"], what, f"{r['seconds']:.2f}", _mm(r["max"]), _mm(r["mean"]),
                         _mm(r["contact_mean"]) if "contact_mean" in r else "–", r["halved"], r["unconverged"],
                         r["sweeps"], f"{r['residual']:.1e}"])
    ref = SIM_REFERENCE
    grooms = "; ".join(
        f"{g['strands']} guides of the sample {g['groom']} groom ({g['elements']} elements, {g['contacts']} "
        f"contacts, {g['body']} of them with the body)" for g in result["grooms"])
    refs = ", ".join(f"{1e3 * g['reference_moved']:.1f} mm on {g['groom']}" for g in result["grooms"])
    still = "; ".join(
        f"{g['groom']}: " + ", ".join(f"{s['preset']} {s['seconds']:.2f} s (largest displacement "
                                      f"{1e3 * s['moved']:.1g} mm)" for s in g["still"])
        for g in result["grooms"])
    steps = round(SIM_SECONDS / config.resolve().dynamics.time_step)
    return [
        "### simulate: `dynamics.time_step`, `dynamics.max_turn`, `dynamics.max_sweeps`, `dynamics.tolerance`, "
        "`dynamics.stall_rounds`",
        "",
        f"`hairinv.dynamics.run.run_scene` on {grooms}, each inverted once with the `default` settings, in the "
        f"first {SIM_SECONDS:g} s of the `motion` scene (the head starts turning). Each run changes one knob of "
        f"the `default` dynamics, or takes a preset's `[dynamics]` (the fit and the inversion stay the default's). "
        f"The contact solve of a step stops at the first of: every contact within `tolerance` (a fraction of "
        f"g h), `max_sweeps` sweeps, or `stall_rounds` rounds in a row that did not halve its residual (the "
        f"default {config.DynamicsSettings().stall_rounds}). The `max_sweeps` rows keep the default tolerance; "
        f"the `tolerance` rows raise the cap to "
        f"{SIM_TOLERANCE_CAP:,} sweeps, so that the tolerance or the stall, not the cap, stops them (a row whose "
        f"most sweeps equal the cap says where a step still took all of them); the `stall_rounds 0` rows "
        f"never stop on a stall. The reference (its own row): time_step {ref['time_step']:g} s, max_turn "
        f"{ref['max_turn']:g} rad, tolerance {ref['tolerance']:g}, up to {ref['max_sweeps']:,} sweeps a step, "
        f"stall_rounds 0 (in it the strands move up to {refs}). "
        "Error: each strand's largest point distance from the reference's at the end (points at the ends and "
        "middle of every element), the largest and the mean over strands; the plot shows the mean above (the largest "
        "is one strand's, whose path through its contacts may fork). Mean from the tightest solve: for the rows at "
        f"the default time_step and max_turn, the same mean distance from the run of tolerance "
        f"{min(SIM_TOLERANCES):g} at {SIM_TOLERANCE_CAP:,} sweeps, which shares their time-step error: what the "
        "contact solve alone changes (the plot below). Time: wall clock of the run, median "
        f"of {REPEATS} when under {QUICK:g} s; a setting met twice (the default is the row of time_step "
        f"0.01, max_turn 0.05, max_sweeps 200 and the preset) is run once. Halved: steps split by max_turn; "
        f"unconverged: steps (of {steps} at the default step) whose contact solve stopped above its tolerance, "
        "on the cap or a stall; most sweeps: the most one step took (equal to the cap: the cap stopped it); "
        "largest residual: the largest relative residual a step ended at, against the tolerance.",
        "",
        "![simulate: time against the distance from the reference (above) and, for the contact solve's rows, from "
        "the tightest contact solve at the same step (below)](img/bench_trade_simulate.png)",
        "",
        table(["groom", "setting", "time (s)", "largest distance (mm)", "mean over strands (mm)",
               "mean from the tightest solve (mm)", "halved", "unconverged", "most sweeps", "largest residual"],
              rows, ["l", "l", "r", "r", "r", "r", "r", "r", "r", "r"]),
        "",
    ] + _sim_findings(result) + [
        f"At rest (the `still` scene, {STILL_SECONDS:g} s, each preset's dynamics): {still}."
        + "".join(_still_note(g) for g in result["grooms"]),
    ]


# ---------------------------------------------------------------------------------------------------------------
# detect


def detect_stage() -> dict:
    from hairinv.contacts.body import BodyMesh
    from hairinv.contacts.detect import detect_contacts
    from hairinv.pipeline import prepare

    settings = config.apply(config.resolve(), {"import": {"guides": DET_STRANDS}})
    scene = prepare(SAMPLES / "wavy.h5", BODY, settings, contacts=False)
    helices, up = scene.helices, scene.up
    mesh = BodyMesh.from_mesh(scene.body)
    base = settings.contacts
    detect_contacts(helices, mesh, base, up=up)  # warm
    runs = ([dict(kind="samples", samples_per_element=s, max_hair_per_element=base.max_hair_per_element)
             for s in DET_SAMPLES]
            + [dict(kind="cap", samples_per_element=base.samples_per_element, max_hair_per_element=c)
               for c in DET_CAPS])
    rows = []
    for run in runs:
        cs = dataclasses.replace(base, samples_per_element=run["samples_per_element"],
                                 max_hair_per_element=run["max_hair_per_element"])
        seconds, (contacts, _), n = _timed(lambda: detect_contacts(helices, mesh, cs, up=up))
        touching = np.unique(contacts.strand[contacts.strand[:, 1] < 0, 0]).size
        rows.append(dict(seconds=seconds, runs=n, contacts=contacts.n_contacts, body=contacts.n_body,
                         hair=contacts.n_hair, touching=int(touching), **run))
    presets = {q: (_preset(q).contacts.samples_per_element, _preset(q).contacts.max_hair_per_element)
               for q in QUALITIES}
    return {"rows": rows, "strands": helices.n_strands, "elements": helices.n_elements, "presets": presets,
            "default": (base.samples_per_element, base.max_hair_per_element)}


def detect_plot(result: dict, path: Path) -> None:
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7.5, 5.0))
    for kind, colour, label, tag in (
            ("samples", "tab:blue", "contacts.samples_per_element", lambda r: f"{r['samples_per_element']}"),
            ("cap", "tab:red", "contacts.max_hair_per_element", lambda r: f"{r['max_hair_per_element'] or 'none'}")):
        line = [r for r in result["rows"] if r["kind"] == kind]
        ax.plot([1e3 * r["seconds"] for r in line], [r["contacts"] for r in line], "-o", ms=4, color=colour,
                label=label)
        for r in line:
            ax.annotate(tag(r), (1e3 * r["seconds"], r["contacts"]), textcoords="offset points", xytext=(4, 4),
                        fontsize=7, color=colour)
    spot = next(r for r in result["rows"] if r["kind"] == "cap"
                and (r["samples_per_element"], r["max_hair_per_element"]) == result["default"])
    _mark_presets(ax, [dict(spot, preset=q) for q in result["presets"]
                       if result["presets"][q] == result["default"]],
                  lambda r: 1e3 * r["seconds"], lambda r: r["contacts"])
    _log_axes(ax, y=False)
    ax.set_xlabel("detection time (ms, median)")
    ax.set_ylabel("contacts declared (hair-body + hair-hair)")
    ax.set_title(f"detect: {result['strands']} strands of the sample wavy groom on the sample bust", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    _save(fig, path)


def detect_section(result: dict) -> list[str]:
    rows = []
    for r in result["rows"]:
        what = (f"samples_per_element {r['samples_per_element']}" if r["kind"] == "samples"
                else f"max_hair_per_element {r['max_hair_per_element'] or '0 (none)'}")
        rows.append([what, f"{1e3 * r['seconds']:.1f}", r["contacts"], r["body"], r["hair"], r["touching"]])
    same = all(v == result["default"] for v in result["presets"].values())
    return [
        "### detect: `contacts.samples_per_element` and `contacts.max_hair_per_element`",
        "",
        f"`detect_contacts` on {result['strands']} strands of the sample wavy groom ({result['elements']:,} elements) "
        f"on the sample bust, one knob changed at a time from the default "
        f"(samples_per_element {result['default'][0]}, max_hair_per_element {result['default'][1]}); time: median of "
        f"{REPEATS} runs. "
        + ("The three presets leave both at the default (they mark one point). " if same else "")
        + "What the contacts cost further on (the inversion's and the simulation's time follow the contact count) "
        "is in the sections above; a contact missed shows up as a strand sinking into the body or another strand.",
        "",
        "![detect: time against contacts declared](img/bench_trade_detect.png)",
        "",
        table(["setting", "time (ms)", "contacts", "hair-body", "hair-hair", "strands touching the body"], rows,
              ["l", "r", "r", "r", "r", "r"]),
    ]


# ---------------------------------------------------------------------------------------------------------------


STAGES = (("fit", fit_stage, fit_plot, fit_section),
          ("invert", invert_stage, invert_plot, invert_section),
          ("simulate", simulate_stage, simulate_plot, simulate_section),
          ("detect", detect_stage, detect_plot, detect_section))


def _jsonable(value):
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def _stage(name: str, redraw: bool = False) -> list[str]:
    """Run one stage (or, with ``redraw``, read its last run's figures from out/), draw its plot and return its
    subsection, the ``### `` title first."""
    _, stage, plot, section = next(s for s in STAGES if s[0] == name)
    saved = WORK / f"bench_trade_{name}.json"
    if redraw:
        result = json.loads(saved.read_text())
    else:
        log(f"trade: {name}")
        BACKGROUND.clear()
        when = datetime.datetime.now(datetime.timezone.utc)
        load = _load()
        started = time.perf_counter()
        result = stage()
        result.update(background=list(BACKGROUND), started=f"{when:%Y-%m-%d %H:%M}", load=load,
                      seconds=time.perf_counter() - started)
        # the figures of the run, kept beside its work files (out/), to read or redraw without running again
        WORK.mkdir(parents=True, exist_ok=True)
        saved.write_text(json.dumps(_jsonable(result), indent=1))
        log(f"trade: {name} done, {result['seconds']:.0f} s")
    plot(result, IMG / f"bench_trade_{name}.png")
    shares = np.array(result["background"]) if result["background"] else np.zeros(1)
    return section(result) + [
        "", f"Other processes used a median of {100 * np.median(shares):.0f} % of the machine's CPU during this "
            f"stage's timed runs ({100 * np.percentile(shares, 90):.0f} % at the 90th percentile, "
            f"{len(result['background'])} runs); its times are slower by about that share.", ""]


def run() -> str:
    parts = []
    for name, *_ in STAGES:
        parts += _stage(name)
    return "\n".join([
        f"## {TITLE}",
        "",
        "`bench/trade_bench.py`: every knob that trades time for accuracy, swept on the same grooms, each point a "
        "time against an error a user sees: the fit's distance from the input, the rest shape's distance from the "
        "exact optimum, the simulation's distance from a finer one, and the contacts declared. The presets "
        "`draft`, `default` and `final` (configs/quality/) are marked on each plot. All runs of a stage in one "
        "process on the machine at the top of this page, with the numba kernels compiled beforehand.",
        "",
    ] + parts).rstrip() + "\n"


def replace_subsection(page: str, text: str) -> str:
    """``page`` with the subsection of this section that ``text`` is (matched by its ``### stage:`` prefix)
    replaced by ``text``; the rest of the page as it was."""
    lines = page.split("\n")
    head = lines.index(f"## {TITLE}")
    prefix = text.split("\n", 1)[0].split(":", 1)[0] + ":"
    start = next(i for i in range(head + 1, len(lines)) if lines[i].startswith(prefix))
    if any(line.startswith("## ") for line in lines[head + 1:start]):
        raise ValueError(f"no {prefix} subsection under ## {TITLE}")
    end = next((i for i in range(start + 1, len(lines)) if lines[i].startswith(("### ", "## "))), len(lines))
    return "\n".join(lines[:start] + text.rstrip("\n").split("\n") + [""] + lines[end:])


def stamp(text: list[str], name: str, result: dict) -> list[str]:
    """A subsection rerun alone, with a line under its title saying when, for how long and at what load."""
    load = result.get("load")
    line = (f"_Rerun alone on {result['started']} (UTC), {result['seconds'] / 60:.1f} min"
            + (", load average at its start " + " / ".join(f"{v:.2f}" for v in load) if load else "")
            + f" (`bench/trade_bench.py --stage {name} --write`); the other subsections are from the run "
              "above._")
    return text[:1] + ["", line] + text[1:]


def main(argv=None) -> int:
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--stage", action="append", choices=[s[0] for s in STAGES],
                        help="run only this stage (repeatable) and print its subsection")
    parser.add_argument("--write", action="store_true",
                        help="with --stage: replace the stage's subsection in docs/benchmarks.md, the rest of the "
                             "page as it was")
    parser.add_argument("--redraw", action="store_true",
                        help="with --stage: no runs; the plot and text from the last run's figures in out/")
    args = parser.parse_args(argv)
    if not args.stage:
        if args.write or args.redraw:
            parser.error("--write and --redraw need --stage (the whole section: bench/run.py trade)")
        print(run())
        return 0
    page_path = DOCS / "benchmarks.md"
    for name in args.stage:
        text = _stage(name, redraw=args.redraw)
        if args.write:
            if SMOKE:
                parser.error("a smoke run does not write docs/")
            result = json.loads((WORK / f"bench_trade_{name}.json").read_text())
            page_path.write_text(replace_subsection(page_path.read_text(), "\n".join(stamp(text, name, result))))
            log(f"wrote the {name} subsection of {page_path}")
        print("\n".join(text))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
