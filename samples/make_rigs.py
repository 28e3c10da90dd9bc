#!/usr/bin/env python
"""Rigged mannequin shots: the sample bust skinned to a small skeleton, with motions that are hard on hair.

The mannequin is ``samples/body.obj``'s bust (the same vertices, in the same order, built by
``make_samples.build_body``) closed at the chest cut by a flat fan, so the sample grooms sit on it in the
bind pose exactly as they sit on ``body.obj``. Metres, +Y up, the face toward +Z, the body's left at +X;
the head is 0.24 m from the chin (y = 1.495) to the top (y = 1.735).

The skeleton (all joints on the body's vertical axis x = z = 0, unrotated in the bind pose)::

    root  (0, 1.200, 0)   the chest cut: the whole body moves with it (jump, stop, walk)
    chest (0, 1.360, 0)   the torso above the lower chest (walk sway)
    neck  (0, 1.490, 0)   the base of the neck
    head  (0, 1.575, 0)   the skull base

Skin weights follow the parts the bust is blended from (``make_samples.profile_parts``): a vertex's share
of the head, neck and torso parts is ``r_part^8 / sum r^8``, ``r_part`` being the part's own radius in the
vertex's direction (the bust is the smooth maximum of the three with the same exponent), so the weights
blend smoothly over the neck (into the chest from y = 1.41 to 1.47, into the head from y = 1.51 to 1.60)
and under the chin; below y = 1.36 only the torso counts. The torso's share goes to the chest above
y = 1.34 and to the root below y = 1.24, blended between. Shares under 0.002 are dropped and the rest
renormalised: the skull (above y = 1.60 or so) is weighted to the head alone, rigidly.

Motions (each a function returning a :class:`Motion`: the root's translation and every joint's local
rotation at each frame, 30 fps unless asked otherwise; every one starts with ``lead`` seconds still in the
bind pose, so a simulation can start from the bind pose at rest):

``turn(angle=90, duration=0.3)``
    The head turns about the vertical axis (positive: toward its left, +X) by ``angle`` degrees in
    ``duration`` seconds with a minimum-jerk profile (peak 1.875 angle / duration), then holds. The neck
    takes ``neck_share`` (0.4) of the turn and the head the rest; both joints are on the vertical axis,
    so whatever is weighted to the head alone turns by exactly ``angle`` about it.
``nod(angle=30, down=0.4, up=0.4)``
    The head pitches forward (chin down) by ``angle`` degrees in ``down`` seconds and back up in ``up``
    seconds (minimum jerk, the neck taking 0.4 of it), then holds.
``jump(height=0.3)``
    The whole body pushes off (velocity rising smoothly to the take-off speed over ``push`` = 0.12 s),
    flies ballistically (g = 9.81 m/s^2) to ``height`` above its start and falls back, lands at its start
    height at sqrt(2 g height) (2.43 m/s for 0.3 m) and stops within ``land`` = 0.1 s (about 5 g; the body
    sinks by half the landing speed times ``land``), then rises back to its start height over ``recover``.
``stop(speed=1.5, stop=0.1)``
    A walk-like forward run along +Z: the body speeds up to ``speed`` m/s over ``accelerate`` = 0.6 s,
    keeps it for ``cruise`` = 0.8 s, and stops within ``stop`` seconds (``speed / stop`` m/s^2 on average,
    15 m/s^2 for the defaults); while it moves it bobs (1.2 cm at every step) and the chest sways (4
    degrees of yaw per stride, the head keeping half of it back), in proportion to the speed.
``walk(speed=1.2)``
    The same gait at a steady ``speed`` after a ``ramp`` of 0.5 s, for ``duration`` seconds: a stride
    sway (chest yaw and roll, head counter-turn) and a bob.
``hold(duration=1.0)``
    The bind pose, keyed: an animated body that does not move (a groom inverted on it must stay still).

``VARIANTS`` names ready-made shots (motion, parameters, frame rate, head seed); ``DEVELOPMENT`` and
``HELD_OUT`` split them, so that dynamics are tuned on some and judged on the others. A head seed other
than 0 gives a slightly different head (a smooth warp of space about the head centre, fading out below
the chin: its size, width, depth, the back of the skull and a slight asymmetry change by a few per cent),
and the variant's groom is the sample straight groom under the same warp, so it sits on that head as the
sample sits on the sample bust.

Files, per variant, in ``OUTDIR/NAME/``: ``NAME.glb`` (glTF 2.0 binary: one skinned mesh, the four joints,
inverse bind matrices, JOINTS_0/WEIGHTS_0, one animation of LINEAR samplers keyed at every frame: the
root's translation and the joints' rotations), ``NAME.usda`` (UsdSkel: a SkelRoot holding the skeleton, its
SkelAnimation sampled at every frame as time codes 0, 1, ... at ``fps`` time codes per second, and the
skinned mesh), ``frames/body.####.obj`` (the posed mesh at every frame, frame 0 first: read it with
``--fps`` equal to the variant's), ``groom.h5`` (a hairinv stage file holding ``/curves``: the groom in the
bind pose) and ``rig.json`` (what the variant is). Frame ``k`` is at ``k / fps`` seconds in all three; frame
0 is the bind pose.

Command line (from the project root)::

    .venv/bin/python samples/make_rigs.py [-o OUTDIR] [--no-check] [NAME ...]   # default out/rigs, every variant
    .venv/bin/python samples/make_rigs.py --sample                              # rewrite samples/turn.glb

For every variant written it prints the head's peak speed and acceleration and reads the files back with
hairinv's readers (``hairinv.formats.read_animated_body``), comparing them with this script's own linear
blend skinning at every frame (they agree to float32 storage, under 1e-6 m). ``--sample`` writes
``samples/turn.glb``: the sample bust turning its head by 90 degrees (``turn90``), the shot of the README.
Everything is deterministic: rerunning gives byte-identical files.
"""

