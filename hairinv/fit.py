"""Curves to G1 piecewise super-helices (paper, section 4.2).

The numerics live in :mod:`hairinv.rod.fitting`; this module owns the
arrays, runs the strands in chunks (so a caller can show progress), and
builds the ``/helices`` stage group.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .config import FitSettings
from .errors import InputError
from ._parallel import run_chunks
from .groom import Groom, strand_lengths
from .model import Helices
from .rod import fitting
from .rod.fitting import FIT_TOLERANCE_NOT_MET, closest_distances, element_caps, fit_batch, sampling_figures

__all__ = ["FitReport", "fit_groom"]

# A fitted strand longer than this times the smooth curve through its vertices (their chords lengthened
# by their turning, hairinv.rod.fitting.sampling_figures) winds between vertices: a shape they do not show.
OVERLONG = 1.02
# Strands listed by name in the report, worst first.
LISTED = 5
# Below this correlation of consecutive deviations from the chords, a strand's vertices scatter about a
# smooth curve: noise dominates them (white noise gives -2/3; a smooth curve, however coarsely or unevenly
# sampled, near 1; a coil at n points per turn cos(2 pi / n)). The fit uses the same bound.
SCATTERED = float(fitting._NOISE_GATE)


@dataclass
class FitReport:
    """Counts and figures of a fit, for the user."""

    strands: int
    elements: np.ndarray
    fit_error: np.ndarray
    tolerance_missed: int
    seconds: float
    overlong: int = 0
    """Strands whose fitted curve is over 2% longer than the smooth curve through their vertices: it winds
    between vertices, a shape the vertices do not show."""
    tolerance: float = 0.0
    """m, the fit tolerance"""
    length_ratio: np.ndarray | None = None
    """(S,) each strand's fitted length over its polyline's"""
    sagitta: np.ndarray | None = None
    """(S,) m, the largest distance a smooth curve through the vertices may pass from a chord
    (:func:`hairinv.rod.fitting.sampling_figures`): above the tolerance the strand is too coarse for it"""
    missed: np.ndarray | None = None
    """(S,) bool, the strands farther than the tolerance from a vertex"""
    smooth: np.ndarray | None = None
    """(S,) the correlation of consecutive deviations of the vertices from their chords: near 1 on a smooth
    curve, below :data:`SCATTERED` where the vertices scatter about one (noise)"""
    noise: np.ndarray | None = None
    """(S,) m, where the vertices scatter (``smooth`` below :data:`SCATTERED`), the noise's estimated
    standard deviation per coordinate (:func:`hairinv.rod.fitting._scatter`), else 0"""
    noisy: np.ndarray | None = None
    """(S,) bool, the strands whose noise leaves more than the tolerance at their vertices (the largest of
    their M deviations, sigma sqrt(2 ln M + 4), beyond it): the fit lays the smooth curve through the middle
    of their noise"""

    def worst(self, count: int = LISTED) -> list[tuple[int, float, float]]:
        """The strands farthest from their vertices: (index, largest distance m, length ratio)."""
        order = np.argsort(-self.fit_error[:, 1], kind="stable")[:count]
        ratio = self.length_ratio if self.length_ratio is not None else np.full(self.strands, np.nan)
        return [(int(k), float(self.fit_error[k, 1]), float(ratio[k])) for k in order]

    def lines(self) -> list[str]:
        mean_mm = 1e3 * self.fit_error[:, 0]
        max_mm = 1e3 * self.fit_error[:, 1]
        lines = [
            f"fitted {self.strands} strands with {int(self.elements.sum())} elements "
            f"(per strand min {self.elements.min()}, median {int(np.median(self.elements))}, max {self.elements.max()}) "
            f"in {self.seconds:.2f} s",
            f"fit error, mm: mean {mean_mm.mean():.4f}, median of strand means {np.median(mean_mm):.4f}, "
            f"95th percentile of strand maxima {np.percentile(max_mm, 95):.4f}, max {max_mm.max():.4f}",
        ]
        if self.length_ratio is not None and self.strands:
            lines.append(f"fitted length over polyline length: {self.length_ratio.min():.4f} to "
                         f"{self.length_ratio.max():.4f}")
        if self.overlong:
            lines.append(
                f"warning: {self.overlong} fitted strands are over {100 * (OVERLONG - 1):.0f}% longer than a smooth "
                "curve through their vertices (the curve winds between vertices); check them, or fit with more "
                "points per strand or a larger tolerance"
            )
        if self.tolerance_missed:
            lines += self._missed_lines()
        return lines

    def _missed_lines(self) -> list[str]:
        """Which strands missed the tolerance, why, and what to change."""
        tol_mm = 1e3 * self.tolerance
        missed = self.missed if self.missed is not None else self.fit_error[:, 1] > self.tolerance
        lines = [f"{self.tolerance_missed} of {self.strands} strands are farther than the tolerance "
                 f"({tol_mm:.3g} mm) from some vertex, with the most elements their vertices determine:"]
        if self.sagitta is not None:
            coarse = missed & (self.sagitta > self.tolerance)
            if self.noisy is not None:
                coarse &= ~self.noisy
            elif self.noise is not None:
                coarse &= self.noise == 0
            elif self.smooth is not None:
                coarse &= self.smooth >= SCATTERED
            rough = missed & ~coarse
            if coarse.any():
                lines.append(
                    f"  {int(coarse.sum())} are sampled too coarsely for it: between their vertices a smooth curve "
                    f"may pass up to {1e3 * self.sagitta[coarse].max():.2f} mm from the chords, so the vertices do "
                    "not determine it to the tolerance. Resample them more finely, or raise fit.tolerance")
            if self.noisy is not None:
                noisy = rough & self.noisy
            else:
                noisy = rough & (self.noise > 0) if self.noise is not None else np.zeros_like(rough)
            kinked = rough & ~noisy
            if noisy.any():
                need = 1e3 * self.fit_error[noisy, 1].max()
                sigma = 1e3 * self.noise[noisy]
                lines.append(
                    f"  {int(noisy.sum())} have vertices that scatter about a smooth curve (noise of about "
                    f"{np.median(sigma):.2g} mm per coordinate, up to {sigma.max():.2g} mm): they are fitted by "
                    "the smooth curve, not the noise. "
                    f"Smooth them, or raise fit.tolerance to {_up(need):g} mm")
            if kinked.any():
                need = 1e3 * self.fit_error[kinked, 1].max()
                lines.append(
                    f"  {int(kinked.sum())} bend sharper (kinks) than a smooth rod follows within it. "
                    f"Smooth them, or raise fit.tolerance to {_up(need):g} mm")
        listed = ", ".join(f"{k} ({1e3 * e:.3f} mm, length ratio {r:.3f})"
                           for k, e, r in self.worst() if e > self.tolerance)
        lines.append(f"  worst strands (index, largest distance, fitted length over polyline): {listed}")
        return lines


def _up(x: float) -> float:
    """``x`` > 0 rounded up to two significant digits (a tolerance that the distances it is raised to meet)."""
    step = 10.0 ** (np.floor(np.log10(x)) - 1)
    return float(np.ceil(x / step - 1e-9) * step)


def _validate(settings: FitSettings) -> None:
    if not settings.tolerance > 0:
        raise InputError(f"fit.tolerance must be > 0 m, got {settings.tolerance}")
    if settings.elements < 0 or settings.min_elements < 1 or (
            settings.max_elements != 0 and settings.max_elements < settings.min_elements) or settings.max_elements < 0:
        raise InputError("fit element counts must satisfy 1 <= min_elements <= max_elements (or max_elements = 0, "
                         "as many as the vertices determine) and elements >= 0")
    if settings.max_iterations < 1:
        raise InputError("fit.max_iterations must be >= 1")


def fit_groom(groom: Groom, settings: FitSettings, progress=None, chunk: int = 32) -> tuple[Helices, FitReport]:
    """Fit super-helices to every strand of ``groom``.

    Parameters
    ----------
    groom : Groom
        Clean strands in metres (see :func:`hairinv.groom.load_groom`).
    settings : FitSettings
    progress : callable, optional
        Called with the number of strands finished after each chunk.
    """
    _validate(settings)
    start = time.perf_counter()
    points = np.ascontiguousarray(groom.points, dtype=np.float64)
    offsets = np.ascontiguousarray(groom.offsets, dtype=np.int64)
    up = np.ascontiguousarray(groom.up, dtype=np.float64)
    count = groom.n_strands
    if settings.elements > 0:
        n_max = settings.elements
    else:
        n_max = int(element_caps(points, offsets, settings.max_elements).max()) if count else 1
    out_n = np.zeros(count, np.int64)
    out_frame = np.zeros((count, 3, 3))
    out_omega = np.zeros((count, n_max, 3))
    out_length = np.zeros((count, n_max))
    out_worst = np.zeros(count)
    out_status = np.zeros(count, np.int64)
    def fit_chunk(lo: int, hi: int) -> None:
        sub = offsets[lo:hi + 1] - offsets[lo]
        fit_batch(points[offsets[lo]:offsets[hi]], sub, up, float(settings.tolerance), int(settings.elements),
                  int(settings.min_elements), int(settings.max_elements), int(settings.max_iterations), out_n[lo:hi],
                  out_frame[lo:hi], out_omega[lo:hi], out_length[lo:hi], out_worst[lo:hi], out_status[lo:hi])

    run_chunks(fit_chunk, count, chunk, progress)
    helix_offsets = np.concatenate([[0], np.cumsum(out_n)]).astype(np.int64)
    omega = np.concatenate([out_omega[i, :out_n[i]] for i in range(count)])
    length = np.concatenate([out_length[i, :out_n[i]] for i in range(count)])
    roots = np.ascontiguousarray(points[offsets[:-1]])
    err_mean = np.zeros(count)
    err_max = np.zeros(count)
    def error_chunk(lo: int, hi: int) -> None:
        closest_distances(points[offsets[lo]:offsets[hi]], offsets[lo:hi + 1] - offsets[lo], roots[lo:hi],
                          out_frame[lo:hi], helix_offsets[lo:hi + 1] - helix_offsets[lo],
                          omega[helix_offsets[lo]:helix_offsets[hi]], length[helix_offsets[lo]:helix_offsets[hi]],
                          err_mean[lo:hi], err_max[lo:hi])

    run_chunks(error_chunk, count, 1024)
    fit_error = np.stack([err_mean, err_max], axis=1)
    helices = Helices(roots, out_frame, helix_offsets, length, omega, fit_error)
    missed = (out_status == FIT_TOLERANCE_NOT_MET) if settings.elements == 0 else np.zeros(count, bool)
    fitted_length = np.add.reduceat(length, helix_offsets[:-1]) if count else np.zeros(0)
    arc, sagitta, smooth, noise = np.zeros(count), np.zeros(count), np.zeros(count), np.zeros(count)
    sampling_figures(points, offsets, arc, sagitta, smooth, noise)
    vertices = np.maximum(np.diff(offsets), 2)
    noisy = noise * np.sqrt(2.0 * np.log(vertices) + fitting._NOISE_MARGIN) > settings.tolerance
    overlong = int((fitted_length > OVERLONG * arc).sum())
    report = FitReport(count, out_n, fit_error, int(missed.sum()), time.perf_counter() - start, overlong,
                       float(settings.tolerance), fitted_length / strand_lengths(points, offsets), sagitta, missed,
                       smooth, noise, noisy)
    return helices, report
