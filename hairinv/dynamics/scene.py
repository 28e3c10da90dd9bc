"""Scenes: what happens around a simulated groom (docs/scenes.md).

A scene is a small TOML file: whether the body stays still, moves rigidly
through keyframes, or is removed; whether the strands are trimmed, and when;
and the run's default duration and frame rate. Presets live in
``configs/scenes/<name>.toml``.

Conventions
-----------
The body's pose is a rigid transform of the groom's own coordinates (metres,
the axes of the imported file): ``x_world = R @ x_body + c``, where body
coordinates are world coordinates in the pose the groom was captured in.
A keyframe gives yaw, pitch and roll in degrees about the body's axes and a
translation of the pivot in world metres:

    R = Rot(up, yaw) @ Rot(left, pitch) @ Rot(forward, roll),
    c = pivot + translate - R @ pivot,

so yaw turns the head about the up axis first, pitch then nods it about its
own (turned) left axis, roll then tilts it about its own forward axis. The
body axes are right-handed: ``left = up x forward``. Signs, by the right-hand
rule: positive yaw turns the face towards the character's left, positive
pitch tips the face down (a nod, or a lean forward), positive roll lowers the
right ear towards the right shoulder.

``up`` is the groom's up axis (``Groom.up``, ``/curves`` attribute ``up``).
``forward`` is the scene key ``forward`` or, by default ("auto"), +Z made
orthogonal to up (Maya, Houdini and USD characters face +Z in a Y-up scene),
or -Y when up is along Z (Blender characters face -Y).

Between two keys the body eases in and out: the pose follows the key's
relative rotation vector and translation with the cubic Hermite profile
``h(u) = 3u^2 - 2u^3`` (zero velocity at both keys), so velocities are
continuous (C1) and accelerations bounded: the fictitious forces of a
simulation in the body frame are finite. Rotations are interpolated on SO(3)
along the geodesic ``R(t) = R_k Exp(h(u) phi_k)``, ``phi_k = Log(R_k^T R_k+1)``.
Before the first key the body is at the first key; after the last, at the last.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .._jit import jit
from ..config import CONFIG_DIR
from ..errors import InputError
from ..model import Helices

__all__ = [
    "SCENE_DIR",
    "MAX_SECONDS",
    "MAX_FPS",
    "MAX_FRAMES",
    "check_run_length",
    "BODIES",
    "Keyframe",
    "Trim",
    "Scene",
    "BodyMotion",
    "scene_names",
    "trim_helices",
]

SCENE_DIR = CONFIG_DIR / "scenes"
BODIES = ("fixed", "keyframed", "removed")
AXES = {"x": 0, "y": 1, "z": 2}
# Two consecutive keys closer to a half turn than this are ambiguous (which way round?).
MAX_KEY_TURN_DEG = 179.0
# |forward . up| above this: forward is too close to up to define the left axis.
PARALLEL = 0.99
#: s. The longest run a scene or ``--seconds`` may ask for: a day, far beyond a shot, whose frames a groom's
#: memory could not hold anyway (the frame count is bounded by RUN_FRAMES below).
MAX_SECONDS = 86400.0
#: Frames per second, at most: a high-speed camera's rate; beyond it a frame is shorter than any step.
MAX_FPS = 1e5
#: Frames in one run, at most (10 minutes at 30 fps is 18,000): /frames is allocated whole before the
#: first step, so a slip of the exponent in seconds or fps would ask for terabytes.
MAX_FRAMES = 10**6


def scene_names() -> list[str]:
    """Names of the scene presets in ``configs/scenes/``."""
    return sorted(p.stem for p in SCENE_DIR.glob("*.toml"))


@dataclass(frozen=True)
class Keyframe:
    """A pose of the body at one time."""

    time: float
    """s. When the body is in this pose."""
    yaw: float = 0.0
    """Degrees about the body's up axis; positive turns the face to the character's left."""
    pitch: float = 0.0
    """Degrees about the body's (yawed) left axis; positive tips the face down."""
    roll: float = 0.0
    """Degrees about the body's (yawed, pitched) forward axis; positive lowers the right ear."""
    translate: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """m, world axes. Displacement of the pivot from where it was captured."""


@dataclass(frozen=True)
class Trim:
    """Cut every strand at one arc length, once."""

    length: float | None = None
    """m. Arc length from the root at which every strand is cut; strands shorter than this are kept whole."""
    fraction: float | None = None
    """In (0, 1]: cut each strand at this fraction of its own length. Exactly one of length and fraction."""
    time: float = 0.0
    """s. When the cut happens; 0 cuts before the first step."""


