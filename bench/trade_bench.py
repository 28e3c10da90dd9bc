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
* simulate: ``dynamics.time_step``, ``dynamics.max_turn`` and ``dynamics.tolerance`` on 40 inverted guides of
  the wavy sample in the ``motion`` scene's first 0.5 s: wall time against the distance of the strands' points
  at the end from a reference run at finer settings than ``final``;
* detect: ``contacts.samples_per_element`` and ``contacts.max_hair_per_element`` on the wavy sample: time
  against the contacts declared.

The quality presets (``configs/quality/{draft,default,final}.toml``) are placed on each stage's curve.

    .venv/bin/python bench/run.py trade      # rewrites this section of docs/benchmarks.md
    .venv/bin/python bench/trade_bench.py    # prints it
"""

from __future__ import annotations

import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from common import DATA, IMG, ROOT, SMOKE, WORK, log, median_time, smoke, table  # noqa: E402

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
SIM_GUIDES = smoke(40, 4)
SIM_SECONDS = smoke(0.5, 0.04)
SIM_STEPS = smoke((0.02, 0.01, 0.005, 0.0025), (0.02, 0.01))
SIM_TURNS = smoke((0.2, 0.1, 0.05, 0.025), (0.1,))
SIM_TOLERANCES = smoke((1e-4, 1e-6, 1e-8), (1e-4,))
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
    from hairinv.invert import Material
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


def simulate_stage() -> dict:
    from hairinv.dynamics.run import _samples, run_scene
    from hairinv.dynamics.scene import Scene
    from hairinv.invert import Material, invert
    from hairinv.pipeline import prepare

    settings = config.apply(config.resolve(), {"import": {"guides": SIM_GUIDES}})
    scene = prepare(SAMPLES / "wavy.h5", BODY, settings)
    helices = scene.helices
    material = Material.from_settings(settings.material, scene.up)
    model, _ = invert(helices, scene.contacts, material, settings.solver)
    group = model.group({}, [])
    out = {"strands": helices.n_strands, "elements": helices.n_elements, "contacts": scene.contacts.n_contacts,
           "rows": [], "still": []}

    def simulate(name, dynamics, seconds):
        s = dataclasses.replace(settings, dynamics=dynamics)
        sc = Scene.load(name)
        return lambda: run_scene(helices, group, scene.contacts, scene.body, sc, s, seconds=seconds, fps=sc.fps)

    def points(frames):
        return _samples(helices, np.asarray(frames.omega[-1]))

    simulate("motion", settings.dynamics, 2 * SIM_STEPS[0])()  # warm
    log(f"simulate: the reference {SIM_REFERENCE}")
    ref_dyn = dataclasses.replace(settings.dynamics, **SIM_REFERENCE)
    started = time.perf_counter()
    ref = simulate("motion", ref_dyn, SIM_SECONDS)()
    out["reference_seconds"] = time.perf_counter() - started
    ref_points = points(ref)
    out["reference_moved"] = max(f.displacement for f in ref.log)
    base = settings.dynamics
    runs = ([dict(kind="time_step", dynamics=dataclasses.replace(base, time_step=h)) for h in SIM_STEPS]
            + [dict(kind="max_turn", dynamics=dataclasses.replace(base, max_turn=t)) for t in SIM_TURNS]
            + [dict(kind="tolerance", dynamics=dataclasses.replace(base, tolerance=t)) for t in SIM_TOLERANCES]
            + [dict(kind="preset", preset=q, dynamics=_preset(q).dynamics) for q in QUALITIES])
    for run in runs:
        d = run["dynamics"]
        log(f"simulate: {run['kind']} {run.get('preset') or ''} h {d.time_step} turn {d.max_turn} tol {d.tolerance}")
        seconds, frames, n = _timed(simulate("motion", d, SIM_SECONDS))
        dev = np.array([float(np.max(np.linalg.norm(a - b, axis=1))) for a, b in zip(points(frames), ref_points)])
        out["rows"].append(dict(seconds=seconds, runs=n, max=float(dev.max()), mean=float(dev.mean()),
                                halved=int(sum(f.halved for f in frames.log)),
                                unconverged=int(sum(f.unconverged_steps for f in frames.log)),
                                time_step=d.time_step, max_turn=d.max_turn, tolerance=d.tolerance,
                                max_sweeps=d.max_sweeps, stall_rounds=d.stall_rounds,
                                kind=run["kind"], preset=run.get("preset")))
    for q in QUALITIES:
        log(f"simulate: still, {q}")
        seconds, frames, n = _timed(simulate("still", _preset(q).dynamics, STILL_SECONDS))
        out["still"].append(dict(preset=q, seconds=seconds, runs=n, moved=max(f.displacement for f in frames.log)))
    return out


def simulate_plot(result: dict, path: Path) -> None:
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7.5, 5.0))
    floor = 1e-7
    for kind, colour, label, tag in (
            ("time_step", "tab:blue", "dynamics.time_step (s)", lambda r: f"{r['time_step']:g}"),
            ("max_turn", "tab:red", "dynamics.max_turn (rad)", lambda r: f"{r['max_turn']:g}"),
            ("tolerance", "tab:gray", "dynamics.tolerance", lambda r: f"{r['tolerance']:g}")):
        line = [r for r in result["rows"] if r["kind"] == kind]
        ax.plot([r["seconds"] for r in line], [max(1e3 * r["mean"], floor) for r in line], "-o", ms=4,
                color=colour, label=label)
        for r in line:
            ax.annotate(tag(r), (r["seconds"], max(1e3 * r["mean"], floor)), textcoords="offset points",
                        xytext={"time_step": (4, 4), "max_turn": (4, -11), "tolerance": (-30, 6)}[kind], fontsize=7,
                        color=colour)
    _mark_presets(ax, [r for r in result["rows"] if r["kind"] == "preset"], lambda r: r["seconds"],
                  lambda r: 1e3 * r["mean"], floor)
    _log_axes(ax)
    ax.set_xlabel(f"wall time of {SIM_SECONDS:g} s simulated (s)")
    ax.set_ylabel("distance from the reference at the end (mm), mean over strands")
    ax.set_title(f"simulate: {result['strands']} inverted wavy guides, the motion scene's first {SIM_SECONDS:g} s",
                 fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="lower left")
    _save(fig, path)


def simulate_section(result: dict) -> list[str]:
    rows = []
    for r in result["rows"]:
        what = {"time_step": f"time_step {r['time_step']:g} s", "max_turn": f"max_turn {r['max_turn']:g} rad",
                "tolerance": f"tolerance {r['tolerance']:g}",
                "preset": f"**{r['preset']}** (time_step {r['time_step']:g}, tolerance {r['tolerance']:g}, "
                          f"max_sweeps {r['max_sweeps']}, stall_rounds {r['stall_rounds']})"}[r["kind"]]
        rows.append([what, f"{r['seconds']:.2f}", _mm(r["max"]), _mm(r["mean"]), r["halved"], r["unconverged"]])
    still = ", ".join(f"{s['preset']} {s['seconds']:.2f} s (largest displacement {1e3 * s['moved']:.1g} mm)"
                      for s in result["still"])
    ref = SIM_REFERENCE
    return [
        "### simulate: `dynamics.time_step`, `dynamics.max_turn`, `dynamics.tolerance`",
        "",
        f"`hairinv.dynamics.run.run_scene` on {result['strands']} guides of the sample wavy groom "
        f"({result['elements']} elements, {result['contacts']} contacts), inverted once with the `default` "
        f"settings, in the first {SIM_SECONDS:g} s of the `motion` scene (the head starts turning). Each run changes "
        f"one knob of the `default` dynamics, or takes a preset's `[dynamics]` (the fit and the inversion stay the "
        f"default's). The reference: time_step {ref['time_step']:g} s, max_turn {ref['max_turn']:g} rad, "
        f"tolerance {ref['tolerance']:g}, {ref['max_sweeps']} sweeps a step, stall_rounds 0 "
        f"({result['reference_seconds']:.1f} s; the strands move up to {1e3 * result['reference_moved']:.1f} mm). "
        "Error: each strand's largest point distance from the reference's at the end (points at the ends and "
        "middle of every element), the largest and the mean over strands; the plot shows the mean (the largest is "
        "one strand's, whose path through its contacts may fork). Time: wall clock of the run, median "
        f"of {REPEATS} when under {QUICK:g} s. Halved: steps split by max_turn; unconverged: steps whose contact "
        "solve stopped on its sweep cap or stall.",
        "",
        "![simulate: time against the distance from the reference](img/bench_trade_simulate.png)",
        "",
        table(["setting", "time (s)", "largest distance (mm)", "mean over strands (mm)", "halved", "unconverged"],
              rows, ["l", "r", "r", "r", "r", "r"]),
        "",
        f"At rest (the `still` scene, {STILL_SECONDS:g} s, each preset's dynamics): {still}.",
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


def run() -> str:
    started = time.perf_counter()
    parts = []
    for name, stage, plot, section in STAGES:
        log(f"trade: {name}")
        BACKGROUND.clear()
        result = stage()
        result["background"] = list(BACKGROUND)
        # the figures of the run, kept beside its work files (out/), to read or redraw without running again
        WORK.mkdir(parents=True, exist_ok=True)
        (WORK / f"bench_trade_{name}.json").write_text(json.dumps(_jsonable(result), indent=1))
        plot(result, IMG / f"bench_trade_{name}.png")
        shares = np.array(BACKGROUND) if BACKGROUND else np.zeros(1)
        parts += section(result) + [
            "", f"Other processes used a median of {100 * np.median(shares):.0f} % of the machine's CPU during this "
                f"stage's timed runs ({100 * np.percentile(shares, 90):.0f} % at the 90th percentile, "
                f"{len(BACKGROUND)} runs); its times are slower by about that share.", ""]
        log(f"trade: {name} done, {time.perf_counter() - started:.0f} s")
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


if __name__ == "__main__":
    print(run())
