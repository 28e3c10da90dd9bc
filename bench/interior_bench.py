"""The interior-point method against the sweeps and Clarabel: rest-shape distance from the optimum against time.

Run alone with ``python bench/interior_bench.py`` (prints the markdown
section), or ``python bench/run.py interior`` to write it into
``docs/benchmarks.md``. About 13 minutes.

On ruby short (a seeded 1,000-guide subset and the whole groom), the SOCQP
built as ``invert`` builds it (``invert_bench.Problem``), each solver is run
to several accuracies in this process:

* the sweeps (``gauss_seidel.solve``, momentum on, as ``invert`` runs them) at
  several sweep caps;
* the interior-point method (``interior.solve``) at the presets' rest-shape
  tolerances, with its own bound on the distance;
* Clarabel at three tolerances (the subset only: on the whole groom a single
  run at its default tolerance took over 13 minutes).

Accuracy is the rms over elements of ``|q0 - q0*|`` (1/m), the distance of
the rest shape from that of the run with the lowest objective of all.

Then the samples and generated grooms (``bench/grooms.py``, variants it was
developed on and held-out ones) through ``hairinv invert`` with each method
at its defaults: status, steps, time, the bound, and how far apart the two
rest shapes are.
"""

from __future__ import annotations

import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import invert_bench as ib  # type: ignore
    from common import IMG, ROOT, WORK, log, smoke, table  # type: ignore
else:
    from . import invert_bench as ib
    from .common import IMG, ROOT, WORK, log, smoke, table

from hairinv.solver import gauss_seidel, interior  # noqa: E402
from hairinv.solver.gauss_seidel import split_strands  # noqa: E402
from hairinv.solver.interior import cholesky_backend  # noqa: E402
from hairinv.solver.problem import CONE, ConeProblem, InteriorSettings, SweepSettings  # noqa: E402
from hairinv.solver.reference import solve_socqp_clarabel  # noqa: E402
from hairinv.contacts.rows import contact_rows  # noqa: E402
from hairinv.testing import project_cone  # noqa: E402

TITLE = "The interior-point method: rest shape against time"
GROOMS = smoke(((1000, True), (0, False)), ((30, True),))  # (guides, 0: all; run Clarabel)
SWEEPS = smoke((100, 300, 1000, 2000), (10, 30))
SWEEPS_CAP = smoke(20000, 60)  # the sweeps stopped by rest_tolerance: a cap they should not reach
REST = smoke((0.5, 0.05, 0.005), (0.5, 0.05))  # 1/m: draft, default, final
CLARABEL_TOLS = smoke((1e-3, 1e-5, 1e-8), (1e-3,))
TARGET = 0.05  # 1/m, the distance the targets are stated at
SAMPLES = smoke(("wavy", "curly", "straight", "settled"), ("settled",))
# generated grooms of bench/grooms.py: two it was developed on, four held out (other seeds, gaps, spacings)
GENERATED = smoke(("draped_gap4", "mohawk", "draped_gap5_s3_sp2", "curly_gap6_r4_s5", "mohawk_s2", "updo_s2"), ())
HAIRINV = ROOT / ".venv" / "bin" / "hairinv"
PYTHON = ROOT / ".venv" / "bin" / "python"


def _case(guides: int) -> dict:
    g = ib.prepare_groom(guides, 1)
    prob = ib.Problem.build(g["helices"], g["contacts"], g["material"], g["settings"].solver)
    h, c = prob.helices, prob.contacts
    length = np.add.reduceat(h.length, h.offsets[:-1])
    weight = g["material"].linear_density * np.linalg.norm(g["material"].gravity) * float(length.max())
    return {"guides": guides, "prob": prob, "rows": contact_rows(h, c), "weight": weight,
            "strands": h.n_strands, "elements": h.n_elements, "contacts": c.n_contacts,
            "hair_hair": int(np.count_nonzero(c.strand[:, 1] >= 0))}


def _problem(case: dict) -> ConeProblem:
    """The inverse problem of ``case`` as the solvers take it, the residual relative to the heaviest strand's weight."""
    p, rows, c, h = case["prob"], case["rows"], case["prob"].contacts, case["prob"].helices
    return ConeProblem.of(rows, p.d, p.gamma, p.b, c.mu, c.strand, h.n_strands, case["weight"], s=c.s,
                          part_of=split_strands(h.root, c.strand))