class BodyMotion(NamedTuple):
    """Rigid pose of the body at one time and its derivatives, all in world axes.

    ``x_world = R @ x_body + c``. A body point's velocity is
    ``omega x (R x_body) + velocity``, its acceleration
    ``alpha x r + omega x (omega x r) + acceleration`` with ``r = R x_body``.
    """

    R: np.ndarray
    """(3, 3) float64, rotation body -> world."""
    c: np.ndarray
    """(3,) float64, m, world position of the body-frame origin."""
    omega: np.ndarray
    """(3,) float64, rad/s, angular velocity."""
    alpha: np.ndarray
    """(3,) float64, rad/s^2, angular acceleration d(omega)/dt."""
    velocity: np.ndarray
    """(3,) float64, m/s, dc/dt."""
    acceleration: np.ndarray
    """(3,) float64, m/s^2, d^2c/dt^2."""

    def points(self, x_body: np.ndarray) -> np.ndarray:
        """World positions of body points ``x_body`` (n, 3), m."""
        return np.asarray(x_body, np.float64) @ self.R.T + self.c

    def point_velocities(self, x_body: np.ndarray) -> np.ndarray:
        """World velocities (n, 3), m/s, of body points ``x_body`` (n, 3), m."""
        r = np.asarray(x_body, np.float64) @ self.R.T
        return np.cross(self.omega, r) + self.velocity

    def point_accelerations(self, x_body: np.ndarray) -> np.ndarray:
        """World accelerations (n, 3), m/s^2, of body points ``x_body`` (n, 3), m."""
        r = np.asarray(x_body, np.float64) @ self.R.T
        return np.cross(self.alpha, r) + np.cross(self.omega, np.cross(self.omega, r)) + self.acceleration


