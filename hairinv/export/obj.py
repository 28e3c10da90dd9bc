"""Wavefront OBJ polylines: one shape, metres, +Y up (OBJ's usual convention, as hairinv's reader assumes).

One ``l`` element per strand, root first; comment lines name the stage file, the shape, the unit and
the up axis.
"""

from __future__ import annotations

from ..formats.obj import write_obj_curves
from .base import register_exporter
from .polylines import polyline_shape, wrote


@register_exporter(".obj", name="OBJ polylines")
def export_obj(source, path, shape, report) -> None:
    strands, _, header = polyline_shape(source, shape, "y", report)
    write_obj_curves(path, strands.points, strands.offsets, header=[header])
    wrote(report, path, strands, "OBJ polylines, +Y up")
