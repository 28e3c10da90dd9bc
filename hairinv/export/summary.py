"""JSON: the summary of every stage the file carries, the one ``hairinv info --json`` prints
(:func:`hairinv.summary.summarise`; docs/export.md gives its schema). UTF-8, indented, keys in a fixed order."""

from __future__ import annotations

import json
from pathlib import Path

from ..atomic import write_bytes
from ..summary import SCHEMA, summarise
from .base import register_exporter


def summary_text(source) -> str:
    return json.dumps(summarise(source.stage), indent=2, allow_nan=False) + "\n"


def _owns(path: Path) -> bool:
    """A JSON summary hairinv wrote: an object with ``schema`` and ``producer`` at the top."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):
        return False
    return isinstance(data, dict) and "schema" in data and "producer" in data


@register_exporter(".json", name="JSON summary", default_shape=None, owns=_owns)
def export_json(source, path, shape, report) -> None:
    write_bytes(path, summary_text(source).encode("utf-8"))
    report.lines.append(f"wrote {path}: JSON summary (schema {SCHEMA}) of {source.name}, stages "
                        f"{','.join(source.stage.groups)}")
