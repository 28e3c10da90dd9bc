"""Several simulations of one groom side by side (PNG, and inlined in the HTML report): one before/after
column per stage file.

Each column shows the input shape (grey), carried with the body to its pose at the run's last frame, against
that frame, from the front (above) and from the side (below), over the body at that pose, as the
before/after row of :mod:`hairinv.export.picture` does for one file (far strands first, those the body
hides faded).
The last frame's strands are coloured by how far each vertex moved: its distance at the last frame from
where it was at frame 0, in the body's frame (the measure ``simulate`` prints and ``/frames/displacement``
stores, here at the input's vertices). Every column has the same views, limits and colour scale (0 to the
largest displacement over all the runs), so a run that sags stands out beside one that stays still. The
column's title gives the run's initialisation (``/frames`` ``init``), its model's target (``/model``
``target``) and its largest displacement at the last frame.

The PNG's text chunks record the colour scale (``hairinv:quantity`` ``displacement``, ``hairinv:unit``
``mm``, ``hairinv:min``, ``hairinv:max``) and, as JSON, one entry per column (``hairinv:columns``: file,
init, target, scene, time of the last frame, largest displacement in mm).
"""

from __future__ import annotations

import io
import json
from dataclasses import dataclass
import numpy as np

from .. import __version__
from ..atomic import write_bytes
from .base import register_comparison
from .picture import (DPI, INPUT_GREY, VIEWS, Body, ColourScale, Coloring, Picture, Quantity, _draw_body,
                      _draw_strands, _frame_axes, _view, hidden_by)
from .source import ExportSource, OutputAxes, Strands

__all__ = ["DISPLACEMENT", "Run", "comparison_picture", "comparison_size", "draw_comparison", "export_png_comparison",
           "run_of"]

# Figure layout, inches at DPI: one column of views per run and a colour bar; the height does not depend
# on the number of runs, the width grows by COLUMN_IN per run.
COLUMN_IN = 4.0
BAR_IN = 1.2
ROW_IN = 5.0
TITLE_IN = 1.9
BOTTOM_IN = 0.6
DISPLACEMENT = Quantity("displacement at the last frame", "mm", 1e3, "plasma")


@dataclass
class Run:
    """One column: a simulation and its last frame.

    Attributes
    ----------
    source : ExportSource, a stage file with ``/frames``
    init, target, scene : str, ``/frames`` ``init``, ``/model`` ``target``, ``/frames`` ``scene`` ("" where
        the file does not record one)
    time : float, s, time of the last frame
    last : Strands, the last frame at the input's vertices (a trimmed run: on its cut strands), m, world frame
    moved : (P,) float64, m, per vertex of ``last``: its distance from the same vertex at frame 0, in the body's
        frame
    pose : (4, 4) float64, the body's rigid transform at the last frame, from its rest pose (column vectors, m)
    """

    source: ExportSource
    init: str
    target: str
    scene: str
    time: float
    last: Strands
    moved: np.ndarray
    pose: np.ndarray

    @property
    def largest(self) -> float:
        """m, the largest displacement at the last frame."""
        return float(self.moved.max()) if len(self.moved) else 0.0

    def column(self) -> dict:
        return {"file": self.source.name, "init": self.init, "target": self.target, "scene": self.scene,
                "time_s": self.time, "largest_displacement_mm": 1e3 * self.largest}


def _in_body_frame(points: np.ndarray, transform: np.ndarray) -> np.ndarray:
    """World points -> the body's frame, ``transform`` (4, 4) taking the body's frame to the world."""
    return (points - transform[:3, 3]) @ transform[:3, :3]


def run_of(source: ExportSource) -> Run:
    """The column of a stage file with ``/frames``: its last frame and how far each vertex moved."""
    last_index = source.n_frames - 1
    first, last = source.frame(0), source.frame(last_index)
    pose = source.body_transform(last_index)
    moved = np.linalg.norm(_in_body_frame(last.points, pose)
                           - _in_body_frame(first.points, source.body_transform(0)), axis=1)
    target = "" if source.model is None else str(source.model.attrs.get("target", ""))
    return Run(source, str(source.frames.attrs.get("init", "")), target, str(source.frames.attrs.get("scene", "")),
               float(source.times[last_index]), last, moved, pose)


def comparison_size(columns: int) -> tuple[int, int]:
    """(width, height) in pixels of a comparison of ``columns`` runs."""
    return round((columns * COLUMN_IN + BAR_IN) * DPI), round((TITLE_IN + 2 * ROW_IN + BOTTOM_IN) * DPI)


def _title(run: Run) -> str:
    init = run.init or "unrecorded"
    target = f", model target {run.target}" if run.target else ""
    scene = f"{run.scene} scene, " if run.scene else ""
    return (f"{run.source.name}\ninit {init}{target}\n{scene}largest displacement at t = {run.time:g} s:\n"
            f"{1e3 * run.largest:.3g} mm")


