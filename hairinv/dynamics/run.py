"""Run a scene on an inverted model and collect its frames (``hairinv simulate``).

The model file gives the groom (``/helices``), the contacts and forces it was
inverted with (``/contacts``, ``/model``) and the material. The scene says
what the body does; the initialisation says which rest shape the strands
get: ``inverted`` (the model's), ``naive`` (the input shape itself, as a
simulator that ignores gravity would take it) or ``gravity-only`` (the
contact-free inversion, ``q0 = q - K^-1 F_g``).
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np

from .. import stages
from ..config import Settings
from ..contacts.body import BodyMesh
from ..errors import InputError, Interrupted, in_file
from ..gravity import generalized_gravity
from ..model import (Contacts, Helices, Material, material_from_group, rest_from_group, stiffening_from_group,
                     stiffness)
from ..solver.status import Status
from .scene import Scene, check_run_length, trim_helices
from .simulate import Motion, Simulation, StepReport
from .tracking import points_on

__all__ = ["INITS", "Frames", "FrameLog", "initial_rest", "run_scene"]

INITS = ("inverted", "naive", "gravity-only")


@dataclass
class FrameLog:
    """One output frame: what the steps since the previous frame did."""

    index: int
    time: float
    contacts: int
    n_body: int
    sweeps: int
    relative_residual: float
    unconverged_steps: int
    kinetic: float
    elastic: float
    displacement: float
    """m, the largest distance of a strand point from where it started, in the body frame."""
    seconds: float
    halved: int = 0
    """substeps beyond one per step: how often the frame's steps were halved"""
    halved_by: int = -1
    """the strand that last made a step of the frame halve by turning an element too far (-1: none)"""
    strand_displacement: np.ndarray | None = None
    """(S,) float64, m: each strand's largest point distance from where it started (``displacement`` is their max)."""

    def line(self) -> str:
        by = str(self.halved_by) if self.halved_by >= 0 else "-"
        return (f"frame {self.index:4d}  t {self.time:6.3f} s  contacts {self.contacts:6d} (body {self.n_body:5d})  "
                f"sweeps {self.sweeps:4d}  residual {self.relative_residual:8.2e}  halved {self.halved:3d} by {by:>5}  "
                f"kinetic {self.kinetic:9.3e} J  "
                f"elastic {self.elastic:9.3e} J  moved {1e3 * self.displacement:8.3f} mm  {self.seconds:6.2f} s")


@dataclass
class Frames:
    """A simulation's frames (the ``/frames`` group) and its log."""

    time: np.ndarray
    omega: np.ndarray
    root: np.ndarray
    frame0: np.ndarray
    body_transform: np.ndarray
    log: list = field(default_factory=list)
    helices: Helices | None = None
    trimmed: bool = False
    body_removed: bool = False
    attrs: dict = field(default_factory=dict)
    stopped: bool = False
    """``on_frame`` stopped the run: the arrays and the log hold only the frames done."""
    body_vertices: np.ndarray | None = None
    """(F, V, 3) float32, m: an animated body at each frame (a shot), else None."""
    body_faces: np.ndarray | None = None
    binding: object = None
    """:class:`hairinv.dynamics.skin.Binding` of a shot's roots, else None."""
    interrupted: bool = False
    """Ctrl-C stopped the run (:class:`hairinv.errors.Interrupted`): the arrays and the log hold only the frames
    done."""
    requested: int = 0
    """the frames the run was asked for (the first, at t = 0, included)"""

    def group(self, config: dict, inputs: list[dict]) -> stages.Group:
        data = {"time": self.time, "omega": self.omega, "root": self.root, "frame0": self.frame0,
                "body_transform": self.body_transform,
                "displacement": np.array([f.displacement for f in self.log]),
                "kinetic_energy": np.array([f.kinetic for f in self.log]),
                "elastic_energy": np.array([f.elastic for f in self.log]),
                "contact_count": np.array([f.contacts for f in self.log], dtype=np.int64),
                "solver_residual": np.array([f.relative_residual for f in self.log]),
                "frame_seconds": np.array([f.seconds for f in self.log])}
        if self.log and all(f.strand_displacement is not None for f in self.log):
            data["strand_displacement"] = np.array([f.strand_displacement for f in self.log], dtype=np.float64)
        if self.body_vertices is not None:
            data["body_vertices"] = self.body_vertices
            data["body_faces"] = np.asarray(self.body_faces, dtype=np.int64)
        if self.binding is not None:
            data.update({f"binding_{key}": value for key, value in self.binding.arrays().items()})
        if self.trimmed:
            data["offsets"] = self.helices.offsets
            data["length"] = self.helices.length
        attrs = dict(self.attrs)
        attrs.update(body_removed=self.body_removed, trimmed=self.trimmed, stopped=self.stopped,
                     interrupted=self.interrupted, frames_requested=int(self.requested or len(self.log)),
                     seconds=float(sum(f.seconds for f in self.log)))
        return stages.Group(stages.FRAMES, data, attrs=attrs, config=config, inputs=inputs)


