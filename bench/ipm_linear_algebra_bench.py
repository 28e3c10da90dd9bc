"""The linear algebra an interior-point solve of the inverse SOCQP would need: measurements.

Run alone with ``python bench/ipm_linear_algebra_bench.py`` (prints the
markdown section), or ``python bench/run.py ipm`` to write it into
``docs/benchmarks.md``. It takes about ten minutes.

An interior-point method on ``min 1/2 r'Wr + b'r`` over the Coulomb cones,
``W = G G' + gamma I`` with ``G = H K^-1``, solves per iteration a system
``(W + D) dr = rhs``, ``D`` block-diagonal (3x3 per contact: the cones' NT
scaling). By Woodbury it reduces to the rod-coordinate system

    S = I + G' (D + gamma I)^-1 G        (n x n, n = 3 x elements, SPD)

which is what this benchmark builds and factors, on 1,000 guides of ruby
short and on ruby short whole:

* the matrix: its size, non-zeros, the time to form it, and the non-zeros
  and flops of its Cholesky factor under each fill-reducing ordering
  (counted exactly from the ordering's elimination tree);
* CHOLMOD (scikit-sparse, optional) under each ordering, supernodal and
  simplicial, with the system's reference BLAS and with OpenBLAS: the first
  factorisation (ordering + symbolic + numeric) and the numeric-only
  refactorisation reusing the symbolic analysis (``cholesky_inplace``);
* PARDISO (pypardiso, Intel MKL, optional) as a peer;
* the strand structure: strands joined by hair-hair contacts form clusters
  (connected components), factored as dense blocks with numpy;
* the projected time of an interior-point solve of 20 and 40 iterations.

Each CHOLMOD or PARDISO configuration runs in a child process (so the BLAS
can be chosen with ``LD_LIBRARY_PATH`` and a runaway fill is cut off by a
timeout). OpenBLAS is looked for in the folder named by
``HAIRINV_BENCH_OPENBLAS`` (holding ``libblas.so.3`` and ``liblapack.so.3``),
else in Debian's ``/usr/lib/x86_64-linux-gnu/openblas-pthread``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp

HERE = Path(__file__).resolve().parent
if __package__ in (None, ""):
    sys.path.insert(0, str(HERE))
    sys.path.insert(0, str(HERE.parent))

from common import smoke  # noqa: E402

TITLE = "Linear algebra for an interior-point solver"
GUIDES = smoke((1000, 0), (20,))  # ruby short subsets (0: the whole groom)
SWEEPS = smoke(200, 10)  # Gauss-Seidel sweeps giving the forces the scaling is taken at
SHIFT = 1e-3  # interior shift of the primal and dual points, relative (see nt_scaling)
ORDERINGS = ("natural", "amd", "metis", "nesdis", "best")
MODES = ("supernodal", "simplicial")
REPEATS = smoke(3, 1)  # numeric refactorisations timed per configuration (median)
CHILD_TIMEOUT = 150.0  # s per configuration
# configurations whose factor needs more flops are not factored (their fill is counted only):
# about a minute at this machine's rates (reference BLAS ~3.5 GFlop/s, OpenBLAS ~15, simplicial ~1)
FLOP_CAPS = {"reference BLAS": 2e11, "OpenBLAS": 8e11, "simplicial": 2e10}
IPM_ITERS = (20, 40)
TARGETS = smoke({1000: 1.0, 0: 19.0}, {20: 1.0})  # s for a whole solve
DENSE_PROBE = smoke(4000, 400)  # size of the dense Cholesky timed to get numpy's flop rate
OPENBLAS_DEFAULT = Path("/usr/lib/x86_64-linux-gnu/openblas-pthread")


# ---------------------------------------------------------------------------
# the system


def nt_scaling(r: np.ndarray, u: np.ndarray, mu: np.ndarray, force_shift: float, velocity_shift: float) -> np.ndarray:
    """Per contact the 3x3 NT scaling ``D_i`` (force coordinates) at the primal point ``r_i`` and dual ``u_i``.

    In cone coordinates ``x = (mu r_N, r_T)`` (second-order cone) and
    ``z = (u_N / mu, u_T)`` (its dual, also second-order), both moved into the
    interior by ``shift * e``, ``e = (1, 0, 0)``. With the NT point ``w``
    (normalised, ``w'Jw = 1``), ``H = W_nt^2 = eta^2 (2 w w' - J)``, ``H x = z``
    (Vandenberghe, the CVXOPT cone solvers); in force coordinates ``D = T H T``,
    ``T = diag(mu, 1, 1)``. Returns (C, 3, 3).
    """
    from hairinv.testing import project_cone

    J = np.diag([1.0, -1.0, -1.0])
    x = r * np.stack([mu, np.ones_like(mu), np.ones_like(mu)], axis=1)
    z = u / np.stack([mu, np.ones_like(mu), np.ones_like(mu)], axis=1)
    # the dual point onto its cone first (the sweeps' u is not exactly feasible): here the second-order cone,
    # the Coulomb cone of mu = 1
    z = project_cone(z, 1.0)
    x[:, 0] += force_shift
    z[:, 0] += velocity_shift
    detx = x[:, 0] ** 2 - np.sum(x[:, 1:] ** 2, axis=1)
    detz = z[:, 0] ** 2 - np.sum(z[:, 1:] ** 2, axis=1)
    xb = x / np.sqrt(detx)[:, None]
    zb = z / np.sqrt(detz)[:, None]
    g = np.sqrt((1.0 + np.sum(xb * zb, axis=1)) / 2.0)
    wb = (zb + xb @ J) / (2.0 * g)[:, None]
    eta = (detz / detx) ** 0.25
    Hs = (eta ** 2)[:, None, None] * (2.0 * wb[:, :, None] * wb[:, None, :] - J)  # = W_nt^2
    T = np.stack([mu, np.ones_like(mu), np.ones_like(mu)], axis=1)
    return T[:, :, None] * Hs * T[:, None, :]


def block_inverse(D: np.ndarray, gamma) -> sp.bsr_matrix:
    """``(D + gamma I)^-1`` as a block-diagonal sparse matrix (``gamma`` one number or one per block)."""
    B = np.linalg.inv(D + np.asarray(gamma, dtype=np.float64)[..., None, None] * np.eye(3))
    B = 0.5 * (B + np.transpose(B, (0, 2, 1)))
    C = len(B)
    return sp.bsr_matrix((B, np.arange(C), np.arange(C + 1)), shape=(3 * C, 3 * C))


def form_system(G: sp.csr_matrix, Binv: sp.bsr_matrix) -> sp.csc_matrix:
    """``S = I + G' Binv G`` (scipy sparse products), CSC with sorted indices."""
    S = (G.T @ (Binv @ G)).tocsc() + sp.identity(G.shape[1], format="csc")
    S.sort_indices()
    return S


