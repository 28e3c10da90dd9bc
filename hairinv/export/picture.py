"""PNG (matplotlib, Agg, headless): the groom from the front and the side over its body, coloured by a quantity.

Views are orthographic, in the groom's frame turned so that its up axis is vertical (+Y): the front view
looks along -Z (horizontal axis x), the side view along -X (horizontal axis z). The body mesh, if the stage
file records one that is still there unchanged (found as the USD writer finds it), is drawn light grey
behind the strands, its triangles shaded by how squarely they face the viewer. Each strand segment takes
the larger of its two vertices' values; segments are drawn in order of value, so the largest lie on top.
With ``/frames`` a second row shows the input shape against the last frame.

The PNG's text chunks record what the colours mean: ``hairinv:quantity``, ``hairinv:unit``,
``hairinv:min`` and ``hairinv:max`` (the colour bar's range, in that unit: the quantity's smallest and
largest value over the vertices or strands it is defined on).

``--plot convergence`` draws the model's contact solver history instead
(:mod:`hairinv.export.convergence`); several stage files are drawn side by side by
:mod:`hairinv.export.compare`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import __version__
from ..atomic import write_bytes
from ..errors import InputError
from .base import register_exporter
from .convergence import convergence_of, convergence_png, convergence_size
from .source import ExportSource, OutputAxes

__all__ = ["COLORS", "PLOTS", "Coloring", "Picture", "coloring", "default_color", "draw", "picture", "png_size"]

# Figure layout: inches at DPI, so the PNG is WIDTH_IN * DPI pixels wide and ROW_IN * DPI per row of views
# (plus the title band); fixed, not cropped to the drawing, so every picture of one kind has one size.
DPI = 100
WIDTH_IN = 12.0
ROW_IN = 6.0
TITLE_IN = 1.0
# Margin around the strands, as a fraction of their extent: the views are framed on the hair.
MARGIN = 0.08
# Grey levels of the body: triangles facing the viewer are the lightest.
BODY_GREY = (0.72, 0.9)
INPUT_GREY = "0.45"
STRAND_GREY = "0.3"
# Points squared: the dots of a quantity shown at vertices.
DOT_SIZE = 12.0
LAST_FRAME = "tab:red"
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@dataclass(frozen=True)
class Quantity:
    """A ``--color`` choice: its label, the unit shown and the factor from SI to it, the colour map."""

    label: str
    unit: str
    scale: float
    cmap: str
    at_points: bool = False
    """nonzero at a few vertices only: the strands are drawn grey and those vertices as coloured dots"""


COLORS = {
    "contact-force": Quantity("net contact force per vertex", "mN", 1e3, "plasma", at_points=True),
    "rest-curvature": Quantity("rest curvature", "1/m", 1.0, "viridis"),
    "stiffening": Quantity("stiffening factor", "x material stiffness", 1.0, "cividis"),
    "fit-error": Quantity("largest fit error of the strand", "mm", 1e3, "viridis"),
}
_CHOICES = ", ".join(list(COLORS)[:-1]) + " or " + list(COLORS)[-1]


@dataclass
class Coloring:
    """The values a picture is coloured by: ``values`` per input vertex (in ``quantity.unit``), and the
    range of the quantity where it is defined (``vmin``, ``vmax``)."""

    name: str
    quantity: Quantity
    values: np.ndarray
    vmin: float
    vmax: float


def png_size(rows: int) -> tuple[int, int]:
    """(width, height) in pixels of a picture with ``rows`` rows of views."""
    return round(WIDTH_IN * DPI), round((TITLE_IN + rows * ROW_IN) * DPI)


def default_color(source: ExportSource) -> str | None:
    """Contact force for a model whose contacts carry force, its rest curvature for one without (a
    gravity-only model), the fit error for a fitted file, nothing for a file without helices."""
    if source.model is not None:
        force = source.vertex_values().get("contact_force")
        return "contact-force" if force is not None and np.any(force[0] > 0) else "rest-curvature"
    return "fit-error" if source.helices is not None else None


def coloring(source: ExportSource, name: str, output: Path) -> Coloring:
    """The values of quantity ``name`` on the input vertices, or an :class:`InputError` naming the file."""
    if name not in COLORS:
        raise InputError(f"--color takes {_CHOICES}, not {name!r}", output)
    quantity = COLORS[name]
    per_strand = np.repeat(np.arange(source.n_strands), np.diff(source.offsets))
    if name in ("contact-force", "rest-curvature"):
        if source.model is None:
            raise InputError(f"has no /model group, so it has no {quantity.label} to colour by; run `hairinv "
                             "invert` on it first", source.path)
        values = source.vertex_values().get(name.replace("-", "_"))
        if values is None:
            raise InputError("has no contact forces matching its /contacts to colour by", source.path)
        values = values[0] * quantity.scale
        return Coloring(name, quantity, values, float(values.min()), float(values.max()))
    strand_values = source.strand_values()
    key = "stiffening" if name == "stiffening" else "fit_error_max"
    if key not in strand_values:
        why = ("has no stiffening factors (a model inverted with --stabilize off, or no /model group)"
               if name == "stiffening" else "has no /helices group, so it has no fit error")
        raise InputError(f"{why}; choose another --color", source.path)
    per = strand_values[key][0] * quantity.scale
    return Coloring(name, quantity, per[per_strand], float(per.min()), float(per.max()))


def _segments(points2d: np.ndarray, offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Segments (n, 2, 2) joining consecutive vertices of each strand, and the first vertex of each."""
    starts = np.arange(len(points2d) - 1)
    inside = np.ones(len(starts), dtype=bool)
    inside[offsets[1:-1] - 1] = False  # no segment from a strand's tip to the next root
    starts = starts[inside & (starts < offsets[-1] - 1)]
    return np.stack([points2d[starts], points2d[starts + 1]], axis=1), starts