from __future__ import annotations

import argparse
import json
import shutil
import struct
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
for _p in (ROOT, HERE):
    if str(_p) not in sys.path:
        sys.path.insert(0, str(_p))

import make_samples as ms  # noqa: E402

FPS = 30.0
GRAVITY = 9.81
JOINTS = ("root", "chest", "neck", "head")
PARENTS = (-1, 0, 1, 2)
ROOT_J, CHEST, NECK, HEAD = range(4)


def f32(a) -> np.ndarray:
    """``a`` rounded to float32 and held as float64: the values the files store."""
    return np.asarray(a, dtype=np.float64).astype(np.float32).astype(np.float64)


# bind-pose joint positions (world, metres), float32 values so that every file states them exactly
JOINT_POSITIONS = f32([[0.0, 1.200, 0.0], [0.0, 1.360, 0.0], [0.0, 1.490, 0.0], [0.0, 1.575, 0.0]])
# their translations from the parent joint (exact in float32: differences of nearby float32 values)
JOINT_OFFSETS = np.array([JOINT_POSITIONS[j] - (JOINT_POSITIONS[p] if p >= 0 else 0.0) for j, p in enumerate(PARENTS)])


# --------------------------------------------------------------------------
# The mannequin
# --------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Rig:
    """The skinned mannequin.

    ``vertices`` (V, 3) is the bind pose in metres and ``weights`` (V, 4) each vertex's weight of every
    joint of ``JOINTS``, both float32 values held as float64 (what the files store); ``faces`` (F, 3) has
    outward winding; ``seed`` is the head seed.
    """

    vertices: np.ndarray
    faces: np.ndarray
    weights: np.ndarray
    seed: int = 0


def smoothstep(e0, e1, x):
    return ms.smoothstep(e0, e1, x)


def skin_weights(p, sharpness=8.0, prune=0.002) -> np.ndarray:
    """Weights (V, 4) of the joints at points ``p`` on the undeformed bust (see the module's docstring)."""
    theta = np.arctan2(p[:, 2], p[:, 0])
    y = p[:, 1]
    # each part's radius in the vertex's direction (0 where the part has shrunk to nothing: the neck above the
    # head's centre, everything at the pole, which goes to the head)
    radii = np.stack([np.where(np.maximum(a, np.maximum(bf, bb)) > 0, ms.ring_radius(theta, a, bf, bb, n), 0.0)
                      for a, bf, bb, n in ms.profile_parts(y)])  # head, neck, torso
    power = radii**sharpness
    total = power.sum(axis=0)
    share = np.where(total > 0, power / np.where(total > 0, total, 1.0), np.array([[1.0], [0.0], [0.0]]))
    # below the shoulders (and at the centre of the cap) only the torso counts
    share[:2] *= smoothstep(1.36, 1.40, y)
    share[2] = 1.0 - share[0] - share[1]
    chest = smoothstep(1.24, 1.34, y)
    w = np.stack([share[2] * (1.0 - chest), share[2] * chest, share[1], share[0]], axis=1)
    w[w < prune] = 0.0
    w /= w.sum(axis=1, keepdims=True)
    # float32, the largest weight taking up the rounding so that the stored weights add up to 1 as well as
    # float32 can
    w32 = w.astype(np.float32)
    top = np.argmax(w32, axis=1)
    rows = np.arange(len(w32))
    rest = w32.sum(axis=1, dtype=np.float64) - w32[rows, top]
    w32[rows, top] = (1.0 - rest).astype(np.float32)
    return w32.astype(np.float64)


def head_warp(seed: int):
    """The smooth map of space that changes the head's shape for head seed ``seed`` (0: none).

    ``p -> p + s(y) e(u) (p - c)``: about the head centre ``c``, a point moves out along its direction ``u``
    by ``e(u)`` of its distance (a few per cent: size, width, depth, the back of the skull, a slight
    asymmetry), ``s`` fading that out from the skull (y = 1.60) to the shoulders (y = 1.47). Small, so it
    is one-to-one: what lies outside the head stays outside.
    """
    if seed == 0:
        return lambda p: np.array(p, dtype=np.float64)
    rng = np.random.default_rng(1000 + seed)
    a = rng.uniform(-1.0, 1.0, 5) * np.array([0.03, 0.05, 0.05, 0.04, 0.015])
    c = np.array([0.0, ms.HEAD_C, -0.005])

    def warp(p):
        p = np.asarray(p, dtype=np.float64)
        d = p - c
        u = d / np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-9)
        e = a[0] + a[1] * u[..., 0] ** 2 + a[2] * u[..., 2] ** 2 + a[3] * u[..., 1] * u[..., 2] + a[4] * u[..., 0]
        return p + (smoothstep(1.47, 1.60, p[..., 1]) * e)[..., None] * d

    return warp


