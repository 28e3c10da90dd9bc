"""Roots bound to a deforming body, and what the body does over one time step.

A root is bound to the triangle it sits on (:class:`Binding`): the barycentric coordinates of its closest
point on the triangle, and the root's offset from that point in the triangle's own frame (first edge,
normal x edge, normal). As the skin moves, the triangle's frame carries the root and its frame: strand
``k`` is placed by a rigid motion of its own, ``x = R_k x_bind + c_k``, with

    R_k(t) = T_k(t) T_k(bind)^T,    c_k(t) = p_k(t) - R_k(t) p_k(bind),

``T_k`` the triangle's frame and ``p_k`` the barycentric point. A skin that moves rigidly gives every
root the same ``(R, c)``: the body frame of a rigid scene (:mod:`hairinv.dynamics.scene`).

The dynamics keeps each strand's coordinates in its bind pose (its root and root frame never change
there); :class:`SkinStep` gives a step the strands' own frames at its end, their fictitious forces
(:class:`hairinv.dynamics.simulate.Motion` per strand, from differences of the frames over the step),
the body at the step's end, and the velocities of the frames and of the skin that contacts need.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..contacts.body import BodyMesh
from ..errors import InputError

__all__ = ["Binding", "PREROLL", "Shot", "SkinnedBody", "SkinStep", "triangle_frames", "rotation_log"]


def triangle_frames(vertices: np.ndarray, faces: np.ndarray, triangle: np.ndarray,
                    barycentric: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The barycentric points ``p`` (n, 3) and the frames ``T`` (n, 3, 3) of the triangles ``triangle`` (n,):
    columns the unit first edge ``b - a``, ``normal x edge`` and the unit normal ``(b - a) x (c - a)``."""
    corners = vertices[faces[triangle]]  # (n, 3 corners, 3)
    p = np.einsum("nk,nki->ni", barycentric, corners)
    edge = corners[:, 1] - corners[:, 0]
    normal = np.cross(edge, corners[:, 2] - corners[:, 0])
    edge = edge / np.linalg.norm(edge, axis=1, keepdims=True)
    normal = normal / np.linalg.norm(normal, axis=1, keepdims=True)
    T = np.stack([edge, np.cross(normal, edge), normal], axis=2)
    return p, T


def rotation_log(R: np.ndarray) -> np.ndarray:
    """The rotation vectors (n, 3) of rotations ``R`` (n, 3, 3): ``R = exp(hat(phi))``, ``|phi| <= pi``."""
    R = np.asarray(R, dtype=np.float64).reshape(-1, 3, 3)
    cos = np.clip(0.5 * (np.trace(R, axis1=1, axis2=2) - 1.0), -1.0, 1.0)
    angle = np.arccos(cos)
    axis = np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]], axis=1)
    sin = np.sin(angle)
    out = np.empty((len(R), 3))
    small = angle < 1e-4
    # small turns: phi = vee(R - R^T) / 2 (1 + angle^2 / 6), exact to round-off
    out[small] = 0.5 * axis[small] * (1.0 + angle[small, None] ** 2 / 6.0)
    mid = ~small & (angle < np.pi - 1e-6)
    out[mid] = axis[mid] * (angle[mid] / (2.0 * sin[mid]))[:, None]
    for i in np.flatnonzero(~small & ~mid):  # a half turn: the axis from R + I
        B = 0.5 * (R[i] + np.eye(3))
        j = int(np.argmax(np.diag(B)))
        v = B[:, j] / np.sqrt(max(B[j, j], 1e-300))
        out[i] = angle[i] * v / np.linalg.norm(v)
    return out