@dataclass(frozen=True)
class Scene:
    """What happens around a simulated groom: body motion, trimming, run length.

    Load one with :meth:`Scene.load`; the file format is in docs/scenes.md.
    """

    description: str = ""
    """Free text for the user, shown when the scene is loaded."""
    body: str = "fixed"
    """fixed (still), keyframed (moves rigidly through ``keyframes``) or removed (no hair-body contacts;
    the roots stay clamped where they are)."""
    keyframes: tuple[Keyframe, ...] = ()
    """Poses of a keyframed body, strictly increasing in time."""
    pivot: tuple[float, float, float] | None = None
    """m, world. Point the keyframe rotations turn about; None: the centre of the hair roots."""
    forward: str = "auto"
    """The body's forward axis, +x, -x, +y, -y, +z, -z, or auto (+Z, or -Y for a Z-up groom)."""
    trim: Trim | None = None
    """Cut the strands once during the run; None: no cut."""
    seconds: float = 2.0
    """s. Default simulated duration, > 0 and at most MAX_SECONDS; 2 s lets a released groom settle."""
    fps: float = 30.0
    """1/s. Frames written per simulated second by default (the usual animation rate); at most MAX_FPS, and
    ``seconds * fps`` at most MAX_FRAMES."""
    source: str | None = None
    """The file the scene was read from, for messages."""

    def __post_init__(self):
        _check_scene(self)

    # ----------------------------------------------------------------- loading

    @classmethod
    def load(cls, path_or_name) -> "Scene":
        """A scene from a preset name (``configs/scenes/NAME.toml``) or a TOML file.

        A ``Path``, or a string that ends in ``.toml`` or holds a path separator,
        is a file; any other string is a preset name.

        Raises
        ------
        InputError
            For a missing file or preset, invalid TOML, an unknown key, a value of the
            wrong type or out of range, or keyframes that are not strictly increasing
            in time; the message names the file.
        """
        path = _scene_path(path_or_name)
        try:
            with open(path, "rb") as fh:
                raw = tomllib.load(fh)
        except FileNotFoundError:
            raise InputError("no such scene file", path) from None
        except tomllib.TOMLDecodeError as exc:
            raise InputError(f"is not valid TOML ({exc})", path) from None
        except UnicodeDecodeError as exc:
            raise InputError(f"is not a TOML text file: byte {exc.start} is not UTF-8", path) from None
        except IsADirectoryError:
            raise InputError("is a folder, not a scene file", path) from None
        except OSError as exc:
            raise InputError(f"cannot be read ({exc.strerror})", path) from None
        return _scene_from_dict(raw, str(path))

    # ---------------------------------------------------------------- queries

    @property
    def name(self) -> str:
        """The preset name or file stem the scene was read from ("" when built in code)."""
        return Path(self.source).stem if self.source else ""

    @property
    def body_contacts(self) -> bool:
        """Whether hair-body contacts exist in this scene (false when the body is removed)."""
        return self.body != "removed"

    @property
    def moving(self) -> bool:
        """Whether the body can move (keyframed, with more than one key)."""
        return self.body == "keyframed" and len(self.keyframes) > 1

    def pivot_point(self, roots: np.ndarray) -> np.ndarray:
        """The rotation pivot (3,), m: the scene's ``pivot`` or else the mean of ``roots`` (S, 3), m."""
        if self.pivot is not None:
            return np.array(self.pivot, np.float64)
        roots = np.asarray(roots, np.float64).reshape(-1, 3)
        if len(roots) == 0:
            raise InputError("the scene has no pivot and the groom has no roots to centre it on", self.source)
        return roots.mean(axis=0)

    def body_axes(self, up) -> np.ndarray:
        """(3, 3) float64 whose columns are the body's forward, left and up axes in world coordinates.

        Parameters
        ----------
        up : (3,) float64, the groom's up axis (any length > 0)
        """
        u = np.asarray(up, np.float64).reshape(3)
        norm = np.linalg.norm(u)
        if not norm > 0:
            raise InputError(f"the up axis {tuple(u)} has no length", self.source)
        u = u / norm
        if self.forward == "auto":
            f = np.array([0.0, 0.0, 1.0]) if abs(u[2]) < PARALLEL else np.array([0.0, -1.0, 0.0])
        else:
            f = np.zeros(3)
            f[AXES[self.forward[-1]]] = -1.0 if self.forward[0] == "-" else 1.0
            if abs(f @ u) > PARALLEL:
                raise InputError(f"forward axis {self.forward} is along the groom's up axis; choose another",
                                 self.source)
        f = f - (f @ u) * u
        f /= np.linalg.norm(f)
        return np.column_stack([f, np.cross(u, f), u])

    def body_motion(self, t: float, pivot, up) -> BodyMotion:
        """Rigid pose of the body at time ``t`` and its exact time derivatives.

        Parameters
        ----------
        t : float, s
        pivot : (3,) float64, m, world
            Point the rotations turn about; use :meth:`pivot_point` for the scene's choice.
        up : (3,) float64
            The groom's up axis (defines yaw, pitch and roll with ``forward``).

        Returns
        -------
        BodyMotion
            ``R, c, omega, alpha, velocity, acceleration`` (world axes; m, s, rad).
            Identity and zeros unless the body is keyframed. Pose and velocities are
            continuous; accelerations jump at keys, where their limit from the right
            (the motion about to happen) is returned. Constant before the first key
            and from the last key on.
        """
        p = np.asarray(pivot, np.float64).reshape(3)
        zero = np.zeros(3)
        if self.body != "keyframed" or not self.keyframes:
            return BodyMotion(np.eye(3), zero, zero.copy(), zero.copy(), zero.copy(), zero.copy())
        B = self.body_axes(up)
        keys = self.keyframes
        t = float(t)
        if not keys[0].time <= t < keys[-1].time:  # at rest: in the first pose before it, the last from it on
            key = keys[0] if t < keys[0].time else keys[-1]
            R = B @ _key_rotation(key) @ B.T
            c = p + np.array(key.translate, np.float64) - R @ p
            return BodyMotion(R, c, zero, zero.copy(), zero.copy(), zero.copy())
        times = np.array([key.time for key in keys])
        k = int(np.searchsorted(times, t, side="right")) - 1
        a, b = keys[k], keys[k + 1]
        duration = b.time - a.time
        u = (t - a.time) / duration  # in [0, 1): at a key, accelerations are their limits from the right
        h = u * u * (3.0 - 2.0 * u)
        h_t = 6.0 * u * (1.0 - u) / duration
        h_tt = (6.0 - 12.0 * u) / (duration * duration)
        Ra = _key_rotation(a)
        phi = _log(Ra.T @ _key_rotation(b))  # relative rotation in the body axes of key k (canonical)
        dT = np.subtract(b.translate, a.translate)
        R = B @ (Ra @ _exp(h * phi)) @ B.T
        axis = B @ (Ra @ phi)  # world direction of the turn: omega = h' R_k phi, as Exp(h phi) phi = phi
        omega = h_t * axis
        alpha = h_tt * axis
        r = R @ p
        c = p + np.array(a.translate, np.float64) + h * dT - r
        velocity = h_t * dT - np.cross(omega, r)
        acceleration = h_tt * dT - np.cross(alpha, r) - np.cross(omega, np.cross(omega, r))
        return BodyMotion(R, c, omega, alpha, velocity, acceleration)

    def transform_matrix(self, t: float, pivot, up) -> np.ndarray:
        """(4, 4) float64 homogeneous body -> world transform at time ``t`` (see :meth:`body_motion`)."""
        motion = self.body_motion(t, pivot, up)
        out = np.eye(4)
        out[:3, :3] = motion.R
        out[:3, 3] = motion.c
        return out


