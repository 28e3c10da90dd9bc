"""Benchmark of shots: a groom inverted on an animated body's bind pose, then simulated under its animation.

Run alone with ``python bench/shots_bench.py`` (prints the markdown section), or through
``bench/run.py shots``, which writes the section "Shots: hair on an animated body" of
``docs/benchmarks.md``. ``HAIRINV_BENCH_SMOKE=1`` runs a smoke version (a few strands, a fraction
of a second of two shots).

The shots (docs/shots.md):

* CesiumMan walking (the real-data folder's ``cesiumman/CesiumMan.glb``, ``common.DATA``) with the bob
  ``bench/cesiumman_groom.py`` grows on its head in the bind pose: inverted on the GLB (its bind pose),
  then simulated over the whole walk cycle after the default pre-roll from the bind pose (arms out) to the
  cycle's first frame;
* the rigged mannequin of ``samples/make_rigs.py``: the development motions turn90, nod30, jump30 and stop15,
  held-out variants judged with the same settings (``HELD_OUT_RUN``), each with its own groom (the sample
  straight groom on that variant's head), and ``hold`` (the bind pose keyed for 1 s, simulated for 2 s:
  the still promise, largest displacement < 0.1 mm).

Each groom is inverted through the command line as a user would run it (``hairinv invert GROOM BODY.glb
--guides N``, default settings); the simulation runs in this process (``hairinv.simulation.load`` and
``Run.simulate``, what ``hairinv simulate MODEL BODY.glb`` calls, default settings) under cProfile, and its
``/frames`` is written and read back with h5py for the figures:

* roots off their triangles: the largest distance, over strands and frames, of ``/frames/root`` from where
  the binding puts it on the frame's ``body_vertices`` (docs/stage-files.md: ``p + o_0 e + o_1 (n x e) +
  o_2 n``, written out here);
* deepest penetration: each strand sampled every ``SAMPLE_SPACING`` along its arc length at every frame
  (``hairinv.rod.helix.strand_points`` of the frame's roots, root frames and curvatures), the signed
  distance of every sample to that frame's body mesh (``hairinv.contacts.body.BodyMesh.closest``);
* strands moved: ``/frames/strand_displacement`` is each strand's largest point distance from where it
  started, in its own root's frame (the motion the skin carries is not counted): the strands past
  ``MOVED`` at any frame, and still past it at the last frame;
* strands off the body: a strand touches the body at a frame when one of its samples is within
  ``TOUCH`` of it (the contacts' body distance, 4 mm, plus the hair layer's gaps, up to 7 mm); the strands
  that touch it at the first frame and not at the last;
* stretch: super-helices are inextensible by construction; as a sanity value, ``|dx/ds|`` by central
  differences of +-``STRETCH_EPS`` at the samples, the largest ``| |dx/ds| - 1 |`` over strands and frames;
* time: each frame's computing time (``/frames/frame_seconds``, median over the frames), the pre-roll's
  (from the call to the first recorded frame), and a profile of the steps by phase (cProfile's cumulative
  times, ``PHASES``).
"""

from __future__ import annotations

import cProfile
import json
import os
import pstats
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from common import DATA, ROOT, SMOKE, WORK, log, machine, smoke, table  # type: ignore
else:
    from .common import DATA, ROOT, SMOKE, WORK, log, machine, smoke, table

sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "samples"))

import h5py  # noqa: E402

import make_rigs as mr  # noqa: E402
from hairinv.contacts.body import BodyMesh  # noqa: E402
from hairinv.rod.helix import strand_points  # noqa: E402

TITLE = "Shots: hair on an animated body"
HERE = Path(__file__).resolve().parent
CESIUMMAN = DATA / "cesiumman" / "CesiumMan.glb"
RUBY = DATA / "ruby" / "ruby_short_hair_16_guide.tfx"