# ---------------------------------------------------------------------------
# exact fill of a Cholesky factor under a permutation (elimination tree, row subtrees)


def factor_counts(S: sp.csc_matrix, perm: np.ndarray) -> np.ndarray:
    """Column counts of the Cholesky factor of ``S[perm][:, perm]`` (diagonal included)."""
    from hairinv.solver.interior import column_counts

    P = S[perm][:, perm]
    U = sp.triu(P, format="csc")  # column k: rows i <= k
    U.sort_indices()
    return column_counts(U.shape[0], U.indptr.astype(np.int64), U.indices.astype(np.int64), np.inf)


# ---------------------------------------------------------------------------
# child processes: CHOLMOD and PARDISO


def _child_cholmod(arg: dict) -> dict:
    from sksparse.cholmod import analyze

    S = sp.load_npz(arg["matrix"]).tocsc()
    S.sort_indices()
    out = {}
    start = time.perf_counter()
    factor = analyze(S, mode=arg["mode"], ordering_method=arg["ordering"])
    out["analyze"] = time.perf_counter() - start
    out["perm"] = None
    if arg.get("save_perm"):
        np.save(arg["save_perm"], factor.P())
    times = []
    for _ in range(arg["repeats"] + 1):
        start = time.perf_counter()
        factor.cholesky_inplace(S)
        times.append(time.perf_counter() - start)
    out["first_numeric"] = times[0]
    out["numeric"] = float(np.median(times[1:]))
    rhs = np.random.default_rng(0).normal(size=S.shape[0])
    solves = []
    for _ in range(arg["repeats"]):
        start = time.perf_counter()
        x = factor(rhs)
        solves.append(time.perf_counter() - start)
    out["solve"] = float(np.median(solves))
    out["residual"] = float(np.linalg.norm(S @ x - rhs) / np.linalg.norm(rhs))
    return out


