#!/usr/bin/env python
"""A short bob grown on CesiumMan's head, in the bind pose, for shots with a real animated body.

CesiumMan (``cesiumman/CesiumMan.glb`` in the real-data folder: ``HAIRINV_REAL_DATA``, or
``shared/data/real`` beside the repository; CC BY 4.0, "CesiumMan, (c) 2017 Cesium") is a skinned
glTF character walking in place, 1.5 m tall, metres, +Y up once its ``Z_UP`` node is applied, the
face toward +Z. Its head is a low-poly drum whose axis runs front to back (the face is its front disc), 0.34 m
across at the face, tapering to 0.26 m at the back, with no scalp of its own. This script grows hair on the head's
own triangles in the bind pose (the pose ``hairinv`` reads a glTF body in, the arms out to the
sides), with the drape of ``bench/grooms.py``:

- roots spread evenly (farthest-point sampling of random points on the triangles) over the top and
  the sides of the drum down to a little below its centre line (where ears would be), not over its
  front 6 cm, and over the upper back disc;
- each strand is combed away from a centre parting over the top, down the sides and the back; it
  rises from the skin to its own gap (2-7 mm: later strands lie further out, so the bob has some
  volume) over its first 2-3 cm, runs along the head at that gap, bent downhill by gravity, and once
  the head curves away below it hangs down; a strand that would land on the shoulders or the arms
  turns to slide over them. The paths are smoothed and projected back out to their gaps;
- lengths 10-20 cm, longer at the back and the sides than on top, points every 5 mm.

Distances are exact closest-point distances to the welded body mesh (``hairinv.contacts.body.BodyMesh``).
The report gives the strand and point counts, the lengths, how far the roots are from the mesh (on it,
to round-off), the distances of the other points to the body and the turning angles.

Command line (from the project root)::

    .venv/bin/python bench/cesiumman_groom.py [--data DIR] [-o OUT] [--strands N] [--seed S] [--picture]

writes ``OUT`` (default ``out/cesiumman/bob.h5``, a hairinv stage file holding ``/curves``: metres, +Y
up, in the glTF's world frame, so no ``--units`` or ``--up`` is needed) and with ``--picture`` a
front and side view beside it (``bob.png``). Then::

    .venv/bin/hairinv fit out/cesiumman/bob.h5 -o out/cesiumman/bob.fit.h5
    .venv/bin/hairinv invert out/cesiumman/bob.fit.h5 ../shared/data/real/cesiumman/CesiumMan.glb \\
        -o out/cesiumman/bob.model.h5
    .venv/bin/hairinv verify out/cesiumman/bob.model.h5

The body needs no option: glTF is metres and +Y up by definition, as the groom is. ``invert`` warns
that the body is animated and takes its bind pose. With the defaults (300 strands, seed 1): 9,544
points, 22-41 per strand, 10.7-20 cm long; the fit's largest error 0.2 mm; the inversion declares
2,724 contacts (2,457 on the body, 267 between strands), converges and leaves every strand stable
without stiffening; ``verify`` passes (the largest motion in 2 s is 2e-12 mm).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

import grooms as g  # noqa: E402  (the drape; it also puts the project root and samples/ on sys.path)
from common import DATA  # noqa: E402

from hairinv.formats import read_animated_body  # noqa: E402

ROOT = HERE.parent
G = np.array([0.0, -1.0, 0.0])


def cesiumman_path(data: Path | None = None) -> Path:
    path = Path(data or DATA) / "cesiumman" / "CesiumMan.glb"
    if not path.exists():
        raise SystemExit(f"CesiumMan not found at {path} (give --data or set HAIRINV_REAL_DATA)")
    return path


class Head:
    """The drum of the head, measured on the bind-pose mesh: its axis along z at height ``yc``, its radius
    ``r_at(z)`` (it tapers from 0.169 m at the face to 0.13 m at the back), the largest radius ``r``, and
    the front and back discs at ``z_front`` and ``z_back``."""

    def __init__(self, vertices: np.ndarray):
        v = vertices[(vertices[:, 1] > 1.16) & (np.abs(vertices[:, 0]) < 0.25)]
        if len(v) < 100:
            raise SystemExit("CesiumMan.glb: no head found above y = 1.16 m (is it the file the README describes?)")
        lo, hi = v.min(axis=0), v.max(axis=0)
        self.yc = 0.5 * (lo[1] + hi[1])
        self.z_back, self.z_front = lo[2], hi[2]
        # the rings of the drum's side: vertices at one z, all far from the axis (the discs reach the axis)
        rho = np.hypot(v[:, 0], v[:, 1] - self.yc)
        z = np.round(v[:, 2], 4)
        rings = [(zz, rho[z == zz].max()) for zz in np.unique(z)
                 if np.sum(z == zz) >= 40 and rho[z == zz].min() > 0.1]
        if len(rings) < 3:
            raise SystemExit("CesiumMan.glb: the head is not the drum expected (no rings of vertices along z)")
        self.ring_z, self.ring_r = np.array(rings).T
        self.r = float(self.ring_r.max())
        if not (0.1 < self.r < 0.25 and abs(hi[0] - self.r) < 0.01):
            raise SystemExit(f"CesiumMan.glb: the head is not the drum expected (radius {self.r:.3f} m, "
                             f"x up to {hi[0]:.3f} m)")

    def r_at(self, z):
        return np.interp(z, self.ring_z, self.ring_r)

    def scalp(self, p: np.ndarray, front=0.06, below=0.03, back_below=0.06) -> np.ndarray:
        """True on the scalp: the drum's side from its top down to ``below`` under its axis, except its front
        ``front``; the back disc down to ``back_below`` under the axis."""
        rho = np.hypot(p[:, 0], p[:, 1] - self.yc)
        band = ((rho > self.r_at(p[:, 2]) - 0.004) & (p[:, 1] > self.yc - below)
                & (p[:, 2] < self.z_front - front) & (p[:, 2] > self.z_back + 0.002))
        back = ((p[:, 2] < self.z_back + 0.002) & (rho < self.r_at(self.z_back) - 0.004)
                & (p[:, 1] > self.yc - back_below))
        return band | back

    def comb(self, p: np.ndarray, normal: np.ndarray) -> np.ndarray:
        """Away from a parting along the top (x = 0), down the sides and a little toward the back; down the
        back disc, spreading a little sideways (tangent to the skin)."""
        side = np.sign(p[:, 0]) * np.minimum(np.abs(p[:, 0]) / 0.02, 1.0)
        on_back = p[:, 2] < self.z_back + 0.002
        c = np.stack([np.where(on_back, 2.0 * p[:, 0] / self.r, side), np.full(len(p), -1.0),
                      np.where(on_back, 0.0, -0.4)], axis=1)
        return g.unit(g.tangential(c, normal))


def grow(body: "g.Mannequin", head: Head, n_strands=300, seed=1, length=(0.10, 0.20), gap=(0.002, 0.007),
         spacing=0.005, jitter=0.0003):
    """Points (P, 3) and offsets (S + 1,) of the bob (see the module's docstring)."""
    rng = np.random.default_rng(seed)
    tri = body.mesh.triangles
    tri = tri[tri[:, :, 1].min(axis=1) > head.yc - head.r - 0.005]
    area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1) / 2
    pick = rng.choice(len(tri), size=60000, p=area / area.sum())
    u = rng.random((len(pick), 2))
    flip = u.sum(axis=1) > 1
    u[flip] = 1 - u[flip]
    t = tri[pick]
    cand = t[:, 0] + u[:, :1] * (t[:, 1] - t[:, 0]) + u[:, 1:] * (t[:, 2] - t[:, 0])
    cand = cand[head.scalp(cand)][:15000]
    roots = g.farthest_points(cand, n_strands, rng)
    _, n0 = body.query(roots)
    comb = head.comb(roots, n0)
    # longer at the back and low on the sides than on top
    low = np.clip((head.yc + head.r - roots[:, 1]) / head.r, 0.0, 1.0)
    back = np.clip(-roots[:, 2] / (-head.z_back), 0.0, 1.0)
    share = np.clip(0.5 * low + 0.3 * back + 0.2 * rng.random(n_strands), 0.0, 1.0)
    lengths = length[0] + (length[1] - length[0]) * share
    layer = rng.permutation(n_strands) / max(n_strands - 1, 1)
    gaps = gap[0] + (gap[1] - gap[0]) * layer + rng.uniform(-jitter, jitter, n_strands)
    root_rise = np.sqrt(6.0 * gap[1] / 50.0)  # the rise bends a strand by about 6 gap / rise^2: at most 50 / m

    def need_at(s):
        return gaps * g.rise(s, root_rise)

    steps = int(np.ceil((lengths.max() + 0.01) / g.DS))
    paths = g.drape_paths(body, roots, comb, lambda k: need_at(k * g.DS), steps, hold=root_rise)
    s_grid = np.arange(steps + 1)[:, None] * g.DS
    paths = g.smooth_paths(body, paths, need_at(s_grid))
    strands = [g.resample_to(paths[:, i], lengths[i], spacing) for i in range(n_strands)]
    strands = g.lift_resampled(body, strands, lambda s, who: gaps[who] * g.rise(s, root_rise))
    return g.pack(strands)


