"""Benchmark of the promise "invert, then a still simulation does not move", on every kind of groom.

Run alone with ``python bench/still_bench.py`` (prints the markdown section),
or through ``bench/run.py still``, which writes the section "Still on any
groom" of ``docs/benchmarks.md``. ``python bench/still_bench.py --quick`` is a
smoke run (20 guide strands of the generated mohawk, well under a minute);
``run(quick=True)`` returns its section and ``measure_groom`` one groom's
figures, for a test.

Each groom goes through the command line as a user would run it, with the
default settings, each command in its own subprocess::

    hairinv invert STYLE BODY -o model.h5 [--scale S] [--target zero]
    hairinv verify model.h5 BODY --seconds 2 --tolerance 0.1mm --json

The grooms: the development and the held-out variants of ``bench/grooms.py``
(generated into ``out/still_bench/`` with its mannequin), sintel, ruby
short, ruby long and the TressFX ponytail's bangs and tail from the real
data (``common.DATA``), and the repository samples
``samples/settled.h5`` (with ``--target zero``: the paper's controlled
validation, whose truth is a straight rest shape) and
``samples/settled_curly.h5`` on ``samples/body.obj``.

Recorded per groom: from invert's printed report the declared contacts
(hair-body, the "hair layer:" and "wisps:" lines, hair-hair), the contacts
carrying force, the median layer gap, the solver's stop and the gravity-only
factor; from the model file (h5py) the body contacts inside the body
(``/contacts/gap`` < 0), the strand count and the stiffening factors
(``/model/stiffening``); from verify's JSON the verdict, the largest
displacement, the time the run stopped at and the strands that moved. Both
commands are timed (wall clock, the whole subprocess). A groom whose two
commands together run past ``GROOM_BUDGET`` seconds is killed and recorded
as timed out.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from common import DATA, ROOT, SMOKE, log, machine, machine_markdown, table  # type: ignore
else:
    from .common import DATA, ROOT, SMOKE, log, machine, machine_markdown, table

sys.path.insert(0, str(ROOT / "bench"))

from grooms import DEVELOPMENT, HELD_OUT  # noqa: E402

TITLE = "Still on any groom"
HERE = Path(__file__).resolve().parent
HAIRINV = ROOT / ".venv" / "bin" / "hairinv"
PYTHON = ROOT / ".venv" / "bin" / "python"
SAMPLES = ROOT / "samples"
WORK = ROOT / "out" / "still_bench"
SECONDS = 2.0
TOLERANCE = "0.1mm"
GROOM_BUDGET = 600.0  # s, invert and verify of one groom together
# held-out variants run (None: all of them); all 18 grooms took 23-30 min on 2 cores (2026-12-01)
HELD_OUT_RUN = None
QUICK_VARIANT = "mohawk"
QUICK_GUIDES = 20
LIST_ALL = 40  # a failing groom's sentence names every strand that moved up to this many
LIST_STRANDS = 12  # and beyond, the strands that moved most (the others are counted)


@dataclass
class Groom:
    name: str
    kind: str
    """development, held out, real, sample"""
    style: Path
    body: Path
    args: list[str] = field(default_factory=list)
    """extra options of ``hairinv invert`` (units, target, guides)"""


def real_grooms() -> list[Groom]:
    return [
        Groom("sintel", "real", DATA / "sintel" / "GEO-sintel_hair_emit.001-sintel_hair.tfx",
              DATA / "sintel" / "sintel.obj", ["--scale", "0.008"]),
        Groom("ruby short", "real", DATA / "ruby" / "ruby_short_hair_16_guide.tfx", DATA / "ruby" / "ruby_head.obj",
              ["--scale", "0.002"]),
        Groom("ruby long", "real", DATA / "ruby" / "ruby_long_hair_16_guide.tfx", DATA / "ruby" / "ruby_head.obj",
              ["--scale", "0.002"]),
        Groom("ponytail front", "real", DATA / "ponytail" / "hair_front_16_guide.tfx",
              DATA / "ponytail" / "head_max4.obj", ["--scale", "0.0025"]),
        Groom("ponytail tail (TressFX 3)", "real", DATA / "ponytail" / "tressfx3" / "tail.tfx",
              DATA / "ponytail" / "head_max4.obj", ["--scale", "0.0025", "--flip", "z"]),
    ]


def sample_grooms() -> list[Groom]:
    return [
        Groom("settled (target zero)", "sample", SAMPLES / "settled.h5", SAMPLES / "body.obj", ["--target", "zero"]),
        Groom("settled_curly", "sample", SAMPLES / "settled_curly.h5", SAMPLES / "body.obj"),
    ]


def generated_names(held_out: int | None = HELD_OUT_RUN) -> tuple[list[str], list[str]]:
    held = list(HELD_OUT) if held_out is None else list(HELD_OUT)[:held_out]
    return list(DEVELOPMENT), held


def generate(outdir: Path, names: list[str]) -> float:
    """Write ``outdir/mannequin.obj`` and the named variants with ``bench/grooms.py``; returns its seconds."""
    outdir.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    subprocess.run([str(PYTHON), str(HERE / "grooms.py"), "-o", str(outdir), *names], check=True,
                   stdout=subprocess.DEVNULL, cwd=ROOT)
    return time.perf_counter() - start


# ---------------------------------------------------------------------------
# running one groom


def _run(cmd: list[str], timeout: float, cwd: Path) -> tuple[int | None, str, str, float]:
    """Run ``cmd`` in its own process group; kill that group past ``timeout`` s.
    Returns (exit code or None if killed, stdout, stderr, wall seconds)."""
    start = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=cwd,
                            start_new_session=True)
    try:
        out, err = proc.communicate(timeout=max(timeout, 1.0))
        code = proc.returncode
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)  # the group of the process started here, by its id
        out, err = proc.communicate()
        code = None
    return code, out, err, time.perf_counter() - start


_NUM = r"([-+0-9.eE]+)"


def parse_invert(text: str) -> dict:
    """Figures of invert's printed report."""
    r: dict = {}
    m = re.search(r"declared (\d+) contacts in \S+ s: (\d+) hair-body on (\d+) strands, (\d+) hair-hair", text)
    if m:
        r["declared"], r["body"], r["body_strands"], r["hair"] = map(int, m.groups())
    else:  # no body, or no contacts at all
        r["declared"] = r["body"] = r["hair"] = 0
        m = re.search(r"declared (\d+) contacts", text)
        if m:
            r["declared"] = int(m.group(1))
    m = re.search(r"hair layer: (\d+) of the body contacts lie beyond body_distance, on (\d+) strands.*?median "
                  + _NUM, text)
    r["layer"], r["layer_strands"], r["layer_gap_median_mm"] = (
        (int(m.group(1)), int(m.group(2)), float(m.group(3))) if m else (0, 0, None))
    m = re.search(r"wisps: (\d+) of the hair-hair contacts", text)
    r["wisp"] = int(m.group(1)) if m else 0
    m = re.search(r"warning: (\d+) sample points on (\d+) strands? lie inside the body \(deepest " + _NUM + " mm\\)",
                  text)
    r["inside_points"], r["inside_strands"], r["inside_deepest_mm"] = (
        (int(m.group(1)), int(m.group(2)), float(m.group(3))) if m else (0, 0, 0.0))
    m = re.search(r"; (\d+) carry force", text)
    r["carrying"] = int(m.group(1)) if m else 0
    m = re.search(r"solver: (\S+) after (\d+) (sweeps|interior-point steps)", text)
    r["solver"], r["sweeps"], r["solver_work"] = (
        (m.group(1), int(m.group(2)), "steps" if m.group(3) != "sweeps" else "sweeps") if m else (None, None, None))
    m = re.search(r"stiffened (\d+) of (\d+) strands .*?factor median " + _NUM + r", 90th percentile " + _NUM
                  + r", max " + _NUM, text)
    r["stiffened_report"] = (int(m.group(1)), float(m.group(3)), float(m.group(5))) if m else None
    m = re.search(r"warning: (\d+) of (\d+) strands rest in an unstable equilibrium", text)
    r["unstable"] = int(m.group(1)) if m else 0
    m = re.search(r"for comparison, the gravity-only inversion leaves (\d+) strands unstable(?:; it would need "
                  r"E = \S+ GPa \(" + _NUM + r" times\))?", text)
    if m:
        r["gravity_only_unstable"] = int(m.group(1))
        r["gravity_only_factor"] = float(m.group(2)) if m.group(2) else 1.0
    else:
        r["gravity_only_unstable"] = r["gravity_only_factor"] = None
    return r


