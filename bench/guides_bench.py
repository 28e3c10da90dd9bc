"""Benchmark: inverting a subset of guide strands instead of the whole groom.

Run alone with ``python bench/guides_bench.py`` (prints the markdown section),
or through ``bench/run.py``, which writes ``docs/benchmarks.md``.

A groom's strands hold each other up: a strand inverted among fewer neighbours
rests on fewer hair-hair contacts, so its rest shape carries more of its weight
itself. ``import.guides`` (``--guides N``) keeps N strands spread over the scalp.
For each groom, ``hairinv invert STYLE BODY --guides N`` runs as a user runs it
(fit, detect and invert in one command, default settings), for the whole groom
and for subsets. Each subset strand is matched to the same strand of the whole
groom by its root (the fit of a strand does not depend on the others: the
same elements, bit for bit), and reported is how far its rest shape lies from
the whole groom's (rms over the subset's elements, 1/m), next to how far the
whole groom's rest shape lies from the input shape on the same strands (what
the inversion changes at all) and the default solver's own distance from the
exact optimum (0.035-0.047 1/m, "Speed against accuracy").
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from common import DATA, ROOT, WORK, log, smoke, table  # type: ignore
    from full_head_bench import HAIRINV, spawn  # type: ignore
else:
    from .common import DATA, ROOT, WORK, log, smoke, table
    from .full_head_bench import HAIRINV, spawn

TITLE = "Guides: what inverting a subset changes"
SAMPLES = ROOT / "samples"
# (label, style, body, extra arguments, guide counts; 0: every strand)
GROOMS = smoke(
    [("ruby short (1,867 strands)", DATA / "ruby" / "ruby_short_hair_16_guide.tfx", DATA / "ruby" / "ruby_head.obj",
      ["--body-scale", "0.002"], (0, 1000, 500, 250, 125)),
     ("wavy sample (280 strands)", SAMPLES / "wavy.h5", SAMPLES / "body.obj", [], (0, 140, 70, 35))],
    [("wavy sample, 40 guides as the reference", SAMPLES / "wavy.h5", SAMPLES / "body.obj", [], (40, 20))])


def invert_guides(style: Path, body: Path, extra: list[str], guides: int, out: Path) -> dict:
    """One ``hairinv invert`` run; what it wrote, and its wall time and peak memory."""
    out.unlink(missing_ok=True)
    run = spawn(["invert", str(style), str(body), *extra, "--guides", str(guides), "-o", str(out)])
    if run["code"] != 0:
        raise RuntimeError(f"hairinv invert --guides {guides} failed: {run['stderr'][-500:]}")
    summary = json.loads(subprocess.run([HAIRINV, "info", "--json", str(out)], capture_output=True, text=True,
                                        check=True).stdout)["groups"]
    with h5py.File(out, "r") as fh:
        model = {k: fh[f"helices/{k}"][()] for k in ("root", "offsets", "omega", "length")}
        model["rest"] = fh["model/omega_rest"][()]
        model["used"] = fh["model/omega_rest_stiffened"][()] if "omega_rest_stiffened" in fh["model"] else model["rest"]
    hair = int(summary["contacts"]["hair_hair"])
    return {**model, "wall": run["wall"], "peak": run["rss"], "strands": len(model["root"]),
            "body": int(summary["contacts"]["hair_body"]), "hair": hair, "status": summary["model"]["status"],
            "solve": float(summary["model"]["solve_seconds"]), "stiffened": int(summary["model"]["strands_stiffened"] or 0)}


def compare(sub: dict, full: dict, rest: str = "rest") -> dict:
    """The subset's strands against the same strands of the whole groom (matched by root): their rest shapes
    ``rest`` (``"rest"``: the material's, ``"used"``: the stiffened strands' own)."""
    where = {tuple(r): k for k, r in enumerate(full["root"])}
    diff, change, matched, same_fit = [], [], 0, 0
    for k, root in enumerate(sub["root"]):
        j = where.get(tuple(root))
        if j is None:
            continue
        a, b = slice(sub["offsets"][k], sub["offsets"][k + 1]), slice(full["offsets"][j], full["offsets"][j + 1])
        matched += 1
        if sub["omega"][a].shape != full["omega"][b].shape or not np.array_equal(sub["omega"][a], full["omega"][b]):
            continue
        same_fit += 1
        diff.append(sub[rest][a] - full[rest][b])
        change.append(full[rest][b] - full["omega"][b])
    rms = (lambda parts: float(np.sqrt(np.mean(np.concatenate(parts) ** 2))) if parts else float("nan"))
    return {"matched": matched, "same_fit": same_fit, "from_full": rms(diff), "full_change": rms(change)}


def run() -> str:
    work = WORK / "guides"
    work.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    parts = []
    for label, style, body, extra, counts in GROOMS:
        if not style.exists() or not body.exists():
            log(f"guides: {style} not found, skipped")
            continue
        runs = []
        for guides in counts:
            log(f"guides: {label}, --guides {guides}")
            runs.append(invert_guides(style, body, extra, guides, work / f"{style.stem}.g{guides}.h5"))
        full = runs[0]
        lines = []
        for r in runs:
            c = compare(r, full)
            c_used = compare(r, full, "used")
            lines.append([f"{r['strands']:,}" + (" (reference)" if r is full else ""), f"{r['body']:,} / {r['hair']:,}",
                          f"{r['hair'] / r['strands']:.1f}", f"{r['wall']:.1f}", f"{r['solve']:.1f}", r["status"],
                          f"{r['peak'] / 2**30:.2f}", f"{r['stiffened']}",
                          "reference" if r is full else f"{c['same_fit']} of {r['strands']}",
                          "" if r is full else f"{c['from_full']:.3f}", f"{c['full_change']:.3f}",
                          "" if r is full else f"{c_used['from_full']:.3f}", f"{c_used['full_change']:.3f}"])
        parts += [f"**{label}**:", "",
                  table(["strands inverted", "contacts body / hair", "hair-hair per strand", "invert (s)",
                         "solver (s)", "status", "peak GiB", "strands stiffened", "strands compared",
                         "rest shape from the whole groom's, rms 1/m", "whole groom: rest shape from the input, rms 1/m",
                         "as simulated (stiffened strands' own): from the whole groom's",
                         "as simulated: whole groom from the input"],
                        lines), ""]
    return "\n".join([
        f"## {TITLE}",
        "",
        "`bench/guides_bench.py`: `hairinv invert STYLE BODY --guides N` (fit, detect and invert in one command, "
        "default settings) for the whole groom and for subsets spread over the scalp, each once in its own process "
        "(time: the command's wall time, starting Python included; memory: its peak resident size). Each subset "
        "strand is matched to the same strand of the whole groom by its root; those whose fit is the same (all "
        "here) are compared: the rms over their elements of the difference of their rest shapes (1/m; "
        "`/model/omega_rest`, the rest shape under the material's own stiffness), next to how far the whole "
        "groom's rest shape lies from the input shape on the same strands (what the inversion changes at all). "
        "For scale, the default solver stops 0.035-0.047 1/m from the "
        "exact optimum (\"Speed against accuracy\"), and the paper's whole validation error is 0.9 1/m. A still "
        "body holds any of these inputs exactly: what a subset changes is how its strands carry their weight "
        "once the hair moves (fewer neighbours: fewer hair-hair contacts per strand, more weight in the rest shape). "
        "The last two columns compare the rest shapes a simulation uses: a stiffened strand's own "
        "(`/model/omega_rest_stiffened`, taken again under its stiffer material), so they add what stiffening "
        "changes, strand by strand, to the contacts' share.",
        "",
        *parts,
        f"This section took {(time.perf_counter() - started) / 60:.1f} min.",
    ])


if __name__ == "__main__":
    print(run())