def _runs(case: dict, clarabel: bool) -> list[dict]:
    p, rows, c, h = case["prob"], case["rows"], case["prob"].contacts, case["prob"].helices
    problem = _problem(case)
    out = []
    for n in SWEEPS:
        log(f"  sweeps {n}")
        t = time.perf_counter()
        res = gauss_seidel.solve(problem, CONE, SweepSettings(1e-12, n, 5))
        out.append({"solver": "sweeps", "setting": f"{n} sweeps", "seconds": time.perf_counter() - t, "r": res.r,
                    "steps": res.sweeps, "bound": res.rest_bound, "status": res.status})
    for tol in REST:  # the sweeps stopped by their own bound (the residual tolerance out of reach)
        log(f"  sweeps, rest_tolerance {tol}")
        t = time.perf_counter()
        res = gauss_seidel.solve(problem, CONE, SweepSettings(1e-12, SWEEPS_CAP, 5, rest_tolerance=tol))
        out.append({"solver": "sweeps", "setting": f"rest_tolerance {tol:g}", "seconds": time.perf_counter() - t,
                    "r": res.r, "steps": res.sweeps, "bound": res.rest_bound, "status": res.status})
    for tol in REST:
        log(f"  interior point {tol}")
        res = interior.solve(problem, CONE, InteriorSettings(rest_tolerance=tol))
        out.append({"solver": "interior point", "setting": f"rest_tolerance {tol:g}", "seconds": res.seconds,
                    "r": project_cone(res.r, c.mu), "steps": res.iterations, "bound": res.rest_bound,
                    "status": res.status, "history": res.history})
    if clarabel:
        for tol in CLARABEL_TOLS:
            log(f"  Clarabel {tol:g}")
            t = time.perf_counter()
            r, info = solve_socqp_clarabel(p.H, p.d, p.gamma, p.b.ravel(), c.mu, tol=tol)
            out.append({"solver": "Clarabel", "setting": f"tolerance {tol:g}", "seconds": time.perf_counter() - t,
                        "r": project_cone(r, c.mu), "steps": info["iterations"], "bound": np.nan,
                        "status": info["status"]})
    for run in out:
        run["objective"] = p.objective(run["r"])
    best = min(out, key=lambda run: run["objective"])
    for run in out:
        run["distance"] = float(np.sqrt(np.mean(np.sum((p.rest(run["r"]) - p.rest(best["r"])) ** 2, axis=1))))
        run["best"] = run is best
    return out


def _fastest(runs: list[dict], solver: str, within: float):
    ok = [r for r in runs if r["solver"] == solver and r["distance"] <= within]
    return min(ok, key=lambda r: r["seconds"]) if ok else None


def _label(case: dict) -> str:
    return f"ruby short, {case['guides']:,} guides" if case["guides"] else "ruby short, whole"


def _invert_cli(stage: Path, body: Path, method: str, out: Path) -> dict:
    """``hairinv invert`` of a detected stage file with ``method`` (stability check off): the solver's line."""
    out.unlink(missing_ok=True)
    done = subprocess.run([str(HAIRINV), "invert", str(stage), str(body), "-o", str(out), "--no-stability-check",
                           "--set", f"solver.method={method}"], capture_output=True, text=True, cwd=ROOT)
    if done.returncode != 0:
        raise RuntimeError(f"hairinv invert {stage} ({method}) failed: {done.stderr[-500:]}")
    text = done.stdout + done.stderr
    line = re.search(r"^solver: (\w+) after (.+?) in ([\d.]+) s", text, re.M)
    bound = re.search(r"within ([\d.e+-]+) 1/m", text)
    import h5py

    with h5py.File(out, "r") as f:
        rest = f["model/omega_rest"][:]
        contacts = int(f["contacts/mu"].shape[0])
    return {"status": line.group(1), "steps": line.group(2), "seconds": float(line.group(3)),
            "bound": float(bound.group(1)) if bound else np.nan, "rest": rest, "contacts": contacts}


