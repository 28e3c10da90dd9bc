"""Benchmark: multiplicative Schwarz over parts of the groom, against the interior point on the whole.

Run alone with ``python bench/schwarz_bench.py`` (prints the markdown section),
or through ``bench/run.py``, which writes ``docs/benchmarks.md``.

The inverse SOCQP of 1,000 guides of ruby short (default settings, built as
``invert`` builds it). The strands are cut into parts of P strands; a part's
contacts are those whose first strand lies in it. One Schwarz sweep solves
each part's contacts exactly (the interior point, on the rows of its contacts
and the coordinates they touch) with every other contact's force held, part
after part, each part seeing the forces the parts before it just found. Two
partitions: consecutive strands along a Morton curve of the roots, and parts
grown breadth first along the hair-hair contacts from a seed in that order (so
that a part holds strands that touch). Measured: the rest shape's distance from
the exact optimum after each sweep, against the time spent, beside the
interior point on the whole problem.
"""

from __future__ import annotations

import sys
import time
from collections import deque
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from common import DATA, ROOT, log, smoke, table  # type: ignore
    import invert_bench as ib  # type: ignore
else:
    from .common import DATA, ROOT, log, smoke, table
    from . import invert_bench as ib

sys.path.insert(0, str(ROOT))

from hairinv.solver import interior  # noqa: E402
from hairinv.solver.problem import CONE, ConeProblem, InteriorSettings  # noqa: E402
from hairinv.contacts.rows import contact_rows  # noqa: E402
from hairinv.solver.rows import ContactRows  # noqa: E402
from hairinv.testing import project_cone  # noqa: E402

TITLE = "Multiplicative Schwarz over parts of the groom"
GUIDES = smoke(1000, 40)
PARTS = smoke((100, 250, 500), (10, 20))  # strands per part
SWEEPS = smoke(4, 2)
PART_TOLERANCE = 0.01  # 1/m: each part's interior point stops once its own rest-shape bound is below this
REST = (0.5, 0.05)


def morton_order(root: np.ndarray) -> np.ndarray:
    """The strands in the order of a Morton curve through their roots (10 bits an axis)."""
    lo, hi = root.min(axis=0), root.max(axis=0)
    cells = np.floor((root - lo) / np.maximum(hi - lo, 1e-12) * 1023).astype(np.int64)
    key = np.zeros(len(root), dtype=np.int64)
    for bit in range(10):
        for axis in range(3):
            key |= ((cells[:, axis] >> bit) & 1) << (3 * bit + axis)
    return np.argsort(key, kind="stable")


def partition(strand: np.ndarray, n_strands: int, order: np.ndarray, size: int, grown: bool) -> np.ndarray:
    """Part of each strand: ``size`` consecutive strands of ``order``, or (``grown``) parts of ``size`` strands
    grown breadth first along the hair-hair contacts (``strand`` (C, 2), -1 for the body) from the first strand
    of ``order`` not yet taken (and from the next such one, while the part is not full)."""
    part = np.full(n_strands, -1, dtype=np.int64)
    if not grown:
        part[order] = np.arange(n_strands) // size
        return part
    pairs = strand[strand[:, 1] >= 0]
    neighbours = [[] for _ in range(n_strands)]
    for a, b in pairs:
        neighbours[a].append(b)
        neighbours[b].append(a)
    k, count = 0, 0
    for seed in order:
        if part[seed] >= 0:
            continue
        # a part takes the strands reached from its seed; a part not yet full goes on from the next seed
        part[seed], count, queue = k, count + 1, deque([seed])
        while queue and count < size:
            for t in neighbours[queue.popleft()]:
                if part[t] < 0 and count < size:
                    part[t], count = k, count + 1
                    queue.append(t)
        if count >= size:
            k, count = k + 1, 0
    return part


def sub_rows(rows: ContactRows, idx: np.ndarray) -> tuple[ContactRows, np.ndarray]:
    """The rows of contacts ``idx`` on the coordinates they touch, and those coordinates."""
    starts, ends = rows.ptr[idx], rows.ptr[idx + 1]
    sel = np.concatenate([np.arange(a, b) for a, b in zip(starts, ends)])
    used, local = np.unique(rows.cols[sel], return_inverse=True)
    ptr = np.concatenate([[0], np.cumsum(ends - starts)]).astype(np.int64)
    return ContactRows(ptr, local.astype(np.int64), np.ascontiguousarray(rows.vals[sel]), len(used)), used


def schwarz(p, rows: ContactRows, part_of_contact: np.ndarray, sweeps: int, distance) -> list[tuple[float, float]]:
    """(seconds, distance) after each sweep; the parts' rows are built within the first sweep's time."""
    c = p.contacts
    gamma = np.broadcast_to(np.asarray(p.gamma, dtype=np.float64), (c.n_contacts,))
    started = time.perf_counter()
    parts = []
    for k in range(int(part_of_contact.max()) + 1):
        idx = np.flatnonzero(part_of_contact == k)
        if len(idx):
            parts.append((idx, *sub_rows(rows, idx)))
    r = np.zeros((c.n_contacts, 3))
    f = np.zeros(rows.n_dofs)  # D H^T r
    out, spent = [], time.perf_counter() - started
    for _ in range(sweeps):
        began = time.perf_counter()
        for idx, sub, used in parts:
            d = p.d[used]
            own = d * sub.rmatvec(r[idx])
            b = p.b[idx] + sub.matvec(np.ascontiguousarray(f[used] - own))
            part = ConeProblem.of(sub, d, gamma[idx], b, c.mu[idx], c.strand[idx], p.helices.n_strands, 1.0)
            res = interior.solve(part, CONE, InteriorSettings(rest_tolerance=PART_TOLERANCE))
            new = project_cone(res.r, c.mu[idx])
            f[used] += d * sub.rmatvec(new - r[idx])
            r[idx] = new
        spent += time.perf_counter() - began
        out.append((spent, distance(r)))
    return out