DEVELOPMENT_RUN = smoke(("turn90", "nod30", "jump30", "stop15"), ("turn90",))
HELD_OUT_RUN = smoke(("turn_right75", "jump20"), ())
# held-out grooms on held-out motions: (motion variant, sample groom warped onto its head, guides; 0: every
# strand): the curly groom on the hardest stop, the wavy groom, the settled curly groom (40 strands resting on
# the body; the others' layers lie 1.5 to 10 mm above it), and three times the straight groom's guides
GROOM_VARIANTS = smoke((("stop20", "curly", 48), ("nod20_fast", "wavy", 32), ("turn45_snap", "settled_curly", 0),
                        ("walk_fast", "straight", 96)), ())
MANNEQUIN_GUIDES = smoke(32, 4)  # of the groom's 300 strands
CESIUMMAN_STRANDS = smoke(300, 40)  # the bob's strands
CESIUMMAN_GUIDES = smoke(60, 4)
HOLD_GUIDES = smoke(0, 4)  # 0: every strand
HOLD_SECONDS = smoke(2.0, 0.1)
SMOKE_SECONDS = 0.1  # s of each moving shot in a smoke run
WARM_UP_SECONDS = 0.1
STILL = 1e-4  # m: the hold shot's promise (hairinv verify's default tolerance)
SAMPLE_SPACING = 1e-3  # m along each strand
MOVED = 0.01  # m
TOUCH = 0.008  # m
STRETCH_EPS = 1e-5  # m
INVERT_BUDGET = 900.0  # s for one inversion before it is killed

# phases of a step: (label, [(file suffix, function name, caller's function name or None)])
PHASES = (
    ("free motion", [("dynamics/simulate.py", "run_chunks", "_step"), ("dynamics/rods.py", "stale_strands", None),
                     ("dynamics/simulate.py", "_contact_hessians", None)]),
    ("detect", [("dynamics/tracking.py", "detect", None)]),
    ("contacts kept", [("dynamics/tracking.py", "persist", None), ("dynamics/tracking.py", "remember", None)]),
    ("rows", [("contacts/rows.py", "contact_rows", "_step"), ("", "factored_blocks", "_step"),
              ("", "factored_rows", "_step"), ("", "coulomb_problem", "_step"),
              ("dynamics/tracking.py", "drift", None)]),
    ("solve", [("", "solve_coulomb", "_step"), ("dynamics/simulate.py", "_warm_start", None),
               ("dynamics/simulate.py", "_mass_solve", "_step")]),
    ("skin", [("dynamics/skin.py", "step", None)]),
)


@dataclass
class Shot:
    name: str
    split: str
    """real, development, held out, still"""
    body: Path
    groom: Path
    guides: int
    """0: every strand"""
    seconds: float | None = None
    """None: the animation's length"""
    what: str = ""
    figures: dict = field(default_factory=dict)


def _hairinv(*args, cwd: Path, timeout: float = INVERT_BUDGET) -> subprocess.CompletedProcess:
    """``hairinv ARGS`` in a subprocess of this Python (the package it imports)."""
    return subprocess.run([sys.executable, "-m", "hairinv_cli.main", *map(str, args)], cwd=cwd, capture_output=True,
                          text=True, timeout=timeout, env=dict(os.environ, HAIRINV_PROGRESS_SECONDS="1e9"))


# ---------------------------------------------------------------------------------------------------- inputs


def mannequin_shots(folder: Path) -> list[Shot]:
    shots = []
    runs = ([(n, "development", "straight", MANNEQUIN_GUIDES) for n in DEVELOPMENT_RUN]
            + [(n, "held out", "straight", MANNEQUIN_GUIDES) for n in HELD_OUT_RUN]
            + [(n, "held out, groom", g, k) for n, g, k in GROOM_VARIANTS] + [("hold", "still", "straight", HOLD_GUIDES)])
    for name, split, groom_name, guides in runs:
        rig, motion = mr.variant(name)
        label = name if split != "held out, groom" else f"{name} {groom_name}" + (f" {guides}" if guides else "")
        where = folder / _slug(label)
        where.mkdir(parents=True, exist_ok=True)
        glb = mr.write_glb(where / f"{name}.glb", rig, motion)
        groom = mr.write_groom(where / "groom.h5", rig.seed, groom_name)
        kind, params, fps, seed = mr.VARIANTS[name]
        what = ", ".join(f"{k} {v:g}" for k, v in params.items()) or "the bind pose"
        what = f"{kind} ({what}), head seed {seed}, {fps:g} fps" + ("" if groom_name == "straight" else
                                                                    f", the {groom_name.replace('_', ' ')} groom")
        seconds = HOLD_SECONDS if name == "hold" else (SMOKE_SECONDS if SMOKE else None)
        shots.append(Shot(label, split, glb, groom, guides, seconds, what))
    return shots


