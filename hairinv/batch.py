"""``hairinv batch``: many grooms, each one task on a Dask cluster (docs/batch.md).

A manifest (TOML) lists the grooms: hair file, body file, their units and axes, settings overrides and
options, and what to make of each (``invert``, ``verify``, exports). Each groom is one task: it runs the
``hairinv`` commands a user would type, on the worker, with its own log, and returns one row of the
summary. Shots (``[[shot]]``: a groom's model simulated under an animated body) are tasks of their own, each
started once its groom's model is made. The cluster is a :class:`distributed.LocalCluster` on the loopback interface by default, or the
scheduler at an address given (with TLS when certificates are given). A groom that fails is reported
with its message and never stops the others.

Resumable: the inversion runs with ``--if-stale``, an export is made again only when the model it was
made from changed (by SHA-256), and a verification is kept while the model it checked is unchanged (by SHA-256), so a second run
of the same manifest redoes only what changed.
"""

from __future__ import annotations

import json
import logging
import os
import shlex
import subprocess
import sys
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from . import stages
from .atomic import write_bytes
from .errors import InputError

#: What a groom may ask for: the model, its still check, and exports by suffix.
STAGES = ("invert", "verify", "export")
EXPORT_SUFFIXES = ("usda", "usdc", "usd", "hair", "data", "obj", "json", "png", "html")
_GROOM_KEYS = {"name", "hair", "body", "units", "scale", "up", "flip", "body_units", "body_scale", "body_up",
               "body_flip", "bind_time", "guides", "quality", "set", "options", "stages", "exports", "verify_seconds"}
_SHOT_KEYS = {"name", "groom", "body", "seconds", "fps", "preroll", "options", "exports"}
#: What a shot's frames may be exported to.
SHOT_EXPORTS = ("usda", "usdc", "usd", "png", "gif", "html", "json")
#: How long to wait for a scheduler given by address.
CONNECT_TIMEOUT = "20s"
_OPTION_OF = {"units": "--units", "scale": "--scale", "up": "--up", "flip": "--flip", "body_units": "--body-units",
              "body_scale": "--body-scale", "body_up": "--body-up", "body_flip": "--body-flip",
              "bind_time": "--bind-time",
              "guides": "--guides", "quality": "--quality"}


@dataclass
class BatchItem:
    """One groom of a manifest (a ``[[groom]]`` table), its paths resolved against the manifest's folder."""

    name: str
    hair: str
    body: str | None = None
    options: list[str] = field(default_factory=list)
    """command-line options of ``hairinv invert`` (units, axes, guides, quality, --set ...)"""
    stages: list[str] = field(default_factory=lambda: ["invert", "verify"])
    exports: list[str] = field(default_factory=list)
    verify_seconds: float | None = None


@dataclass
class ShotItem:
    """One shot of a manifest (a ``[[shot]]`` table): a groom's model simulated under an animated body."""

    name: str
    groom: str
    """the name of the ``[[groom]]`` whose model it simulates"""
    body: str
    options: list[str] = field(default_factory=list)
    """command-line options of ``hairinv simulate`` (--seconds, --fps, --preroll, ...)"""
    exports: list[str] = field(default_factory=list)


def read_manifest(path) -> tuple[list[BatchItem], dict]:
    """The grooms of a manifest and its ``[tls]`` table (empty when absent).

    Raises
    ------
    InputError
        Not TOML, no grooms, an unknown key, a missing hair file, two grooms of one name.
    """
    grooms, _, tls = read_manifest_shots(path)
    return grooms, tls


