"""hairinv's own HDF5 stage files as a hairstyle source (group ``/curves``).

Any stage file carries ``/curves`` (each stage copies what it read), so any
of them can be fitted again. Points are already in metres with a stated up
axis, so no unit or axis guess is made for them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import stages
from ..errors import InputError
from .base import check_strands, register_curves_reader, register_curves_writer


@register_curves_reader(".h5", ".hdf5")
def read_hdf5_curves(path: Path):
    stage = stages.read_stage(path)
    if stages.CURVES not in stage:
        raise InputError("has no /curves group to read strands from", path)
    group = stage[stages.CURVES]
    raw = check_strands(group["points"], group["offsets"], path, "hairinv-hdf5")
    raw.scale_to_m = 1.0
    up = np.asarray(group.attrs.get("up", (0.0, 1.0, 0.0)), dtype=np.float64)
    raw.up = up
    raw.extras["source"] = group.attrs.get("source", str(Path(path).name))
    return raw


@register_curves_writer(".h5", ".hdf5")
def write_hdf5_curves(path: Path, points, offsets, up=(0.0, 1.0, 0.0), source: str = "", command: str = "export"):
    """Write a stage file holding only ``/curves`` (points in metres)."""
    group = stages.Group(
        stages.CURVES,
        {"points": np.asarray(points, np.float64), "offsets": np.asarray(offsets, np.int64)},
        attrs={"source": source, "scale_to_m": 1.0, "up": np.asarray(up, np.float64)},
    )
    stages.write_stage(path, [group], command)