def cesiumman_shot(folder: Path) -> Shot | None:
    if not CESIUMMAN.exists():
        log(f"{CESIUMMAN} not found: the CesiumMan shot is skipped")
        return None
    folder.mkdir(parents=True, exist_ok=True)
    groom = folder / "bob.h5"
    done = subprocess.run([sys.executable, str(HERE / "cesiumman_groom.py"), "--data", str(DATA), "-o", str(groom),
                           "--strands", str(CESIUMMAN_STRANDS)], capture_output=True, text=True, cwd=ROOT)
    if done.returncode != 0:
        raise RuntimeError(f"bench/cesiumman_groom.py failed: {done.stderr[-2000:]}")
    return Shot("CesiumMan walk", "real", CESIUMMAN, groom, CESIUMMAN_GUIDES, SMOKE_SECONDS if SMOKE else None,
                f"the GLB's walk cycle, the bob of bench/cesiumman_groom.py ({CESIUMMAN_STRANDS} strands)")


# ---------------------------------------------------------------------------------------------------- running


def invert(shot: Shot, folder: Path) -> Path:
    model = folder / f"{_slug(shot.name)}.model.h5"
    args = ["invert", shot.groom, shot.body, "-o", model, "--no-progress"]
    if shot.guides:
        args += ["--guides", shot.guides]
    start = time.perf_counter()
    done = _hairinv(*args, cwd=folder)
    shot.figures["invert_seconds"] = time.perf_counter() - start
    (folder / f"{_slug(shot.name)}.invert.log").write_text(done.stdout + done.stderr)
    if done.returncode != 0:
        raise RuntimeError(f"{shot.name}: invert failed: {done.stderr.strip().splitlines()[-1:]}")
    return model


def simulate(shot: Shot, model: Path, folder: Path) -> Path:
    """The shot in this process under cProfile; its frames written to ``folder``."""
    from hairinv import simulation

    lines: list[str] = []
    run = simulation.load(model, shot.body, seconds=shot.seconds, say=lines.append)
    marks = {}

    def on_frame(frame_log):
        if frame_log.index == 0:
            marks["first"] = time.perf_counter()
        return False

    profile = cProfile.Profile()
    start = time.perf_counter()
    profile.enable()
    try:
        run.simulate(on_frame=on_frame)
    finally:
        profile.disable()
    total = time.perf_counter() - start
    output = folder / f"{_slug(shot.name)}.frames.h5"
    run.record = simulation.simulate_record(run, "still")
    run.write(output)
    (folder / f"{_slug(shot.name)}.simulate.log").write_text("\n".join(lines) + "\n")
    stats = pstats.Stats(profile)
    shot.figures.update(simulate_seconds=total, preroll_seconds=marks["first"] - start, preroll=run.shot.preroll,
                        phases=phases(stats),
                        tree_seconds=(_cumulative(stats, "contacts/body.py", "from_mesh", "body_at")
                                      + _cumulative(stats, "contacts/body.py", "moved", "body_at")),
                        steps_seconds=_cumulative(stats, "dynamics/simulate.py", "step", None),
                        strands=run.helices.n_strands, fps=run.fps, seconds=run.seconds, notes=lines)
    return output