def read_model(path: Path, body_distance_default: float = 0.004) -> dict:
    """Figures of the model file: strands, body contacts by gap, stiffening, the rest curvature."""
    r: dict = {}
    with h5py.File(path, "r") as f:
        r["strands"] = int(len(f["helices/offsets"]) - 1)
        r["elements"] = int(len(f["helices/length"]))
        cfg = json.loads(f["contacts"].attrs.get("config", "{}") or "{}") if "contacts" in f else {}
        body_distance = float(cfg.get("contacts", {}).get("body_distance", body_distance_default))
        r["body_distance_mm"] = 1e3 * body_distance
        if "contacts" in f and "strand" in f["contacts"]:
            strand = f["contacts/strand"][...]
            gap = f["contacts/gap"][...] if "gap" in f["contacts"] else np.zeros(len(strand))
            body = strand[:, 1] < 0
            r["file_body"] = int(body.sum())
            r["file_inside"] = int(np.sum(body & (gap < 0)))
            r["file_within"] = int(np.sum(body & (gap >= 0) & (gap < body_distance)))
            r["file_beyond"] = int(np.sum(body & (gap >= body_distance)))
            r["file_hair"] = int(np.sum(~body))
        else:
            r.update(file_body=0, file_inside=0, file_within=0, file_beyond=0, file_hair=0)
        model = f["model"]
        if "force" in model:
            force = model["force"][...]
            r["file_carrying"] = int(np.sum(np.linalg.norm(force, axis=1) > 0))
        if "stiffening" in model:
            a = model["stiffening"][...]
            up = a[a > 1.0]
            r["stiffened"] = int(len(up))
            r["factor_median"] = float(np.median(up)) if len(up) else None
            r["factor_max"] = float(up.max()) if len(up) else None
        else:
            r["stiffened"], r["factor_median"], r["factor_max"] = 0, None, None
        rest_name = "omega_rest_stiffened" if "omega_rest_stiffened" in model else "omega_rest"
        q0 = model[rest_name][...]
        length = f["helices/length"][...]
        norms = np.linalg.norm(q0, axis=1)
        r["rest_name"] = rest_name
        r["q0_mean"] = float(norms.mean())
        r["q0_mean_length_weighted"] = float(np.sum(norms * length) / length.sum())
        r["target"] = str(model.attrs.get("target", ""))
    return r