def read_manifest_shots(path) -> tuple[list[BatchItem], list[ShotItem], dict]:
    """The grooms and shots of a manifest and its ``[tls]`` table (empty when absent).

    Raises
    ------
    InputError
        Not TOML, no grooms, an unknown key, a missing hair file, two grooms or shots of one name, a shot of a
        groom the manifest does not list, a shot's missing body file.
    """
    path = Path(path)
    if not path.exists():
        raise InputError("no such file", path)
    try:
        data = tomllib.loads(path.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"is not valid TOML ({exc})", path) from None
    unknown = set(data) - {"defaults", "groom", "shot", "tls"}
    if unknown:
        raise InputError(f"has unknown table(s) {', '.join(sorted(unknown))}; known: defaults, groom, shot, tls",
                         path)
    defaults = data.get("defaults", {})
    entries = data.get("groom", [])
    if not isinstance(entries, list) or not entries:
        raise InputError("lists no grooms: add [[groom]] tables with name, hair and body", path)
    grooms, seen = [], set()
    for k, entry in enumerate(entries, 1):
        merged = {**defaults, **entry, "set": {**defaults.get("set", {}), **entry.get("set", {})}}
        name = _entry_name("groom", k, merged, _GROOM_KEYS, seen, path)
        if "hair" not in merged:
            raise InputError(f"groom {name!r}: needs a hair file", path)
        hair = (path.parent / merged["hair"]).resolve()
        body = (path.parent / merged["body"]).resolve() if merged.get("body") else None
        options = []
        for key, flag in _OPTION_OF.items():
            if key in merged:
                options += [flag, str(merged[key])]
        for key, value in merged["set"].items():
            options += ["--set", f"{key}={str(value).lower() if isinstance(value, bool) else value}"]
        options += [str(o) for o in merged.get("options", [])]
        wanted = list(merged.get("stages", ["invert", "verify"]))
        if not set(wanted) <= set(STAGES) or "invert" not in wanted:
            raise InputError(f"groom {name!r}: stages must include invert and be among {', '.join(STAGES)}", path)
        exports = [str(e).lstrip(".").lower() for e in merged.get("exports", [])]
        bad_exports = [e for e in exports if e not in EXPORT_SUFFIXES]
        if bad_exports:
            raise InputError(f"groom {name!r}: unknown export(s) {', '.join(bad_exports)}; known: "
                             f"{', '.join(EXPORT_SUFFIXES)}", path)
        if exports and "export" not in wanted:
            wanted.append("export")
        grooms.append(BatchItem(name, str(hair), None if body is None else str(body), options, wanted, exports,
                                merged.get("verify_seconds")))
    return grooms, _read_shots(data.get("shot", []), {g.name for g in grooms}, seen, path), data.get("tls", {})


def _entry_name(kind: str, k: int, table: dict, known: set, taken: set, path: Path) -> str:
    """The name of the ``k``-th ``[[kind]]`` table, refused if it has unknown keys or a name that is not a file
    name or is taken already (grooms and shots share the output's file names); added to ``taken``."""
    bad = set(table) - known
    if bad:
        raise InputError(f"{kind} {k}: unknown key(s) {', '.join(sorted(bad))}; known: {', '.join(sorted(known))}",
                         path)
    name = str(table.get("name", ""))
    if not name or "/" in name or name.startswith("."):
        raise InputError(f"{kind} {k}: needs a name usable as a file name, got {name!r}", path)
    if name in taken:
        raise InputError(f"{kind} {k}: the name {name!r} is used twice (grooms and shots name the output's files)",
                         path)
    taken.add(name)
    return name


def _read_shots(entries, groom_names: set, taken: set, path: Path) -> list[ShotItem]:
    """The ``[[shot]]`` tables: each a name, the groom it simulates and an animated body file."""
    if not isinstance(entries, list):
        raise InputError("has a shot table that is not a list: write [[shot]] tables", path)
    shots = []
    for k, entry in enumerate(entries, 1):
        if not isinstance(entry, dict):
            raise InputError(f"shot {k}: is not a table", path)
        name = _entry_name("shot", k, entry, _SHOT_KEYS, taken, path)
        groom = str(entry.get("groom", ""))
        if groom not in groom_names:
            raise InputError(f"shot {name!r}: names groom {groom!r}, which the manifest does not list "
                             f"(grooms: {', '.join(sorted(groom_names))})", path)
        if not entry.get("body"):
            raise InputError(f"shot {name!r}: needs a body file (the animated body)", path)
        body = (path.parent / str(entry["body"])).resolve()
        if not (body.exists() or "#" in body.name):
            raise InputError(f"shot {name!r}: its body {entry['body']} does not exist", path)
        options = []
        for key in ("seconds", "fps", "preroll"):
            if key in entry:
                value = entry[key]
                if isinstance(value, bool) or not isinstance(value, (int, float)):
                    raise InputError(f"shot {name!r}: {key} must be a number, got {value!r}", path)
                options += [f"--{key}", str(value)]
        options += [str(o) for o in entry.get("options", [])]
        exports = [str(e).lstrip(".").lower() for e in entry.get("exports", [])]
        bad_exports = [e for e in exports if e not in SHOT_EXPORTS]
        if bad_exports:
            raise InputError(f"shot {name!r}: unknown export(s) {', '.join(bad_exports)}; a shot exports to "
                             f"{', '.join(SHOT_EXPORTS)}", path)
        shots.append(ShotItem(name, groom, str(body), options, exports))
    return shots


