"""Benchmark: what fewer (or more) contacts change, on a dense head and on guides.

Run alone with ``python bench/contact_budget_bench.py`` (prints the markdown section),
or through ``bench/run.py``, which writes ``docs/benchmarks.md``.

Contacts are the inversion's cost: its time per sweep grows with them, and so
does the simulation's. Before any are cut, this measures what cutting them
changes. Two heads from ``bench/full_head.py``: a dense one (250 guides of
ruby, each with 3 follow hairs within 3 mm: 1,000 strands) and the 1,000
guides alone (as sparse as the paper's). Each is fitted once; then, for each
contact rule's setting, ``hairinv detect``, ``hairinv invert`` (default
settings) and ``hairinv verify`` (a still body, 0.2 s, every strand's largest
displacement) run as a user runs them. Reported: the contacts declared, the
time of detect and invert, the solver's status, how far the rest shape lies
from the default's (rms over elements, 1/m; for scale, the default solver's
own distance from the exact optimum is 0.035-0.047 1/m, "Speed against
accuracy"), and what the still check measures: the largest displacement of any
strand and the mean over strands.
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
    from common import WORK, log, smoke, table  # type: ignore
    import full_head  # type: ignore
    from full_head_bench import HAIRINV, spawn  # type: ignore
else:
    from . import full_head
    from .common import WORK, log, smoke, table
    from .full_head_bench import HAIRINV, spawn

TITLE = "What the contacts buy: fewer or more, on a dense head and on guides"
BODY = ["--body-scale", str(full_head.SCALE)]
# (label, --set overrides); the first is the reference
VARIANTS = [
    ("default (8 per element, hair 1 mm, body 4 mm)", []),
    ("max_hair_per_element 4", ["contacts.max_hair_per_element=4"]),
    ("max_hair_per_element 2", ["contacts.max_hair_per_element=2"]),
    ("max_hair_per_element 1", ["contacts.max_hair_per_element=1"]),
    ("hair_distance 0.5 mm", ["contacts.hair_distance=5e-4"]),
    ("hair_distance 2 mm", ["contacts.hair_distance=2e-3"]),
    ("body_distance 2 mm", ["contacts.body_distance=2e-3"]),
    ("body_distance 8 mm", ["contacts.body_distance=8e-3"]),
    ("samples_per_element 4", ["contacts.samples_per_element=4"]),
]
VARIANTS = smoke(VARIANTS, VARIANTS[:2])
# (label, strands, guides kept first: 0 = the strands are guides)
HEADS = smoke([("dense: 250 guides + 3 follow hairs each", 1000, 250), ("guides alone", 1000, 0)],
              [("dense", 40, 10)])
VERIFY = ["--seconds", str(smoke(0.2, 0.02)), "--full"]


def _sets(overrides: list[str]) -> list[str]:
    return [arg for o in overrides for arg in ("--set", o)]


def _run(args: list[str]) -> dict:
    r = spawn(args)
    if r["code"] not in (0, 1):
        raise RuntimeError(f"hairinv {args[0]} exited {r['code']}: {r['stderr'].strip()[-400:]}")
    return r


def variant(fit: Path, tag: str, label: str, overrides: list[str]) -> dict:
    contacts, model, frames = (fit.with_name(f"{tag}.{s}.h5") for s in ("contacts", "model", "frames"))
    head = str(full_head.HEAD)
    detect = _run(["detect", str(fit), head, *BODY, "-o", str(contacts), *_sets(overrides)])
    invert = _run(["invert", str(contacts), head, *BODY, "-o", str(model), *_sets(overrides)])
    verify = _run(["verify", str(model), *VERIFY, "-o", str(frames)])
    summary = json.loads(subprocess.run([HAIRINV, "info", "--json", str(model)], capture_output=True, text=True,
                                        check=True).stdout)["groups"]
    with h5py.File(model, "r") as fh:
        rest = fh["model/omega_rest"][()]
    with h5py.File(frames, "r") as fh:
        moved = fh["frames/strand_displacement"][()].max(axis=0)
    return {"label": label, "detect": detect["wall"], "invert": invert["wall"],
            "body": int(summary["contacts"]["hair_body"]), "hair": int(summary["contacts"]["hair_hair"]),
            "carrying": int(summary["contacts"]["carrying_force"]), "status": summary["model"]["status"],
            "sweeps": int(summary["model"]["sweeps"]), "solve": float(summary["model"]["solve_seconds"]),
            "stiffened": int(summary["model"]["strands_stiffened"]), "rest": rest,
            "largest": float(moved.max()), "mean": float(moved.mean()), "passed": verify["code"] == 0}


def run() -> str:
    work = WORK / "contact_budget"
    work.mkdir(parents=True, exist_ok=True)
    base = full_head.guides()
    started = time.perf_counter()
    parts = []
    for head_label, n, guides in HEADS:
        groom = full_head.write(n, work / f"head{n}_{guides}.h5", base=base, guide_count=guides)
        fit = work / f"head{n}_{guides}.fit.h5"
        _run(["fit", str(groom), "-o", str(fit)])
        rows = []
        for k, (label, overrides) in enumerate(VARIANTS):
            log(f"{head_label}: {label}")
            rows.append(variant(fit, f"head{n}_{guides}.v{k}", label, overrides))
        ref = rows[0]
        lines = []
        for r in rows:
            same = r["rest"].shape == ref["rest"].shape
            drift = float(np.sqrt(np.mean((r["rest"] - ref["rest"]) ** 2))) if same else float("nan")
            lines.append([r["label"], f"{r['body']:,} / {r['hair']:,}", f"{r['carrying']:,}",
                          f"{r['detect']:.1f}", f"{r['invert']:.1f} ({r['solve']:.1f})", f"{r['sweeps']} {r['status']}",
                          "reference" if r is ref else f"{drift:.3f}", f"{r['stiffened']}",
                          f"{1e3 * r['largest']:.2g}", f"{1e3 * r['mean']:.2g}", "pass" if r["passed"] else "FAIL"])
        parts += [f"**{head_label}** ({n:,} strands):", "",
                  table(["contacts", "declared body / hair", "carrying force", "detect (s)", "invert (solver) (s)",
                         "sweeps, status", "rest shape from the default's, rms 1/m", "strands stiffened",
                         "still body: largest displacement (mm)", "mean over strands (mm)", "verify"], lines), ""]
    return "\n".join([
        f"## {TITLE}",
        "",
        "`bench/contact_budget_bench.py`: each contact rule's setting on two heads of `bench/full_head.py`, "
        "each a chain of hairinv commands as a user runs them: `detect` and `invert` (default settings, "
        "`--body-scale 0.002` for ruby's head), then `verify` on a still body for "
        f"{VERIFY[1]} s (`--full`: every strand's largest displacement, over all frames). The rest shape's "
        "distance from the default's is the rms over elements of the difference of `/model/omega_rest`; the "
        "default solver itself stops 0.035-0.047 1/m from the exact optimum (\"Speed against accuracy\"), so "
        "differences of that size are the solver's, not the contacts'. The still check passes at 0.1 mm.",
        "",
        *parts,
        f"This section took {(time.perf_counter() - started) / 60:.1f} min.",
        "",
    ])


if __name__ == "__main__":
    print(run())