def run() -> str:
    started = time.perf_counter()
    if not (DATA / "ruby" / "ruby_short_hair_16_guide.tfx").exists():
        return f"## {TITLE}\n\nruby short not found under {DATA}: not run.\n\n| |\n|---|\n"
    log(f"schwarz: ruby short, {GUIDES} guides")
    g = ib.prepare_groom(GUIDES, 1)
    p = ib.Problem.build(g["helices"], g["contacts"], g["material"], g["settings"].solver)
    h, c = p.helices, p.contacts
    rows = contact_rows(h, c)
    whole_problem = ConeProblem.of(rows, p.d, p.gamma, p.b, c.mu, c.strand, h.n_strands, 1.0)
    interior.solve(whole_problem, CONE, InteriorSettings(rest_tolerance=0.5))  # compiled and warm
    exact = interior.solve(whole_problem, CONE, InteriorSettings(rest_tolerance=1e-4))
    optimum = p.rest(project_cone(exact.r, c.mu))

    def distance(r: np.ndarray) -> float:
        return float(np.sqrt(np.mean(np.sum((p.rest(r) - optimum) ** 2, axis=1))))

    lines = []
    for tol in REST:
        res = interior.solve(whole_problem, CONE, InteriorSettings(rest_tolerance=tol))
        lines.append(["interior point, whole problem", f"rest_tolerance {tol:g}", "", "",
                      f"{res.iterations} steps", f"{res.seconds:.2f}", f"{distance(project_cone(res.r, c.mu)):.3g}"])
    whole, whole_distance = res.seconds, distance(project_cone(res.r, c.mu))
    order = morton_order(h.root)
    firsts, lasts = [], []
    for grown in (False, True):
        for size in PARTS:
            part = partition(c.strand, h.n_strands, order, size, grown)
            of_contact = part[c.strand[:, 0]]
            other = np.where(c.strand[:, 1] >= 0, part[np.maximum(c.strand[:, 1], 0)], of_contact)
            crossing = float(np.mean(other != of_contact))
            label = f"Schwarz, {'grown along contacts' if grown else 'Morton order'}"
            log(f"schwarz: {label}, parts of {size}")
            trace = schwarz(p, rows, of_contact, SWEEPS, distance)
            times = [t for t, _ in trace]
            firsts += list(np.diff([0.0] + times) / whole)  # each sweep's own time (the first builds the rows)
            lasts.append(trace[-1][1])
            for k, (seconds, dist) in enumerate(trace):
                lines.append([label if k == 0 else "", f"parts of {size} strands" if k == 0 else "",
                              f"{int(of_contact.max()) + 1}" if k == 0 else "",
                              f"{100 * crossing:.1f} %" if k == 0 else "", f"sweep {k + 1}", f"{seconds:.2f}",
                              f"{dist:.3g}"])
    text = [
        f"## {TITLE}",
        "",
        f"`bench/schwarz_bench.py`. The inverse SOCQP of {h.n_strands:,} guides of ruby short ({c.n_contacts:,} "
        f"contacts, {int(np.count_nonzero(c.strand[:, 1] >= 0)):,} hair-hair; default settings, as `invert` builds "
        "it). Multiplicative Schwarz: the strands are cut into parts, a part's contacts are those whose first "
        "strand lies in it, and a sweep solves each part's contacts exactly (the interior point on the rows of its "
        f"contacts and the coordinates they touch, to a rest-shape bound of {PART_TOLERANCE:g} 1/m) with every other "
        "force held, part after part. Parts are consecutive strands along a Morton curve through the roots, or "
        "grown breadth first along the hair-hair contacts from a seed in that order. Crossing: the hair-hair "
        "contacts whose two strands lie in different parts, as a share of all contacts. Distance: rms over "
        "elements of the rest shape's distance from the exact optimum (the interior point to 1e-4 1/m), 1/m. "
        "Times: the solver's own, one process; a Schwarz row's time is cumulative from the start, building the "
        "parts' rows included.",
        "",
        table(["method", "setting", "parts", "crossing", "steps / sweep", "time (s)", "distance, 1/m"], lines),
        "",
        f"A Schwarz sweep costs {min(firsts):.2f}-{max(firsts):.2f} times the interior point's solve of the whole "
        f"problem to 0.05 1/m ({whole:.2f} s, ending {whole_distance:.3g} 1/m from the optimum; the parts are solved "
        f"to {PART_TOLERANCE:g} 1/m each); after {SWEEPS} sweeps the nearest Schwarz run is {min(lasts):.3g} 1/m from "
        "the optimum."
        + (" A sweep, which solves every contact once in its part, costs about what the whole solve does, and "
           "the sweeps leave the rest shape farther from the optimum than the whole solve."
           if min(lasts) > whole_distance else ""),
        "",
        f"This section took {(time.perf_counter() - started) / 60:.1f} min.",
    ]
    return "\n".join(text)


if __name__ == "__main__":
    print(run())