def _child_pardiso(arg: dict) -> dict:
    from pypardiso import PyPardisoSolver

    S = sp.load_npz(arg["matrix"]).tocsr()
    U = sp.triu(S, format="csr")
    U.sort_indices()
    solver = PyPardisoSolver(mtype=2)  # real symmetric positive definite, upper triangle
    rhs = np.random.default_rng(0).normal(size=(S.shape[0], 1))
    out = {}
    solver._check_A(U)
    start = time.perf_counter()
    solver.set_phase(11)
    solver._call_pardiso(U, rhs)
    out["analyze"] = time.perf_counter() - start
    times = []
    for _ in range(arg["repeats"] + 1):
        start = time.perf_counter()
        solver.set_phase(22)
        solver._call_pardiso(U, rhs)
        times.append(time.perf_counter() - start)
    out["first_numeric"] = times[0]
    out["numeric"] = float(np.median(times[1:]))
    solves = []
    for _ in range(arg["repeats"]):
        start = time.perf_counter()
        solver.set_phase(33)
        x = solver._call_pardiso(U, rhs)
        solves.append(time.perf_counter() - start)
    out["solve"] = float(np.median(solves))
    x = np.asarray(x).reshape(-1)
    out["residual"] = float(np.linalg.norm(S @ x - rhs[:, 0]) / np.linalg.norm(rhs))
    out["lnz"] = int(solver.iparm[17]) if hasattr(solver, "iparm") else None
    out["threads"] = int(solver.get_num_threads()) if hasattr(solver, "get_num_threads") else None
    return out


def _in_child(kind: str, arg: dict, blas: Path | None) -> dict:
    """Run ``_child_<kind>(arg)`` in a fresh interpreter (with ``blas`` first on the library path)."""
    env = dict(os.environ)
    if blas is not None:
        env["LD_LIBRARY_PATH"] = str(blas) + (":" + env["LD_LIBRARY_PATH"] if env.get("LD_LIBRARY_PATH") else "")
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", kind, json.dumps(arg)]
    try:
        done = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=CHILD_TIMEOUT)
    except subprocess.TimeoutExpired:
        return {"error": f"over {CHILD_TIMEOUT:.0f} s"}
    if done.returncode != 0:
        return {"error": (done.stderr.strip().splitlines() or ["failed"])[-1][:200]}
    return json.loads(done.stdout.strip().splitlines()[-1])


def _have(module: str) -> str | None:
    """None if ``module`` imports, else the reason it does not."""
    try:
        __import__(module)
        return None
    except Exception as exc:  # noqa: BLE001 - any failure means the column is skipped
        return f"{type(exc).__name__}: {exc}"


def openblas_dir() -> Path | None:
    folder = os.environ.get("HAIRINV_BENCH_OPENBLAS")
    for p in ([Path(folder)] if folder else []) + [OPENBLAS_DEFAULT]:
        if (p / "libblas.so.3").exists() and (p / "liblapack.so.3").exists():
            return p
    return None


def _package_mb(names) -> float:
    import importlib.metadata as md

    total = 0
    for name in names:
        try:
            total += sum((f.size or 0) for f in md.files(name) or [])
        except md.PackageNotFoundError:
            pass
    return total / 1e6


# ---------------------------------------------------------------------------
# the measurements


