#!/usr/bin/env python
"""Regenerate the sample body mesh and grooms in ``samples/``.

Writes ``samples/body.obj`` (a stylised bust), ``samples/straight.h5``,
``samples/wavy.h5``, ``samples/curly.h5`` (hairinv stage files holding
``/curves``) and the preview picture ``docs/img/samples.png``.

Everything is in metres, +Y up, face toward +Z. The script is deterministic
(fixed seeds) and needs only numpy, scipy, trimesh, matplotlib and h5py::

    cd <project root> && .venv/bin/python samples/make_samples.py

How the hair is made: roots are spread evenly over the scalp of the body mesh
(farthest-point sampling of random surface points). Each strand's centre line
is grown in 2 mm steps with a direction that turns smoothly, never faster than
a set curvature: it leaves the scalp at a shallow angle, is combed along the
head at a small offset (later strands lie a little further out, so the hair
has some volume) while gravity bends it down, and below the widest part of
the head it turns down freely. Points a few centimetres ahead look for the
body, so a strand turns in time to slide over the shoulders and back instead
of running into them. The centre lines are then smoothed (Gaussian) and
pushed back out of the body where the smoothing pulled them in, twice; the
pushes are smooth bumps, not point moves, so they put no corners in. Waves
and curls are added as smooth offsets in a frame carried along the centre
line by parallel transport (turned slowly to face away from the body), and
the strands are resampled to evenly spaced points. The report checks the
turning angle at every vertex.

The body is a lofted surface: horizontal superelliptic rings whose
half-widths follow smooth profiles of the height. Because the profiles are
known analytically, the signed distance to the body is estimated in the
vertical half-plane through each point (distance to the 2-D meridian curve).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import trimesh
from scipy.interpolate import CubicSpline
from scipy.ndimage import gaussian_filter1d

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[0]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

Y_TOP = 1.735  # top of the head (pole of the mesh)
Y_BOT = 1.20  # the chest is cut open here
HEAD_C = 1.62  # height of the head centre (its widest ring)
G = np.array([0.0, -1.0, 0.0])


# --------------------------------------------------------------------------
# Body profiles
# --------------------------------------------------------------------------


def smoothstep(e0, e1, x):
    t = np.clip((np.asarray(x, float) - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def profile_parts(y):
    """The three parts the bust is blended from, at heights ``y``: head, neck and torso.

    Returns ``(a, bf, bb, n)`` per part: half-width along x, half-widths toward the
    front (+z) and the back (-z), each an array shaped like ``y``, and the part's
    superellipse exponent. ``profile`` blends them (a smooth maximum);
    ``make_rigs.py`` weights the mannequin's skin by them.
    """
    y = np.asarray(y, float)
    # Head: an ellipsoid centred at HEAD_C, a little longer below the centre
    # (chin), narrower at the jaw and tucked in at the back of the skull base.
    cy = np.where(y >= HEAD_C, Y_TOP - HEAD_C, 0.125)
    s = (y - HEAD_C) / cy
    e = np.sqrt(np.clip(1.0 - s * s, 0.0, None))
    low = smoothstep(0.0, -1.0, s)
    a_h = 0.078 * e * (1.0 - 0.14 * low)
    bf_h = 0.092 * e * (1.0 + 0.06 * low)
    bb_h = 0.098 * e * (1.0 - 0.22 * low)
    # Neck: a cylinder that fades out inside the head.
    nk = 1.0 - smoothstep(1.57, 1.67, y)
    a_n = 0.056 * nk
    bf_n = 0.052 * nk
    bb_n = 0.056 * nk
    # Torso: shoulders rounding off toward the neck, chest a bit narrower at the cut.
    st = np.clip((y - 1.355) / 0.118, 0.0, 1.0)
    f = np.sqrt(np.clip(1.0 - st * st, 0.0, None))
    a_t = (0.200 - 0.030 * smoothstep(1.36, 1.20, y)) * f
    bf_t = (0.100 + 0.008 * smoothstep(1.38, 1.25, y)) * f
    bb_t = 0.098 * f
    return (a_h, bf_h, bb_h, 2.0), (a_n, bf_n, bb_n, 2.0), (a_t, bf_t, bb_t, 2.6)


def profile(y):
    """Ring shape at heights ``y``.

    Returns half-width along x ``a``, half-widths toward the front (+z)
    ``bf`` and the back (-z) ``bb``, and the superellipse exponent ``n``.
    """
    y = np.asarray(y, float)
    (a_h, bf_h, bb_h, _), (a_n, bf_n, bb_n, _), (a_t, bf_t, bb_t, _) = profile_parts(y)
    k = 8.0
    comps_a = np.stack([a_h, a_n, a_t])
    tiny = 1e-9
    a = (np.sum(comps_a**k, axis=0) + tiny**k) ** (1.0 / k)
    bf = (np.sum(np.stack([bf_h, bf_n, bf_t]) ** k, axis=0) + tiny**k) ** (1.0 / k)
    bb = (np.sum(np.stack([bb_h, bb_n, bb_t]) ** k, axis=0) + tiny**k) ** (1.0 / k)
    total = np.sum(comps_a**k, axis=0)
    w = comps_a**k / np.maximum(total, 1e-300)
    n = np.where(total > 0, 2.0 * w[0] + 2.0 * w[1] + 2.6 * w[2], 2.0)
    return a, bf, bb, n


def ring_radius(theta, a, bf, bb, n):
    """Radius of a superelliptic ring in direction ``theta`` (broadcasting)."""
    c = np.abs(np.cos(theta))
    sn = np.sin(theta)
    b = np.where(sn >= 0.0, bf, bb)
    a = np.maximum(a, 1e-12)
    b = np.maximum(b, 1e-12)
    return ((c / a) ** n + (np.abs(sn) / b) ** n) ** (-1.0 / n)


def nose(theta, y):
    """A small nose on the face (+Z), so the bust's front is obvious."""
    g = smoothstep(1.630, 1.582, y) * smoothstep(1.560, 1.582, y)
    dth = np.angle(np.exp(1j * (theta - np.pi / 2)))
    return 0.015 * g * np.exp(-((dth / 0.15) ** 2))


