"""An animated GIF of a simulation: the hair and the body at every frame, front and side views.

Each frame of ``/frames`` is drawn as the PNG picture draws a groom (:mod:`hairinv.export.picture`): the body at
that frame (a shot's deforming body from ``/frames/body_vertices``, a rigid scene's moved by
``/frames/body_transform``), the strands in front of it, those behind faded. The views keep one frame for the
whole run, so that what moves is the hair and the body, not the picture. A run of more than
:data:`MAX_FRAMES` frames is shown at every n-th frame, and the GIF says so.
"""

from __future__ import annotations

import io

import numpy as np

from ..atomic import write_bytes
from ..errors import InputError
from .base import register_exporter
from .picture import VIEWS, Body, OutputAxes, _draw_body, _draw_strands, _view, hidden_by

#: frames drawn at most (a longer run is shown at every n-th frame)
MAX_FRAMES = 240
#: pixels of one frame
SIZE = (960, 540)
DPI = 100
GIF_SIGNATURE = b"GIF8"


def _owns(path) -> bool:
    try:
        with open(path, "rb") as fh:
            return fh.read(4) == GIF_SIGNATURE
    except OSError:
        return False


def frames_shown(n_frames: int) -> np.ndarray:
    """The frames a GIF shows: all, or every n-th (and the last) of a longer run."""
    if n_frames <= MAX_FRAMES:
        return np.arange(n_frames)
    every = int(np.ceil(n_frames / MAX_FRAMES))
    shown = np.arange(0, n_frames, every)
    return shown if shown[-1] == n_frames - 1 else np.append(shown, n_frames - 1)


def _bodies(source, axes):
    """A callable giving the body drawn at frame ``k`` (picture frame), or None without a body."""
    if source.body_removed:
        return lambda k: None
    if source.body_animated:
        return lambda k: Body.posed(source.body_mesh(k), axes)
    mesh, _ = source.body()
    if mesh is None:
        return lambda k: None
    return lambda k: Body.posed(mesh, axes, source.body_transform(k))


@register_exporter(".gif", name="GIF", default_shape=None, owns=_owns)
def export_gif(source, path, shape, report) -> None:
    from matplotlib.figure import Figure
    from PIL import Image

    if not source.n_frames:
        raise InputError("holds no /frames: an animation shows a simulation (hairinv simulate)", source.path)
    axes = OutputAxes.onto(source.up, "y")
    shown = frames_shown(source.n_frames)
    body_at = _bodies(source, axes)
    strands = [source.frame(int(k)) for k in shown]
    points = [axes.points(s.points) for s in strands]
    bodies = [body_at(int(k)) for k in shown]
    # one frame of view for the whole run: every strand point and body vertex of every frame shown
    limits = []
    for side in (False, True):
        screens = [_view(p, side)[0] for p in points] + [_view(b.vertices, side)[0] for b in bodies if b is not None]
        every = np.concatenate(screens)
        lo, hi = every.min(axis=0), every.max(axis=0)
        pad = 0.05 * max(float((hi - lo).max()), 1e-6)
        limits.append((lo - pad, hi + pad))
    times = source.times
    images = []
    for index, k in enumerate(shown):
        fig = Figure(figsize=(SIZE[0] / DPI, SIZE[1] / DPI), dpi=DPI)
        for column, (side, label, horizontal) in enumerate(VIEWS):
            ax = fig.add_axes((0.02 + 0.5 * column, 0.02, 0.46, 0.88))
            body = bodies[index]
            if body is not None:
                _draw_body(ax, body, side)
            strand = strands[index]
            _draw_strands(ax, points[index], strand.offsets, side, hidden_by(body, points[index], side),
                          color="#7a3b12", linewidths=0.6)
            lo, hi = limits[column]
            ax.set_xlim(lo[0], hi[0])
            ax.set_ylim(lo[1], hi[1])
            ax.set_aspect("equal", adjustable="box")
            ax.set_axis_off()
            ax.set_title(f"{label} view", fontsize=10)
        fig.suptitle(f"{source.name}: frame {int(k)}, t = {times[k]:.3f} s", fontsize=11)
        buffer = io.BytesIO()
        fig.savefig(buffer, format="png", dpi=DPI)
        images.append(Image.open(io.BytesIO(buffer.getvalue())).convert("RGB"))
    fps = float(source.frames.attrs.get("fps", 24.0))
    step = (shown[1] - shown[0]) if len(shown) > 1 else 1
    duration = max(20, int(round(1000.0 * step / fps)))  # ms per frame shown (GIF counts in 10 ms)
    # one palette for every frame (the first's: the body's greys and the hair's colour), so nothing flickers
    first = images[0].quantize(colors=128, method=Image.Quantize.MEDIANCUT)
    palette = [first] + [image.quantize(palette=first, dither=Image.Dither.NONE) for image in images[1:]]
    out = io.BytesIO()
    palette[0].save(out, format="GIF", save_all=True, append_images=palette[1:], duration=duration, loop=0,
                    disposal=1)
    write_bytes(path, out.getvalue())
    every = f", every {step}th frame of {source.n_frames}" if step > 1 else ""
    report.lines.append(f"wrote {path}: GIF, {SIZE[0]} x {SIZE[1]} px, {len(shown)} frames{every} at "
                        f"{duration} ms each (the run's {fps:g} frames per second), front and side views")
