"""Contact detection: where the fitted strands touch the body and each other (paper, section 5).

Every element of every strand is sampled at ``samples_per_element`` points
along its fitted centerline, both ends included. A strand touches the body
where a sample beyond ``root_clearance`` comes within ``body_distance`` of the
surface or lies inside it; it touches another strand where the two
centerlines come within ``hair_distance``. At most one contact is declared per
element against the body and per pair of elements between strands, at the
closest (or deepest) point, refined on the exact centerlines. An element owns
its arc-length range ``[start, end)`` (the last element also its tip): an
element (or pair) whose closest point is its end declares nothing there, since
that point starts the next element, whose own closest point is at least as
close. See docs/contacts.md for the rules and the reasons for the defaults.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field

import numpy as np

from .._jit import jit
from .._parallel import balanced, run_chunks
from .._sorting import float_order, stable_order
from ..config import ContactSettings
from .._text import counted
from ..errors import InputError
from ..model import BODY, Contacts, Helices
from ._curve import element_starts, sample_elements
from .body import REFINE_ITERATIONS, BodyMesh, element_body_contacts
from .hair import _grow, element_sag, hair_pairs, pair_points, polyline_slack, refine_pairs

__all__ = ["DetectReport", "detect_contacts", "validate_settings", "contact_frames"]

# Below this fraction of the contact distance the two closest points are taken as coincident and the
# normal comes from the geometry instead (the body's pseudo-normal, or the two hair tangents).
COINCIDENT = 1e-6
# Strands per chunk of the body stage: the unit of the progress callback.
CHUNK = 64


@dataclass
class DetectReport:
    """Counts and figures of a detection, for the user."""

    n_body: int
    n_hair: int
    strands_touching_body: int
    strands_inside_body: int
    points_inside_body: int
    seconds: float
    notes: list[str] = field(default_factory=list)
    deepest_inside: float = 0.0
    """m. Depth of the deepest sample inside the body (0 if none)."""
    body_layer: int = 0
    """body contacts declared by the layer rule (beyond body_distance, on a strand's hair layer)"""
    layer_gaps: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """m, the gap of every run of a strand along the body that declared layer contacts"""
    layer_strands: int = 0
    hair_wisp: int = 0
    """hair-hair contacts declared by the wisp rule (beyond hair_distance, resting on a strand below)"""
    wisp_radius: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """m, per strand, the wisp contact distance derived from the local spacing (hair_distance where none)"""

    def lines(self) -> list[str]:
        lines = [
            f"declared {self.n_body + self.n_hair} contacts in {self.seconds:.2f} s: {self.n_body} hair-body "
            f"on {self.strands_touching_body} strands, {self.n_hair} hair-hair"
        ]
        if self.body_layer:
            g = 1e3 * self.layer_gaps
            lines.append(
                f"hair layer: {self.body_layer} of the body contacts lie beyond body_distance, on {self.layer_strands} "
                f"strands running along the body at a nearly constant gap (gap, mm: 5th percentile "
                f"{np.percentile(g, 5):.2f}, median {np.median(g):.2f}, 95th {np.percentile(g, 95):.2f}, max "
                f"{g.max():.2f}; contacts.layer)")
        if self.hair_wisp:
            w = 1e3 * self.wisp_radius
            lines.append(
                f"wisps: {self.hair_wisp} of the hair-hair contacts rest on a strand below beyond hair_distance, "
                f"within the wisp width of the local spacing (mm: median {np.median(w):.2f}, max {w.max():.2f}; "
                "contacts.wisp)")
        if self.points_inside_body:
            lines.append(
                f"warning: {self.points_inside_body} sample points on {self.strands_inside_body} "
                f"strand{'s' if self.strands_inside_body != 1 else ''} lie inside "
                f"the body (deepest {1e3 * self.deepest_inside:.2f} mm); they stay body contacts (at most one per "
                "element, at its deepest point), with normals pushing the hair out"
            )
        lines += self.notes
        return lines


def validate_settings(settings: ContactSettings) -> None:
    """Raise :class:`InputError` with one sentence if a contact setting is out of range."""
    for name in ("body_distance", "hair_distance"):
        value = getattr(settings, name)
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise InputError(f"contacts.{name} must be a distance > 0 m, got {value!r}")
    value = settings.root_clearance
    if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
        raise InputError(f"contacts.root_clearance must be a distance >= 0 m, got {value!r}")
    for name in ("mu_body", "mu_hair"):
        value = getattr(settings, name)
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
            raise InputError(f"contacts.{name} must be a friction coefficient >= 0, got {value!r}")
    if not isinstance(settings.max_hair_per_element, int) or settings.max_hair_per_element < 0:
        raise InputError("contacts.max_hair_per_element must be an integer >= 0 (0: no limit), "
                         f"got {settings.max_hair_per_element!r}")
    for name in ("layer_max_gap", "layer_tolerance", "layer_min_length", "hair_max_distance"):
        value = getattr(settings, name)
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
            raise InputError(f"contacts.{name} must be a distance >= 0 m, got {value!r}")
    value = settings.samples_per_element
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 2:
        raise InputError(f"contacts.samples_per_element must be an integer >= 2 (an element's two ends), got {value!r}")


def _validate_helices(helices: Helices) -> None:
    offsets = np.asarray(helices.offsets)
    count = len(offsets) - 1
    if offsets.ndim != 1 or count < 0 or offsets[0] != 0 or np.any(np.diff(offsets) < 0):
        raise InputError("the helices' offsets are not a valid CSR offset array")
    elements = int(offsets[-1])
    shapes = {"root": (count, 3), "frame0": (count, 3, 3), "length": (elements,), "omega": (elements, 3)}
    for name, shape in shapes.items():
        value = np.asarray(getattr(helices, name))
        if value.shape != shape:
            raise InputError(f"the helices' {name} has shape {value.shape}, expected {shape}")
        if not np.all(np.isfinite(value)):
            raise InputError(f"the helices' {name} contains NaN or Inf")
    if np.any(np.asarray(helices.length) <= 0):
        raise InputError("the helices have elements of zero or negative length")


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def contact_frames(normal: np.ndarray) -> np.ndarray:
    """Right-handed orthonormal frames (C, 3, 3) with rows (normal, tangent1, tangent2).

    ``tangent1`` is the world axis least aligned with the normal, made
    orthogonal to it (Gram-Schmidt; ties to the lowest axis), and
    ``tangent2 = normal x tangent1``: the same normal always gives the same frame.
    """
    normal = _unit(np.asarray(normal, dtype=np.float64).reshape(-1, 3))
    axis = np.zeros_like(normal)
    axis[np.arange(len(normal)), np.argmin(np.abs(normal), axis=1)] = 1.0
    t1 = _unit(axis - np.einsum("ij,ij->i", axis, normal)[:, None] * normal)
    t2 = np.cross(normal, t1)
    return np.ascontiguousarray(np.stack([normal, t1, t2], axis=1))


def _largest_positive(v: np.ndarray) -> np.ndarray:
    """``v`` with each row's largest-magnitude component (the first of equals) made positive."""
    pick = np.argmax(np.abs(v), axis=1)
    sign = np.where(v[np.arange(len(v)), pick] < 0, -1.0, 1.0)
    return v * sign[:, None]


def _hair_normals(point_a, point_b, tangent_a, tangent_b, dist, flat) -> np.ndarray:
    """unit(xA - xB); where the centerlines cross (distance ~0), the tangents' cross product, oriented."""
    normal = np.empty_like(point_a)
    apart = dist > flat
    normal[apart] = (point_a[apart] - point_b[apart]) / dist[apart, None]
    if np.any(~apart):
        cross = np.cross(tangent_a[~apart], tangent_b[~apart])
        norm = np.linalg.norm(cross, axis=1)
        parallel = norm < 1e-8
        cross[parallel] = contact_frames(tangent_a[~apart][parallel])[:, 1]
        normal[~apart] = _largest_positive(_unit(cross))
    return normal


@jit
def _before(d1, k1, d2, k2):
    """The greedy's order: by distance, ties to the lower index."""
    return d1 < d2 or (d1 == d2 and k1 < k2)


@jit
def _heap_push(key, item, n, d, k):
    """Push ``(d, k)`` on the binary min-heap ``key[:n], item[:n]`` ordered by (key, item); returns n + 1."""
    t = n
    while t > 0:
        parent = (t - 1) // 2
        if _before(key[parent], item[parent], d, k):
            break
        key[t] = key[parent]
        item[t] = item[parent]
        t = parent
    key[t] = d
    item[t] = k
    return n + 1


@jit
def _heap_pop(key, item, n):
    """Remove the top of the heap ``key[:n], item[:n]``; returns n - 1."""
    n -= 1
    d = key[n]
    k = item[n]
    t = 0
    while True:
        c = 2 * t + 1
        if c >= n:
            break
        if c + 1 < n and _before(key[c + 1], item[c + 1], key[c], item[c]):
            c += 1
        if _before(d, k, key[c], item[c]):
            break
        key[t] = key[c]
        item[t] = item[c]
        t = c
    key[t] = d
    item[t] = k
    return n


# With the per-element cap, hair pairs are first searched to this fraction of hair_distance (a dense head's
# elements mostly fill the cap there); an element then holding the cap is searched no farther, since the
# greedy cannot keep any farther pair of it. detect on 100,000 ruby strands (689,361 elements): 167 s with
# every pair searched to 1 mm, 74 s first to 0.25 mm. Also measured: 101 s with the elements that start
# within root_clearance searched to 1 mm whatever they hold, and slower in more steps (0.25 then 0.5 mm:
# 109 s; 0.15, 0.3, 0.6 mm: 120 s).
NARROW = 0.25

# pending pairs refined ahead of the greedy at once, on the worker threads (those it then measures are
# the same pairs, refined from the same start, so the same values; the others are dropped unused)
_CAP_WINDOW = 16384


@jit
def _cap_greedy(ea, eb, sa, sb, dist, refined, known, pending, low, cap, within, s0, length, is_last,
                root_clearance, out, count, key, item, state, window_end, ahead_sa, ahead_sb, ahead_dist, ahead_done):
    """The greedy of :func:`_cap_pairs`, resumable: it stops (and returns the heap, which may have grown) when
    its next candidate is the pending pair ``pending[window_end]``, whose refinement has not been done ahead.
    ``state`` = (heap size, next pending, next known, dropped, unmeasured), updated in place. A pending pair
    ``pending[i]`` within the window takes its refinement from ``ahead_*[i - (window_end - len(ahead))]``
    where ``ahead_done`` says one was made (none where an element was already full: it still is)."""
    n, i, j, dropped, unmeasured = state[0], state[1], state[2], state[3], state[4]
    window_start = window_end - ahead_done.shape[0]
    while True:
        k = -1
        from_heap = False
        if j < known.shape[0]:
            k = known[j]
        if n > 0 and (k < 0 or _before(key[0], item[0], dist[k], k)):
            k = item[0]
            from_heap = True
        if i < pending.shape[0] and (k < 0 or not dist[k] < low[pending[i]]):
            if i >= window_end:
                break  # its refinement is the next window's
            p = pending[i]
            w = i - window_start
            i += 1
            if count[ea[p]] >= cap or count[eb[p]] >= cap:
                unmeasured += 1
                continue
            if not ahead_done[w]:  # (an element was full when the window was refined: it is now too)
                unmeasured += 1
                continue
            sa[p] = ahead_sa[w]
            sb[p] = ahead_sb[w]
            dist[p] = ahead_dist[w]
            refined[p] = True
            a = ea[p]
            b = eb[p]
            if (dist[p] < 0.5 * (within[a] + within[b]) and not (sa[p] == length[a] and is_last[a] == 0)
                    and not (sb[p] == length[b] and is_last[b] == 0)
                    and not (s0[a] + sa[p] < root_clearance and s0[b] + sb[p] < root_clearance)):
                if n == key.shape[0]:
                    key = _grow(key, 2 * n)
                    item = _grow(item, 2 * n)
                n = _heap_push(key, item, n, dist[p], p)
            continue
        if k < 0:
            break
        if from_heap:
            n = _heap_pop(key, item, n)
        else:
            j += 1
        if count[ea[k]] < cap and count[eb[k]] < cap:
            count[ea[k]] += 1
            count[eb[k]] += 1
            out[k] = True
        else:
            dropped += 1
    state[0], state[1], state[2], state[3], state[4] = n, i, j, dropped, unmeasured
    return key, item


def _cap_pairs(ea, eb, sa, sb, dist, refined, known, pending, low, cap, elements, within, s0, length, is_last,
               root_clearance, xs, Fs, omega, out):
    """Greedy, closest first (ties to the lower index): keep a pair while both of its elements hold fewer
    than ``cap`` contacts; marks ``out``.

    The candidates are the refined pairs ``known``, in the order of their distances (ties to the lower
    index), and the pairs not refined yet, ``pending``, in the order of their lower bounds ``low`` (ties in
    any order). These are taken always before any refined candidate farther than their bound, so
    the order is that of the distances. When its turn comes, a pair one of whose elements already holds
    ``cap`` contacts cannot be kept whatever its distance (counts only grow) and is left unmeasured; the
    others are refined (``sa``, ``sb``, ``dist``, ``refined`` updated in place) and are candidates as
    ``keep`` would have marked them: closer than ``within`` (float, or per element: a pair's is the mean of
    its two elements' values, as :func:`_found_pairs` searches them), neither point an element's end that starts
    the next, not both within ``root_clearance`` of the roots. The refinements are made ahead, a window of
    ``_CAP_WINDOW`` pending pairs at a time on the worker threads, for the pairs whose elements are not full
    yet; the greedy itself is sequential.

    Returns ``(dropped, unmeasured)``: candidates not kept, and pairs left unmeasured.
    """
    count = np.zeros(elements, dtype=np.int64)
    within = _per_element(within, elements)
    key = np.empty(1024)
    item = np.empty(1024, dtype=np.int64)
    state = np.zeros(5, dtype=np.int64)
    window_end = 0
    size = max(1, int(_CAP_WINDOW))
    ahead = np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0, dtype=np.bool_)  # the window's refinements
    while True:
        key, item = _cap_greedy(ea, eb, sa, sb, dist, refined, known, pending, low, cap, within, s0, length,
                                is_last, root_clearance, out, count, key, item, state, window_end, *ahead)
        if state[1] >= len(pending):
            break  # done: otherwise the greedy stopped at the window's end, before pending[window_end]
        window = pending[window_end:window_end + size]
        window_end += len(window)
        todo = np.flatnonzero((count[ea[window]] < cap) & (count[eb[window]] < cap))
        pairs = window[todo]
        a, b = ea[pairs], eb[pairs]
        ahead_sa, ahead_sb, ahead_dist = sa[pairs], sb[pairs], np.empty(len(pairs))
        run_chunks(lambda lo, hi: refine_pairs(lo, hi, a, b, ahead_sa, ahead_sb, xs, Fs, omega, length, ahead_dist),
                   len(pairs), 512)
        ahead = (np.zeros(len(window)), np.zeros(len(window)), np.zeros(len(window)),
                 np.zeros(len(window), dtype=np.bool_))
        ahead[0][todo], ahead[1][todo], ahead[2][todo], ahead[3][todo] = ahead_sa, ahead_sb, ahead_dist, True
    return int(state[3]), int(state[4])