def surface_radius(theta, y):
    """Distance of the surface from the vertical axis at angle ``theta`` (from +X toward +Z) and height ``y``."""
    a, bf, bb, n = profile(y)
    return ring_radius(theta, a, bf, bb, n) + nose(theta, y)


def meridian_heights(count, include_pole):
    """Heights from the top down, evenly spaced along the meridian arc
    (a little denser across the face)."""
    y = np.linspace(Y_TOP, Y_BOT, 4001)
    a, bf, bb, _ = profile(y)
    r = 0.5 * a + 0.25 * (bf + bb)
    weight = 1.0 + 0.8 * np.exp(-(((y - 1.59) / 0.035) ** 2))
    step = np.hypot(np.diff(r), np.diff(y)) * 0.5 * (weight[1:] + weight[:-1])
    arc = np.concatenate([[0.0], np.cumsum(step)])
    t = np.linspace(0.0, arc[-1], count + (0 if include_pole else 1))
    if not include_pole:
        t = t[1:]
    return np.interp(t, arc, y)


# --------------------------------------------------------------------------
# Mesh
# --------------------------------------------------------------------------


def build_body(n_rings=42, n_seg=64):
    """Lofted bust: a pole at the top, ``n_rings`` rings, open at the bottom."""
    ys = meridian_heights(n_rings, include_pole=False)
    theta = np.linspace(0.0, 2.0 * np.pi, n_seg, endpoint=False)
    r = surface_radius(theta[None, :], ys[:, None])
    verts = [np.array([[0.0, Y_TOP, 0.0]])]
    ring = np.stack(
        [r * np.cos(theta)[None, :], np.broadcast_to(ys[:, None], r.shape), r * np.sin(theta)[None, :]], axis=-1
    )
    verts.append(ring.reshape(-1, 3))
    verts = np.concatenate(verts)
    idx = 1 + np.arange(n_rings * n_seg).reshape(n_rings, n_seg)
    nxt = np.roll(idx, -1, axis=1)
    faces = [np.stack([np.zeros(n_seg, int), nxt[0], idx[0]], axis=1)]
    for i in range(n_rings - 1):
        faces.append(np.stack([idx[i], nxt[i], nxt[i + 1]], axis=1))
        faces.append(np.stack([idx[i], nxt[i + 1], idx[i + 1]], axis=1))
    faces = np.concatenate(faces)
    mesh = trimesh.Trimesh(verts, faces, process=False)
    if capped(mesh).volume < 0:
        mesh = trimesh.Trimesh(verts, faces[:, ::-1], process=False)
    return mesh


def capped(mesh):
    """Copy of the bust with its bottom hole closed by a fan (for volume and ray tests)."""
    edges = mesh.edges_sorted
    uniq, counts = np.unique(edges, axis=0, return_counts=True)
    boundary = np.unique(uniq[counts == 1])
    centre = mesh.vertices[boundary].mean(axis=0)
    # boundary loop in face order: directed edges whose reverse is missing
    directed = mesh.edges
    key = set(map(tuple, directed))
    loop = [tuple(e) for e in directed if (e[1], e[0]) not in key]
    verts = np.vstack([mesh.vertices, centre])
    c = len(mesh.vertices)
    cap = np.array([[c, e[1], e[0]] for e in loop])
    return trimesh.Trimesh(verts, np.vstack([mesh.faces, cap]), process=False)


def write_obj(path, mesh, header=("hairinv sample body: a stylised bust (head, neck, shoulders), open at the chest",
                                  "units: metres; +Y up; face toward +Z", "written by samples/make_samples.py")):
    lines = [f"# {line}" for line in header] + [f"# {len(mesh.vertices)} vertices, {len(mesh.faces)} triangles"]
    lines += [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in mesh.vertices]
    lines += [f"f {i + 1} {j + 1} {k + 1}" for i, j, k in mesh.faces]
    Path(path).write_text("\n".join(lines) + "\n")


# --------------------------------------------------------------------------
# Analytic distance to the body
# --------------------------------------------------------------------------