def measure_groom(groom: Groom, workdir: Path, budget: float = GROOM_BUDGET) -> dict:
    """Invert and verify ``groom`` through the command line; every figure recorded, or why it stopped."""
    workdir.mkdir(parents=True, exist_ok=True)
    slug = re.sub(r"[^A-Za-z0-9_]+", "_", groom.name).strip("_")
    model = workdir / f"{slug}.model.h5"
    model.unlink(missing_ok=True)
    res: dict = {"name": groom.name, "kind": groom.kind, "args": groom.args}
    cmd = [str(HAIRINV), "invert", str(groom.style), str(groom.body), "-o", str(model), *groom.args]
    log(f"{groom.name}: {' '.join(Path(c).name if os.sep in c else c for c in cmd[1:])}")
    code, out, err, seconds = _run(cmd, budget, workdir)
    (workdir / f"{slug}.invert.log").write_text(out + err)
    res["invert_seconds"] = seconds
    if code is None:
        res["status"] = "timed out"
        res["timed_out_in"] = "invert"
        log(f"{groom.name}: invert killed after {seconds:.0f} s")
        return res
    if code != 0:
        res["status"] = "invert failed"
        res["error"] = (err.strip().splitlines() or out.strip().splitlines() or [f"exit {code}"])[-1]
        log(f"{groom.name}: invert exited with {code}: {res['error']}")
        return res
    res.update(parse_invert(out + err))
    res.update(read_model(model))
    if (res["file_within"], res["file_beyond"]) != (res["body"] - res["layer"] - res["file_inside"], res["layer"]):
        log(f"{groom.name}: note: /contacts gaps give {res['file_within']} body contacts within body_distance and "
            f"{res['file_beyond']} beyond, the report {res['body'] - res['layer'] - res['file_inside']} and "
            f"{res['layer']}")
    log(f"{groom.name}: invert {seconds:.1f} s, {res['strands']} strands, {res['declared']} contacts, "
        f"{res['stiffened']} stiffened")
    cmd = [str(HAIRINV), "verify", str(model), str(groom.body), "--seconds", f"{SECONDS:g}", "--tolerance", TOLERANCE,
           "--json"]
    code, out, err, seconds = _run(cmd, budget - res["invert_seconds"], workdir)
    (workdir / f"{slug}.verify.json").write_text(out)
    (workdir / f"{slug}.verify.log").write_text(err)
    res["verify_seconds"] = seconds
    if code is None:
        res["status"] = "timed out"
        res["timed_out_in"] = "verify"
        log(f"{groom.name}: verify killed after {seconds:.0f} s ({res['invert_seconds'] + seconds:.0f} s in all)")
        return res
    try:
        v = json.loads(out)
    except json.JSONDecodeError:
        res["status"] = "verify failed"
        res["error"] = (err.strip().splitlines() or [f"exit {code}"])[-1]
        log(f"{groom.name}: verify exited with {code} without JSON: {res['error']}")
        return res
    res["status"] = "ok"
    res["verify"] = v
    log(f"{groom.name}: verify {seconds:.1f} s: {v['verdict']}, largest {1e3 * v['largest']['displacement_m']:.3g} mm"
        f" at {v['seconds_simulated']:.3g} s, {v['n_moved']} strands moved")
    return res