def mannequin(seed: int = 0, rings: int = 42, segments: int = 64) -> Rig:
    """The skinned mannequin of head seed ``seed``: the sample bust (``rings`` x ``segments``, the sample's
    own resolution by default) closed at the chest cut, weighted, its head warped by ``head_warp(seed)``."""
    closed = ms.capped(ms.build_body(rings, segments))
    vertices = np.asarray(closed.vertices, dtype=np.float64)
    weights = skin_weights(vertices)
    return Rig(f32(head_warp(seed)(vertices)), np.asarray(closed.faces, dtype=np.int64), weights, seed)


# --------------------------------------------------------------------------
# Quaternions (x, y, z, w), glTF's order
# --------------------------------------------------------------------------


def axis_angle(axis, angle) -> np.ndarray:
    """Unit quaternion of a rotation by ``angle`` radians about ``axis``."""
    axis = np.asarray(axis, dtype=np.float64) / np.linalg.norm(axis)
    return np.r_[np.sin(angle / 2.0) * axis, np.cos(angle / 2.0)]


def quat_mul(a, b) -> np.ndarray:
    """The rotation ``a`` after ``b`` (Hamilton product)."""
    (ax, ay, az, aw), (bx, by, bz, bw) = a, b
    return np.array([aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz])


def quat_matrix(q) -> np.ndarray:
    """3x3 rotation of a quaternion (normalised first, as readers do with stored float32 quaternions)."""
    x, y, z, w = np.asarray(q, dtype=np.float64) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


YAW, PITCH, ROLL = np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])


# --------------------------------------------------------------------------
# Motions
# --------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Motion:
    """Keys of a motion at every frame ``k`` (time ``k / fps``).

    ``translation`` (K, 3): the root joint's translation (its bind position plus the body's motion),
    ``rotation`` (K, 4, 4): every joint's local rotation, quaternions (x, y, z, w); float32 values held as
    float64, as the files store them. ``params`` are the motion's parameters as given.
    """

    name: str
    fps: float
    translation: np.ndarray
    rotation: np.ndarray
    params: dict = field(default_factory=dict)

    @property
    def frames(self) -> int:
        return len(self.translation)

    @property
    def times(self) -> np.ndarray:
        return np.arange(self.frames) / self.fps

    @property
    def duration(self) -> float:
        return (self.frames - 1) / self.fps


def sample(name, at, duration, fps, params) -> Motion:
    """A motion from ``at(t) -> (body offset (3,), {joint: quaternion})`` sampled at every frame up to ``duration``."""
    times = np.arange(int(round(duration * fps)) + 1) / fps
    translation = np.empty((len(times), 3))
    rotation = np.tile(np.array([0.0, 0.0, 0.0, 1.0]), (len(times), len(JOINTS), 1))
    for k, t in enumerate(times):
        offset, turns = at(t)
        translation[k] = JOINT_POSITIONS[ROOT_J] + offset
        for j, q in turns.items():
            rotation[k, j] = q
    return Motion(name, float(fps), f32(translation), f32(rotation), dict(params, fps=fps))


def minimum_jerk(u):
    """0 -> 1 over u in [0, 1] with zero velocity and acceleration at both ends."""
    u = np.clip(u, 0.0, 1.0)
    return u**3 * (10.0 - 15.0 * u + 6.0 * u * u)


def _ease(u):
    """Smoothstep, 0 -> 1 over u in [0, 1], and its integral from 0 (a velocity ramp and the distance it covers)."""
    u = np.clip(u, 0.0, 1.0)
    return 3 * u**2 - 2 * u**3, u**3 - 0.5 * u**4


def _split(angle, axis, neck_share):
    """The neck's and the head's local rotations that make ``angle`` about ``axis`` together."""
    return {NECK: axis_angle(axis, neck_share * angle), HEAD: axis_angle(axis, (1.0 - neck_share) * angle)}


def turn(angle=90.0, duration=0.3, lead=0.2, hold=1.0, neck_share=0.4, fps=FPS) -> Motion:
    """The head turns by ``angle`` degrees (positive toward its left, +X) in ``duration`` s, then holds."""
    params = dict(angle=angle, duration=duration, lead=lead, hold=hold, neck_share=neck_share)

    def at(t):
        return np.zeros(3), _split(np.radians(angle) * minimum_jerk((t - lead) / duration), YAW, neck_share)

    return sample("turn", at, lead + duration + hold, fps, params)


def nod(angle=30.0, down=0.4, up=0.4, pause=0.0, lead=0.2, hold=0.6, neck_share=0.4, fps=FPS) -> Motion:
    """The head pitches forward by ``angle`` degrees in ``down`` s, (after ``pause``) back in ``up`` s, then holds."""
    params = dict(angle=angle, down=down, up=up, pause=pause, lead=lead, hold=hold, neck_share=neck_share)

    def at(t):
        s = minimum_jerk((t - lead) / down) - minimum_jerk((t - lead - down - pause) / up)
        return np.zeros(3), _split(np.radians(angle) * s, PITCH, neck_share)

    return sample("nod", at, lead + down + pause + up + hold, fps, params)


