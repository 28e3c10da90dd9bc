#!/usr/bin/env python
"""Test grooms of kinds hairinv has not been tuned on, over a mannequin body.

The sample grooms in ``samples/`` were drawn to stand a few millimetres off
the body, at a distance that varies from strand to strand. Real inputs are
often different: combed grooms and captures lie in a layer at an almost
constant small gap over the skin, gelled hair stands up in spikes whose
strands rest on each other, updos are pulled tight against the scalp, and
captured hair sinks into its mesh in places. This script makes such grooms,
deterministically (every kind takes a ``seed``), so the pipeline
(``hairinv fit -> detect -> invert -> simulate``) can be tried on them, with
some variants kept for development and others held out for checking that
what was tuned carries over.

Everything is in metres, +Y up, the face toward +Z, gravity along -Y. All
distances to the body are measured on the triangle mesh that is written
(``mannequin.obj``) with hairinv's own exact closest-point queries
(``hairinv.contacts.body.BodyMesh``), so a gap asked for is the gap the
files have.

The body, ``mannequin.obj``
    Head (with a small nose), neck and torso down to the waist (y = 1.00 m),
    with rounded shoulders 0.40 m wide and an upper back; the torso leans
    back a little below the shoulders (as a seated figure does), so hair
    that comes down the back lies on it and hair in front falls free of the
    chest. A lofted surface (superelliptic rings whose half-widths follow
    smooth profiles of the height, as in ``samples/make_samples.py``),
    closed at the waist by a flat cap, outward-oriented, about 18,000
    triangles.

The kinds
    ``draped(gap, curl_radius=0, ...)``
        Straight hair draped over the mannequin in a layer at a nearly
        constant ``gap`` above the skin, as combed grooms and captures lie.
        Roots are spread evenly over the scalp, on the skin; each strand
        rises to its gap over its first 2-3 cm (bending by at most 50 / m
        there), is combed away from a centre parting (the sides forward of
        the ears, the rest back), runs along the head at exactly its gap
        wherever it would come closer, comes down on the shoulders and the
        upper back and lies on them, and hangs free where it leaves the body
        (below the back of the head, beside the face and the neck). The
        drape is kinematic: a strand grows in 2 mm steps whose direction
        turns at a bounded rate toward where it wants to go (along the
        surface and a little downhill while it rests on the body; down while
        it hangs), looks a few centimetres ahead to turn before it lands on
        a shoulder, and is projected back onto its gap wherever a step would
        go closer; the paths are then smoothed and projected again, so a few
        small kinks remain where the body pushed them out. Almost every
        strand rests on the body over part of its length (about 45 % of the
        points), all at one distance: many contacts just beyond a small
        detection distance, or just within it. ``curl_radius > 0`` winds a
        coil of that radius (period 1-2 cm) around the draped centre line,
        which is held ``curl_radius`` further out so that the coil stays
        outside the body: the innermost point of each turn lies at about
        the gap.
    ``mohawk(...)``
        Standing hair: strands rooted in a strip along the head's mid-line
        from the forehead over the crown to the nape, standing up and back,
        6-20 cm long, gathered in spikes (wisps of 5-20 strands, their centre
        lines 0.5-3 mm apart, converging toward the tip); neighbouring
        spikes are paired and lean toward each other until they rest lightly
        on each other (where the scalp lets them lean that far). Almost no
        contact with the body, many hair-hair contacts, and hair that is
        held up against gravity by its stiffness alone.
    ``updo(...)``
        Hair combed up from the nape and the sides over the scalp, pulled
        tight at exactly the gap, to a bun on top: each strand walks along
        the head to the bun and winds around it in a spiral. Strands rest on
        the head over most of their length and the contact normals point
        every way, including downward at the nape.
    ``inside(...)``
        A dense captured-style groom (short hair, 20 points per strand) whose
        points are displaced along the body normal by a smooth field, as a
        capture floats above and sinks below its mesh: about 20 % of the
        points lie 0-2 mm inside the head mesh, roots included.

Each kind returns ``(points (P, 3) float64, offsets (S + 1,) int64)``;
``write_groom`` writes it as a hairinv stage file holding ``/curves``
(up = +Y, scale_to_m = 1). ``VARIANTS`` names the variants (kind and
parameters); ``DEVELOPMENT`` and ``HELD_OUT`` split them.

Command line (from the project root)::

    .venv/bin/python bench/grooms.py [-o OUTDIR] [--pictures] [NAME ...]

writes ``OUTDIR/mannequin.obj`` (default ``out/grooms`` under the project
root, which git ignores) and the named variants (default: all, about 40 s
on two cores) as ``OUTDIR/<name>.h5`` and prints, per groom: strands,
points, lengths, turning angles, the nearest point of another strand, and
the distribution of point distances to the body (percentiles 5/25/50/75/95
and the fraction inside, deeper than 0.1 micrometre). For grooms laid at a
gap it also prints the distances of the points lying on the body (beyond
3 cm of the root and within the gap + 1.5 mm), whose median is the gap, and
for curly ones those of the innermost point of each turn of the coil.
``--pictures`` also draws each kind once over the body (front and side;
blue where the hair lies on the body, red inside it) to
``OUTDIR/<kind>.png``. Then, e.g.::

    .venv/bin/hairinv fit out/grooms/draped_gap4.h5 -o out/grooms/draped_gap4.fit.h5
    .venv/bin/hairinv detect out/grooms/draped_gap4.fit.h5 out/grooms/mannequin.obj -o out/grooms/draped_gap4.contacts.h5
"""

from __future__ import annotations

import argparse
import functools
import sys
import time
from pathlib import Path

import numpy as np
import trimesh
from scipy.interpolate import CubicSpline
from scipy.spatial import cKDTree

ROOT = Path(__file__).resolve().parents[1]
for _p in (ROOT, ROOT / "samples"):
    if str(_p) not in sys.path:
        sys.path.insert(0, str(_p))

from make_samples import write_obj as _write_obj  # noqa: E402
from make_samples import (  # noqa: E402  (generic curve helpers of the sample generator)
    arclength,
    blur,
    ring_radius,
    smoothstep,
    tangential,
    transported_frames,
    turning_angles,
    unit,
)

from hairinv.contacts.body import BodyMesh  # noqa: E402
from hairinv.formats.hdf5 import write_hdf5_curves  # noqa: E402

Y_TOP = 1.74  # top of the head (pole of the mesh)
Y_BOT = 1.00  # the torso is cut (and capped) here
HEAD_C = 1.62  # height of the head centre (its widest ring)
G = np.array([0.0, -1.0, 0.0])
UP = np.array([0.0, 1.0, 0.0])
DS = 0.002  # step of the drape, m


# --------------------------------------------------------------------------
# The mannequin
# --------------------------------------------------------------------------


