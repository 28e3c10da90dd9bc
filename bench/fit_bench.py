"""Benchmark of the super-helix fit (``hairinv.fit.fit_groom``).

Run alone with ``python bench/fit_bench.py`` (prints the markdown section),
or through ``bench/run.py``, which writes ``docs/benchmarks.md``.

Measured, in this order:

* the one-off numba compile time, in a fresh subprocess with an empty cache;
* 2,000 real strands of 32 points, 10-50 cm long: median of 5 runs of
  ``fit_groom`` with the default settings and thread count;
* a peer, ``scipy.optimize.least_squares`` fitting the same model to 100 of
  those strands, against our kernel on the same 100, both single-threaded;
* a tolerance sweep (speed against accuracy) with a plot;
* secondary grooms: the Sintel file as it is and the three samples.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from common import DATA, IMG, ROOT, SMOKE, log, median_time, smoke, table, wait_quiet  # type: ignore
else:
    from .common import DATA, IMG, ROOT, SMOKE, log, median_time, smoke, table, wait_quiet

sys.path.insert(0, str(ROOT))

from scipy.interpolate import CubicSpline  # noqa: E402
from scipy.optimize import least_squares  # noqa: E402

from hairinv.config import FitSettings, ImportSettings  # noqa: E402
from hairinv.fit import fit_groom  # noqa: E402
from hairinv.groom import Groom, load_groom  # noqa: E402
from hairinv.rod import fitting  # noqa: E402
from hairinv.rod.helix import points_at  # noqa: E402

TITLE = "Fitting super-helices to strands"
SEED = 0
STRANDS = smoke(2000, 40)
POINTS = 32
LENGTH_RANGE = (0.10, 0.50)  # m
SOURCES = [  # (file, metres per file unit, label)
    (DATA / "ruby" / "ruby_long_hair_16_guide.tfx", 0.002, "ruby long"),
    (DATA / "ponytail" / "hair_free_16_guide.tfx", 0.0025, "ponytail free"),
]
SINTEL = (DATA / "sintel" / "GEO-sintel_hair_emit.001-sintel_hair.tfx", 0.008)
SAMPLES = smoke(sorted((ROOT / "samples").glob("*.h5")), [ROOT / "samples" / "straight.h5"])
REPEATS = smoke(5, 1)
PEER_STRANDS = smoke(100, 2)
PEER_REPEATS = smoke(3, 1)
SWEEP_MM = smoke((0.05, 0.1, 0.2, 0.5, 1.0), (0.2, 1.0))
SWEEP_REPEATS = smoke(3, 1)
TARGET_SECONDS = 3.0
TARGET_MEAN_MM = 0.1
PLOT = IMG / "bench_fit_tolerance.png"
SPLINE_SAMPLES = 1000
# A fitted strand whose length exceeds its polyline's by more than this share is counted as too long.
LONG_FIT = 0.05
# Runs during which other processes used more than this share of the CPU are flagged.
BUSY = 0.10


# ---------------------------------------------------------------------------
# strand set


def _polyline_lengths(points: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    return np.array([seg[offsets[i]:offsets[i + 1] - 1].sum() for i in range(len(offsets) - 1)])


def _resample(p: np.ndarray, count: int) -> np.ndarray:
    """``count`` points evenly spaced by arc length along a cubic spline through ``p``.

    The spline (``scipy.interpolate.CubicSpline``, not-a-knot ends) is
    parameterised by chord length; its arc length is measured on
    ``SPLINE_SAMPLES`` points and inverted by linear interpolation.
    """
    u = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
    spline = CubicSpline(u, p, axis=0)
    fine = np.linspace(0.0, u[-1], SPLINE_SAMPLES)
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(spline(fine), axis=0), axis=1))])
    return spline(np.interp(np.linspace(0.0, arc[-1], count), arc, fine))


def build_strands() -> tuple[Groom, dict]:
    """The 2,000-strand set: real strands 10-50 cm long, resampled to 32 points."""
    pool, origin, counts = [], [], {}
    for path, scale, label in SOURCES:
        groom, _ = load_groom(path, ImportSettings(scale=scale))
        lengths = _polyline_lengths(groom.points, groom.offsets)
        keep = np.flatnonzero((lengths >= LENGTH_RANGE[0]) & (lengths <= LENGTH_RANGE[1]))
        counts[label] = {"strands": groom.n_strands, "in_range": len(keep), "points": int(np.diff(groom.offsets)[0])}
        pool += [groom.points[groom.offsets[i]:groom.offsets[i + 1]] for i in keep]
        origin += [label] * len(keep)
    rng = np.random.default_rng(SEED)
    chosen = np.sort(rng.choice(len(pool), STRANDS, replace=False))
    for label in counts:
        counts[label]["chosen"] = int(sum(origin[i] == label for i in chosen))
    points = np.ascontiguousarray(np.concatenate([_resample(pool[i], POINTS) for i in chosen]))
    offsets = np.arange(0, POINTS * (STRANDS + 1), POINTS, dtype=np.int64)
    groom = Groom(points, offsets, up=np.array([0.0, 1.0, 0.0]), scale_to_m=1.0, source="bench",
                  index=np.arange(STRANDS))
    lengths = _polyline_lengths(points, offsets)
    return groom, {"sources": counts, "lengths": lengths}


def subset(groom: Groom, idx: np.ndarray) -> Groom:
    rows = np.concatenate([np.arange(groom.offsets[i], groom.offsets[i + 1]) for i in idx])
    counts = np.diff(groom.offsets)[idx]
    offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    return Groom(np.ascontiguousarray(groom.points[rows]), offsets, groom.up, 1.0, groom.source, np.asarray(idx))


# ---------------------------------------------------------------------------
# compile time


_PROBE = textwrap.dedent(
    """
    import json, sys, time
    t0 = time.perf_counter()
    import numpy as np
    sys.path.insert(0, {root!r})
    from hairinv.config import FitSettings
    from hairinv.fit import fit_groom
    from hairinv.groom import Groom
    t1 = time.perf_counter()
    points = np.load({points!r})
    offsets = np.arange(0, {m} * 11, {m}, dtype=np.int64)
    groom = Groom(points, offsets, np.array([0.0, 1.0, 0.0]), 1.0, "probe", np.arange(10))
    t2 = time.perf_counter()
    fit_groom(groom, FitSettings())
    t3 = time.perf_counter()
    fit_groom(groom, FitSettings())
    t4 = time.perf_counter()
    print(json.dumps({{"import": t1 - t0, "first": t3 - t2, "second": t4 - t3}}))
    """
)


def measure_compile(groom: Groom) -> dict:
    """Compile cost of the fit path: a fresh interpreter, an empty ``NUMBA_CACHE_DIR``, 10 strands.

    Compile time = first ``fit_groom`` call minus the second (same strands,
    now compiled). Also returns the subprocess's total wall time.
    """
    import json

    with tempfile.TemporaryDirectory(prefix="hairinv-bench-") as tmp:
        np.save(Path(tmp) / "points.npy", groom.points[: 10 * POINTS])
        cache = Path(tmp) / "numba-cache"
        cache.mkdir()
        # a smoke run checks the probe only, with the kernels already compiled
        env = dict(os.environ) if SMOKE else dict(os.environ, NUMBA_CACHE_DIR=str(cache))
        code = _PROBE.format(root=str(ROOT), points=str(Path(tmp) / "points.npy"), m=POINTS)
        start = time.perf_counter()
        out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
        wall = time.perf_counter() - start
        cold_cache_files = sum(1 for _ in cache.rglob("*.nbc"))
    result = json.loads(out.stdout.strip().splitlines()[-1])
    result["wall"] = wall
    result["compile"] = result["first"] - result["second"]
    result["cache_files"] = cold_cache_files
    return result


# ---------------------------------------------------------------------------
# our fit


def fit_summary(groom: Groom, settings: FitSettings, repeats: int, slow: tuple | None = None) -> dict:
    """Median of ``repeats`` timed ``fit_groom`` runs, with the fit's figures.

    With ``slow = ((s1, n1), (s2, n2), ...)``, a groom whose first run takes
    longer than ``s`` seconds gets ``n`` runs in all instead of ``repeats``
    (the last matching pair wins), to bound the benchmark's duration.
    """
    first = median_time(lambda: fit_groom(groom, settings), 1)
    total = repeats
    for limit, runs in slow or ():
        if first.median > limit:
            total = min(total, runs)
    rest = median_time(lambda: fit_groom(groom, settings), total - 1) if total > 1 else None
    times = first.times + (rest.times if rest else [])
    background = first.background + (rest.background if rest else [])
    cpu = first.cpu + (rest.cpu if rest else [])
    helices, report = (rest or first).result
    seconds = float(np.median(times))
    fitted = np.add.reduceat(helices.length, helices.offsets[:-1])
    ratio = fitted / _polyline_lengths(groom.points, groom.offsets)
    return {
        "seconds": seconds,
        "times": times,
        "runs": len(times),
        "background": background,
        "cpu": float(np.median(cpu)),
        "ms_per_strand": 1e3 * seconds / groom.n_strands,
        "elements": report.elements,
        "mean_mm": 1e3 * float(helices.fit_error[:, 0].mean()),
        "max_mm": 1e3 * float(helices.fit_error[:, 1].max()),
        "p95_max_mm": 1e3 * float(np.percentile(helices.fit_error[:, 1], 95)),
        "over_tol": int((helices.fit_error[:, 1] > settings.tolerance * (1 + 1e-6)).sum()),
        "missed": report.tolerance_missed,
        "length_ratio": ratio,
        "too_long": int((ratio > 1 + LONG_FIT).sum()),
        "helices": helices,
    }


def _elements(e: np.ndarray) -> str:
    return f"{int(e.min())} / {np.median(e):g} / {int(e.max())}"


# ---------------------------------------------------------------------------
# the peer: scipy.optimize.least_squares on the same model


def _errors(p: np.ndarray, root, frame, omega, length) -> tuple[float, float]:
    """Mean and max vertex distance to the centerline, as ``fit_groom`` reports them."""
    mean, worst = np.zeros(1), np.zeros(1)
    fitting.closest_distances(p, np.array([0, len(p)], np.int64), root[None], frame[None],
                              np.array([0, len(omega)], np.int64), omega, length, mean, worst)
    return float(mean[0]), float(worst[0])


def _rotate(F: np.ndarray, a: float, b: float) -> np.ndarray:
    """Rotate the rows of ``F`` by the rotation vector ``a n1 + b n2`` (the fitter's root-tangent angles)."""
    th = a * F[1] + b * F[2]
    angle = float(np.sqrt(th @ th))
    if angle == 0.0:
        return F.copy()
    k = th / angle
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    R = np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * (K @ K)
    return F @ R.T


def initial_guess(p: np.ndarray, up: np.ndarray, s: np.ndarray, length: np.ndarray, tolerance: float):
    """The fitter's initial guess for given element lengths: ``_initial_frame``, then ``_sequential_init``.

    Uses the fitter's ``_start`` when it exists with the expected arguments.
    Otherwise mirrors the start of ``fit_adaptive``: when ``_sequential_init`` takes a
    ``look_ahead``, two starts are computed (without and with ``_LOOK_AHEAD``)
    and the one with the smaller largest vertex distance is kept; ``eta`` and
    ``cap`` are computed as ``fit_adaptive`` computes them.
    """
    import inspect

    root = p[0].copy()
    names = list(inspect.signature(fitting._sequential_init.py_func).parameters)[6:]
    values = {}
    if "eta" in names:
        values["eta"] = fitting._PRIOR_OF_TOLERANCE * tolerance
    if "cap" in names:
        values["cap"] = fitting._CAP_FACTOR * fitting._max_discrete_curvature(p)
    start = getattr(fitting, "_start", None)
    if start is not None and list(inspect.signature(start.py_func).parameters) == [
            "root", "F0", "p", "s", "up", "length", "omega", "eta", "bend_cap", "err"]:
        # the fitter's own two-start initialisation (_initial_frame, then _sequential_init twice)
        F0 = np.zeros((3, 3))
        omega = np.zeros((len(length), 3))
        start(root, F0, p, s, up, length, omega, values["eta"], values["cap"], np.zeros(len(p)))
        return F0, omega
    looks = [0.0, float(fitting._LOOK_AHEAD)] if "look_ahead" in names else [None]
    unknown = [n for n in names if n not in ("look_ahead", "eta", "cap")]
    if unknown:
        raise RuntimeError(f"bench/fit_bench.py does not know _sequential_init's arguments {unknown}; update initial_guess")
    best = None
    for look in looks:
        F0 = np.zeros((3, 3))
        omega = np.zeros((len(length), 3))
        fitting._initial_frame(p, up, F0)
        args = [look if n == "look_ahead" else values[n] for n in names]
        fitting._sequential_init(root, F0, p, s, length, omega, *args)
        worst = fitting._vertex_errors(root, F0, omega, length, s.copy(), p, np.zeros(len(p))) if len(looks) > 1 else 0.0
        if best is None or worst < best[0]:
            best = (worst, F0, omega)
    return best[1], best[2]


def peer_fit(p: np.ndarray, up: np.ndarray, length: np.ndarray, tolerance: float):
    """Fit one strand with ``least_squares`` (trf, 2-point Jacobian, default tolerances).

    Parameters: the root tangent's two angles and all omegas; the element
    lengths are fixed to ``length``. Residuals: the centerline at each
    vertex's arc length (its chord-length fraction times the strand length)
    minus the vertex. Starts from the fitter's own initialisation
    (``_initial_frame`` then ``_sequential_init``) for these element lengths.
    """
    m = len(p)
    n = len(length)
    total = float(length.sum())
    chord = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
    s = np.ascontiguousarray(chord / chord[-1] * total)
    root = p[0].copy()
    F0, omega0 = initial_guess(p, up, s, length, tolerance)
    out = np.empty((m, 3))
    target = p[1:]

    cache = {}  # the frame for the last angles: the omega columns of the Jacobian reuse it

    def residuals(x):
        key = (float(x[0]), float(x[1]))
        F = cache.get(key)
        if F is None:
            cache.clear()
            F = cache[key] = _rotate(F0, x[0], x[1])
        points_at(root, F, np.ascontiguousarray(x[2:].reshape(n, 3)), length, s, out)
        return (out[1:] - target).ravel()

    x0 = np.concatenate([[0.0, 0.0], omega0.ravel()])
    sol = least_squares(residuals, x0, method="trf", jac="2-point")
    return root, _rotate(F0, sol.x[0], sol.x[1]), np.ascontiguousarray(sol.x[2:].reshape(n, 3)), sol.nfev


def element_range(fs: FitSettings) -> str:
    """The element counts the settings allow, in words."""
    if fs.max_elements > 0:
        return f"{fs.min_elements} to {fs.max_elements} elements"
    return f"at least {fs.min_elements} elements and at most what the vertices determine ((2M-5)/3 for M vertices)"


def ours_fit(p: np.ndarray, up: np.ndarray, settings: FitSettings):
    """One strand through the fitter's batch kernel (single-threaded, no Python work around it)."""
    n_max = settings.elements if settings.elements > 0 else fitting.element_cap(p, settings.max_elements)
    out_n, out_status = np.zeros(1, np.int64), np.zeros(1, np.int64)
    out_frame, out_omega = np.zeros((1, 3, 3)), np.zeros((1, n_max, 3))
    out_length, out_worst = np.zeros((1, n_max)), np.zeros(1)
    fitting.fit_batch(p, np.array([0, len(p)], np.int64), up, float(settings.tolerance), int(settings.elements),
                      int(settings.min_elements), int(n_max), int(settings.max_iterations),
                      out_n, out_frame, out_omega, out_length, out_worst, out_status)
    n = int(out_n[0])
    return p[0].copy(), out_frame[0], np.ascontiguousarray(out_omega[0, :n]), np.ascontiguousarray(out_length[0, :n])


def _per_strand_median(fn, strands, repeats):
    """Per strand: the median of ``repeats`` timed calls. Returns the times (s) and the last results."""
    times, results = [], []
    for p in strands:
        t = []
        for _ in range(repeats):
            start = time.perf_counter()
            res = fn(p)
            t.append(time.perf_counter() - start)
        times.append(float(np.median(t)))
        results.append(res)
    return np.array(times), results


def peer_comparison(groom: Groom, settings: FitSettings) -> dict:
    """Ours against ``least_squares`` on the same fixed random 100 strands, one thread each.

    Ours is the batch kernel called on one strand at a time from this thread
    (no worker threads); ``least_squares`` runs in the same thread. The
    peer's element count and lengths are the ones our fit found, which
    spares it the search for the element count. Each strand is timed
    ``PEER_REPEATS`` times; a strand's time is the median.
    """
    rng = np.random.default_rng(SEED + 1)
    idx = np.sort(rng.choice(groom.n_strands, PEER_STRANDS, replace=False))
    strands = [np.ascontiguousarray(groom.points[groom.offsets[i]:groom.offsets[i + 1]]) for i in idx]
    up = np.ascontiguousarray(groom.up, dtype=np.float64)
    # warm-up: compile, or load from the cache, every kernel called from here
    warm = ours_fit(strands[0], up, settings)
    peer_fit(strands[0], up, warm[3], settings.tolerance)
    wait_quiet()
    ours_t, ours_res = _per_strand_median(lambda p: ours_fit(p, up, settings), strands, PEER_REPEATS)
    lengths = [r[3] for r in ours_res]
    wait_quiet()
    peer_t, peer_res = [], []
    for p, ln in zip(strands, lengths):
        t, res = _per_strand_median(lambda q: peer_fit(q, up, ln, settings.tolerance), [p], PEER_REPEATS)
        peer_t.append(t[0])
        peer_res.append(res[0])
    peer_t = np.array(peer_t)
    ours_err = np.array([_errors(p, *r) for p, r in zip(strands, ours_res)])
    peer_err = np.array([_errors(p, *r[:3], ln) for p, r, ln in zip(strands, peer_res, lengths)])
    elements = np.array([len(ln) for ln in lengths])
    return {
        "ours_ms": 1e3 * float(np.median(ours_t)),
        "peer_ms": 1e3 * float(np.median(peer_t)),
        "ours_total": float(ours_t.sum()),
        "peer_total": float(peer_t.sum()),
        "ratio": float(np.median(peer_t) / np.median(ours_t)),
        "ratio_total": float(peer_t.sum() / ours_t.sum()),
        "ours_mean_mm": 1e3 * float(ours_err[:, 0].mean()),
        "ours_max_mm": 1e3 * float(ours_err[:, 1].max()),
        "peer_mean_mm": 1e3 * float(peer_err[:, 0].mean()),
        "peer_max_mm": 1e3 * float(peer_err[:, 1].max()),
        "peer_missed": int((peer_err[:, 1] > settings.tolerance * (1 + 1e-9)).sum()),
        "ours_missed": int((ours_err[:, 1] > settings.tolerance * (1 + 1e-9)).sum()),
        "peer_better": int((peer_err[:, 0] < ours_err[:, 0]).sum()),
        "nfev": np.array([r[3] for r in peer_res]),
        "elements": elements,
    }


# ---------------------------------------------------------------------------
# tolerance sweep


def tolerance_sweep(groom: Groom, default: dict) -> list[dict]:
    """The 2,000 strands at each tolerance of ``SWEEP_MM``; the default tolerance reuses ``default``."""
    rows = []
    for mm in SWEEP_MM:
        if abs(mm * 1e-3 - FitSettings().tolerance) < 1e-12:
            r = dict(default)
        else:
            log(f"  tolerance {mm} mm")
            r = fit_summary(groom, FitSettings(tolerance=mm * 1e-3), SWEEP_REPEATS)
        r["tolerance_mm"] = mm
        rows.append(r)
    return rows


def plot_sweep(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tol = np.array([r["tolerance_mm"] for r in rows])
    secs = np.array([r["seconds"] for r in rows])
    mean = np.array([r["mean_mm"] for r in rows])
    worst = np.array([r["max_mm"] for r in rows])
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4.2), constrained_layout=True)
    cpu = np.array([r["cpu"] for r in rows])
    a.loglog(tol, secs, "o-", color="C0", label="wall time, median")
    a.loglog(tol, cpu, "^--", color="C4", label="CPU time of the process (both threads), median")
    busy = np.array([float(np.median(r["background"])) > BUSY for r in rows])
    if busy.any():
        a.plot(tol[busy], secs[busy], "o", ms=13, mfc="none", mec="C3",
               label=f"other processes used > {100 * BUSY:g} % of the CPU")
    a.axhline(TARGET_SECONDS, color="C3", ls="--", lw=1, label=f"target {TARGET_SECONDS:g} s")
    a.axvline(FitSettings().tolerance * 1e3, color="0.5", ls=":", lw=1, label="default tolerance")
    a.set_xlabel("tolerance (largest vertex distance target), mm")
    a.set_ylabel(f"time to fit {STRANDS:,} strands with 2 threads, s")
    a.set_title("Time against tolerance")
    a.grid(True, which="both", alpha=0.3)
    a.legend(fontsize=8)
    b.loglog(tol, mean, "o-", color="C1", label="mean error (mean of strand means)")
    b.loglog(tol, worst, "s-", color="C2", label="max error (largest vertex distance)")
    b.loglog(tol, tol, color="k", ls=(0, (2, 3)), lw=1.5, zorder=5, label="error = tolerance")
    b.axhline(TARGET_MEAN_MM, color="C3", ls="--", lw=1, label=f"target mean {TARGET_MEAN_MM:g} mm")
    b.axvline(FitSettings().tolerance * 1e3, color="0.5", ls=":", lw=1)
    b.set_xlabel("tolerance (largest vertex distance target), mm")
    b.set_ylabel("fit error, mm")
    b.set_title("Fit error against tolerance")
    b.grid(True, which="both", alpha=0.3)
    b.legend(fontsize=8)
    fig.suptitle(f"{STRANDS:,} real strands of {POINTS} points, 10-50 cm long; medians of repeated runs", fontsize=11)
    from matplotlib.ticker import FixedLocator, NullLocator, FuncFormatter

    for ax in (a, b):
        ax.xaxis.set_major_locator(FixedLocator(list(tol)))
        ax.xaxis.set_minor_locator(NullLocator())
        ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        ax.yaxis.set_minor_formatter(FuncFormatter(lambda v, _, left=ax is a: f"{v:g}" if left else ""))
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ---------------------------------------------------------------------------
# secondary grooms