def _cumulative(stats: pstats.Stats, suffix: str, name: str, caller: str | None) -> float:
    """Cumulative seconds of the functions ``name`` in files ending in ``suffix`` (any file: ''), all calls or
    those from functions named ``caller``."""
    total = 0.0
    for (filename, _, funcname), (_, _, _, ct, callers) in stats.stats.items():
        if funcname != name or not filename.replace(os.sep, "/").endswith(suffix):
            continue
        if caller is None:
            total += ct
        else:
            total += sum(v[3] for (_, _, cname), v in callers.items() if cname == caller)
    return total


def phases(stats: pstats.Stats) -> dict:
    return {label: sum(_cumulative(stats, *spec) for spec in specs) for label, specs in PHASES}


# ---------------------------------------------------------------------------------------------------- figures


def _roots_on_triangles(vertices, faces, triangle, barycentric, offset):
    """The bound roots by the binding's definition (docs/stage-files.md), written out here."""
    a, b, c = (vertices[faces[triangle, i]] for i in range(3))
    p = barycentric[:, :1] * a + barycentric[:, 1:2] * b + barycentric[:, 2:] * c
    e = (b - a) / np.linalg.norm(b - a, axis=1, keepdims=True)
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return p + offset[:, :1] * e + offset[:, 1:2] * np.cross(n, e) + offset[:, 2:] * n


class _Mesh:
    def __init__(self, vertices, faces):
        self.vertices, self.faces = np.asarray(vertices, dtype=np.float64), faces


def measure(path: Path) -> dict:
    """The figures of a shot's ``/frames`` (see the module's docstring)."""
    with h5py.File(path, "r") as fh:
        f = fh["frames"]
        data = {key: f[key][()] for key in ("time", "root", "frame0", "omega", "body_vertices", "body_faces",
                                            "binding_triangle", "binding_barycentric", "binding_offset",
                                            "strand_displacement", "frame_seconds", "displacement",
                                            "contact_count")}
        offsets, length = fh["helices/offsets"][()], fh["helices/length"][()]
        step = float(f.attrs["time_step"])
    S = len(offsets) - 1
    total = np.add.reduceat(length, offsets[:-1])
    per = np.maximum(np.ceil(total / SAMPLE_SPACING).astype(int), 2) + 1
    strand = np.repeat(np.arange(S), per)
    first = np.r_[0, np.cumsum(per)[:-1]]
    s = (np.arange(per.sum()) - np.repeat(first, per)) / np.repeat(per - 1, per) * total[strand]
    inner = (s > STRETCH_EPS) & (s < total[strand] - STRETCH_EPS)
    faces = data["body_faces"]
    off_triangle = deepest = stretch = 0.0
    deepest_at, deepest_s, deepest_speed = (0, -1), (0.0, 0.0), 0.0
    touching = []
    for k in range(len(data["time"])):
        vertices = data["body_vertices"][k].astype(np.float64)
        expected = _roots_on_triangles(vertices, faces, data["binding_triangle"], data["binding_barycentric"],
                                       data["binding_offset"])
        off_triangle = max(off_triangle, float(np.linalg.norm(data["root"][k] - expected, axis=1).max()))
        args = (data["root"][k], data["frame0"][k], offsets, data["omega"][k], length)
        x = strand_points(*args, strand, s)
        d = BodyMesh.from_mesh(_Mesh(vertices, faces)).closest(x)[0]
        if -d.min() > deepest:
            i = int(np.argmin(d))
            deepest, deepest_at = float(-d.min()), (k, int(strand[i]))
            deepest_s = (float(s[i]), float(total[strand[i]]))
            deepest_speed = 0.0
            if k:  # how fast that point of the strand moved over the frame before
                j = np.array([strand[i]])
                before = strand_points(data["root"][k - 1], data["frame0"][k - 1], offsets, data["omega"][k - 1],
                                       length, j, np.array([s[i]]))
                dt = float(data["time"][k] - data["time"][k - 1])
                deepest_speed = float(np.linalg.norm(x[i] - before[0]) / dt)
        touching.append(np.minimum.reduceat(d, first) < TOUCH)
        ahead = strand_points(*args, strand[inner], s[inner] + STRETCH_EPS)
        behind = strand_points(*args, strand[inner], s[inner] - STRETCH_EPS)
        speed = np.linalg.norm(ahead - behind, axis=1) / (2 * STRETCH_EPS)
        stretch = max(stretch, float(np.abs(speed - 1.0).max()))
    moved = data["strand_displacement"] > MOVED
    seconds = data["frame_seconds"][1:]
    return {"frames": len(data["time"]), "strands": S, "off_triangle": off_triangle, "deepest": deepest,
            "deepest_at": deepest_at, "deepest_s": deepest_s, "deepest_speed": deepest_speed,
            "moved_any": int(moved.any(axis=0).sum()), "moved_last": int(moved[-1].sum()),
            "left_body": int(np.sum(touching[0] & ~touching[-1])), "touching_first": int(touching[0].sum()),
            "stretch": stretch, "largest": float(data["displacement"].max()),
            "frame_median": float(np.median(seconds)) if len(seconds) else 0.0,
            "frames_total": float(seconds.sum()), "contacts_median": float(np.median(data["contact_count"])),
            "samples": int(per.sum()), "peak_frame": int(np.argmax(data["displacement"])), "time_step": step}


