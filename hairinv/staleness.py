"""Make-style staleness: is a stage file current for the inputs and settings that would make it again?

Every stage file a subcommand writes records, as the root attribute ``command`` (JSON), what made it: the
subcommand, each input file (name, path as given, SHA-256, in command-line order), the settings it used
(the sections of :class:`hairinv.config.Settings` that subcommand reads, after defaults, preset,
``--config``, ``--set`` and options) and its other options (``--target``, ``--scene``, ``--init``...). A
file is current for a command when the record that command would write is the recorded one: same
subcommand, same input contents (by SHA-256, wherever the files now are), same settings and options.

``--if-stale`` compares before any work: a current output is left as it is (its modification time is set
to now, so that ``make`` sees it newer than its inputs) and the command exits 0. ``hairinv status`` compares
a file with its recorded inputs as they are on disk now (or with the files named), and with settings when
they are given.

``export`` writes formats with no room for a record (``.hair``, ``.data``), so with ``--if-stale`` it keeps
the record beside its output, as JSON in ``OUTPUT.hairinv.json`` (:func:`write_sidecar`), together with the
output's own SHA-256: an output written again by another command, or edited, is then never taken as
current.
"""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path

from . import stages
from .config import _SECTIONS, Settings
from .errors import InputError

#: Root attribute of a stage file holding its command record (an addition to the stage-file contract).
COMMAND_ATTR = "command"


def command_record(subcommand: str, inputs, settings: Settings, sections, options: dict | None = None) -> dict:
    """What a run of ``subcommand`` on ``inputs`` (paths, None for an absent optional one) with ``settings``
    is made of: the record its output carries, and what ``--if-stale`` compares. A rest mesh the body
    settings name (``--body-rest``) is an input too, after the others."""
    values = settings.to_dict()
    inputs = list(inputs)
    rest = str(settings.body.rest_mesh).strip() if "body" in sections else ""
    if rest and Path(rest).is_file():
        inputs.append(rest)
    return {
        "subcommand": subcommand,
        "inputs": [None if p is None else stages.file_record(p) for p in inputs],
        "settings": {section: values[section] for section in sections},
        "options": {key: value for key, value in sorted((options or {}).items())},
    }


def _canonical(value):
    """JSON round trip: tuples become lists, numbers and keys compare as they are stored."""
    return json.loads(json.dumps(value, sort_keys=True, default=str))


def recorded_command(path) -> dict | None:
    """The command record of a stage file, or None if it has none (written before records were kept)."""
    import h5py

    try:
        with h5py.File(path, "r") as fh:
            text = fh.attrs.get(COMMAND_ATTR)
    except (OSError, ValueError):
        raise InputError("cannot be read as an HDF5 stage file", path) from None
    if text is None:
        return None
    try:
        record = json.loads(text.decode(errors="replace") if isinstance(text, bytes) else str(text))
    except json.JSONDecodeError:
        raise InputError(f"has a {COMMAND_ATTR} attribute that is not JSON", path) from None
    stages.check_command_record(record, path)
    return record


_NO_DEFAULT = object()
#: Every setting's default, by section: a record written before a setting existed lacks it.
_DEFAULTS = {section: dataclasses.asdict(getattr(Settings(), attr)) for section, attr in _SECTIONS.items()}