def profile(y):
    """Ring shape at heights ``y``: half-width along x ``a``, toward the front
    ``bf`` and the back ``bb``, and the superellipse exponent ``n``."""
    y = np.asarray(y, float)
    # head: an ellipsoid, longer below its centre (chin), narrower at the jaw, tucked in at the skull base
    cy = np.where(y >= HEAD_C, Y_TOP - HEAD_C, 0.13)
    s = (y - HEAD_C) / cy
    e = np.sqrt(np.clip(1.0 - s * s, 0.0, None))
    low = smoothstep(0.0, -1.0, s)
    a_h = 0.079 * e * (1.0 - 0.15 * low)
    bf_h = 0.093 * e * (1.0 + 0.05 * low)
    bb_h = 0.099 * e * (1.0 - 0.24 * low)
    # neck: a cylinder fading out inside the head
    nk = 1.0 - smoothstep(1.56, 1.67, y)
    a_n, bf_n, bb_n = 0.054 * nk, 0.050 * nk, 0.056 * nk
    # torso: shoulders rounding off toward the neck, a waist, shoulder blades, a chest
    st = np.clip((y - 1.36) / 0.118, 0.0, 1.0)
    f = np.sqrt(np.clip(1.0 - st * st, 0.0, None))
    a_t = (0.198 - 0.040 * smoothstep(1.34, 1.05, y)) * f
    bf_t = (0.100 + 0.010 * np.exp(-(((y - 1.27) / 0.07) ** 2)) - 0.012 * smoothstep(1.18, 1.00, y)) * f
    bb_t = (0.102 + 0.012 * np.exp(-(((y - 1.33) / 0.08) ** 2))) * f
    k = 8.0
    comps = np.stack([a_h, a_n, a_t])
    tiny = 1e-9
    a = (np.sum(comps**k, axis=0) + tiny**k) ** (1.0 / k)
    bf = (np.sum(np.stack([bf_h, bf_n, bf_t]) ** k, axis=0) + tiny**k) ** (1.0 / k)
    bb = (np.sum(np.stack([bb_h, bb_n, bb_t]) ** k, axis=0) + tiny**k) ** (1.0 / k)
    total = np.sum(comps**k, axis=0)
    w = comps**k / np.maximum(total, 1e-300)
    n = np.where(total > 0, 2.0 * (w[0] + w[1]) + 2.6 * w[2], 2.0)
    return a, bf, bb, n


def lean(y, tilt=0.14, start=1.44, width=0.08):
    """Backward shift (-z) of the ring centres: the torso leans back below the shoulders (C1 ramp)."""
    u = np.clip(start - np.asarray(y, float), 0.0, None)
    return tilt * np.where(u < width, u * u / (2 * width), u - width / 2)


def nose(theta, y):
    g = smoothstep(1.632, 1.585, y) * smoothstep(1.560, 1.585, y)
    dth = np.angle(np.exp(1j * (theta - np.pi / 2)))
    return 0.014 * g * np.exp(-((dth / 0.15) ** 2))


def surface_radius(theta, y):
    a, bf, bb, n = profile(y)
    return ring_radius(theta, a, bf, bb, n) + nose(theta, y)


def ring_heights(count):
    """``count`` heights below the pole, evenly spaced along the meridian (denser across the face)."""
    y = np.linspace(Y_TOP, Y_BOT, 8001)
    a, bf, bb, _ = profile(y)
    r = 0.5 * a + 0.25 * (bf + bb)
    z = lean(y)
    weight = 1.0 + 0.6 * np.exp(-(((y - 1.59) / 0.035) ** 2))
    step = np.sqrt(np.diff(r) ** 2 + np.diff(y) ** 2 + np.diff(z) ** 2) * 0.5 * (weight[1:] + weight[:-1])
    arc = np.concatenate([[0.0], np.cumsum(step)])
    t = np.linspace(0.0, arc[-1], count + 1)[1:]
    return np.interp(t, arc, y)


def build_mannequin(n_rings=100, n_seg=90):
    """The lofted mannequin: a pole at the top, ``n_rings`` rings, a flat cap at the waist.

    Vertices are rounded to the micrometre, as written to the OBJ file, so
    distances measured on this mesh are those of the file.
    """
    ys = ring_heights(n_rings)
    theta = np.linspace(0.0, 2.0 * np.pi, n_seg, endpoint=False) + np.pi / n_seg
    r = surface_radius(theta[None, :], ys[:, None])
    zc = -lean(ys)[:, None]
    ring = np.stack([r * np.cos(theta), np.broadcast_to(ys[:, None], r.shape), zc + r * np.sin(theta)], axis=-1)
    bottom = np.array([[0.0, Y_BOT, -float(lean(Y_BOT))]])
    verts = np.round(np.concatenate([[[0.0, Y_TOP, 0.0]], ring.reshape(-1, 3), bottom]), 6)
    idx = 1 + np.arange(n_rings * n_seg).reshape(n_rings, n_seg)
    nxt = np.roll(idx, -1, axis=1)
    faces = [np.stack([np.zeros(n_seg, int), nxt[0], idx[0]], axis=1)]
    for i in range(n_rings - 1):
        faces.append(np.stack([idx[i], nxt[i], nxt[i + 1]], axis=1))
        faces.append(np.stack([idx[i], nxt[i + 1], idx[i + 1]], axis=1))
    faces.append(np.stack([np.full(n_seg, len(verts) - 1), idx[-1], nxt[-1]], axis=1))
    faces = np.concatenate(faces)
    mesh = trimesh.Trimesh(verts, faces, process=False)
    if mesh.volume < 0:
        mesh = trimesh.Trimesh(verts, faces[:, ::-1], process=False)
    return mesh


def write_obj(path, mesh):
    """The mannequin as OBJ, with the sample body's writer (``samples/make_samples.py``)."""
    _write_obj(path, mesh, ("hairinv test mannequin: head, neck, shoulders, upper back and torso, closed at the waist",
                            "units: metres; +Y up; face toward +Z", "written by bench/grooms.py"))


class Mannequin:
    """The mannequin mesh and exact signed distances to it."""

    def __init__(self, mesh):
        self.mesh = mesh
        self.bm = BodyMesh.from_mesh(mesh)

    def query(self, p):
        """Signed distance (negative inside) and unit gradient of the distance (outward) at points ``p`` (..., 3)."""
        shape = p.shape[:-1]
        flat = np.ascontiguousarray(p.reshape(-1, 3))
        sd, c, nf, _ = self.bm.closest(flat)
        v = flat - c
        dist = np.linalg.norm(v, axis=1)
        sign = np.where(sd < 0, -1.0, 1.0)
        n = np.where(dist[:, None] > 1e-9, sign[:, None] * v / np.maximum(dist, 1e-300)[:, None], nf)
        return sd.reshape(shape), n.reshape(shape + (3,))

    def distance(self, p):
        return self.bm.closest(np.ascontiguousarray(np.reshape(p, (-1, 3))))[0].reshape(np.shape(p)[:-1])

    def _move(self, p, target, outward_only, iters=8, tol=1e-10):
        """Points ``p`` moved along the distance gradient until their distance reaches ``target``
        (only those short of it when ``outward_only``)."""
        p = np.array(p, float)
        shape = p.shape[:-1]
        flat = p.reshape(-1, 3)
        target = np.broadcast_to(target, shape).reshape(-1)
        todo = np.arange(len(flat))
        for _ in range(iters):
            d, n = self.query(flat[todo])
            err = target[todo] - d
            off = err > tol if outward_only else np.abs(err) > tol
            if not off.any():
                break
            todo = todo[off]
            flat[todo] += err[off, None] * n[off]
        return flat.reshape(shape + (3,))

    def project_out(self, p, need, iters=8, tol=1e-10):
        """Points ``p`` moved outward along the distance gradient to at least ``need`` from the body."""
        return self._move(p, need, True, iters, tol)

    def set_distance(self, p, target, iters=8, tol=1e-10):
        """Points ``p`` moved along the distance gradient to exactly ``target`` from the body."""
        return self._move(p, target, False, iters, tol)