def picture(shot: Shot, frames: Path, folder: Path) -> Path:
    """``hairinv export FRAMES -o NAME.png``: the groom before and after, over the body at those frames."""
    png = folder / f"{_slug(shot.name)}.png"
    done = _hairinv("export", frames, "-o", png, cwd=folder)
    if done.returncode != 0:
        log(f"{shot.name}: export failed: {done.stderr.strip()[-500:]}")
    return png


def _slug(name: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in name).strip("_").lower()


def run_shot(shot: Shot, folder: Path) -> Shot:
    log(f"{shot.name}: invert {shot.groom.name} on {shot.body.name}"
        + (f", {shot.guides} guides" if shot.guides else ""))
    model = invert(shot, folder)
    log(f"{shot.name}: inverted in {shot.figures['invert_seconds']:.0f} s; simulating")
    frames = simulate(shot, model, folder)
    log(f"{shot.name}: simulated {shot.figures['seconds']:.3g} s in {shot.figures['simulate_seconds']:.0f} s "
        f"(pre-roll {shot.figures['preroll_seconds']:.0f} s); measuring")
    shot.figures.update(measure(frames))
    shot.figures["picture"] = str(picture(shot, frames, folder))
    f = shot.figures
    log(f"{shot.name}: roots off {1e3 * f['off_triangle']:.2g} mm, deepest {1e3 * f['deepest']:.3g} mm, "
        f"moved {f['moved_any']}/{f['moved_last']}, left {f['left_body']}, stretch {f['stretch']:.2g}, "
        f"largest {1e3 * f['largest']:.3g} mm, {f['frame_median']:.2f} s a frame")
    return shot


# ---------------------------------------------------------------------------------------------------- section


def _mm(x, digits=3):
    return f"{1e3 * x:.{digits}g}"


