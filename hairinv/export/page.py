"""HTML: one self-contained report of a stage file, readable offline.

The JSON summary (:func:`hairinv.summary.summarise`) as tables, one per stage, and the PNG pictures
inlined as base64 ``data:`` URLs: the groom (:mod:`hairinv.export.picture`), and with ``/model`` the contact
solver's convergence (:mod:`hairinv.export.convergence`) above the model's table. Several stage files (runs
of one groom) make one page comparing them: the side-by-side picture (:mod:`hairinv.export.compare`) and a
table of the runs. No script, no stylesheet, font or image is loaded from anywhere: the style sheet is in
the file, and the file names no external resource.
"""

from __future__ import annotations

import base64
from html import escape
from pathlib import Path

from .. import __version__
from ..atomic import write_bytes
from ..summary import SCHEMA, summarise
from .base import register_comparison, register_exporter
from .compare import comparison_picture
from .convergence import convergence_of, convergence_png, convergence_size
from .picture import picture

GENERATOR = "hairinv"
# Rows of a list shown in full (the stiffened strands, the residual history); the rest are counted.
LIST_ROWS = 40

_STYLE = """
body { font-family: sans-serif; margin: 2em; color: #222; max-width: 1250px; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; margin-top: 1.5em; }
table { border-collapse: collapse; margin: 0.5em 0; }
th, td { border: 1px solid #ccc; padding: 0.2em 0.6em; text-align: left; vertical-align: top; }
th { background: #f2f2f2; font-weight: normal; }
td.num { font-family: monospace; text-align: right; }
p.warning { color: #a40; }
img { max-width: 100%; }
"""


def _number(value) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value)


def _cell(value) -> str:
    """One value as the content of a table cell (nested objects and lists as tables of their own)."""
    if value is None:
        return "<td>&ndash;</td>"
    if isinstance(value, dict) and value and all(isinstance(v, (int, float)) for v in value.values()):
        # a statistic or a count by rule: one row
        head = "".join(f"<th>{escape(str(k))}</th>" for k in value)
        row = "".join(f'<td class="num">{escape(_number(v))}</td>' for v in value.values())
        return f"<td><table><tr>{head}</tr><tr>{row}</tr></table></td>"
    if isinstance(value, dict):
        return f"<td>{_table(value)}</td>"
    if isinstance(value, list):
        return f"<td>{_list(value)}</td>"
    if isinstance(value, (int, float)):
        return f'<td class="num">{escape(_number(value))}</td>'
    return f"<td>{escape(str(value))}</td>"


def _table(values: dict) -> str:
    rows = "".join(f"<tr><th>{escape(str(key))}</th>{_cell(value)}</tr>" for key, value in values.items())
    return f"<table>{rows}</table>"


def _list(values: list) -> str:
    if not values:
        return "none"
    if all(isinstance(v, (int, float)) for v in values):
        return escape(", ".join(_number(v) for v in values))
    shown = values[:LIST_ROWS]
    if all(isinstance(v, dict) for v in shown):
        keys = list(shown[0])
        head = "".join(f"<th>{escape(k)}</th>" for k in keys)
        body = "".join("<tr>" + "".join(_cell(v.get(k)) for k in keys) + "</tr>" for v in shown)
    else:
        head = ""
        body = "".join("<tr>" + "".join(_cell(x) for x in (v if isinstance(v, list) else [v])) + "</tr>"
                       for v in shown)
    more = f"<p>and {len(values) - LIST_ROWS} more</p>" if len(values) > LIST_ROWS else ""
    return f"<table>{'<tr>' + head + '</tr>' if head else ''}{body}</table>{more}"


def _image(png: bytes, alt: str, size: tuple[int, int]) -> str:
    width, height = size
    data = base64.b64encode(png).decode("ascii")
    return f'<img alt="{escape(alt)}" width="{width}" height="{height}" src="data:image/png;base64,{data}">'


def _head(title: str) -> list[str]:
    return [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f'<meta name="generator" content="{GENERATOR} {escape(__version__)}">',
        f"<title>{escape(title)}: hairinv report</title>",
        f"<style>{_STYLE}</style></head><body>",
    ]


def _convergence(source) -> tuple[list[str], list[str]]:
    """The model's convergence plot (or the sentence saying why there is none), and lines for the user."""
    history, why = convergence_of(source)
    if history is None:
        return [f"<p>No convergence plot: {escape(source.name)} {escape(why)}.</p>"], []
    png, lines = convergence_png(history, source)
    return ["<p>The contact solver's largest residual over the contacts, relative to the heaviest strand's "
            "weight, at each check of its sweeps; the dashed line is its tolerance.</p>",
            _image(png, f"{source.name}: contact solver convergence", convergence_size())], lines