@dataclass(frozen=True)
class Binding:
    """Each root bound to a triangle of the body in its bind pose.

    Attributes
    ----------
    triangle : (S,) int64, the face each root is bound to (an index into the body's faces)
    barycentric : (S, 3) float64, its closest point on that face
    offset : (S, 3) float64, m, the root from that point, in the triangle's frame at bind time
    distance : (S,) float64, m, the root's signed distance to the body at bind time
    bind_point : (S, 3) float64, m, the barycentric points at bind time
    bind_frame : (S, 3, 3) float64, the triangles' frames at bind time (columns)
    """

    triangle: np.ndarray
    barycentric: np.ndarray
    offset: np.ndarray
    distance: np.ndarray
    bind_point: np.ndarray
    bind_frame: np.ndarray

    @classmethod
    def bind(cls, roots: np.ndarray, vertices: np.ndarray, faces: np.ndarray,
             body: BodyMesh | None = None) -> "Binding":
        """Bind ``roots`` (S, 3) to the closest triangles of the mesh ``vertices`` (V, 3), ``faces`` (F, 3)."""
        roots = np.ascontiguousarray(roots, dtype=np.float64).reshape(-1, 3)
        vertices = np.ascontiguousarray(vertices, dtype=np.float64)
        faces = np.ascontiguousarray(faces, dtype=np.int64)
        if body is None:
            body = BodyMesh.from_mesh(MeshArrays(vertices, faces))
        sd, closest, _, face = body.closest(roots) if len(roots) else (np.zeros(0), np.zeros((0, 3)), None,
                                                                          np.zeros(0, dtype=np.int64))
        bary = barycentric(closest, vertices[faces[face]])
        p, T = triangle_frames(vertices, faces, face, bary)
        offset = np.einsum("nji,nj->ni", T, roots - p)
        return cls(face.astype(np.int64), bary, offset, sd, p, T)

    @property
    def n_roots(self) -> int:
        return int(len(self.triangle))

    def frames(self, vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each strand's rigid motion from the bind pose on the mesh ``vertices``: ``R`` (S, 3, 3), ``c`` (S, 3)
        with ``x = R x_bind + c``."""
        p, T = triangle_frames(vertices, faces, self.triangle, self.barycentric)
        R = np.einsum("nij,nkj->nik", T, self.bind_frame)
        c = p - np.einsum("nij,nj->ni", R, self.bind_point)
        return R, c

    def roots(self, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
        """(S, 3) m, the bound roots on the mesh ``vertices``."""
        p, T = triangle_frames(vertices, faces, self.triangle, self.barycentric)
        return p + np.einsum("nij,nj->ni", T, self.offset)

    def arrays(self) -> dict:
        """The datasets of the ``/binding`` group (docs/stage-files.md)."""
        return {"triangle": self.triangle, "barycentric": self.barycentric, "offset": self.offset,
                "distance": self.distance}


def barycentric(points: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """(n, 3) barycentric coordinates of ``points`` (n, 3) in the triangles ``corners`` (n, 3, 3) (of their
    projections on the triangles' planes)."""
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    v0, v1, v2 = b - a, c - a, points - a
    d00 = np.einsum("ij,ij->i", v0, v0)
    d01 = np.einsum("ij,ij->i", v0, v1)
    d11 = np.einsum("ij,ij->i", v1, v1)
    d20 = np.einsum("ij,ij->i", v2, v0)
    d21 = np.einsum("ij,ij->i", v2, v1)
    det = d00 * d11 - d01 * d01
    v = (d11 * d20 - d01 * d21) / det
    w = (d00 * d21 - d01 * d20) / det
    return np.stack([1.0 - v - w, v, w], axis=1)


class MeshArrays:
    """Vertices and faces, as :meth:`BodyMesh.from_mesh` takes them."""

    def __init__(self, vertices, faces):
        self.vertices = vertices
        self.faces = faces


@dataclass
class SkinStep:
    """What a deforming body does over one step ``[t, t + h]``, in the groom's frame.

    Attributes
    ----------
    motion : (S, 5, 3) float64, each strand's :meth:`Motion.packed` at ``t``, in its bind-pose coordinates
    R, c : (S, 3, 3), (S, 3) the strands' frames at ``t + h`` (``x = R x_bind + c``)
    R_start, c_start : the same at ``t``
    body : BodyMesh or None, the body at ``t``
    vertices, vertices_start : (V, 3) the body's vertices at ``t + h`` and at ``t``
    faces : (F, 3) int64
    moves : bool, whether anything moved over the step (the skin, or any frame)
    h : float, s
    """

    motion: np.ndarray
    R: np.ndarray
    c: np.ndarray
    R_start: np.ndarray
    c_start: np.ndarray
    body: BodyMesh | None
    vertices: np.ndarray
    vertices_start: np.ndarray
    faces: np.ndarray
    moves: bool
    h: float

    def frame_velocity(self, strand: np.ndarray, x: np.ndarray) -> np.ndarray:
        """(n, 3) m/s: how fast strand ``strand``'s frame carries the point at ``x`` (at the step's start)
        over the step: ``(x_end - x) / h``, ``x_end`` where that frame holds the same point at its end."""
        local = np.einsum("nji,nj->ni", self.R_start[strand], x - self.c_start[strand])
        end = np.einsum("nij,nj->ni", self.R[strand], local) + self.c[strand]
        return (end - x) / self.h

    def skin_velocity(self, face: np.ndarray, x: np.ndarray) -> np.ndarray:
        """(n, 3) m/s: how fast the skin near ``x`` (at the step's start) moves over the step, the faces
        ``face`` carrying ``x`` rigidly in their own frames (a rigid body: its velocity at ``x``)."""
        third = np.full((len(face), 3), 1.0 / 3.0)
        p1, T1 = triangle_frames(self.vertices, self.faces, face, third)
        p0, T0 = triangle_frames(self.vertices_start, self.faces, face, third)
        local = np.einsum("nji,nj->ni", T0, x - p0)
        end = np.einsum("nij,nj->ni", T1, local) + p1
        return (end - x) / self.h

    def margins(self, root: np.ndarray, tip: np.ndarray) -> tuple[float, float]:
        """m: how much closer than at the step's start a strand may come to the body, and two strands to each
        other, within the step as their frames and the skin move (bounds, the strands taken as rigid in their
        frames; ``root``, ``tip`` (S, 3) their ends in the bind pose). Motion shared by all (the roots'
        median displacement) does not count."""
        if not self.moves or not len(root):
            return 0.0, 0.0

        def carried(x, R, c):
            return np.einsum("nij,nj->ni", R, x) + c

        d_root = carried(root, self.R, self.c) - carried(root, self.R_start, self.c_start)
        d_tip = carried(tip, self.R, self.c) - carried(tip, self.R_start, self.c_start)
        shared = np.median(d_root, axis=0)
        sweep = float(max(np.linalg.norm(d_root - shared, axis=1).max(), np.linalg.norm(d_tip - shared, axis=1).max()))
        skin = float(np.linalg.norm(self.vertices - self.vertices_start - shared, axis=1).max())
        return skin + sweep, 2.0 * sweep


class SkinnedBody:
    """An animated body in the groom's frame, metres, with the roots bound to it.

    Parameters
    ----------
    vertices_at : callable(t) -> (V, 3), the body at animation time ``t`` (s), in the groom's frame
    faces : (F, 3) int64
    binding : Binding
    gravity : (3,) m/s^2, in the groom's frame
    contacts : bool, whether steps carry the body for contacts (False: the body only moves the roots)
    """

    def __init__(self, vertices_at, faces: np.ndarray, binding: Binding, gravity: np.ndarray,
                 contacts: bool = True):
        self.vertices_at = vertices_at
        self.faces = np.ascontiguousarray(faces, dtype=np.int64)
        self.binding = binding
        self.gravity = np.asarray(gravity, dtype=np.float64)
        self.contacts = contacts
        self._cache: dict[float, tuple] = {}
        self._bodies: dict[float, BodyMesh] = {}
        self._prepared: BodyMesh | None = None

    def pose(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(vertices, R, c)`` at time ``t``: the mesh and the strands' frames."""
        t = float(t)
        hit = self._cache.get(t)
        if hit is None:
            vertices = np.ascontiguousarray(self.vertices_at(t), dtype=np.float64)
            if not np.isfinite(vertices).all():
                raise InputError(f"the body's vertices at t = {t:.4g} s are not all finite")
            R, c = self.binding.frames(vertices, self.faces)
            hit = (vertices, R, c)
            if len(self._cache) > 8:
                self._cache.clear()
            self._cache[t] = hit
        return hit

    def step(self, t: float, h: float) -> SkinStep:
        """The body over ``[t, t + h]``: frames from differences over ``t - h, t, t + h``."""
        v0, R0, c0 = self.pose(t - h)
        v1, R1, c1 = self.pose(t)
        v2, R2, c2 = self.pose(t + h)
        forward = rotation_log(np.einsum("nij,nkj->nik", R2, R1)) / h  # world, over [t, t + h]
        backward = rotation_log(np.einsum("nij,nkj->nik", R1, R0)) / h
        spin = 0.5 * (forward + backward)
        spin_rate = (forward - backward) / h
        velocity = (c2 - c0) / (2.0 * h)
        accel = (c2 - 2.0 * c1 + c0) / (h * h)
        S = len(c1)
        motion = np.empty((S, 5, 3))
        # in each strand's bind-pose coordinates: R^T of the world vectors
        for i, vec in enumerate((np.broadcast_to(self.gravity, (S, 3)), accel, velocity, spin, spin_rate)):
            motion[:, i] = np.einsum("nji,nj->ni", R1, vec)
        moves = not (np.array_equal(v1, v2) and np.array_equal(R1, R2) and np.array_equal(c1, c2))
        body = self.body_at(t) if self.contacts else None
        return SkinStep(motion, R2, c2, R1, c1, body, v2, v1, self.faces, moves, h)

    def body_at(self, t: float) -> BodyMesh:
        """The body at time ``t``, prepared for contact queries (the last few kept): prepared once, then
        moved to each pose (:meth:`BodyMesh.moved`: the same triangles, their tree refitted)."""
        t = float(t)
        hit = self._bodies.get(t)
        if hit is None:
            if len(self._bodies) > 2:
                self._bodies.clear()
            vertices = self.pose(t)[0]
            if self._prepared is None:
                self._prepared = BodyMesh.from_mesh(MeshArrays(vertices, self.faces))
                hit = self._prepared
            else:
                hit = self._prepared.moved(vertices)
            self._bodies[t] = hit
        return hit


#: s, the pre-roll when the groom's pose is not the shot's first (docs/shots.md)
PREROLL = 0.5
#: m: roots farther than this from every triangle of the body are named (they follow their nearest one)
ROOT_REACH = 5e-3


@dataclass(frozen=True, eq=False)
class Shot:
    """An animated body driving a simulation, in the groom's frame and metres.

    Shot time 0 is the animation's first frame. Before it, over the pre-roll, the body moves from the pose
    the groom was made on (``bind``: the file's rest pose, a skinned mesh's bind pose) to that first frame,
    each vertex along a smoothstep in time, so that the hair is carried there rather than jerked.

    A first frame that is the groom's pose to round-off (a skinned mesh's bind pose, skinned in float32: some
    1e-8 m off the rest pose) is taken as that pose exactly: every frame is the rest pose plus its motion from the
    first frame, so that the contacts the groom was inverted with keep their gaps and a held pose stays still.

    Attributes
    ----------
    body : AnimatedBody, already in the groom's frame (:meth:`AnimatedBody.transformed`)
    preroll : float, s
    first : (V, 3) or None, the animation's first frame where it is the rest pose to round-off, else None
    """

    body: object
    preroll: float
    first: np.ndarray | None = field(default=None, init=False, repr=False)

    def __post_init__(self):
        if not Shot.needs_preroll(self.body):
            object.__setattr__(self, "first", self.body.vertices_at(self.body.start))

    @property
    def bind(self) -> np.ndarray:
        return self.body.vertices

    @property
    def faces(self) -> np.ndarray:
        return self.body.faces

    @property
    def length(self) -> float:
        """s, the animation's length."""
        return float(self.body.end - self.body.start)

    def vertices_at(self, t: float) -> np.ndarray:
        """(V, 3) m, the body at shot time ``t`` (negative: within the pre-roll)."""
        body = self.body
        if t >= 0.0 or self.preroll <= 0.0:
            out = body.vertices_at(body.start + max(t, 0.0))
            # (out - first) + rest: the rest pose itself, to the bit, where the animation holds its first frame
            return out if self.first is None else (out - self.first) + body.vertices
        first = self.vertices_at(0.0)
        u = min(max((t + self.preroll) / self.preroll, 0.0), 1.0)
        w = u * u * (3.0 - 2.0 * u)
        return (1.0 - w) * body.vertices + w * first

    @staticmethod
    def needs_preroll(body) -> bool:
        """Whether the animation's first frame is another pose than its rest pose."""
        first = body.vertices_at(body.start)
        size = float(np.linalg.norm(np.ptp(body.vertices, axis=0))) or 1.0
        # (float32 skinning at the bind pose is off by about 1e-7 of the size: not another pose)
        return bool(np.abs(first - body.vertices).max() > 1e-5 * size)
