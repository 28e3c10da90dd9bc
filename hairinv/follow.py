"""Render strands that follow simulated guides (docs/export.md, "The render groom").

When the simulated strands are guides of a larger groom (``--guides N``), every strand of that groom, the
render groom, is carried by its guides:

- **Binding**, in the pose the groom was read in (the guides' fitted ``/helices``, the render strands' input
  polylines). Each render vertex has a normalized arc length ``u`` (chord length from the root over the
  strand's), and its guide point is the guide's point at the same normalized arc length, ``x_g(u L_g)``.
  Each render strand takes the :data:`GUIDES_PER_STRAND` guides that lie nearest along it (mean distance
  from its vertices to their guide points) among the :data:`CANDIDATES` whose roots are nearest its root
  (``by="curve"``, Unreal's "parametric" weighting; ``by="root"``: the nearest roots, Unreal's "root"),
  weighted by Franke and Nielson's modified Shepard kernel (:func:`shepard_weights`). Each vertex keeps its
  offset from each guide point in that guide's root frame (``at_root``; or in its material frame there).
- **Following**: in any other pose of the guides (a frame of ``/frames``, the rest shape), the vertex is the
  weighted sum of where each guide carries it, ``sum_g w_g (x_g'(u L_g) + F_g'^T F_g (x - x_g(u L_g)))``, with
  ``F_g``, ``F_g'`` the guide's root frames (rows) in the two poses: the guide's own deformation, moved
  over to the render strand, with the offset turned as the guide's root turns (with the skin).

In the binding pose this gives the render strands back exactly; under a rigid motion of every guide it moves
them rigidly with it. On a deforming body (a shot, ``/frames/body_vertices``) each render root is also bound
to the skin (:class:`hairinv.dynamics.skin.Binding`) and the strand is moved with its root so that the root
stays where its triangle carries it.

Why these choices (bench/follow_bench.py, docs/benchmarks.md "Render strands following guides"): against
simulating the render strands themselves, choosing the guides along the strand rather than by root alone,
and turning the offsets with the guide's root rather than its material frame, had the smaller error on the
sample grooms (a material frame turns a centimetre offset by the guide's own swing, which a strand a
centimetre away does not share); 3 guides did better than 1.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import stages
from .config import ImportSettings
from .errors import InputError
from .groom import Groom, find_recorded, load_groom
from .model import Helices
from .rod.follow import bind_offsets, curve_distances, follow_points, guide_chains

__all__ = ["CANDIDATES", "GUIDES_PER_STRAND", "SAME_ROOT", "Follow", "Following", "SkinRoots", "guide_weights",
           "nearest_roots", "normalized_arc_length", "render_groom", "shepard_weights", "subset_helices"]

#: Guides each render strand follows: Unreal's interpolation takes up to 3 closest guides (its Alembic
#: schema's ``groom_closest_guides``), and 3 roots around a point span the scalp's surface there.
GUIDES_PER_STRAND = 3
#: Guides whose roots are nearest a render strand's, among which the ``GUIDES_PER_STRAND`` that lie nearest
#: along the strand are chosen (``by = "curve"``).
CANDIDATES = 12
#: m: a render root this close to a guide's root is that guide's (it follows it alone, weight 1). Roots of
#: the same strand read from the same file agree to the bit.
SAME_ROOT = 1e-9
#: The render roots' median distance to their nearest guide's root, over the guides' own median spacing,
#: beyond which the render groom is refused: its strands grow elsewhere (another groom, other units or axes).
FAR_FROM_GUIDES = 5.0


def shepard_weights(distance: np.ndarray, k: int = GUIDES_PER_STRAND) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` nearest of each row's candidates and their weights, from their distances ``distance`` (R, M).

    The weights are Franke and Nielson's modified Shepard kernel (1980), ``w_j = ((D - d_j)_+ / (D d_j))^2``
    normalised to sum to 1, with ``d_j`` the candidate's distance and ``D`` the distance of the ``(k + 1)``-th
    nearest: a candidate's weight falls to 0 as it stops being among the ``k`` nearest, so the weights are
    continuous in the distances (plain inverse distances over the ``k`` nearest jump where the nearest set
    changes). With ``k`` candidates or fewer, ``D`` is infinite (``w_j = 1 / d_j^2``). A candidate within
    :data:`SAME_ROOT` takes the whole weight; where the ``k + 1`` nearest are all equally far, the ``k`` share
    it equally.

    Returns
    -------
    chosen : (R, min(k, M)) int64, column indices into ``distance``, nearest first
    weight : (R, min(k, M)) float64, summing to 1 over each row
    """
    distance = np.asarray(distance, dtype=np.float64)
    rows, count = distance.shape
    k = min(int(k), count)
    order = np.argsort(distance, axis=1, kind="stable")
    chosen = np.ascontiguousarray(order[:, :k])
    near = np.take_along_axis(distance, chosen, axis=1)
    safe = np.maximum(near, SAME_ROOT)
    if count > k:
        reach = np.take_along_axis(distance, order[:, k:k + 1], axis=1)
        weight = (np.maximum(reach - near, 0.0) / (reach * safe)) ** 2
    else:
        weight = 1.0 / safe ** 2
    weight[weight.sum(axis=1) <= 0.0] = 1.0  # the k + 1 nearest all at one distance
    same = near[:, 0] <= SAME_ROOT
    weight[same] = 0.0
    weight[same, 0] = 1.0
    weight /= weight.sum(axis=1, keepdims=True)
    return chosen.astype(np.int64), np.ascontiguousarray(weight)


