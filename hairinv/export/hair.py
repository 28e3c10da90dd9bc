"""Cem Yuksel's ``.hair``: one shape, metres, +Z up (the format's convention, as hairinv's reader assumes).

The rod diameter is the header's default thickness; the header text names the stage file, the shape,
the unit and the up axis.
"""

from __future__ import annotations

from ..formats.yuksel import write_hair
from .base import register_exporter
from .polylines import polyline_shape, wrote


@register_exporter(".hair", name="Yuksel .hair")
def export_hair(source, path, shape, report) -> None:
    strands, axes, header = polyline_shape(source, shape, "z", report)
    radius, _ = source.radius
    write_hair(path, strands.points, strands.offsets, thickness=float(axes.length(2.0 * radius)), info=header)
    wrote(report, path, strands, "Yuksel .hair, +Z up")
