"""A stage file seen as what ``hairinv export`` writes: its shapes as polylines, with their units and axes.

Shapes (``--shape``):

- ``input``: ``/curves`` as stored (the groom after import cleaning), vertex for vertex.
- ``rest``: the rest shape ``q0`` of ``/model`` evaluated as a centerline from the fitted roots and root
  frames, with nothing pressing on it (no gravity, no contact): for a rod the shape of zero elastic force
  is its rest shape, ``q = q0``. A stiffened model rests in ``omega_rest_stiffened``, the rest shape its
  simulation uses with its stiffening (docs/stage-files.md), else in ``omega_rest``.
- ``frame:N``: frame N (0-based) of ``/frames``, the centerlines of its shapes ``q`` from its own
  (moving) roots and root frames, in the world frame.
- ``all``: every shape the file holds, for formats that carry several.

The helix shapes are sampled at the input's vertices: vertex ``i`` of a strand sits at the arc length
``s_i = L c_i / c_n`` on the fitted centerline (``c`` the cumulative chord length of the input polyline,
``L`` the fitted strand's length), so the root is at ``s = 0``, the tip at ``s = L`` (where the fit
matches them) and the same material point of the rod keeps the same index in every shape. A trimmed
simulation keeps the vertices before its cut and ends each cut strand at its new tip.

Everything here is in the stage file's units and frame (metres, gravity along ``-up``); the writers
convert to their format's units and axes with :class:`OutputAxes`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import stages
from ..config import MaterialSettings
from ..errors import InputError
from ..groom import AXES as _AXES
from ..groom import SAME_AXIS as _SAME_AXIS
from ..groom import rotation_onto
from ..model import UNSTABLE_MARGIN, Helices, rest_from_group, stability_from_group, stiffening_from_group
from ..rod.helix import points_at

__all__ = ["SHAPE_KINDS", "ExportSource", "OutputAxes", "Shape", "Strands", "parse_shape"]

SHAPE_KINDS = ("input", "rest", "frame", "all")
_SHAPE_HELP = "input, rest, frame:N (N counted from 0) or all"


@dataclass(frozen=True)
class Shape:
    """A ``--shape`` value: ``kind`` in :data:`SHAPE_KINDS`, ``frame`` the index for ``frame``."""

    kind: str
    frame: int | None = None

    def __str__(self) -> str:
        return f"frame:{self.frame}" if self.kind == "frame" else self.kind


def parse_shape(text: str) -> Shape:
    """``input``, ``rest``, ``all`` or ``frame:N``; anything else is an :class:`InputError`."""
    text = str(text).strip().lower()
    if text in ("input", "rest", "all"):
        return Shape(text)
    head, _, tail = text.partition(":")
    if head == "frame" and tail.strip().isdigit():
        return Shape("frame", int(tail))
    raise InputError(f"--shape takes {_SHAPE_HELP}, not {text!r}")


@dataclass
class Strands:
    """Polylines of one shape.

    Attributes
    ----------
    points : (P, 3) float64, m, the stage file's world frame
    offsets : (S + 1,) int64, CSR offsets
    label : str, what the shape is, for reports and file headers
    """

    points: np.ndarray
    offsets: np.ndarray
    label: str

    @property
    def n_strands(self) -> int:
        return int(len(self.offsets) - 1)

    @property
    def counts(self) -> np.ndarray:
        return np.diff(self.offsets)


def _axis_name(up: np.ndarray) -> str:
    for name, i in _AXES.items():
        if abs(up[i]) > _SAME_AXIS:
            return ("+" if up[i] > 0 else "-") + name.upper()
    return "(" + ", ".join(f"{v:.3g}" for v in up) + ")"


@dataclass(frozen=True)
class OutputAxes:
    """From the stage file's frame (metres) to a file's coordinates: ``rotation @ x / meters_per_unit``.

    ``up`` is the file's up axis (``"y"`` or ``"z"``); ``note`` says what was turned, or is empty.
    """

    rotation: np.ndarray
    meters_per_unit: float
    up: str
    note: str = ""

    def points(self, x: np.ndarray) -> np.ndarray:
        """(n, 3) positions in metres -> file coordinates."""
        return (np.asarray(x, dtype=np.float64) @ self.rotation.T) / self.meters_per_unit

    def length(self, metres):
        """A length (or array of lengths) in metres -> file units."""
        return np.asarray(metres, dtype=np.float64) / self.meters_per_unit

    def transform(self, T: np.ndarray) -> np.ndarray:
        """A rigid transform (4, 4) of the stage frame (column vectors, metres) -> the same in file coordinates."""
        A = self.rotation
        out = np.eye(4)
        out[:3, :3] = A @ T[:3, :3] @ A.T
        out[:3, 3] = A @ T[:3, 3] / self.meters_per_unit
        return out

    @classmethod
    def onto(cls, up: np.ndarray, axis: str, meters_per_unit: float = 1.0) -> OutputAxes:
        """Turn the groom's ``up`` onto the file's ``axis`` (a format's fixed convention)."""
        target = np.eye(3)[_AXES[axis]]
        rotation = rotation_onto(up, target)
        note = "" if np.allclose(rotation, np.eye(3)) else (
            f"turned the groom's up axis {_axis_name(up)} to +{axis.upper()}, the format's convention")
        return cls(rotation, float(meters_per_unit), axis, note)

    @classmethod
    def keeping(cls, up: np.ndarray, allowed: tuple[str, ...], meters_per_unit: float = 1.0) -> OutputAxes:
        """Keep the groom's axes if its up axis is one of ``allowed`` (positive), else turn it onto the first."""
        for axis in allowed:
            if up[_AXES[axis]] > _SAME_AXIS:
                return cls(np.eye(3), float(meters_per_unit), axis)
        axis = allowed[0]
        rotation = rotation_onto(up, np.eye(3)[_AXES[axis]])
        names = " or ".join(f"+{a.upper()}" for a in allowed)
        return cls(rotation, float(meters_per_unit), axis,
                   f"turned the groom's up axis {_axis_name(up)} to +{axis.upper()} (the format's up axis is {names})")


def _keyed(values: np.ndarray, offsets: np.ndarray, spans: np.ndarray) -> np.ndarray:
    """Per-strand monotone values made globally monotone: strand ``k``'s shifted past every earlier strand."""
    shift = np.concatenate([[0.0], np.cumsum(spans + 1.0)])[:-1]
    return values + np.repeat(shift, np.diff(offsets))


class ExportSource:
    """A stage file read for export; see the module docstring for the shapes it offers.

    Parameters
    ----------
    path : path-like, a hairinv stage file with at least ``/curves``
    """

    #: the render strands' binding to the simulated guides (:class:`hairinv.export.follow.FollowSource`); None: the
    #: stage file's own strands
    follow = None

    def __init__(self, path):
        self.path = Path(path)
        if not self.path.exists():
            raise InputError("no such file", self.path)
        if not stages.is_stage_file(self.path):
            raise InputError("is not a hairinv stage file; export reads the files fit, detect, invert and "
                             "simulate write", self.path)
        self.stage = stages.read_stage(self.path)
        if stages.CURVES not in self.stage:
            raise InputError("has no /curves group to export", self.path)
        curves = self.stage[stages.CURVES]
        self.curves = curves
        self.up = np.asarray(curves.attrs.get("up", (0.0, 1.0, 0.0)), dtype=np.float64).reshape(3)
        self.up = self.up / np.linalg.norm(self.up)
        self.scale_to_m = float(curves.attrs.get("scale_to_m", 1.0))
        self.flip = str(curves.config.get("import", {}).get("flip", ""))
        self.offsets = np.ascontiguousarray(curves["offsets"], dtype=np.int64)
        self.points = np.ascontiguousarray(curves["points"], dtype=np.float64)
        self.n_strands = len(self.offsets) - 1
        self.helices = Helices.from_group(self.stage[stages.HELICES]) if stages.HELICES in self.stage else None
        if self.helices is not None and self.helices.n_strands != self.n_strands:
            raise InputError(f"holds {self.n_strands} strands in /curves but {self.helices.n_strands} in /helices",
                             self.path)
        self.model = self.stage.groups.get(stages.MODEL)
        if self.model is not None and self.helices is None:
            raise InputError("has a /model group but no /helices to evaluate it on", self.path)
        self.frames = self.stage.groups.get(stages.FRAMES)
        if self.frames is not None and self.helices is None:
            raise InputError("has a /frames group but no /helices to evaluate it on", self.path)
        self.contacts = self.stage.groups.get(stages.CONTACTS)
        self._vertex_s = None
        self._frame_layout = None

    # ------------------------------------------------------------------ what the file holds

    @property
    def name(self) -> str:
        return self.path.name

    @property
    def has_rest(self) -> bool:
        return self.model is not None

    @property
    def n_frames(self) -> int:
        return 0 if self.frames is None else len(self.frames["time"])

    @property
    def times(self) -> np.ndarray:
        """(F,) float64, s."""
        return np.zeros(0) if self.frames is None else np.asarray(self.frames["time"], dtype=np.float64)

    @property
    def fps(self) -> float:
        """Frames per second of the run: its ``fps`` attribute, else from its times (1 for a single frame)."""
        if self.frames is None:
            return 1.0
        fps = float(self.frames.attrs.get("fps", 0.0))
        if fps > 0:
            return fps
        steps = np.diff(self.times)
        return float(1.0 / np.median(steps)) if len(steps) and np.median(steps) > 0 else 1.0

    @property
    def frames_trimmed(self) -> bool:
        """The run cut its strands: its frames have their own element layout (and fewer vertices)."""
        return self.frames is not None and "offsets" in self.frames.datasets

    @property
    def body_removed(self) -> bool:
        return self.frames is not None and bool(self.frames.attrs.get("body_removed", False))

    @property
    def radius(self) -> tuple[float, str]:
        """The rod radius (m) and where it comes from: the model's material, else the default material's."""
        if self.model is not None and "radius" in self.model.attrs:
            return float(self.model.attrs["radius"]), f"the model's radius {1e3 * float(self.model.attrs['radius']):g} mm"
        radius = MaterialSettings().radius
        return radius, f"the default material radius {1e3 * radius:g} mm (the file has no /model)"

    def require(self, shape: Shape) -> None:
        """Raise :class:`InputError` (one sentence naming the file) if the file does not carry ``shape``."""
        if shape.kind == "rest" and not self.has_rest:
            raise InputError("has no /model group, so it has no rest shape to export; run `hairinv invert` on it "
                             "first", self.path)
        if shape.kind == "frame":
            if self.frames is None:
                raise InputError(f"has no /frames group, so it has no frame {shape.frame} to export; run `hairinv "
                                 "simulate` on it first", self.path)
            if not 0 <= shape.frame < self.n_frames:
                raise InputError(f"has {self.n_frames} frames (0 to {self.n_frames - 1}), so it has no frame "
                                 f"{shape.frame}", self.path)

    def input_files(self) -> list[Path]:
        """The files this stage file was made from, where they were (export must not write over them)."""
        out = []
        for group in self.stage.groups.values():
            for record in group.inputs:
                if record.get("path"):
                    out.append(Path(record["path"]))
                    out.append(self.path.parent / record["path"])
        return out

    # ------------------------------------------------------------------ shapes

    def strands(self, shape: Shape) -> Strands:
        """The polylines of one shape (``input``, ``rest`` or ``frame``), metres, stage frame."""
        self.require(shape)
        if shape.kind == "input":
            return self.input()
        if shape.kind == "rest":
            return self.rest()
        if shape.kind == "frame":
            return self.frame(shape.frame)
        raise InputError(f"--shape {shape} names several shapes; this format holds one: choose input, rest or "
                         "frame:N")

    def input(self) -> Strands:
        return Strands(self.points, self.offsets, "input shape")

    @property
    def vertex_s(self) -> np.ndarray:
        """(P,) float64, m: each input vertex's arc length on its fitted centerline (module docstring)."""
        if self._vertex_s is None:
            h = self.helices
            chord = np.linalg.norm(np.diff(self.points, axis=0), axis=1)
            cum = np.concatenate([[0.0], np.cumsum(chord)])
            start = cum[self.offsets[:-1]]
            end = cum[self.offsets[1:] - 1]
            fitted = np.add.reduceat(h.length, h.offsets[:-1]) if h.n_elements else np.zeros(self.n_strands)
            per = np.repeat(np.arange(self.n_strands), np.diff(self.offsets))
            span = np.where(end > start, end - start, 1.0)
            self._vertex_s = (cum - start[per]) / span[per] * fitted[per]
        return self._vertex_s

    def _evaluate(self, root, frame0, h_offsets, omega, length, v_offsets, s) -> np.ndarray:
        """Centerline points at arc lengths ``s`` (CSR ``v_offsets``) of every strand, m."""
        out = np.empty((len(s), 3))
        for k in range(len(v_offsets) - 1):
            a, z = h_offsets[k], h_offsets[k + 1]
            lo, hi = v_offsets[k], v_offsets[k + 1]
            pts = np.empty((hi - lo, 3))
            points_at(np.ascontiguousarray(root[k]), np.ascontiguousarray(frame0[k]),
                      np.ascontiguousarray(omega[a:z]), np.ascontiguousarray(length[a:z]),
                      np.ascontiguousarray(s[lo:hi]), pts)
            out[lo:hi] = pts
        return out

    @property
    def rest_omega(self) -> np.ndarray:
        """(E, 3) the rest shape a simulation of the model uses (``omega_rest_stiffened`` where stiffened)."""
        return rest_from_group(self.model)

    def rest(self) -> Strands:
        h = self.helices
        pts = self._evaluate(h.root, h.frame0, h.offsets, self.rest_omega, h.length, self.offsets, self.vertex_s)
        return Strands(pts, self.offsets, "rest shape")

    def frame_layout(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(element offsets, element lengths, vertex offsets, vertex arc lengths) of the frames' strands."""
        if self._frame_layout is None:
            h = self.helices
            if not self.frames_trimmed:
                self._frame_layout = (h.offsets, h.length, self.offsets, self.vertex_s)
            else:
                e_off = np.asarray(self.frames["offsets"], dtype=np.int64)
                length = np.asarray(self.frames["length"], dtype=np.float64)
                total = np.add.reduceat(length, e_off[:-1]) if len(length) else np.zeros(self.n_strands)
                pieces, counts = [], []
                for k in range(self.n_strands):
                    s = self.vertex_s[self.offsets[k]:self.offsets[k + 1]]
                    # vertices before the cut (a relative 1e-9 of the strand: the uncut tip stays), then the new tip
                    keep = s[s < total[k] * (1.0 - 1e-9)]
                    piece = np.append(keep, total[k])
                    pieces.append(piece)
                    counts.append(len(piece))
                v_off = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
                self._frame_layout = (e_off, length, v_off, np.concatenate(pieces))
        return self._frame_layout

    def frame(self, k: int) -> Strands:
        e_off, length, v_off, s = self.frame_layout()
        f = self.frames
        pts = self._evaluate(f["root"][k], f["frame0"][k], e_off, np.asarray(f["omega"][k]), length, v_off, s)
        return Strands(pts, v_off, f"frame {k} (t = {self.times[k]:g} s)")

    def body_transform(self, k: int) -> np.ndarray:
        return np.asarray(self.frames["body_transform"][k], dtype=np.float64)

    @property
    def body_animated(self) -> bool:
        """Whether the frames keep a deforming body's vertices (a shot): ``/frames/body_vertices``."""
        return self.frames is not None and "body_vertices" in self.frames.datasets

    def body_mesh(self, k: int):
        """The shot's body at frame ``k`` as a mesh (``vertices``, ``faces``; m, the groom's frame)."""
        import trimesh

        return trimesh.Trimesh(np.asarray(self.frames["body_vertices"][k], dtype=np.float64),
                               np.asarray(self.frames["body_faces"], dtype=np.int64), process=False)

    def carried(self, k: int) -> np.ndarray:
        """(P, 3) m: the input's points carried to frame ``k`` by their strands' root frames alone (the body's
        motion, rigid or each root with its own triangle), as if the hair did not move relative to them: from
        the input's own roots and root frames (the groom's pose, which a shot's pre-roll leaves before frame 0)."""
        f, h = self.frames, self.helices
        Fk = np.asarray(f["frame0"][k], dtype=np.float64)
        R = np.einsum("nji,njk->nik", Fk, h.frame0)  # frame0_k = frame0_input R^T
        c = np.asarray(f["root"][k], dtype=np.float64) - np.einsum("nij,nj->ni", R, h.root)
        strand = np.repeat(np.arange(len(R)), np.diff(self.offsets))
        return np.einsum("nij,nj->ni", R[strand], self.points) + c[strand]

    # ------------------------------------------------------------------ per-strand and per-vertex quantities

    def strand_values(self) -> dict[str, tuple[np.ndarray, str]]:
        """Per-strand quantities the file carries: name -> ((S,) float64, what it is with its unit)."""
        out = {}
        if self.helices is not None:
            out["fit_error_mean"] = (self.helices.fit_error[:, 0],
                                     "mean distance of the input vertices to the fitted centerline, m")
            out["fit_error_max"] = (self.helices.fit_error[:, 1],
                                    "largest distance of an input vertex to the fitted centerline, m")
        if self.model is not None:
            factor = stiffening_from_group(self.model, self.n_strands)
            if factor is not None:
                out["stiffening"] = (factor, ("factor the strand's bending and twist stiffness was multiplied by "
                                              "so that it rests stably (1: the material's own)"))
            margin = stability_from_group(self.model, self.n_strands)
            if margin is not None:
                under = "held fixed" if self.model.attrs.get("stable_under") == "forces" else "held in place"
                out["stability_margin"] = (margin, (
                    "smallest eigenvalue of the strand's stiffness-scaled Hessian at rest, its contact forces "
                    f"{under}: > 0 rests stably, < {UNSTABLE_MARGIN:g} unstable, inf: no motion left"))
        return out

    def guide_flags(self) -> np.ndarray:
        """(S,) int32, 1 on each strand that was simulated: every strand of a stage file."""
        return np.ones(self.n_strands, dtype=np.int32)

    def stable(self) -> np.ndarray | None:
        """(S,) bool, whether each strand rests in a stable equilibrium, or None if the file does not say."""
        if self.model is None:
            return None
        margin = stability_from_group(self.model, self.n_strands)
        return None if margin is None else ~(margin < UNSTABLE_MARGIN)

    def vertex_values(self) -> dict[str, tuple[np.ndarray, str]]:
        """Per-vertex quantities (input topology): name -> ((P,) float64, what it is with its unit)."""
        out = {}
        if self.model is None:
            return out
        h = self.helices
        # element of each vertex: the one starting at or before its arc length (the last one at the tip)
        starts = np.cumsum(h.length) - h.length
        local = starts - np.repeat(starts[h.offsets[:-1]], np.diff(h.offsets))
        spans = np.add.reduceat(h.length, h.offsets[:-1])
        keys = _keyed(local, h.offsets, spans)
        vkeys = _keyed(self.vertex_s, self.offsets, spans)
        per = np.repeat(np.arange(self.n_strands), np.diff(self.offsets))
        element = np.searchsorted(keys, vkeys, side="right") - 1
        element = np.clip(element, h.offsets[:-1][per], h.offsets[1:][per] - 1)
        rest = self.rest_omega
        out["rest_curvature"] = (np.hypot(rest[element, 0], rest[element, 1]),
                                 "curvature of the rest shape at the vertex, 1/m")
        force = self.contact_force(spans)
        if force is not None:
            out["contact_force"] = (force, ("magnitude of the net contact force on the vertex (the contacts "
                                            "nearest it along the strand), N"))
        return out

    def contact_force(self, spans: np.ndarray) -> np.ndarray | None:
        """(P,) float64, N: per vertex, |sum of the world contact forces of the contacts nearest it|."""
        if self.contacts is None or "force" not in self.model.datasets:
            return None
        strand = np.asarray(self.contacts["strand"], dtype=np.int64).reshape(-1, 2)
        force = np.asarray(self.model["force"], dtype=np.float64).reshape(-1, 3)
        if len(force) != len(strand):
            return None
        s = np.asarray(self.contacts["s"], dtype=np.float64).reshape(-1, 2)
        frame = np.asarray(self.contacts["frame"], dtype=np.float64).reshape(-1, 3, 3)
        world = np.einsum("cji,cj->ci", frame, force)  # frame.T @ r, on side A
        vkeys = _keyed(self.vertex_s, self.offsets, spans)
        shift = np.concatenate([[0.0], np.cumsum(spans + 1.0)])[:-1]
        total = np.zeros((len(self.points), 3))
        for side, sign in ((0, 1.0), (1, -1.0)):
            k = strand[:, side]
            on = k >= 0
            k = k[on]
            key = s[on, side] + shift[k]
            right = np.clip(np.searchsorted(vkeys, key), self.offsets[k], self.offsets[k + 1] - 1)
            left = np.maximum(right - 1, self.offsets[k])
            nearest = np.where(np.abs(vkeys[left] - key) <= np.abs(vkeys[right] - key), left, right)
            np.add.at(total, nearest, sign * world[on])
        return np.linalg.norm(total, axis=1)

    # ------------------------------------------------------------------ the body

    def body(self):
        """The body mesh the file records (trimesh, metres, the groom's frame), or None, and a line saying why.

        The body is the last input of ``/frames`` (the run's), else of ``/contacts`` or ``/model``; it is used
        if it is still at its recorded path (as given, or relative to the stage file's folder) with the
        recorded SHA-256.
        """
        from ..groom import find_recorded_body, load_body, posed_mesh, recorded_body_transform, recorded_pose

        path, record, why = find_recorded_body(self.stage, self.path)
        if path is None:
            return None, why or "the file records no body mesh"
        try:
            mesh = posed_mesh(path, recorded_pose(record, self.path))  # in the groom's pose
        except InputError as exc:  # its rest mesh gone, say: drawn without the body, as when the body is gone
            return None, str(exc)
        return load_body(path, recorded_body_transform(record, self.scale_to_m, self.flip, path), mesh), f"body: {path}"