def build_case(guides: int, body=None) -> dict:
    import invert_bench as ib
    from common import log, median_time
    from hairinv.solver import gauss_seidel
    from hairinv.solver.gauss_seidel import split_strands
    from hairinv.solver.problem import CONE, ConeProblem, SweepSettings
    from hairinv.contacts.rows import contact_rows

    log(f"ipm: ruby short, {guides or 'all'} guides")
    g = ib.prepare_groom(guides, 1, body=body)
    prob = ib.Problem.build(g["helices"], g["contacts"], g["material"], g["settings"].solver)
    h, c = prob.helices, prob.contacts
    length = np.add.reduceat(h.length, h.offsets[:-1])
    weight = g["material"].linear_density * np.linalg.norm(g["material"].gravity) * float(length.max())
    rows = contact_rows(h, c)
    problem = ConeProblem.of(rows, prob.d, prob.gamma, prob.b, c.mu, c.strand, h.n_strands, weight, s=c.s,
                             part_of=split_strands(h.root, c.strand))
    res = gauss_seidel.solve(problem, CONE, SweepSettings(1e-12, SWEEPS, 5))
    r = res.r
    u = prob.W(r).reshape(-1, 3) + prob.b
    # shifts: SHIFT of a strand's weight on the forces, SHIFT of the median |u| on the velocities
    D = nt_scaling(r, u, c.mu, SHIFT * weight, SHIFT * float(np.median(np.linalg.norm(u, axis=1))))
    G = (prob.H @ sp.diags(1.0 / prob.K)).tocsr()
    timing = median_time(lambda: form_system(G, block_inverse(D, prob.gamma)), 3)
    S = timing.result
    pair = c.strand[:, 1] >= 0
    from scipy.sparse.csgraph import connected_components

    graph = sp.coo_matrix((np.ones(int(pair.sum())), (c.strand[pair, 0], c.strand[pair, 1])),
                          shape=(h.n_strands, h.n_strands))
    n_comp, label = connected_components(graph, directed=False)
    dofs = 3 * np.diff(h.offsets)
    cluster_dofs = np.bincount(label, weights=dofs).astype(np.int64)
    cluster_strands = np.bincount(label)
    eig = np.linalg.eigvalsh(D)
    return {"guides": guides, "strands": h.n_strands, "elements": h.n_elements, "contacts": c.n_contacts,
            "hair_hair": int(pair.sum()), "S": S, "n": S.shape[0], "nnz": int(S.nnz), "form": timing.median, "body": g["body"],
            "sweeps": res.sweeps, "relres": res.relative_residual, "H_nnz": int(prob.H.nnz),
            "cluster_strands": cluster_strands, "cluster_dofs": cluster_dofs, "n_clusters": n_comp,
            "label": label, "offsets": h.offsets, "D_eig": (float(eig.min()), float(eig.max())),
            "gamma": prob.gamma}


def fill_rows(case: dict, tmp: Path) -> dict:
    """Per ordering, CHOLMOD's permutation and the exact factor non-zeros and flops."""
    from common import log

    out = {}
    S = case["S"]
    for ordering in ORDERINGS:
        if ordering == "natural":
            perm = np.arange(S.shape[0])
            seconds = 0.0
        else:
            path = tmp / f"perm_{case['guides']}_{ordering}.npy"
            start = time.perf_counter()
            got = _in_child("cholmod_perm", {"matrix": str(tmp / f"S_{case['guides']}.npz"), "ordering": ordering,
                                             "save_perm": str(path)}, None)
            seconds = time.perf_counter() - start
            if "error" in got:
                out[ordering] = {"error": got["error"]}
                continue
            perm = np.load(path)
        counts = factor_counts(S, perm)
        out[ordering] = {"lnz": int(counts.sum()), "flops": float(np.sum(counts.astype(np.float64) ** 2)),
                         "seconds": seconds}
        log(f"  fill {ordering}: nnz(L) {counts.sum():,}, {out[ordering]['flops'] / 1e9:.1f} GFlop")
    return out


def _child_cholmod_perm(arg: dict) -> dict:
    from sksparse.cholmod import analyze

    S = sp.load_npz(arg["matrix"]).tocsc()
    S.sort_indices()
    factor = analyze(S, mode="simplicial", ordering_method=arg["ordering"])
    np.save(arg["save_perm"], factor.P())
    return {}