# ---------------------------------------------------------------------------
# the section


def _f(x, fmt="{:.3g}", none="–"):
    return none if x is None else fmt.format(x)


def _ranges(indices: list[int]) -> str:
    """``[1, 2, 3, 7]`` as ``1-3, 7``."""
    out, run = [], []
    for i in sorted(indices):
        if run and i == run[-1] + 1:
            run.append(i)
        else:
            if run:
                out.append(str(run[0]) if len(run) == 1 else f"{run[0]}-{run[-1]}")
            run = [i]
    if run:
        out.append(str(run[0]) if len(run) == 1 else f"{run[0]}-{run[-1]}")
    return ", ".join(out)


def row(r: dict) -> list[str]:
    name = f"`{r['name']}`" if r["kind"] in ("development", "held out") else r["name"]
    head = [name, r["kind"]]
    if r["status"] != "ok" and "strands" not in r:
        reason = (f"timed out in invert after {r['invert_seconds']:.0f} s" if r["status"] == "timed out" else
                  f"invert failed: {r.get('error', '')}")
        return head + ["–"] * (len(HEADER) - 7) + [reason, "–", "–", "–", "–"]
    within = r["body"] - r["layer"] - r["file_inside"]
    stiffened = f"{r['stiffened']} ({r['factor_median']:.3g} / {r['factor_max']:.3g})" if r["stiffened"] else "0"
    cells = head + [
        str(r["strands"]), str(within), str(r["layer"]), str(r["file_inside"]), f"{r['hair']} ({r['wisp']})",
        str(r["carrying"]), _f(r["layer_gap_median_mm"], "{:.2f}"), stiffened,
        _f(r["gravity_only_factor"], "{:.3g}"), f"{r['solver']} ({r['sweeps']} {r['solver_work']})" if r["solver"] else "–",
        str(r["unstable"]), f"{r['invert_seconds']:.1f}"]
    if r["status"] == "timed out":
        return cells + [f"timed out in verify after {r['verify_seconds']:.0f} s "
                        f"({r['invert_seconds'] + r['verify_seconds']:.0f} s with invert)", "–", "–", "–", "–"]
    if r["status"] != "ok":
        return cells + [f"verify failed: {r.get('error', '')}", "–", "–", "–", f"{r['verify_seconds']:.1f}"]
    v = r["verify"]
    return cells + [v["verdict"], f"{1e3 * v['largest']['displacement_m']:.3g}", f"{v['seconds_simulated']:.3g}",
                    f"{v['n_moved']} of {v['n_strands']}", f"{r['verify_seconds']:.1f}"]