def _hairinv() -> list[str]:
    return [sys.executable, "-m", "hairinv_cli.main"]


def _env(threads: int) -> dict:
    """The environment of a task's commands: its share of the cores for hairinv, numba and BLAS."""
    return {**os.environ, "HAIRINV_THREADS": str(threads), "OMP_NUM_THREADS": str(threads),
            "OPENBLAS_NUM_THREADS": str(threads), "MKL_NUM_THREADS": str(threads), "NUMBA_NUM_THREADS": str(threads)}


def _runner(log, env: dict):
    """``run(args)``: ``hairinv args`` as a subprocess, the command, its output and exit code written to ``log``."""

    def run(args: list[str]) -> subprocess.CompletedProcess:
        log.write(f"$ hairinv {shlex.join(args)}\n")
        log.flush()
        result = subprocess.run(_hairinv() + args, env=env, capture_output=True, text=True)
        log.write(result.stdout + result.stderr + f"(exit {result.returncode})\n\n")
        log.flush()
        return result

    return run


def _failed(row: dict, result: subprocess.CompletedProcess, what: str) -> dict:
    """``row`` marked failed with the last line the command printed."""
    lines = (result.stderr or result.stdout).strip().splitlines()
    row.update(status="failed", message=f"{what}: {lines[-1] if lines else f'exit {result.returncode}'}")
    return row


def _export_all(name: str, source: Path, suffixes: list[str], out: Path, run, row: dict) -> bool:
    """Each export ``out/<name>.<suffix>`` of ``source``, kept while ``source`` is unchanged (its SHA-256 is
    recorded in ``<name>.exports.json``); False, with ``row`` failed, when one fails."""
    made_path = out / f"{name}.exports.json"
    made = json.loads(made_path.read_text()) if made_path.exists() else {}
    digest = stages.sha256_file(source)
    for suffix in suffixes:
        target = out / f"{name}.{suffix}"
        if target.exists() and made.get(suffix) == digest:
            row["skipped"].append(f"export {suffix}")
            continue
        result = run(["export", str(source), "-o", str(target)])
        if result.returncode != 0:
            _failed(row, result, f"export {suffix}")
            return False
        made[suffix] = digest
        write_bytes(made_path, json.dumps(made, indent=2).encode())
    return True


def run_groom(groom: BatchItem, outdir: str, threads: int) -> dict:
    """One groom's commands, run where this task runs; the summary row. Never raises: a failure is a row."""
    out = Path(outdir)
    log_path = out / f"{groom.name}.log"
    model = out / f"{groom.name}.model.h5"
    row = {"groom": groom.name, "status": "ok", "seconds": 0.0, "strands": None, "contacts": None,
           "solver": None, "verify": None, "message": "", "log": str(log_path), "model": str(model), "skipped": []}
    started = time.perf_counter()
    with open(log_path, "w") as log:
        run = _runner(log, _env(threads))
        try:
            args = ["invert", groom.hair] + ([groom.body] if groom.body else []) + ["-o", str(model), "--if-stale",
                                                                                  *groom.options]
            result = run(args)
            if result.returncode != 0:
                return _failed(row, result, "invert")
            if "is current" in result.stdout:
                row["skipped"].append("invert")
            _describe(model, row)
            if "verify" in groom.stages:
                verify_row(groom, model, out, run, row)
            if groom.exports:
                _export_all(groom.name, model, groom.exports, out, run, row)
        except Exception as exc:  # a task must report, not raise: the others go on
            row.update(status="failed", message=f"{type(exc).__name__}: {exc}")
        finally:
            row["seconds"] = time.perf_counter() - started
    return row