# --------------------------------------------------------------------- SO(3)


def _hat(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _exp(phi: np.ndarray) -> np.ndarray:
    """Rotation matrix of the rotation vector ``phi`` (Rodrigues)."""
    y = float(phi @ phi)
    if y < 1e-8:  # series of sin x / x and (1 - cos x) / x^2; next terms below 1e-18
        A = 1.0 - y / 6.0 + y * y / 120.0
        B = 0.5 - y / 24.0 + y * y / 720.0
    else:
        x = math.sqrt(y)
        A = math.sin(x) / x
        B = 2.0 * math.sin(0.5 * x) ** 2 / y
    K = _hat(phi)
    return np.eye(3) + A * K + B * (K @ K)


def _log(R: np.ndarray) -> np.ndarray:
    """Rotation vector of ``R`` for angles below pi (keys are checked to stay below MAX_KEY_TURN_DEG)."""
    w = 0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])  # sin(x) axis
    s = float(np.linalg.norm(w))
    x = math.atan2(s, 0.5 * (np.trace(R) - 1.0))
    if s < 1e-12:
        return w
    return w * (x / s)


def _rotation(axis: int, degrees: float) -> np.ndarray:
    x = math.radians(degrees)
    c, s = math.cos(x), math.sin(x)
    i, j = (axis + 1) % 3, (axis + 2) % 3
    R = np.eye(3)
    R[i, i] = c
    R[j, j] = c
    R[j, i] = s
    R[i, j] = -s
    return R


def _key_rotation(key: Keyframe) -> np.ndarray:
    """Rotation of a key in canonical body axes (x forward, y left, z up)."""
    return _rotation(2, key.yaw) @ _rotation(1, key.pitch) @ _rotation(0, key.roll)


# ------------------------------------------------------------------- loading


def _scene_path(path_or_name) -> Path:
    if isinstance(path_or_name, Path):
        return path_or_name
    text = str(path_or_name)
    if text.endswith(".toml") or "/" in text or "\\" in text:
        return Path(text)
    preset = SCENE_DIR / f"{text}.toml"
    if not preset.exists():
        raise InputError(f"unknown scene {text!r}: not a .toml file and not a preset "
                         f"(presets: {', '.join(scene_names())})")
    return preset


_TOP_KEYS = ("description", "body", "seconds", "fps", "pivot", "forward", "keyframe", "trim")
_KEY_KEYS = ("time", "yaw", "pitch", "roll", "translate")
_TRIM_KEYS = ("length", "fraction", "time")


def _reject_unknown(table: dict, known, where: str, source: str) -> None:
    for key in table:
        if key not in known:
            raise InputError(f"unknown key {where}{key}; known: {', '.join(known)}", source)


def _number(value, where: str, source: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"{where} expects a number, got {value!r}", source)
    if not math.isfinite(value):
        raise InputError(f"{where} must be finite, got {value!r}", source)
    return float(value)


def _vector(value, where: str, source: str) -> tuple[float, float, float]:
    if not isinstance(value, list) or len(value) != 3:
        raise InputError(f"{where} expects three numbers [x, y, z] in metres, got {value!r}", source)
    return tuple(_number(v, f"{where}[{i}]", source) for i, v in enumerate(value))


def _string(value, where: str, source: str) -> str:
    if not isinstance(value, str):
        raise InputError(f"{where} expects a string, got {value!r}", source)
    return value