def jump_profile(height=0.3, push=0.12, land=0.1, recover=0.4, lead=0.2):
    """The jump's height ``y(t)`` (a function) and its phases' end times (push, flight, landing, recovery).

    The take-off speed ``v0`` makes the apex ``height``: ``v0 push / 2`` rising during the push plus
    ``v0^2 / 2g`` in flight. The body lands at its start height at ``vl = sqrt(2 g height)``.
    """
    g = GRAVITY
    v0 = (-push / 2 + np.sqrt((push / 2) ** 2 + 2 * height / g)) * g
    y1 = v0 * push / 2
    vl = np.sqrt(2 * g * height)
    flight = (v0 + vl) / g
    t1 = lead + push
    t2 = t1 + flight
    t3 = t2 + land
    dip = vl * land / 2
    t4 = t3 + recover

    def y(t):
        if t < lead:
            return 0.0
        if t < t1:
            return v0 * push * _ease((t - lead) / push)[1]
        if t < t2:
            tau = t - t1
            return y1 + v0 * tau - 0.5 * g * tau * tau
        if t < t3:
            u = (t - t2) / land
            return -vl * land * (u - _ease(u)[1])
        return -dip * (1.0 - minimum_jerk((t - t3) / recover))

    return y, (t1, t2, t3, t4), dict(takeoff_speed=v0, landing_speed=vl, dip=dip)


def jump(height=0.3, push=0.12, land=0.1, recover=0.4, lead=0.2, hold=0.4, fps=FPS) -> Motion:
    """The whole body jumps ``height`` m up and lands with a stop within ``land`` s (see the module's docstring)."""
    params = dict(height=height, push=push, land=land, recover=recover, lead=lead, hold=hold)
    y, ends, _ = jump_profile(height, push, land, recover, lead)
    return sample("jump", lambda t: (np.array([0.0, y(t), 0.0]), {}), ends[-1] + hold, fps, params)


def _gait(t, share, lead, step, bob, sway, roll):
    """The bob (m, down) and the chest's and head's rotations of a walk at ``share`` of its full amplitude."""
    phase = np.pi * (t - lead) / step  # one step per pi, a stride (two steps) per 2 pi
    down = -bob * share * np.sin(phase) ** 2
    yaw = np.radians(sway) * share * np.sin(phase)
    tilt = np.radians(roll) * share * np.sin(phase)
    chest = quat_mul(axis_angle(YAW, yaw), axis_angle(ROLL, tilt))
    return down, {CHEST: chest, HEAD: axis_angle(YAW, -0.5 * yaw)}


def stop(speed=1.5, stop=0.1, accelerate=0.6, cruise=0.8, lead=0.2, hold=0.8, step=0.5, bob=0.012, sway=4.0,
         roll=2.0, fps=FPS) -> Motion:
    """A walk-like run forward (+Z) at ``speed`` m/s that stops within ``stop`` s (see the module's docstring)."""
    params = dict(speed=speed, stop=stop, accelerate=accelerate, cruise=cruise, lead=lead, hold=hold, step=step,
                  bob=bob, sway=sway, roll=roll)
    t1, t2 = lead + accelerate, lead + accelerate + cruise
    d1 = speed * accelerate / 2

    def at(t):
        if t < lead:
            z, v = 0.0, 0.0
        elif t < t1:
            ramp, covered = _ease((t - lead) / accelerate)
            z, v = speed * accelerate * covered, speed * ramp
        elif t < t2:
            z, v = d1 + speed * (t - t1), speed
        else:
            ramp, covered = _ease((t - t2) / stop)
            u = min((t - t2) / stop, 1.0)
            z, v = d1 + speed * cruise + speed * stop * (u - covered), speed * (1.0 - ramp)
        down, turns = _gait(t, v / speed, lead, step, bob, sway, roll)
        return np.array([0.0, down, z]), turns

    return sample("stop", at, t2 + stop + hold, fps, params)


def walk(speed=1.2, ramp=0.5, duration=3.0, lead=0.2, step=0.55, bob=0.015, sway=5.0, roll=2.5, fps=FPS) -> Motion:
    """A steady walk forward (+Z) at ``speed`` m/s reached over ``ramp`` s, swaying, for ``duration`` s."""
    params = dict(speed=speed, ramp=ramp, duration=duration, lead=lead, step=step, bob=bob, sway=sway, roll=roll)

    def at(t):
        share, covered = _ease((t - lead) / ramp)
        z = speed * ramp * covered + speed * max(t - lead - ramp, 0.0)
        down, turns = _gait(t, share, lead, step, bob, sway, roll)
        return np.array([0.0, down, z]), turns

    return sample("walk", at, duration, fps, params)


def hold(duration=1.0, fps=FPS) -> Motion:
    """The bind pose at every frame."""
    return sample("hold", lambda t: (np.zeros(3), {}), duration, fps, dict(duration=duration))


MOTIONS = {"turn": turn, "nod": nod, "jump": jump, "stop": stop, "walk": walk, "hold": hold}