class Body:
    """Signed distance to the lofted surface, measured in the vertical half-plane
    through the point (distance to the meridian curve in that direction).

    Outside the body the value is positive. Below the cut (y < Y_BOT) nothing
    counts as inside.
    """

    def __init__(self, k=300, n_theta=720):
        self.y = meridian_heights(k, include_pole=True)
        self.theta = np.linspace(-np.pi, np.pi, n_theta + 1)
        self.table = surface_radius(self.theta[:, None], self.y[None, :])  # (T, K)
        self.dth = self.theta[1] - self.theta[0]

    def query(self, p, window=40):
        """Signed distance ``d`` (S,) and outward unit normal (S, 3) at points ``p``.

        Only the meridian segments within ``window`` of the point's own height
        are searched: enough for anything within a few cm of the surface.
        """
        x, y, z = p[:, 0], p[:, 1], p[:, 2]
        rho = np.hypot(x, z)
        th = np.arctan2(z, x)
        u = (th + np.pi) / self.dth
        it = np.clip(np.floor(u).astype(int), 0, len(self.theta) - 2)
        ft = (u - it)[:, None]
        nk = len(self.y)
        yy = np.clip(y, Y_BOT, Y_TOP)
        kk = np.clip(np.searchsorted(-self.y, -yy) - 1, 0, nk - 2)
        lo = np.clip(kk - window, 0, max(nk - 1 - 2 * window, 0))
        idx = lo[:, None] + np.arange(min(2 * window + 1, nk))[None, :]  # (S, W) meridian points
        r = self.table[it[:, None], idx] * (1 - ft) + self.table[it[:, None] + 1, idx] * ft
        ym = self.y[idx]
        ra, rb = r[:, :-1], r[:, 1:]
        ya, yb = ym[:, :-1], ym[:, 1:]
        ex = rb - ra
        ey = yb - ya
        qx = rho[:, None] - ra
        qy = y[:, None] - ya
        t = np.clip((qx * ex + qy * ey) / (ex * ex + ey * ey), 0.0, 1.0)
        dx = qx - t * ex
        dy = qy - t * ey
        d2 = dx * dx + dy * dy
        j = np.argmin(d2, axis=1)
        rows = np.arange(len(p))
        dist = np.sqrt(d2[rows, j])
        vx = dx[rows, j]
        vy = dy[rows, j]
        # inside test: closer to the axis than the ring at the point's own height
        jj = kk - lo
        w = (self.y[kk] - yy) / (self.y[kk] - self.y[kk + 1])
        r_here = r[rows, jj] * (1 - w) + r[rows, jj + 1] * w
        inside = (rho < r_here) & (y >= Y_BOT) & (y <= Y_TOP)
        sign = np.where(inside, -1.0, 1.0)
        safe = np.maximum(dist, 1e-12)
        nr = vx / safe * sign
        ny = vy / safe * sign
        # points (almost) on the surface: use the meridian segment's normal
        flat = dist < 1e-7
        if np.any(flat):
            sx = ex[rows, j]
            sy = ey[rows, j]
            ln = np.hypot(sx, sy)
            nr = np.where(flat, -sy / ln, nr)
            ny = np.where(flat, sx / ln, ny)
        # outward normal of the meridian (r, y) -> 3-D
        normal = np.stack([nr * np.cos(th), ny, nr * np.sin(th)], axis=1)
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        return sign * dist, normal


def unit(v):
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)


def tangential(v, n):
    return v - np.sum(v * n, axis=-1, keepdims=True) * n


# --------------------------------------------------------------------------
# Roots
# --------------------------------------------------------------------------


def scalp_mask(p):
    """True on the scalp: top, back and sides of the head and the nape; not the face."""
    phi = np.abs(np.arctan2(p[:, 0], -p[:, 2]))  # 0 at the back, pi at the face
    hairline = np.interp(
        phi, [0.0, 0.5, 1.0, 1.4, 1.8, 2.3, 2.7, np.pi], [1.505, 1.512, 1.540, 1.580, 1.600, 1.655, 1.675, 1.680]
    )
    return p[:, 1] > hairline


def sample_roots(mesh, count, rng, n_candidates=12000):
    """Evenly spread points on the scalp triangles (farthest-point sampling)."""
    tri = mesh.triangles
    head = tri[:, :, 1].min(axis=1) > 1.50
    tri = tri[head]
    area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1) / 2
    pick = rng.choice(len(tri), size=n_candidates * 2, p=area / area.sum())
    u = rng.random((len(pick), 2))
    flip = u.sum(axis=1) > 1
    u[flip] = 1 - u[flip]
    t = tri[pick]
    pts = t[:, 0] + u[:, :1] * (t[:, 1] - t[:, 0]) + u[:, 1:] * (t[:, 2] - t[:, 0])
    pts = pts[scalp_mask(pts)][:n_candidates]
    chosen = [int(rng.integers(len(pts)))]
    dmin = np.linalg.norm(pts - pts[chosen[0]], axis=1)
    for _ in range(count - 1):
        i = int(np.argmax(dmin))
        chosen.append(i)
        dmin = np.minimum(dmin, np.linalg.norm(pts - pts[i], axis=1))
    return pts[chosen]


# --------------------------------------------------------------------------
# Strands
# --------------------------------------------------------------------------


def comb_direction(roots, normal):
    """Where each strand is combed: away from a centre parting, toward the back."""
    u = np.stack([roots[:, 0] / 0.078, (roots[:, 1] - HEAD_C) / 0.115, roots[:, 2] / 0.095], axis=1)
    side = np.sign(u[:, 0]) * np.minimum(np.abs(u[:, 0]) * 4.0, 1.0)
    c = np.stack([1.1 * side + 0.6 * u[:, 0], np.full(len(u), -0.4), -0.7 + 0.3 * u[:, 2]], axis=1)
    return unit(tangential(c, normal))


NEAR = 12  # meridian window of distance queries that only need to be right within about 2 cm of the body


def query(body, p, chunk=20000):
    """``Body.query`` for points of any leading shape that only matter near the body."""
    shape = p.shape[:-1]
    flat = p.reshape(-1, 3)
    d = np.empty(len(flat))
    n = np.empty_like(flat)
    for i in range(0, len(flat), chunk):
        d[i : i + chunk], n[i : i + chunk] = body.query(flat[i : i + chunk], window=NEAR)
    return d.reshape(shape), n.reshape(shape + (3,))