HEADER = ["groom", "set", "strands", "body within body_distance", "body, layer rule", "body, inside",
          "hair-hair (wisp rule)", "carrying force", "layer gap median (mm)", "strands stiffened (factor median / max)",
          "gravity-only factor", "solver stop (interior-point steps or sweeps)", "unstable after invert",
          "invert (s)", "verify", "largest displacement (mm)", "stopped at (s)", "strands moved", "verify (s)"]


def failure_sentence(r: dict) -> str | None:
    """One sentence of facts on a groom verify failed: which strands moved, by how much, when."""
    if r["status"] != "ok" or r["verify"]["verdict"] == "PASS":
        return None
    v = r["verify"]
    moved = v["strands"]
    times = sorted({s["passed_at_s"] for s in moved if s.get("passed_at_s") is not None})
    indices = [s["index"] for s in moved]
    if len(indices) <= LIST_ALL:
        which = f"strand{'s' if len(indices) != 1 else ''} {_ranges(indices)}"
    else:
        which = (f"the {LIST_STRANDS} that moved most: {', '.join(map(str, indices[:LIST_STRANDS]))}, and "
                 f"{len(indices) - LIST_STRANDS} more")
    first = abs(times[0] - 1.0 / v["fps"]) < 1e-9 if times else False
    if len(times) == 1:
        when = (f"{'all ' if len(indices) > 1 else ''}first past it at the check at {times[0]:.3g} s"
                + (" (the first)" if first else ""))
    else:
        when = f"first past it between {times[0]:.3g} s and {times[-1]:.3g} s"
    stop = (f"verify stopped at {v['seconds_simulated']:.3g} s of the {v['seconds_requested']:g} s asked"
            if v["stopped_early"] else f"verify ran the whole {v['seconds_simulated']:.3g} s")
    big = v["largest"]
    return (f"`{r['name']}`: {v['n_moved']} of {v['n_strands']} strands moved more than "
            f"{TOLERANCE.replace('mm', ' mm')} ({which}), {when}, and {stop}; the largest displacement, "
            f"{1e3 * big['displacement_m']:.3g} mm, was strand {big['index']}'s.")