def render(shots: list[Shot], meta: dict) -> str:
    info = meta["machine"]
    lines = [f"## {TITLE}", ""]
    lines.append(
        "A groom inverted on an animated body's bind pose, then simulated under the body's animation "
        "(docs/shots.md): `hairinv invert GROOM BODY.glb --guides N` through the command line, then what "
        "`hairinv simulate MODEL BODY.glb` runs (`hairinv.simulation.load` and `Run.simulate`, in the benchmark's "
        "process under cProfile), both at the default settings, and `/frames` read back with h5py. "
        f"On {info['cpu']}, {info['cores']} logical cores, {info['ram']} RAM, Python {info['python']}, "
        f"numpy / scipy / numba {info['numpy']} / {info['scipy']} / {info['numba']}; each shot run once "
        "(a shot takes minutes: times are single runs, and other processes shared the machine as the load "
        "average above says). `python bench/shots_bench.py` prints this section; the work files and each shot's "
        "picture are in `out/shots_bench/`.")
    lines.append("")
    lines.append(
        "The shots: CesiumMan (the real-data folder's `cesiumman/CesiumMan.glb`, a skinned human, 19 joints, "
        "3,273 vertices) walking its 1.96 s cycle with the bob `bench/cesiumman_groom.py` grows on its head "
        f"({CESIUMMAN_STRANDS} strands; inverted and simulated on {CESIUMMAN_GUIDES} guides of them, `--guides "
        f"{CESIUMMAN_GUIDES}`: all 300 took 12-18 s a frame over the cycle's first 0.2 s in a trial run on this "
        "machine shared with other processes, 10-14 minutes for the cycle), after the default 0.5 s pre-roll from the bind pose (arms out) to "
        "the cycle's first frame; "
        "the rigged mannequin of `samples/make_rigs.py` in its development motions and in held-out variants "
        "(another head and another motion of the same kind, judged with the same settings), each with its own "
        f"groom (the sample straight groom on that head, 300 strands; {MANNEQUIN_GUIDES} guides of them, to keep "
        "the benchmark under 20 minutes on a machine that others load), each over its whole animation; held-out grooms "
        "on held-out motions (the samples' curly, wavy and settled curly grooms and 96 straight guides, each on that "
        "motion's head; the settled curly groom's 40 strands rest on the body, the others' layers lie 1.5 to 10 mm "
        "above it); and `hold`, the bind pose keyed for 1 s "
        f"and simulated for {HOLD_SECONDS:g} s on "
        + (f"{HOLD_GUIDES} guides" if HOLD_GUIDES else "every strand") + ", the still promise.")
    lines.append("")
    header = ["shot", "split", "motion", "strands", "frames (s)", "invert", "simulate (pre-roll share)",
              "per frame, median", "contacts, median"]
    rows = []
    for s in shots:
        f = s.figures
        if "error" in f:
            rows.append([s.name, s.split, s.what, "–", "–", "–", f["error"], "–", "–"])
            continue
        pre = f"{f['preroll_seconds'] / f['simulate_seconds']:.0%} for {f['preroll']:g} s" if f["preroll"] else "none"
        rows.append([s.name, s.split, s.what, f"{f['strands']}", f"{f['frames']} ({f['seconds']:.3g} s at "
                     f"{f['fps']:g} fps)", f"{f['invert_seconds']:.0f} s",
                     f"{f['simulate_seconds']:.0f} s ({pre})", f"{f['frame_median']:.2f} s",
                     f"{f['contacts_median']:,.0f}"])
    lines += [table(header, rows, ["l", "l", "l"] + ["r"] * 6), ""]
    lines.append(
        "\"Invert\" is the whole `hairinv invert` subprocess (reading, fitting, detecting, inverting, the stability "
        "check); \"simulate\" the whole `Run.simulate` call, the pre-roll included (its share is the time "
        "to the first recorded frame: the binding and the pre-roll's steps); \"per frame\" the median of "
        "`/frames/frame_seconds` over the recorded frames (the steps between two frames, halvings included).")
    lines.append("")
    header = ["shot", "roots off their triangles, largest", "deepest point inside the body",
              f"strands moved > {1e3 * MOVED:g} mm in their root's frame: any frame / last", "strands off the body",
              "largest stretch", "largest displacement", "verdict"]
    rows = []
    for s in shots:
        f = s.figures
        if "error" in f:
            continue
        verdict = ""
        if s.split == "still":
            verdict = f"**{'PASS' if f['largest'] < STILL else 'FAIL'}** (< {1e3 * STILL:g} mm)"
        k, strand = f["deepest_at"]
        deep = f"{_mm(f['deepest'])} mm (frame {k}, strand {strand})" if f["deepest"] > 0 else "none"
        rows.append([s.name, f"{_mm(f['off_triangle'], 2)} mm", deep, f"{f['moved_any']} / {f['moved_last']}",
                     f"{f['left_body']} of {f['touching_first']}", f"{f['stretch']:.1e}",
                     f"{_mm(f['largest'])} mm", verdict])
    lines += [table(header, rows), ""]
    worst = max((sh for sh in shots if "error" not in sh.figures), key=lambda sh: sh.figures["deepest"], default=None)
    if worst is not None and worst.figures["deepest"] > 1e-3:
        f = worst.figures
        k, strand = f["deepest_at"]
        at, total = f["deepest_s"]
        lines += [
            f"The deepest point, {_mm(f['deepest'], 2)} mm in {worst.name} ({worst.split}), is strand {strand}'s "
            f"at {1e3 * at:.0f} mm of its {1e3 * total:.0f} mm, at frame {k} (t = {k / f['fps']:.3g} s), a point that "
            f"moved at {f['deepest_speed']:.2g} m/s over the frame before: "
            f"{1e3 * f['deepest_speed'] * f['time_step']:.0f} mm in a {1e3 * f['time_step']:.3g} ms step, unless "
            "the step was halved. Contacts are found at each step's "
            "start within the contact distance widened by how far the skin, the strands' frames and the strands' own "
            "motion (at the velocity the step starts with) sweep in the step; what a step adds to a strand's speed "
            "(the kick of the body's acceleration, a contact's push) is counted from the next step on, so a point can "
            "reach into the skin by about that much before a contact holds it, and is pushed out over the following "
            "steps.", ""]
    lines.append(
        "Roots off their triangles: the largest distance, over strands and frames, of `/frames/root` from where "
        "the binding datasets put the root on the frame's `body_vertices` (float32: 1e-7 m is their round-off). "
        f"Deepest point: each strand sampled every {1e3 * SAMPLE_SPACING:g} mm along its arc length at every frame, "
        "the signed distance of the samples to that frame's body mesh (`BodyMesh.closest`); the contacts keep a "
        "strand at its own gap, so a depth of a hair's radius (0.05 mm) is round-off of the contact model, "
        f"more is hair through the skin. Strands moved: `/frames/strand_displacement` past {1e3 * MOVED:g} mm, "
        "the strand's largest point distance from its inverted shape in its own root's frame (the motion the "
        "skin carries is not counted), at any frame and at the last one (the swing has not settled back). "
        f"Strands off the body: strands with a sample within {1e3 * TOUCH:g} mm of the body at the first frame "
        "(the contacts' 4 mm and the hair layer's gaps), none at the last, of those touching at the first. "
        "Largest stretch: `| |dx/ds| - 1 |` at the samples, by central differences of "
        f"{1e6 * STRETCH_EPS:g} um (super-helices are inextensible by construction: a sanity value, round-off and "
        "the differences' truncation). Largest displacement: `/frames/displacement`, in the root's frame.")
    lines.append("")
    header = ["shot", "steps"] + [label for label, _ in PHASES] + ["of it, the body's tree", "other"]
    rows = []
    for s in shots:
        f = s.figures
        if "error" in f:
            continue
        steps = f["steps_seconds"]
        parts = [f["phases"][label] for label, _ in PHASES]
        rows.append([s.name, f"{steps:.0f} s"] + [f"{p / steps:.0%}" for p in parts]
                    + [f"{f['tree_seconds'] / steps:.0%}", f"{max(steps - sum(parts), 0.0) / steps:.0%}"])
    lines += ["Where a shot's steps go (cProfile's cumulative times in the main thread, the kernels' worker "
              "threads counted in the calls that wait for them, as shares of `Simulation.step`):", "",
              table(header, rows), ""]
    lines.append(
        "Free motion: each strand's dynamics without contacts (the `run_chunks` of the free velocity, the gravity "
        "and contact Hessians); detect: `ContactTracker.detect` (contact detection on the posed strands and the body "
        "where it is at the step's start, or the last detection reused); contacts kept: the remembered contacts "
        "measured again and matched (`ContactTracker.persist`, `remember`); rows: the contact rows, their factored blocks and "
        "the drift of the frames and the skin against each other; solve: the Coulomb solve (`solve_coulomb`, "
        "or the warm start accepted) and its correction; skin: `SkinnedBody.step` (the body's vertices at the "
        "step's times, the strands' frames, and the body prepared for the contacts' closest-point queries: "
        "prepared once by `BodyMesh.from_mesh`, then `BodyMesh.moved` to each step's vertices, its pseudo-normals "
        "taken again and its tree refitted, the next column; built afresh at every step, it took 34-47 % of a "
        "moving mannequin shot's steps and 64 % of a held pose's).")
    lines.append("")
    lines += _verdict_lines(shots, meta)
    return "\n".join(lines)