def radial_normal(p, h=1e-4):
    """Outward normal of the body surface at the height and azimuth of points ``p``
    (the surface point straight out from the vertical axis, not the nearest one)."""
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    th = np.arctan2(z, x)
    rho = np.hypot(x, z)
    r = surface_radius(th, y)
    dr_dy = (surface_radius(th, y + h) - surface_radius(th, y - h)) / (2 * h)
    dr_dth = (surface_radius(th + h, y) - surface_radius(th - h, y)) / (2 * h)
    e_rho = np.stack([np.cos(th), np.zeros_like(th), np.sin(th)], axis=1)
    e_th = np.stack([-np.sin(th), np.zeros_like(th), np.cos(th)], axis=1)
    g = e_rho - (dr_dth / np.maximum(np.maximum(rho, r), 1e-6))[:, None] * e_th + dr_dy[:, None] * G[None, :]
    return unit(g)


def no_closer(w, n, vn, weight=1.0):
    """Directions ``w`` with their component along the surface normals ``n`` raised
    to at least ``vn`` (fully where ``weight`` is 1, not at all where it is 0)."""
    wn = np.sum(w * n, axis=1)
    lift = weight * (np.maximum(wn, vn) - wn)
    return unit(w + lift[:, None] * n)


def turn_toward(t, w, max_angle, share=1.0):
    """Rotate unit vectors ``t`` toward unit vectors ``w`` by ``share`` of the angle
    between them, but by at most ``max_angle`` radians."""
    c = np.clip(np.sum(t * w, axis=1), -1.0, 1.0)
    ang = np.arccos(c)
    e = w - c[:, None] * t
    en = np.linalg.norm(e, axis=1)
    ok = en > 1e-12
    step = np.minimum(ang * share, max_angle)
    out = t.copy()
    e = e[ok] / en[ok, None]
    out[ok] = t[ok] * np.cos(step[ok])[:, None] + e * np.sin(step[ok])[:, None]
    return unit(out)


def march(body, roots, off_head, off_fall, steps, kappa, ds=0.002, r_head=0.10, r_fall=0.08, approach=0.03,
          climb=np.radians(15.0), feelers=(0.01, 0.02, 0.035, 0.05, 0.07, 0.09, 0.12, 0.16), deep=0.008):
    """Guide paths of all strands, grown together in steps of ``ds``: (steps + 1, S, 3).

    The direction of a strand turns smoothly, never faster than ``kappa``
    (radians per metre), toward where the strand wants to go. On the head that
    is along the scalp in the comb direction, bent down by gravity, at the
    height ``off_head``: a strand leaves the scalp climbing (at most ``climb``)
    and levels off at that height over about ``approach``; where the head
    curves more sharply than ``kappa`` the strand stands off it a little. Once
    below the widest part of the head a strand turns down under gravity (over
    about ``r_fall``). Points ``feelers`` ahead of it look for the body: where
    the strand would come closer than ``off_fall`` it turns, the more the
    deeper (up to ``deep``) the feeler is, to run along the surface there.
    Returns the paths and the step at which each strand started to fall.
    """
    _, n0 = body.query(roots)
    p = roots.copy()
    comb = comb_direction(roots, n0)
    fall = n0[:, 1] < 0.0  # roots at the nape hang down the neck at once
    vn0 = np.clip(off_head / approach, 0.0, np.sin(climb))
    t = unit(comb * np.sqrt(1.0 - vn0**2)[:, None] + n0 * vn0[:, None])
    t[fall] = unit(tangential(G[None, :], n0[fall]) + np.tan(climb) * n0[fall])
    k_fall = np.where(fall, 0, steps + 1)
    out = [p.copy()]
    turn = kappa * ds
    lam = np.asarray(feelers)
    for k in range(1, steps + 1):
        head = ~fall
        want = t.copy()
        if np.any(head):
            d, n = body.query(p[head], window=NEAR)
            along = unit(tangential(t[head], n) + tangential(G[None, :], n) * (ds / r_head))
            vn = np.clip((off_head[head] - d) / approach, -np.sin(climb), np.sin(climb))
            want[head] = along * np.sqrt(1.0 - vn**2)[:, None] + n * vn[:, None]
            now = np.flatnonzero(head)[n[:, 1] < 0.0]
            fall[now] = True
            k_fall[now] = k
        fa = fall & ~head  # strands that were falling before this step
        if np.any(fa):
            pf, tf, need = p[fa], t[fa], off_fall[fa]
            w = turn_toward(tf, np.broadcast_to(G, tf.shape), np.inf, ds / r_fall)
            # look ahead along the current direction for where the strand would
            # come too close; turn to run along the surface there once that is
            # within the distance the strand needs to turn that far
            d0 = body.query(pf, window=NEAR)[0]
            need_ahead = np.minimum(need, d0 - 0.002)  # what is already too close is dealt with below
            d, _ = query(body, pf[None] + tf[None] * lam[:, None, None])
            hit = d < need_ahead[None]
            c = hit.any(axis=0)
            if np.any(c):
                j = np.argmax(hit[:, c], axis=0)
                hi = lam[j]
                lo = np.where(j > 0, lam[np.maximum(j - 1, 0)], 0.0)
                pc, tc, nc = pf[c], tf[c], need_ahead[c]
                for _ in range(4):
                    mid = 0.5 * (lo + hi)
                    inside = body.query(pc + tc * mid[:, None], window=NEAR)[0] < nc
                    hi = np.where(inside, mid, hi)
                    lo = np.where(inside, lo, mid)
                # the surface's normal a little below where the ray enters (the
                # nearest-point normal would be the neck's in the corner between
                # neck and shoulders)
                ne = radial_normal(pc + tc * (hi + deep)[:, None])
                brake = np.maximum(-np.sum(tc * ne, axis=1), 0.0) / kappa * 1.2 + 0.002
                weight = np.clip((1.5 * brake - hi) / (0.75 * brake), 0.0, 1.0)
                w[c] = no_closer(w[c], ne, 0.0, weight)
            # close already: run along the surface; too close: move away
            d, n = body.query(pf, window=NEAR)
            c = d < need + 0.001
            vn = np.clip((need[c] - d[c]) / approach, 0.0, np.sin(climb))
            w[c] = no_closer(w[c], n[c], vn, np.clip((need[c] + 0.001 - d[c]) / 0.001, 0.0, 1.0))
            want[fa] = w
        t = turn_toward(t, unit(want), turn)
        p = p + t * ds
        out.append(p.copy())
    return np.stack(out), k_fall