def _scene_from_dict(raw: dict, source: str) -> Scene:
    _reject_unknown(raw, _TOP_KEYS, "", source)
    kwargs: dict = {"source": source}
    if "description" in raw:
        kwargs["description"] = _string(raw["description"], "description", source)
    if "body" in raw:
        kwargs["body"] = _string(raw["body"], "body", source)
    for name in ("seconds", "fps"):
        if name in raw:
            kwargs[name] = _number(raw[name], name, source)
    if "pivot" in raw:
        value = raw["pivot"]
        if value != "roots":
            kwargs["pivot"] = _vector(value, "pivot (\"roots\" or [x, y, z])", source)
    if "forward" in raw:
        kwargs["forward"] = _string(raw["forward"], "forward", source)
    if "keyframe" in raw:
        tables = raw["keyframe"]
        if not isinstance(tables, list) or not all(isinstance(k, dict) for k in tables):
            raise InputError("keyframe must be a list of [[keyframe]] tables", source)
        keys = []
        for i, table in enumerate(tables):
            where = f"keyframe {i + 1}"
            _reject_unknown(table, _KEY_KEYS, f"in {where}: ", source)
            if "time" not in table:
                raise InputError(f"{where} has no time", source)
            values = {name: _number(table[name], f"{where} {name}", source)
                      for name in ("time", "yaw", "pitch", "roll") if name in table}
            if "translate" in table:
                values["translate"] = _vector(table["translate"], f"{where} translate", source)
            keys.append(Keyframe(**values))
        kwargs["keyframes"] = tuple(keys)
    if "trim" in raw:
        table = raw["trim"]
        if not isinstance(table, dict):
            raise InputError("trim must be a [trim] table", source)
        _reject_unknown(table, _TRIM_KEYS, "trim.", source)
        kwargs["trim"] = Trim(**{name: _number(table[name], f"trim.{name}", source)
                                 for name in _TRIM_KEYS if name in table})
    return Scene(**kwargs)


def check_run_length(seconds: float, fps: float, source: str | None = None, seconds_name: str = "seconds",
                     fps_name: str = "fps") -> None:
    """Refuse a duration (s) or frame rate (1/s) that is not a finite number > 0 within MAX_SECONDS and
    MAX_FPS, or whose frames (``seconds * fps``) exceed MAX_FRAMES, before anything is allocated for them.
    ``source`` is the file they come from (None: the command line); the names are the keys or options."""
    try:
        seconds, fps = float(seconds), float(fps)
    except (TypeError, ValueError):
        raise InputError(f"{seconds_name} and {fps_name} must be numbers, got {seconds!r} and {fps!r}",
                         source) from None
    if not (math.isfinite(seconds) and 0 < seconds <= MAX_SECONDS):
        raise InputError(f"{seconds_name} must be a duration > 0 s and at most {MAX_SECONDS:g} s, got {seconds!r}",
                         source)
    if not (math.isfinite(fps) and 0 < fps <= MAX_FPS):
        raise InputError(f"{fps_name} must be > 0 and at most {MAX_FPS:g} frames per second, got {fps!r}", source)
    if seconds * fps > MAX_FRAMES:
        raise InputError(f"{seconds_name} {seconds:g} s at {fps_name} {fps:g} makes {seconds * fps:.3g} frames; "
                         f"at most {MAX_FRAMES:,} fit in one run (lower {fps_name} or {seconds_name})", source)