@functools.lru_cache(maxsize=1)
def mannequin():
    """The mannequin (built once per process)."""
    return Mannequin(build_mannequin())


# --------------------------------------------------------------------------
# Shared pieces
# --------------------------------------------------------------------------


def turn_toward(t, w, max_angle):
    """Rotate unit vectors ``t`` toward unit vectors ``w`` by at most ``max_angle`` radians."""
    c = np.clip(np.sum(t * w, axis=-1), -1.0, 1.0)
    ang = np.arccos(c)
    e = w - c[..., None] * t
    en = np.linalg.norm(e, axis=-1)
    step = np.minimum(ang, max_angle)
    ok = en > 1e-12
    out = t.copy()
    out[ok] = t[ok] * np.cos(step[ok])[:, None] + (e[ok] / en[ok, None]) * np.sin(step[ok])[:, None]
    return unit(out)


def scalp_mask(p):
    """True on the scalp: top, back and sides of the head and the nape; not the face."""
    phi = np.abs(np.arctan2(p[:, 0], -p[:, 2]))  # 0 at the back, pi at the face
    hairline = np.interp(
        phi, [0.0, 0.5, 1.0, 1.4, 1.8, 2.3, 2.7, np.pi], [1.525, 1.530, 1.550, 1.585, 1.605, 1.655, 1.675, 1.682]
    )
    return (p[:, 1] > hairline) & (np.abs(p[:, 2] + lean(p[:, 1])) < 0.2)


def surface_samples(body, count, rng, select):
    """``count`` random points on the triangles of the body (area-weighted) where ``select(points)`` holds."""
    tri = body.mesh.triangles
    tri = tri[tri[:, :, 1].min(axis=1) > 1.45]
    area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1) / 2
    pick = rng.choice(len(tri), size=count * 4, p=area / area.sum())
    u = rng.random((len(pick), 2))
    flip = u.sum(axis=1) > 1
    u[flip] = 1 - u[flip]
    t = tri[pick]
    pts = t[:, 0] + u[:, :1] * (t[:, 1] - t[:, 0]) + u[:, 1:] * (t[:, 2] - t[:, 0])
    return pts[select(pts)][:count]


def farthest_points(pts, count, rng):
    """``count`` of ``pts`` spread evenly (farthest-point sampling from a random start)."""
    chosen = [int(rng.integers(len(pts)))]
    dmin = np.linalg.norm(pts - pts[chosen[0]], axis=1)
    for _ in range(count - 1):
        i = int(np.argmax(dmin))
        chosen.append(i)
        dmin = np.minimum(dmin, np.linalg.norm(pts - pts[i], axis=1))
    return pts[chosen]


def scalp_roots(body, count, rng):
    cand = surface_samples(body, max(12000, 8 * count), rng, scalp_mask)
    return farthest_points(cand, count, rng)


def _scalp_start(body, n_strands, seed, length):
    """What the draped and inside grooms start from: the body (the mannequin if None), the seeded
    generator, roots over the scalp, their comb directions and the strands' lengths (drawn in this order)."""
    body = body or mannequin()
    rng = np.random.default_rng(seed)
    roots = scalp_roots(body, n_strands, rng)
    _, n0 = body.query(roots)
    return body, rng, roots, comb_direction(roots, n0), rng.uniform(*length, n_strands)


def comb_direction(roots, normal):
    """Away from a centre parting, toward the back (tangent to the scalp)."""
    u = np.stack([roots[:, 0] / 0.079, (roots[:, 1] - HEAD_C) / 0.12, roots[:, 2] / 0.095], axis=1)
    side = np.sign(u[:, 0]) * np.minimum(np.abs(u[:, 0]) * 4.0, 1.0)
    front = np.clip(u[:, 2], 0.0, 1.0)  # from the front hairline the hair goes up and back over the head
    c = np.stack([1.1 * side + 0.6 * u[:, 0], -0.4 + 1.2 * front, -0.5 + 1.3 * u[:, 2] * np.abs(side)], axis=1)
    return unit(tangential(c, normal))


def rise(s, length=0.01):
    """0 at the root, 1 beyond ``length`` of arc: how much of its gap a strand keeps at arc length ``s``."""
    return smoothstep(0.0, length, s) if length > 0 else np.ones_like(np.asarray(s, float))


def resample_to(path, s_end, spacing):
    """Points evenly spaced (about ``spacing``) along the first ``s_end`` of a polyline (N, 3)."""
    s = arclength(path)
    s_end = min(s_end, s[-1])
    count = max(int(round(s_end / spacing)) + 1, 3)
    q = np.linspace(0.0, s_end, count)
    return np.stack([np.interp(q, s, path[:, k]) for k in range(3)], axis=1)


def pack(strands):
    points = np.ascontiguousarray(np.concatenate(strands), dtype=np.float64)
    offsets = np.concatenate([[0], np.cumsum([len(s) for s in strands])]).astype(np.int64)
    return points, offsets


def unpack(points, offsets):
    return [points[offsets[i]:offsets[i + 1]] for i in range(len(offsets) - 1)]


def lift_resampled(body, strands, need_fn):
    """Project each strand's points out to ``need_fn(arc length, strand)`` where they came closer."""
    pts, off = pack(strands)
    s = np.concatenate([arclength(st) for st in strands])
    owner = np.repeat(np.arange(len(strands)), np.diff(off))
    pts = body.project_out(pts, need_fn(s, owner))
    return unpack(pts, off)


# --------------------------------------------------------------------------
# Draped (straight and curly)
# --------------------------------------------------------------------------