def _view(points: np.ndarray, side: bool) -> tuple[np.ndarray, np.ndarray]:
    """(horizontal, vertical) screen coordinates and depth towards the viewer, of points in the Y-up frame."""
    if side:  # looking along -X, seen from +X: z increases to the viewer's left; drawn as it increases
        return points[:, [2, 1]], points[:, 0]
    return points[:, [0, 1]], points[:, 2]


def _draw_body(ax, mesh, rotation: np.ndarray, side: bool) -> None:
    from matplotlib.collections import PolyCollection

    vertices = np.asarray(mesh.vertices, dtype=np.float64) @ rotation.T
    faces = np.asarray(mesh.faces, dtype=np.int64)
    screen, depth = _view(vertices, side)
    tri = vertices[faces]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(normal, axis=1)
    facing = np.abs(normal[:, 0 if side else 2]) / np.where(length > 0, length, 1.0)
    grey = BODY_GREY[0] + (BODY_GREY[1] - BODY_GREY[0]) * facing
    order = np.argsort(depth[faces].mean(axis=1))  # back to front
    polys = PolyCollection(screen[faces[order]], facecolors=np.repeat(grey[order, None], 3, axis=1),
                           edgecolors="none", zorder=1)
    ax.add_collection(polys)


def _frame_axes(ax, screen: np.ndarray, title: str, horizontal: str) -> None:
    lo, hi = screen.min(axis=0), screen.max(axis=0)
    pad = MARGIN * max(float((hi - lo).max()), 1e-6)
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_aspect("equal", adjustable="box")
    ax.set_title(title, fontsize=11)
    ax.set_xlabel(f"{horizontal} (m)")
    ax.set_ylabel("up (m)")
    ax.tick_params(labelsize=8)