def secondary_grooms() -> list[tuple[str, Groom]]:
    out = []
    groom, _ = load_groom(SINTEL[0], ImportSettings(scale=SINTEL[1]))
    out.append((f"Sintel `{SINTEL[0].name}` as is (scale {SINTEL[1]} m/unit)", groom))
    for path in SAMPLES:
        groom, _ = load_groom(path, ImportSettings())
        out.append((f"sample `samples/{path.name}`", groom))
    return out


# ---------------------------------------------------------------------------
# the section


def _f(x: float, digits: int = 3) -> str:
    return f"{x:.{digits}f}"


def _pass(ok: bool) -> str:
    return "**PASS**" if ok else "**FAIL**"


def run() -> str:
    """Run every measurement and return the markdown section."""
    settings = FitSettings()
    log("fit: building the strand set")
    groom, info = build_strands()
    log("fit: compile time (fresh interpreter, empty numba cache)")
    comp = measure_compile(groom)
    log("fit: warm-up")
    fit_groom(subset(groom, np.arange(10)), settings)
    fit_groom(groom, settings)
    log("fit: 2,000 strands, default threads")
    main = fit_summary(groom, settings, REPEATS)
    log("fit: 2,000 strands, 1 thread")
    old = os.environ.get("HAIRINV_THREADS")
    os.environ["HAIRINV_THREADS"] = "1"
    try:
        single = fit_summary(groom, settings, smoke(3, 1))
    finally:
        if old is None:
            os.environ.pop("HAIRINV_THREADS", None)
        else:
            os.environ["HAIRINV_THREADS"] = old
    log("fit: peer (scipy least_squares) on 100 strands")
    peer = peer_comparison(groom, settings)
    log("fit: tolerance sweep")
    sweep = tolerance_sweep(groom, main)
    plot_sweep(sweep, PLOT)
    log("fit: secondary grooms")
    others = []
    for label, g in secondary_grooms():
        log(f"  {label}")
        counts = np.diff(g.offsets)
        lengths = _polyline_lengths(g.points, g.offsets)
        try:
            fit_groom(subset(g, np.arange(min(4, g.n_strands))), settings)
            r = fit_summary(g, settings, REPEATS, slow=((2.0, 3), (10.0, 1)))
        except Exception as exc:  # a failing groom is reported in its row, the other rows still run
            r = {"error": f"{type(exc).__name__}: {exc}"}
        others.append((label, g.n_strands, counts, lengths, r))
    return render(groom, info, comp, main, single, peer, sweep, others)


