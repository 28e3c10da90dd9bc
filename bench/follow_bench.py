"""Benchmark: render strands following simulated guides (``hairinv export --follow``, hairinv.follow).

Run alone with ``python bench/follow_bench.py`` (prints the markdown section), or through ``bench/run.py``,
which writes ``docs/benchmarks.md``.

**Error.** Every strand of a small groom is inverted and simulated (``hairinv invert``, ``hairinv simulate``
as a user runs them); then a subset, the strands ``--guides N`` would pick (``hairinv.groom.select_guides``,
seed 0), is taken as the guides and the others as render strands: each render strand is carried by its guides
from its input polyline (``hairinv.follow.Following``, what the export does) and compared, vertex by vertex
and frame by frame, with where its own simulation put the same vertex (the fitted centerline at the vertex's
arc length, as ``--shape frame:N`` writes it). Reported: the median and 90th percentile of that distance over
every render vertex and frame after the first, beside how far the same vertices moved in their own simulation
relative to the body (from where their own root frame carries their first frame: a render strand that ignored
its guides and moved rigidly with its root would be off by exactly this). Methods: the guides chosen by root
distance or along the strand (``by``), the offsets turned by the guide's root frame or by its material frame
(``at_root``).

**Cost.** A synthetic groom of 50,000 render strands of 32 vertices around 500 guides of 12 elements:
``Follow.bind`` once, then ``Follow.points`` per frame (median of 5), the numba kernels of
``hairinv.rod.follow`` on this machine's threads.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from common import ROOT, WORK, log, median_time, smoke, table  # type: ignore
else:
    from .common import ROOT, WORK, log, median_time, smoke, table

TITLE = "Render strands following guides"
SAMPLES = ROOT / "samples"
# (label, groom: a sample file or "settled300", body, simulate's options, guide counts)
CASES = smoke(
    [("settled straight, 40 strands, `motion` scene (4 s)", "settled.h5", "body.obj", ["--scene", "motion"], (10, 20)),
     ("settled curly, 40 strands, `motion` scene (4 s)", "settled_curly.h5", "body.obj", ["--scene", "motion"],
      (10, 20)),
     ("settled straight, 40 strands, `turn.glb` shot (1.5 s)", "settled.h5", "turn.glb", [], (10, 20)),
     ("settled straight, 300 strands, `motion` scene (4 s)", "settled300", "body.obj", ["--scene", "motion"],
      (30, 75, 150))],
    [("settled straight, 40 strands, `motion` scene (0.2 s)", "settled.h5", "body.obj",
      ["--scene", "motion", "--seconds", "0.2", "--fps", "10"], (10,))])
# (by, at_root): the default first
METHODS = (("curve", True), ("curve", False), ("root", True))
RENDER = smoke(50_000, 2_000)
GUIDES = smoke(500, 50)
VERTICES = 32
ELEMENTS = 12


def hairinv(*args, cwd: Path) -> None:
    done = subprocess.run([sys.executable, "-m", "hairinv_cli.main", "--no-progress", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"hairinv {' '.join(map(str, args))} exited {done.returncode}: {done.stderr[-600:]}")


def settled300(path: Path) -> None:
    """Every strand of the straight sample settled on the bust as samples/make_settled.py settles 40."""
    sys.path.insert(0, str(SAMPLES))
    import make_settled  # type: ignore

    make_settled.settle("straight.h5", True, path, guides=0)


def simulation(groom: str, body: str, options: list[str], work: Path) -> Path:
    """The groom inverted on the bust and simulated, every strand (reused when current: ``--if-stale``)."""
    style = work / "settled300.h5" if groom == "settled300" else SAMPLES / groom
    if groom == "settled300" and not style.exists():
        log("follow: settling 300 strands")
        settled300(style)
    tag = f"{Path(groom).stem}.{Path(body).stem}"
    model, frames = work / f"{tag}.model.h5", work / f"{tag}.{'-'.join(options) or 'shot'}.frames.h5"
    log(f"follow: {tag}: invert, simulate {' '.join(options)}")
    hairinv("invert", style, SAMPLES / body, "-o", model, "--if-stale", cwd=work)
    hairinv("simulate", model, SAMPLES / body, *options, "-o", frames, "--if-stale", cwd=work)
    return frames


def leave_out(path: Path, count: int) -> list[dict]:
    """``count`` of the simulated strands as guides, the others following them (module docstring)."""
    from hairinv.export.source import ExportSource
    from hairinv.follow import Following
    from hairinv.groom import select_guides

    source = ExportSource(path)
    helices, frames = source.helices, source.frames
    guides = select_guides(helices.root, count, 0)
    render = np.setdiff1d(np.arange(helices.n_strands), guides)
    counts = np.diff(source.offsets)[render]
    rows = np.concatenate([np.arange(source.offsets[k], source.offsets[k + 1]) for k in render])
    offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    per = np.repeat(np.arange(len(render)), counts)
    own = [source.frame(k).points[rows] for k in range(source.n_frames)]
    moved = []
    for k in range(1, source.n_frames):  # from where each render strand's own root frame carries its first frame
        F0, Fk = np.asarray(frames["frame0"][0])[render], np.asarray(frames["frame0"][k])[render]
        R = np.einsum("nji,njk->nik", Fk, F0)
        c = np.asarray(frames["root"][k])[render] - np.einsum("nij,nj->ni", R, np.asarray(frames["root"][0])[render])
        moved.append(np.linalg.norm(own[k] - (np.einsum("nij,nj->ni", R[per], own[0]) + c[per]), axis=1))
    moved = np.concatenate(moved)
    out = []
    for by, at_root in METHODS:
        following = Following(source.points[rows], offsets, helices, frames, guides=guides, by=by, at_root=at_root)
        error = np.concatenate([np.linalg.norm(following.frame(k) - own[k], axis=1)
                                for k in range(1, source.n_frames)])
        out.append({"by": by, "at_root": at_root, "guides": len(guides), "render": len(render),
                    "error": (np.median(error), np.percentile(error, 90)),
                    "moved": (np.median(moved), np.percentile(moved, 90))})
    return out


def synthetic(rng, guides: int, render: int):
    """Guides of ``ELEMENTS`` curled elements rooted over a cap of a 9 cm sphere, and render strands of
    ``VERTICES`` vertices hanging from roots among them."""
    from hairinv.model import Helices

    def cap(n):
        z = rng.uniform(0.0, 1.0, n)
        a = rng.uniform(0.0, 2.0 * np.pi, n)
        return 0.09 * np.column_stack([np.sqrt(1 - z ** 2) * np.cos(a), z, np.sqrt(1 - z ** 2) * np.sin(a)])

    roots = cap(guides)
    t = roots / np.linalg.norm(roots, axis=1, keepdims=True)
    n1 = np.cross(t, rng.normal(size=(guides, 3)))
    n1 /= np.linalg.norm(n1, axis=1, keepdims=True)
    frame0 = np.stack([t, n1, np.cross(t, n1)], axis=1)
    offsets = np.arange(guides + 1, dtype=np.int64) * ELEMENTS
    length = np.full(guides * ELEMENTS, 0.3 / ELEMENTS)
    omega = rng.normal(0.0, 20.0, (guides * ELEMENTS, 3))
    helices = Helices(roots, frame0, offsets, length, omega, np.zeros((guides, 2)))
    r_roots = cap(render)
    s = np.linspace(0.0, rng.uniform(0.1, 0.3, (render, 1)), VERTICES, axis=1)[..., 0]
    points = (r_roots[:, None, :] + s[..., None] * np.array([0.0, -1.0, 0.0])
              + 0.005 * np.sin(40.0 * s)[..., None] * np.array([1.0, 0.0, 0.0])).reshape(-1, 3)
    return helices, points, np.arange(render + 1, dtype=np.int64) * VERTICES


def cost() -> dict:
    import numba

    from hairinv.follow import Follow

    rng = np.random.default_rng(55)
    helices, points, offsets = synthetic(rng, GUIDES, RENDER)
    Follow.bind(points[:VERTICES * 10], offsets[:11], helices)  # compile
    start = time.perf_counter()
    follow = Follow.bind(points, offsets, helices)
    bind = time.perf_counter() - start
    moved = helices.omega * 1.1
    follow.points(helices.root, helices.frame0, moved)  # compile
    frame = median_time(lambda: follow.points(helices.root, helices.frame0, moved), repeats=5)
    return {"bind": bind, "frame": frame.median, "cpu": float(np.median(frame.cpu)),
            "load": float(np.median(frame.background)), "threads": numba.get_num_threads(), "points": len(points),
            "memory": follow.local.nbytes + follow.u.nbytes + follow.guide.nbytes + follow.weight.nbytes}


def run() -> str:
    work = WORK / "follow"
    work.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    parts = []
    for label, groom, body, options, counts in CASES:
        frames = simulation(groom, body, options, work)
        rows = []
        for count in counts:
            log(f"follow: {label}, {count} guides")
            for r in leave_out(frames, count):
                rows.append([f"{r['guides']} of {r['guides'] + r['render']}",
                             f"{r['by']}, {'root' if r['at_root'] else 'material'} frame"
                             + (" (default)" if (r["by"], r["at_root"]) == METHODS[0] else ""),
                             f"{1e3 * r['error'][0]:.2f}", f"{1e3 * r['error'][1]:.1f}",
                             f"{1e3 * r['moved'][0]:.2f}", f"{1e3 * r['moved'][1]:.1f}",
                             f"{r['error'][0] / r['moved'][0]:.2f}", f"{r['error'][1] / r['moved'][1]:.2f}"])
        parts += [f"**{label}**:", "",
                  table(["guides", "guides chosen by, offsets turned by", "error median (mm)", "error p90 (mm)",
                         "moved median (mm)", "moved p90 (mm)", "median ratio", "p90 ratio"], rows), ""]
    log("follow: cost")
    c = cost()
    parts += [table(["render strands", "vertices", "guides", "bind (s)", "per frame (s)", "per frame, CPU (s)",
                     "CPU per million vertices (s)", "binding memory (MB)", "threads", "other processes' CPU share"],
                    [[f"{RENDER:,}", f"{c['points']:,}", f"{GUIDES:,}", f"{c['bind']:.2f}", f"{c['frame']:.3f}",
                      f"{c['cpu']:.3f}", f"{c['cpu'] / c['points'] * 1e6:.3f}", f"{c['memory'] / 1e6:.0f}",
                      c["threads"], f"{100 * c['load']:.0f} %"]]), ""]
    return "\n".join([
        f"## {TITLE}",
        "",
        "`bench/follow_bench.py`. **Error**: every strand of a groom inverted on the bust and simulated "
        "(`hairinv invert`, `hairinv simulate`); then the strands `--guides N` would pick are taken as guides and "
        "the others as render strands, carried by their 3 guides from their input polylines as `hairinv export "
        "--follow` carries them (`hairinv.follow.Following`), and compared with their own simulation at the "
        "same vertices, over every frame after the first. *Moved*: how far those vertices moved in their own "
        "simulation relative to the body (from where their own root frame carries them): a render strand that "
        "ignored its guides would be off by that much, so a ratio below 1 is what following buys. Guides chosen "
        "by root distance, or along the strand (the 3 lying nearest it, point by point, among the 12 nearest by "
        "root); offsets turned by each guide's root frame or by its material frame where they are measured.",
        "",
        *parts,
        f"**Cost**: a synthetic groom of {RENDER:,} render strands of {VERTICES} vertices around {GUIDES:,} guides "
        f"of {ELEMENTS} curled elements (bind once: the candidates' distances along the strands and the offsets; "
        "per frame: every vertex from its 3 guides, exact super-helix evaluation, median of 5).",
        "",
        f"This section took {(time.perf_counter() - started) / 60:.1f} min.",
    ])


if __name__ == "__main__":
    print(run())