# name: (motion, its parameters, frame rate, head seed)
VARIANTS = {
    "turn90": ("turn", dict(angle=90.0, duration=0.3), 30.0, 0),
    "turn60_fast": ("turn", dict(angle=60.0, duration=0.2), 24.0, 1),
    "turn_right75": ("turn", dict(angle=-75.0, duration=0.25), 30.0, 2),
    "turn45_snap": ("turn", dict(angle=45.0, duration=0.15, neck_share=0.3), 30.0, 3),
    "nod30": ("nod", dict(angle=30.0, down=0.4, up=0.4), 30.0, 0),
    "nod20_fast": ("nod", dict(angle=20.0, down=0.25, up=0.25), 24.0, 4),
    "nod40_pause": ("nod", dict(angle=40.0, down=0.5, up=0.3, pause=0.2), 30.0, 5),
    "jump30": ("jump", dict(height=0.3), 30.0, 0),
    "jump20": ("jump", dict(height=0.2, land=0.08), 24.0, 6),
    "stop15": ("stop", dict(speed=1.5, stop=0.1), 30.0, 0),
    "stop20": ("stop", dict(speed=2.0, stop=0.08), 30.0, 7),
    "hold": ("hold", dict(), 30.0, 0),
    "hold_head8": ("hold", dict(), 24.0, 8),
    "walk": ("walk", dict(speed=1.2), 30.0, 0),
    "walk_fast": ("walk", dict(speed=1.6, step=0.45), 24.0, 9),
}
DEVELOPMENT = ("turn90", "turn60_fast", "nod30", "jump30", "stop15", "hold", "walk")
HELD_OUT = tuple(name for name in VARIANTS if name not in DEVELOPMENT)


def variant(name: str) -> tuple[Rig, Motion]:
    """The mannequin and the motion of variant ``name``."""
    kind, params, fps, seed = VARIANTS[name]
    motion = MOTIONS[kind](fps=fps, **params)
    return mannequin(seed), Motion(name, motion.fps, motion.translation, motion.rotation,
                                   dict(motion.params, motion=kind))


# --------------------------------------------------------------------------
# Posing: linear blend skinning
# --------------------------------------------------------------------------


def joint_world(translation, rotation) -> np.ndarray:
    """World matrices (4, 4, 4) of the joints with the root at ``translation`` and local ``rotation`` (4, 4)."""
    world = np.empty((len(JOINTS), 4, 4))
    for j, parent in enumerate(PARENTS):
        local = np.eye(4)
        local[:3, :3] = quat_matrix(rotation[j])
        local[:3, 3] = translation if parent < 0 else JOINT_OFFSETS[j]
        world[j] = local if parent < 0 else world[parent] @ local
    return world


def inverse_bind() -> np.ndarray:
    """Inverse bind matrices (4, 4, 4): the joints are unrotated in the bind pose."""
    out = np.tile(np.eye(4), (len(JOINTS), 1, 1))
    out[:, :3, 3] = -JOINT_POSITIONS
    return out


def pose(rig: Rig, motion: Motion, k: int) -> np.ndarray:
    """The mannequin's vertices (V, 3) at frame ``k``: ``sum_j w_j J_j B_j [v, 1]``."""
    skin = joint_world(motion.translation[k], motion.rotation[k]) @ inverse_bind()
    blended = np.einsum("vj,jab->vab", rig.weights, skin[:, :3, :])
    return np.einsum("vab,vb->va", blended[:, :, :3], rig.vertices) + blended[:, :, 3]


def poses(rig: Rig, motion: Motion) -> np.ndarray:
    """(K, V, 3): every frame."""
    return np.stack([pose(rig, motion, k) for k in range(motion.frames)])


# --------------------------------------------------------------------------
# Files
# --------------------------------------------------------------------------

_FLOAT, _UBYTE, _USHORT, _UINT = 5126, 5121, 5123, 5125
_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963