def arclength(pts):
    """Arc length at each point of a polyline (N, 3), or of strands stacked along axis 0 (N, S, 3)."""
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=-1)
    return np.concatenate([np.zeros((1,) + seg.shape[1:]), np.cumsum(seg, axis=0)])


def resample(pts, count, length=None):
    """``count`` points evenly spaced along the first ``length`` of a polyline."""
    s = arclength(pts)
    total = s[-1] if length is None else min(length, s[-1])
    q = np.linspace(0.0, total, count)
    return np.stack([np.interp(q, s, pts[:, k]) for k in range(3)], axis=1)


def blur(a, sigma, fixed_ends=True):
    """Gaussian smoothing along axis 0 with ``sigma`` in samples.

    With ``fixed_ends`` the data are extended by point reflection at both ends,
    which keeps the end points where they are and the curve straight there.
    """
    if sigma <= 0:
        return a
    if not fixed_ends:
        return gaussian_filter1d(a, sigma, axis=0, mode="nearest", truncate=3.0)
    pad = min(int(3.0 * sigma + 0.5) + 1, len(a) - 1)
    ext = np.concatenate([2 * a[:1] - a[1 : pad + 1][::-1], a, 2 * a[-1:] - a[-pad - 1 : -1][::-1]])
    return gaussian_filter1d(ext, sigma, axis=0, mode="nearest", truncate=3.0)[pad : pad + len(a)]


def soft_push(body, p, need, hold, width, iters=10, margin=0.001):
    """Move points of strands ``p`` (K, S, 3) to at least ``need`` (K, S) outside the body
    with a smooth displacement field.

    Each deficit is spread along the strand as a Gaussian bump of ``width``
    samples (a running maximum of the bumps, then blurred), so pushing a
    strand out of the body bends it gently instead of putting a corner in it.
    ``hold`` (K, S) scales the displacement (0 keeps the root in place).
    Points more than ``margin`` beyond their ``need`` only move outward, so
    they are not looked at again.
    """
    reach = int(3.0 * width)
    d, n = query(body, p)
    active = d < need + margin
    for _ in range(iters):
        deficit = np.maximum(need - d, 0.0)
        if deficit.max() < 1e-6:
            break
        mag = deficit.copy()
        for j in range(1, min(reach, len(p) - 1) + 1):
            g = np.exp(-0.5 * (j / width) ** 2)
            np.maximum(mag[j:], g * deficit[:-j], out=mag[j:])
            np.maximum(mag[:-j], g * deficit[j:], out=mag[:-j])
        mag = blur(mag, 0.4 * width, fixed_ends=False) * hold
        p = p + n * (1.1 * mag)[..., None]
        active &= d - mag < need + margin
        d[active], n[active] = query(body, p[active])
    # what is left (a few micrometres) is pushed point by point
    deficit = np.maximum(need - d, 0.0) * (hold > 0)
    return p + n * deficit[..., None]


def relax(body, p, need, hold, ds, passes):
    """Smooth guide paths ``p`` (K, S, 3) and push them back out of the body, a few times.

    ``passes`` holds (smoothing sigma, push width) in metres; ``need`` and
    ``hold`` are as for ``soft_push``.
    """
    for sigma, width in passes:
        p = soft_push(body, blur(p, sigma / ds), need, hold, width / ds)
    return p


def transported_frames(p, normal, sigma):
    """Two unit normals ``u``, ``v`` of strands ``p`` (K, S, 3), smooth along them.

    The normals are carried along by parallel transport and then turned about
    the tangent by a slowly varying angle so that ``u`` points away from the
    body (``normal``) on average over ``sigma`` samples.
    """
    tang = unit(np.gradient(p, axis=0))
    u = np.empty_like(p)
    u0 = tangential(normal[0], tang[0])
    u0 = np.where(np.linalg.norm(u0, axis=1, keepdims=True) > 1e-6, u0, tangential(-G[None, :], tang[0]))
    u[0] = unit(u0)
    for k in range(1, len(p)):
        # rotate the previous normal by the rotation taking tang[k-1] to tang[k]
        a, b = tang[k - 1], tang[k]
        axis = np.cross(a, b)
        c = np.sum(a * b, axis=1, keepdims=True)
        prev = u[k - 1]
        rot = prev * c + np.cross(axis, prev) + axis * (np.sum(axis * prev, axis=1, keepdims=True) / (1.0 + c))
        u[k] = unit(tangential(rot, b))
    v = np.cross(tang, u)
    cu = blur(np.sum(normal * u, axis=-1), sigma, fixed_ends=False)
    cv = blur(np.sum(normal * v, axis=-1), sigma, fixed_ends=False)
    phi = np.arctan2(cv, cu)[..., None]
    u2 = np.cos(phi) * u + np.sin(phi) * v
    return u2, np.cross(tang, u2)