def draw_comparison(sources: list[ExportSource]):
    """The figure (matplotlib, Agg) and what it shows: ``(figure, runs, (vmin, vmax) in mm, lines, bodies)``;
    ``bodies`` holds each file's body note (see :meth:`ExportSource.body`)."""
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure

    runs = [run_of(source) for source in sources]
    axes = OutputAxes.onto(sources[0].up, "y")
    # each run's input carried with its body to the last frame's pose, and the last frame, picture frame
    befores = [axes.points(run.source.points @ run.pose[:3, :3].T + run.pose[:3, 3]) for run in runs]
    afters = [axes.points(run.last.points) for run in runs]
    vmax = max(DISPLACEMENT.scale * run.largest for run in runs)
    norm = Normalize(0.0, vmax if vmax > 0 else 1.0)
    width, height = comparison_size(len(runs))
    fig = Figure(figsize=(width / DPI, height / DPI), dpi=DPI)
    grid = fig.add_gridspec(2, len(runs) + 1, width_ratios=[1.0] * len(runs) + [0.06],
                            left=0.8 / (width / DPI), right=1.0 - 0.75 / (width / DPI), wspace=0.3, hspace=0.15,
                            top=1.0 - TITLE_IN / (height / DPI), bottom=BOTTOM_IN / (height / DPI))
    fig.suptitle("before/after: the input (grey) against each run's last frame,\ncoloured by how far it moved",
                 fontsize=13, y=1.0 - 0.12 / (height / DPI), va="top")
    bodies = []
    for run in runs:
        mesh, note = run.source.body()
        body = None if mesh is None or run.source.body_removed else Body.posed(mesh, axes, run.pose)
        bodies.append((body, note))
    for row, (side, label, horizontal) in enumerate(VIEWS):
        # the same limits in every column
        frame_on = np.concatenate([_view(points, side)[0] for points in (*befores, *afters)])
        for column, (run, before, after) in enumerate(zip(runs, befores, afters)):
            ax = fig.add_subplot(grid[row, column])
            body = bodies[column][0]
            if body is not None:
                _draw_body(ax, body, side)
            _draw_strands(ax, before, run.source.offsets, side, hidden_by(body, before, side), color=INPUT_GREY,
                          linewidths=1.4, zorder=2.0)
            _draw_strands(ax, after, run.last.offsets, side, hidden_by(body, after, side),
                          values=DISPLACEMENT.scale * run.moved, cmap=DISPLACEMENT.cmap, norm=norm, linewidths=0.8,
                          zorder=3.0)
            _frame_axes(ax, frame_on, f"{label} view", horizontal)
            if row == 0:
                ax.set_title(_title(run) + f"\n\n{label} view", fontsize=10)
    bar = fig.colorbar(ScalarMappable(norm=norm, cmap=DISPLACEMENT.cmap), cax=fig.add_subplot(grid[:, -1]))
    label = f"{DISPLACEMENT.label} ({DISPLACEMENT.unit})"
    if vmax <= 0:
        bar.set_ticks([0.0])
        label += ": 0 everywhere"
    bar.set_label(label)
    lines = [f"{run.source.name}: init {run.init or 'unrecorded'}, model target {run.target or 'none'}; largest "
             f"displacement at t = {run.time:g} s: {1e3 * run.largest:.3g} mm" for run in runs]
    lines.append(f"colour: {DISPLACEMENT.label}, 0 to {vmax:.4g} {DISPLACEMENT.unit}, the same in every column")
    return fig, runs, (0.0, vmax), lines, [note for _, note in bodies]


def _metadata(runs: list[Run], vmin: float, vmax: float) -> dict:
    names = ", ".join(run.source.name for run in runs)
    return {"Title": f"comparison of {names}", "Software": f"hairinv {__version__}", "Source": names,
            "hairinv:quantity": "displacement", "hairinv:unit": DISPLACEMENT.unit, "hairinv:min": repr(vmin),
            "hairinv:max": repr(vmax), "hairinv:scale": "linear", "hairinv:bar_min": repr(vmin),
            "hairinv:bar_max": repr(vmax), "hairinv:columns": json.dumps([run.column() for run in runs])}


def comparison_picture(sources: list[ExportSource]) -> tuple[Picture, list[Run]]:
    """Draw the comparison of ``sources`` (see the module docstring) into PNG bytes; the runs it shows."""
    fig, runs, (vmin, vmax), lines, bodies = draw_comparison(sources)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=DPI, metadata=_metadata(runs, vmin, vmax))
    warnings = []
    for run, note in zip(runs, bodies):
        if note.startswith("body: "):
            lines.append(f"{run.source.name}: {note}")
        elif "records no body" in note:
            lines.append(f"{run.source.name}: no body drawn: {note}")
        else:  # the file names a body that is gone or changed: say so as USD does
            warnings.append(f"warning: {run.source.name}: {note}; its column has no body")
    moved = np.concatenate([DISPLACEMENT.scale * run.moved for run in runs])
    paint = Coloring("displacement", DISPLACEMENT, moved, vmin, vmax, ColourScale(vmin, vmax))
    return Picture(buffer.getvalue(), paint, comparison_size(len(runs)), lines, warnings), runs


@register_comparison(".png")
def export_png_comparison(sources, path, report) -> None:
    drawn, _ = comparison_picture(sources)
    write_bytes(path, drawn.png)
    width, height = drawn.size
    report.lines.append(f"wrote {path}: PNG, {width} x {height} px, {len(sources)} simulations side by side, "
                        "front and side views")
    report.lines += drawn.lines
    report.warnings += drawn.warnings