def draw(source: ExportSource, color: str | None, output: Path):
    """The figure (matplotlib, Agg) and what it shows: ``(figure, coloring or None, rows, lines)``."""
    from matplotlib.collections import LineCollection
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure

    name = color if color is not None else default_color(source)
    paint = None if name is None else coloring(source, name, output)
    axes = OutputAxes.onto(source.up, "y")
    rotation = axes.rotation
    points = axes.points(source.points)
    mesh, body_note = source.body()
    lines = [body_note if mesh is not None else f"no body drawn: {body_note}"]
    rows = 2 if source.n_frames else 1
    width, height = png_size(rows)
    fig = Figure(figsize=(width / DPI, height / DPI), dpi=DPI)
    grid = fig.add_gridspec(rows, 3, width_ratios=[1.0, 1.0, 0.05], left=0.07, right=0.93, wspace=0.25,
                            hspace=0.3, top=1.0 - TITLE_IN / (height / DPI) - 0.02, bottom=0.7 / (height / DPI))
    what = "input shape" if paint is None else f"input shape coloured by {paint.quantity.label}"
    fig.suptitle(f"{source.name}: {what}", fontsize=13)
    norm = None
    if paint is not None:
        vmin, vmax = paint.vmin, paint.vmax
        if vmax <= vmin:  # one value everywhere: a range around it, so the colour bar can be drawn
            vmin, vmax = vmin - 0.5 * max(abs(vmin), 1.0), vmax + 0.5 * max(abs(vmax), 1.0)
        norm = Normalize(vmin, vmax)
    for column, (side, label, horizontal) in enumerate(((False, "front", "x"), (True, "side", "z"))):
        ax = fig.add_subplot(grid[0, column])
        screen, _ = _view(points, side)
        if mesh is not None:
            _draw_body(ax, mesh, rotation, side)
        segments, starts = _segments(screen, source.offsets)
        if paint is None:
            collection = LineCollection(segments, colors="tab:brown", linewidths=0.6, zorder=2)
        elif paint.quantity.at_points:
            ax.add_collection(LineCollection(segments, colors=STRAND_GREY, linewidths=0.6, zorder=2))
            loaded = np.flatnonzero(paint.values > 0)
            loaded = loaded[np.argsort(paint.values[loaded], kind="stable")]
            collection = ax.scatter(screen[loaded, 0], screen[loaded, 1], c=paint.values[loaded], s=DOT_SIZE,
                                    cmap=paint.quantity.cmap, norm=norm, edgecolors="none", zorder=3)
        else:
            value = np.maximum(paint.values[starts], paint.values[starts + 1])
            order = np.argsort(value, kind="stable")
            collection = LineCollection(segments[order], array=value[order], cmap=paint.quantity.cmap, norm=norm,
                                        linewidths=0.8, zorder=2)
        if not paint or not paint.quantity.at_points:
            ax.add_collection(collection)
        _frame_axes(ax, screen, f"{label} view", horizontal)
    if paint is not None:
        bar = fig.colorbar(collection, cax=fig.add_subplot(grid[0, 2]))
        label = f"{paint.quantity.label} ({paint.quantity.unit})"
        if paint.vmax <= paint.vmin:
            bar.set_ticks([paint.vmin])
            label += f": {paint.vmin:.4g} everywhere"
        bar.set_label(label)
        lines.append(f"colour: {paint.quantity.label}, {paint.vmin:.4g} to {paint.vmax:.4g} {paint.quantity.unit}")
    if rows == 2:
        last = source.n_frames - 1
        frame = source.frame(last)
        moved = None
        if frame.points.shape == source.points.shape:
            moved = 1e3 * float(np.linalg.norm(frame.points - source.points, axis=1).max())
        after = axes.points(frame.points)
        for column, (side, label, horizontal) in enumerate(((False, "front", "x"), (True, "side", "z"))):
            ax = fig.add_subplot(grid[1, column])
            screen, _ = _view(points, side)
            screen_after, _ = _view(after, side)
            if mesh is not None:
                _draw_body(ax, mesh, rotation, side)
            ax.add_collection(LineCollection(_segments(screen, source.offsets)[0], colors=INPUT_GREY,
                                             linewidths=1.4, zorder=2, label="input"))
            ax.add_collection(LineCollection(_segments(screen_after, frame.offsets)[0], colors=LAST_FRAME,
                                             linewidths=0.6, zorder=3, label=frame.label))
            _frame_axes(ax, np.concatenate([screen, screen_after]), f"before/after, {label} view", horizontal)
            ax.legend(loc="upper right", fontsize=8, framealpha=0.8)
        scene = source.frames.attrs.get("scene", "")
        note = f"{scene} scene, " if scene else ""
        if moved is not None:
            note += f"the last frame's vertices are at most {moved:.3g} mm from the input's"
        else:
            note += "the last frame is on the trimmed strands"
        fig.text(0.5, 1.0 - (TITLE_IN + ROW_IN - 0.1) / (height / DPI), f"before/after: the input (grey) against "
                 f"{frame.label} (red); {note}", ha="center", fontsize=11)
        lines.append(f"before/after: the input against {frame.label}; {note}")
    return fig, paint, rows, lines