def factor_runs(case: dict, fill: dict, tmp: Path) -> list[dict]:
    from common import log

    runs = []
    matrix = str(tmp / f"S_{case['guides']}.npz")
    blas = openblas_dir()
    for mode in MODES:
        variants = [("reference BLAS", None)]
        if mode == "supernodal":
            variants.append(("OpenBLAS", blas) if blas is not None else ("OpenBLAS", "missing"))
        for ordering in ORDERINGS:
            f = fill.get(ordering, {})
            for name, lib in variants:
                cap = FLOP_CAPS["simplicial" if mode == "simplicial" else name]
                row = {"mode": mode, "ordering": ordering, "blas": name}
                if lib == "missing":
                    row["error"] = "no OpenBLAS found"
                elif "flops" not in f:
                    row["error"] = f.get("error", "no ordering")
                elif f["flops"] > cap:
                    row["error"] = f"not run: {f['flops'] / 1e9:,.0f} GFlop"
                else:
                    start = time.perf_counter()
                    row.update(_in_child("cholmod", {"matrix": matrix, "mode": mode, "ordering": ordering,
                                                     "repeats": REPEATS}, lib))
                    row["wall"] = time.perf_counter() - start
                runs.append(row)
                log(f"  cholmod {mode} {ordering} {name}: "
                    + (row["error"] if "error" in row else f"first {row['analyze'] + row['first_numeric']:.2f} s, "
                       f"numeric {row['numeric']:.2f} s"))
    return runs


def pardiso_run(case: dict, tmp: Path) -> dict:
    from common import log

    row = _in_child("pardiso", {"matrix": str(tmp / f"S_{case['guides']}.npz"), "repeats": REPEATS}, None)
    log(f"  pardiso: {row}")
    return row


def dense_rate() -> float:
    """numpy's dense Cholesky speed on this machine, flop/s (n^3/3 flops), from a DENSE_PROBE-sized matrix."""
    from common import median_time

    rng = np.random.default_rng(0)
    A = rng.normal(size=(DENSE_PROBE, DENSE_PROBE))
    A = A @ A.T + DENSE_PROBE * np.eye(DENSE_PROBE)
    t = median_time(lambda: np.linalg.cholesky(A), 3)
    return DENSE_PROBE ** 3 / 3.0 / t.median


def cluster_path(case: dict, rate: float) -> dict:
    """The strand structure: clusters of strands joined by hair-hair contacts, each factored densely.

    The clusters of one strand are stacked (padded with the identity to the
    largest) and factored in one batched ``np.linalg.cholesky``; larger
    clusters are factored as dense matrices if they hold at most 8,000
    coordinates, else their time is projected from numpy's measured rate.
    """
    from common import median_time

    S = case["S"].tocsr()
    label, offsets = case["label"], case["offsets"]
    sizes = case["cluster_strands"]
    single = np.flatnonzero(sizes[label] == 1)  # strands alone in their cluster
    out = {"single_strands": int(len(single))}
    if len(single):
        width = int(3 * np.max(np.diff(offsets)[single]))
        stack = np.tile(np.eye(width), (len(single), 1, 1))
        for k, s in enumerate(single):
            lo, hi = 3 * offsets[s], 3 * offsets[s + 1]
            stack[k, :hi - lo, :hi - lo] = S[lo:hi, lo:hi].toarray()
        out["single_seconds"] = median_time(lambda: np.linalg.cholesky(stack), 5).median
    big = [k for k in np.argsort(sizes)[::-1] if sizes[k] > 1]
    measured, projected = 0.0, 0.0
    for k in big:
        n = int(case["cluster_dofs"][k])
        if n <= 8000:
            strands = np.flatnonzero(label == k)
            idx = np.concatenate([np.arange(3 * offsets[s], 3 * offsets[s + 1]) for s in strands])
            A = S[idx][:, idx].toarray()
            measured += median_time(lambda: np.linalg.cholesky(A), 3).median
        else:
            projected += n ** 3 / 3.0 / rate
    out["multi_measured"] = measured
    out["multi_projected"] = projected
    out["largest_dofs"] = int(case["cluster_dofs"].max())
    return out


