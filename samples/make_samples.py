#!/usr/bin/env python
"""Regenerate the sample body mesh and grooms in ``samples/``.

Writes ``samples/body.obj`` (a stylised bust), ``samples/straight.h5``,
``samples/wavy.h5``, ``samples/curly.h5`` (hairinv stage files holding
``/curves``) and the preview picture ``docs/img/samples.png``.

Everything is in metres, +Y up, face toward +Z. The script is deterministic
(fixed seeds) and needs only numpy, trimesh, matplotlib and h5py::

    cd <project root> && .venv/bin/python samples/make_samples.py

How the hair is made: roots are spread evenly over the scalp of the body mesh
(farthest-point sampling of random surface points). Each strand leaves the
scalp along the normal, is combed along the head surface at a small offset
(later strands lie a little further out, so the hair has some volume),
bends toward -Y under gravity, and once below the widest part of the head
falls freely; wherever it would enter the body it is pushed back out to the
surface plus a small offset, so hair drapes over the shoulders and back.
Waves and curls are added afterwards, the strands are pushed out of the body
again and resampled to evenly spaced points.

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


def profile(y):
    """Ring shape at heights ``y``.

    Returns half-width along x ``a``, half-widths toward the front (+z)
    ``bf`` and the back (-z) ``bb``, and the superellipse exponent ``n``.
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


def write_obj(path, mesh):
    lines = [
        "# hairinv sample body: a stylised bust (head, neck, shoulders), open at the chest",
        "# units: metres; +Y up; face toward +Z",
        "# written by samples/make_samples.py",
        f"# {len(mesh.vertices)} vertices, {len(mesh.faces)} triangles",
    ]
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


def march(body, roots, off_head, off_fall, length, lift=0.004, ds=0.002, r_head=0.07, r_fall=0.025):
    """Grow all strands together; returns (steps + 1, S, 3) positions."""
    _, n0 = body.query(roots)
    steps = int(np.ceil(length / ds)) + 1
    out = [roots.copy()]
    p = roots.copy()
    # 1) leave the scalp along the normal
    n_lift = int(round(lift / ds))
    for i in range(1, n_lift + 1):
        p = roots + n0 * (i * ds)
        out.append(p.copy())
    t = comb_direction(roots, n0)
    fall = n0[:, 1] < 0.0
    t[fall] = n0[fall]
    s = np.full(len(p), lift)
    ramp_len = 0.02
    for _ in range(steps - n_lift):
        head = ~fall
        if np.any(head):
            ph = p[head]
            d, n = body.query(ph)
            th = t[head] + tangential(G[None, :], n) * (ds / r_head)
            th = unit(tangential(th, n))
            ph = ph + th * ds
            d, n = body.query(ph)
            sh = s[head] + ds
            target = lift + (off_head[head] - lift) * smoothstep(lift, lift + ramp_len, sh)
            ph = ph + n * (target - d)[:, None]
            p[head] = ph
            t[head] = th
            fall[np.flatnonzero(head)[n[:, 1] < 0.0]] = True
        fa = fall & ~head  # strands that were falling before this step
        if np.any(fa):
            pf = p[fa]
            tf = unit(t[fa] + G[None, :] * (ds / r_fall))
            pf = pf + tf * ds
            d, n = body.query(pf)
            hit = d < off_fall[fa]
            if np.any(hit):
                pf[hit] += n[hit] * (off_fall[fa][hit] - d[hit])[:, None]
                inward = np.minimum(np.sum(tf[hit] * n[hit], axis=1), 0.0)
                tf[hit] = unit(tf[hit] - inward[:, None] * n[hit])
            p[fa] = pf
            t[fa] = tf
        s += ds
        out.append(p.copy())
    return np.stack(out)


def arclength(pts):
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])


def resample(pts, count, length=None):
    s = arclength(pts)
    total = s[-1] if length is None else min(length, s[-1])
    q = np.linspace(0.0, total, count)
    return np.stack([np.interp(q, s, pts[:, k]) for k in range(3)], axis=1)