def shape_params(kind, count, rng):
    """Per-strand wave or curl parameters."""
    if kind == "wavy":
        lam = rng.uniform(0.09, 0.12, count)  # wavelength
        kappa = rng.uniform(11.0, 16.0, count)  # curvature at the crests, 1/m
        return dict(
            amp=kappa / (2 * np.pi / lam) ** 2,
            lam=lam,
            ramp=rng.uniform(0.06, 0.09, count),
            phase=rng.uniform(0, 2 * np.pi, count),
            tilt=rng.uniform(-0.35, 0.35, count),  # mostly along the surface, a little off it
        )
    if kind == "curly":
        return dict(
            rad=rng.uniform(0.0055, 0.007, count),
            pitch=rng.uniform(0.025, 0.030, count),
            ramp=rng.uniform(0.04, 0.06, count),
            phase=rng.uniform(0, 2 * np.pi, count),
            hand=rng.choice([-1.0, 1.0], count),
        )
    return {}


def centre_pad(kind, prm):
    """How far the wave or curl reaches toward the body from the centre line (S,)."""
    if kind == "wavy":  # (the frame follows the body normal only on average)
        return prm["amp"] * (np.abs(prm["tilt"]) + 0.05) / np.sqrt(1.0 + prm["tilt"] ** 2)
    if kind == "curly":
        return prm["rad"]
    return 0.0


def add_shape(base, u, v, s, kind, prm):
    """Add a wave (along the surface, tilted a little off it) or a helical curl
    around centre lines ``base`` (K, S, 3) with frames ``u``, ``v`` and arc length ``s``."""
    if kind == "wavy":
        ramp = smoothstep(0.0, prm["ramp"], s)
        w = unit(v + prm["tilt"][None, :, None] * u)
        off = prm["amp"] * ramp * np.sin(2 * np.pi * s / prm["lam"] + prm["phase"])
        return base + off[..., None] * w
    if kind == "curly":
        # the curl grows in over the first few cm, winding up from a looser pitch
        ramp = smoothstep(0.0, prm["ramp"], s)
        rate = 2 * np.pi / prm["pitch"] * (0.4 + 0.6 * ramp)
        turned = np.cumsum(0.5 * (rate[1:] + rate[:-1]) * np.diff(s, axis=0), axis=0)
        ph = prm["phase"] + prm["hand"] * np.concatenate([np.zeros((1,) + s.shape[1:]), turned])
        off = np.cos(ph)[..., None] * u + np.sin(ph)[..., None] * v
        return base + (prm["rad"] * ramp)[..., None] * off
    return base


GROOMS = {
    # name: strand count, points per strand (min, max) and their target spacing in metres,
    # largest curvature of the centre lines (1/m), length range in metres, random seed
    "straight": dict(count=300, points=(24, 40), spacing=0.0095, kappa=12.0, length=(0.25, 0.40), seed=11),
    "wavy": dict(count=280, points=(32, 48), spacing=0.0072, kappa=13.0, length=(0.25, 0.35), seed=22),
    "curly": dict(count=260, points=(64, 96), spacing=0.0025, kappa=9.0, length=(0.15, 0.24), seed=33),
}


def make_groom(body, mesh, name, spec, ds=0.002):
    """Strands of one groom (a list of (N, 3) arrays) and per-strand notes."""
    rng = np.random.default_rng(spec["seed"])
    count = spec["count"]
    roots = sample_roots(mesh, count, rng)
    layer = np.arange(count) / (count - 1)
    off_head = 0.0015 + 0.0085 * layer + rng.uniform(0, 0.001, count)
    off_fall = 0.0010 + 0.0015 * layer
    lo, hi = spec["length"]
    if name == "curly":  # a curly bob: longer at the back and the nape, shorter on top
        uy = np.clip((roots[:, 1] - HEAD_C) / 0.115, -0.6, 1.0)
        lengths = lo + (hi - lo) * np.clip(0.55 * (1.0 - uy) / 1.6 + 0.45 * rng.random(count), 0, 1)
    else:
        lengths = rng.uniform(lo, hi, count)
    pmin, pmax = spec["points"]
    npts = np.clip(np.round(lengths / spec["spacing"]).astype(int) + 1 + rng.integers(-2, 3, count), pmin, pmax)
    prm = shape_params(name, count, rng)
    pad = centre_pad(name, prm)

    # 1) guide paths (centre lines); curls need less centre line than their length
    base_len = lengths.max() * (0.7 if name == "curly" else 1.0) + 0.06
    steps = int(np.ceil(base_len / ds))
    path, k_fall = march(body, roots, off_head + pad, off_fall + pad, steps, spec["kappa"], ds)

    # 2) smooth them a little, not letting them come closer to the body
    k = np.arange(steps + 1)[:, None]
    s = k * ds
    d, _ = query(body, path)
    ramp = smoothstep(0.0, prm["ramp"], s) if name != "straight" else 1.0
    # (at least 0.8 mm plus room for the wave or curl beyond the first 2 cm; near
    # the root the smoothing may bring a path a little closer than it was)
    nominal = off_fall + pad * ramp
    floor = (0.0008 + pad * ramp) * smoothstep(0.0, 0.02, s)
    need = np.maximum(np.minimum(d, nominal), floor) - 0.0005 * (1.0 - smoothstep(0.0, 0.03, s))
    hold = smoothstep(0.0, 0.01, s) * np.ones((1, count))
    path = relax(body, path, need, hold, ds, ((1.5 * spec["spacing"], 0.012), (0.8 * spec["spacing"], 0.010)))

    # 3) the wave or curl, on a finer grid
    up = 4 if name == "curly" else 2
    fine_k = np.linspace(0, steps, steps * up + 1)
    d, normal = query(body, path)
    base = CubicSpline(k[:, 0], path, axis=0)(fine_k)
    normal = CubicSpline(k[:, 0], normal, axis=0)(fine_k)
    d = CubicSpline(k[:, 0], d, axis=0)(fine_k)
    sb = arclength(base)
    u, v = transported_frames(base, normal, 0.03 / (ds / up))
    strands = add_shape(base, u, v, sb, name, prm)

    # 4) nothing inside the body, then even spacing
    sf = arclength(strands)
    need = np.minimum(0.0008, d)
    hold = smoothstep(0.0, 0.004, sf)
    strands = soft_push(body, strands, need, hold, 0.008 / (ds / up))
    out = [resample(strands[:, i], npts[i], lengths[i]) for i in range(count)]
    notes = {}
    if name == "curly":
        turn = np.hypot(2 * np.pi * prm["rad"], prm["pitch"])
        notes["points per turn"] = turn / (lengths / (npts - 1))
    return out, notes