def glb_document(rig: Rig, motion: Motion) -> tuple[dict, bytes]:
    """The glTF 2.0 document and its binary buffer."""
    blob, views, accessors = bytearray(), [], []

    def add(array, component, kind, target=None, bounds=False):
        array = np.ascontiguousarray(array)
        while len(blob) % 4:
            blob.append(0)
        view = {"buffer": 0, "byteOffset": len(blob), "byteLength": array.nbytes}
        if target is not None:
            view["target"] = target
        views.append(view)
        blob.extend(array.tobytes())
        accessor = {"bufferView": len(views) - 1, "componentType": component, "count": int(array.shape[0]),
                    "type": kind}
        if bounds:
            flat = array.reshape(len(array), -1).astype(np.float64)
            accessor["min"], accessor["max"] = flat.min(axis=0).tolist(), flat.max(axis=0).tolist()
        accessors.append(accessor)
        return len(accessors) - 1

    # influences by decreasing weight; an unused one names joint 0 with weight 0, as the specification asks
    order = np.argsort(-rig.weights, axis=1, kind="stable")
    weights = np.take_along_axis(rig.weights, order, axis=1)
    joints = np.where(weights > 0, order, 0)
    small = len(rig.vertices) < 65535
    attributes = {
        "POSITION": add(rig.vertices.astype(np.float32), _FLOAT, "VEC3", _ARRAY_BUFFER, bounds=True),
        "JOINTS_0": add(joints.astype(np.uint8), _UBYTE, "VEC4", _ARRAY_BUFFER),
        "WEIGHTS_0": add(weights.astype(np.float32), _FLOAT, "VEC4", _ARRAY_BUFFER),
    }
    indices = add(rig.faces.ravel().astype(np.uint16 if small else np.uint32), _USHORT if small else _UINT, "SCALAR",
                  _ELEMENT_ARRAY_BUFFER)
    ibm = add(np.ascontiguousarray(inverse_bind().transpose(0, 2, 1)).reshape(len(JOINTS), 16).astype(np.float32),
              _FLOAT, "MAT4")
    times = add(motion.times.astype(np.float32), _FLOAT, "SCALAR", bounds=True)
    samplers = [{"input": times, "output": add(motion.translation.astype(np.float32), _FLOAT, "VEC3"),
                 "interpolation": "LINEAR"}]
    channels = [{"sampler": 0, "target": {"node": 1 + ROOT_J, "path": "translation"}}]
    for j in range(len(JOINTS)):
        samplers.append({"input": times, "output": add(motion.rotation[:, j].astype(np.float32), _FLOAT, "VEC4"),
                         "interpolation": "LINEAR"})
        channels.append({"sampler": len(samplers) - 1, "target": {"node": 1 + j, "path": "rotation"}})
    nodes = [{"name": "mannequin", "mesh": 0, "skin": 0}]
    for j, name in enumerate(JOINTS):
        node = {"name": name, "translation": JOINT_OFFSETS[j].tolist()}
        if j + 1 < len(JOINTS):
            node["children"] = [2 + j]
        nodes.append(node)
    doc = {
        "asset": {"version": "2.0", "generator": "hairinv samples/make_rigs.py",
                  "extras": {"motion": motion.name, "fps": motion.fps, "params": motion.params,
                             "head_seed": rig.seed}},
        "scene": 0,
        "scenes": [{"name": motion.name, "nodes": [0, 1]}],
        "nodes": nodes,
        "meshes": [{"name": "mannequin", "primitives": [{"attributes": attributes, "indices": indices, "mode": 4}]}],
        "skins": [{"name": "mannequin", "joints": [1 + j for j in range(len(JOINTS))], "inverseBindMatrices": ibm,
                   "skeleton": 1}],
        "animations": [{"name": motion.name, "channels": channels, "samplers": samplers}],
        "buffers": [{"byteLength": len(blob) + (-len(blob) % 4)}],
        "bufferViews": views,
        "accessors": accessors,
    }
    return doc, bytes(blob) + b"\0" * (-len(blob) % 4)


def write_glb(path, rig: Rig, motion: Motion) -> Path:
    """``path`` as a GLB: the 12-byte header, the JSON chunk (padded with spaces), the BIN chunk (with zeros)."""
    doc, blob = glb_document(rig, motion)
    text = json.dumps(doc, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    chunks = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(blob), 0x004E4942) + blob
    path = Path(path)
    path.write_bytes(struct.pack("<4sII", b"glTF", 2, 12 + len(chunks)) + chunks)
    return path


def write_usd(path, rig: Rig, motion: Motion) -> Path:
    """``path`` (.usda, .usdc or .usd) as UsdSkel: SkelRoot /Mannequin holding the Skeleton (its joints'
    bind and rest transforms), its SkelAnimation keyed at time codes 0 .. K-1 (``fps`` codes per second) and
    the skinned Mesh (every vertex naming all four joints)."""
    from pxr import Gf, Usd, UsdGeom, UsdSkel, Vt

    path = Path(path)
    if path.exists():
        path.unlink()
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    stage.SetTimeCodesPerSecond(motion.fps)
    stage.SetFramesPerSecond(motion.fps)
    stage.SetStartTimeCode(0)
    stage.SetEndTimeCode(motion.frames - 1)
    stage.GetRootLayer().documentation = (f"hairinv mannequin, motion '{motion.name}' "
                                          f"{json.dumps(motion.params, sort_keys=True)}, head seed {rig.seed}; "
                                          "metres, +Y up, face toward +Z; written by samples/make_rigs.py")
    root = UsdSkel.Root.Define(stage, "/Mannequin")
    stage.SetDefaultPrim(root.GetPrim())
    skel = UsdSkel.Skeleton.Define(stage, "/Mannequin/Skeleton")
    paths = ["/".join(JOINTS[: j + 1]) for j in range(len(JOINTS))]
    skel.CreateJointsAttr(paths)

    def matrix(M):
        return Gf.Matrix4d(np.asarray(M).T.tolist())

    def translation(t):
        return np.c_[np.eye(4)[:, :3], np.r_[t, 1.0]]

    skel.CreateBindTransformsAttr(Vt.Matrix4dArray([matrix(translation(p)) for p in JOINT_POSITIONS]))
    skel.CreateRestTransformsAttr(Vt.Matrix4dArray([matrix(translation(t)) for t in JOINT_OFFSETS]))
    anim = UsdSkel.Animation.Define(stage, "/Mannequin/Skeleton/Motion")
    anim.CreateJointsAttr(paths)
    translations, rotations = anim.CreateTranslationsAttr(), anim.CreateRotationsAttr()
    anim.CreateScalesAttr().Set(Vt.Vec3hArray([Gf.Vec3h(1, 1, 1)] * len(JOINTS)))
    for k in range(motion.frames):
        offsets = JOINT_OFFSETS.copy()
        offsets[ROOT_J] = motion.translation[k]
        translations.Set(Vt.Vec3fArray([Gf.Vec3f(*map(float, t)) for t in offsets]), Usd.TimeCode(k))
        rotations.Set(Vt.QuatfArray([Gf.Quatf(float(q[3]), Gf.Vec3f(*map(float, q[:3]))) for q in motion.rotation[k]]),
                      Usd.TimeCode(k))
    UsdSkel.BindingAPI.Apply(skel.GetPrim()).CreateAnimationSourceRel().SetTargets([anim.GetPath()])
    mesh = UsdGeom.Mesh.Define(stage, "/Mannequin/Body")
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(rig.vertices.astype(np.float32)))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(rig.faces), 3, dtype=np.int32)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(rig.faces.ravel().astype(np.int32)))
    mesh.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, rig.vertices.min(axis=0))),
                                         Gf.Vec3f(*map(float, rig.vertices.max(axis=0)))]))
    binding = UsdSkel.BindingAPI.Apply(mesh.GetPrim())
    binding.CreateSkeletonRel().SetTargets([skel.GetPath()])
    indices = np.tile(np.arange(len(JOINTS), dtype=np.int32), len(rig.vertices))
    binding.CreateJointIndicesPrimvar(False, len(JOINTS)).Set(Vt.IntArray.FromNumpy(indices))
    binding.CreateJointWeightsPrimvar(False, len(JOINTS)).Set(
        Vt.FloatArray.FromNumpy(rig.weights.astype(np.float32).ravel()))
    binding.CreateGeomBindTransformAttr(Gf.Matrix4d(1.0))
    stage.GetRootLayer().Save()
    return path


