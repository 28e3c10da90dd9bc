"""USC-HairSalon ``.data``: one shape, metres, +Y up (the USC data's convention). The format has no header."""

from __future__ import annotations

from ..formats.usc import write_usc
from .base import register_exporter
from .polylines import polyline_shape, wrote


@register_exporter(".data", name="USC-HairSalon .data")
def export_data(source, path, shape, report) -> None:
    strands, _, _ = polyline_shape(source, shape, "y", report)
    write_usc(path, strands.points, strands.offsets)
    wrote(report, path, strands, "USC-HairSalon .data, +Y up")