def nearest_roots(render_roots: np.ndarray, guide_roots: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``count`` guide roots nearest each render root (fewer if there are fewer guides): their distances
    (R, m) m and indices (R, m) int64, nearest first."""
    from scipy.spatial import cKDTree

    render_roots = np.asarray(render_roots, dtype=np.float64).reshape(-1, 3)
    guide_roots = np.asarray(guide_roots, dtype=np.float64).reshape(-1, 3)
    if len(guide_roots) == 0:
        raise InputError("there is no guide to follow")
    count = min(int(count), len(guide_roots))
    dist, index = cKDTree(guide_roots).query(render_roots, count)
    return (np.asarray(dist, dtype=np.float64).reshape(len(render_roots), count),
            np.asarray(index, dtype=np.int64).reshape(len(render_roots), count))


def guide_weights(render_roots: np.ndarray, guide_roots: np.ndarray,
                  k: int = GUIDES_PER_STRAND) -> tuple[np.ndarray, np.ndarray]:
    """Each render root's ``k`` nearest guide roots and their weights (:func:`shepard_weights` of the root
    distances).

    Returns
    -------
    guide : (R, min(k, G)) int64, the guides nearest first
    weight : (R, min(k, G)) float64, summing to 1 over each row
    """
    dist, index = nearest_roots(render_roots, guide_roots, k + 1)
    chosen, weight = shepard_weights(dist, k)
    return np.ascontiguousarray(np.take_along_axis(index, chosen, axis=1)), weight


def normalized_arc_length(points: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """(P,) each vertex's chord length from its strand's root over the strand's: 0 at the root, 1 at the tip
    (the vertex placement of docs/export.md)."""
    chord = np.linalg.norm(np.diff(points, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(chord)])
    start = cum[offsets[:-1]]
    end = cum[offsets[1:] - 1]
    span = np.where(end > start, end - start, 1.0)
    per = np.repeat(np.arange(len(offsets) - 1), np.diff(offsets))
    return (cum - start[per]) / span[per]


def _f64(a) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64)


@dataclass(frozen=True, eq=False)
class Follow:
    """Render strands bound to guides (module docstring).

    Attributes
    ----------
    offsets : (R + 1,) int64, CSR offsets of the render vertices
    u : (P,) float64, each render vertex's normalized arc length
    guide : (R, K) int64, each render strand's guides (indices of the guide strands), nearest first
    weight : (R, K) float64, their weights, summing to 1 over a strand
    local : (P, K, 3) float64, m, each vertex's offset in each of its guides' frames
    guide_offsets : (G + 1,) int64, the guides' element offsets
    guide_length : (E,) float64, m, the guides' element lengths
    """

    offsets: np.ndarray
    u: np.ndarray
    guide: np.ndarray
    weight: np.ndarray
    local: np.ndarray
    guide_offsets: np.ndarray
    guide_length: np.ndarray
    at_root: bool = True

    @classmethod
    def bind(cls, points: np.ndarray, offsets: np.ndarray, guides: Helices, k: int = GUIDES_PER_STRAND,
             by: str = "curve", at_root: bool = True) -> "Follow":
        """Bind the render strands ``points`` (P, 3) m, ``offsets`` (R + 1,), to the guides ``guides`` in the
        same pose (the groom as read: the guides' fitted helices, the render strands' input polylines).

        ``by``: ``"root"``, the ``k`` guides whose roots are nearest; ``"curve"``, of the :data:`CANDIDATES`
        nearest by root, the ``k`` nearest along the strand (mean distance between points at the same
        normalized arc length), which keeps a strand with the guides lying beside it rather than those across
        a parting. ``at_root``: the offsets turn with each guide's root frame (True) or with its material
        frame at the point they are measured from (False).
        """
        if by not in ("root", "curve"):
            raise ValueError(f"by is 'root' or 'curve', not {by!r}")
        points = _f64(points).reshape(-1, 3)
        offsets = np.ascontiguousarray(offsets, dtype=np.int64)
        u = np.ascontiguousarray(normalized_arc_length(points, offsets))
        g_offsets = np.ascontiguousarray(guides.offsets, dtype=np.int64)
        g_length = _f64(guides.length)
        g_omega = _f64(guides.omega)
        xs, Fs, starts = _chains(guides.root, guides.frame0, g_offsets, g_omega, g_length)
        roots = points[offsets[:-1]]
        if by == "root":
            guide, weight = guide_weights(roots, guides.root, k)
        else:
            root_dist, candidate = nearest_roots(roots, guides.root, max(CANDIDATES, k + 1))
            along = np.empty(candidate.shape)
            curve_distances(xs, Fs, starts, g_offsets, g_omega, offsets, u, points, candidate, along)
            along[root_dist <= SAME_ROOT] = 0.0  # a render strand that is a guide follows it alone
            chosen, weight = shepard_weights(along, k)
            guide = np.ascontiguousarray(np.take_along_axis(candidate, chosen, axis=1))
        local = np.empty((len(points), guide.shape[1], 3))
        bind_offsets(xs, Fs, starts, g_offsets, g_omega, offsets, u, points, guide, bool(at_root), local)
        return cls(offsets, u, guide, weight, local, g_offsets, g_length, bool(at_root))

    @property
    def n_strands(self) -> int:
        return int(len(self.offsets) - 1)

    def points(self, root: np.ndarray, frame0: np.ndarray, omega: np.ndarray) -> np.ndarray:
        """(P, 3) m: the render vertices carried by the guides in the pose ``root`` (G, 3), ``frame0``
        (G, 3, 3), ``omega`` (E, 3) (the guides' element lengths do not change)."""
        omega = _f64(omega)
        xs, Fs, starts = _chains(root, frame0, self.guide_offsets, omega, self.guide_length)
        out = np.empty((len(self.u), 3))
        follow_points(xs, Fs, starts, self.guide_offsets, omega, self.offsets, self.u, self.guide, self.weight,
                      self.at_root, self.local, out)
        return out


def _chains(root, frame0, offsets, omega, length):
    rows = len(length) + len(offsets) - 1
    xs, Fs, starts = np.empty((rows, 3)), np.empty((rows, 3, 3)), np.empty(rows)
    guide_chains(_f64(root), _f64(frame0), offsets, _f64(omega), length, xs, Fs, starts)
    return xs, Fs, starts


def subset_helices(helices: Helices, strands: np.ndarray) -> tuple[Helices, np.ndarray]:
    """The strands ``strands`` of ``helices`` as helices of their own, and their element rows in ``helices``."""
    strands = np.asarray(strands, dtype=np.int64)
    counts = np.diff(helices.offsets)[strands]
    rows = (np.concatenate([np.arange(helices.offsets[k], helices.offsets[k + 1]) for k in strands])
            if len(strands) else np.zeros(0, np.int64))
    offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    sub = Helices(_f64(helices.root[strands]), _f64(helices.frame0[strands]), offsets, _f64(helices.length[rows]),
                  _f64(helices.omega[rows]), _f64(helices.fit_error[strands]))
    return sub, rows


class Following:
    """Render strands following the simulated guides of a simulation, frame by frame.

    Parameters
    ----------
    points : (P, 3) float64, m, the render strands as read (the guides' binding pose); offsets (R + 1,) int64
    helices : Helices, the stage file's ``/helices`` (the simulated strands as read)
    frames : the stage file's ``/frames`` group (untrimmed)
    guides : (G,) int64, optional, the strands of ``helices`` the render strands follow (default: all)
    by, at_root : how the guides are chosen and the offsets turned (:meth:`Follow.bind`)
    """

    def __init__(self, points: np.ndarray, offsets: np.ndarray, helices: Helices, frames: stages.Group,
                 guides: np.ndarray | None = None, by: str = "curve", at_root: bool = True):
        if guides is None:
            self.strands, self.rows = None, None
            sub = helices
        else:
            self.strands = np.asarray(guides, dtype=np.int64)
            sub, self.rows = subset_helices(helices, self.strands)
        self.helices = sub
        self.offsets = np.ascontiguousarray(offsets, dtype=np.int64)
        self.follow = Follow.bind(points, self.offsets, sub, by=by, at_root=at_root)
        self.frames = frames
        self._skin = None

    def _pick(self, root, frame0, omega):
        if self.strands is None:
            return root, frame0, omega
        return root[self.strands], frame0[self.strands], omega[self.rows]

    def pose(self, root: np.ndarray, frame0: np.ndarray, omega: np.ndarray) -> np.ndarray:
        """(P, 3) m: the render strands where the simulated strands' pose (all of them: ``root`` (S, 3),
        ``frame0`` (S, 3, 3), ``omega`` (E, 3)) carries them."""
        return self.follow.points(*self._pick(np.asarray(root), np.asarray(frame0), np.asarray(omega)))

    def frame(self, k: int) -> np.ndarray:
        """(P, 3) m: the render strands in frame ``k``; on a deforming body (``body_vertices``) each strand moved
        with its root to where the skin carries it, bound to the skin where the guides put it in frame 0."""
        f = self.frames
        points = self.pose(f["root"][k], f["frame0"][k], f["omega"][k])
        if "body_vertices" not in f.datasets:
            return points
        roots = points[self.offsets[:-1]]
        if self._skin is None:
            first = roots if k == 0 else self.pose(f["root"][0], f["frame0"][0], f["omega"][0])[self.offsets[:-1]]
            self._skin = SkinRoots(first, np.asarray(f["body_vertices"][0], dtype=np.float64),
                                   np.asarray(f["body_faces"], dtype=np.int64))
        shift = self._skin.roots(np.asarray(f["body_vertices"][k], dtype=np.float64)) - roots
        return points + np.repeat(shift, np.diff(self.offsets), axis=0)


class SkinRoots:
    """The render roots bound to a deforming body's skin where the guides put them in the first frame.

    Parameters
    ----------
    roots : (R, 3) m, the render roots in the first frame
    vertices : (V, 3) m, the body in the first frame; faces (T, 3) int64
    """

    def __init__(self, roots: np.ndarray, vertices: np.ndarray, faces: np.ndarray):
        from .dynamics.skin import Binding

        self.faces = np.ascontiguousarray(faces, dtype=np.int64)
        self.binding = Binding.bind(roots, vertices, self.faces)

    def roots(self, vertices: np.ndarray) -> np.ndarray:
        """(R, 3) m: the render roots carried by their triangles on the body ``vertices``."""
        return self.binding.roots(_f64(vertices), self.faces)


def render_groom(curves: stages.Group, stage_path, render=None) -> tuple[Groom, Path]:
    """The render groom of a stage file's guides: every strand of the hairstyle its ``/curves`` were read
    from (``render`` None: the file its ``inputs`` record, found as the body is and only with the recorded
    SHA-256), or of the file ``render``, read with the import settings ``/curves`` records (its units, up
    axis and flips), every strand kept.

    Raises
    ------
    InputError
        The recorded file is gone or has changed, no file is recorded, ``render`` is missing or unreadable,
        or its up axis is not the guides'; one sentence naming the file.
    """
    if render is None:
        record = curves.inputs[0] if curves.inputs else None
        if record is None:
            raise InputError("records no hairstyle file its strands were read from, so it has no render groom to "
                             "follow its guides; name one with --render STYLE", stage_path)
        path, why = find_recorded(record, stage_path)
        if path is None:
            raise InputError(f"{why}: that hairstyle is its render groom; name it with --render STYLE", stage_path)
    else:
        path = Path(render)
        if not path.exists():
            raise InputError("no such file (the render groom, --render)", path)
    stored = dict(curves.config.get("import", {}))
    known = {f.name for f in dataclasses.fields(ImportSettings)}
    settings = ImportSettings(**{key: value for key, value in stored.items() if key in known})
    # every strand, in the unit the guides were read in (a guessed unit may have been guessed from the body)
    settings = dataclasses.replace(settings, guides=0, scale=float(curves.attrs.get("scale_to_m", 1.0)))
    groom, _ = load_groom(path, settings)
    up = np.asarray(curves.attrs.get("up", (0.0, 1.0, 0.0)), dtype=np.float64)
    up = up / np.linalg.norm(up)
    if not np.allclose(groom.up, up, atol=1e-9):
        raise InputError(f"reads with the up axis {np.round(groom.up, 6).tolist()}, not the guides' "
                         f"{np.round(up, 6).tolist()}: pass the render groom in the guides' axes", path)
    return groom, path