def _per_element(value, elements: int) -> np.ndarray:
    """``value`` (a float, or per element) as an (elements,) float64 array."""
    return np.ascontiguousarray(np.broadcast_to(np.asarray(value, dtype=np.float64), (elements,)))


def _keep_closest(pairs: "_Pairs", keep, cap: int, within, s0, length, is_last, root_clearance, xs, Fs,
                  omega) -> tuple[np.ndarray, int, int]:
    """:func:`_cap_pairs` over the candidates ``keep`` (refined pairs) and the pairs not refined yet (refined in
    place where measured). Returns ``(kept, dropped, unmeasured)``, ``kept`` a mask over the pairs."""
    known = np.flatnonzero(keep)
    known = known[float_order(pairs.dist[known])]
    pending = np.flatnonzero(~pairs.refined)
    pending = pending[float_order(pairs.low[pending])]
    out = np.zeros(len(pairs.ea), dtype=bool)
    dropped, unmeasured = _cap_pairs(pairs.ea, pairs.eb, pairs.sa, pairs.sb, pairs.dist, pairs.refined, known,
                                     pending, pairs.low, cap, len(length), within, s0, length, is_last,
                                     root_clearance, xs, Fs, omega, out)
    return out, dropped, unmeasured


def detect_contacts(helices: Helices, body, settings: ContactSettings, progress=None,
                    up: np.ndarray | None = None,
                    refine_iterations: int = REFINE_ITERATIONS, narrow: bool = True,
                    touching: np.ndarray | None = None,
                    farther: np.ndarray | None = None) -> tuple[Contacts, DetectReport]:
    """Declare hair-body and hair-hair contacts of fitted strands.

    Parameters
    ----------
    helices : Helices
        Fitted strands in metres (see :func:`hairinv.fit.fit_groom`).
    body : trimesh.Trimesh, BodyMesh or None
        The body in metres, in the hair's world frame; open, non-manifold
        and multi-piece meshes are fine. None: no hair-body contacts.
    settings : ContactSettings
    progress : callable, optional
        Called with a number of strands after each chunk of strands is
        sampled and tested against the body (the calls sum to the strand
        count); hair-hair detection follows, over all strands at once.
    up : (3,) float64, optional
        The world up axis (against gravity). The wisp rule (``settings.wisp``)
        declares only contacts where a strand rests on one below it, so it
        needs it; without it only ``hair_distance`` applies.
    refine_iterations : int
        Golden-section steps that place a body contact between its element's samples (the default
        places it to 1e-5 of the bracket; a distance near its least is off by the square of that).
    narrow : bool
        Search hair pairs to ``NARROW`` times ``hair_distance`` first, and no farther for the elements that
        then hold ``max_hair_per_element`` contacts. The contacts are the same either way; only the time
        differs. It pays where most elements hold the cap that close: on a head of follow hairs around
        their guides, detect at 100,000 strands took 82 s instead of 179. Where few do, the first search is
        wasted: on ruby short's 1,867 guides, moving, 20 of 12,797 elements held it, and detection took
        0.35 s with it against 0.24 s without (one thread). A simulation chooses from its last detection
        (:meth:`~hairinv.dynamics.tracking.ContactTracker.detect`).
    touching : (S,) bool, optional
        Only the hair-hair pairs with at least one strand among these are searched and declared (the
        per-element cap counts only those); body contacts are unaffected. The wisp rule needs every pair, so
        it must be off. None: every pair.
    farther : (S,) float64, optional
        m, per strand: a hair-hair pair of strands ``a`` and ``b`` is searched and declared within
        ``hair_distance + farther[a] + farther[b]`` (how far the two may move towards each other, in a
        simulation's step). As ``touching``, without the wisp rule; ``narrow`` does not apply. None: zeros.

    Returns
    -------
    contacts : Contacts
        Body contacts first, sorted by (strand, s); then hair-hair contacts
        sorted by (A, B, s along A). The same input gives the same output.
    report : DetectReport
    """
    validate_settings(settings)
    _validate_helices(helices)
    start = time.perf_counter()
    notes: list[str] = []
    root = np.ascontiguousarray(helices.root, dtype=np.float64)
    frame0 = np.ascontiguousarray(helices.frame0, dtype=np.float64)
    offsets = np.ascontiguousarray(helices.offsets, dtype=np.int64)
    omega = np.ascontiguousarray(helices.omega, dtype=np.float64)
    length = np.ascontiguousarray(helices.length, dtype=np.float64)
    count = len(offsets) - 1
    elements = int(offsets[-1])
    n = int(settings.samples_per_element)
    strand_of = np.repeat(np.arange(count, dtype=np.int64), np.diff(offsets))
    is_last = np.zeros(elements, np.int8)
    is_last[offsets[1:][np.diff(offsets) > 0] - 1] = 1
    xs = np.empty((elements, 3))
    Fs = np.empty((elements, 3, 3))
    s0 = np.empty(elements)
    samples = np.empty((elements, n, 3))

    mesh = None
    if settings.body and body is not None:
        mesh = body if isinstance(body, BodyMesh) else BodyMesh.from_mesh(body)
        notes += mesh.notes
    elif settings.body:
        notes.append("no body mesh given: no hair-body contacts")
    elif body is not None:
        notes.append("contacts.body is off: the body mesh is ignored")
    inside = np.zeros(elements, np.int64)
    deepest = np.full(elements, np.inf)
    has = np.zeros(elements, np.int8)
    sigma = np.zeros(elements)
    b_point = np.zeros((elements, 3))
    b_normal = np.zeros((elements, 3))
    b_sd = np.zeros(elements)

    # elements within the widest layer get their closest point too; those beyond body_distance are kept
    # only where the layer rule takes them (the others' contacts are the same as without the rule)
    body_reach = float(max(settings.body_distance, settings.layer_max_gap) if settings.layer else
                       settings.body_distance)

    def strands_chunk(lo: int, hi: int) -> None:
        element_starts(root, frame0, offsets, omega, length, lo, hi, xs, Fs, s0)
        e0, e1 = int(offsets[lo]), int(offsets[hi])
        sample_elements(xs, Fs, omega, length, e0, e1, samples)
        if mesh is not None:
            element_body_contacts(e0, e1, samples, xs, Fs, omega, length, s0, is_last, *mesh.tree,
                                  body_reach, float(settings.root_clearance),
                                  COINCIDENT * float(settings.body_distance), int(refine_iterations), inside, deepest,
                                  has, sigma, b_point, b_normal, b_sd)

    run_chunks(strands_chunk, count, balanced(count, CHUNK), progress)

    layer = np.zeros(elements, dtype=bool)
    layer_gaps = np.zeros(0)
    if mesh is not None and settings.layer:
        layer, layer_gaps = _layer_elements(has, b_sd, sigma, deepest, samples, s0, length, offsets, mesh, settings)
        has = has.astype(bool) & ((b_sd < settings.body_distance) | layer)
    body_idx = np.flatnonzero(has)
    body_part = Contacts(
        np.stack([strand_of[body_idx], np.full(len(body_idx), BODY, np.int64)], axis=1),
        np.stack([s0[body_idx] + sigma[body_idx], np.zeros(len(body_idx))], axis=1),
        b_point[body_idx],
        contact_frames(b_normal[body_idx]),
        np.full(len(body_idx), float(settings.mu_body)),
        b_sd[body_idx],
        np.stack([body_idx, np.full(len(body_idx), BODY, np.int64)], axis=1),
    )
    body_part = body_part.subset(np.lexsort((body_part.s[:, 0], body_part.strand[:, 0])))

    hair_part = Contacts.empty()
    hair_wisp = 0
    wisp_radius = np.zeros(0)
    if settings.hair_hair and elements:
        wisp = settings.wisp and up is not None and settings.hair_max_distance > settings.hair_distance
        if (touching is not None or farther is not None) and wisp:
            raise ValueError("hair pairs touching given strands or searched farther are searched without the wisp rule")
        # per element, where pairs are searched farther: a pair's reach is the mean of its two elements' values
        reach_of = (float(settings.hair_distance) if farther is None else
                    float(settings.hair_distance) + 2.0 * np.asarray(farther, dtype=np.float64)[strand_of])
        pairs, keep, dense, settled = _hair_candidates(
            samples, xs, Fs, omega, length, strand_of, is_last, s0, count, settings, wisp, narrow=narrow,
            touching=None if touching is None else np.ascontiguousarray(np.asarray(touching, dtype=bool)[strand_of]),
            near=reach_of)
        ea, eb, sa, sb, dist = pairs.ea, pairs.eb, pairs.sa, pairs.sb, pairs.dist
        wisp_radius = np.full(count, float(settings.hair_distance))
        by_wisp = np.zeros(len(ea), dtype=bool)
        if wisp:
            wisp_radius = _wisp_radius(ea[keep], eb[keep], dist[keep], strand_of, count, settings, dense)
            beyond = keep & (dist >= settings.hair_distance)
            reach = np.minimum(wisp_radius[strand_of[ea]], wisp_radius[strand_of[eb]])
            within = np.flatnonzero(beyond & (dist < reach))
            pa, pb, _, _ = _pair_points(ea[within], eb[within], sa[within], sb[within], xs, Fs, omega)
            vertical = np.abs((pa - pb) @ np.asarray(up, dtype=np.float64)) / np.maximum(dist[within], 1e-300)
            vertical /= np.linalg.norm(up)
            # resting on the strand below: the two centre lines stacked against gravity (within 60 degrees
            # of the vertical), and within the narrower wisp's width
            by_wisp[within[vertical >= WISP_VERTICAL]] = True
            keep &= (dist < settings.hair_distance) | by_wisp
        near_roots = keep & _near_both_roots(ea, eb, sa, sb, s0, settings.root_clearance)
        # the pairs near both roots are all there unless an element that starts there was settled
        settled_at_roots = settled is not None and bool(np.any(settled & (s0 < settings.root_clearance)))
        if near_roots.any() and not settled_at_roots:
            notes.append(f"hair-hair: {int(near_roots.sum())} contacts between two strands within "
                         f"root_clearance ({1e3 * settings.root_clearance:g} mm) of both roots were not declared")
        elif near_roots.any():
            # such an element's farther pairs were not all searched: count those closer than the first reach
            closer = NARROW * settings.hair_distance
            notes.append(f"hair-hair: {int(np.count_nonzero(near_roots & (dist < closer)))} contacts between two "
                         f"strands closer than {1e3 * closer:g} mm within root_clearance "
                         f"({1e3 * settings.root_clearance:g} mm) of both roots were not declared; nor were farther "
                         f"ones there, not all of which were searched or counted")
        keep &= ~near_roots
        cap = int(settings.max_hair_per_element)
        if cap > 0:
            capped, dropped, unmeasured = _keep_closest(pairs, keep, cap, reach_of, s0, length,
                                                        is_last, float(settings.root_clearance), xs, Fs, omega)
            left = ([f"{counted(dropped, 'farther contact was', 'farther contacts were')} not declared"]
                    if dropped else []) + (
                [f"{counted(unmeasured, 'candidate pair within reach was', 'candidate pairs within reach were')} "
                 f"not measured (an element of each already held "
                 f"{'a closer contact' if cap == 1 else f'{cap} closer contacts'})"] if unmeasured else [])
            if settled is not None:  # the counts above then cover only the pairs searched
                held = f"held {counted(cap, 'contact')} within {1e3 * NARROW * settings.hair_distance:g} mm"
                left = [f"{counted(int(np.count_nonzero(settled)), f'element that {held} was', f'elements that {held} were')}"
                        " not searched farther"] + ([f"of the pairs searched, {' and '.join(left)}"] if left else [])
            if left:
                kept = "the closest contact" if cap == 1 else f"the {cap} closest contacts"
                notes.append(f"hair-hair: kept {kept} per element (contacts.max_hair_per_element); " + "; ".join(left))
            keep = capped
        hair_wisp = int(np.count_nonzero(by_wisp & keep))
        ea, eb, sa, sb = ea[keep], eb[keep], sa[keep], sb[keep]
        pa, pb, ta, tb = _pair_points(ea, eb, sa, sb, xs, Fs, omega)
        normal = _hair_normals(pa, pb, ta, tb, dist[keep], COINCIDENT * float(settings.hair_distance))
        hair_part = Contacts(
            np.stack([strand_of[ea], strand_of[eb]], axis=1),
            np.stack([s0[ea] + sa, s0[eb] + sb], axis=1),
            pa,
            contact_frames(normal),
            np.full(len(ea), float(settings.mu_hair)),
            dist[keep],
            np.stack([ea, eb], axis=1),
        )
        hair_part = hair_part.subset(np.lexsort((hair_part.s[:, 1], hair_part.s[:, 0], hair_part.strand[:, 1],
                                                 hair_part.strand[:, 0])))

    contacts = Contacts(*(np.ascontiguousarray(np.concatenate([a, b])) for a, b in zip(
        (body_part.strand, body_part.s, body_part.point, body_part.frame, body_part.mu, body_part.gap,
         body_part.element),
        (hair_part.strand, hair_part.s, hair_part.point, hair_part.frame, hair_part.mu, hair_part.gap,
         hair_part.element))))
    inside_strands = np.bincount(strand_of, weights=inside, minlength=count) > 0 if elements else np.zeros(0, bool)
    points_inside = int(inside.sum())
    report = DetectReport(
        n_body=body_part.n_contacts,
        n_hair=hair_part.n_contacts,
        strands_touching_body=int(len(np.unique(body_part.strand[:, 0]))),
        strands_inside_body=int(inside_strands.sum()),
        points_inside_body=points_inside,
        seconds=time.perf_counter() - start,
        notes=notes,
        deepest_inside=float(-deepest.min()) if points_inside else 0.0,
        body_layer=int(np.count_nonzero(layer & (b_sd >= settings.body_distance) & has.astype(bool))),
        layer_gaps=layer_gaps,
        layer_strands=int(len(np.unique(strand_of[layer]))) if layer.any() else 0,
        hair_wisp=hair_wisp,
        wisp_radius=wisp_radius,
    )
    return contacts, report