def _check_scene(scene: Scene) -> None:
    """Ranges and consistency; called on every Scene, loaded or built in code."""
    source = scene.source
    if scene.body not in BODIES:
        raise InputError(f"body must be one of {', '.join(BODIES)}, got {scene.body!r}", source)
    check_run_length(scene.seconds, scene.fps, source)
    allowed = ["auto"] + [f"{sign}{axis}" for axis in AXES for sign in ("+", "-", "")]
    if scene.forward not in allowed:
        raise InputError(f"forward must be auto or an axis such as +z or -y, got {scene.forward!r}", source)
    keys = scene.keyframes
    if scene.body == "keyframed" and not keys:
        raise InputError("body is keyframed but there is no [[keyframe]]", source)
    if scene.body != "keyframed" and keys:
        raise InputError(f"[[keyframe]] tables are given but body is {scene.body!r}; set body = \"keyframed\"",
                         source)
    for i, key in enumerate(keys):
        if not key.time >= 0:
            raise InputError(f"keyframe {i + 1} has time {key.time} s; times must be >= 0", source)
    for i in range(1, len(keys)):
        a, b = keys[i - 1], keys[i]
        if not b.time > a.time:
            raise InputError(f"keyframe times must increase strictly, but keyframe {i + 1} is at {b.time} s "
                             f"after keyframe {i} at {a.time} s", source)
        turn = math.degrees(np.linalg.norm(_log(_key_rotation(a).T @ _key_rotation(b))))
        steps = max(abs(b.yaw - a.yaw), abs(b.pitch - a.pitch), abs(b.roll - a.roll))
        if steps >= 180.0 or turn >= MAX_KEY_TURN_DEG:
            raise InputError(f"keyframes {i} and {i + 1} differ by half a turn or more, so the way round is "
                             "ambiguous; add a key between them", source)
    trim = scene.trim
    if trim is not None:
        if (trim.length is None) == (trim.fraction is None):
            raise InputError("[trim] needs exactly one of length (m) and fraction (0 to 1)", source)
        if trim.length is not None and not trim.length > 0:
            raise InputError(f"trim.length must be > 0 m, got {trim.length}", source)
        if trim.fraction is not None and not 0.0 < trim.fraction <= 1.0:
            raise InputError(f"trim.fraction must be in (0, 1], got {trim.fraction}", source)
        if not trim.time >= 0:
            raise InputError(f"trim.time must be >= 0 s, got {trim.time}", source)


# ---------------------------------------------------------------------- trim


@jit
def _trim_plan(offsets, length, cut, fraction, new_length, keep):
    """Per element: kept (1) or dropped (0), and its length after the cut.

    Each strand is cut at arc length ``cut`` (m) or, when ``fraction > 0``,
    at ``fraction`` times its own length. An element starting at or beyond
    the cut is dropped; the one containing it ends at the cut.
    """
    for strand in range(offsets.shape[0] - 1):
        a, z = offsets[strand], offsets[strand + 1]
        total = 0.0
        for e in range(a, z):
            total += length[e]
        limit = fraction * total if fraction > 0.0 else cut
        s = 0.0
        for e in range(a, z):
            if limit >= total:
                keep[e] = 1
                new_length[e] = length[e]
            elif s >= limit:
                keep[e] = 0
                new_length[e] = 0.0
            else:
                keep[e] = 1
                new_length[e] = min(length[e], limit - s)
            s += length[e]
    return 0


def trim_helices(helices: Helices, length: float | None = None,
                 fraction: float | None = None) -> tuple[Helices, np.ndarray]:
    """Cut every strand at arc length ``length`` or at ``fraction`` of its own length.

    Elements wholly beyond the cut are removed; the element containing it keeps its
    curvature and twist ``omega`` and is shortened, so the cut strand is exactly the
    first part of the original curve. Strands no longer than the cut are unchanged.

    Parameters
    ----------
    helices : Helices
    length : float, m, > 0, optional
    fraction : float in (0, 1], optional
        Exactly one of ``length`` and ``fraction``.

    Returns
    -------
    Helices
        Same roots, frames and fit errors; new offsets, lengths and omegas.
    element_map : (E_new,) int64
        Old element index of each new element (to carry per-element arrays along:
        ``omega_rest[element_map]``).
    """
    if (length is None) == (fraction is None):
        raise InputError("trim needs exactly one of length (m) and fraction (0 to 1)")
    if length is not None and not length > 0:
        raise InputError(f"trim length must be > 0 m, got {length}")
    if fraction is not None and not 0.0 < fraction <= 1.0:
        raise InputError(f"trim fraction must be in (0, 1], got {fraction}")
    offsets = np.ascontiguousarray(helices.offsets, np.int64)
    old_length = np.ascontiguousarray(helices.length, np.float64)
    new_length = np.empty_like(old_length)
    keep = np.empty(len(old_length), np.int64)
    _trim_plan(offsets, old_length, float(length or 0.0), float(fraction or 0.0), new_length, keep)
    element_map = np.flatnonzero(keep).astype(np.int64)
    kept_before = np.concatenate([[0], np.cumsum(keep)]).astype(np.int64)  # kept elements before each index
    new_offsets = np.ascontiguousarray(kept_before[offsets])
    trimmed = Helices(
        np.array(helices.root, np.float64),
        np.array(helices.frame0, np.float64),
        new_offsets,
        np.ascontiguousarray(new_length[element_map]),
        np.ascontiguousarray(np.asarray(helices.omega, np.float64)[element_map]),
        np.array(helices.fit_error, np.float64),
    )
    return trimmed, element_map