# --------------------------------------------------------------------------
# Checks, files, picture
# --------------------------------------------------------------------------


def write_curves(path, strands, source):
    points = np.concatenate(strands).astype(np.float64)
    offsets = np.concatenate([[0], np.cumsum([len(s) for s in strands])]).astype(np.int64)
    try:
        from hairinv.formats.hdf5 import write_hdf5_curves
    except Exception:  # the formats package may be incomplete; write the stage file directly
        from hairinv import stages

        group = stages.Group(
            stages.CURVES,
            {"points": points, "offsets": offsets},
            attrs={"source": source, "scale_to_m": 1.0, "up": np.array([0.0, 1.0, 0.0])},
        )
        stages.write_stage(path, [group], "samples")
    else:
        write_hdf5_curves(path, points, offsets, up=(0.0, 1.0, 0.0), source=source, command="samples")


def report_body(mesh):
    edges, counts = np.unique(mesh.edges_sorted, axis=0, return_counts=True)
    areas = mesh.area_faces
    cap = capped(mesh)
    lo, hi = mesh.bounds
    print(
        f"body.obj: {len(mesh.vertices)} vertices, {len(mesh.faces)} triangles, "
        f"boundary edges {int(np.sum(counts == 1))}, non-manifold edges {int(np.sum(counts > 2))}, "
        f"min triangle area {areas.min():.2e} m^2"
    )
    print(f"  bbox min ({lo[0]:.3f}, {lo[1]:.3f}, {lo[2]:.3f})  max ({hi[0]:.3f}, {hi[1]:.3f}, {hi[2]:.3f}) m")
    radial = mesh.vertices - np.c_[np.zeros(len(mesh.vertices)), mesh.vertices[:, 1], np.zeros(len(mesh.vertices))]
    vn = mesh.vertex_normals
    print(
        f"  winding consistent {mesh.is_winding_consistent}, capped copy watertight {cap.is_watertight}, "
        f"capped volume {cap.volume * 1000:.2f} L, mean normal.radial {np.mean(np.sum(vn * unit(radial), axis=1)):.3f}"
    )
    return cap


def mesh_signed_distance(mesh, points):
    """Distance to the mesh, negative on the inner side of the nearest triangle."""
    closest, dist, tri = trimesh.proximity.closest_point(mesh, points)
    side = np.sum((points - closest) * mesh.face_normals[tri], axis=1)
    return np.where(side < 0, -dist, dist)


def turning_angles(st):
    """Angle in degrees between consecutive segments at each interior vertex."""
    d = unit(np.diff(st, axis=0))
    return np.degrees(np.arccos(np.clip(np.sum(d[:-1] * d[1:], axis=1), -1.0, 1.0)))


def isolated_corners(st, floor=1.0):
    """Vertices of a polyline turning more than twice as much as their neighbours
    on average (and more than ``floor`` degrees).

    The first and last turning vertex have one neighbour only; there the
    comparison is with the larger of that neighbour's turn and the turn
    extrapolated linearly from the next two vertices (as turning vectors, so
    that a curve just past an inflection does not count).
    """
    angles = turning_angles(st)
    if len(angles) < 3:
        return 0
    d = unit(np.diff(st, axis=0))
    turn = unit(np.cross(d[:-1], d[1:])) * angles[:, None]  # turning vectors, degrees
    nb = np.empty_like(angles)
    nb[1:-1] = 0.5 * (angles[:-2] + angles[2:])
    nb[0] = max(angles[1], np.linalg.norm(2 * turn[1] - turn[2]))
    nb[-1] = max(angles[-2], np.linalg.norm(2 * turn[-2] - turn[-3]))
    return int(np.sum((angles > 2.0 * nb) & (angles > floor)))