def write_obj(path, vertices, faces, header=()):
    """One OBJ frame: vertices to 0.1 micrometre, 1-based triangles."""
    lines = [f"# {h}" for h in header]
    lines += [f"v {x:.7f} {y:.7f} {z:.7f}" for x, y, z in vertices]
    lines += [f"f {i + 1} {j + 1} {k + 1}" for i, j, k in faces]
    Path(path).write_text("\n".join(lines) + "\n")


def write_obj_sequence(folder, rig: Rig, motion: Motion, posed=None) -> Path:
    """``folder/body.####.obj``, frame ``k`` the mannequin posed at frame ``k`` (time ``k / fps``)."""
    folder = Path(folder)
    if folder.exists():
        shutil.rmtree(folder)
    folder.mkdir(parents=True)
    posed = poses(rig, motion) if posed is None else posed
    for k, vertices in enumerate(posed):
        header = (f"hairinv mannequin, motion '{motion.name}', frame {k} of {motion.frames} at {motion.fps:g} fps "
                  f"(t = {k / motion.fps:.6f} s)", "units: metres; +Y up; face toward +Z",
                  "written by samples/make_rigs.py") if k == 0 else ()
        write_obj(folder / f"body.{k:04d}.obj", vertices, rig.faces, header)
    return folder / "body.####.obj"


def sample_groom(name="straight"):
    """A sample groom's ``(points (P, 3), offsets (S + 1,))`` from ``samples/NAME.h5``."""
    import h5py

    with h5py.File(HERE / f"{name}.h5", "r") as f:
        return f["curves/points"][()], f["curves/offsets"][()]


def groom(seed: int = 0, name="straight"):
    """The sample groom ``name`` on head ``seed``: its points under ``head_warp(seed)``."""
    points, offsets = sample_groom(name)
    return head_warp(seed)(points), offsets


def write_groom(path, seed: int = 0, name="straight") -> Path:
    from hairinv.formats.hdf5 import write_hdf5_curves

    points, offsets = groom(seed, name)
    write_hdf5_curves(path, points, offsets, up=(0.0, 1.0, 0.0),
                      source=f"hairinv sample groom '{name}' on mannequin head {seed} (samples/make_rigs.py)",
                      command="samples")
    return Path(path)


def write_variant(outdir, name: str, check: bool = True) -> dict:
    """Every file of variant ``name`` in ``outdir/name/``; returns what ``rig.json`` holds."""
    rig, motion = variant(name)
    folder = Path(outdir) / name
    folder.mkdir(parents=True, exist_ok=True)
    posed = poses(rig, motion)
    files = {
        "glb": write_glb(folder / f"{name}.glb", rig, motion),
        "usd": write_usd(folder / f"{name}.usda", rig, motion),
        "obj": write_obj_sequence(folder / "frames", rig, motion, posed),
        "groom": write_groom(folder / "groom.h5", rig.seed),
    }
    info = {
        "name": name, "motion": motion.params["motion"], "params": motion.params, "fps": motion.fps,
        "frames": motion.frames, "duration_s": motion.duration, "head_seed": rig.seed,
        "split": "development" if name in DEVELOPMENT else "held out",
        "vertices": len(rig.vertices), "triangles": len(rig.faces), "joints": list(JOINTS),
        "files": {k: str(v.relative_to(folder)) for k, v in files.items()},
        "head": head_motion(rig, motion, posed),
    }
    if check:
        info["agreement_m"] = check_files(rig, motion, files, posed)
    (folder / "rig.json").write_text(json.dumps(info, indent=2) + "\n")
    return info