#: a wisp contact joins strands stacked against gravity: |unit(xA - xB) . up| at least cos 60 degrees
WISP_VERTICAL = 0.5
#: a wisp is a little wider than the spacing of its strands, so that neighbouring wisps touch where
#: their centre lines are that spacing apart
WISP_WIDTH = 1.25


def _layer_elements(has: np.ndarray, sd: np.ndarray, sigma: np.ndarray, least: np.ndarray, samples: np.ndarray,
                    s0: np.ndarray, length: np.ndarray, offsets: np.ndarray, mesh: BodyMesh,
                    settings: ContactSettings) -> tuple[np.ndarray, np.ndarray]:
    """The elements whose body contact the layer rule declares, (E,) bool, and the gaps of the runs
    that declared any (m).

    ``sd`` and ``sigma`` are the signed distance and the arc length along its element of each element's
    contact point (where ``has``), ``least`` the least
    signed distance of its own samples (inf where none came within reach). The samples of the elements
    within ``layer_max_gap`` are measured; along each strand, a run is a maximal stretch of consecutive
    samples within ``layer_max_gap`` (past ``root_clearance``). Its gap ``g`` is the median of their
    distances (inside counted as 0). The strand lies on the layer where its samples stay within
    ``g + layer_tolerance`` over at least ``layer_min_length`` of arc: a strand passing the body comes
    that close over a short stretch only. The elements beyond ``body_distance`` whose contact point lies
    in such a stretch, at most ``g + layer_tolerance`` from the body, are declared; where the distance
    grows past it, the strand is leaving the body, and nothing more is.
    """
    E, n = samples.shape[0], samples.shape[1]
    has = has.astype(bool)
    out = np.zeros(E, dtype=bool)
    gaps: list[float] = []
    near = np.flatnonzero(np.minimum(np.where(has, sd, np.inf), least) <= settings.layer_max_gap)
    if not len(near):
        return out, np.zeros(0)
    dist = mesh.closest(np.ascontiguousarray(samples[near].reshape(-1, 3)))[0].reshape(-1, n)
    arc = s0[near, None] + length[near, None] * np.minimum(np.arange(n) / (n - 1), 1.0)[None, :]
    strand_of = np.searchsorted(offsets, near, side="right") - 1
    gaps = np.empty(len(near) * n)
    count = _layer_runs(near, n, np.ascontiguousarray(dist).ravel(), np.ascontiguousarray(arc).ravel(), strand_of,
                        has, sd, sigma, s0,
                        length, float(settings.root_clearance), float(settings.layer_max_gap),
                        float(settings.layer_tolerance), float(settings.layer_min_length),
                        float(settings.body_distance), out, gaps)
    return out, gaps[:count].copy()


