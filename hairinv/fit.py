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
from .rod.fitting import FIT_TOLERANCE_NOT_MET, closest_distances, fit_batch

__all__ = ["Helices", "FitReport", "fit_groom"]

# A fitted strand longer than this times its polyline winds between vertices.
OVERLONG = 1.05


@dataclass
class FitReport:
    """Counts and figures of a fit, for the user."""

    strands: int
    elements: np.ndarray
    fit_error: np.ndarray
    tolerance_missed: int
    seconds: float
    overlong: int = 0
    """Strands whose fitted curve is over 5% longer than their polyline: it
    winds between vertices, a shape the vertices do not show."""

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
        if self.overlong:
            lines.append(
                f"warning: {self.overlong} fitted strands are over 5% longer than their polyline (the curve winds "
                "between vertices); check them, or fit with more points per strand or a larger tolerance"
            )
        if self.tolerance_missed:
            lines.append(
                f"{self.tolerance_missed} strands did not reach the tolerance with the maximum element count "
                "(raise fit.max_elements or the tolerance)"
            )
        return lines


def _validate(settings: FitSettings) -> None:
    if not settings.tolerance > 0:
        raise InputError(f"fit.tolerance must be > 0 m, got {settings.tolerance}")
    if settings.elements < 0 or settings.min_elements < 1 or settings.max_elements < settings.min_elements:
        raise InputError("fit element counts must satisfy 1 <= min_elements <= max_elements and elements >= 0")
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
    n_max = max(settings.max_elements, settings.elements)
    out_n = np.zeros(count, np.int64)
    out_frame = np.zeros((count, 3, 3))
    out_omega = np.zeros((count, n_max, 3))
    out_length = np.zeros((count, n_max))
    out_worst = np.zeros(count)
    out_status = np.zeros(count, np.int64)
    def fit_chunk(lo: int, hi: int) -> None:
        sub = offsets[lo:hi + 1] - offsets[lo]
        fit_batch(points[offsets[lo]:offsets[hi]], sub, up, float(settings.tolerance), int(settings.elements),
                  int(settings.min_elements), int(n_max), int(settings.max_iterations), out_n[lo:hi],
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
    missed = int((out_status == FIT_TOLERANCE_NOT_MET).sum()) if settings.elements == 0 else 0
    fitted_length = np.add.reduceat(length, helix_offsets[:-1])
    overlong = int((fitted_length > OVERLONG * strand_lengths(points, offsets)).sum())
    report = FitReport(count, out_n, fit_error, missed, time.perf_counter() - start, overlong)
    return helices, report
