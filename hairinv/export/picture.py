"""PNG (matplotlib, Agg, headless): the groom from the front and the side over its body, coloured by a quantity.

Views are orthographic, in the groom's frame turned so that its up axis is vertical (+Y): the front view
looks along -Z (horizontal axis x), the side view along +X (horizontal axis z); neither is mirrored. The
body mesh, if the stage file records one that is still there unchanged (found as the USD writer finds it),
is drawn light grey, its triangles shaded by how squarely they face the viewer, at the pose of the frame
shown: at rest under the input shape, moved by ``/frames/body_transform`` of the last frame under the last
frame. Strand segments and dots are drawn far to near; those the body hides (its surface nearest the viewer
lies in front of them, found on a grid of cells by :mod:`hairinv.export._depth`) are drawn faded over it.
Each strand segment takes the larger of its two vertices' values. The colour bar runs over the values, or
over their 2nd to 98th percentiles where a few values would set its range, on a log scale where those
span two decades or more (:func:`colour_scale`); its label says which. With ``/frames`` a second row
shows the input shape, carried with the body, against the last frame.

The PNG's text chunks record what the colours mean: ``hairinv:quantity``, ``hairinv:unit``,
``hairinv:min`` and ``hairinv:max`` (the quantity's smallest and largest value over the vertices or strands
it is defined on), ``hairinv:scale``, ``hairinv:bar_min`` and ``hairinv:bar_max`` (the colour bar's scale
and limits, in that unit).

``--plot convergence`` draws the model's contact solver history instead
(:mod:`hairinv.export.convergence`), ``--plot render`` has Blender render the groom on its body
(:mod:`hairinv.export.render`); several stage files are drawn side by side by :mod:`hairinv.export.compare`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import __version__
from ..atomic import write_bytes
from ..errors import InputError
from ._depth import nearest_depth
from .base import register_exporter
from .convergence import convergence_of, convergence_png, convergence_size
from .source import ExportSource, OutputAxes

__all__ = ["COLORS", "PLOTS", "Body", "ColourScale", "Coloring", "Picture", "colour_scale", "coloring",
           "default_color", "draw", "hidden_by", "picture", "png_size"]

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
# (side, name, horizontal axis) of the two views of a row: the front view, then the side view.
VIEWS = ((False, "front", "x"), (True, "side", "z"))

# Depth: the body's surface nearest the viewer on a grid of DEPTH_CELLS cells across the strands' extent
# (about the views' own pixels: a view is some 450 pixels across). A point is hidden where that surface is
# more than DEPTH_TOLERANCE in front of it at its cell and at the 8 around it: hair lying on the scalp (a
# few tenths of a millimetre off it, some just inside) stays in front, and the surface's slope across one
# cell, which is steep at the body's outline, does not hide the strands beside it.
DEPTH_CELLS = 512
DEPTH_TOLERANCE = 2e-3  # m
# Opacity of what the body hides, drawn over it: there, but not in front of the face.
HIDDEN_ALPHA = 0.12

# The colour scale (:func:`colour_scale`): where the spread between these quantiles is less than
# OUTLIER_SHARE of the values' whole range, a few values would take most of the colour bar, so the bar runs
# between the quantiles; where the upper quantile is LOG_SPAN times the lower or more (two decades), the
# bar is logarithmic between the quantiles. The quantiles are values that occur (numpy's ``inverted_cdf``):
# 98 strands of stiffening 1 and two stiffened keep the whole range, 1 to the largest factor, where an
# interpolated 98th percentile (1.02) would draw both stiffened strands in one clipped colour.
QUANTILES = (0.02, 0.98)
QUANTILE_METHOD = "inverted_cdf"
OUTLIER_SHARE = 0.5
LOG_SPAN = 100.0


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


@dataclass(frozen=True)
class ColourScale:
    """How values map onto the colour map: linearly or logarithmically from ``vmin`` to ``vmax``; values
    beyond take the end colours. ``clipped``: the limits are the :data:`QUANTILES` of the values, not their
    extremes."""

    vmin: float
    vmax: float
    log: bool = False
    clipped: bool = False

    @property
    def kind(self) -> str:
        """``linear``, ``linear, 2-98 % quantiles`` or ``log, 2-98 % quantiles`` (the PNG's ``hairinv:scale``)."""
        lo, hi = (f"{100 * q:g}" for q in QUANTILES)
        return ("log" if self.log else "linear") + (f", {lo}-{hi} % quantiles" if self.clipped else "")

    @property
    def note(self) -> str:
        """What the colour bar's label adds: empty for a linear bar over every value."""
        if not self.clipped:
            return ""
        lo, hi = (f"{100 * q:g}" for q in QUANTILES)
        return ("log scale, " if self.log else "") + f"{lo}-{hi} % quantiles; beyond clipped"

    def norm(self):
        from matplotlib.colors import LogNorm, Normalize

        vmin, vmax = self.vmin, self.vmax
        if vmax <= vmin:  # one value everywhere: a range around it, so the colour bar can be drawn
            return Normalize(vmin - 0.5 * max(abs(vmin), 1.0), vmax + 0.5 * max(abs(vmax), 1.0))
        return LogNorm(vmin, vmax) if self.log else Normalize(vmin, vmax)

    def clip(self, values: np.ndarray) -> np.ndarray:
        """``values`` within the limits: those beyond are drawn in the end colours (a log scale would leave
        zeros out)."""
        return np.clip(values, self.vmin, self.vmax) if self.vmax > self.vmin else values

    def extend(self, values: np.ndarray) -> str:
        """The colour bar's ``extend``: an arrow at each end beyond which values were clipped."""
        below = bool(np.any(values < self.vmin))
        above = bool(np.any(values > self.vmax))
        return {(False, False): "neither", (True, False): "min", (False, True): "max"}.get((below, above), "both")


def colour_scale(values: np.ndarray) -> ColourScale:
    """The colour bar's scale for ``values`` (the finite ones): between their 2nd and 98th percentiles
    (:data:`QUANTILES`, values that occur) where that spread is less than half their whole range, on a log
    scale where the 98th percentile is 100 times the 2nd or more (:data:`OUTLIER_SHARE`, :data:`LOG_SPAN`);
    else linear from the smallest to the largest."""
    values = np.asarray(values, dtype=np.float64)
    values = values[np.isfinite(values)]
    if len(values) == 0:
        return ColourScale(0.0, 0.0)
    lo, hi = float(values.min()), float(values.max())
    q_lo, q_hi = (float(q) for q in np.quantile(values, QUANTILES, method=QUANTILE_METHOD))
    if q_hi > q_lo:  # an empty spread (most values equal: stiffening 1) leaves the extremes to show
        if q_lo > 0.0 and q_hi >= LOG_SPAN * q_lo:
            return ColourScale(q_lo, q_hi, log=True, clipped=True)
        if q_hi - q_lo < OUTLIER_SHARE * (hi - lo):
            return ColourScale(q_lo, q_hi, clipped=True)
    return ColourScale(lo, hi)


@dataclass
class Coloring:
    """The values a picture is coloured by: ``values`` per input vertex (in ``quantity.unit``), the range of
    the quantity where it is defined (``vmin``, ``vmax``) and the colour bar's scale. A quantity drawn as
    dots has one at each vertex whose value exceeds ``floor``."""

    name: str
    quantity: Quantity
    values: np.ndarray
    vmin: float
    vmax: float
    scale: ColourScale | None = None
    floor: float = 0.0

    @property
    def dotted(self) -> np.ndarray:
        """Indices of the vertices drawn as dots."""
        return np.flatnonzero(self.values > self.floor)

    @property
    def bar(self) -> ColourScale:
        return self.scale if self.scale is not None else ColourScale(self.vmin, self.vmax)

    def describe(self) -> str:
        """The values and the colour bar in words: ``0 to 0.75 mN; colour bar 0.01 to 0.3 mN, log scale, 2-98 %
        quantiles; beyond clipped``, or ``0.01 to 0.3 mN`` where the bar runs over every value."""
        bar, unit = self.bar, self.quantity.unit
        text = f"{self.vmin:.4g} to {self.vmax:.4g} {unit}"
        if bar.clipped:
            text += f"; colour bar {bar.vmin:.4g} to {bar.vmax:.4g} {unit}, {bar.note}"
        return text


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
    """The values of quantity ``name`` on the input vertices, or an :class:`InputError` naming the file.

    The colour bar's scale is set by the values where they are drawn: for ``contact-force`` the vertices
    that carry force, above ``/model`` ``carrying_threshold`` as ``invert`` counts contacts carrying force
    (the others are not dotted), every vertex for ``rest-curvature``, every strand (once each) for the
    per-strand quantities."""
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
        floor = quantity.scale * float(source.model.attrs.get("carrying_threshold", 0.0)) if quantity.at_points \
            else 0.0
        drawn = values[values > floor] if quantity.at_points else values
        return Coloring(name, quantity, values, float(values.min()), float(values.max()), colour_scale(drawn), floor)
    strand_values = source.strand_values()
    key = "stiffening" if name == "stiffening" else "fit_error_max"
    if key not in strand_values:
        why = ("has no stiffening factors (a model inverted with --stabilize off, or no /model group)"
               if name == "stiffening" else "has no /helices group, so it has no fit error")
        raise InputError(f"{why}; choose another --color", source.path)
    per = strand_values[key][0] * quantity.scale
    return Coloring(name, quantity, per[per_strand], float(per.min()), float(per.max()), colour_scale(per))


def _segments(points2d: np.ndarray, offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Segments (n, 2, 2) joining consecutive vertices of each strand, and the first vertex of each."""
    starts = np.arange(len(points2d) - 1)
    inside = np.ones(len(starts), dtype=bool)
    inside[offsets[1:-1] - 1] = False  # no segment from a strand's tip to the next root
    starts = starts[inside & (starts < offsets[-1] - 1)]
    return np.stack([points2d[starts], points2d[starts + 1]], axis=1), starts


def _view(points: np.ndarray, side: bool) -> tuple[np.ndarray, np.ndarray]:
    """(horizontal, vertical) screen coordinates (n, 2) and depth towards the viewer (n,), m, of points
    (n, 3) in the Y-up frame.

    Front: the viewer at +Z looks along -Z, x to the right. Side: the viewer at -X looks along +X, z to the
    right (right = forward x up, as for the front view), so the picture is what that viewer sees, not its
    mirror image."""
    if side:
        return points[:, [2, 1]], np.ascontiguousarray(-points[:, 0])
    return points[:, [0, 1]], np.ascontiguousarray(points[:, 2])


@dataclass(frozen=True)
class Body:
    """The body mesh where a picture shows it.

    Attributes
    ----------
    vertices : (V, 3) float64, m, the picture's Y-up frame
    faces : (T, 3) int64
    """

    vertices: np.ndarray
    faces: np.ndarray

    @classmethod
    def posed(cls, mesh, axes: OutputAxes, transform: np.ndarray | None = None) -> Body:
        """``mesh`` (trimesh, m, the groom's frame, at rest) moved by the rigid ``transform`` (4, 4) from the
        body's rest pose to the pose shown (``/frames/body_transform`` of a frame; None: at rest), then
        turned with ``axes`` into the picture's frame."""
        vertices = np.asarray(mesh.vertices, dtype=np.float64)
        if transform is not None:
            vertices = vertices @ transform[:3, :3].T + transform[:3, 3]
        return cls(np.ascontiguousarray(axes.points(vertices)), np.ascontiguousarray(mesh.faces, dtype=np.int64))


def hidden_by(body: Body | None, points: np.ndarray, side: bool) -> np.ndarray:
    """(n,) bool: which of ``points`` (n, 3), m, picture frame, the body hides in the view ``side``.

    A point is hidden where the body's surface nearest the viewer lies more than :data:`DEPTH_TOLERANCE` in
    front of it, at the cell of a :data:`DEPTH_CELLS` grid over the points that holds it and at the 8 cells
    around it; so a point beside the body's outline or on its surface is not hidden."""
    hidden = np.zeros(len(points), dtype=bool)
    if body is None or len(points) == 0 or len(body.faces) == 0:
        return hidden
    screen, depth = _view(points, side)
    lo, hi = screen.min(axis=0), screen.max(axis=0)
    cell = max(float((hi - lo).max()), 1e-3) / DEPTH_CELLS
    origin = lo - 2.0 * cell
    nx, ny = (np.ceil((hi - lo) / cell).astype(np.int64) + 4).tolist()
    near = np.full((ny, nx), -np.inf)
    body_screen, body_depth = _view(body.vertices, side)
    nearest_depth(np.ascontiguousarray(body_screen), body_depth, body.faces, float(origin[0]), float(origin[1]),
                  cell, near)
    padded = np.pad(near, 1, constant_values=-np.inf)
    cover = near.copy()
    for dj in range(3):
        for di in range(3):
            np.minimum(cover, padded[dj:dj + ny, di:di + nx], out=cover)
    i = np.clip(((screen[:, 0] - origin[0]) / cell).astype(np.int64), 0, nx - 1)
    j = np.clip(((screen[:, 1] - origin[1]) / cell).astype(np.int64), 0, ny - 1)
    return cover[j, i] > depth + DEPTH_TOLERANCE


def _draw_body(ax, body: Body, side: bool) -> None:
    from matplotlib.collections import PolyCollection

    vertices, faces = body.vertices, body.faces
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


def _faded_zorder(zorder: float) -> float:
    """Hidden strands and dots lie over the body (zorder 1) and under every visible one (zorder 2 and up)."""
    return 1.0 + 0.1 * zorder


def _draw_strands(ax, points: np.ndarray, offsets: np.ndarray, side: bool, hidden: np.ndarray, *, color=None,
                  values=None, cmap=None, norm=None, linewidths: float = 0.6, zorder: float = 2.0,
                  label: str | None = None) -> None:
    """Strand segments far to near, in ``color`` or coloured by per-vertex ``values`` (a segment takes the
    larger of its two vertices'); a segment whose two ends the body hides is drawn faded."""
    from matplotlib.collections import LineCollection

    screen, depth = _view(points, side)
    segments, starts = _segments(screen, offsets)
    far = 0.5 * (depth[starts] + depth[starts + 1])
    faded = hidden[starts] & hidden[starts + 1]
    value = None if values is None else np.maximum(values[starts], values[starts + 1])
    for fade in (True, False):
        pick = np.flatnonzero(faded == fade)
        pick = pick[np.argsort(far[pick], kind="stable")]
        style = {"linewidths": linewidths, "alpha": HIDDEN_ALPHA if fade else 1.0,
                 "zorder": _faded_zorder(zorder) if fade else zorder}
        if value is None:
            style["colors"] = color
        else:
            style.update(array=value[pick], cmap=cmap, norm=norm)
        if label is not None and not fade:
            style["label"] = label
        ax.add_collection(LineCollection(segments[pick], **style))


def _draw_dots(ax, points: np.ndarray, side: bool, hidden: np.ndarray, values: np.ndarray, cmap, norm,
               zorder: float = 3.0) -> None:
    """Dots at ``points`` coloured by ``values``, far to near; those the body hides drawn faded."""
    screen, depth = _view(points, side)
    for fade in (True, False):
        pick = np.flatnonzero(hidden == fade)
        if len(pick):
            pick = pick[np.argsort(depth[pick], kind="stable")]
            ax.scatter(screen[pick, 0], screen[pick, 1], c=values[pick], s=DOT_SIZE, cmap=cmap, norm=norm,
                       edgecolors="none", alpha=HIDDEN_ALPHA if fade else 1.0,
                       zorder=_faded_zorder(zorder) if fade else zorder)


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
    from matplotlib.cm import ScalarMappable
    from matplotlib.figure import Figure

    name = color if color is not None else default_color(source)
    paint = None if name is None else coloring(source, name, output)
    axes = OutputAxes.onto(source.up, "y")
    points = axes.points(source.points)
    if source.body_animated and not float(source.frames.attrs.get("preroll", 0.0)):
        # a shot: the body as its first frame shows it, the groom's pose (after a pre-roll, the body file's)
        mesh, body_note = source.body_mesh(0), "body: the shot's animated body, as the frames keep it"
    else:
        mesh, body_note = source.body()
    body = None if mesh is None else Body.posed(mesh, axes)
    lines = [body_note if mesh is not None else f"no body drawn: {body_note}"]
    rows = 2 if source.n_frames else 1
    width, height = png_size(rows)
    fig = Figure(figsize=(width / DPI, height / DPI), dpi=DPI)
    grid = fig.add_gridspec(rows, 3, width_ratios=[1.0, 1.0, 0.05], left=0.07, right=0.93, wspace=0.25,
                            hspace=0.3, top=1.0 - TITLE_IN / (height / DPI) - 0.02, bottom=0.7 / (height / DPI))
    what = "input shape" if paint is None else f"input shape coloured by {paint.quantity.label}"
    fig.suptitle(f"{source.name}: {what}", fontsize=13)
    norm = cmap = values = None
    if paint is not None:
        norm, cmap = paint.bar.norm(), paint.quantity.cmap
        values = paint.bar.clip(paint.values)
    for column, (side, label, horizontal) in enumerate(VIEWS):
        ax = fig.add_subplot(grid[0, column])
        if body is not None:
            _draw_body(ax, body, side)
        hidden = hidden_by(body, points, side)
        if paint is None:
            _draw_strands(ax, points, source.offsets, side, hidden, color="tab:brown")
        elif paint.quantity.at_points:
            _draw_strands(ax, points, source.offsets, side, hidden, color=STRAND_GREY)
            loaded = paint.dotted
            _draw_dots(ax, points[loaded], side, hidden[loaded], values[loaded], cmap, norm)
        else:
            _draw_strands(ax, points, source.offsets, side, hidden, values=values, cmap=cmap, norm=norm,
                          linewidths=0.8)
        _frame_axes(ax, _view(points, side)[0], f"{label} view", horizontal)
    if paint is not None:
        bar_scale = paint.bar
        shown = paint.values[paint.dotted] if paint.quantity.at_points else paint.values
        bar = fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), cax=fig.add_subplot(grid[0, 2]),
                           extend=bar_scale.extend(shown))
        bar.outline.set_visible(False)  # the colours, and the arrows of clipped ends, stand without a frame
        label = f"{paint.quantity.label} ({paint.quantity.unit})"
        if bar_scale.vmax <= bar_scale.vmin:
            bar.set_ticks([bar_scale.vmin])
            label += f": {bar_scale.vmin:.4g} " + ("at every dot" if paint.quantity.at_points else "everywhere")
        elif bar_scale.note:
            label += f",\n{bar_scale.note}"
        bar.set_label(label)
        lines.append(f"colour: {paint.quantity.label}, {paint.describe()}")
    if rows == 2:
        lines.append(_before_after(fig, grid, source, axes, mesh, height))
    return fig, paint, rows, lines


def _before_after(fig, grid, source: ExportSource, axes: OutputAxes, mesh, height: float) -> str:
    """The second row: the input, carried with the body, against the last frame; the line saying so."""
    last = source.n_frames - 1
    frame = source.frame(last)
    pose = source.body_transform(last)
    if source.body_animated:  # each strand carried by its own root's frame
        carried = source.carried(last)
        turned = not np.allclose(carried, source.points, rtol=0.0, atol=1e-12)
    else:
        carried = source.points @ pose[:3, :3].T + pose[:3, 3]  # the input where the body has taken it
        turned = not np.allclose(pose, np.eye(4), rtol=0.0, atol=1e-12)
    moved = None
    if frame.points.shape == carried.shape:
        moved = 1e3 * float(np.linalg.norm(frame.points - carried, axis=1).max())
    if source.body_animated and not source.body_removed:
        body = Body.posed(source.body_mesh(last), axes)
    else:
        body = None if mesh is None or source.body_removed else Body.posed(mesh, axes, pose)
    before, after = axes.points(carried), axes.points(frame.points)
    for column, (side, label, horizontal) in enumerate(VIEWS):
        ax = fig.add_subplot(grid[1, column])
        if body is not None:
            _draw_body(ax, body, side)
        _draw_strands(ax, before, source.offsets, side, hidden_by(body, before, side), color=INPUT_GREY,
                      linewidths=1.4, zorder=2.0, label="input")
        _draw_strands(ax, after, frame.offsets, side, hidden_by(body, after, side), color=LAST_FRAME,
                      linewidths=0.6, zorder=3.0, label=frame.label)
        _frame_axes(ax, np.concatenate([_view(before, side)[0], _view(after, side)[0]]),
                    f"before/after, {label} view", horizontal)
        ax.legend(loc="upper right", fontsize=8, framealpha=0.8)
    scene = source.frames.attrs.get("scene", "")
    note = "a shot (animated body), " if source.body_animated else (f"{scene} scene, " if scene else "")
    if source.body_removed:
        note += "the body removed, "
    if moved is not None:
        note += f"the last frame's vertices are at most {moved:.3g} mm from the input's"
    else:
        note += "the last frame is on the trimmed strands"
    carried_note = (", each strand carried by its root's triangle," if source.body_animated else
                    ", moved with the body,") if turned else ""
    fig.text(0.5, 1.0 - (TITLE_IN + ROW_IN - 0.25) / (height / DPI), f"before/after: the input (grey){carried_note} "
             f"against {frame.label} (red)\n{note}", ha="center", va="center", fontsize=11)
    return f"before/after: the input{carried_note} against {frame.label}; {note}"


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
                     "hairinv:min": repr(paint.vmin), "hairinv:max": repr(paint.vmax),
                     "hairinv:scale": paint.bar.kind, "hairinv:bar_min": repr(paint.bar.vmin),
                     "hairinv:bar_max": repr(paint.bar.vmax)})
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


# ``--plot``: what the PNG of one stage file shows (docs/export.md); ``render``: a still rendered by Blender
# (:mod:`hairinv.export.render`).
PLOTS = ("groom", "convergence", "render")


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
        raise InputError(f"--plot takes {', '.join(PLOTS[:-1])} or {PLOTS[-1]}, not {plot!r}", path)
    if plot in ("convergence", "render"):
        if color is not None:
            raise InputError(f"--color applies to the picture of the groom, not to --plot {plot}", path)
        if plot == "render":
            from .render import export_render

            export_render(source, Path(path), report)
        else:
            _export_convergence(source, Path(path), report)
        return
    drawn = picture(source, color, Path(path))
    write_bytes(path, drawn.png)
    width, height = drawn.size
    report.lines.append(f"wrote {path}: PNG, {width} x {height} px, front and side views"
                        + (", before/after" if height > png_size(1)[1] else ""))
    report.lines += drawn.lines
    report.warnings += drawn.warnings