def report_groom(name, strands, mesh, body, notes=None):
    counts = np.array([len(s) for s in strands])
    lengths = np.array([arclength(s)[-1] for s in strands])
    roots = np.array([s[0] for s in strands])
    _, rd, _ = trimesh.proximity.closest_point(mesh, roots)
    rest = np.concatenate([s[1:] for s in strands])
    s_along = np.concatenate([arclength(s)[1:] for s in strands])
    owner = np.concatenate([np.full(len(s) - 1, i) for i, s in enumerate(strands)])
    # Points more than 5 mm outside the analytic surface are outside the mesh
    # (the mesh is within 0.5 mm of it); the others are measured on the mesh.
    d_an, _ = body.query(rest)
    cand = np.flatnonzero(d_an < 0.005)
    d_mesh = np.full(len(rest), np.inf)
    d_mesh[cand] = mesh_signed_distance(mesh, rest[cand])
    inside = d_mesh < 0
    near = (d_mesh < 0.003) & (s_along > 0.02)
    below = rest[:, 1] < 1.52  # below the head (the chin is at 1.495, the skull base about 1.55)
    touch_low = np.unique(owner[near & below])
    touch_head = np.unique(owner[near & ~below])
    seg = np.concatenate([np.diff(arclength(s)) / (arclength(s)[-1] / (len(s) - 1)) for s in strands])
    print(
        f"{name}: {len(strands)} strands, {counts.sum()} points, points/strand {counts.min()}-{counts.max()}, "
        f"length min/median/max {lengths.min():.3f}/{np.median(lengths):.3f}/{lengths.max():.3f} m"
    )
    print(
        f"  max root distance to body {rd.max() * 1000:.4f} mm; non-root points inside body "
        f"{inside.mean() * 100:.2f}% ({int(inside.sum())}); min distance of non-root points "
        f"{d_mesh.min() * 1000:.2f} mm"
    )
    print(
        f"  strands with a point within 3 mm of the body: below the head {len(touch_low) / len(strands) * 100:.1f}%, "
        f"on the head (beyond 2 cm from the root) {len(touch_head) / len(strands) * 100:.1f}%; "
        f"segment length / strand mean {seg.min():.3f}-{seg.max():.3f}"
    )
    angles = [turning_angles(s) for s in strands]
    flat = np.concatenate(angles)
    corners = sum(isolated_corners(s) for s in strands)
    line = (
        f"  turning angle per vertex max {flat.max():.2f} deg, 99th percentile {np.percentile(flat, 99):.2f} deg; "
        f"isolated corners (> 2x the neighbours' mean and > 1 deg) {corners}"
    )
    if notes and "points per turn" in notes:
        ppt = notes["points per turn"]
        line += f"; points per turn of curl min/median/max {ppt.min():.1f}/{np.median(ppt):.1f}/{ppt.max():.1f}"
    print(line)


def draw(mesh_view, grooms, path, views=(("front-left 3/4 view", 10, -55), ("left side view", 4, 0))):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

    def to_plot(p):  # (x, y, z) with +Y up -> matplotlib (x, -z, y) with Z up
        return np.stack([p[..., 0], -p[..., 2], p[..., 1]], axis=-1)

    def split(strands, toward):
        """Strand pieces on the camera's side of the body axis, and the others."""
        near, far = [], []
        for st in strands:
            front = (st[:, 0] * toward[0] + st[:, 2] * toward[2]) > 0
            seg_front = front[:-1] | front[1:]
            start = 0
            for k in range(1, len(seg_front) + 1):
                if k == len(seg_front) or seg_front[k] != seg_front[start]:
                    (near if seg_front[start] else far).append(to_plot(st[start : k + 1]))
                    start = k
        return near, far

    colours = {"straight": (0.45, 0.25, 0.10), "wavy": (0.80, 0.55, 0.18), "curly": (0.22, 0.13, 0.08)}
    fig = plt.figure(figsize=(12, 4.5 * len(views)), dpi=110)
    tris = to_plot(mesh_view.triangles)
    light = unit(np.array([0.3, -1.0, 0.8]))
    shade = 0.6 + 0.4 * np.clip(to_plot(mesh_view.face_normals) @ light, 0, 1)
    face = np.c_[shade[:, None] * np.array([[0.90, 0.86, 0.82]]), np.full(len(tris), 0.85)]
    for row, (label, elev, azim) in enumerate(views):
        el, az = np.radians(elev), np.radians(azim)
        toward = np.array([np.cos(az), 0.0, -np.sin(az)])  # camera direction, body coordinates
        for col, (name, strands) in enumerate(grooms.items()):
            ax = fig.add_subplot(len(views), 3, row * 3 + col + 1, projection="3d")
            ax.computed_zorder = False
            near, far = split(strands, toward)
            base = np.array(colours[name])
            ax.add_collection3d(Line3DCollection(far, colors=[base], linewidths=0.6, alpha=0.9, zorder=1))
            body = Poly3DCollection(tris, linewidths=0, zorder=2)
            body.set_facecolor(face)
            ax.add_collection3d(body)
            ax.add_collection3d(Line3DCollection(near, colors=[base], linewidths=0.6, alpha=0.9, zorder=3))
            ax.set_xlim(-0.24, 0.24)
            ax.set_ylim(-0.24, 0.24)
            ax.set_zlim(1.16, 1.76)
            ax.set_box_aspect((0.48, 0.48, 0.60))
            ax.view_init(elev=elev, azim=azim)
            ax.set_axis_off()
            ax.set_title(f"{name}: {len(strands)} strands, {label}", fontsize=10)
    fig.text(0.5, 0.005, "samples/body.obj with samples/straight.h5, wavy.h5, curly.h5 (metres, +Y up, face toward +Z)",
             ha="center", fontsize=9, color="0.3")
    fig.subplots_adjust(left=0, right=1, bottom=0.02, top=0.96, wspace=0, hspace=0.06)
    fig.savefig(path)
    plt.close(fig)


def main():
    t0 = time.time()
    mesh = build_body()
    write_obj(HERE / "body.obj", mesh)
    mesh = trimesh.load(HERE / "body.obj", process=False)
    report_body(mesh)
    body = Body()
    grooms = {}
    for name, spec in GROOMS.items():
        strands, notes = make_groom(body, mesh, name, spec)
        write_curves(HERE / f"{name}.h5", strands, f"hairinv sample groom '{name}' (samples/make_samples.py)")
        report_groom(name, strands, mesh, body, notes)
        grooms[name] = strands
    img = ROOT / "docs" / "img"
    img.mkdir(parents=True, exist_ok=True)
    draw(build_body(24, 32), grooms, img / "samples.png")
    for f in ["body.obj", "straight.h5", "wavy.h5", "curly.h5"]:
        print(f"  {f}: {(HERE / f).stat().st_size / 1024:.0f} KiB")
    print(f"  docs/img/samples.png: {(img / 'samples.png').stat().st_size / 1024:.0f} KiB")
    print(f"done in {time.time() - t0:.1f} s")


if __name__ == "__main__":
    main()