def draw(mesh, points, offsets, d, path, title):
    """Front, side and back views of the groom over the upper body (red where a point is inside it)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

    def to_plot(p):  # (x, y, z), +Y up -> matplotlib (x, -z, y), Z up
        return np.stack([p[..., 0], -p[..., 2], p[..., 1]], axis=-1)

    keep = mesh.triangles[:, :, 1].min(axis=1) > 0.85
    tris = to_plot(mesh.triangles[keep])
    normals = to_plot(mesh.face_normals[keep])
    shade = 0.55 + 0.45 * np.clip(normals @ g.unit(np.array([0.3, -1.0, 0.8])), 0, 1)
    face = np.c_[shade[:, None] * np.array([[0.90, 0.86, 0.82]]), np.ones(len(tris))]
    strands = g.unpack(points, offsets)
    inside = d < -1e-7
    segs = [to_plot(st) for st in strands]
    colours = [(0.9, 0.0, 0.0) if inside[offsets[i]:offsets[i + 1]].any() else (0.45, 0.25, 0.10)
               for i in range(len(strands))]
    views = (("front", 8, -90), ("left side", 8, 0), ("back", 8, 90))
    fig = plt.figure(figsize=(5.0 * len(views), 5.6), dpi=100)
    for col, (label, elev, azim) in enumerate(views):
        ax = fig.add_subplot(1, len(views), col + 1, projection="3d")
        ax.computed_zorder = False
        toward = np.array([np.cos(np.radians(azim)), np.sin(np.radians(azim))])
        depth = [float(np.mean(s[:, :2] @ toward)) for s in segs]
        far = [i for i in range(len(segs)) if depth[i] <= 0]
        near = [i for i in range(len(segs)) if depth[i] > 0]
        for order, which in ((1, far), (3, near)):
            if which:
                ax.add_collection3d(Line3DCollection([segs[i] for i in which], colors=[colours[i] for i in which],
                                                     linewidths=0.7, zorder=order))
        body = Poly3DCollection(tris, linewidths=0, zorder=2)
        body.set_facecolor(face)
        ax.add_collection3d(body)
        ax.set_xlim(-0.35, 0.35)
        ax.set_ylim(-0.35, 0.35)
        ax.set_zlim(0.95, 1.55)
        ax.set_box_aspect((0.70, 0.70, 0.60))
        ax.view_init(elev=elev, azim=azim)
        ax.set_axis_off()
        ax.set_title(label, fontsize=10)
    fig.suptitle(title, fontsize=10)
    fig.subplots_adjust(left=0, right=1, bottom=0, top=0.92, wspace=0)
    fig.savefig(path)
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path,
                        help="the real-data folder (default: HAIRINV_REAL_DATA or shared/data/real)")
    parser.add_argument("-o", "--output", type=Path, default=ROOT / "out" / "cesiumman" / "bob.h5")
    parser.add_argument("--strands", type=int, default=300)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--picture", action="store_true", help="also draw OUTPUT with .png")
    args = parser.parse_args(argv)
    t0 = time.time()
    source = cesiumman_path(args.data)
    rest = read_animated_body(source)
    import trimesh

    mesh = trimesh.Trimesh(rest.vertices, rest.faces, process=False)
    body = g.Mannequin(mesh)
    head = Head(rest.vertices)
    print(f"{source}: {len(mesh.vertices)} vertices, {len(mesh.faces)} triangles in the bind pose; head: a drum "
          f"about y = {head.yc:.3f} m from z = {head.z_back:.3f} to {head.z_front:.3f} m, radius "
          f"{head.r_at(head.z_back):.3f} m at the back to {head.r:.3f} m")
    points, offsets = grow(body, head, args.strands, args.seed)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    g.write_groom(args.output, points, offsets,
                  f"bench/cesiumman_groom.py: a short bob on CesiumMan's head in its bind pose (seed {args.seed}); "
                  "CesiumMan (c) 2017 Cesium, CC BY 4.0")
    st = g.groom_stats(body, points, offsets)
    print(f"wrote {args.output} [{time.time() - t0:.1f} s]")
    g.report("bob", st, {})
    if args.picture:
        png = args.output.with_suffix(".png")
        draw(mesh, points, offsets, st["d"], png, f"{args.output.name}: {st['strands']} strands on CesiumMan's head "
             "(bind pose; red: a strand with a point inside the body)")
        print(f"  picture {png}")


if __name__ == "__main__":
    main()