def run() -> str:
    from common import log

    started = time.perf_counter()
    load = os.getloadavg()
    missing = {"scikit-sparse": _have("sksparse.cholmod"), "pypardiso": _have("pypardiso")}
    cases, fills, runs, pard, clusters = [], [], [], [], []
    rate = dense_rate()
    log(f"ipm: numpy dense Cholesky at {rate / 1e9:.1f} GFlop/s")
    with tempfile.TemporaryDirectory() as name:
        tmp = Path(name)
        body = None
        for guides in GUIDES:
            case = build_case(guides, body)
            body = case["body"]
            sp.save_npz(tmp / f"S_{guides}.npz", case["S"], compressed=False)
            log(f"  S: n {case['S'].shape[0]:,}, nnz {case['S'].nnz:,}, formed in {case['form']:.2f} s")
            fill = fill_rows(case, tmp) if missing["scikit-sparse"] is None else {}
            runs.append(factor_runs(case, fill, tmp) if missing["scikit-sparse"] is None else [])
            pard.append(pardiso_run(case, tmp) if missing["pypardiso"] is None else None)
            clusters.append(cluster_path(case, rate))
            case.pop("S")
            case.pop("body")
            cases.append(case)
            fills.append(fill)
    return render(cases, fills, runs, pard, clusters, rate, missing, load, time.perf_counter() - started)


# ---------------------------------------------------------------------------
# the section


def _s(x: float) -> str:
    if x < 0.01:
        return f"{x * 1000:.2f} ms"
    return f"{x * 1000:.0f} ms" if x < 0.1 else f"{x:.2f} s" if x < 100 else f"{x:.0f} s"