def smooth_rows(v, width):
    """Moving average along a strand (edges padded), then renormalised."""
    if width <= 1:
        return v
    kern = np.ones(width) / width
    pad = width // 2
    vp = np.pad(v, ((pad, width - 1 - pad), (0, 0)), mode="edge")
    out = np.stack([np.convolve(vp[:, k], kern, mode="valid") for k in range(3)], axis=1)
    return unit(out)


def push_out(body, strands, min_off=0.001, iters=3):
    """Move every non-root point to at least ``min_off`` outside the body."""
    flat = np.concatenate([st[1:] for st in strands])
    s_along = np.concatenate([arclength(st)[1:] for st in strands])
    need = np.minimum(min_off, 0.8 * s_along)
    for _ in range(iters):
        d, n = body.query(flat)
        bad = d < need
        if not np.any(bad):
            break
        flat[bad] += n[bad] * (need[bad] - d[bad])[:, None]
    out, k = [], 0
    for st in strands:
        m = len(st) - 1
        out.append(np.vstack([st[:1], flat[k : k + m]]))
        k += m
    return out


def add_shape(body, base, kind, rng):
    """Add a planar-ish wave or a helical curl around a base path (root unchanged)."""
    s = arclength(base)
    tang = unit(np.gradient(base, axis=0))
    _, n = body.query(base)
    n = smooth_rows(n, 9)
    u = unit(tangential(n, tang))  # away from the body, across the strand
    v = np.cross(tang, u)  # along the body surface, across the strand
    if kind == "wavy":
        amp = rng.uniform(0.005, 0.010)
        lam = rng.uniform(0.04, 0.06)
        ramp = smoothstep(0.0, rng.uniform(0.03, 0.05), s)
        phase = rng.uniform(0, 2 * np.pi)
        tilt = rng.uniform(-0.35, 0.35)  # mostly along the surface, a little off it
        w = unit(v + tilt * u)
        return base + (amp * ramp * np.sin(2 * np.pi * s / lam + phase))[:, None] * w
    if kind == "curly":
        rad = rng.uniform(0.005, 0.008)
        pitch = rng.uniform(0.02, 0.03)
        ramp = smoothstep(0.0, rng.uniform(0.025, 0.04), s)
        phase = rng.uniform(0, 2 * np.pi) + rng.choice([-1.0, 1.0]) * 2 * np.pi * s / pitch
        # start from the outward side so the curl begins away from the scalp
        off = np.cos(phase)[:, None] * u + np.sin(phase)[:, None] * v
        return base + (rad * ramp)[:, None] * off
    return base


GROOMS = {
    # name: strand count, points per strand (min, max), length range in metres, random seed
    "straight": dict(count=300, points=(24, 36), length=(0.25, 0.40), seed=11),
    "wavy": dict(count=280, points=(30, 40), length=(0.25, 0.35), seed=22),
    "curly": dict(count=260, points=(32, 40), length=(0.15, 0.25), seed=33),
}


def make_groom(body, mesh, name, spec):
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
    npts = rng.integers(spec["points"][0], spec["points"][1] + 1, count)
    # wavy and curly centre lines keep a little further from the body than the curl radius allows
    curl_pad = {"straight": 0.0, "wavy": 0.001, "curly": 0.004}[name]
    path = march(body, roots, off_head + curl_pad, off_fall + curl_pad, lengths.max())
    strands = []
    for i in range(count):
        base = path[:, i]
        if name != "straight":
            base = add_shape(body, base, name, rng)
        strands.append(base)
    strands = push_out(body, strands)
    strands = [resample(st, npts[i], lengths[i]) for i, st in enumerate(strands)]
    strands = push_out(body, strands, min_off=0.0008)
    # keep the stored spacing even after the push
    strands = [resample(st, len(st)) for st in strands]
    return strands


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


def report_groom(name, strands, mesh, body):
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
        strands = make_groom(body, mesh, name, spec)
        write_curves(HERE / f"{name}.h5", strands, f"hairinv sample groom '{name}' (samples/make_samples.py)")
        report_groom(name, strands, mesh, body)
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
