"""``hairinv export``: a stage file's groom in the formats other tools load (docs/export.md).

One module per output kind registers its writer by suffix (:mod:`hairinv.export.base`); importing this
package imports them all. Every writer writes through the one atomic writer (:mod:`hairinv.atomic`): on
any error nothing is left behind and an existing output is replaced only on success.

Several stage files (simulations of one groom) are compared side by side by the kinds that register a
comparison (PNG, HTML; :mod:`hairinv.export.compare`).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..errors import InputError

# Each module of an output kind registers its writer when imported.
from . import animation, compare, data, hair, obj, page, picture, summary, usd  # noqa: F401
from .base import COMPARISONS, EXPORTERS, ExportReport, check_export_path, exporter_for
from .follow import follow_source
from .source import ExportSource, Shape, parse_shape

__all__ = ["EXPORTERS", "ExportReport", "ExportSource", "Shape", "export", "parse_shape"]


def export(stage_path, output, shape: str | None = None, follow: bool = False, render=None,
           **options) -> ExportReport:
    """Write the groom of ``stage_path`` to ``output``, in the format of its suffix.

    Parameters
    ----------
    stage_path : path-like, a hairinv stage file; or a sequence of them, simulations of one groom (each with
        ``/frames``) compared side by side, one column each (PNG and HTML only)
    output : path-like, ``.usda``, ``.usdc``, ``.usd``, ``.hair``, ``.data``, ``.obj``, ``.json``, ``.png`` or
        ``.html``
    shape : str, optional
        ``input``, ``rest``, ``frame:N`` or ``all``; default: the format's (USD ``all``, the polyline formats
        ``input``). The summary and the pictures take none: they show the whole file.
    follow : bool
        Write the render groom instead of the simulated strands: every strand of the hairstyle the simulated
        guides were picked from, each carried by its nearest guides (:mod:`hairinv.follow`); the groom formats
        only, for a stage file with ``/frames``.
    render : path-like, optional
        The render groom's hairstyle file (implies ``follow``); default: the one the stage file records.
    **options
        Further options of the writer, None when not given: ``color`` (PNG, HTML), the quantity the strands
        are coloured by.

    Raises
    ------
    InputError
        Unknown suffix, a shape the file does not carry, an option the format does not take, an output that
        would overwrite an input or a file that is not a hairstyle; several stage files for a format that
        holds one, or files that are not simulations of one groom; nothing is written.
    """
    output = Path(output)
    exporter = exporter_for(output)
    given = {key: value for key, value in options.items() if value is not None}
    paths = [stage_path] if isinstance(stage_path, (str, os.PathLike)) else list(stage_path)
    if not paths:
        raise InputError("no stage file to export", output)
    follow = follow or render is not None
    if len(paths) > 1:
        if follow:
            raise InputError(f"--{'render' if render is not None else 'follow'} writes one stage file's render "
                             "groom; give one stage file", output)
        return _compare(paths, output, exporter, shape, given)
    stage_path = paths[0]
    for key in given:
        if key not in exporter.options:
            takers = sorted({e.name for e in EXPORTERS.values() if key in e.options})
            raise InputError(f"--{key} applies to {' and '.join(takers)} output, not to {exporter.name}", output)
    if exporter.default_shape is None:
        if shape is not None:
            raise InputError(f"--shape does not apply to {exporter.name} output, which shows the whole stage file",
                             output)
        wanted = None
    else:
        wanted = parse_shape(shape if shape is not None else exporter.default_shape)
        if wanted.kind == "all" and not exporter.several_shapes:
            raise InputError(f"the {exporter.name} format holds one shape; choose --shape input, rest or frame:N",
                             output)
    report = ExportReport()
    if follow:
        if exporter.default_shape is None:
            groom_kinds = sorted({e.name for e in EXPORTERS.values() if e.default_shape is not None})
            raise InputError(f"--{'render' if render is not None else 'follow'} applies to the groom formats "
                             f"({', '.join(groom_kinds)}), not to {exporter.name} output", output)
        source = follow_source(stage_path, render, report.lines)
    else:
        source = ExportSource(stage_path)
    check_export_path(output, inputs=[source.path, *source.input_files()], exporter=exporter)
    if wanted is not None and wanted.kind != "all":
        source.require(wanted)
    exporter.write(source, output, wanted, report, **given)
    return report


def _compare(paths, output: Path, exporter, shape, given: dict) -> ExportReport:
    """Several simulations of one groom, side by side: checked, then written by the suffix's comparison."""
    write = COMPARISONS.get(output.suffix.lower())
    if write is None:
        kinds = sorted({EXPORTERS[suffix].name for suffix in COMPARISONS})
        raise InputError(f"{exporter.name} output holds one stage file; several stage files are compared only "
                         f"in {' or '.join(kinds)} output", output)
    if shape is not None:
        raise InputError("--shape does not apply to a comparison, which shows each run's last frame against the "
                         "input", output)
    if given:
        raise InputError(f"--{next(iter(given))} does not apply to a comparison of several stage files, which "
                         "colours each run's last frame by how far it moved", output)
    sources = [ExportSource(path) for path in paths]
    for source in sources:
        if source.frames is None:
            raise InputError("has no /frames group, so it has no simulation to compare; run `hairinv simulate` "
                             "on it first", source.path)
    first = sources[0]
    for source in sources[1:]:
        if not (np.array_equal(source.offsets, first.offsets) and np.array_equal(source.points, first.points)
                and np.array_equal(source.up, first.up)):
            raise InputError(f"holds another groom than {first.name} (its /curves differ); a comparison shows "
                             "simulations of one groom", source.path)
    inputs = [path for source in sources for path in (source.path, *source.input_files())]
    check_export_path(output, inputs=inputs, exporter=exporter)
    report = ExportReport()
    write(sources, output, report)
    return report