def _verdict_lines(shots: list[Shot], meta: dict) -> list[str]:
    out = []
    failed = [s for s in shots if "error" in s.figures]
    for s in failed:
        out.append(f"- {s.name}: {s.figures['error']}")
    if meta.get("cesiumman_skipped"):
        out.append(f"- CesiumMan: not run, {CESIUMMAN} not found (set HAIRINV_REAL_DATA).")
    out.append(
        "Ruby short (`ruby/ruby_short_hair_16_guide.tfx`) on the mannequin's head is not run: it is groomed on "
        "`ruby_head.obj`, another head than the mannequin's: at its 0.002 m per unit its roots lie about 1 m from "
        "the mannequin's skin (ruby's head is at the origin), and moved onto the mannequin's head they would still "
        "not sit on it (they span 9 cm across, the mannequin's skull 16 cm), while a shot binds each root to the "
        "animated body's nearest triangle and refuses a body no root is within 5 mm of; no rig of ruby's head "
        "exists to animate it.")
    out.append("")
    out.append(f"The whole benchmark took {meta['seconds'] / 60:.1f} min (generating the rigs and the bob "
               f"{meta['generate_seconds']:.0f} s).")
    return out


def warm_up(shots: list[Shot], folder: Path) -> float:
    """A fraction of a second of the first shot on a few guides, untimed: numba's kernels compiled or loaded
    from its cache before the shots are timed."""
    start = time.perf_counter()
    folder.mkdir(parents=True, exist_ok=True)
    for shot in shots[:1] + [s for s in shots if s.split != "real"][:1]:
        probe = Shot(shot.name, shot.split, shot.body, shot.groom, 4, WARM_UP_SECONDS)
        log(f"warm-up: {probe.name}, 4 guides, {WARM_UP_SECONDS:g} s")
        simulate(probe, invert(probe, folder), folder)
    return time.perf_counter() - start