def render(cases, fills, runs, pard, clusters, rate, missing, load, total) -> str:
    from common import table

    blas = openblas_dir()
    out = [f"## {TITLE}", ""]
    out.append(
        "`bench/ipm_linear_algebra_bench.py`. An interior-point method on the inverse SOCQP solves, per "
        "iteration, `(W + D) dr = rhs` with `W = G G' + gamma I`, `G = H K^-1`, and `D` block-diagonal "
        "(3x3 per contact, the cones' NT scaling). By Woodbury that reduces to the rod-coordinate system "
        "`S = I + G' (D + gamma I)^-1 G` (n = 3 x elements, SPD), which is what is built and factored here. "
        f"`D` is the NT scaling at the forces of {SWEEPS} Gauss-Seidel sweeps (`r`) and their velocities "
        f"(`u = W r + b`, projected onto the dual cone), both moved into the interior by {SHIFT:g} of a strand's "
        "weight and of the median `|u|`: a late interior-point iterate's spread of scalings (contacts at the cone's "
        "boundary get `(D + gamma I)^-1` near `1/gamma`, separated ones near zero). A Cholesky factorisation "
        "does not pivot, so its time depends on the pattern, not on these values. Load average at the start: "
        + " / ".join(f"{v:.2f}" for v in load) + " on 2 cores shared with other work, so the absolute times "
        "carry that noise; each time is the median of "
        f"{REPEATS} runs in one child process.")
    out.append("")
    for name, why in missing.items():
        if why is not None:
            out.append(f"- {name} is not installed here ({why}); its columns are skipped.")
    if blas is None:
        out.append("- No OpenBLAS found (`HAIRINV_BENCH_OPENBLAS`); the OpenBLAS rows are skipped.")
    if any(why is not None for why in missing.values()) or blas is None:
        out.append("")
    out.append("### The system")
    out.append("")
    rows = []
    for case, cl in zip(cases, clusters):
        sizes = np.sort(case["cluster_strands"])[::-1]
        rows.append([
            f"ruby short, {case['guides']:,} guides" if case["guides"] else "ruby short, whole",
            f"{case['strands']:,}", f"{case['contacts']:,} ({case['hair_hair']:,})",
            f"{case['n']:,}",
            f"{case['nnz']:,}", _s(case["form"]),
            f"{case['n_clusters']}: {sizes[0]:,} strands ({cl['largest_dofs']:,} coordinates) + "
            f"{int(np.sum(sizes == 1))} alone" + (f" + {len(sizes) - 1 - int(np.sum(sizes == 1))} more"
                                                   if len(sizes) - 1 - int(np.sum(sizes == 1)) > 0 else "")])
    out.append(table(["groom", "strands", "contacts (hair-hair)", "n", "nnz(S)", "forming S (scipy)",
                      "clusters (components of the hair-hair graph)"], rows))
    out.append("")
    out.append(
        "Forming `S` (the 3x3 inverses and two scipy sparse products) is needed at every iteration too. "
        "The hair-hair contacts join almost every strand into one cluster, so the strand structure leaves "
        "nothing independent to factor apart.")
    out.append("")
    if fills and fills[0]:
        out.append("### Fill of the Cholesky factor under each ordering")
        out.append("")
        out.append(
            "`nnz(L)` (diagonal included; in brackets against the non-zeros of `S`'s lower triangle) and the factor's flops (`sum_j c_j^2` over its column counts) are counted "
            "exactly from the elimination tree of `S` under the permutation CHOLMOD's analysis chose for that "
            "ordering; a supernodal factor stores a little more (explicit zeros in its supernodes).")
        out.append("")
        rows = []
        for ordering in ORDERINGS:
            row = [ordering]
            for case, fill in zip(cases, fills):
                f = fill.get(ordering, {})
                if "lnz" in f:
                    lower = (case["nnz"] + case["n"]) / 2
                    row += [f"{f['lnz'] / 1e6:,.1f} M ({f['lnz'] / lower:.1f} x)", f"{f['flops'] / 1e9:,.1f}"]
                else:
                    row += [f.get("error", ""), ""]
            rows.append(row)
        head = ["ordering"]
        for case in cases:
            name = f"{case['guides']:,} guides" if case["guides"] else "whole"
            head += [f"nnz(L), {name}", f"GFlop, {name}"]
        out.append(table(head, rows))
        out.append("")
    out.append("### Factorisation times")
    out.append("")
    out.append(
        "\"First\" is one factorisation from scratch (ordering, symbolic analysis and numeric factorisation, "
        "as `cholmod.analyze` + the first `cholesky_inplace`); \"numeric\" is a refactorisation reusing the "
        "symbolic analysis (`cholesky_inplace` on new values, what each interior-point iteration needs); "
        "\"solve\" is one forward and back substitution; \"residual\" is `|S x - rhs| / |rhs|` of that solve. "
        f"Configurations whose factor needs more than {FLOP_CAPS['reference BLAS'] / 1e9:g} GFlop (supernodal, "
        f"reference BLAS), {FLOP_CAPS['OpenBLAS'] / 1e9:g} GFlop (supernodal, OpenBLAS) or "
        f"{FLOP_CAPS['simplicial'] / 1e9:g} GFlop (simplicial) are not run (about a minute or more each); "
        f"a child over {CHILD_TIMEOUT:.0f} s is stopped. "
        "CHOLMOD is scikit-sparse 0.4.16 on Debian's SuiteSparse 5.12 (CHOLMOD 3, with METIS); \"reference BLAS\" "
        "is the system's `libblas.so.3` (netlib, what `libsuitesparse-dev` pulls in), OpenBLAS is "
        + (f"`{blas}`" if blas else "not available") + " (pthreads, 2 threads) put first on `LD_LIBRARY_PATH`. "
        "PARDISO is pypardiso (Intel MKL, its default nested-dissection ordering, 2 threads), matrix type 2 "
        "(SPD) on the upper triangle.")
    out.append("")
    rows = []
    labels = [f"{c['guides']:,} guides" if c["guides"] else "whole" for c in cases]
    keyed = {}
    for ci, rs in enumerate(runs):
        for r in rs:
            keyed.setdefault((r["mode"], r["ordering"], r["blas"]), [None] * len(cases))[ci] = r
    for (mode, ordering, blas_name), per in keyed.items():
        row = [f"CHOLMOD {mode}, {ordering}, {blas_name}"]
        for r in per:
            if r is None or "error" in r:
                row += [r["error"] if r else "", "", "", ""]
            else:
                row += [_s(r["analyze"] + r["first_numeric"]), _s(r["numeric"]), _s(r["solve"]), f"{r['residual']:.0e}"]
        rows.append(row)
    prow = ["PARDISO (MKL)"]
    for p in pard:
        if p is None:
            prow += ["not installed", "", "", ""]
        elif "error" in p:
            prow += [p["error"], "", "", ""]
        else:
            prow += [_s(p["analyze"] + p["first_numeric"]), _s(p["numeric"]), _s(p["solve"]), f"{p['residual']:.0e}"]
    rows.append(prow)
    crow = ["numpy, clusters as dense blocks"]
    for cl in clusters:
        t = cl.get("single_seconds", 0.0) + cl["multi_measured"] + cl["multi_projected"]
        crow += ["", (_s(t) + (" (projected)" if cl["multi_projected"] else "")), "", ""]
    rows.append(crow)
    head = ["solver"]
    for name in labels:
        head += [f"first, {name}", f"numeric, {name}", f"solve, {name}", f"residual, {name}"]
    out.append(table(head, rows))
    out.append("")
    largest = [c["largest_dofs"] for c in clusters]
    out.append(
        f"The numpy path factors the strands alone in their cluster ({', '.join(str(c['single_strands']) for c in clusters)} "
        f"strands) in one batched `np.linalg.cholesky` ({', '.join(_s(c.get('single_seconds', 0.0)) for c in clusters)}); "
        f"the rest is one dense matrix of {', '.join(f'{n:,}' for n in largest)} coordinates, "
        f"whose time is projected from numpy's dense Cholesky rate on this machine ({rate / 1e9:.1f} GFlop/s, "
        f"measured at n = {DENSE_PROBE:,}) as n^3/3 flops; it would also need "
        f"{', '.join(f'{8 * n ** 2 / 2 ** 30:.1f}' for n in largest)} GiB.")
    out.append("")
    out.append("### Projected interior-point solve")
    out.append("")
    out.append(
        "Per iteration: forming `S`, one numeric refactorisation and two solves (predictor and corrector), plus "
        "one first factorisation; the rest of an iteration (products with `G`, the cone algebra) is left out, so "
        "these are lower bounds. Targets: 1,000 guides in about 1 s, ruby short whole under 19 s.")
    out.append("")
    rows = []
    candidates = []
    for ci, case in enumerate(cases):
        best = {}
        for r in runs[ci] if runs else []:
            if "error" in r:
                continue
            key = f"CHOLMOD {r['mode']}, {r['ordering']}, {r['blas']}"
            best[key] = r
        if pard[ci] is not None and "error" not in pard[ci]:
            best["PARDISO (MKL)"] = pard[ci]
        ranked = sorted(best.items(), key=lambda kv: kv[1]["numeric"])
        chosen = ranked[:3]
        cholmod_ref = [kv for kv in ranked if "reference" in kv[0]]
        if cholmod_ref and cholmod_ref[0] not in chosen:
            chosen.append(cholmod_ref[0])
        for key, r in chosen:
            per = case["form"] + r["numeric"] + 2 * r["solve"]
            proj = [r["analyze"] + r["first_numeric"] + (k - 1) * per for k in IPM_ITERS]
            target = TARGETS[case["guides"]]
            rows.append([labels[ci], key, _s(per)] + [_s(p) for p in proj]
                        + [f"{target:g} s", "**PASS**" if proj[0] <= target else "**FAIL**"])
            candidates.append((labels[ci], key, proj))
    out.append(table(["groom", "linear algebra", "per iteration", f"{IPM_ITERS[0]} iterations",
                      f"{IPM_ITERS[1]} iterations", "target", f"at {IPM_ITERS[0]} iterations"], rows))
    out.append("")
    if pard and pard[0] is not None:
        out.append(f"pypardiso pulls in Intel MKL and its runtime: {_package_mb(['pypardiso', 'mkl', 'intel-openmp', 'tbb', 'tcmlib', 'umf', 'intel-cmplr-lib-ur']):,.0f} MB installed.")
        out.append("")
    out.append(f"This section took {total / 60:.1f} min.")
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    if len(sys.argv) > 2 and sys.argv[1] == "--child":
        kind, arg = sys.argv[2], json.loads(sys.argv[3])
        result = {"cholmod": _child_cholmod, "pardiso": _child_pardiso, "cholmod_perm": _child_cholmod_perm}[kind](arg)
        print(json.dumps(result))
    else:
        print(run())