def write_sample(path=HERE / "turn.glb") -> Path:
    """``samples/turn.glb``: the sample bust (head seed 0) turning its head by 90 degrees in 0.3 s."""
    rig, motion = variant("turn90")
    return write_glb(path, rig, motion)


# --------------------------------------------------------------------------
# Checks
# --------------------------------------------------------------------------


def head_motion(rig: Rig, motion: Motion, posed) -> dict:
    """Peak speed and acceleration of the top of the head and of the skull's widest ring (finite differences
    of the frames), and the largest displacement from the bind pose."""
    top = np.argmax(rig.vertices[:, 1])
    head = np.flatnonzero(rig.weights[:, HEAD] == 1.0)
    dt = 1.0 / motion.fps
    out = {"rigid_head_vertices": int(len(head))}
    if motion.frames >= 3:
        v = np.diff(posed[:, head], axis=0) / dt
        a = np.diff(posed[:, head], n=2, axis=0) / dt**2
        out["head_peak_speed_m_s"] = float(np.linalg.norm(v, axis=-1).max())
        out["head_peak_acceleration_m_s2"] = float(np.linalg.norm(a, axis=-1).max())
    out["top_of_head_path_m"] = float(np.linalg.norm(np.diff(posed[:, top], axis=0), axis=-1).sum())
    out["largest_displacement_m"] = float(np.linalg.norm(posed - rig.vertices[None], axis=-1).max())
    return out


def check_files(rig: Rig, motion: Motion, files: dict, posed) -> dict:
    """The largest distance (m) between each file read back with hairinv's readers and this script's posing,
    over every frame (the bind pose included)."""
    from hairinv.formats import read_animated_body

    worst = {}
    for kind in ("glb", "usd", "obj"):
        body = read_animated_body(files[kind], fps=motion.fps if kind == "obj" else None)
        if len(body.times) != motion.frames or not np.allclose(body.times, motion.times, atol=1e-6):
            raise SystemExit(f"{files[kind]}: {len(body.times)} frames read back, {motion.frames} written")
        if not np.array_equal(body.faces, rig.faces):
            raise SystemExit(f"{files[kind]}: other triangles read back")
        err = np.abs(body.vertices - rig.vertices).max()
        for k, t in enumerate(motion.times):
            err = max(err, float(np.abs(body.vertices_at(t) - posed[k]).max()))
        worst[kind] = err
    return worst


def groom_clearance(seed: int, name="straight") -> dict:
    """How the groom of head ``seed`` sits on that head: the largest root distance to the mesh and the
    nearest other point (negative: inside), by the exact closest-point queries hairinv uses."""
    import trimesh

    from hairinv.contacts.body import BodyMesh

    rig = mannequin(seed)
    points, offsets = groom(seed, name)
    bm = BodyMesh.from_mesh(trimesh.Trimesh(rig.vertices, rig.faces, process=False))
    d = bm.closest(np.ascontiguousarray(points))[0]
    roots = np.zeros(len(points), bool)
    roots[offsets[:-1]] = True
    return {"root_distance_max_m": float(np.abs(d[roots]).max()), "min_distance_m": float(d[~roots].min()),
            "inside_points": int(np.sum(d[~roots] < 0))}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("names", nargs="*", help=f"variants (default: all): {', '.join(VARIANTS)}")
    parser.add_argument("-o", "--outdir", type=Path, default=ROOT / "out" / "rigs")
    parser.add_argument("--no-check", action="store_true", help="do not read the files back")
    parser.add_argument("--sample", action="store_true", help="write samples/turn.glb only")
    args = parser.parse_args(argv)
    t0 = time.time()
    if args.sample:
        path = write_sample()
        print(f"{path.relative_to(ROOT)}: {path.stat().st_size / 1024:.0f} KiB ({time.time() - t0:.1f} s)")
        return
    unknown = [n for n in args.names if n not in VARIANTS]
    if unknown:
        parser.error(f"unknown variants {', '.join(unknown)}; known: {', '.join(VARIANTS)}")
    for name in args.names or VARIANTS:
        t1 = time.time()
        info = write_variant(args.outdir, name, check=not args.no_check)
        head = info["head"]
        line = (f"{name} ({info['split']}): {info['motion']}, {info['frames']} frames at {info['fps']:g} fps "
                f"({info['duration_s']:.2f} s), head seed {info['head_seed']}; head peak speed "
                f"{head.get('head_peak_speed_m_s', 0):.2f} m/s, acceleration "
                f"{head.get('head_peak_acceleration_m_s2', 0):.1f} m/s^2")
        if "agreement_m" in info:
            line += "; read back vs posed: " + ", ".join(f"{k} {v:.1e} m" for k, v in info["agreement_m"].items())
        print(line + f" ({time.time() - t1:.1f} s)")
        if info["head_seed"]:
            c = groom_clearance(info["head_seed"])
            print(f"  groom on head {info['head_seed']}: roots within {c['root_distance_max_m'] * 1e3:.3f} mm of the "
                  f"mesh, nearest other point {c['min_distance_m'] * 1e3:.2f} mm, {c['inside_points']} inside")
    print(f"{args.outdir}: done in {time.time() - t0:.1f} s")


if __name__ == "__main__":
    main()