def initial_rest(init: str, helices: Helices, material: Material, model: stages.Group | None) -> np.ndarray:
    """The rest shape ``q0`` (E, 3) of an initialisation (see the module docstring)."""
    if init == "inverted":
        if model is None:
            raise InputError("has no /model group: invert it first, or simulate with --init naive")
        return rest_from_group(model)
    if init == "naive":
        return helices.omega.copy()
    if init == "gravity-only":
        return helices.omega - generalized_gravity(helices, material) / stiffness(helices, material).reshape(-1, 3)
    raise InputError(f"unknown initialisation {init!r}; choose one of {', '.join(INITS)}")


def _sample_points(helices: Helices, q: np.ndarray, per_element: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Points at the ends and inside every element, all strands at once: (P, 3) in the body frame, and
    ``ptr`` (S + 1,), strand ``k``'s points being ``[ptr[k], ptr[k + 1])`` (``per_element`` per element and
    the tip, evenly spaced in arc length)."""
    S = helices.n_strands
    counts = np.diff(helices.offsets)
    per_strand = per_element * counts + 1
    ptr = np.zeros(S + 1, dtype=np.int64)
    np.cumsum(per_strand, out=ptr[1:])
    strand = np.repeat(np.arange(S, dtype=np.int64), per_strand)
    total = np.bincount(np.repeat(np.arange(S), counts), weights=helices.length, minlength=S)
    # as np.linspace spaces them: index times (total / intervals), the last one exactly the total
    index = np.arange(ptr[-1]) - ptr[strand]
    s = index * (total / np.maximum(per_strand - 1, 1))[strand]
    s[ptr[1:] - 1] = total
    return points_on(helices, np.ascontiguousarray(q, dtype=np.float64), strand, s), ptr


def _samples(helices: Helices, q: np.ndarray, per_element: int = 2) -> list[np.ndarray]:
    """:func:`_sample_points` strand by strand: a list of (k, 3) arrays."""
    points, ptr = _sample_points(helices, q, per_element)
    return np.split(points, ptr[1:-1]) if helices.n_strands else []


def run_scene(helices: Helices, model: stages.Group | None, contacts: Contacts | None, body_mesh,
              scene: Scene, settings: Settings, init: str = "inverted", seconds: float | None = None,
              fps: float | None = None, on_frame=None, on_step=None, body_path=None, shot=None, say=None) -> Frames:
    """Simulate ``scene`` from the model.

    Parameters
    ----------
    helices : Helices, the fitted groom (body frame = the groom's own frame at rest)
    model : the ``/model`` group or None (then only ``naive`` works)
    contacts : the model's contacts and ``model["force"]`` their forces (warm start of the first step)
    body_mesh : trimesh.Trimesh or None, in metres
    scene : Scene
    settings : Settings (``material`` is taken from the model when there is one)
    on_frame : callable(FrameLog), optional, after every frame; returning True stops the run there
    on_step : callable(), optional, after every step
    body_path : the body mesh's file, named by a refusal of its data (a mesh of degenerate triangles only)
    shot : :class:`hairinv.dynamics.skin.Shot` or None: an animated body that moves each root with the
        triangle it is bound to (then ``body_mesh`` is its rest pose, and the scene must not move the body)
    say : callable(str), optional, gets what the binding found

    Raises
    ------
    Interrupted
        Ctrl-C once a frame was done: its ``result`` holds the frames done (``interrupted`` set), whole
        frames only. Before the first frame (a shot's pre-roll included), a plain ``KeyboardInterrupt``.
    """
    seconds = float(scene.seconds if seconds is None else seconds)
    fps = float(scene.fps if fps is None else fps)
    if not seconds > 0 or not fps > 0:
        raise InputError(f"the simulated time and the frame rate must be > 0, got {seconds} s at {fps} fps")
    check_run_length(seconds, fps)
    if model is not None:
        material = material_from_group(model)
    else:
        raise InputError("has no /model group: run `hairinv invert` on it first")
    rest = initial_rest(init, helices, material, model)
    # the inverted model's strands keep the stiffness they were inverted with (/model/stiffening)
    factor = stiffening_from_group(model, helices.n_strands) if init == "inverted" else None
    force = np.asarray(model["force"], dtype=np.float64) if (init == "inverted" and model is not None) else None
    trimmed = False
    if scene.trim is not None:
        if scene.trim.time > 0:
            raise InputError(f"{scene.source}: trim.time must be 0: /frames holds one element layout for the "
                             "whole run, so strands are cut before it starts")
        helices, element_map = trim_helices(helices, length=scene.trim.length, fraction=scene.trim.fraction)
        rest = rest[element_map]
        trimmed = True
        contacts, force = None, None  # the cut groom starts from its own contacts, unloaded
    if shot is not None and scene.moving:
        raise InputError(f"{scene.source}: the scene moves the body by keyframes, and the body file is animated: "
                         "its animation is the body's motion; choose a scene without keyframes (still, trim)")
    body_removed = scene.body == "removed"
    contact_settings = settings.contacts
    if body_removed:
        contact_settings = dataclasses.replace(contact_settings, body=False)
        if contacts is not None:
            keep = contacts.strand[:, 1] >= 0
            contacts = contacts.subset(keep)
            force = None if force is None else force[keep]
    # no body queries where no body contact is modelled (the scene removes it, or contacts.body is off)
    with in_file(body_path):
        body = BodyMesh.from_mesh(body_mesh) if (body_mesh is not None and not body_removed
                                                 and contact_settings.body) else None
    sim = Simulation(helices, rest, material, body, contact_settings, settings.dynamics,
                     initial=contacts, initial_force=force, stiffening=factor)
    skinned = None
    if shot is not None:
        skinned = _skinned(helices, shot, body, material.gravity, body_path, say)

    steps_per_frame = max(1, int(round(1.0 / (fps * settings.dynamics.time_step))))
    h = 1.0 / (fps * steps_per_frame)
    n_frames = int(round(seconds * fps)) + 1
    pivot = scene.pivot_point(helices.root) if helices.n_strands else np.zeros(3)
    world_gravity = material.gravity
    # without gravity there is no up axis (zero): a moving scene, which needs one, says so
    up = -world_gravity / max(np.linalg.norm(world_gravity), 1e-300)
    start_points, sample_ptr = _sample_points(helices, sim.q)

    def state(t: float):
        if not scene.moving:
            return np.eye(3), np.zeros(3), Motion.still(world_gravity)
        m = scene.body_motion(t, pivot, up)
        R = m.R
        return R, m.c, Motion(R.T @ world_gravity, R.T @ m.acceleration, R.T @ m.velocity, R.T @ m.omega,
                              R.T @ m.alpha)

    F, S, E = n_frames, helices.n_strands, helices.n_elements
    out = Frames(np.zeros(F), np.zeros((F, E, 3)), np.zeros((F, S, 3)), np.zeros((F, S, 3, 3)), np.zeros((F, 4, 4)),
                 helices=helices, trimmed=trimmed, body_removed=body_removed, requested=n_frames,
                 attrs={"time_step": h, "steps_per_frame": steps_per_frame, "fps": fps, "init": init,
                        "scene": scene.name})

    if shot is not None:
        out.body_vertices = np.zeros((F, len(shot.bind), 3), dtype=np.float32)
        out.body_faces = shot.faces
        out.binding = skinned.binding
        out.attrs.update(preroll=float(shot.preroll), body_animated=True)

    def record(index: int, t: float, reports: list[StepReport], seconds_used: float) -> bool:
        out.time[index] = t
        out.omega[index] = sim.q
        if shot is None:
            R, c, _ = state(t)
            out.root[index] = helices.root @ R.T + c
            out.frame0[index] = helices.frame0 @ R.T
            out.body_transform[index] = np.eye(4)
            out.body_transform[index, :3, :3] = R
            out.body_transform[index, :3, 3] = c
        else:  # each strand in its own frame; the body deforms (its vertices are kept, its transform is none)
            out.root[index] = np.einsum("nij,nj->ni", sim.R, helices.root) + sim.c
            out.frame0[index] = np.einsum("nij,nkj->nik", helices.frame0, sim.R)
            out.body_transform[index] = np.eye(4)
            out.body_vertices[index] = shot.vertices_at(t)
        now, _ = _sample_points(helices, sim.q)
        distance = np.linalg.norm(now - start_points, axis=1)
        per_strand = np.maximum.reduceat(distance, sample_ptr[:-1]) if len(distance) else np.zeros(0)
        moved = float(per_strand.max()) if len(per_strand) else 0.0
        log = FrameLog(index, t, reports[-1].contacts if reports else sim.contacts.n_contacts,
                       reports[-1].n_body if reports else sim.contacts.n_body,
                       max((r.sweeps for r in reports), default=0),
                       max((r.relative_residual for r in reports), default=0.0),
                       sum(r.status != Status.CONVERGED for r in reports),
                       sim.kinetic_energy(), sim.elastic_energy(), moved, seconds_used,
                       sum(r.substeps - 1 for r in reports),
                       next((r.turned for r in reversed(reports) if r.turned >= 0), -1), per_strand)
        out.log.append(log)
        return on_frame is not None and bool(on_frame(log))

    t = 0.0
    stop, caught = False, False
    try:
        if shot is not None and shot.preroll > 0:
            # the pre-roll: from the groom's pose to the shot's first frame, not recorded
            n_pre = int(np.ceil(shot.preroll / h - 1e-9))
            for k in range(n_pre):
                t = -shot.preroll + k * shot.preroll / n_pre
                try:
                    sim.step(skinned, shot.preroll / n_pre, t)
                except FloatingPointError as exc:
                    raise FloatingPointError(f"in the pre-roll's step from t = {t:.4g} s: {exc}") from None
                if on_step is not None:
                    on_step()
            t = 0.0
        stop = record(0, 0.0, [], 0.0)
        for index in range(1, n_frames):
            if stop:
                break
            began = time.perf_counter()
            reports = []
            for _ in range(steps_per_frame):
                motion = skinned if shot is not None else state(t)[2]
                try:
                    reports.append(sim.step(motion, h, t if shot is not None else None))
                except FloatingPointError as exc:
                    raise FloatingPointError(f"in the step from t = {t:.4g} s: {exc}") from None
                t += h
                if on_step is not None:
                    on_step()
            stop = record(index, index / fps, reports, time.perf_counter() - began)
    except KeyboardInterrupt:
        if not out.log:
            raise
        caught = True  # a frame's log entry is appended once its arrays are filled: the frames logged are whole
    done = len(out.log)
    out.stopped = bool(stop) and done < n_frames
    out.interrupted = caught and not out.stopped and done < n_frames
    if done < n_frames:
        out.time, out.omega, out.root = out.time[:done], out.omega[:done], out.root[:done]
        out.frame0, out.body_transform = out.frame0[:done], out.body_transform[:done]
        if out.body_vertices is not None:
            out.body_vertices = out.body_vertices[:done]
    if caught:
        raise Interrupted(out)
    return out


def _skinned(helices: Helices, shot, body: BodyMesh | None, gravity, body_path, say):
    """The shot's body with the roots bound to its rest pose; roots far from it named, none near refused."""
    from .skin import ROOT_REACH, Binding, MeshArrays, SkinnedBody

    with in_file(body_path):
        bind_body = BodyMesh.from_mesh(MeshArrays(shot.bind, shot.faces))
    binding = Binding.bind(helices.root, shot.bind, shot.faces, body=bind_body)
    far = np.abs(binding.distance) > ROOT_REACH
    if len(far) and far.all():
        raise InputError(f"no root is within {1e3 * ROOT_REACH:g} mm of the animated body (the nearest is "
                         f"{1e3 * np.abs(binding.distance).min():.3g} mm away): check its units and axes "
                         "(--body-units, --body-up)", body_path)
    if far.any() and say is not None:
        say(f"warning: {int(far.sum())} of {len(far)} roots are more than {1e3 * ROOT_REACH:g} mm from the body "
            f"(farthest {1e3 * np.abs(binding.distance).max():.3g} mm, strand {int(np.argmax(np.abs(binding.distance)))}): "
            "each follows its nearest triangle")
    if say is not None:
        say(f"roots bound to {len(np.unique(binding.triangle))} triangles of the body "
            f"(largest distance {1e3 * np.abs(binding.distance).max(initial=0.0):.3g} mm)")
    return SkinnedBody(shot.vertices_at, shot.faces, binding, gravity, contacts=body is not None)