def render(results: list[dict], meta: dict) -> str:
    dev, held = meta["development"], meta["held_out"]
    held_all = list(HELD_OUT)
    kinds = {r["kind"] for r in results}
    if meta.get("quick"):
        grooms = (f"The grooms (a smoke run): {QUICK_GUIDES} guide strands (`--guides {QUICK_GUIDES}`) of the "
                  f"generated `{QUICK_VARIANT}` of `bench/grooms.py` over its mannequin.")
    else:
        held_text = ", ".join(f"`{n}`" for n in held)
        if len(held) < len(held_all):
            held_text += (f"; {len(held)} of the {len(held_all)}, not run: "
                          + ", ".join(f"`{n}`" for n in held_all if n not in held))
        parts = [f"the generated kinds of `bench/grooms.py` over its mannequin (draped, curly, mohawk, updo, "
                 f"inside), the development variants ({', '.join(f'`{n}`' for n in dev)}) and the held-out ones "
                 f"({held_text}), kept out of the tuning"]
        if "real" in kinds:
            parts.append("the real grooms sintel (`--scale 0.008`), ruby short and ruby long (1,867 and 3,000 "
                         "guides, `--scale 0.002`) and two parts of the TressFX ponytail groom, its bangs (`hair_front`, "
                         "93 strands, `--scale 0.0025`) and its tail (the TressFX 3 `tail.tfx`, 255 strands, "
                         "`--scale 0.0025 --flip z`), on their own meshes")
        if "sample" in kinds:
            parts.append("the samples `settled.h5` (with `--target zero`, the paper's controlled validation: hair "
                         "settled by the simulator from a straight rest shape) and `settled_curly.h5` on "
                         "`samples/body.obj`")
        grooms = "The grooms: " + "; ".join(parts) + "."
    lines = [f"## {TITLE}", "",
             "`bench/still_bench.py`. The promise measured: invert a groom with the default settings, then the "
             "still scene (the body still, the inverted rest shape) does not move it. Each groom is run through "
             "the command line as a user would, each command in its own process: "
             "`hairinv invert STYLE BODY -o model.h5` (only the options a file needs: `--scale` for the real "
             "grooms, `--target zero` for the controlled validation), then "
             f"`hairinv verify model.h5 BODY --seconds {SECONDS:g} --tolerance {TOLERANCE} --json`, which passes if "
             f"no strand point moves more than 0.1 mm from where it started within {SECONDS:g} s and stops at the "
             "first check (30 per second) past it. " + grooms + " A groom whose two commands together run past "
             f"{GROOM_BUDGET / 60:.0f} min is killed and recorded as timed out. Single runs"
             + ("" if meta.get("quick") else
                f", after a warm-up (invert and verify of {QUICK_GUIDES} mohawk guides, not reported) that fills "
                "the compiled-code cache")
             + "; wall clock of the whole subprocess, start-up included.", "",
             machine_markdown(meta["machine"]), "",
             table(HEADER, [row(r) for r in results]), "",
             "Contacts are those declared by `detect` (in invert): on the body within `body_distance` "
             f"({meta['body_distance_mm']:g} mm), beyond it by the layer rule (the report's \"hair layer:\" line), "
             "inside the body (the body contacts of `/contacts` with a negative gap), and hair-hair, of which the "
             "wisp rule declared those in the \"wisps:\" line (in brackets). \"Carrying force\" counts the contacts invert "
             "reports as carrying force; \"layer gap median\" is the report's median gap of the runs along the "
             "body that declared layer contacts. \"Strands stiffened\" and the factors are read from "
             "`/model/stiffening` (factors above 1); the gravity-only factor is the one invert quotes for making "
             "the whole groom stable without contacts (1: no strand of the gravity-only inversion is unstable). "
             "\"Unstable after invert\" is the count of invert's warning (0: every strand checked stable). "
             "\"Stopped at\" is the simulated time of the last check done; \"strands moved\" counts the strands "
             "past 0.1 mm by then (strand indices below are 0-based, as in `/helices`).", ""]
    for r in results:
        if r["kind"] == "sample" and r["status"] != "invert failed" and "q0_mean" in r and "zero" in r["args"]:
            lines += [f"Controlled validation (`settled.h5`, target zero): the mean |q0| over its {r['elements']} "
                      f"elements (`/model/{r['rest_name']}`; the truth is 0) is {r['q0_mean']:.3g} 1/m "
                      f"(weighted by element length: {r['q0_mean_length_weighted']:.3g} 1/m).", ""]
    failing = [s for s in (failure_sentence(r) for r in results) if s]
    other = [r for r in results if r["status"] != "ok"]
    if failing or other:
        lines += ["Failing grooms:", ""]
        lines += [f"- {s}" for s in failing]
        for r in other:
            if r["status"] == "timed out":
                lines.append(f"- `{r['name']}`: killed in {r['timed_out_in']} after "
                             f"{r['invert_seconds'] + r.get('verify_seconds', 0.0):.0f} s in all.")
            else:
                lines.append(f"- `{r['name']}`: {r['status']}: {r.get('error', '')}")
        lines.append("")
    passed = sum(1 for r in results if r["status"] == "ok" and r["verify"]["verdict"] == "PASS")
    generated = len(dev) + len(held)
    lines += [f"{passed} of {len(results)} grooms passed. Generating the {generated} groom{'s' if generated != 1 else ''} "
              f"took {meta['generate_seconds']:.0f} s; the whole benchmark {meta['seconds'] / 60:.1f} min.", ""]
    return "\n".join(lines)