def run_all(folder: Path) -> tuple[list[Shot], dict]:
    start = time.perf_counter()
    info = machine()
    folder.mkdir(parents=True, exist_ok=True)
    shots = []
    cesium = cesiumman_shot(folder / "cesiumman")
    if cesium is not None:
        shots.append(cesium)
    shots += mannequin_shots(folder / "rigs")
    meta = {"machine": info, "generate_seconds": time.perf_counter() - start, "cesiumman_skipped": cesium is None}
    if not SMOKE:
        meta["warm_up_seconds"] = warm_up(shots, folder / "warm_up")
    for shot in shots:
        try:
            run_shot(shot, folder)
        except (RuntimeError, subprocess.TimeoutExpired) as exc:
            shot.figures["error"] = str(exc)
            log(f"{shot.name}: {exc}")
    meta["seconds"] = time.perf_counter() - start
    (folder / "results.json").write_text(json.dumps(
        {"meta": meta, "shots": [{"name": s.name, "split": s.split, "guides": s.guides, **s.figures}
                                 for s in shots]}, indent=1, default=str))
    return shots, meta


def run() -> str:
    if SMOKE:
        with tempfile.TemporaryDirectory(prefix="shots_bench_", dir=WORK if WORK.exists() else None) as folder:
            shots, meta = run_all(Path(folder))
    else:
        shots, meta = run_all(WORK / "shots_bench")
    return render(shots, meta)


def main() -> int:
    print(run())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
