"""Islands of strands at rest are put to sleep: not stepped until something near them changes.

As rigid-body engines do (Box2D's islands, Bullet's and Jolt's sleeping bodies), strands joined by
hair-hair contacts form an island; an island whose every strand has been at rest for
``SLEEP_STEPS`` steps in a row, under a body motion that has not changed, is put to sleep. A sleeping
strand keeps its shape and its contacts (with their forces) and costs nothing in a step: it has no
free motion, no contact rows and no place in the contact solve. It is woken, with its whole island,
when

* the body's motion as its strand feels it changes (gravity, the frame's acceleration, velocity,
  spin or their rates), or its root is carried;
* a deforming body moves a triangle within the body's contact distance of it;
* a strand that is awake comes into contact with it (a neighbour hits it).

For a groom at rest this is exact up to ``dynamics.sleep_speed``: the still promise leaves an inverted
groom's velocity far below it, so a still run with sleeping is the run without it, stopped. At rest here
means that no point of the strand moves faster than ``sleep_speed`` (bound: ``L sum |v_e| l_e``).
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from ..rod.helix import strand_points

__all__ = ["SLEEP_STEPS", "Sleepers", "carried", "islands"]

#: kept steps in a row a strand must be at rest, under an unchanged motion, before its island sleeps: a
#: swinging strand is that slow for a small part of one step at the end of its swing
SLEEP_STEPS = 3
# a motion (m/s^2, m/s, rad/s, rad/s^2) or a frame (m, or a rotation's entries) counts as changed by more
# than this (relative to gravity for the motion, absolute for the frame): round-off of the same input
_SAME = 1e-12


def carried(skin) -> np.ndarray:
    """(S,) bool: the strands whose frame a deforming body's step (:class:`~hairinv.dynamics.skin.SkinStep`)
    moves by more than round-off."""
    n = len(skin.c)
    return (np.abs(skin.R - skin.R_start).reshape(n, -1).max(axis=1, initial=0.0) > _SAME) | \
        (np.abs(skin.c - skin.c_start).max(axis=1, initial=0.0) > _SAME)


def islands(n_strands: int, pair: np.ndarray) -> np.ndarray:
    """(S,) int64: each strand's island, the connected components of the hair-hair contacts ``pair``
    (C, 2) (a body contact's second strand is -1 and joins nothing)."""
    hair = pair[pair[:, 1] >= 0] if len(pair) else np.zeros((0, 2), dtype=np.int64)
    graph = coo_matrix((np.ones(len(hair)), (hair[:, 0], hair[:, 1])), shape=(n_strands, n_strands))
    return connected_components(graph, directed=False)[1].astype(np.int64)


class Sleepers:
    """Which strands sleep, and what they fell asleep under.

    Attributes
    ----------
    asleep : (S,) bool
    calm : (S,) int64, kept steps in a row each awake strand has been at rest under an unchanged motion
    motion : (S, 5, 3) float64, the motion each strand felt at its last kept step (a sleeping strand's:
        the one it fell asleep under)
    box : (S, 2, 3) float64, m, a sleeping strand's points' bounding box grown by the reach of body
        contacts (where a moving triangle wakes it)
    island : (S,) int64, the island each sleeping strand fell asleep with (-1: awake); islands wake whole
    speed : float, m/s, ``dynamics.sleep_speed`` (0: nothing sleeps)
    woken : int, strands woken so far (each time)
    """

    def __init__(self, n_strands: int, speed: float):
        self.asleep = np.zeros(n_strands, dtype=np.bool_)
        self.calm = np.zeros(n_strands, dtype=np.int64)
        self.motion = None
        self.box = np.zeros((n_strands, 2, 3))
        self.island = np.full(n_strands, -1, dtype=np.int64)
        self.speed = float(speed)
        self.woken = 0
        self._labels = 0

    def any(self) -> bool:
        return bool(self.asleep.any())

    def stirred(self, packed: np.ndarray, skin, moved: np.ndarray | None = None) -> np.ndarray:
        """(S,) bool: sleeping strands a step's motion wakes (``packed`` (S, 5, 3), the step's motion per
        strand; ``skin``: its :class:`~hairinv.dynamics.skin.SkinStep`, or None for a rigid motion; ``moved``
        its :func:`carried`, if already known)."""
        stirred = np.zeros_like(self.asleep)
        sleeping = np.flatnonzero(self.asleep)
        if not len(sleeping):
            return stirred
        scale = _SAME * max(float(np.linalg.norm(packed[0, 0])), 1.0)
        changed = np.abs(packed[sleeping] - self.motion[sleeping]).reshape(len(sleeping), -1).max(axis=1) > scale
        if skin is not None:
            changed |= (carried(skin) if moved is None else moved)[sleeping]
            if skin.body is not None:
                changed |= self._near_moving_skin(sleeping, skin)
        stirred[sleeping[changed]] = True
        return stirred

    def _near_moving_skin(self, sleeping: np.ndarray, skin) -> np.ndarray:
        """(n,) bool: which of the ``sleeping`` strands' boxes a triangle that moves over the step meets."""
        moved = np.abs(skin.vertices - skin.vertices_start).max(axis=1) > _SAME
        near = np.zeros(len(sleeping), dtype=np.bool_)
        if not moved.any():
            return near
        faces = skin.faces[moved[skin.faces].any(axis=1)]
        corners = np.concatenate([skin.vertices[faces], skin.vertices_start[faces]], axis=1)  # (F, 6, 3)
        lo, hi = corners.min(axis=1), corners.max(axis=1)
        box = self.box[sleeping]
        # first against all the moving triangles together, then triangle by triangle in chunks
        maybe = np.flatnonzero(np.all((box[:, 0] <= hi.max(axis=0)) & (box[:, 1] >= lo.min(axis=0)), axis=1))
        for start in range(0, len(maybe), 256):
            which = maybe[start:start + 256]
            meets = np.all((box[which, None, 0] <= hi[None]) & (box[which, None, 1] >= lo[None]), axis=2)
            near[which] = meets.any(axis=1)
        return near

    def settle(self, speeds: np.ndarray, packed: np.ndarray, carried: np.ndarray) -> None:
        """Count a kept step: ``speeds`` (S,) m/s, each strand's fastest point (a bound), ``packed`` the
        step's motion, ``carried`` (S,) bool the strands whose frame the body moved over it."""
        awake = ~self.asleep
        if self.motion is None:
            same = np.zeros_like(awake)
        else:
            scale = _SAME * max(float(np.linalg.norm(packed[0, 0])), 1.0)
            same = np.abs(packed - self.motion).reshape(len(packed), -1).max(axis=1) <= scale
        still = awake & same & ~carried & (speeds <= self.speed)
        self.calm[awake] = np.where(still[awake], self.calm[awake] + 1, 0)
        motion = np.array(packed, dtype=np.float64, copy=True)
        if self.motion is not None:
            motion[self.asleep] = self.motion[self.asleep]
        self.motion = motion

    def ready(self, island: np.ndarray) -> np.ndarray:
        """(S,) bool: the awake strands whose whole island (``island`` (S,), :func:`islands`) is calm long enough."""
        if self.speed <= 0:
            return np.zeros_like(self.asleep)
        calm = ~self.asleep & (self.calm >= SLEEP_STEPS)
        n = int(island.max(initial=-1)) + 1
        restless = np.zeros(n, dtype=np.bool_)
        restless[island[~calm]] = True
        return calm & ~restless[island]

    def sleep(self, which: np.ndarray, island: np.ndarray, helices, reach: float) -> None:
        """Put ``which`` (S,) bool to sleep, whole islands of ``island`` (S,); ``helices`` the strands where
        they are, ``reach`` m how far from them a moving triangle of the body wakes them."""
        strands = np.flatnonzero(which)
        if not len(strands):
            return
        offsets, length = helices.offsets, helices.length
        counts = np.diff(offsets)[strands]
        elements = np.concatenate([np.arange(offsets[k], offsets[k + 1]) for k in strands])
        # every element's ends and middle; between them the centerline bulges from the chord by at most
        # (l / 2)^2 |omega| / 8, added to the reach
        starts = np.cumsum(length) - length
        s_end = np.concatenate([starts[elements] - starts[offsets[strands]].repeat(counts),
                                (starts[elements] + length[elements] - starts[offsets[strands]].repeat(counts))])
        s_mid = starts[elements] + 0.5 * length[elements] - starts[offsets[strands]].repeat(counts)
        owner = np.concatenate([strands.repeat(counts)] * 3)
        x = strand_points(helices.root, helices.frame0, offsets, helices.omega, length, owner.astype(np.int64),
                          np.concatenate([s_end, s_mid]))
        order = np.argsort(owner, kind="stable")
        owner, x = owner[order], x[order]
        first = np.searchsorted(owner, strands)
        bulge = (0.5 * length[elements]) ** 2 * np.linalg.norm(helices.omega[elements], axis=1) / 8.0
        grow = reach + np.maximum.reduceat(bulge, np.r_[0, np.cumsum(counts)[:-1]])
        self.box[strands, 0] = np.minimum.reduceat(x, first, axis=0) - grow[:, None]
        self.box[strands, 1] = np.maximum.reduceat(x, first, axis=0) + grow[:, None]
        self.asleep[strands] = True
        self.calm[strands] = 0
        _, label = np.unique(island[strands], return_inverse=True)
        self.island[strands] = self._labels + label
        self._labels += int(label.max()) + 1

    def wake(self, which: np.ndarray) -> np.ndarray:
        """Wake the islands of the sleeping strands ``which`` (S,) bool; returns (S,) bool, those woken."""
        hit = np.unique(self.island[which & self.asleep])
        woken = self.asleep & np.isin(self.island, hit)
        self.asleep[woken] = False
        self.calm[woken] = 0
        self.island[woken] = -1
        self.woken += int(np.count_nonzero(woken))
        return woken
