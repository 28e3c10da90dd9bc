"""The contact solver's convergence of a model (PNG with ``--plot convergence``, and in the HTML report).

``invert`` stores the solver's residual at every check (``/model/residual_history``: sweep, the largest
natural-map residual over the contacts in newtons; docs/stage-files.md). The solver stops when that
residual falls below ``solver.tolerance`` times the weight of the heaviest strand (linear density times
``|g|`` times the longest fitted strand's length, :func:`hairinv.invert.invert`), and the model's
``relative_residual`` is its last residual over that weight. The plot draws the same ratio against the
sweeps, on a log scale, with the tolerance (``/model`` ``config`` ``solver.tolerance``) as a horizontal line
and the residual in newtons on the right-hand axis; the title gives the solver's status.

A gravity-only model, or one without contacts, solved for no contact force: it has no history to plot, and
:func:`convergence_of` says so instead.

The PNG's text chunks record what is plotted: ``hairinv:plot`` (``convergence``), ``hairinv:sweeps`` and
``hairinv:relative_residual`` (JSON lists, the points drawn), ``hairinv:tolerance``, ``hairinv:status`` and
``hairinv:force_scale_N`` (the heaviest strand's weight the residual is divided by).
"""

from __future__ import annotations

import io
import json
from dataclasses import dataclass

import numpy as np

from .. import __version__
from .source import ExportSource

__all__ = ["Convergence", "convergence_figure", "convergence_of", "convergence_png", "convergence_size"]

# 100 dots per inch, as the groom picture; 10 x 6 inches.
DPI = 100
WIDTH_IN = 10.0
HEIGHT_IN = 6.0
RESIDUAL = "tab:blue"
TOLERANCE = "tab:red"


@dataclass
class Convergence:
    """A model's solver history.

    Attributes
    ----------
    sweeps : (n,) int64, the sweeps of this run at which the residual was checked
    residual : (n,) float64, N, the largest natural-map residual over the contacts at each check
    force_scale : float, N, the heaviest strand's weight, the residual's scale
    tolerance : float or None, relative, the solver's stopping tolerance (None: not recorded)
    status : str, ``CONVERGED``, ``MAX_ITERS``, ...
    iterations : int, sweeps of this run
    prior_sweeps : int, sweeps of the earlier runs whose forces this one started from
    method : str, "sweeps" or "interior-point" (``/model`` attribute ``method``)
    interior_steps : int, the interior point's steps (0 for the sweeps)
    rest_bound : float or None, 1/m, the bound on the rest shape's distance from the optimum the model records
    rest_tolerance : float or None, 1/m, ``solver.rest_tolerance``: what the interior point stops on
    """

    sweeps: np.ndarray
    residual: np.ndarray
    force_scale: float
    tolerance: float | None
    status: str
    iterations: int
    prior_sweeps: int
    method: str = "sweeps"
    interior_steps: int = 0
    rest_bound: float | None = None
    rest_tolerance: float | None = None

    @property
    def relative(self) -> np.ndarray:
        """(n,) float64, the residual over the heaviest strand's weight (what the tolerance applies to)."""
        return self.residual / self.force_scale


def convergence_of(source: ExportSource) -> tuple[Convergence | None, str]:
    """The solver history of ``source``'s model, or None and one sentence saying why it has none."""
    model = source.model
    if model is None:
        return None, "has no /model group, so it has no solver convergence to plot; run `hairinv invert` on it first"
    if str(model.attrs.get("target", "")) == "gravity-only":
        return None, ("is a gravity-only model: its inversion solves for no contact force, so it has no solver "
                      "convergence to plot")
    if len(model["force"]) == 0:
        return None, ("declares no contacts: its inversion solved for no contact force, so it has no solver "
                      "convergence to plot")
    if "residual_history" not in model.datasets or len(model["residual_history"]) == 0:
        return None, "records no residual history (a model written before hairinv stored it)"
    history = np.asarray(model["residual_history"], dtype=np.float64).reshape(-1, 2)
    a = model.attrs
    linear_density = float(a["density"]) * np.pi * float(a["radius"]) ** 2
    h = source.helices
    longest = float(np.add.reduceat(h.length, h.offsets[:-1]).max())
    force_scale = linear_density * float(np.linalg.norm(a["gravity"])) * longest
    solver = model.config.get("solver", {})
    tolerance, rest_tolerance = solver.get("tolerance"), solver.get("rest_tolerance")
    return Convergence(history[:, 0].astype(np.int64), history[:, 1], force_scale,
                       None if tolerance is None else float(tolerance), str(a.get("status", "")),
                       int(a.get("iterations", 0)), int(a.get("prior_sweeps", 0)), str(a.get("method", "sweeps")),
                       int(a.get("interior_steps", 0)), float(a["rest_bound"]) if "rest_bound" in a else None,
                       None if rest_tolerance is None else float(rest_tolerance)), ""