def differences(recorded: dict, wanted: dict) -> list[str]:
    """What differs between two command records, as short phrases for the user (empty: none)."""
    recorded, wanted = _canonical(recorded), _canonical(wanted)
    found = []
    if recorded.get("subcommand") != wanted["subcommand"]:
        found.append(f"it was written by `{recorded.get('subcommand')}`, not `{wanted['subcommand']}`")
        return found
    old_inputs, new_inputs = recorded.get("inputs", []), wanted["inputs"]
    for k in range(max(len(old_inputs), len(new_inputs))):
        old = old_inputs[k] if k < len(old_inputs) else None
        new = new_inputs[k] if k < len(new_inputs) else None
        if old is None and new is None:
            continue
        if old is None or new is None:
            name = (new or old)["name"]
            found.append(f"input {name} was {'not given' if old is None else 'given'} then")
        elif old.get("sha256") != new["sha256"]:
            found.append(f"input {new['name']} changed" if old.get("name") == new["name"]
                         else f"input {new['name']} differs from {old.get('name')} it was made from")
    for section, values in wanted["settings"].items():
        old = recorded.get("settings", {}).get(section, {})
        for key, value in values.items():
            if key not in old and value == _DEFAULTS.get(section, {}).get(key, _NO_DEFAULT):
                continue  # a setting added since, at its default: what the older version did
            if old.get(key) != value:
                found.append(f"setting {section}.{key} was {old.get(key)!r}, now {value!r}")
    old_options = recorded.get("options", {})
    for key in sorted(set(old_options) | set(wanted["options"])):
        if old_options.get(key) != wanted["options"].get(key):
            found.append(f"option {key} was {old_options.get(key)!r}, now {wanted['options'].get(key)!r}")
    return found


def interrupted(path) -> str | None:
    """Why a stage file is stale whatever its record says: it holds a simulation Ctrl-C stopped (``/frames``
    attribute ``interrupted``), which a rerun computes whole; None if it does not."""
    import h5py

    try:
        with h5py.File(path, "r") as fh:
            frames = fh.get(stages.FRAMES)
            if not isinstance(frames, h5py.Group) or not bool(frames.attrs.get("interrupted", False)):
                return None
            done = len(frames["time"]) if "time" in frames else 0
            asked = frames.attrs.get("frames_requested")
    except (OSError, ValueError, TypeError):
        return None  # the readers' checks refuse such a file in their own words
    return f"its run was interrupted after {done}" + (f" of {int(asked)}" if asked is not None else "") + " frames"


def check_current(output, wanted: dict) -> tuple[bool, list[str]]:
    """Whether ``output`` is current for the command record ``wanted``, and if not, why."""
    output = Path(output)
    if not output.exists():
        return False, [f"{output} does not exist"]
    if not stages.is_stage_file(output):
        return False, [f"{output} is not a hairinv stage file"]
    recorded = recorded_command(output)
    if recorded is None:
        return False, [f"{output} records no command (written by an older hairinv)"]
    found = differences(recorded, wanted)
    cut = interrupted(output)
    if cut is not None:
        found.insert(0, cut)
    return not found, found


#: Suffix added to an export's file name for the file holding its command record (:func:`write_sidecar`).
SIDECAR_SUFFIX = ".hairinv.json"


def sidecar_path(output) -> Path:
    """Where the command record of a non-stage output is kept: ``OUTPUT.hairinv.json`` beside it."""
    output = Path(output)
    return output.with_name(output.name + SIDECAR_SUFFIX)


