"""An animated body: one triangle mesh of constant topology whose vertices move in time.

The readers (:mod:`~hairinv.formats.gltf_anim`, :mod:`~hairinv.formats.usd_anim`,
:mod:`~hairinv.formats.sequence`, :mod:`~hairinv.formats.alembic`) each build an :class:`AnimatedBody`.
Like the static body readers they keep the file's units and axes and say what the file states
(``scale_to_m``, ``up``): the groom's transform (:func:`hairinv.groom.body_to_groom`) is applied afterwards
with :meth:`AnimatedBody.transformed`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from ..errors import InputError

__all__ = ["AnimatedBody", "summary_lines", "lerp_samples"]


@dataclass(frozen=True, eq=False)
class AnimatedBody:
    """A deforming triangle mesh and how to evaluate it at any time.

    Attributes
    ----------
    vertices : (V, 3) float64, file units
        The rest pose: the bind pose of a skinned mesh (the mesh placed by its node, as static readers
        such as trimesh read the file), else the first sample.
    faces : (F, 3) int64
        Triangles, the same at every time.
    times : (T,) float64, seconds
        The file's sample times, increasing: keyframe times of a skinned animation, frame times of a
        point cache or sequence.
    fps : float or None
        Frames per second: stated by the file (USD), given (sequences), or the key spacing (glTF, which
        has no frame rate); None for a single sample.
    format : str
        Short name of the reader, e.g. ``"gltf-skin"``.
    joints : tuple of str
        Joint names of the skeleton(s) driving the mesh, empty when not skinned.
    scale_to_m : float or None
        Metres per file unit when the file states it (glTF: metres; USD ``metersPerUnit``).
    up : str or None
        The file's up axis (``"y"``, ``"z"``) when it states one.
    notes : tuple of str
        What the reader assumed or left out, for the user.
    """

    vertices: np.ndarray
    faces: np.ndarray
    times: np.ndarray
    fps: float | None
    format: str
    evaluate: Callable[[float], np.ndarray] = field(repr=False)
    joints: tuple[str, ...] = ()
    scale_to_m: float | None = None
    up: str | None = None
    notes: tuple[str, ...] = ()

    def __post_init__(self):
        vertices = np.ascontiguousarray(self.vertices, dtype=np.float64)
        faces = np.ascontiguousarray(self.faces, dtype=np.int64)
        times = np.ascontiguousarray(self.times, dtype=np.float64).reshape(-1)
        if vertices.ndim != 2 or vertices.shape[1] != 3:
            raise InputError(f"body vertices must be (V, 3); got {vertices.shape}")
        if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0:
            raise InputError(f"body faces must be (F, 3) with F > 0; got {faces.shape}")
        if faces.min() < 0 or faces.max() >= len(vertices):
            raise InputError("body faces index vertices that do not exist")
        if len(times) == 0 or np.any(np.diff(times) <= 0) or not np.isfinite(times).all():
            raise InputError("body sample times must be finite and increasing")
        object.__setattr__(self, "vertices", vertices)
        object.__setattr__(self, "faces", faces)
        object.__setattr__(self, "times", times)

    @property
    def n_frames(self) -> int:
        return int(len(self.times))

    @property
    def start(self) -> float:
        return float(self.times[0])

    @property
    def end(self) -> float:
        return float(self.times[-1])

    def vertices_at(self, t: float) -> np.ndarray:
        """The vertices at time ``t`` seconds: (V, 3) float64, file units (held at the ends outside the range)."""
        t = float(t)
        if not np.isfinite(t):
            raise InputError(f"an animated body is evaluated at a finite time; got {t}")
        return self.evaluate(t)

    def bounds(self) -> np.ndarray:
        """(2, 3) float64: the lowest and highest coordinates reached at the sample times and at rest."""
        lo, hi = self.vertices.min(axis=0), self.vertices.max(axis=0)
        for t in self.times:
            v = self.vertices_at(t)
            lo, hi = np.minimum(lo, v.min(axis=0)), np.maximum(hi, v.max(axis=0))
        return np.stack([lo, hi])

    def transformed(self, matrix) -> "AnimatedBody":
        """The body under the 4x4 ``matrix`` (e.g. :func:`hairinv.groom.body_to_groom`'s), at every time; a
        mirror reverses each triangle so that normals stay outward."""
        matrix = np.asarray(matrix, dtype=np.float64)
        if matrix.shape != (4, 4):
            raise InputError(f"a body transform must be (4, 4); got {matrix.shape}")
        A, b = matrix[:3, :3].copy(), matrix[:3, 3].copy()
        evaluate = self.evaluate
        faces = self.faces[:, ::-1] if np.linalg.det(A) < 0 else self.faces
        return replace(self, vertices=self.vertices @ A.T + b, faces=faces, evaluate=lambda t: evaluate(t) @ A.T + b,
                       scale_to_m=None, up=None)

    def summary(self) -> dict:
        """Frames, rate, time range, size, bounds and joints, as plain values (``hairinv info BODY``)."""
        lo, hi = self.bounds()
        return {
            "format": self.format,
            "frames": self.n_frames,
            "fps": self.fps,
            "start_s": self.start,
            "end_s": self.end,
            "duration_s": self.end - self.start,
            "vertices": int(len(self.vertices)),
            "faces": int(len(self.faces)),
            "bounds_min": lo.tolist(),
            "bounds_max": hi.tolist(),
            "scale_to_m": self.scale_to_m,
            "up": self.up,
            "joints": list(self.joints),
            "notes": list(self.notes),
        }


def summary_lines(summary: dict, name: str) -> list[str]:
    """The lines ``hairinv info`` prints for an animated body's :meth:`AnimatedBody.summary`."""
    fps = "unknown rate" if summary["fps"] is None else f"{summary['fps']:g} fps"
    unit = "file units" if summary["scale_to_m"] is None else f"x {summary['scale_to_m']:g} m"
    lines = [
        f"{name}: animated body ({summary['format']}), {summary['vertices']} vertices, {summary['faces']} triangles",
        f"  frames: {summary['frames']} at {fps}, {summary['start_s']:.6g} .. {summary['end_s']:.6g} s "
        f"({summary['duration_s']:.6g} s)",
        "  bounds: " + " .. ".join("(" + ", ".join(f"{c:.4g}" for c in summary[key]) + ")"
                                  for key in ("bounds_min", "bounds_max")) + f" [{unit}]"
        + (f", +{summary['up'].upper()} up" if summary["up"] else ""),
    ]
    if summary["joints"]:
        lines.append(f"  joints ({len(summary['joints'])}): " + ", ".join(summary["joints"]))
    lines += [f"  note: {note}" for note in summary["notes"]]
    return lines


def lerp_samples(times: np.ndarray, samples: np.ndarray, t: float) -> np.ndarray:
    """Piecewise-linear interpolation of per-time vertex samples (T, V, 3) at ``t``, held at the ends."""
    if t <= times[0]:
        return samples[0].copy()
    if t >= times[-1]:
        return samples[-1].copy()
    k = int(np.searchsorted(times, t, side="right")) - 1
    s = (t - times[k]) / (times[k + 1] - times[k])
    return (1.0 - s) * samples[k] + s * samples[k + 1]