def _owns(path: Path) -> bool:
    """A PNG file: hairinv replaces a picture, not another kind of file under a .png name."""
    try:
        with open(path, "rb") as fh:
            return fh.read(len(PNG_SIGNATURE)) == PNG_SIGNATURE
    except OSError:
        return False


def _metadata(paint: Coloring | None, source: ExportSource) -> dict:
    meta = {"Title": f"{source.name}", "Software": f"hairinv {__version__}", "Source": source.name}
    if paint is not None:
        meta.update({"hairinv:quantity": paint.name, "hairinv:unit": paint.quantity.unit,
                     "hairinv:min": repr(paint.vmin), "hairinv:max": repr(paint.vmax)})
    return meta


@dataclass
class Picture:
    """A drawn picture: the PNG's bytes, what it is coloured by, its size and what to tell the user."""

    png: bytes
    coloring: Coloring | None
    size: tuple[int, int]
    lines: list[str]
    warnings: list[str]


def picture(source: ExportSource, color: str | None, output: Path) -> Picture:
    """Draw the picture of ``source`` (see the module docstring) into PNG bytes."""
    import io

    fig, paint, rows, lines = draw(source, color, Path(output))
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=DPI, metadata=_metadata(paint, source))
    warnings = []
    if lines and lines[0].startswith("no body drawn") and "records no body" not in lines[0]:
        # the file names a body that is gone or changed: say so as USD does
        warnings.append(f"warning: {source.name}: {lines.pop(0).removeprefix('no body drawn: ')}; the picture "
                        "has no body")
    return Picture(buffer.getvalue(), paint, png_size(rows), lines, warnings)


# ``--plot``: what the PNG of one stage file shows (docs/export.md).
PLOTS = ("groom", "convergence")


def _export_convergence(source, path: Path, report) -> None:
    history, why = convergence_of(source)
    if history is None:
        raise InputError(why, source.path)
    png, lines = convergence_png(history, source)
    write_bytes(path, png)
    width, height = convergence_size()
    report.lines.append(f"wrote {path}: PNG, {width} x {height} px, the contact solver's relative residual against "
                        "the sweeps")
    report.lines += lines


@register_exporter(".png", name="PNG", default_shape=None, options=("color", "plot"), owns=_owns)
def export_png(source, path, shape, report, color: str | None = None, plot: str | None = None) -> None:
    if plot is not None and plot not in PLOTS:
        raise InputError(f"--plot takes {' or '.join(PLOTS)}, not {plot!r}", path)
    if plot == "convergence":
        if color is not None:
            raise InputError("--color applies to the picture of the groom, not to --plot convergence", path)
        _export_convergence(source, Path(path), report)
        return
    drawn = picture(source, color, Path(path))
    write_bytes(path, drawn.png)
    width, height = drawn.size
    report.lines.append(f"wrote {path}: PNG, {width} x {height} px, front and side views"
                        + (", before/after" if height > png_size(1)[1] else ""))
    report.lines += drawn.lines
    report.warnings += drawn.warnings
