"""``hairinv export``: a stage file's groom in the formats other tools load (docs/export.md).

One module per output kind registers its writer by suffix (:mod:`hairinv.export.base`); importing this
package imports them all. Every writer writes through the one atomic writer (:mod:`hairinv.atomic`): on
any error nothing is left behind and an existing output is replaced only on success.
"""

from __future__ import annotations

from pathlib import Path

from ..errors import InputError

# Each module of an output kind registers its writer when imported.
from . import data, hair, obj, page, picture, summary, usd  # noqa: F401
from .base import EXPORTERS, ExportReport, check_export_path, exporter_for
from .source import ExportSource, Shape, parse_shape

__all__ = ["EXPORTERS", "ExportReport", "ExportSource", "Shape", "export", "parse_shape"]


def export(stage_path, output, shape: str | None = None, **options) -> ExportReport:
    """Write the groom of ``stage_path`` to ``output``, in the format of its suffix.

    Parameters
    ----------
    stage_path : path-like, a hairinv stage file
    output : path-like, ``.usda``, ``.usdc``, ``.usd``, ``.hair``, ``.data``, ``.obj``, ``.json``, ``.png`` or
        ``.html``
    shape : str, optional
        ``input``, ``rest``, ``frame:N`` or ``all``; default: the format's (USD ``all``, the polyline formats
        ``input``). The summary and the pictures take none: they show the whole file.
    **options
        Further options of the writer, None when not given: ``color`` (PNG, HTML), the quantity the strands
        are coloured by.

    Raises
    ------
    InputError
        Unknown suffix, a shape the file does not carry, an option the format does not take, an output that
        would overwrite an input or a file that is not a hairstyle; nothing is written.
    """
    output = Path(output)
    exporter = exporter_for(output)
    given = {key: value for key, value in options.items() if value is not None}
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
    source = ExportSource(stage_path)
    check_export_path(output, inputs=[source.path, *source.input_files()], exporter=exporter)
    if wanted is not None and wanted.kind != "all":
        source.require(wanted)
    report = ExportReport()
    exporter.write(source, output, wanted, report, **given)
    return report
