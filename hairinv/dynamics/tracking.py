"""The contacts a simulation follows from step to step: detection, and the contacts it remembers.

As collision detection stands apart from the integrators in NVIDIA warp's ``warp/sim`` (``collide(model,
state)``), :class:`ContactTracker` finds a step's contacts on the strands as they are at its start
(:meth:`~ContactTracker.detect`), keeps the remembered ones on the same material points
(:meth:`~ContactTracker.persist`), gives them their thickness and warm start
(:meth:`~ContactTracker.remember`), and keeps what a step ends with (:meth:`~ContactTracker.keep`).
The body it meets is the step's: the model's, for a rigid motion, or the one a deforming body's step
carries (:meth:`~ContactTracker.begin`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .._jit import jit
from ..contacts.body import REFINE_ITERATIONS, BodyMesh
from ..contacts.detect import COINCIDENT, contact_frames, detect_contacts
from ..model import Contacts, Helices
from ..rod.helix import chain, strand_points
from .contact import contact_keys
from .rods import RodModel, RodState

__all__ = ["ContactTracker", "points_on"]

# m: a remembered contact point stays while it is at most this much farther from the surface than
# the point detection finds on the same element
_PERSIST_SLACK = 1e-5
# of its element's length: how far along it from a body contact holding the element at its thickness the point
# detection finds closer must be to become the element's second contact (see ContactTracker.persist); closer
# points are the same support, and two contacts that near on one element only make the solve stiffer
_SECOND_APART = 0.25
# golden-section steps placing a body contact along its element once the groom moves: 3.1e-3 of the bracket
# between two samples (10-30 um on the samples' elements), where the distance found is off by the square
# of that over twice the radius of curvature (below 1e-8 m); the first detection (the model's own contacts)
# keeps the detector's default
_MOVING_REFINE = 12
# the share of elements holding the per-element cap of hair-hair contacts above which detection searches
# hair pairs narrowly first (one thread, the same contacts either way): on ruby short's 1,867 guides moving,
# 12 % held it, and detection took 0.24 s without the narrow search against 0.35 with it; heads of 8,000 and
# 30,000 strands around 400 and 1,500 guides (bench/full_head.py): 32 %, 1.8 s against 2.1-2.5; 65 %, 18 s
# against 13
_NARROW_SHARE = 0.5
# with hair-hair contact, the share of strands up to which a detection redoes only the strands that moved
# (see ContactTracker._detect_strands); beyond it the whole groom (0.95 instead: ruby short's first 9 steps
# from the start of the motion scene spent the same time detecting, within 4 %, on a shared machine)
_PARTIAL_SHARE = 0.5


def joined(first: Contacts, second: Contacts) -> Contacts:
    """The contacts of ``first`` and then those of ``second`` (their gaps and elements where both have them)."""
    return Contacts(*(None if a is None or b is None else np.concatenate([a, b]) for a, b in zip(
        (first.strand, first.s, first.point, first.frame, first.mu, first.gap, first.element),
        (second.strand, second.s, second.point, second.frame, second.mu, second.gap, second.element))))


def _on(asleep: np.ndarray, pair: np.ndarray) -> np.ndarray:
    """(C,) bool: the contacts ``pair`` (C, 2) whose every strand is in ``asleep`` (S,) bool."""
    return asleep[pair[:, 0]] & ((pair[:, 1] < 0) | asleep[np.maximum(pair[:, 1], 0)])


def points_on(helices: Helices, omega: np.ndarray, strand: np.ndarray, s: np.ndarray) -> np.ndarray:
    """:func:`hairinv.rod.helix.strand_points` of ``helices`` with the curvatures ``omega``, (n, 3)."""
    return strand_points(helices.root, helices.frame0, helices.offsets, omega, helices.length, strand, s)


@jit
def _strand_moves(root, frame0, offsets, q_from, q_to, length, out):
    """Per strand, a bound on how far any of its centerline points has moved from ``q_from`` to ``q_to``, m.

    A point at ``sigma`` along element ``e`` is ``x_e + F_e^T P(sigma; omega_e)``, and ``P`` moves
    by at most ``sigma^2 |d omega_e| / 2`` (its tangent turns by at most ``sigma |d omega_e|``), so
    it moves by at most ``|dx_e| + ||dF_e||_F l_e + l_e^2 |d omega_e| / 2``.
    """
    for k in range(offsets.shape[0] - 1):
        worst = 0.0
        a = offsets[k]
        z = offsets[k + 1]
        n = z - a
        xs0 = np.empty((n + 1, 3))
        Fs0 = np.empty((n + 1, 3, 3))
        xs1 = np.empty((n + 1, 3))
        Fs1 = np.empty((n + 1, 3, 3))
        chain(root[k], frame0[k], q_from[a:z], length[a:z], xs0, Fs0)
        chain(root[k], frame0[k], q_to[a:z], length[a:z], xs1, Fs1)
        for e in range(n + 1):
            dx = 0.0
            for i in range(3):
                dx += (xs1[e, i] - xs0[e, i]) ** 2
            bound = np.sqrt(dx)
            if e < n:
                dF = 0.0
                dw = 0.0
                for i in range(3):
                    dw += (q_to[a + e, i] - q_from[a + e, i]) ** 2
                    for j in range(3):
                        dF += (Fs1[e, i, j] - Fs0[e, i, j]) ** 2
                bound += np.sqrt(dF) * length[a + e] + 0.5 * length[a + e] ** 2 * np.sqrt(dw)
            worst = max(worst, bound)
        out[k] = worst


@jit
def _closest_per_element(ea, eb, order, cap, held, out):
    """Mark in ``out`` the element pairs taken in ``order`` while both of their elements hold fewer than ``cap``
    (``held``, per element, zeros on entry)."""
    for k in range(order.shape[0]):
        p = order[k]
        if held[ea[p]] < cap and held[eb[p]] < cap:
            held[ea[p]] += 1
            held[eb[p]] += 1
            out[p] = True


class ContactTracker:
    """A groom's contacts from one step to the next.

    Parameters
    ----------
    model : RodModel
    q : (E, 3) float64, the starting shape (where the model's own contacts were found)
    initial : Contacts, optional, the contacts of the starting shape and ``impulse`` their forces times
        the step, as warm start; they are matched to the first step's contacts element by element
    initial_force : (C, 3) float64, optional, their forces in their frames (N; None: unloaded)

    Attributes
    ----------
    contacts : Contacts, those of the last step (the starting ones before any)
    first : bool, whether no step has been kept yet
    keys, arc, pair, elements, mu, thickness, impulse : the remembered contacts, sorted by key (a contact's
        element, or element pair): where each sits on its strands, its strands and elements, its friction,
        its thickness (the room it keeps), its last impulse in world coordinates (frames may turn between steps)
    impulse_step : float, s, the remembered impulses are forces times this
    anchor : (point, normal, gap), where each remembered body contact's gap was last measured exactly (NaN
        points: none, or a hair-hair contact)
    last_found, q_detected : the last detection and the shape it was made on (per strand, for a partial one)
    stale : (C,) bool, which of this step's detected contacts come from an earlier shape (a detection
        reused, in whole or for the strands that have hardly moved)
    redetected : int, strands detected afresh at this step
    skin, body, margin, own : the step being taken: its deforming body's :class:`SkinStep` (None for a rigid
        motion), the body its contacts meet, how much closer than detected the body and strands come within
        it (m), and how far each strand's own motion may carry its points in its frame where that reaches
        beyond what the detection rules leave room for (m, (S,); else 0, see :meth:`own_sweep`)
    """

    def __init__(self, model: RodModel, q: np.ndarray, initial: Contacts | None = None,
                 initial_force: np.ndarray | None = None):
        self.model = model
        helices = model.helices
        contacts = model.contact_settings
        # new contacts come from the fixed distances: the hair layer and the wisps describe the input groom
        # (the model's own contacts of those rules persist at their distances, see persist)
        self.detect_settings = dataclasses.replace(contacts, layer=False, wisp=False)
        self.keys = np.zeros(0, dtype=np.int64)
        self.arc = np.zeros((0, 2))
        self.pair = np.zeros((0, 2), dtype=np.int64)
        self.elements = np.zeros((0, 2), dtype=np.int64)
        self.anchor = (np.full((0, 3), np.nan), np.zeros((0, 3)), np.zeros(0))
        self.mu = np.zeros(0)
        self.thickness = np.zeros(0)
        self.impulse = np.zeros((0, 3))
        self.impulse_step = 1.0  # s: the remembered impulses are forces times this (forces at the start)
        self.first = True
        self.initial = initial if initial is not None and initial.n_contacts else None
        self.initial_impulse = None
        if self.initial is not None:
            force = np.zeros((initial.n_contacts, 3)) if initial_force is None else initial_force
            self.initial_impulse = np.asarray(force, dtype=np.float64)
            keys = self.keys_of(initial)
            order = np.argsort(keys, kind="stable")
            self.keys = keys[order]
            gap = initial.gap if initial.gap is not None else np.zeros(initial.n_contacts)
            self.thickness = gap[order]
            self.arc = initial.s[order]
            self.pair = initial.strand[order]
            self.mu = initial.mu[order]
            self.elements = self.elements_of(initial)[order]
            self.anchor = self.anchors_of(initial, order)
            self.impulse = np.einsum("cji,cj->ci", initial.frame, self.initial_impulse)[order]
        self.contacts = initial if initial is not None else Contacts.empty()
        self.last_found = None
        self.stale = np.zeros(0, dtype=np.bool_)
        self.redetected = 0
        used = ([contacts.hair_distance] if contacts.hair_hair else []) + (
            [contacts.body_distance] if contacts.body and model.body is not None else [])
        self.detect_distance = min(used) if used else np.inf
        self.q_detected = None
        if self.initial is not None:
            # the starting contacts are those the model was inverted with, on this very shape: they are the
            # first detection, as stored (detecting them again could differ in round-off, or by the version
            # of the rules), provided their elements name them one by one
            elements = self.elements_of(self.initial)
            keys = self.keys_of(dataclasses.replace(self.initial, element=elements))
            if len(np.unique(keys)) == len(keys):
                self.initial = dataclasses.replace(self.initial, element=elements)
                self.last_found = self.initial
                self.q_detected = q.copy()
                self.stale = np.zeros(self.initial.n_contacts, dtype=np.bool_)
        self.skin = None
        self.body = model.body
        self.margin = (0.0, 0.0)
        self.own = np.zeros(helices.n_strands)
        self.ahead = None
        self.parked = None  # the sleeping strands' remembered contacts (see park)

    # ------------------------------------------------------------------ the step being taken
    def begin(self, skin, body: BodyMesh | None) -> None:
        """Start an attempt at a step under ``skin`` (a :class:`~hairinv.dynamics.skin.SkinStep`, None for a
        rigid motion), whose contacts meet ``body``."""
        self.skin = skin
        self.body = body
        self.margin = skin.margins(self.model.helices.root, self.model.tips) if skin is not None else (0.0, 0.0)

    @property
    def moving(self) -> bool:
        """Whether the body moves the strands' frames or itself over the step being taken."""
        return self.skin is not None and self.skin.moves

    # ------------------------------------------------------------------ detection
    def detect(self, state: RodState) -> Contacts:
        """This step's contacts: detected afresh once any strand point may have moved by more than a
        quarter of the smallest contact distance in use (the hair-hair one, or the body's without
        hair-hair contact) since the last detection (bounds: the elements' turns times the strand's
        length, cheap, then :func:`_strand_moves`, tighter); until then the last detection is reused,
        and the remembered contacts are measured again where they are (see :meth:`persist`).

        A strand whose own motion over the step (see :meth:`own_sweep`) reaches that far is detected
        again too, and its contacts are searched as far as that motion goes: a strand swinging into the
        body faster than the contact distance a step (hair down a back when the character stops short)
        meets it instead of passing into it, and a strand falling onto another meets it instead of passing
        through it (a pair is searched as far as the two strands' own motions together reach,
        :meth:`_hair_strands`).

        The strands are detected one by one: only those that may have moved by that much since their own
        last detection are detected again (the body does not move in its frame), and the others keep theirs.
        In the ``motion`` scene about half the strands of the 300-strand groom are detected at a step. With
        hair-hair contact a strand detected again meets the whole groom: every pair with it is searched
        afresh, and the pairs of two strands that have hardly moved are kept (:meth:`_detect_strands`);
        beyond half the strands the whole groom is detected. On ruby short (1,867 strands), moving from
        0.5 s into the ``motion`` scene, 28-255 strands were detected again at each of its first steps.
        """
        model = self.model
        h = model.helices
        S = h.n_strands
        q = state.q
        moving = self.moving
        swings = self.own > 0.0
        if self.last_found is not None and h.n_elements and not moving:
            reach = 0.25 * self.detect_distance
            # first the cheap bound: every element's turn |d omega_e| l_e swings the whole strand
            redo = model.swing(q - self.q_detected) >= reach
            if redo.any():
                moves = np.zeros(S)
                _strand_moves(h.root, h.frame0, h.offsets, self.q_detected, q, h.length, moves)
                redo &= moves >= reach  # either bound will do, strand by strand
            redo |= swings
            if not redo.any():
                self.stale = np.ones(self.last_found.n_contacts, dtype=np.bool_)
                self.redetected = 0
                return self.last_found
            if not redo.all() and (not model.contact_settings.hair_hair or redo.mean() <= _PARTIAL_SHARE):
                return self._detect_strands(state, np.flatnonzero(redo))
        # the first detection is the model's own, on the starting shape: the same rules as the contacts it was
        # inverted with (the hair layer and wisps included), so the first step meets them again
        # (and so is a first step the body moves: the model's contacts, remembered, are measured again)
        first = self.last_found is None or (self.first and moving)
        rules = model.contact_settings if first and self.initial is not None else self.detect_settings
        own = float(self.own.max(initial=0.0))
        if moving or own:  # what comes within reach during the step: the body's and the frames' sweep, and the
            # strands' own
            rules = dataclasses.replace(rules, body_distance=rules.body_distance + self.margin[0] + own,
                                        hair_distance=rules.hair_distance + self.margin[1])
        current = state.current(model)  # (placed by their frames under a deforming body: built once)
        # the pairs with a strand that moves that far, searched as far as it goes (see _swept): in the same
        # search, but for the first detection's wisp rule, which takes no per-strand reach
        reach = self.detect_settings.hair_distance + self.margin[1]
        swept = rules.hair_hair and bool(np.any(self._fast(reach)))
        farther = self.own if swept and not rules.wisp else None
        found, _ = detect_contacts(current, self.body, rules, up=model.up,
                                   refine_iterations=REFINE_ITERATIONS if first else _MOVING_REFINE,
                                   narrow=self._narrow_pays(), farther=farther)
        if own and rules.layer is False:  # (contacts the hair layer rule declares lie beyond the distance)
            found = self._within_sweep(found)
        if swept:
            hair = found.strand[:, 1] >= 0
            pairs = found.subset(hair)
            pairs = (pairs.subset(self._come_within(current, pairs, reach)) if farther is not None else
                     self._swept(current, pairs, swings, reach))
            found = joined(found.subset(~hair), pairs.subset(self._closest(pairs)))
        self.stale = np.zeros(found.n_contacts, dtype=np.bool_)
        self.redetected = S
        self.last_found, self.q_detected = found, q.copy()
        return found

    def _narrow_pays(self) -> bool:
        """Whether detection's first hair-pair search, to a quarter of ``hair_distance`` (``narrow`` of
        :func:`~hairinv.contacts.detect.detect_contacts`), is likely to save more than it costs: where at least
        ``_NARROW_SHARE`` of the elements held ``max_hair_per_element`` hair-hair contacts at the last detection
        (those it can settle are among them). The contacts are the same either way."""
        last, cap = self.last_found, int(self.model.contact_settings.max_hair_per_element)
        if last is None or cap <= 0 or not self.model.contact_settings.hair_hair:
            return True
        n = self.model.helices.n_elements
        elements = self.elements_of(last)[last.strand[:, 1] >= 0]
        held = np.bincount(elements[:, 0], minlength=n) + np.bincount(elements[:, 1], minlength=n)
        return np.count_nonzero(held >= cap) >= _NARROW_SHARE * n

    def _detect_strands(self, state: RodState, which: np.ndarray) -> Contacts:
        """The strands ``which`` detected afresh, the others' last detection kept: their body contacts, and with
        hair-hair contact every pair with a strand among them, searched against the whole groom; the pairs of two
        other strands are the last detection's, and each element then keeps its ``max_hair_per_element``
        closest pairs of the two (the rule of a whole detection, on the distances each was detected at)."""
        h = state.current(self.model)  # placed by their frames, under a deforming body
        counts = np.diff(h.offsets)
        elements = np.concatenate([np.arange(h.offsets[k], h.offsets[k + 1]) for k in which])
        sub = Helices(h.root[which], h.frame0[which], np.r_[0, np.cumsum(counts[which])].astype(np.int64),
                      h.length[elements], state.q[elements], h.fit_error[which])
        rules = dataclasses.replace(self.detect_settings, hair_hair=False)  # (the pairs: _hair_strands)
        own = float(self.own[which].max(initial=0.0))
        if own:  # as far as the strands' own motion goes (see detect)
            rules = dataclasses.replace(rules, body_distance=rules.body_distance + own)
        fresh, _ = detect_contacts(sub, self.body, rules, refine_iterations=_MOVING_REFINE)
        # back to the groom's numbering: strands, and elements (a body contact's second is -1)
        fresh.strand[:, 0] = which[fresh.strand[:, 0]]
        fresh.element[:, 0] = elements[fresh.element[:, 0]]
        if own:
            fresh = self._within_sweep(fresh)
        last = self.last_found
        redone = np.zeros(h.n_strands, dtype=bool)
        redone[which] = True
        body = last.strand[:, 1] < 0
        kept = last.subset(body & ~redone[last.strand[:, 0]])
        merged = joined(kept, fresh)
        order = np.lexsort((merged.s[:, 0], merged.strand[:, 0]))  # as detect_contacts orders body contacts
        found = merged.subset(order)
        stale = order < kept.n_contacts
        if self.model.contact_settings.hair_hair:
            hair, hair_stale = self._hair_strands(h, last.subset(~body), redone)
            found, stale = joined(found, hair), np.concatenate([stale, hair_stale])
        self.stale = stale
        self.redetected = len(which)
        self.q_detected[elements] = state.q[elements]
        self.last_found = found
        return found

    def _hair_strands(self, h: Helices, last: Contacts, redone: np.ndarray) -> tuple[Contacts, np.ndarray]:
        """Hair-hair contacts of ``h`` (the strands as they are), the pairs with a strand in ``redone`` (S,) bool
        detected afresh (as far as their strands move, :meth:`_swept`) and those of two other strands kept from
        ``last`` (the last detection's hair-hair contacts), each element keeping its ``max_hair_per_element``
        closest; and which are kept ones."""
        rules = dataclasses.replace(self.detect_settings, body=False)
        reach = rules.hair_distance + self.margin[1]
        # as far as their strands move, in the same search where one of them moves fast (see _swept)
        farther = self.own if np.any(redone & self._fast(reach)) else None
        fresh, _ = detect_contacts(h, None, rules, refine_iterations=_MOVING_REFINE, narrow=self._narrow_pays(),
                                   touching=redone, farther=farther)
        if farther is not None:
            fresh = fresh.subset(self._come_within(h, fresh, reach))
        kept = last.subset(~(redone[last.strand[:, 0]] | redone[last.strand[:, 1]]))
        both = joined(kept, fresh)
        order = self._closest(both, np.concatenate([kept.gap if kept.gap is not None else np.zeros(kept.n_contacts),
                                                    fresh.gap]))
        return both.subset(order), order < kept.n_contacts

    def _closest(self, pairs: Contacts, gap: np.ndarray | None = None) -> np.ndarray:
        """The hair-hair ``pairs`` each element keeps (its ``max_hair_per_element`` closest by ``gap``, default
        theirs), in the order :func:`~hairinv.contacts.detect.detect_contacts` gives hair-hair contacts."""
        cap = int(self.detect_settings.max_hair_per_element)
        if cap > 0 and pairs.n_contacts:
            elements = self.elements_of(pairs)
            gap = pairs.gap if gap is None else gap
            closest = np.zeros(pairs.n_contacts, dtype=np.bool_)
            _closest_per_element(elements[:, 0], elements[:, 1], np.argsort(gap, kind="stable"), cap,
                                 np.zeros(self.model.helices.n_elements, dtype=np.int64), closest)
        else:
            closest = np.ones(pairs.n_contacts, dtype=np.bool_)
        order = np.flatnonzero(closest)
        return order[np.lexsort((pairs.s[order, 1], pairs.s[order, 0], pairs.strand[order, 1],
                                 pairs.strand[order, 0]))]

    def _swept(self, h: Helices, fresh: Contacts, redone: np.ndarray, reach: float) -> Contacts:
        """``fresh`` (hair-hair pairs found within the contact distance ``reach``, the step's margin included,
        their strands among ``redone``) with the pairs of a strand that moves fast searched again as far as
        their strands move.

        Two strands can pass through each other between two detections only if together they move farther
        than the contact distance over the step (:meth:`own_sweep`), so one of them more than half of it.
        Each pair with such a strand is searched as far as its two strands' motions reach, and kept where
        their points, carried in a straight line by the velocities the step starts with, come within the
        contact distance (:meth:`_come_within`): strands that move together (a wisp swinging) are not asked
        to keep apart. Each pair is searched to its own reach (``farther`` of
        :func:`~hairinv.contacts.detect.detect_contacts`). :meth:`detect` and :meth:`_hair_strands` do it in
        their own search; this second search is for the first detection under the wisp rule, which takes no
        per-strand reach. On ruby short from the start of the ``motion`` scene a step's detection took
        0.33-0.44 s in one search, 0.49-0.52 s with this second one, and 0.8-0.9 s when the fast strands were
        searched in groups moving within a factor of two of each other, each to twice its fastest's motion."""
        fast = redone & self._fast(reach)
        if not fast.any():
            return fresh
        rules = dataclasses.replace(self.detect_settings, body=False, hair_distance=reach)
        swept, _ = detect_contacts(h, None, rules, refine_iterations=_MOVING_REFINE, touching=fast, farther=self.own)
        out = fresh.subset(~(fast[fresh.strand[:, 0]] | fast[fresh.strand[:, 1]]))
        return joined(out, swept.subset(self._come_within(h, swept, reach)))

    def _fast(self, reach: float) -> np.ndarray:
        """(S,) bool: the strands whose own motion over the step (:meth:`own_sweep`) exceeds half the contact
        distance ``reach``: with another, they could pass through each other between two detections."""
        return self.own > 0.5 * reach

    def _come_within(self, h: Helices, pairs: Contacts, reach: float) -> np.ndarray:
        """Which hair ``pairs`` come within ``reach`` over the step, their two points moved as the strands'
        velocities at the step's start carry them (:meth:`own_sweep`), in a straight line: two strands that move
        together (a wisp swinging) are not asked to keep apart."""
        near = pairs.gap < reach
        if self.ahead is None or near.all():
            return near
        strand, s = pairs.strand, pairs.s
        now = points_on(h, h.omega, strand[:, 0], s[:, 0]) - points_on(h, h.omega, strand[:, 1], s[:, 1])
        then = points_on(h, self.ahead, strand[:, 0], s[:, 0]) - points_on(h, self.ahead, strand[:, 1], s[:, 1])
        closing = then - now
        t = np.clip(-np.einsum("ij,ij->i", now, closing) / np.maximum(np.einsum("ij,ij->i", closing, closing),
                                                                         1e-300), 0.0, 1.0)
        return near | (np.linalg.norm(now + t[:, None] * closing, axis=1) < reach)

    def own_sweep(self, state: RodState, h: float) -> np.ndarray:
        """(S,) m: how far each strand's own motion carries its points in its frame over the step, at the velocity
        it starts with (a bound, :func:`_strand_moves` from ``q`` to ``q + h v``), where that reaches a quarter
        of the smallest contact distance in use, beyond which :meth:`detect` no longer reuses a detection; 0
        elsewhere, where the room between the contact distances and thicknesses already holds it.

        (The velocity the step starts with, not the free one: a strand at rest on its contacts has a free
        velocity, gravity's pull over the step, that those contacts take away; the pull a step adds to a moving
        strand, ``a h``, moves it by ``a h^2`` more, a millimetre for 1 g at 100 steps a second, and is counted
        from the next step on.)"""
        hel = self.model.helices
        own = np.zeros(hel.n_strands)
        self.ahead = None
        if not hel.n_elements or not np.isfinite(self.detect_distance):
            return own
        reach = 0.25 * self.detect_distance
        cheap = self.model.swing(state.v, h)
        if cheap.max() < reach:
            return own
        self.ahead = state.q + h * state.v  # (the shape the step's start velocity leads to: _come_within)
        _strand_moves(hel.root, hel.frame0, hel.offsets, state.q, self.ahead, hel.length, own)
        own = np.minimum(own, cheap)
        own[own < reach] = 0.0
        return own

    def _within_sweep(self, found: Contacts) -> Contacts:
        """``found`` without the body contacts beyond their own strand's reach this step: detection searched
        as far as the farthest strand's own sweep reaches, for every strand."""
        limit = self.detect_settings.body_distance + self.margin[0] + self.own[found.strand[:, 0]]
        far = (found.strand[:, 1] < 0) & (found.gap >= limit)
        return found.subset(~far) if far.any() else found

    # ------------------------------------------------------------------ naming contacts
    def keys_of(self, contacts: Contacts) -> np.ndarray:
        """A key per contact naming it from one detection to the next: its element (pair)."""
        helices = self.model.helices
        if contacts.element is None:
            return contact_keys(contacts.strand, contacts.s, helices.offsets, helices.length)
        n = helices.n_elements
        return np.where(contacts.element[:, 1] < 0, contacts.element[:, 0],
                        n * (1 + contacts.element[:, 0]) + contacts.element[:, 1])

    def _match(self, keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For each key, its index among the remembered contacts' (sorted) keys, and whether it is one."""
        where = np.minimum(np.searchsorted(self.keys, keys), max(len(self.keys) - 1, 0))
        known = self.keys[where] == keys if len(self.keys) else np.zeros(len(keys), bool)
        return where, known

    def elements_of(self, contacts: Contacts) -> np.ndarray:
        """(C, 2) int64, each contact's elements (a body contact's second is -1)."""
        if contacts.element is not None:
            return contacts.element
        keys = self.keys_of(contacts)
        n = self.model.helices.n_elements
        return np.stack([np.where(keys < n, keys, keys // n - 1), np.where(keys < n, -1, keys % n)], axis=1)

    @staticmethod
    def anchors_of(contacts: Contacts, order: np.ndarray) -> tuple:
        """Exact gap measurements of body contacts as detected (NaN points: none for hair-hair)."""
        point = contacts.point[order].copy()
        point[contacts.strand[order, 1] >= 0] = np.nan
        gap = contacts.gap[order] if contacts.gap is not None else np.zeros(len(order))
        return point, contacts.frame[order, 0].copy(), gap.copy()

    # ------------------------------------------------------------------ remembered contacts
    def persist(self, state: RodState, found: Contacts, dt: float) -> tuple[Contacts, tuple, np.ndarray]:
        """Contacts that persist stay on the same material points of their strands.

        Detection picks each element's closest point afresh; where a strand lies
        along the body (or along another strand) that point jumps along the
        element with the slightest motion (or to the element's end, where no
        contact is declared), and the force warm-started from the last step
        would act somewhere else or vanish. So a remembered contact keeps its
        arc lengths, its gap and normal are measured there, and it is kept as
        long as that gap stays within the detection distance.

        A detection reused from an earlier shape (see :meth:`detect`), in whole
        or for some strands, was made there: all its contacts are measured again at
        their arc lengths, and none moves to its (stale) detected point.

        A body contact whose point has moved by less than ``tolerance g dt^2 / 4``
        since its gap was last measured exactly (its anchor) takes the gap to first
        order from there, ``gap + n . dx``, and keeps the normal: the signed
        distance is 1-Lipschitz, so the error is under ``2 |dx|``, which moves the
        contact velocity by under half the contact solve's tolerance. A still
        groom then makes no closest-point queries.

        Returns the contacts, their anchors (point, normal, gap; NaN points for
        hair-hair contacts) and their keys, for :meth:`remember` and :meth:`keep`.
        """
        model = self.model
        settings, contact_settings = model.settings, model.contact_settings
        moving = self.moving
        if (self.first and not moving) or not (len(self.keys) or self.stale.any()):
            # the first step meets the starting contacts as detected (see remember), and so does a
            # fresh detection with nothing remembered
            return found, self.anchors_of(found, np.arange(found.n_contacts)), self.keys_of(found)
        keys = self.keys_of(found)
        where, known = self._match(keys)
        missing = np.ones(len(self.keys), bool)
        missing[where[known]] = False
        # the union: what detection found, and the remembered contacts it did not find again
        extra = np.flatnonzero(missing)
        strand = np.concatenate([found.strand, self.pair[extra]])
        arc = np.concatenate([found.s, self.arc[extra]])
        arc[np.flatnonzero(known)] = self.arc[where[known]]
        mu = np.concatenate([found.mu, self.mu[extra]])
        element = np.concatenate([self.elements_of(found), self.elements[extra]])
        old_frame = np.concatenate([found.frame, np.zeros((len(extra), 3, 3))])
        # measured again: the remembered contacts, and every contact of a reused detection (its points,
        # gaps and normals are from the shape it was made on)
        redo = np.flatnonzero(np.concatenate([known | self.stale, np.ones(len(extra), dtype=np.bool_)]))
        gap = np.concatenate([found.gap if found.gap is not None else np.zeros(found.n_contacts),
                              np.zeros(len(extra))])
        # each contact's anchor: the remembered one where it is remembered, else none yet
        remembered = np.concatenate([np.where(known, where, -1), extra])
        anchor_point = np.full((len(strand), 3), np.nan)
        anchor_normal = np.zeros((len(strand), 3))
        anchor_gap = np.zeros(len(strand))
        had = remembered >= 0
        anchor_point[had] = self.anchor[0][remembered[had]]
        anchor_normal[had] = self.anchor[1][remembered[had]]
        anchor_gap[had] = self.anchor[2][remembered[had]]
        point = np.concatenate([found.point, np.zeros((len(extra), 3))])
        normal = old_frame[:, 0].copy()  # remembered contacts get theirs measured below
        h = state.current(model)
        xa = points_on(h, state.q, strand[redo, 0], arc[redo, 0])
        point[redo] = xa
        body = strand[redo, 1] < 0
        limit = np.where(body, contact_settings.body_distance + self.margin[0] + self.own[strand[redo, 0]],
                         contact_settings.hair_distance + self.margin[1] + self.own[strand[redo, 0]]
                         + self.own[np.maximum(strand[redo, 1], 0)])
        if body.any():
            if self.body is None:
                gap[redo[body]] = np.inf
            else:
                at = redo[body]
                shift = xa[body] - anchor_point[at]
                # NaN (no anchor) compares False: measured
                near = np.linalg.norm(shift, axis=1) <= 0.25 * settings.tolerance * model.velocity_scale * dt * dt
                if moving:
                    near[:] = False  # the body has moved under every anchor
                held = at[near]
                normal[held] = anchor_normal[held]
                gap[held] = anchor_gap[held] + np.einsum("ij,ij->i", anchor_normal[held], shift[near])
                measure = at[~near]
                if len(measure):
                    x = xa[body][~near]
                    sd, closest, feature, _ = self.body.closest(x)
                    away = x - closest
                    dist = np.linalg.norm(away, axis=1)
                    flat = dist <= COINCIDENT * contact_settings.body_distance
                    side = np.where(sd < 0, -1.0, 1.0)[:, None]
                    normal[measure] = np.where(flat[:, None], feature,
                                               side * away / np.where(flat, 1.0, dist)[:, None])
                    gap[measure] = sd
                    anchor_point[measure], anchor_normal[measure], anchor_gap[measure] = x, normal[measure], sd
        hair = ~body
        if hair.any():
            xb = points_on(h, state.q, strand[redo[hair], 1], arc[redo[hair], 1])
            apart = xa[hair] - xb
            dist = np.linalg.norm(apart, axis=1)
            flat = dist <= COINCIDENT * contact_settings.hair_distance
            normal[redo[hair]] = np.where(flat[:, None], normal[redo[hair]], apart / np.where(flat, 1.0, dist)[:, None])
            gap[redo[hair]] = dist
        frame = old_frame
        frame[redo] = contact_frames(normal[redo])
        keep = np.ones(len(strand), bool)
        # a remembered contact that touches beyond the detection distance (declared on a hair layer or
        # between wisps) keeps its own reach: its thickness and the layer tolerance
        thick = np.where(remembered[redo] >= 0, self.thickness[np.maximum(remembered[redo], 0)], 0.0) \
            if len(self.thickness) else np.zeros(len(redo))
        limit = np.where(thick > limit, thick + contact_settings.layer_tolerance, limit)
        keep[redo] = gap[redo] < limit  # contacts that have opened beyond reach end here
        # where detection found a point clearly closer than the remembered one (the strand slides or
        # rolls over the surface), the contact moves there: the remembered point would leave the
        # closest one unconstrained
        redetected = np.flatnonzero(known)
        detected_gap = found.gap[redetected] if found.gap is not None else gap[redetected]
        # (not from a reused detection: its closest points are not this shape's)
        deeper = (gap[redetected] > detected_gap + _PERSIST_SLACK) & ~self.stale[redetected]
        # but a body contact whose remembered point holds the strand at its thickness stays, and the point
        # found becomes its element's second contact: an element lying along the body (a strand resting on
        # it) rests on two points, and moving its only one from end to end would rock it for ever (one
        # found inside, being pushed out, moves as the others)
        touches = np.zeros(len(redetected), dtype=bool)
        body_found = deeper & (strand[redetected, 1] < 0)
        if body_found.any() and len(self.thickness):
            on = redetected[body_found]
            apart = np.abs(found.s[on, 0] - arc[on, 0]) >= _SECOND_APART * self.model.helices.length[element[on, 0]]
            touches[body_found] = apart & (np.abs(gap[on] - self.thickness[where[on]]) <= _PERSIST_SLACK)
        moved = redetected[deeper & ~touches]
        arc[moved], point[moved], frame[moved], gap[moved] = (found.s[moved], found.point[moved], found.frame[moved],
                                                              detected_gap[np.searchsorted(redetected, moved)])
        keep[moved] = True
        moved_body = moved[strand[moved, 1] < 0]
        anchor_point[moved_body] = point[moved_body]
        anchor_normal[moved_body] = frame[moved_body, 0]
        anchor_gap[moved_body] = gap[moved_body]
        keys = np.concatenate([keys, self.keys[extra]])
        second = redetected[touches]
        if len(second):
            # its element's second contact, if it has one already (among the remembered ones detection
            # does not name), moves there only if the point found is clearly closer than it too
            second_gap = detected_gap[touches]
            second_key = self.second_key(element[second, 0])
            at, has = self._match(second_key)
            # (detection never names a second contact: a remembered one is among the extra ones)
            old = found.n_contacts + np.searchsorted(extra, at[has])
            shift = gap[old] > second_gap[has] + _PERSIST_SLACK
            old, source = old[shift], second[has][shift]
            arc[old], point[old], frame[old], gap[old] = found.s[source], found.point[source], \
                found.frame[source], second_gap[has][shift]
            keep[old] = True
            anchor_point[old], anchor_normal[old], anchor_gap[old] = point[old], frame[old, 0], gap[old]
            new = second[~has]
            new_gap = second_gap[~has]
            strand, arc, mu, element = (np.concatenate([strand, found.strand[new]]), np.concatenate([arc, found.s[new]]),
                                        np.concatenate([mu, found.mu[new]]), np.concatenate([element, element[new]]))
            point, frame, gap = (np.concatenate([point, found.point[new]]), np.concatenate([frame, found.frame[new]]),
                                 np.concatenate([gap, new_gap]))
            anchor_point = np.concatenate([anchor_point, found.point[new]])
            anchor_normal = np.concatenate([anchor_normal, found.frame[new, 0]])
            anchor_gap = np.concatenate([anchor_gap, new_gap])
            keep = np.concatenate([keep, np.ones(len(new), bool)])
            keys = np.concatenate([keys, second_key[~has]])
        merged = Contacts(strand, arc, point, frame, mu, gap, element)
        anchors = (anchor_point, anchor_normal, anchor_gap)
        if keep.all():
            return merged, anchors, keys
        return merged.subset(keep), tuple(a[keep] for a in anchors), keys[keep]

    def second_key(self, element: np.ndarray) -> np.ndarray:
        """The key of a body contact that is its element's second (see :meth:`persist`): beyond every
        element's and element pair's."""
        n = self.model.helices.n_elements
        return n * (n + 1) + element

    def remember(self, found: Contacts, h: float, keys: np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Keys, thickness and warm-start impulse of this step's contacts (``keys``: theirs from :meth:`persist`;
        None: named by their elements)."""
        model = self.model
        keys = self.keys_of(found) if keys is None else keys
        gap = found.gap if found.gap is not None else np.zeros(found.n_contacts)
        initial = self.initial
        if self.first and initial is not None and initial.n_contacts == found.n_contacts \
                and np.array_equal(initial.strand, found.strand) and np.allclose(initial.s, found.s, rtol=0, atol=1e-12):
            # the starting shape meets the contacts it was inverted with: their forces, one for one
            return keys, gap.copy(), h * self.initial_impulse
        where, known = self._match(keys)
        fresh = np.where(found.strand[:, 1] < 0, model.settings.body_thickness, model.settings.hair_thickness)
        if self.first:
            # everything touching the starting shape touches at its own distance; what a first step finds beyond
            # the detection distances, brought within reach by the body's sweep or the strand's own (in this
            # attempt, or in a longer one it halves, whose detection it reuses), is new (the contacts the hair
            # layer and wisp rules declare beyond them are the model's, remembered: their thickness is below)
            reach = np.where(found.strand[:, 1] < 0, model.contact_settings.body_distance,
                             model.contact_settings.hair_distance)
            fresh = np.where(gap > reach, fresh, gap)
        # a new contact keeps the room it has, up to its thickness; one found inside is pushed out
        thickness = np.minimum(gap if self.first else np.maximum(gap, 0.0), fresh)
        impulse = np.zeros((found.n_contacts, 3))
        if len(self.keys):
            thickness[known] = self.thickness[where[known]]
            # a new second contact of an element (see persist) keeps the room its first one keeps (as the
            # first would, moved there): where the groom was drawn into the body, both hold the element inside
            first_key = self.second_key(0)
            second = np.flatnonzero(~known & (keys >= first_key))
            at, has = self._match(keys[second] - first_key)
            thickness[second[has]] = self.thickness[at[has]]
            # the same forces over this step's length (a halved step starts from half the impulses)
            world = self.impulse[where[known]] * (h / self.impulse_step)
            impulse[known] = np.einsum("cij,cj->ci", found.frame[known], world)
        return keys, thickness, impulse

    def keep(self, found: Contacts, keys: np.ndarray, thickness: np.ndarray, impulse: np.ndarray, anchors: tuple,
             h: float) -> None:
        """Remember a kept step's contacts ``found`` (their keys, thickness, impulses in their frames and anchors
        from :meth:`persist` and :meth:`remember`), sorted by key; ``h`` the step's length."""
        self.first = False
        order = np.argsort(keys, kind="stable")
        world = np.einsum("cji,cj->ci", found.frame, impulse)
        self.keys, self.thickness, self.impulse = keys[order], thickness[order], world[order]
        self.impulse_step = h
        self.arc, self.pair, self.mu = found.s[order], found.strand[order], found.mu[order]
        self.elements = self.elements_of(found)[order]
        if self.moving:  # measured on the body at the step's start, which has moved since: none is kept
            anchors = (np.full_like(anchors[0], np.nan),) + tuple(anchors[1:])
        self.anchor = tuple(a[order] for a in anchors)
        self.contacts = found

    # ------------------------------------------------------------------ sleeping strands
    _REMEMBERED = ("keys", "thickness", "impulse", "arc", "pair", "mu", "elements")

    def park(self, asleep: np.ndarray) -> None:
        """Set aside the remembered contacts of the sleeping strands ``asleep`` (S,) bool (their islands
        whole: none of them touches an awake strand), as they are: steps neither measure nor solve
        them, and :meth:`unpark` gives them back."""
        mask = _on(asleep, self.pair)
        shown = _on(asleep, self.contacts.strand)
        if not mask.any() and not shown.any():
            return
        parked = self.parked
        out = {name: getattr(self, name)[mask] for name in self._REMEMBERED}
        out["anchor"] = tuple(a[mask] for a in self.anchor)
        for name in self._REMEMBERED:
            setattr(self, name, getattr(self, name)[~mask])
        self.anchor = tuple(a[~mask] for a in self.anchor)
        contacts = self.contacts.subset(shown)
        self.contacts = self.contacts.subset(~shown)
        if parked is not None:
            out = {name: np.concatenate([parked[name], out[name]]) for name in self._REMEMBERED} | {
                "anchor": tuple(np.concatenate([a, b]) for a, b in zip(parked["anchor"], out["anchor"]))}
            contacts = joined(parked["contacts"], contacts)
        out["contacts"] = contacts
        self.parked = out

    def unpark(self, woken: np.ndarray) -> None:
        """Give back the parked contacts of the strands ``woken`` (S,) bool, their islands whole."""
        parked = self.parked
        if parked is None:
            return
        mask = woken[parked["pair"][:, 0]]
        shown = woken[parked["contacts"].strand[:, 0]]
        if not mask.any() and not shown.any():
            return
        merged = {name: np.concatenate([getattr(self, name), parked[name][mask]]) for name in self._REMEMBERED}
        order = np.argsort(merged["keys"], kind="stable")
        for name in self._REMEMBERED:
            setattr(self, name, merged[name][order])
        self.anchor = tuple(np.concatenate([a, b[mask]])[order] for a, b in zip(self.anchor, parked["anchor"]))
        self.contacts = joined(self.contacts, parked["contacts"].subset(shown))
        rest = {name: parked[name][~mask] for name in self._REMEMBERED}
        rest["anchor"] = tuple(a[~mask] for a in parked["anchor"])
        rest["contacts"] = parked["contacts"].subset(~shown)
        self.parked = rest

    def awake_only(self, found: Contacts, asleep: np.ndarray) -> Contacts:
        """``found`` without the contacts between sleeping strands (their remembered ones are parked); the
        detection's flags follow."""
        keep = ~_on(asleep, found.strand)
        if keep.all():
            return found
        self.stale = self.stale[keep]
        return found.subset(keep)

    def shown(self) -> Contacts:
        """Every contact of the last step, the sleeping strands' included."""
        parked = self.parked
        if parked is None or not parked["contacts"].n_contacts:
            return self.contacts
        return joined(self.contacts, parked["contacts"])

    # ------------------------------------------------------------------ the contacts' motion
    def rooted(self, found: Contacts) -> np.ndarray:
        """(C,) bool: the contacts with a side on its strand's first element."""
        elements = self.elements_of(found)
        first = self.model.helices.offsets[:-1]
        side0 = elements[:, 0] == first[found.strand[:, 0]]
        hair = found.strand[:, 1] >= 0
        side1 = np.zeros_like(side0)
        side1[hair] = elements[hair, 1] == first[found.strand[hair, 1]]
        return side0 | side1

    def drift(self, state: RodState, found: Contacts) -> np.ndarray:
        """(C, 3) m/s, in the contacts' frames: how fast the strands' frames carry each contact's first side
        against its second (the skin, for a body contact; the other strand's frame) over the step, from
        where they are at its start."""
        skin = self.skin
        posed = state.current(self.model)
        xa = points_on(posed, state.q, found.strand[:, 0], found.s[:, 0])
        world = skin.frame_velocity(found.strand[:, 0], xa)
        body = found.strand[:, 1] < 0
        if body.any() and skin.body is not None:
            _, _, _, face = skin.body.closest(xa[body])
            world[body] -= skin.skin_velocity(face, xa[body])
        hair = np.flatnonzero(~body)
        if len(hair):
            xb = points_on(posed, state.q, found.strand[hair, 1], found.s[hair, 1])
            world[hair] -= skin.frame_velocity(found.strand[hair, 1], xb)
        return np.einsum("cji,ci->cj", found.frame, world)
