"""Benchmark of the super-helix fit on hard grooms: kinks, waves, coils, coarse and noisy strands.

Run alone with ``python bench/fit_any_bench.py`` (prints the markdown section),
or through ``bench/run.py``, which writes ``docs/benchmarks.md``.

Every variant of ``bench/fit_grooms.py`` (development and held out), made
with ``STRANDS`` strands, and the real grooms of ``bench/fit_bench.py``
(``SOURCES`` and ``SINTEL``, every strand as the file has it) are fitted once
with the default ``FitSettings()`` and the default thread count, after a
warm-up fit that loads the compiled kernels. ``measure(groom, settings)``
gives the figures of one groom, for use elsewhere::

    from fit_any_bench import measure      # with bench/ on sys.path
    print(measure(groom, FitSettings()))
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))  # the generator and the other benchmarks are imported by name

if __package__ in (None, ""):
    from common import ROOT, log, machine, machine_markdown, median_time, smoke, table  # type: ignore
else:
    from .common import ROOT, log, machine, machine_markdown, median_time, smoke, table

sys.path.insert(0, str(ROOT))

import fit_grooms  # noqa: E402
from fit_bench import SINTEL, SOURCES, element_range  # noqa: E402  (the same real files as the main fit benchmark)

from hairinv._parallel import worker_count  # noqa: E402
from hairinv.config import FitSettings, ImportSettings  # noqa: E402
from hairinv.fit import fit_groom  # noqa: E402
from hairinv.groom import Groom, load_groom, strand_lengths  # noqa: E402
from hairinv.rod.fitting import closest_distances  # noqa: E402

TITLE = "Fitting hard grooms: kinks, waves, coils, coarse and noisy strands"
STRANDS = smoke(200, 3)  # per generated variant
RATIO_RANGE = (0.99, 1.08)  # fitted length / polyline length outside this range is counted
REAL = smoke([(path, scale, label) for path, scale, label in SOURCES], []) + [(SINTEL[0], SINTEL[1], "sintel")]


def measure(groom: Groom, settings: FitSettings | None = None, repeats: int = 1, quiet: bool = False) -> dict:
    """Fit ``groom`` (``repeats`` timed runs, the median kept) and return its figures.

    Keys: ``strands``; ``points_median``, ``points_min``, ``points_max`` (points per strand);
    ``tolerance`` (m); ``within`` (strands whose largest vertex distance ``fit_error[:, 1]`` is at most the
    tolerance); ``largest_mm`` (the largest vertex distance of all, mm); ``ratio_min``, ``ratio_max`` and
    ``ratio_outside`` (fitted length, the sum of a strand's element lengths, over its polyline length:
    the extremes and the count of strands outside ``RATIO_RANGE``); ``elements_median``, ``elements_max``;
    ``seconds`` (wall time of one ``fit_groom`` call, median) and ``ms_per_strand``; ``runs``;
    ``background`` (median share of the CPU other processes used during the runs);
    ``tolerance_missed`` (the fitter's own count); ``helices`` and ``report`` of the last run.
    With ``quiet``, each run first waits (a few seconds at most) for the machine to go idle.
    """
    settings = settings or FitSettings()
    timing = median_time(lambda: fit_groom(groom, settings), repeats, quiet=quiet)
    helices, report = timing.result
    counts = np.diff(groom.offsets)
    fitted = np.add.reduceat(helices.length, helices.offsets[:-1])
    ratio = fitted / strand_lengths(groom.points, groom.offsets)
    worst = helices.fit_error[:, 1]
    elements = np.diff(helices.offsets)
    return {
        "strands": groom.n_strands,
        "points_median": float(np.median(counts)),
        "points_min": int(counts.min()),
        "points_max": int(counts.max()),
        "tolerance": float(settings.tolerance),
        "within": int((worst <= settings.tolerance).sum()),
        "largest_mm": 1e3 * float(worst.max()),
        "ratio_min": float(ratio.min()),
        "ratio_max": float(ratio.max()),
        "ratio_outside": int(((ratio < RATIO_RANGE[0]) | (ratio > RATIO_RANGE[1])).sum()),
        "elements_median": float(np.median(elements)),
        "elements_max": int(elements.max()),
        "seconds": timing.median,
        "ms_per_strand": 1e3 * timing.median / groom.n_strands,
        "runs": len(timing.times),
        "background": float(np.median(timing.background)),
        "tolerance_missed": int(report.tolerance_missed),
        "helices": helices,
        "report": report,
    }


def under_the_noise(groom: Groom, clean: Groom, r: dict) -> dict:
    """A noisy groom's fit against the curve under its noise: ``clean`` is the same groom without the noise
    (same strands, same vertex count). Keys: ``noise_mm`` (median of
    the fit's per-strand noise estimates); ``fit_mean_mm``, ``fit_max_mm`` (distance of the noise-free
    vertices to the fitted curve: mean over all, largest); ``vertices_mean_mm``, ``vertices_max_mm`` (of
    the noisy vertices to the noise-free ones: what following the vertices would leave); ``ratio_min``,
    ``ratio_max`` (fitted length over the polyline's less the length noise adds to the chords, 2 sigma^2 / h
    per chord with the fit's estimate of sigma)."""
    if not np.array_equal(groom.offsets, clean.offsets):
        raise ValueError("the noise-free twin has other strands")
    h, rep = r["helices"], r["report"]
    count = groom.n_strands
    mean, worst = np.zeros(count), np.zeros(count)
    closest_distances(np.ascontiguousarray(clean.points, dtype=np.float64),
                      np.ascontiguousarray(clean.offsets, dtype=np.int64), h.root, h.frame0, h.offsets, h.omega,
                      h.length, mean, worst)
    off = np.linalg.norm(groom.points - clean.points, axis=1)
    chords = np.linalg.norm(np.diff(groom.points, axis=0), axis=1)
    chords[groom.offsets[1:-1] - 1] = np.inf  # between strands
    strand_of = np.repeat(np.arange(count), np.diff(groom.offsets) - 1)
    inner = np.delete(np.arange(len(chords)), groom.offsets[1:-1] - 1)
    excess = np.bincount(strand_of, weights=2 * rep.noise[strand_of] ** 2 / chords[inner], minlength=count)
    polyline = strand_lengths(groom.points, groom.offsets)
    fitted = np.add.reduceat(h.length, h.offsets[:-1])
    ratio = fitted / (polyline - excess)
    return {
        "noise_mm": 1e3 * float(np.median(rep.noise)),
        "fit_mean_mm": 1e3 * float(np.average(mean, weights=np.diff(groom.offsets))),
        "fit_max_mm": 1e3 * float(worst.max()),
        "vertices_mean_mm": 1e3 * float(off.mean()),
        "vertices_max_mm": 1e3 * float(off.max()),
        "ratio_min": float(ratio.min()),
        "ratio_max": float(ratio.max()),
    }


def _row(name: str, group: str, r: dict) -> list:
    pts = f"{r['points_median']:g} ({r['points_min']}-{r['points_max']})"
    return [name, group, r["strands"], pts, f"{r['within']} ({100 * r['within'] / r['strands']:.0f} %)",
            f"{r['largest_mm']:.3f}", f"{r['ratio_min']:.3f} - {r['ratio_max']:.3f}", r["ratio_outside"],
            f"{r['elements_median']:g} / {r['elements_max']}", f"{r['ms_per_strand']:.2f}"]


def _params(make) -> str:
    kw = {k: v for k, v in make.keywords.items() if k != "n_strands"}
    return f"`{make.func.__name__}(" + ", ".join(f"{k}={v}" for k, v in kw.items()) + ")`"


def run() -> str:
    """Generate, fit and measure every groom; return the markdown section."""
    start = time.perf_counter()
    info = machine()
    settings = FitSettings()
    log("fit_any: warm-up (loads or compiles the fit's kernels)")
    warm = fit_grooms.coarse(n_strands=8, seed=0)
    fit_groom(warm, settings)
    rows, results, described, noisy_rows = [], [], [], []
    generate_seconds = 0.0
    for v in fit_grooms.variants():
        t0 = time.perf_counter()
        groom = v.make(n_strands=STRANDS)
        generate_seconds += time.perf_counter() - t0
        group = "held out" if v.held_out else "development"
        log(f"fit_any: {v.name} ({group}), {groom.n_strands} strands, {len(groom.points)} points")
        r = measure(groom, settings)
        results.append((group, r))
        rows.append(_row(f"`{v.name}`", group, r))
        described.append(f"`{v.name}`: {_params(v.make)}")
        if v.make.func.__name__ == "noisy":
            u = under_the_noise(groom, v.make(n_strands=STRANDS, sigma=0.0), r)
            noisy_rows.append([f"`{v.name}`", group, f"{1e3 * v.make.keywords['sigma']:g}", f"{u['noise_mm']:.3f}",
                               f"{u['vertices_mean_mm']:.3f} / {u['vertices_max_mm']:.3f}",
                               f"{u['fit_mean_mm']:.3f} / {u['fit_max_mm']:.3f}",
                               f"{u['ratio_min']:.3f} - {u['ratio_max']:.3f}"])
    for path, scale, label in REAL:
        groom, _ = load_groom(path, ImportSettings(scale=scale))
        log(f"fit_any: {label} (real), {groom.n_strands} strands")
        r = measure(groom, settings)
        results.append(("real", r))
        rows.append(_row(f"{label} (`{path.parent.name}/{path.name}`, {scale:g} m/unit)", "real", r))
    total = time.perf_counter() - start
    tol_mm = settings.tolerance * 1e3
    sums = []
    for group in ("development", "held out", "real"):
        rs = [r for g, r in results if g == group]
        n = sum(r["strands"] for r in rs)
        ok = sum(r["within"] for r in rs)
        out = sum(r["ratio_outside"] for r in rs)
        sums.append(f"{group}: {ok:,} of {n:,} strands within the tolerance ({100 * ok / n:.0f} %), "
                    f"{out:,} with a length ratio outside [{RATIO_RANGE[0]:g}, {RATIO_RANGE[1]:g}]")
    busy = max(r["background"] for _, r in results)
    lines = [
        f"## {TITLE}",
        "",
        "`bench/fit_any_bench.py`. The fit (`hairinv.fit.fit_groom`, default `FitSettings()`: tolerance "
        f"{tol_mm:g} mm on the largest vertex distance, {element_range(settings)}) "
        "on strands of kinds it finds hard, made by `bench/fit_grooms.py` over the test mannequin of "
        "`bench/grooms.py` (roots on its scalp, strands 10-40 cm long draped over it): straight hair with the "
        "corners a kinematic drape leaves where points were pushed out of the body (`kinks`), waves across the "
        "strand in a slowly turning plane (`waved`), helical coils of 1-5 mm radius around the draped path "
        "sampled at 5-8 points per turn (`coil`), tight 1 mm coils on part of a strand and a slow wave on the "
        "rest (`mixed`), procedural strands of about 23 cm with 21 points (`coarse`), and captured-like strands "
        "with Gaussian noise on every point and uneven 2-6 mm spacing (`noisy`). Development variants are "
        "for tuning; held-out ones differ in seeds and parameter values. Each generated groom has "
        f"{STRANDS} strands (the real grooms: every strand of the file, as `bench/fit_bench.py` reads them). "
        f"\"Within {tol_mm:g} mm\": strands whose `fit_error[:, 1]` (largest vertex distance to the fitted "
        "centerline) is at most the tolerance. \"Length ratio\": a strand's fitted length (the sum of its "
        "element lengths) over its polyline length; a smooth curve through the vertices is at most a few "
        f"percent longer than the polyline, so strands outside [{RATIO_RANGE[0]:g}, {RATIO_RANGE[1]:g}] are "
        "counted: shorter, the fit cuts corners; longer, it makes detours between vertices. Two kinds make "
        "that range approximate: the helix through a coil's points is longer than its polyline (by about 5 % "
        "at 5 points per turn, 4 % at 6 and 2 % at 8 for the coils here), and the noise of the `noisy` grooms "
        "lengthens their polylines (by about 1-2 %), so a fit that smooths it comes out shorter. "
        f"Time: one run per groom, wall clock of `fit_groom` over the strands, {worker_count()} threads (the "
        "default), with the numba kernels already compiled.",
        "",
        machine_markdown(info),
        "",
        table(["groom", "set", "strands", "points per strand, median (range)", f"within {tol_mm:g} mm",
               "largest error, mm", "length ratio, min - max",
               f"ratio outside [{RATIO_RANGE[0]:g}, {RATIO_RANGE[1]:g}]", "elements, median / max",
               "ms per strand"], rows),
        "",
        "In all, " + "; ".join(sums) + ".",
        "",
        "The noisy grooms against the curve under their noise (the same generator and seed without the "
        "noise: the same strands and vertex counts). Where the vertices scatter (noise dominates their "
        "deviations from the chords) and following them would take more elements than they determine, the "
        "fit estimates the noise and fits the smooth curve through its middle instead, and the report says "
        "so. \"Vertices\": distance of each noisy vertex from its noise-free position, what following the "
        "vertices exactly would leave; \"fit\": distance of each noise-free vertex from the fitted curve "
        "(mean over vertices / largest). \"Length ratio\": fitted length over the polyline's less the "
        "length noise adds to the chords (2 sigma^2 / h per chord h, in expectation, with the fit's "
        "estimate of sigma).",
        "",
        table(["groom", "set", "noise sigma, mm", "estimated, mm (median)",
               "vertices from the curve, mm (mean / max)", "fit from the curve, mm (mean / max)",
               "length ratio, min - max"], noisy_rows),
        "",
        "The generated variants: " + "; ".join(described) + ".",
        "",
        f"Generating the grooms took {generate_seconds:.0f} s; the whole section {total / 60:.1f} min"
        + (f" (other processes used up to {100 * busy:.0f} % of the CPU during a fit)." if busy > 0.1 else "."),
        "",
    ]
    return "\n".join(lines)


if __name__ == "__main__":
    print(run())