def is_sidecar(path) -> bool:
    """Whether ``path`` holds a command record hairinv kept (so that it may be written over)."""
    try:
        recorded = json.loads(Path(path).read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return False
    return isinstance(recorded, dict) and "subcommand" in recorded and "output_sha256" in recorded


def write_sidecar(output, record: dict) -> Path:
    """Keep ``record`` for ``output`` (just written) beside it, with the output's SHA-256, atomically."""
    from .atomic import write_bytes

    text = json.dumps({"output_sha256": stages.sha256_file(output), **_canonical(record)}, indent=1,
                      sort_keys=True)
    return write_bytes(sidecar_path(output), (text + "\n").encode())


def check_sidecar(output, wanted: dict) -> tuple[bool, list[str]]:
    """Whether ``output`` (not a stage file) is current for ``wanted``: its sidecar record is ``wanted`` and
    the output is the file that record was written for."""
    output, sidecar = Path(output), sidecar_path(output)
    if not output.exists():
        return False, [f"{output} does not exist"]
    if not sidecar.is_file():
        return False, [f"{output} has no record of what made it ({sidecar.name} is missing)"]
    try:
        recorded = json.loads(sidecar.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return False, [f"{sidecar.name} cannot be read as JSON"]
    if not isinstance(recorded, dict) or recorded.get("output_sha256") != stages.sha256_file(output):
        return False, [f"{output} was written again or changed since {sidecar.name} recorded it"]
    found = differences(recorded, wanted)
    return not found, found


def mark_current(output) -> None:
    """Set ``output``'s modification time to now: make then sees it newer than the inputs it was checked against."""
    os.utime(output)


def status(path, given_inputs=(), settings: Settings | None = None, check_data: bool = False
           ) -> tuple[bool, list[str]]:
    """Whether a stage file, or an export with its record (:func:`write_sidecar`), is current: its recorded
    inputs (or ``given_inputs``, in order) with the recorded SHA-256, and, when ``settings`` are given, the
    recorded settings.

    A stage file is checked from its metadata only (:func:`hairinv.stages.check_metadata`: attributes,
    dataset shapes, the ends of the offsets), so that a large file answers at once; with ``check_data`` it is
    read and checked whole, as every other command reads it (:func:`hairinv.stages.read_stage`).

    Inputs are found as :func:`hairinv.groom.find_recorded_body` finds the body: the recorded path as written
    (relative to the working directory or absolute), then relative to the stage file's folder.

    Raises
    ------
    InputError
        The file cannot be read, is not a stage file, or records no command.
    """
    path = Path(path)
    if not path.exists():
        raise InputError("no such file", path)
    reasons = []
    if stages.is_stage_file(path):
        # refuses a file that breaks the stage-file contract, whole or as far as its metadata shows
        if check_data:
            stages.read_stage(path)
        else:
            stages.check_metadata(path)
        recorded = recorded_command(path)
        if recorded is None:
            raise InputError("records no command (written by an older hairinv): its currency cannot be told; "
                             "make it again", path)
        cut = interrupted(path)
        if cut is not None:
            reasons.append(cut)
    elif sidecar_path(path).is_file() and is_sidecar(sidecar_path(path)):
        recorded = json.loads(sidecar_path(path).read_text())
        if recorded["output_sha256"] != stages.sha256_file(path):
            reasons.append(f"{path.name} was written again or changed since {sidecar_path(path).name} recorded it")
    else:
        raise InputError(f"is neither a hairinv stage file nor an export with its record ({sidecar_path(path).name})",
                         path)
    records = recorded.get("inputs", [])
    given = [Path(p) for p in given_inputs]
    if given and len(given) != len([r for r in records if r is not None]):
        reasons.append(f"{len(given)} inputs given, but it was made from {len([r for r in records if r])}")
    present = [r for r in records if r is not None]
    for k, record in enumerate(present):
        if given:
            if k >= len(given):
                break
            candidates = [given[k]]
        else:
            recorded_path = Path(record.get("path", record["name"]))
            candidates = [recorded_path] + ([path.parent / recorded_path] if not recorded_path.is_absolute() else [])
            candidates += [Path(record["abspath"])] if record.get("abspath") else []
        found = [c for c in candidates if c.is_file()]
        if not found:
            reasons.append(f"input {record['name']} is not at {str(candidates[0])!r}"
                           + ("" if given else " (nor next to the stage file)"))
            continue
        if not any(stages.sha256_file(c) == record["sha256"] for c in found):
            reasons.append(f"input {found[0]} changed since (its SHA-256 differs from the recorded one)")
    if settings is not None:
        values = _canonical(settings.to_dict())
        for section, old in recorded.get("settings", {}).items():
            for key, value in old.items():
                if values.get(section, {}).get(key) != value:
                    reasons.append(f"setting {section}.{key} was {value!r}, now {values[section][key]!r}")
    return not reasons, reasons


__all__ = ["COMMAND_ATTR", "SIDECAR_SUFFIX", "check_current", "check_sidecar", "command_record", "differences",
           "interrupted", "is_sidecar", "mark_current", "recorded_command", "sidecar_path", "status", "write_sidecar"]