def run_shot(shot: ShotItem, outdir: str, threads: int, groom_row: dict) -> dict:
    """One shot's commands (``simulate`` of its groom's model, then its exports), run where this task runs, once
    its groom's task has made the model (``groom_row``); the summary row. Never raises: a failure is a row."""
    out = Path(outdir)
    log_path = out / f"{shot.name}.log"
    frames = out / f"{shot.name}.frames.h5"
    row = {"groom": shot.name, "status": "ok", "seconds": 0.0, "strands": groom_row.get("strands"), "contacts": None,
           "solver": None, "verify": None, "message": "", "log": str(log_path), "model": str(frames), "skipped": [],
           "shot_of": shot.groom}
    if groom_row.get("status") != "ok":
        row.update(status="failed", message=f"its groom {shot.groom} failed")
        return row
    started = time.perf_counter()
    with open(log_path, "w") as log:
        run = _runner(log, _env(threads))
        try:
            result = run(["simulate", groom_row["model"], shot.body, "-o", str(frames), "--if-stale", *shot.options])
            if result.returncode != 0:
                return _failed(row, result, "simulate")
            if "is current" in result.stdout:
                row["skipped"].append("simulate")
            if not _export_all(shot.name, frames, shot.exports, out, run, row):
                return row
            stage = stages.read_stage(frames)
            row["contacts"] = int(stage[stages.FRAMES]["contact_count"][-1]) \
                if "contact_count" in stage[stages.FRAMES].datasets else None
            row["solver"] = f"{len(stage[stages.FRAMES]['time'])} frames"
        except Exception as exc:  # a task must report, not raise: the others go on
            row.update(status="failed", message=f"{type(exc).__name__}: {exc}")
        finally:
            row["seconds"] = time.perf_counter() - started
    return row


def _describe(model: Path, row: dict) -> None:
    stage = stages.read_stage(model)
    row["strands"] = int(len(stage[stages.HELICES]["root"]))
    row["contacts"] = int(len(stage[stages.CONTACTS]["mu"])) if stages.CONTACTS in stage else 0
    row["solver"] = str(stage[stages.MODEL].attrs.get("status", ""))


def verify_row(groom: BatchItem, model: Path, out: Path, run, row: dict) -> None:
    """``hairinv verify`` of the model, kept in ``<name>.verify.json`` while the model is unchanged."""
    record = out / f"{groom.name}.verify.json"
    digest = stages.sha256_file(model)
    if record.exists():
        try:
            kept = json.loads(record.read_text())
        except json.JSONDecodeError:
            kept = {}
        if kept.get("model_sha256") == digest and kept.get("verify_seconds") == groom.verify_seconds:
            row["verify"] = kept["verdict"]
            row["skipped"].append("verify")
            return
    args = ["verify", str(model), "--json"] + (["--seconds", str(groom.verify_seconds)] if groom.verify_seconds
                                               else [])
    result = run(args)
    if result.returncode not in (0, 1):
        lines = result.stderr.strip().splitlines()
        row.update(status="failed", message=f"verify: {lines[-1] if lines else result.returncode}")
        return
    verdict = "PASS" if result.returncode == 0 else "FAIL"
    row["verify"] = verdict
    write_bytes(record, json.dumps({"model_sha256": digest, "verify_seconds": groom.verify_seconds,
                                          "verdict": verdict, "summary": json.loads(result.stdout)}, indent=2).encode())


def security_from(tls: dict, ca_file=None, cert=None, key=None):
    """Dask TLS settings from the command line (winning) or the manifest's ``[tls]`` table, or None."""
    ca_file, cert, key = ca_file or tls.get("ca_file"), cert or tls.get("cert"), key or tls.get("key")
    if not (ca_file or cert or key):
        return None
    if not (ca_file and cert and key):
        raise InputError("TLS needs a CA file, a certificate and its key (--tls-ca-file, --tls-cert, --tls-key or "
                         "the manifest's [tls] ca_file, cert, key)")
    for p in (ca_file, cert, key):
        if not Path(p).exists():
            raise InputError("no such file", p)
    from distributed.security import Security

    return Security(tls_ca_file=str(ca_file), tls_client_cert=str(cert), tls_client_key=str(key),
                    require_encryption=True)