def _share(values) -> str:
    return f"{100 * float(np.median(values)):.0f} %"


def _range(a: np.ndarray) -> str:
    return f"{int(a.min())}" if a.min() == a.max() else f"{int(a.min())}-{int(a.max())}"


def render(groom, info, comp, main, single, peer, sweep, others) -> str:
    fs = FitSettings()
    tol_mm = fs.tolerance * 1e3
    lengths = info["lengths"]
    src = info["sources"]
    ok_time = main["seconds"] < TARGET_SECONDS
    ok_err = main["mean_mm"] < TARGET_MEAN_MM
    e = main["elements"]
    out = [f"## {TITLE}", ""]
    out.append(
        f"`hairinv.fit.fit_groom` with the default `FitSettings`: tolerance {tol_mm:g} mm on the largest "
        f"vertex distance, {element_range(fs)} per strand, "
        f"{fs.max_iterations} Levenberg-Marquardt iterations per element count. "
        "Times are wall clock and are medians of repeated runs in one process, after a warm-up run, with the "
        "numba kernels already compiled (the compile time is measured separately below). Before each timed run "
        "the benchmark waits up to 5 s for other processes to go idle, and it records the share of the "
        "machine's CPU that other processes used during the run. "
        "A strand's fit error is the distance from each input vertex to the nearest point of the fitted "
        "centerline. \"Mean error\" is the mean over strands of each strand's mean vertex distance "
        "(`helices.fit_error[:, 0]`). \"Max error\" is the largest vertex distance over all strands. "
        "\"Strands missing the tolerance\" is the fitter's own count (`FitReport.tolerance_missed`) of strands "
        "whose largest vertex distance, as the fitter measures it, is still above the tolerance when it stops; "
        "\"strands over the tolerance\" counts the strands whose `fit_error` maximum is above it. "
        f"\"Fitted length > polyline + {100 * LONG_FIT:g} %\" counts strands whose fitted centerline is more than "
        f"{100 * LONG_FIT:g} % longer than the input polyline. A smooth curve through the vertices is only slightly "
        "longer than the polyline (at most about 1 % for these point spacings), so a larger excess means the fitted curve "
        "makes detours between vertices, which the vertex distances do not show."
    )
    out += ["", "### Strand set", ""]
    parts = " and ".join(
        f"{v['chosen']:,} from {k} ({v['in_range']:,} of that file's {v['strands']:,} strands are in range)"
        for k, v in src.items()
    )
    out.append(
        f"{STRANDS:,} real strands of {POINTS} points, {LENGTH_RANGE[0] * 100:g}-{LENGTH_RANGE[1] * 100:g} cm long. "
        "The source files have 16 points per strand: `ruby/ruby_long_hair_16_guide.tfx` at 0.002 m per unit and "
        "`ponytail/hair_free_16_guide.tfx` at 0.0025 m per unit (the scales given in the data README). "
        f"Strands whose 16-point polyline is {LENGTH_RANGE[0] * 100:g}-{LENGTH_RANGE[1] * 100:g} cm long are pooled, and "
        f"{STRANDS:,} are drawn at random (numpy `default_rng({SEED})`): {parts}. "
        "Each strand is resampled to 32 points, evenly spaced by arc length, along a cubic spline through its 16 "
        "points (`scipy.interpolate.CubicSpline`, not-a-knot ends, parameterised by chord length; the spline's "
        f"arc length is measured on {SPLINE_SAMPLES:,} samples). "
        f"Resampled lengths are {lengths.min() * 100:.1f} cm (min), {np.median(lengths) * 100:.1f} cm (median) "
        f"and {lengths.max() * 100:.1f} cm (max). "
        "Nearly all strands come from one hairstyle, so the set does not cover curly hair; the sample grooms "
        "below include a synthetic curly one."
    )
    out += ["", "### Result against the target", ""]
    out.append(
        f"Target: {STRANDS:,} strands of {POINTS} points, {LENGTH_RANGE[0] * 100:g}-{LENGTH_RANGE[1] * 100:g} cm long, "
        f"fitted in under {TARGET_SECONDS:g} s on this 2-core machine, with a mean error under "
        f"{TARGET_MEAN_MM:g} mm at the default tolerance."
    )
    out.append("")
    out.append(table(
        ["", "value", "target", ""],
        [
            (f"Time for {STRANDS:,} strands, 2 threads (median of {main['runs']})", f"{main['seconds']:.2f} s",
             f"< {TARGET_SECONDS:g} s", _pass(ok_time)),
            ("Mean error", f"{main['mean_mm']:.4f} mm", f"< {TARGET_MEAN_MM:g} mm", _pass(ok_err)),
            ("Time per strand", f"{main['ms_per_strand']:.2f} ms", "", ""),
            ("Max error", f"{main['max_mm']:.4f} mm", "", ""),
            ("Strands missing the tolerance / over the tolerance", f"{main['missed']} / {main['over_tol']}", "", ""),
            (f"Fitted length > polyline + {100 * LONG_FIT:g} %", f"{main['too_long']}", "", ""),
            ("Fitted length / polyline length, min / median / max",
             " / ".join(f"{v:.3f}" for v in np.percentile(main["length_ratio"], [0, 50, 100])), "", ""),
            ("Elements per strand, min / median / max", _elements(e), "", ""),
            ("Every run, s", ", ".join(f"{t:.2f}" for t in main["times"]), "", ""),
            ("CPU time of the process per run (both threads), median", f"{main['cpu']:.2f} s", "", ""),
            ("CPU share used by other processes during the runs, median", _share(main["background"]), "", ""),
            (f"Same strands, 1 thread (`HAIRINV_THREADS=1`), median of {single['runs']}", f"{single['seconds']:.2f} s", "", ""),
            ("CPU share used by other processes during the 1-thread runs, median", _share(single["background"]), "", ""),
        ],
        ["l", "r", "r", "l"],
    ))
    out.append("")
    out.append(
        f"Two threads ran {single['seconds'] / main['seconds']:.2f} times as fast as one. "
        + ("Other processes used part of the machine during these runs (see the CPU-share rows). "
           if max(np.median(main["background"]), np.median(single["background"])) > BUSY else
           "The machine was nearly idle during these runs (see the CPU-share rows). ")
        + "Load on either core slows the 2-thread wall time, so the CPU time of the process, which load affects "
        "much less, is given too: on an idle machine the 2-thread wall time is about half of it when both "
        "threads stay busy. "
        "The paper's figure (up to 95 s for about 2,000 curves) comes from other hardware and other data and "
        "is not compared here."
    )
    out += ["", "### Compile time (numba)", ""]
    out.append(
        "Measured once, in a fresh Python process with an empty temporary `NUMBA_CACHE_DIR`, by fitting 10 of the "
        "strands twice: compile time = first call minus second call. The compiled kernels are then cached on "
        "disk, so later processes do not pay this again (until the fitter's source changes)."
    )
    out.append("")
    out.append(table(
        ["", "seconds"],
        [
            ("Compile (first fit minus second fit)", _f(comp["compile"], 1)),
            ("Import of numpy, numba and hairinv", _f(comp["import"], 2)),
            ("Second fit of the 10 strands (compiled)", _f(comp["second"], 3)),
            ("Whole subprocess, wall", _f(comp["wall"], 1)),
        ],
    ))
    out += ["", "### Against scipy.optimize.least_squares", ""]
    out.append(
        "The peer is a plain `scipy.optimize.least_squares` fit of the same model (`method=\"trf\"`, "
        f"`jac=\"2-point\"`, default tolerances) on a fixed random subset of {PEER_STRANDS} of the "
        f"{STRANDS:,} strands (`default_rng({SEED + 1})`). "
        "Its parameters are the root tangent's two angles and the curvatures and twist of every element. "
        "Its element count and element lengths are fixed to the ones our fit found for that strand, so it does not "
        "have to search for the element count. Its residuals are the centerline at each vertex's arc length (the "
        "vertex's chord-length fraction times the strand length), evaluated with `hairinv.rod.helix.points_at`, "
        "minus the vertex. It starts from the fitter's own initial guess for those element lengths "
        "(`_initial_frame` and `_sequential_init`, called as `fit_adaptive` calls them), and its time includes "
        "computing that guess. "
        "Ours is `hairinv.rod.fitting.fit_batch` called on one strand at a time. Its time includes its own "
        "initial guess, the search for the element count and both fit phases. "
        "Both run single-threaded, one strand at a time, in the same thread of the same process. "
        f"Each strand is timed {PEER_REPEATS} times and its median is kept; the table gives the median over "
        "strands and the sum over strands. "
        "Both fits' errors are computed the same way (`hairinv.rod.fitting.closest_distances`)."
    )
    out.append("")
    out.append(table(
        ["", "time per strand, median", f"total, {PEER_STRANDS} strands", "mean error", "max error",
         f"strands over {tol_mm:g} mm"],
        [
            ("hairinv (`fit_batch`, 1 thread)", f"{peer['ours_ms']:.2f} ms", f"{peer['ours_total']:.3f} s",
             f"{peer['ours_mean_mm']:.4f} mm", f"{peer['ours_max_mm']:.4f} mm", peer["ours_missed"]),
            ("scipy `least_squares` (trf, 2-point)", f"{peer['peer_ms']:.2f} ms", f"{peer['peer_total']:.1f} s",
             f"{peer['peer_mean_mm']:.4f} mm", f"{peer['peer_max_mm']:.4f} mm", peer["peer_missed"]),
        ],
    ))
    out.append("")
    out.append(
        f"**Ratio least_squares / hairinv: {peer['ratio']:.0f}x on the median time per strand, "
        f"{peer['ratio_total']:.0f}x on the total.** "
        f"Elements per strand in this subset: median {np.median(peer['elements']):g}, max {peer['elements'].max()}. "
        f"`least_squares` used a median of {np.median(peer['nfev']):.0f} residual evaluations per strand, not "
        "counting those of its finite-difference Jacobian. "
        f"Its mean error is lower than ours on {peer['peer_better']} of the {PEER_STRANDS} strands. It minimises "
        "the sum of squared residuals until it converges, while ours stops once every vertex is within the "
        "tolerance."
    )
    out += ["", "### Speed against accuracy", ""]
    runs = sorted({r["runs"] for r in sweep})
    out.append(
        f"The same {STRANDS:,} strands at five tolerances, with the other settings at their defaults and 2 threads. "
        f"Each row is the median of {SWEEP_REPEATS} runs; the {tol_mm:g} mm row is the {main['runs']}-run "
        "measurement above. Where other processes used part of the machine (last column), the wall time is "
        "inflated; the CPU time of the process is the better figure for comparing rows."
        if runs != [SWEEP_REPEATS] else
        f"The same {STRANDS:,} strands at five tolerances, other settings at their defaults, 2 threads, "
        f"median of {SWEEP_REPEATS} runs each."
    )
    out.append("")
    out.append(table(
        ["tolerance", "time", "ms per strand", "CPU time of the process", "elements per strand, median (max)", "mean error",
         "max error", "strands missing / over the tolerance", "CPU share of other processes"],
        [
            (f"{r['tolerance_mm']:g} mm", f"{r['seconds']:.2f} s", f"{r['ms_per_strand']:.2f}", f"{r['cpu']:.2f} s",
             f"{np.median(r['elements']):g} ({int(r['elements'].max())})", f"{r['mean_mm']:.4f} mm",
             f"{r['max_mm']:.4f} mm", f"{r['missed']} / {r['over_tol']}", _share(r["background"]))
            for r in sweep
        ],
    ))
    out.append("")
    out.append(f"![Fit time and error against tolerance, log-log](img/{PLOT.name})")
    out += ["", "### Other grooms", ""]
    out.append(
        "Default settings, 2 threads. Each groom is timed 5 times, or 3 times if its first run takes over 2 s, "
        "or once if it takes over 10 s. "
        "The Sintel strands are fitted as they are in the file (already 32 evenly spaced points per strand). "
        "The samples are the synthetic grooms in `samples/`. \"Max error\" is the single worst vertex; the 95th "
        "percentile of the strands' largest vertex distances shows whether it is an outlier."
    )
    out.append("")
    rows = []
    for label, count, counts, ln, r in others:
        if "error" in r:
            rows.append((label, count, _range(counts), f"{ln.min() * 100:.1f}-{ln.max() * 100:.1f}",
                         f"fit_groom failed: `{r['error'][:200]}`") + ("",) * 7)
            continue
        rows.append((
            label, count, _range(counts), f"{ln.min() * 100:.1f}-{ln.max() * 100:.1f}",
            f"{r['seconds']:.3f} s ({r['runs']})", f"{r['ms_per_strand']:.2f}", _elements(r["elements"]),
            f"{r['mean_mm']:.4f} mm", f"{r['p95_max_mm']:.4f} mm", f"{r['max_mm']:.4f} mm",
            f"{r['missed']} / {r['over_tol']}", f"{r['too_long']} (max {r['length_ratio'].max():.2f}x)",
        ))
    out.append(table(
        ["groom", "strands", "points per strand", "length, cm", "time (runs)", "ms per strand",
         "elements min / median / max", "mean error", "strand max error, 95th pct.", "max error",
         "strands missing / over the tolerance", f"fitted length > polyline + {100 * LONG_FIT:g} %"],
        rows,
    ))
    out.append("")
    notes = []
    for label, count, counts, ln, r in others:
        if "error" in r or not (r["too_long"] or r["over_tol"] > r["missed"]):
            continue
        notes.append(
            f"On {label}, {r['too_long']} of {count} fitted centerlines are more than {100 * LONG_FIT:g} % longer "
            f"than their polyline (up to {r['length_ratio'].max():.2f} times as long), and `fit_error` puts "
            f"{r['over_tol']} strands over the tolerance where the fitter itself reports {r['missed']}."
        )
    if notes:
        out.append(" ".join(notes) + " A fitted centerline much longer than its polyline makes detours between "
                   "vertices, which the vertex distances alone do not show.")
        out.append("")
    return "\n".join(out)


if __name__ == "__main__":
    print(run())
