"""Does a model stay still? The verdict of ``hairinv verify`` (docs/dynamics.md).

The still scene is run from the model (``run_scene``) with an ``on_frame``
that stops the run at the first frame in which any strand point is farther
than the tolerance from where it started (unless every frame is wanted);
:func:`judge` turns the frames done into a verdict. Distances are those of
:class:`~hairinv.dynamics.run.FrameLog`: ``2 n + 1`` points evenly spaced
from root to tip of a strand of ``n`` elements, in the body's frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config import LENGTH_UNITS, parse_length
from .run import Frames

# The lengths of the tolerance are read as every length is, config.parse_length (a unit required here).
__all__ = ["LENGTH_UNITS", "StrandMotion", "Verdict", "judge", "judge_displacements", "parse_length"]


@dataclass(frozen=True)
class StrandMotion:
    """How far one strand moved over the frames done."""

    index: int
    """0-based strand index, as in ``/helices``."""
    displacement: float
    """m, the largest distance of any of its points from where it started."""
    passed_at: float | None
    """s, the time of the first frame in which it was farther than the tolerance; None if never."""


@dataclass(frozen=True)
class Verdict:
    """The result of a still check."""

    tolerance: float
    """m"""
    seconds_requested: float
    seconds_simulated: float
    """s, the time of the last frame done"""
    stopped_early: bool
    """the run stopped at the first frame past the tolerance, before ``seconds_requested``"""
    n_strands: int
    strands: tuple[StrandMotion, ...]
    """every strand, largest displacement first (ties: lower index first)"""

    @property
    def passed(self) -> bool:
        return not self.moved

    @property
    def moved(self) -> tuple[StrandMotion, ...]:
        """The strands that went farther than the tolerance, largest first."""
        return tuple(s for s in self.strands if s.passed_at is not None)

    @property
    def largest(self) -> StrandMotion | None:
        return self.strands[0] if self.strands else None

    def as_dict(self, every_strand: bool = False) -> dict:
        """A JSON-ready summary: ``strands`` lists the strands that moved, or every strand."""

        def entry(s: StrandMotion) -> dict:
            return {"index": s.index, "displacement_m": s.displacement, "passed_at_s": s.passed_at}

        listed = self.strands if every_strand else self.moved
        return {"verdict": "PASS" if self.passed else "FAIL", "tolerance_m": self.tolerance,
                "seconds_simulated": self.seconds_simulated, "seconds_requested": self.seconds_requested,
                "stopped_early": self.stopped_early, "n_strands": self.n_strands, "n_moved": len(self.moved),
                "largest": None if self.largest is None else entry(self.largest),
                "strands": [entry(s) for s in listed]}


def judge(frames: Frames, tolerance: float, seconds_requested: float) -> Verdict:
    """The verdict from a run's frames (each :class:`FrameLog` with its ``strand_displacement``)."""
    log = frames.log
    n_strands = frames.root.shape[1]
    per_frame = np.array([f.strand_displacement for f in log], dtype=np.float64).reshape(len(log), n_strands)
    return judge_displacements(np.array([f.time for f in log]), per_frame, tolerance, seconds_requested,
                               frames.stopped)


def judge_displacements(times: np.ndarray, per_frame: np.ndarray, tolerance: float, seconds_requested: float,
                        stopped: bool) -> Verdict:
    """The verdict from each frame's time (F,) and each strand's largest displacement in it (F, S), m: what a
    run records, and what a ``/frames`` group written by ``verify -o`` holds (``time``,
    ``strand_displacement``, attribute ``stopped``)."""
    per_frame = np.asarray(per_frame, dtype=np.float64)
    n_strands = per_frame.shape[1]
    largest = per_frame.max(axis=0) if len(per_frame) else np.zeros(n_strands)
    past = per_frame > tolerance
    first = np.where(past.any(axis=0), past.argmax(axis=0), -1)
    order = sorted(range(n_strands), key=lambda k: (-largest[k], k))
    strands = tuple(StrandMotion(k, float(largest[k]), float(times[first[k]]) if first[k] >= 0 else None)
                    for k in order)
    return Verdict(tolerance, float(seconds_requested), float(times[-1]) if len(times) else 0.0, bool(stopped),
                   n_strands, strands)
    largest = per_frame.max(axis=0) if len(log) else np.zeros(n_strands)
    past = per_frame > tolerance
    first = np.where(past.any(axis=0), past.argmax(axis=0), -1)
    times = np.array([f.time for f in log])
    order = sorted(range(n_strands), key=lambda k: (-largest[k], k))
    strands = tuple(StrandMotion(k, float(largest[k]), float(times[first[k]]) if first[k] >= 0 else None)
                    for k in order)
    return Verdict(tolerance, float(seconds_requested), float(log[-1].time) if log else 0.0, frames.stopped,
                   n_strands, strands)