def other_grooms() -> list[dict]:
    """The samples and generated grooms, each detected once, then inverted by each method (the CLI)."""
    work = WORK / "interior_bench"
    work.mkdir(parents=True, exist_ok=True)
    grooms = [(f"sample {n}", ROOT / "samples" / f"{n}.h5", ROOT / "samples" / "body.obj", "sample")
              for n in SAMPLES]
    if GENERATED:
        log("interior: generating " + ", ".join(GENERATED))
        subprocess.run([str(PYTHON), str(ROOT / "bench" / "grooms.py"), "-o", str(work), *GENERATED], check=True,
                       stdout=subprocess.DEVNULL, cwd=ROOT)
        sys.path.insert(0, str(ROOT / "bench"))
        import grooms as gg

        grooms += [(n, work / f"{n}.h5", work / "mannequin.obj",
                    "development" if n in gg.DEVELOPMENT else "held out") for n in GENERATED]
    rows = []
    for label, path, body, kind in grooms:
        log(f"interior: {label}")
        stage = work / f"{path.stem}.detect.h5"
        stage.unlink(missing_ok=True)
        subprocess.run([str(HAIRINV), "detect", str(path), str(body), "-o", str(stage)], check=True,
                       capture_output=True, cwd=ROOT)
        runs = {m: _invert_cli(stage, body, m, work / f"{path.stem}.{m}.h5") for m in ("sweeps", "interior-point")}
        d = runs["sweeps"]["rest"] - runs["interior-point"]["rest"]
        rows.append({"groom": label, "kind": kind, "contacts": runs["sweeps"]["contacts"], **runs,
                     "difference": float(np.sqrt(np.mean(np.sum(d ** 2, axis=1))))})
    return rows