def report_html(source, color: str | None, output: Path) -> tuple[str, list[str], list[str]]:
    """The report's text, and the picture's lines and warnings for the user."""
    summary = summarise(source.stage)
    drawn = picture(source, color, output)
    lines = list(drawn.lines)
    top = {key: summary[key] for key in ("file", "sha256", "producer", "schema_version", "stages")}
    parts = [*_head(source.name), f"<h1>{escape(source.name)}</h1>", _table(top)]
    if summary["warnings"]:
        parts.append("<h2>Warnings</h2>")
        parts += [f'<p class="warning">{escape(w)}</p>' for w in summary["warnings"]]
    what = "the input shape" if drawn.coloring is None else (
        f"coloured by {drawn.coloring.quantity.label} ({drawn.coloring.describe()})")
    parts += [
        "<h2>Picture</h2>",
        f"<p>Front and side views, {escape(what)}; strands and dots the body hides are drawn faded.</p>",
        _image(drawn.png, f"{source.name}: front and side views", drawn.size),
    ]
    for name, values in summary["groups"].items():
        if values is not None:
            parts.append(f"<h2>/{escape(name)}</h2>")
            if name == "model":
                plot, plot_lines = _convergence(source)
                parts += plot
                lines += plot_lines
            parts.append(_table(values))
    parts += _foot(summary["timings_s"])
    return "\n".join(parts), lines, drawn.warnings


def _foot(timings: dict | None) -> list[str]:
    out = [] if timings is None else ["<h2>Timings</h2>", _table(timings)]
    return out + [f"<p>hairinv {escape(__version__)}; the summary's schema {SCHEMA} (docs/export.md in "
                  "hairinv).</p>", "</body></html>", ""]


def comparison_html(sources, output: Path) -> tuple[str, list[str], list[str]]:
    """The page comparing several runs of one groom, and the picture's lines and warnings for the user."""
    drawn, columns = comparison_picture(sources)
    names = ", ".join(source.name for source in sources)
    parts = [*_head(f"comparison of {names}"), f"<h1>Comparison of {len(sources)} simulations</h1>",
             f"<p>Simulations of one groom ({sources[0].n_strands} strands): {escape(names)}.</p>"]
    runs = []
    for run in columns:
        summary = summarise(run.source.stage)
        frames = summary["groups"]["frames"]
        runs.append({"file": run.source.name, "sha256": summary["sha256"], "init": run.init or None,
                     "model target": run.target or None, "scene": run.scene or None, "frames": frames["frames"],
                     "seconds": frames["seconds"], "largest displacement at the last frame (mm)": 1e3 * run.largest,
                     "warnings": summary["warnings"] or None})
    lo, hi = drawn.coloring.vmin, drawn.coloring.vmax
    parts += ["<h2>Runs</h2>", _list(runs), "<h2>Picture</h2>",
              (f"<p>One column per simulation: the input (grey) against its last frame, from the front and the "
               f"side, coloured by each vertex's distance from where it was at frame 0 in the body's frame "
               f"({lo:.4g} to {hi:.4g} mm, the same scale in every column).</p>"),
              _image(drawn.png, f"comparison of {names}: front and side views", drawn.size)]
    parts += _foot(None)
    return "\n".join(parts), drawn.lines, drawn.warnings


def _owns(path: Path) -> bool:
    """A report hairinv wrote: its generator tag is in the first kilobytes."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(4096)
    except OSError:
        return False
    return f'<meta name="generator" content="{GENERATOR} '.encode() in head


@register_exporter(".html", ".htm", name="HTML report", default_shape=None, options=("color",), owns=_owns)
def export_html(source, path, shape, report, color: str | None = None) -> None:
    text, lines, warnings = report_html(source, color, Path(path))
    write_bytes(path, text.encode("utf-8"))
    report.lines.append(f"wrote {path}: HTML report of {source.name}, the pictures inlined, readable offline")
    report.lines += lines
    report.warnings += warnings


@register_comparison(".html", ".htm")
def export_html_comparison(sources, path, report) -> None:
    text, lines, warnings = comparison_html(sources, Path(path))
    write_bytes(path, text.encode("utf-8"))
    report.lines.append(f"wrote {path}: HTML report comparing {len(sources)} simulations, the picture inlined, "
                        "readable offline")
    report.lines += lines
    report.warnings += warnings