def run_batch(grooms: list[BatchItem], outdir, scheduler: str | None = None, workers: int | None = None,
              security=None, on_row=None, shots: list[ShotItem] | None = None) -> list[dict]:
    """Every groom as one task on a Dask cluster, and every shot as one task started once its groom's model is
    made; the rows in manifest order (the grooms', then the shots').

    ``scheduler``: the address of a running scheduler, else a LocalCluster on 127.0.0.1 with ``workers``
    processes (default: as many as grooms and shots, at most the cores), one task at a time each, and the cores
    shared out among them as hairinv's threads (``HAIRINV_THREADS``), so that numba and BLAS do not
    oversubscribe. ``on_row(row)`` is called as each groom ends.
    """
    from distributed import Client, LocalCluster, as_completed

    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    cores = os.cpu_count() or 1
    cluster = None
    if scheduler:
        try:
            client = Client(scheduler, security=security, timeout=CONNECT_TIMEOUT)
        except (OSError, TimeoutError, ValueError, TypeError) as exc:  # TypeError: tls:// without certificates
            raise InputError(f"could not connect to the Dask scheduler at {scheduler} ({type(exc).__name__}: "
                             f"{str(exc).splitlines()[0] if str(exc) else 'no reason given'}); a tls:// scheduler "
                             "needs --tls-ca-file, --tls-cert and --tls-key") from None
        n_workers = max(1, len(client.scheduler_info().get("workers", {})))
        threads = int(os.environ.get("HAIRINV_THREADS", 0)) or 1
    else:
        n_workers = max(1, min(workers or cores, len(grooms) + len(shots or []), cores))
        threads = max(1, cores // n_workers)
        # distributed's own logs off, errors too: a task that fails or a worker that dies is reported in its row
        # (from its future), and as the cluster closes a worker whose heartbeat finds the scheduler gone logs a
        # harmless traceback (seen under load)
        cluster = LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                               dashboard_address=None, silence_logs=logging.CRITICAL)
        client = Client(cluster)
    try:
        futures = {client.submit(run_groom, groom, str(outdir.resolve()), threads, key=f"groom-{groom.name}",
                                 pure=False): groom for groom in grooms}
        of_groom = {groom.name: future for future, groom in futures.items()}
        for shot in shots or []:  # a shot waits for its groom's row (Dask passes the result of the future)
            futures[client.submit(run_shot, shot, str(outdir.resolve()), threads, of_groom[shot.groom],
                                  key=f"shot-{shot.name}", pure=False)] = shot
        rows = {}
        for future in as_completed(futures):
            groom = futures[future]
            try:
                row = future.result()
            except Exception as exc:  # the worker died or the task could not run
                row = {"groom": groom.name, "status": "failed", "seconds": None, "strands": None, "contacts": None,
                       "solver": None, "verify": None, "message": f"task lost: {type(exc).__name__}: {exc}",
                       "log": str(outdir / f"{groom.name}.log"), "model": None, "skipped": []}
            rows[groom.name] = row
            if on_row is not None:
                on_row(row)
        return [rows[g.name] for g in grooms] + [rows[s.name] for s in shots or []]
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def table(rows: list[dict]) -> str:
    """The summary as a text table."""
    head = ("groom", "status", "seconds", "strands", "contacts", "solver", "verify", "message")
    lines = [[str(r.get(h)) if r.get(h) is not None else "-" for h in head] for r in rows]
    for line, r in zip(lines, rows):
        line[2] = "-" if r.get("seconds") is None else f"{r['seconds']:.1f}"
        line[7] = r["message"] or (f"reused: {', '.join(r['skipped'])}" if r.get("skipped") else "")
    widths = [max(len(h), *(len(line[i]) for line in lines)) for i, h in enumerate(head)]
    fmt = "  ".join(f"{{:{w}}}" for w in widths)
    return "\n".join([fmt.format(*head), fmt.format(*("-" * w for w in widths))] + [fmt.format(*ln) for ln in lines])