def drape_paths(body, roots, comb, need, steps, kappa=40.0, kappa_free=35.0, r_head=0.10, cling=0.0005,
                reach=0.004, approach=0.01,
                lookahead=(0.012, 0.025, 0.04), support=-0.2, hold=0.0, ds=DS):
    """Centre lines of strands draped over the body: (steps + 1, S, 3), in steps of ``ds``.

    ``need(k)`` (S,) is the least distance from the body a strand keeps at
    step ``k``. A strand resting on the body (within ``reach`` of its
    ``need``, where the surface faces no more than ``support`` downward)
    keeps its direction along the surface, bent downhill by gravity over
    about ``r_head``, and heads for ``cling`` below its layer (coming back
    to it over about ``approach`` when it is above), so it presses on the
    surface a little; a strand off the body turns down. Directions turn by
    at most ``kappa``
    (resting) or ``kappa_free`` (hanging) radians per metre, and a hanging
    strand that would land on the body within ``lookahead`` starts turning
    along the surface there. Wherever a step would go closer than ``need``
    the point is projected back out onto it.
    """
    need0 = need(0)
    t = comb.copy()  # along the scalp; the projection lifts the strand to its gap
    p = body.project_out(roots, need0) if np.any(need0 > 0) else roots.copy()
    out = [p.copy()]
    lam = np.asarray(lookahead)
    for k in range(1, steps + 1):
        d, n = body.query(p)
        now = need(k - 1)
        resting = (d < now + reach) & (n[:, 1] > support)
        want = np.broadcast_to(G, t.shape).copy()
        rate = np.full(len(p), kappa_free * ds)
        if np.any(resting):
            nr, tr = n[resting], t[resting]
            along = unit(unit(tangential(tr, nr)) + tangential(G[None, :], nr) * (ds / r_head))
            # head for a little below the layer (the projection holds the strand on it)
            slope = (need(k) - now)[resting] / ds
            vn = np.clip(slope + (now[resting] - cling - d[resting]) / approach, -0.35, 0.8)
            want[resting] = unit(along * np.sqrt(1.0 - vn**2)[:, None] + nr * vn[:, None])
            rate[resting] = kappa * ds
        free = ~resting
        if np.any(free):
            # look ahead along the current direction for a landing
            ahead = p[free][None] + t[free][None] * lam[:, None, None]
            da, na = body.query(ahead)
            hit = da < now[free][None] + 0.0005
            any_hit = hit.any(axis=0)
            if np.any(any_hit):
                j = np.argmax(hit, axis=0)
                idx = np.flatnonzero(free)[any_hit]
                nh = na[j[any_hit], np.flatnonzero(any_hit)]
                th = t[idx]
                slide = unit(tangential(th, nh) + 0.3 * tangential(G[None, :], nh) + 0.05 * nh)
                want[idx] = slide
                # turn harder the nearer the landing
                rate[idx] = np.maximum(kappa_free, kappa * (lam[-1] / lam[j[any_hit]]) ** 0.5) * ds
        t = turn_toward(t, want, rate)
        q = body.project_out(p + t * ds, need(k))
        if k * ds <= hold:
            q = body.set_distance(q, need(k))
        t = unit(q - p)
        p = q
        out.append(p.copy())
    return np.stack(out)


def smooth_paths(body, paths, need_grid, passes=((0.004,), (0.0025,)), ds=DS):
    """Gaussian smoothing of paths (K, S, 3) along their length (roots kept), each pass followed by
    projecting back out to ``need_grid`` (K, S)."""
    for (sigma,) in passes:
        paths = blur(paths, sigma / ds)
        paths = body.project_out(paths, need_grid)
    return paths


def draped(gap, curl_radius=0.0, spacing=0.004, n_strands=300, seed=1, length=(0.15, 0.45), jitter=0.0003,
           curl_period=(0.012, 0.018), root_rise=0.01, body=None):
    """Straight (or, with ``curl_radius`` > 0, curly) hair draped over the mannequin at ``gap`` (m).

    Parameters
    ----------
    gap : float, m
        Distance of the draped layer from the skin (each strand: ``gap`` plus
        a uniform jitter of +-``jitter``). Roots are on the skin; a strand
        reaches its gap within ``root_rise`` of arc, or more where rising
        that fast would bend it by more than 50 / m.
    curl_radius : float, m
        Radius of a coil wound around the draped centre line (period drawn
        per strand from ``curl_period``); the centre line is held this much
        further out, so the coil's innermost points are at about ``gap``.
    spacing : float, m
        Vertex spacing of the output strands (along the strand, the coil for curly hair).
    n_strands, length, seed
        Strand count, range of strand lengths (m, measured along the output strand), random seed.

    Returns
    -------
    points : (P, 3) float64, offsets : (S + 1,) int64
    """
    body, rng, roots, comb, lengths = _scalp_start(body, n_strands, seed, length)
    gaps = gap + rng.uniform(-jitter, jitter, n_strands)
    curly = curl_radius > 0
    coil_ramp = 0.02

    # the rise from the skin to the gap bends a strand by about 6 gap / rise^2: at most 50 / m
    root_rise = max(root_rise, np.sqrt(6.0 * (gap + curl_radius) / 50.0))

    def need_at(s, who=slice(None)):
        g = gaps[who] * rise(s, root_rise)
        if curly:
            g = g + curl_radius * smoothstep(0.0, coil_ramp, s)
        return g

    steps = int(np.ceil((lengths.max() + 0.01) / DS))
    paths = drape_paths(body, roots, comb, lambda k: need_at(k * DS), steps, hold=root_rise)
    s_grid = np.arange(steps + 1)[:, None] * DS
    need_grid = need_at(s_grid) * np.ones((1, n_strands))
    paths = smooth_paths(body, paths, need_grid)

    if not curly:
        strands = [resample_to(paths[:, i], lengths[i], spacing) for i in range(n_strands)]
        strands = lift_resampled(body, strands, lambda s, who: gaps[who] * rise(s, root_rise))
        return pack(strands)

    # the coil, on a finer grid (0.5 mm), in a frame carried along the centre line facing away from the body
    up = 4
    k = np.arange(steps + 1)
    fine = np.linspace(0, steps, steps * up + 1)
    base = CubicSpline(k, paths, axis=0)(fine)
    _, normal = body.query(base)
    u, v = transported_frames(base, normal, 0.03 / (DS / up))
    sb = arclength(base)
    period = rng.uniform(*curl_period, n_strands)
    phase = rng.uniform(0, 2 * np.pi, n_strands)
    hand = rng.choice([-1.0, 1.0], n_strands)
    ramp = smoothstep(0.0, coil_ramp, sb)
    ph = phase + hand * 2 * np.pi * sb / period
    coil = base + (curl_radius * ramp)[..., None] * (np.cos(ph)[..., None] * u + np.sin(ph)[..., None] * v)
    strands = []
    for i in range(n_strands):
        strands.append(resample_to(coil[:, i], lengths[i], spacing))
    strands = lift_resampled(body, strands, lambda s, who: gaps[who] * rise(s, root_rise))
    return pack(strands)


# --------------------------------------------------------------------------
# Mohawk
# --------------------------------------------------------------------------


def midline_point(body, alpha):
    """Surface points of the head's mid-line at angles ``alpha`` (rad) from the front (+Z) over the top,
    seen from the head centre; and the outward normals there."""
    alpha = np.atleast_1d(np.asarray(alpha, float))
    c = np.array([0.0, HEAD_C, 0.0])
    dirs = np.stack([np.zeros_like(alpha), np.sin(alpha), np.cos(alpha)], axis=1)
    lo = np.full(len(alpha), 0.02)
    hi = np.full(len(alpha), 0.2)
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        inside = body.distance(c + dirs * mid[:, None]) < 0
        lo = np.where(inside, mid, lo)
        hi = np.where(inside, hi, mid)
    p = c + dirs * (0.5 * (lo + hi))[:, None]
    _, n = body.query(p)
    return p, n


