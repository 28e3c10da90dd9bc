"""What the polyline writers (.hair, .data, OBJ) share: one shape, in metres, the format's up axis."""

from __future__ import annotations

from pathlib import Path

from .. import __version__
from .base import ExportReport
from .source import ExportSource, OutputAxes, Shape, Strands

__all__ = ["polyline_shape"]


def polyline_shape(source: ExportSource, shape: Shape, up: str,
                   report: ExportReport) -> tuple[Strands, OutputAxes, str]:
    """The strands of ``shape`` (one shape, not ``all``) in the coordinates of a format whose up axis is
    ``up``, in metres.

    Returns the strands (points already converted), the axes used and a one-line description for the
    file's header.
    """
    strands = source.strands(shape)
    axes = OutputAxes.onto(source.up, up)
    if axes.note:
        report.lines.append(axes.note)
    converted = Strands(axes.points(strands.points), strands.offsets, strands.label)
    # unit and axis first: the .hair header keeps 88 bytes of it
    header = f"metres, +{up.upper()} up; {strands.label}; hairinv {__version__} export of {source.name}"
    return converted, axes, header


def wrote(report: ExportReport, path: Path, strands: Strands, what: str) -> None:
    report.lines.append(f"wrote {path}: {what}, {strands.label}, {strands.n_strands} strands, "
                        f"{len(strands.points)} points, metres")