def plot(results, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    fig, axes = plt.subplots(1, len(results), figsize=(6 * len(results), 4.5), squeeze=False)
    styles = {"sweeps": ("o-", "C0"), "interior point": ("s-", "C3"), "Clarabel": ("^-", "C2")}
    for ax, (case, runs) in zip(axes[0], results):
        for solver, (marker, colour) in styles.items():
            rs = sorted([r for r in runs if r["solver"] == solver], key=lambda r: r["seconds"])
            if rs:
                ax.loglog([r["seconds"] for r in rs], [max(r["distance"], 1e-5) for r in rs], marker, color=colour,
                          label=solver)
        tight = [r for r in runs if r["solver"] == "interior point"]
        if tight:  # the bound the tightest run reported at each of its steps
            h = np.array(tight[-1]["history"])
            ax.loglog(h[:, 1], h[:, 2], ":", color="C3", lw=1, label="interior point: its bound, step by step")
        ax.axhline(TARGET, color="grey", lw=0.8, ls="--")
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_title(f"{_label(case)} ({case['contacts']:,} contacts)")
        ax.set_xlabel("time, s")
        ax.set_ylabel("rest shape from the optimum, rms 1/m (1e-5: the best run)")
        ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def warm_up() -> None:
    """Compile the kernels of every solver timed here on a small groom first, so that no timing includes it."""
    case = _case(ib.WARMUP_GUIDES)
    problem = _problem(case)
    gauss_seidel.solve(problem, CONE, SweepSettings(1e-12, 10, 5, rest_tolerance=0.05))
    interior.solve(problem, CONE, InteriorSettings(rest_tolerance=0.05))


def run() -> str:
    started = time.perf_counter()
    log("interior: compiling the solvers on a small groom")
    warm_up()
    results = []
    for guides, clarabel in GROOMS:
        log(f"interior: ruby short, {guides or 'all'} guides")
        case = _case(guides)
        results.append((case, _runs(case, clarabel)))
    IMG.mkdir(parents=True, exist_ok=True)
    image = IMG / "bench_interior.png"
    plot(results, image)
    others = other_grooms()
    return render(results, others, image, time.perf_counter() - started)


def render(results, others, image: Path, total: float) -> str:
    parts = [f"## {TITLE}\n",
             "`bench/interior_bench.py`. The same SOCQP as `invert` builds it for ruby short (default settings: "
             "each contact weighs at least `solver.gamma_relative` of its diagonal; the friction as declared), "
             "solved by the sweeps (`solver.method = sweeps`), by the interior-point method (`solver.method = "
             f"interior-point`, which `auto`, the default, takes here; sparse Cholesky: {cholesky_backend()}) "
             "and by Clarabel, in one process. "
             "Distance: rms over elements of `|q0 - q0*|`, 1/m, from the rest shape of the run with the lowest "
             "objective (marked *). Bound: what each method reports, from a duality gap (the interior point's "
             "own; the sweeps' from the forces they return, `hairinv.solver.gauss_seidel.rest_gap`). The sweeps "
             "run either a fixed number of sweeps or until their bound meets `rest_tolerance` (with `solver."
             "tolerance` out of reach). Times are the solver's own (Clarabel: the call, with building its "
             "matrices).\n"]
    for case, runs in results:
        parts.append(f"### {_label(case)}\n")
        parts.append(f"{case['strands']:,} strands, {case['elements']:,} elements, {case['contacts']:,} contacts "
                     f"({case['hair_hair']:,} hair-hair).\n")
        rows = [[r["solver"], r["setting"], f"{r['seconds']:.2f} s", r["steps"], r["status"],
                 f"{r['distance']:.3g}" + (" *" if r["best"] else ""),
                 "" if not np.isfinite(r["bound"]) else f"{r['bound']:.3g}", f"{r['objective']:.6g}"]
                for r in runs]
        parts.append(table(["solver", "setting", "time", "sweeps / steps", "status", "distance, 1/m", "bound, 1/m",
                            "objective"], rows, ["l", "l", "r", "r", "l", "r", "r", "r"]) + "\n")
        ip = _fastest(runs, "interior point", TARGET)
        gs = _fastest(runs, "sweeps", TARGET)
        cl = _fastest(runs, "Clarabel", TARGET)
        line = [f"Within {TARGET} 1/m of the optimum:"]
        line.append(f"the interior point in {ip['seconds']:.2f} s ({ip['setting']})" if ip
                    else "the interior point not in these runs")
        line.append(f"the sweeps in {gs['seconds']:.2f} s ({gs['setting']})" if gs
                    else f"the sweeps not within {max(SWEEPS)} sweeps")
        if not any(r["solver"] == "Clarabel" for r in runs):
            line.append("Clarabel not run here (over 13 minutes at its default tolerance on this groom, "
                        "measured by `bench/invert_bench.py` with `HAIRINV_BENCH_CLARABEL_FULL=1`)")
        else:
            line.append(f"Clarabel in {cl['seconds']:.2f} s ({cl['setting']})" if cl
                        else "Clarabel not in these runs")
        text = line[0] + " " + "; ".join(line[1:]) + "."
        if ip and cl:
            text += f" Clarabel's time over the interior point's: **{cl['seconds'] / ip['seconds']:.1f}**."
        parts.append(text + "\n")
        for solver in ("sweeps", "interior point"):
            held = [r for r in runs if r["solver"] == solver and np.isfinite(r["bound"])]
            if held:
                ok = all(r["distance"] <= r["bound"] * (1 + 1e-9) for r in held)
                ratios = [r["bound"] / r["distance"] for r in held if r["distance"] > 1e-4]
                parts.append(f"The {solver}' bound " if solver == "sweeps" else f"The {solver}'s bound ")
                parts[-1] += ("held" if ok else "**did not hold**") + " on every run here (distance at most the bound)"
                if ratios:
                    parts[-1] += (f"; it was {min(ratios):.1f} to {max(ratios):.1f} times the distance actually left "
                                  "(runs more than 1e-4 1/m away)")
                parts[-1] += ".\n"
    parts.append(f"![rest shape against time](img/{image.name})\n")
    if others:
        parts.append("### Other grooms, through the command line\n")
        parts.append("Each groom detected once (`hairinv detect`), then `hairinv invert --no-stability-check` with "
                     "each `solver.method` at its defaults (the sweeps: `rest_tolerance` 0.05 1/m or tolerance 1e-4, "
                     "at most 2,000 sweeps; the interior point: `rest_tolerance` 0.05 1/m). Time: the solver's, from "
                     "the report; bounds: from the report. Difference: rms over elements between the two rest "
                     "shapes, 1/m. Generated grooms: `bench/grooms.py`, marked as the variants it was developed on "
                     "or held out.\n")
        rows = [[r["groom"], r["kind"], f"{r['contacts']:,}",
                 f"{r['sweeps']['status']}, {r['sweeps']['steps']}, {r['sweeps']['seconds']:.2f} s",
                 f"{r['interior-point']['status']}, {r['interior-point']['steps']}, "
                 f"{r['interior-point']['seconds']:.2f} s",
                 f"{r['sweeps']['bound']:.2g} / {r['interior-point']['bound']:.2g}", f"{r['difference']:.3g}"]
                for r in others]
        parts.append(table(["groom", "kind", "contacts", "sweeps", "interior point", "bounds, 1/m: sweeps / "
                            "interior point", "difference, 1/m"], rows, ["l", "l", "r", "l", "l", "r", "r"]) + "\n")
        converged = sum(r["interior-point"]["status"] == "CONVERGED" for r in others)
        faster = sum(r["interior-point"]["seconds"] < r["sweeps"]["seconds"] for r in others)
        parts.append(f"The interior point converged on {converged} of {len(others)} grooms and took less time than "
                     f"the sweeps on {faster}; the sweeps converged on "
                     f"{sum(r['sweeps']['status'] == 'CONVERGED' for r in others)}.\n")
    parts.append(f"This section took {total / 60:.1f} min.\n")
    return "\n".join(parts)


if __name__ == "__main__":
    print(run())