def spike_axis(root, d0, bend_dir, length, kappa, ds=DS):
    """Centre line of a spike: leaves ``root`` along ``d0`` and bends toward ``bend_dir`` at ``kappa`` (1/m)."""
    steps = int(np.ceil(length / ds))
    t = d0.copy()
    pts = [root.copy()]
    p = root.copy()
    for _ in range(steps):
        t = turn_toward(t[None], bend_dir[None], kappa * ds)[0]
        p = p + t * ds
        pts.append(p.copy())
    return np.array(pts)


def rotate(v, axis, angle):
    axis = unit(axis)
    return v * np.cos(angle) + np.cross(axis, v) * np.sin(angle) + axis * np.dot(axis, v) * (1 - np.cos(angle))


def mohawk(spike_spacing=0.016, pitch=0.002, strands_per_spike=(5, 20), spacing=0.008, width=0.012,
           length=(0.06, 0.20), seed=1, body=None, rest_clearance=None):
    """Standing hair in spikes along the head's mid-line, forehead to nape.

    Parameters
    ----------
    spike_spacing : float, m
        Distance between neighbouring spike roots along the mid-line.
    pitch : float, m
        Distance between neighbouring strands of a spike at its root; they
        converge to 0.35 of it at the tip (with the defaults, 0.7-2 mm apart).
    spacing : float, m
        Vertex spacing of the output strands.
    strands_per_spike : (int, int)
        Range of strands per spike (uniform, inclusive).
    width : float, m
        Half-width of the strip: spike roots are jittered sideways within it.
    length : (float, float), m
        Spike lengths: shortest at the nape, longest at the crown (with a random share).
    rest_clearance : float, m
        Clearance between the outer strands of the two spikes of a pair
        where they rest on each other (default: ``pitch``).
    """
    body = body or mannequin()
    rng = np.random.default_rng(seed)
    rest = pitch if rest_clearance is None else rest_clearance
    # mid-line from the forehead hairline (about 40 deg above the front) to the nape (about 45 deg below the back)
    a_dense = np.linspace(np.radians(40), np.radians(228), 2000)
    mp, _ = midline_point(body, a_dense)
    arc = arclength(mp)
    count = int(arc[-1] // spike_spacing)
    s_roots = (np.arange(count) + 0.5) * (arc[-1] / count) + rng.uniform(-0.2, 0.2, count) * spike_spacing
    alpha = np.interp(s_roots, arc, a_dense)
    p0, _ = midline_point(body, alpha)
    p0[:, 0] += rng.uniform(-width, width, count)
    d, n0 = body.query(p0)
    p0 = p0 - d[:, None] * n0  # back onto the surface
    _, n0 = body.query(p0)
    frac = s_roots / arc[-1]  # 0 at the forehead, 1 at the nape
    # longest at the crown (about 40 % of the way), shortest at the nape
    shape = np.interp(frac, [0.0, 0.4, 0.75, 1.0], [0.6, 1.0, 0.6, 0.0])
    spike_len = length[0] + (length[1] - length[0]) * np.clip(shape * rng.uniform(0.8, 1.0, count), 0, 1)
    back = np.array([0.0, 0.0, -1.0])
    x_axis = np.array([1.0, 0.0, 0.0])
    golden = np.pi * (3.0 - np.sqrt(5.0))

    def radius_at(s, L):
        return 1.0 - 0.65 * np.clip(s / L, 0, 1)

    spike_rad = np.zeros(count)
    members = rng.integers(strands_per_spike[0], strands_per_spike[1] + 1, count)
    for i in range(count):
        m = members[i]
        c = pitch / 1.8  # sunflower packing: nearest neighbours about 1.8 c apart
        spike_rad[i] = c * np.sqrt(m - 0.5)
    # neighbouring spikes are paired (front one, back one) and lean toward each other until they rest on each other
    kappa = rng.uniform(2.0, 5.0, count)
    bend = unit(back + 0.3 * G)
    base_dir = unit(n0 + 0.8 * UP + 0.5 * back)
    tilts = np.radians(np.linspace(0.0, 30.0, 31))

    def axis_for(i, extra):  # extra > 0 leans back (about the x axis), < 0 forward
        return spike_axis(p0[i], rotate(base_dir[i], x_axis, -extra), bend, spike_len[i], kappa[i])

    def max_tilt(i, sign):  # as long as the spike leaves the scalp at least 20 deg off the surface
        ok = [np.dot(rotate(base_dir[i], x_axis, -sign * e), n0[i]) >= 0.35 for e in tilts]
        return tilts[np.flatnonzero(ok)[-1]] if any(ok) else 0.0

    def clearance(i, ai, j, aj):
        si, sj = arclength(ai), arclength(aj)
        ri = spike_rad[i] * radius_at(si, spike_len[i])
        rj = spike_rad[j] * radius_at(sj, spike_len[j])
        dd = np.linalg.norm(ai[::2, None] - aj[None, ::2], axis=2) - ri[::2, None] - rj[None, ::2]
        mask = (si[::2, None] > 0.3 * spike_len[i]) & (sj[None, ::2] > 0.3 * spike_len[j])
        return dd[mask].min() if mask.any() else np.inf

    spikes = [axis_for(i, 0.0) for i in range(count)]
    for i in range(0, count - 1, 2):
        j = i + 1
        p0[j, 0] = p0[i, 0]  # the pair sits at one distance from the mid-line
        d, nn = body.query(p0[j][None])
        p0[j] -= d[0] * nn[0]
        top = min(max_tilt(i, 1.0), max_tilt(j, -1.0))
        # the least lean at which they touch (first found in 1 deg steps, then bisected); none if they never do
        lo = hi = 0.0
        for e in tilts[tilts <= top]:
            if clearance(i, axis_for(i, e), j, axis_for(j, -e)) < rest:
                hi = e
                break
            lo = e
        if hi > 0.0:
            for _ in range(12):
                mid = 0.5 * (lo + hi)
                if clearance(i, axis_for(i, mid), j, axis_for(j, -mid)) < rest:
                    hi = mid
                else:
                    lo = mid
        else:
            lo = 0.0
        spikes[i], spikes[j] = axis_for(i, lo), axis_for(j, -lo)
    spikes = [(spikes[i], spike_rad[i], spike_len[i]) for i in range(count)]

    strands = []
    for i in range(count):
        axis, _, L = spikes[i]
        sa = arclength(axis)
        tang = unit(np.gradient(axis, axis=0))
        # frame along the axis: e1 toward +x, transported
        e1 = np.empty_like(axis)
        e1[0] = unit(tangential(x_axis[None], tang[:1]))[0]
        for k in range(1, len(axis)):
            e1[k] = unit(tangential(e1[k - 1][None], tang[k:k + 1]))[0]
        e2 = np.cross(tang, e1)
        # the root disk in the scalp's tangent plane
        f1 = unit(tangential(x_axis[None], n0[i][None]))[0]
        f2 = np.cross(n0[i], f1)
        m = members[i]
        j = np.arange(m)
        rr = (pitch / 1.8) * np.sqrt(j + 0.5)
        ang = j * golden + rng.uniform(0, 2 * np.pi)
        ox, oy = rr * np.cos(ang), rr * np.sin(ang)
        blend = smoothstep(0.0, 0.012, sa)[:, None]
        taper = radius_at(sa, L)[:, None]
        for q in range(m):
            root_off = ox[q] * f1 + oy[q] * f2
            root = body.project_out(body.set_distance((p0[i] + root_off)[None], 0.0), 0.0)[0]
            off = taper * ((1 - blend) * (root - p0[i]) + blend * (ox[q] * e1 + oy[q] * e2))
            line = axis + off
            strands.append(resample_to(line, L * rng.uniform(0.8, 1.0), spacing))
    # nothing inside the head (a strand's first millimetres run along the scalp)
    strands = lift_resampled(body, strands, lambda s, who: 0.0005 * smoothstep(0.0, 0.003, s))
    return pack(strands)


# --------------------------------------------------------------------------
# Updo
# --------------------------------------------------------------------------


def updo(gap=0.003, n_strands=400, spacing=0.004, seed=1, bun_angle=100.0, bun_radius=(0.018, 0.032),
         wrap=(0.08, 0.22), bun_height=(0.008, 0.04), root_rise=0.01, body=None):
    """Hair combed up from the nape and the sides to a bun on top.

    Each strand rises from its root to ``gap`` and walks along the scalp at
    exactly that gap toward the bun, its heading turning smoothly (curving
    round the bun's axis as it nears it, all one way); inside its arrival
    circle (radius drawn from ``bun_radius``) it winds round the bun for
    ``wrap`` more metres, climbing to ``bun_height`` above the scalp and
    tightening as it climbs (by 35 % at 4 cm), so the strands stack up
    into a rounded bun. ``bun_angle`` (degrees) places the bun on the
    mid-line, measured from the front over the top.
    """
    body = body or mannequin()
    rng = np.random.default_rng(seed)
    bp, bn = midline_point(body, np.radians(bun_angle))
    bp, a = bp[0], bn[0]
    # no roots under the bun
    clear = bun_radius[1] + 0.015
    cand = surface_samples(body, max(12000, 8 * n_strands), rng,
                           lambda q: scalp_mask(q) & (np.linalg.norm(q - bp, axis=1) > clear))
    roots = farthest_points(cand, n_strands, rng)
    root_rise = max(root_rise, np.sqrt(6.0 * gap / 50.0))
    e1 = unit(tangential(np.array([1.0, 0.0, 0.0])[None], a[None]))[0]
    e2 = np.cross(a, e1)
    r_arr = rng.uniform(*bun_radius, n_strands)
    gaps = gap + rng.uniform(-0.0003, 0.0003, n_strands)

    def local(p):
        v = p - bp
        h = v @ a
        w = v - h[:, None] * a
        rho = np.linalg.norm(w, axis=1)
        return rho, unit(w), h

    # 1) the walk along the scalp
    ds = DS
    p = roots.copy()
    _, n = body.query(p)
    t = unit(tangential(unit(bp - p), n))
    paths = [p.copy()]
    arrived = np.full(n_strands, -1)
    k = 0
    while np.any(arrived < 0) and k < 400:
        k += 1
        walking = arrived < 0
        pw = p[walking]
        d, n = body.query(pw)
        _, radial, _ = local(pw)
        az = np.cross(a, radial)  # around the bun axis, one way
        rho = np.linalg.norm(pw - bp, axis=1)  # (not the distance from the axis, which is small under the chin too)
        m = smoothstep(r_arr[walking] + 0.02, r_arr[walking], rho)[:, None]
        toward = unit(bp - pw)  # the chord to the bun (its surface projection goes up the nape, not under it)
        want = unit(tangential((1 - 0.6 * m) * toward + m * az, n))
        t[walking] = turn_toward(t[walking], want, 35.0 * ds)
        q = pw + t[walking] * ds
        q = body.set_distance(q, gaps[walking] * rise(k * ds, root_rise))
        t[walking] = unit(q - pw)
        p[walking] = q
        paths.append(p.copy())
        done = np.flatnonzero(walking)[rho <= r_arr[walking] * 1.02]
        arrived[done] = k
    arrived[arrived < 0] = k
    walk = np.stack(paths)  # (K + 1, S, 3); strands stay where they arrived
    strands = []
    wrap_len = rng.uniform(*wrap, n_strands)
    h_end = rng.uniform(*bun_height, n_strands)
    for i in range(n_strands):
        w1 = walk[: arrived[i] + 1, i]
        # 2) round the bun: radius tightens, height climbs (from the arrival point, heading on round)
        q0 = w1[-1]
        rho0, rad0, h0 = local(q0[None])
        rho0, rad0, h0 = rho0[0], rad0[0], h0[0]
        psi0 = np.arctan2(rad0 @ e2, rad0 @ e1)
        sw = np.arange(1, int(np.ceil(wrap_len[i] / ds)) + 1) * ds
        h_s = h0 + (h_end[i] - h0) * smoothstep(0.0, wrap_len[i], sw)
        rho_s = rho0 * (1.0 - 0.35 * np.clip(h_s / 0.04, 0.0, 1.0))
        psi = psi0 + np.cumsum(ds / rho_s)
        w2 = bp + h_s[:, None] * a + rho_s[:, None] * (np.cos(psi)[:, None] * e1 + np.sin(psi)[:, None] * e2)
        strands.append(np.vstack([w1, w2]))
    # smooth each strand, keep it at least at its gap, resample
    out = []
    for i, st in enumerate(strands):
        sm = blur(st, 0.006 / ds)
        s = arclength(sm)
        sm = body.project_out(sm, gaps[i] * rise(s, root_rise))
        out.append(resample_to(sm, arclength(sm)[-1], spacing))
    out = lift_resampled(body, out, lambda s, who: gaps[who] * rise(s, root_rise))
    return pack(out)


# --------------------------------------------------------------------------
# Inside (a capture that floats and sinks)
# --------------------------------------------------------------------------


def inside(n_strands=1500, points_per_strand=20, inside_fraction=0.20, depth=0.002, seed=1, length=(0.06, 0.16),
           layer=(0.0003, 0.0025), float_height=0.001, body=None):
    """A dense captured-style groom part of which lies inside the head mesh.

    Short hair is draped on the head in a layer ``layer`` (m, per strand) off
    the skin, roots included, then every point is moved along the body normal
    by a smooth field (plane waves of 6-12 cm wavelength) that sinks some
    regions by up to ``depth`` + the layer's inner edge and lifts others by
    ``float_height``. The field's level is set so that ``inside_fraction``
    of the points end inside the mesh, 0 to ``depth`` deep. The field fades
    out 4-12 mm from the body, so hanging tips are not moved.
    """
    body, rng, roots, comb, lengths = _scalp_start(body, n_strands, seed, length)
    gaps = rng.uniform(*layer, n_strands)
    steps = int(np.ceil((lengths.max() + 0.005) / DS))
    paths = drape_paths(body, roots, comb, lambda k: gaps, steps)
    paths = smooth_paths(body, paths, gaps[None, :] * np.ones((steps + 1, 1)))
    strands = [resample_to(paths[:, i], lengths[i], lengths[i] / (points_per_strand - 1)) for i in range(n_strands)]
    strands = [st if len(st) == points_per_strand else
               np.stack([np.interp(np.linspace(0, arclength(st)[-1], points_per_strand), arclength(st), st[:, c])
                         for c in range(3)], axis=1) for st in strands]
    strands = lift_resampled(body, strands, lambda s, who: gaps[who])
    pts, off = pack(strands)
    d0, n = body.query(pts)
    # the smooth field
    waves = 6
    kdir = unit(rng.normal(size=(waves, 3)))
    klen = 2 * np.pi / rng.uniform(0.06, 0.12, waves)
    kph = rng.uniform(0, 2 * np.pi, waves)
    f = np.sum(np.sin(pts @ (kdir * klen[:, None]).T + kph), axis=1) / np.sqrt(waves / 2)
    fade = 1.0 - smoothstep(0.004, 0.012, d0)
    sink = depth + layer[0]

    def field(level):
        w = smoothstep(-0.6, 0.6, f + level)
        return (sink * w - float_height * (1 - w)) * fade

    lo, hi = -4.0, 4.0
    for _ in range(40):  # the level whose (predicted) inside fraction is asked for
        mid = 0.5 * (lo + hi)
        frac = np.mean(d0 - field(mid) < 0)
        lo, hi = (lo, mid) if frac > inside_fraction else (mid, hi)
    delta = field(0.5 * (lo + hi))
    pts = pts - delta[:, None] * n
    return pts, off


# --------------------------------------------------------------------------
# Variants, files, report
# --------------------------------------------------------------------------

KINDS = {"draped": draped, "mohawk": mohawk, "updo": updo, "inside": inside}

VARIANTS = {
    # development: tune and debug on these
    "draped_gap2": ("draped", dict(gap=0.002, spacing=0.004, seed=1)),
    "draped_gap4": ("draped", dict(gap=0.004, spacing=0.004, seed=1)),
    "draped_gap6": ("draped", dict(gap=0.006, spacing=0.004, seed=1)),
    "curly_gap4": ("draped", dict(gap=0.004, curl_radius=0.003, spacing=0.002, seed=1)),
    "mohawk": ("mohawk", dict(seed=1)),
    "updo": ("updo", dict(gap=0.003, seed=1)),
    "inside": ("inside", dict(seed=1)),
    # held out: other seeds, spacings, gaps, curl radii, spike layouts
    "draped_gap3_s2_sp8": ("draped", dict(gap=0.003, spacing=0.008, seed=2)),
    "draped_gap5_s3_sp2": ("draped", dict(gap=0.005, spacing=0.002, seed=3)),
    "curly_gap2_r2_s4": ("draped", dict(gap=0.002, curl_radius=0.002, spacing=0.002, seed=4)),
    "curly_gap6_r4_s5": ("draped", dict(gap=0.006, curl_radius=0.004, curl_period=(0.016, 0.020), spacing=0.003,
                                        seed=5, n_strands=250)),
    "mohawk_s2": ("mohawk", dict(seed=2, spike_spacing=0.012, pitch=0.0015, spacing=0.006)),
    "updo_s2": ("updo", dict(gap=0.002, seed=2, bun_angle=80.0, spacing=0.003)),
    "inside_s2": ("inside", dict(seed=2, n_strands=1200, inside_fraction=0.16, depth=0.0015)),
}
DEVELOPMENT = ("draped_gap2", "draped_gap4", "draped_gap6", "curly_gap4", "mohawk", "updo", "inside")
HELD_OUT = tuple(name for name in VARIANTS if name not in DEVELOPMENT)


def make(name, body=None):
    """Points and offsets of the variant ``name``."""
    kind, params = VARIANTS[name]
    return KINDS[kind](body=body, **params)


def write_groom(path, points, offsets, source):
    """Write a hairinv stage file holding ``/curves`` (metres, up = +Y)."""
    write_hdf5_curves(Path(path), points, offsets, up=(0.0, 1.0, 0.0), source=source, command="bench/grooms.py")


def write_variant(outdir, name, body=None):
    """Make variant ``name`` and write ``outdir/<name>.h5``; returns (path, points, offsets)."""
    points, offsets = make(name, body)
    kind, params = VARIANTS[name]
    desc = ", ".join(f"{k}={v}" for k, v in sorted(params.items()))
    path = Path(outdir) / f"{name}.h5"
    write_groom(path, points, offsets, f"bench/grooms.py {name}: {kind}({desc})")
    return path, points, offsets


def groom_stats(body, points, offsets):
    """Measured facts of a groom: lengths, turning angles, distances to the body, nearest other strand."""
    strands = unpack(points, offsets)
    arcs = [arclength(st) for st in strands]
    s = np.concatenate(arcs)
    owner = np.repeat(np.arange(len(strands)), np.diff(offsets))
    d = body.distance(points)
    ang = np.concatenate([turning_angles(st) for st in strands])
    tree = cKDTree(points)
    dd, ii = tree.query(points, k=min(16, len(points)))
    other = owner[ii] != owner[:, None]
    first = np.argmax(other, axis=1)
    nearest = np.where(other.any(axis=1), dd[np.arange(len(points)), first], np.inf)
    seg = np.concatenate([np.linalg.norm(np.diff(st, axis=0), axis=1) for st in strands])
    return dict(strands=len(strands), points=len(points), lengths=np.array([a[-1] for a in arcs]),
                counts=np.diff(offsets), s=s, owner=owner, d=d, angles=ang, nearest=nearest, seg=seg)


def pct(x, q=(5, 25, 50, 75, 95), scale=1000.0):
    if len(x) == 0:
        return "-"
    return "/".join(f"{v * scale:.2f}" for v in np.percentile(x, q))


def report(name, st, params):
    gap = params.get("gap")
    d, s = st["d"], st["s"]
    L = st["lengths"]
    print(f"{name}: {st['strands']} strands, {st['points']} points ({st['counts'].min()}-{st['counts'].max()} per strand), "
          f"length {L.min():.3f}-{L.max():.3f} m (median {np.median(L):.3f}), "
          f"segment {st['seg'].min() * 1000:.2f}-{st['seg'].max() * 1000:.2f} mm")
    print(f"  distance to body, all points, p5/25/50/75/95: {pct(d)} mm; inside {np.mean(d < -1e-7) * 100:.1f}% "
          f"(deepest {max(-d.min(), 0) * 1000:.2f} mm); roots {pct(d[s == 0], (0, 50, 100))} mm (min/median/max)")
    if gap is not None:
        on = (s > 0.03) & (d < gap + 0.0015)
        strands_on = len(np.unique(st["owner"][on]))
        print(f"  lying on the body (beyond 3 cm of the root, within gap + 1.5 mm): {on.mean() * 100:.1f}% of the points, "
              f"{strands_on / st['strands'] * 100:.0f}% of the strands; distances p5/25/50/75/95 {pct(d[on])} mm "
              f"(asked gap {gap * 1000:.1f} mm, median off by {abs(np.median(d[on]) - gap) * 1000:.2f} mm)")
    curl = params.get("curl_radius", 0.0)
    if gap is not None and curl > 0:
        # the innermost point of each turn of the coil: local minima of the distance along a strand
        o = st["owner"]
        inner = np.zeros(len(d), bool)
        inner[1:-1] = (d[1:-1] <= d[:-2]) & (d[1:-1] <= d[2:]) & (o[:-2] == o[1:-1]) & (o[2:] == o[1:-1])
        inner &= (s > 0.03) & (d < gap + 2 * curl + 0.0015)
        print(f"  coil turns resting on the body (innermost point of a turn within gap + 2 curl radii + 1.5 mm): "
              f"{inner.sum()} turns on {len(np.unique(o[inner]))} strands; their distances p5/25/50/75/95 "
              f"{pct(d[inner])} mm (asked gap {gap * 1000:.1f} mm; the centre line is held at gap + curl radius)")
    print(f"  turning angle per vertex: median {np.median(st['angles']):.1f}, p99 {np.percentile(st['angles'], 99):.1f}, "
          f"max {st['angles'].max():.1f} deg; nearest point of another strand p5/50/95 {pct(st['nearest'], (5, 50, 95))} mm")


def draw(body_view, grooms, path, title, head=False):
    """Front and side views of grooms (name -> (points, offsets, colour per point)) over the body
    (``head``: of the head and neck only)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

    def to_plot(p):  # (x, y, z), +Y up -> matplotlib (x, -z, y), Z up
        return np.stack([p[..., 0], -p[..., 2], p[..., 1]], axis=-1)

    views = (("front", 5, -90), ("left side", 5, 0))
    fig = plt.figure(figsize=(4.5 * len(views), 6.0 * len(grooms)), dpi=110)
    tris = to_plot(body_view.triangles)
    light = unit(np.array([0.3, -1.0, 0.8]))
    shade = 0.6 + 0.4 * np.clip(to_plot(body_view.face_normals) @ light, 0, 1)
    face = np.c_[shade[:, None] * np.array([[0.90, 0.86, 0.82]]), np.full(len(tris), 1.0)]
    for row, (gname, (points, offsets, colour_by)) in enumerate(grooms.items()):
        strands = unpack(points, offsets)
        for col, (label, elev, azim) in enumerate(views):
            az = np.radians(azim)
            toward = np.array([np.cos(az), 0.0, -np.sin(az)])  # toward the camera, body coordinates
            near, far, cn, cf = [], [], [], []
            for k, stp in enumerate(strands):
                c = colour_by[offsets[k]:offsets[k + 1]]
                front = (stp[:, 0] * toward[0] + (stp[:, 2] + lean(stp[:, 1])) * toward[2]) > 0
                for j in range(len(stp) - 1):
                    seg = to_plot(stp[j:j + 2])
                    if front[j] or front[j + 1]:
                        near.append(seg)
                        cn.append(c[j])
                    else:
                        far.append(seg)
                        cf.append(c[j])
            ax = fig.add_subplot(len(grooms), len(views), row * len(views) + col + 1, projection="3d")
            ax.computed_zorder = False
            ax.add_collection3d(Line3DCollection(far, colors=cf, linewidths=0.5, alpha=0.9, zorder=1))
            poly = Poly3DCollection(tris, linewidths=0, zorder=2)
            poly.set_facecolor(face)
            ax.add_collection3d(poly)
            ax.add_collection3d(Line3DCollection(near, colors=cn, linewidths=0.5, alpha=0.9, zorder=3))
            if head:
                ax.set_xlim(-0.16, 0.16)
                ax.set_ylim(-0.20, 0.12)
                ax.set_zlim(1.45, 1.90)
                ax.set_box_aspect((0.32, 0.32, 0.45))
            else:
                ax.set_xlim(-0.26, 0.26)
                ax.set_ylim(-0.30, 0.22)
                ax.set_zlim(1.10, 1.84)
                ax.set_box_aspect((0.52, 0.52, 0.74))
            ax.view_init(elev=elev, azim=azim)
            ax.set_axis_off()
            ax.set_title(f"{gname}: {len(strands)} strands, {label}", fontsize=10)
    fig.suptitle(title, fontsize=10)
    fig.subplots_adjust(left=0, right=1, bottom=0, top=0.95, wspace=0, hspace=0.04)
    fig.subplots_adjust(top=0.93)
    fig.savefig(path)
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("names", nargs="*", metavar="NAME",
                        help=f"variants to write (default: all); development: {', '.join(DEVELOPMENT)}; "
                             f"held out: {', '.join(HELD_OUT)}")
    parser.add_argument("-o", "--outdir", default=str(ROOT / "out" / "grooms"),
                        help="output folder (default: out/grooms under the project root)")
    parser.add_argument("--pictures", action="store_true", help="also draw each kind once to OUTDIR/<kind>.png")
    args = parser.parse_args(argv)
    names = args.names or list(VARIANTS)
    unknown = [n for n in names if n not in VARIANTS]
    if unknown:
        parser.error(f"unknown variant(s) {', '.join(unknown)}; known: {', '.join(VARIANTS)}")
    out = Path(args.outdir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.time()
    mesh = build_mannequin()
    write_obj(out / "mannequin.obj", mesh)
    check = trimesh.load(out / "mannequin.obj", process=False)
    assert np.array_equal(check.vertices, mesh.vertices) and np.array_equal(check.faces, mesh.faces)
    body = mannequin()
    edges, counts = np.unique(mesh.edges_sorted, axis=0, return_counts=True)
    lo, hi = mesh.bounds
    print(f"mannequin.obj: {len(mesh.vertices)} vertices, {len(mesh.faces)} triangles, watertight {mesh.is_watertight}, "
          f"winding consistent {mesh.is_winding_consistent}, volume {mesh.volume * 1000:.1f} L; "
          f"bbox ({lo[0]:.3f}, {lo[1]:.3f}, {lo[2]:.3f})-({hi[0]:.3f}, {hi[1]:.3f}, {hi[2]:.3f}) m "
          f"[{time.time() - t0:.1f} s]")
    drawn = {}
    for name in names:
        t1 = time.time()
        path, points, offsets = write_variant(out, name, body)
        kind, params = VARIANTS[name]
        st = groom_stats(body, points, offsets)
        print(f"[{time.time() - t1:.1f} s] {'development' if name in DEVELOPMENT else 'held out'} -> {path}")
        report(name, st, params)
        label = "curly" if kind == "draped" and params.get("curl_radius", 0) > 0 else kind
        if args.pictures and label not in drawn:
            drawn[label] = (name, points, offsets, st["d"])
    if args.pictures:
        view = build_mannequin(40, 40)
        for label, (name, points, offsets, d) in drawn.items():
            base = np.array([0.45, 0.25, 0.10])
            colour = np.where((d < -1e-7)[:, None], np.array([[0.9, 0.0, 0.0]]), base[None, :])
            if "gap" in VARIANTS[name][1]:
                gap = VARIANTS[name][1]["gap"]
                touch = (d >= 0) & (d < gap + 0.0015)
                colour = np.where(touch[:, None], np.array([[0.1, 0.35, 0.85]]), colour)
            png = out / f"{label}.png"
            draw(view, {name: (points, offsets, colour)}, png,
                 f"{name} over mannequin.obj (blue: within gap + 1.5 mm of the body; red: inside the body)",
                 head=label in ("mohawk", "updo", "inside"))
            print(f"  picture {png}")
    print(f"done in {time.time() - t0:.1f} s")


if __name__ == "__main__":
    main()