def convergence_size() -> tuple[int, int]:
    """(width, height) in pixels of the convergence plot."""
    return round(WIDTH_IN * DPI), round(HEIGHT_IN * DPI)


def convergence_figure(c: Convergence, name: str):
    """The figure (matplotlib, Agg) of the relative residual against the sweeps, and lines for the user."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(WIDTH_IN, HEIGHT_IN), dpi=DPI)
    ax = fig.add_subplot()
    fig.subplots_adjust(left=0.11, right=0.88, top=0.87, bottom=0.13)
    shown = c.residual > 0  # a residual of exactly 0 has no place on a log scale: said below the plot
    ax.plot(c.sweeps[shown], c.relative[shown], "o-", color=RESIDUAL, markersize=3, linewidth=1.2,
            label="largest residual over the contacts / the heaviest strand's weight")
    ax.set_yscale("log")
    if c.tolerance is not None:
        ax.axhline(c.tolerance, color=TOLERANCE, linestyle="--", linewidth=1.2,
                   label=f"solver.tolerance = {c.tolerance:g}")
    ax.set_xlabel("sweep" + (f" of this run (it started from the forces of {c.prior_sweeps} earlier sweeps)"
                             if c.prior_sweeps else ""))
    ax.set_ylabel("relative residual")
    scale = c.force_scale
    right = ax.secondary_yaxis("right", functions=(lambda y: y * scale, lambda n: n / scale))
    right.set_ylabel(f"residual (N; heaviest strand's weight {scale:.3g} N)")
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(loc="upper right", fontsize=9, framealpha=0.9)
    last = f", relative residual {c.relative[-1]:.2g}" if len(c.relative) else ""
    status = c.status or "status unrecorded"
    notes = []
    if c.method == "interior-point" and c.iterations == 0:
        # the steps' forces were final: what stopped them is the rest-shape bound, not the residual drawn here
        bound = "" if c.rest_bound is None else f", rest shape within {c.rest_bound:.2g} 1/m of the optimum"
        wanted = "" if c.rest_tolerance is None else f" (solver.rest_tolerance {c.rest_tolerance:g})"
        ax.set_title(f"{name}: contact solver {status} after {c.interior_steps} interior-point steps{bound}",
                     fontsize=11)
        lines = [f"convergence: {status} after {c.interior_steps} interior-point steps{bound}{wanted}, the "
                 f"criterion that method stops on; the residual drawn, {c.relative[-1]:.3g} of the heaviest "
                 "strand's weight at the forces returned, is the sweeps' criterion, not its"]
        notes.append("interior point: no sweeps ran; the point is the residual of the forces it returned")
    else:
        ax.set_title(f"{name}: contact solver {status} after {c.iterations} sweeps{last}", fontsize=12)
        lines = [f"convergence: {status} after {c.iterations} sweeps, {len(c.sweeps)} "
                 f"checks, relative residual {c.relative[0]:.3g} to {c.relative[-1]:.3g}"
                 + ("" if c.tolerance is None else f" (tolerance {c.tolerance:g})")]
    if not np.all(shown):
        notes.append("residual exactly 0 at sweep " + ", ".join(str(s) for s in c.sweeps[~shown]) + " (not drawn)")
    if c.tolerance is None:
        notes.append("the file does not record the solver's tolerance")
    if notes:
        fig.text(0.5, 0.01, "; ".join(notes), ha="center", va="bottom", fontsize=9)
        lines += notes
    return fig, lines


def _metadata(c: Convergence, source: ExportSource) -> dict:
    shown = c.residual > 0
    return {"Title": f"{source.name}: contact solver convergence", "Software": f"hairinv {__version__}",
            "Source": source.name, "hairinv:plot": "convergence",
            "hairinv:sweeps": json.dumps(c.sweeps[shown].tolist()),
            "hairinv:relative_residual": json.dumps(c.relative[shown].tolist()),
            "hairinv:tolerance": "" if c.tolerance is None else repr(c.tolerance), "hairinv:status": c.status,
            "hairinv:force_scale_N": repr(c.force_scale)}


def convergence_png(c: Convergence, source: ExportSource) -> tuple[bytes, list[str]]:
    """The convergence plot of ``source`` as PNG bytes, and lines for the user."""
    fig, lines = convergence_figure(c, source.name)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=DPI, metadata=_metadata(c, source))
    return buffer.getvalue(), lines