def grooms_for(outdir: Path, quick: bool = False, held_out: int | None = HELD_OUT_RUN) -> tuple[list[Groom], dict]:
    """The grooms to run (generating the generated ones into ``outdir``) and what the section says of them."""
    if quick:
        names = [QUICK_VARIANT]
        meta = {"development": names, "held_out": []}
        gen = generate(outdir, names)
        grooms = [Groom(QUICK_VARIANT, "development", outdir / f"{QUICK_VARIANT}.h5", outdir / "mannequin.obj",
                        ["--guides", str(QUICK_GUIDES)])]
    else:
        dev, held = generated_names(held_out)
        meta = {"development": dev, "held_out": held}
        gen = generate(outdir, dev + held)
        grooms = [Groom(n, "development" if n in DEVELOPMENT else "held out", outdir / f"{n}.h5",
                        outdir / "mannequin.obj") for n in dev + held]
        grooms += real_grooms() + sample_grooms()
    meta["generate_seconds"] = gen
    return grooms, meta


def code_state() -> dict:
    """The commit and the state of the library's files (hairinv/, cli/): a run is of one version only if
    this is the same at its start and its end."""
    def git(*args):
        try:
            return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, check=True).stdout.strip()
        except (OSError, subprocess.CalledProcessError):
            return None
    files = sorted(p for d in ("hairinv", "cli") for p in (ROOT / d).rglob("*.py"))
    return {"commit": git("rev-parse", "HEAD"), "changed": git("status", "--porcelain", "--", "hairinv", "cli"),
            "newest_mtime": max((p.stat().st_mtime for p in files), default=0.0)}


def measure(quick: bool = False, workdir: Path | None = None,
            held_out: int | None = HELD_OUT_RUN) -> tuple[list[dict], dict]:
    """Every groom's figures (``measure_groom``) and what the section says of the run."""
    start = time.perf_counter()
    info = machine()
    code_start = code_state()
    if workdir is None:
        workdir = WORK
    grooms, meta = grooms_for(workdir, quick, held_out)
    log(f"generated grooms in {meta['generate_seconds']:.0f} s; {len(grooms)} grooms to run")
    meta["quick"] = quick
    if not quick:
        warm = Groom(f"warm-up {QUICK_VARIANT}", "warm-up", workdir / f"{QUICK_VARIANT}.h5", workdir / "mannequin.obj",
                     ["--guides", str(QUICK_GUIDES)])
        if not (workdir / f"{QUICK_VARIANT}.h5").exists():
            generate(workdir, [QUICK_VARIANT])
        meta["warm_up"] = measure_groom(warm, workdir / "warm_up")
    results = [measure_groom(g, workdir) for g in grooms]
    meta["machine"] = info
    meta["body_distance_mm"] = next((r["body_distance_mm"] for r in results if "body_distance_mm" in r), 4.0)
    meta["seconds"] = time.perf_counter() - start
    meta["code"] = {"start": code_start, "end": code_state()}
    if meta["code"]["start"] != meta["code"]["end"]:
        log("warning: the library (hairinv/, cli/) changed during the run: the grooms were not all run on one version")
    (workdir / "results.json").write_text(json.dumps({"meta": {k: v for k, v in meta.items()}, "results": results},
                                                     indent=1, default=str))
    return results, meta


def run(quick: bool = SMOKE) -> str:
    if quick:
        with tempfile.TemporaryDirectory(prefix="still_bench_") as folder:
            results, meta = measure(quick=True, workdir=Path(folder))
    else:
        results, meta = measure()
    return render(results, meta)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", default=SMOKE,
                        help=f"smoke run: {QUICK_GUIDES} guides of the generated {QUICK_VARIANT} only")
    args = parser.parse_args(argv)
    print(run(quick=args.quick))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