@jit
def _median_sorted(v):
    """The median of sorted ``v``: the middle value, or the mean of the two middle ones (as numpy's)."""
    m = v.shape[0]
    return (v[(m - 1) // 2] + v[m // 2]) / 2.0


@jit
def _layer_runs(near, n, dist, arc, strand_of, has, sd, sigma, s0, length, root_clearance, max_gap, tolerance,
                min_length, body_distance, out, gaps):
    """:func:`_layer_elements` along each strand: ``near`` (sorted) holds the elements measured, ``dist`` and
    ``arc`` (len(near) * n,) their samples' distances to the body and arc lengths. Marks ``out`` and writes the
    gap of each run that declared an element into ``gaps``, strand by strand and run by run; returns their count."""
    found = 0
    first = 0
    while first < near.shape[0]:
        last = first
        while last < near.shape[0] and strand_of[last] == strand_of[first]:
            last += 1
        # the strand's samples, flattened: index i is sample i % n of near element first + i // n
        a = first * n
        b = last * n
        i = a
        while i < b:
            # a run: consecutive valid samples on consecutive elements
            while i < b and not (arc[i] >= root_clearance and dist[i] <= max_gap):
                i += 1
            if i >= b:
                break
            j = i + 1
            while j < b and (arc[j] >= root_clearance and dist[j] <= max_gap) and not (
                    j % n == 0 and near[j // n] - near[j // n - 1] > 1):
                j += 1
            values = np.empty(j - i)
            for t in range(i, j):
                values[t - i] = max(dist[t], 0.0)
            values.sort()
            gap = _median_sorted(values)
            declared = False
            t = i
            while t < j:
                # a stretch of consecutive samples within the band
                if dist[t] > gap + tolerance:
                    t += 1
                    continue
                u = t
                lo = arc[t]
                hi = arc[t]
                while u < j and dist[u] <= gap + tolerance:
                    lo = min(lo, arc[u])
                    hi = max(hi, arc[u])
                    u += 1
                if hi - lo >= min_length:
                    previous = -1
                    for w in range(t, u):
                        e = near[w // n]
                        if e == previous:
                            continue
                        previous = e
                        where = s0[e] + sigma[e]  # the contact point, within the stretch (up to a sample)
                        step = length[e] / (n - 1)
                        if has[e] and body_distance <= sd[e] <= gap + tolerance and lo - step <= where <= hi + step:
                            out[e] = True
                            declared = True
                t = u
            if declared:
                gaps[found] = gap
                found += 1
            i = j
        first = last
    return found


@dataclass
class _Pairs:
    """Candidate element pairs of the hair-hair search, sorted by (element A, element B).

    ``sa``, ``sb`` (m) start as the closest polyline points and ``dist`` (m) is NaN until a pair is
    refined on the exact centre lines (``refined``); ``low`` (m) bounds the refined distance from below
    before (the polylines' distance less both elements' sag). A pair is refined where something depends on
    its distance: with the per-element cap, the pairs whose two elements both hold fewer than the cap
    when their turn comes may be declared, the others cannot, whatever their distance.
    """

    ea: np.ndarray
    eb: np.ndarray
    sa: np.ndarray
    sb: np.ndarray
    dist: np.ndarray
    low: np.ndarray
    refined: np.ndarray

    def copy(self) -> "_Pairs":
        return _Pairs(*(getattr(self, f.name).copy() for f in dataclasses.fields(self)))


def _found_pairs(samples, omega, length, strand_of, reach, wide=None, among=None) -> _Pairs:
    """Element pairs of different strands whose centre lines may come within ``reach`` (float, or per element:
    a pair is searched to the mean of its two elements' values), not yet refined. ``among`` (sorted element
    indices): only the pairs of two of these elements (each pair as the search of all elements gives it:
    the same closest polyline points, since those are the pair's own)."""
    # the samples and the centre line's points are rounded apart by some ulps of the coordinates: a margin of
    # many times that keeps the bound a bound where the arcs are straight (no sag) and distances tie. With
    # the gap's own slack (nearly parallel segments, hair_pairs), the search goes that much farther, so a
    # pair whose centre lines come within reach is found even where its polyline gap is a little past it
    rounding = 64.0 * np.finfo(np.float64).eps * float(np.abs(samples).max(initial=0.0)) + 1e-12 * float(np.max(reach))
    slack = polyline_slack(length, samples.shape[1])
    reach = np.asarray(reach, dtype=np.float64) + 2.0 * slack + rounding  # (a pair: the mean of its two)
    if among is None:
        ea, eb, sa, sb, gap, _close = hair_pairs(samples, omega, length, strand_of, reach, wide)
    else:
        ea, eb, sa, sb, gap, _close = hair_pairs(samples[among], omega[among], length[among], strand_of[among],
                                                 reach[among], None if wide is None else wide[among])
        ea, eb = among[ea], among[eb]
    stray = element_sag(omega, length, samples.shape[1]) + slack
    low = np.maximum(gap - stray[ea] - stray[eb] - rounding, 0.0)
    return _Pairs(ea, eb, sa, sb, np.full(len(ea), np.nan), low, np.zeros(len(ea), dtype=bool))


def _union(parts: list[_Pairs], elements: int) -> _Pairs:
    """The pairs of all ``parts``, each once (its row in the first part that has it), sorted by (A, B)."""
    ea = np.concatenate([p.ea for p in parts])
    key = ea * elements + np.concatenate([p.eb for p in parts])
    del ea
    order = stable_order(key)
    key = key[order]
    rows = order[np.concatenate([[True], key[1:] != key[:-1]])] if len(key) else order
    del key, order
    return _Pairs(*(np.concatenate([getattr(p, f.name) for p in parts])[rows] for f in dataclasses.fields(_Pairs)))


def _refine(pairs: _Pairs, index, xs, Fs, omega, length) -> None:
    """Refine the pairs ``index`` (those not refined yet) on the exact centre lines, in place."""
    index = np.asarray(index)
    if index.dtype == bool:
        index = np.flatnonzero(index)
    index = index[~pairs.refined[index]]
    if not len(index):
        return
    ea, eb = pairs.ea[index], pairs.eb[index]
    sa, sb = pairs.sa[index], pairs.sb[index]
    dist = np.empty(len(index))
    run_chunks(lambda lo, hi: refine_pairs(lo, hi, ea, eb, sa, sb, xs, Fs, omega, length, dist), len(index), 4096)
    pairs.sa[index], pairs.sb[index], pairs.dist[index] = sa, sb, dist
    pairs.refined[index] = True


def _pair_points(ea, eb, sa, sb, xs, Fs, omega) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Centre-line points and tangents ``(pa, pb, ta, tb)``, (P, 3) each, of element pairs at their arc lengths."""
    out = tuple(np.empty((len(ea), 3)) for _ in range(4))
    run_chunks(lambda lo, hi: pair_points(lo, hi, ea, eb, sa, sb, xs, Fs, omega, *out), len(ea), 4096)
    return out


def _near_both_roots(ea, eb, sa, sb, s0, root_clearance: float) -> np.ndarray:
    """The pairs whose points both lie within ``root_clearance`` of their clamped roots: no coordinate moves either
    point, and such a contact would only make W singular (its forces fixed by gamma alone): never declared."""
    return (s0[ea] + sa < root_clearance) & (s0[eb] + sb < root_clearance)


def _kept(ea, eb, sa, sb, dist, within, length, is_last) -> np.ndarray:
    """The pairs closer than ``within`` (float, or per element: a pair's is the mean of its two elements'
    values) whose closest points are not an element's end that starts the next."""
    if np.ndim(within):
        within = 0.5 * (within[ea] + within[eb])
    keep = dist < within
    keep &= ~((sa == length[ea]) & (is_last[ea] == 0))
    keep &= ~((sb == length[eb]) & (is_last[eb] == 0))
    return keep


def _hair_candidates(samples, xs, Fs, omega, length, strand_of, is_last, s0, count: int, settings: ContactSettings,
                     wisp: bool, two_pass: bool = True, lazy: bool = True, narrow: bool = True,
                     touching: np.ndarray | None = None, near=None) -> tuple[_Pairs, np.ndarray, np.ndarray | None,
                                                                                  np.ndarray | None]:
    """The element pairs the hair-hair rules choose from, within ``hair_distance``, and with the wisp rule
    within ``hair_max_distance`` wherever a wisp may be that wide.

    Returns ``(pairs, keep, dense, settled)``: ``keep`` marks the refined pairs closer than their search's distance
    whose closest points are not an element's end that starts the next element (whose pair with the same
    other element is at least as close and declares its own); ``dense`` (per strand, or None after one
    search) the strands whose wisp radius is ``hair_distance``; ``settled`` (per element, or None) the elements
    searched no farther than the first reach (``narrow``).

    A wisp contact joins two strands only within the narrower of their wisp radii, and a strand whose
    elements mostly have a neighbour within ``hair_distance / WISP_WIDTH`` has the radius ``hair_distance``
    (:func:`_wisp_radius`). So the wide search is needed only for pairs of the other strands (sparse guides):
    a first search within ``hair_distance`` finds the dense strands, and the second searches a pair to
    ``hair_max_distance`` only where one element is on another strand (``2 hair_max_distance - hair_distance``
    between two of them, ``hair_distance`` between two dense ones). The pairs it keeps, the radii and so
    the contacts are those of one search to ``hair_max_distance`` for all (``two_pass=False``); a full head
    of follow hairs, where nearly every strand is dense, is searched to 1 mm instead of 3. The second search
    skips the pairs of two dense strands: the first has found them at the same reach.

    ``lazy`` (with the per-element cap): the pairs of two dense strands are refined only where their
    distance is needed: to find the dense strands (each element's pair of least lower bound first, then
    the pairs that may still bring an element within ``hair_distance / WISP_WIDTH``), where both points may
    lie within ``root_clearance`` of the roots, and in :func:`_cap_pairs` where both elements still hold
    fewer contacts than the cap. Every other pair is refined at once; the contacts are the same.

    ``touching`` (E,) bool, without the wisp rule: only the pairs with an element among these.

    ``near`` (float, or (E,) per element without the wisp rule: a pair's is the mean of its two elements'), the
    reach instead of ``hair_distance``; per element, ``narrow`` does not apply (its first search to a fraction of
    the reach holds the closest pairs of an element only where every pair's reach is the same).

    ``narrow`` (with ``lazy``): the search within ``hair_distance`` is made first to ``NARROW`` times it,
    and an element that then holds the cap (:func:`_held_within`) is searched no farther. The pairs left out
    could not be kept, so the contacts and wisp radii are the same; ``settled`` marks the elements left out
    that way (None where none was), and where one of them starts within
    ``root_clearance`` of its root, the note on pairs near both roots counts only those closer than the first
    search's reach (all of which it found).
    """
    near = float(settings.hair_distance) if near is None else near
    narrow = narrow and not np.ndim(near)
    cap = int(settings.max_hair_per_element)
    lazy = lazy and cap > 0 and (two_pass or not wisp)
    rc = float(settings.root_clearance)

    def kept(pairs: _Pairs, within) -> np.ndarray:
        return pairs.refined & _kept(pairs.ea, pairs.eb, pairs.sa, pairs.sb, pairs.dist, within, length, is_last)

    def search(reach, within, wide=None, on_demand=False, among=None) -> _Pairs:
        pairs = _found_pairs(samples, omega, length, strand_of, reach, wide, among)
        if not on_demand:
            _refine(pairs, np.ones(len(pairs.ea), dtype=bool), xs, Fs, omega, length)
        else:
            # both points may lie within root_clearance of their roots only where both elements start there
            _refine(pairs, (s0[pairs.ea] < rc) & (s0[pairs.eb] < rc), xs, Fs, omega, length)
        return pairs

    def search_near() -> tuple[_Pairs, np.ndarray | None]:
        if not (lazy and narrow):
            return search(near, near, wide=touching, on_demand=lazy), None
        inner = search(NARROW * near, NARROW * near, wide=touching, on_demand=True)
        settled = _held_within(inner, NARROW * near, cap, s0, length, is_last, rc, xs, Fs, omega) >= cap
        if not settled.any():
            return search(near, near, wide=touching, on_demand=True), None
        # only the pairs of two elements the cap may still take. A settled element has a neighbour within
        # hair_distance / WISP_WIDTH (a contact it holds), so it still counts towards a dense strand; an element
        # whose neighbour that close is settled may no longer, but a strand then taken as sparse gets every pair
        # from the second search, and its radius comes out as hair_distance, a dense strand's, all the same
        pairs = _union([inner, search(near, near, wide=touching, on_demand=True, among=np.flatnonzero(~settled))],
                       len(length))
        return pairs, settled

    if not wisp:
        first, settled = search_near()
        return first, kept(first, near), None, settled
    far = float(settings.hair_max_distance)
    if not two_pass:
        first = search(far, far)
        return first, kept(first, far), None, None
    first, settled = search_near()
    tight = near / WISP_WIDTH
    if lazy:
        _refine_for_tight(first, tight, near, kept, xs, Fs, omega, length)
    keep = kept(first, near)
    close = np.zeros(len(strand_of), dtype=bool)
    within = keep & (first.dist <= tight)
    close[first.ea[within]] = True
    close[first.eb[within]] = True
    per_strand = np.bincount(strand_of, minlength=count)
    # more than half of a strand's elements (so of those with any neighbour within hair_max_distance) have one
    # within hair_distance / WISP_WIDTH: the median, times WISP_WIDTH, is at most hair_distance
    dense = np.bincount(strand_of, weights=close, minlength=count) >= per_strand // 2 + 1
    if dense.all():
        return first, keep, dense, settled
    sparse = ~dense[strand_of]
    second = search(np.where(sparse, 2.0 * far - near, near), far, sparse)
    # the pairs of two dense strands are the first search's (the same reach), the others the second's,
    # merged in the order of one search
    both_dense = np.flatnonzero(~sparse[first.ea] & ~sparse[first.eb])
    key = np.concatenate([first.ea[both_dense], second.ea]) * len(strand_of) + np.concatenate(
        [first.eb[both_dense], second.eb])
    where = np.empty(len(key), dtype=np.int64)  # the merged position of each row, first's rows then second's
    where[stable_order(key)] = np.arange(len(key))
    del key
    fields = {}
    for f in dataclasses.fields(_Pairs):
        a, b = getattr(first, f.name), getattr(second, f.name)
        out = np.empty(len(where), dtype=a.dtype)
        out[where[:len(both_dense)]] = a[both_dense]
        out[where[len(both_dense):]] = b
        fields[f.name] = out
        setattr(first, f.name, None)  # one field at a time: the search's own arrays go as the merged ones come
    merged = _Pairs(**fields)
    return merged, kept(merged, far), dense, settled


def _held_within(pairs: _Pairs, within, cap: int, s0, length, is_last, root_clearance, xs, Fs,
                 omega) -> np.ndarray:
    """Per element, the contacts the greedy cap keeps when only pairs closer than ``within`` are candidates.

    ``pairs`` must hold every pair that close (a search to ``within``). The greedy takes candidates closest
    first, so it takes these first in any search farther, and in the same order: an element that holds the
    cap after them holds it at the end, and none of its farther pairs can be kept whatever their distance.
    """
    keep = pairs.refined & _kept(pairs.ea, pairs.eb, pairs.sa, pairs.sb, pairs.dist, within, length, is_last)
    keep &= ~_near_both_roots(pairs.ea, pairs.eb, pairs.sa, pairs.sb, s0, root_clearance)
    out, _, _ = _keep_closest(pairs, keep, cap, within, s0, length, is_last, root_clearance, xs, Fs, omega)
    return (np.bincount(pairs.ea[out], minlength=len(length)) + np.bincount(pairs.eb[out], minlength=len(length)))


@jit
def _least_bound_pair(ea, eb, low, least):
    """``least[e]``: the pair of element ``e`` with the least lower bound (the first of equals), -1 if none."""
    for p in range(ea.shape[0]):
        for e in (ea[p], eb[p]):
            if least[e] < 0 or low[p] < low[least[e]]:
                least[e] = p


def _refine_for_tight(pairs: _Pairs, tight: float, near: float, kept, xs, Fs, omega, length) -> None:
    """Refine enough pairs to know, of every element, whether a kept pair brings it within ``tight``.

    First each element's pair of least lower bound (on a dense head nearly always close enough); then,
    for the elements still without one, every pair whose lower bound is within ``tight``: a pair whose
    lower bound is beyond it cannot bring either element that close.
    """
    if not len(pairs.ea):
        return
    elements = len(length)
    least = np.full(elements, -1, dtype=np.int64)
    _least_bound_pair(pairs.ea, pairs.eb, pairs.low, least)
    _refine(pairs, np.unique(least[least >= 0]), xs, Fs, omega, length)
    within = kept(pairs, near) & (pairs.dist <= tight)
    found = np.zeros(elements, dtype=bool)
    found[pairs.ea[within]] = True
    found[pairs.eb[within]] = True
    _refine(pairs, (pairs.low <= tight) & ~(found[pairs.ea] & found[pairs.eb]), xs, Fs, omega, length)


def _wisp_radius(ea: np.ndarray, eb: np.ndarray, dist: np.ndarray, strand_of: np.ndarray, count: int,
                 settings: ContactSettings, dense: np.ndarray | None = None) -> np.ndarray:
    """Per strand, the distance within which its centre line rests on another strand's, (S,), m.

    A guide strand's centre line stands for a wisp as wide as the spacing of the strands around it:
    the median, over its elements, of the distance to the nearest element of another strand (within
    ``hair_max_distance``). The contact distance is ``WISP_WIDTH`` times that spacing (so that neighbours
    that far apart touch), clamped to ``[hair_distance, hair_max_distance]``; a strand with no neighbour
    in reach keeps ``hair_distance``. ``dense`` (per strand): strands more than half of whose elements have a
    neighbour within ``hair_distance / WISP_WIDTH``, so whose radius is ``hair_distance`` by the rule above;
    given, it is set without their pairs (which :func:`_hair_candidates` may not all have measured).
    """
    n_elements = len(strand_of)
    nearest = np.full(n_elements, np.inf)
    np.minimum.at(nearest, ea, dist)
    np.minimum.at(nearest, eb, dist)
    radius = np.full(count, float(settings.hair_distance))
    finite = np.isfinite(nearest)
    if finite.any():
        # each strand's median (the mean of the two middle values for an even count, as numpy's)
        owners = strand_of[finite]
        order = np.lexsort((nearest[finite], owners))
        values = nearest[finite][order]
        bounds = np.searchsorted(owners[order], np.arange(count + 1))
        sizes = np.diff(bounds)
        some = np.flatnonzero(sizes)
        low = values[bounds[some] + (sizes[some] - 1) // 2]
        high = values[bounds[some] + sizes[some] // 2]
        radius[some] = (low + high) / 2.0
    radius = np.clip(WISP_WIDTH * radius, settings.hair_distance, settings.hair_max_distance)
    if dense is not None:
        radius[dense] = settings.hair_distance
    return radius
