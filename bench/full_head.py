#!/usr/bin/env python
"""Full-head grooms of any strand count, from the guides of a real groom plus follow hairs.

The paper pruned its captures to about 2,000 guides; a groom artist's full
head has 50,000 to 150,000 fibres. This script makes a family of heads from
100 to 100,000 strands on the same body, so that each stage can be measured
against the strand count:

* the guides are ruby short and ruby long joined (4,867 strands of 16 points
  on ``ruby_head.obj``, ../shared/data/real/ruby; 0.002 m per file unit, +Y up);
* below 4,867 strands, a subset of the guides spread evenly over the scalp
  (``hairinv.groom.select_guides``, what ``--guides N`` keeps);
* above, every guide plus follow hairs, the TressFX way
  (``numFollowHairsPerGuideHair``, ``maxRadiusAroundGuideHair`` 1.5 units = 3 mm):
  each a copy of its guide moved by a random offset in the 3 mm disc across the
  root tangent, carried along the strand by parallel transport. The follow hairs
  of ``ceil((N - 4867) / 4867)`` copies are drawn at random to make exactly N.

So the head grows denser as N grows, as a real head is denser than its guides:
at 100,000 strands about 20 follow hairs share each guide's 3 mm disc.

Usage: ``python bench/full_head.py N out.h5 [GUIDES]`` writes a /curves stage file in metres (GUIDES:
first keep that many guides, so that a small head is as dense as a large one).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

from common import DATA  # noqa: E402

from hairinv.config import ImportSettings  # noqa: E402
from hairinv.formats.hdf5 import write_hdf5_curves  # noqa: E402
from hairinv.groom import Groom, load_groom, select_guides  # noqa: E402

RUBY = DATA / "ruby"
GUIDE_FILES = (RUBY / "ruby_short_hair_16_guide.tfx", RUBY / "ruby_long_hair_16_guide.tfx")
HEAD = RUBY / "ruby_head.obj"
SCALE = 0.002  # m per file unit (the data README)
FOLLOW_RADIUS = 1.5 * SCALE  # m: maxRadiusAroundGuideHair of the TressFX headers
SEED = 0


def guides() -> Groom:
    """Ruby short and ruby long, joined, in metres (+Y up)."""
    settings = ImportSettings(scale=SCALE, up="y")
    grooms = [load_groom(f, settings)[0] for f in GUIDE_FILES]
    points = np.concatenate([g.points for g in grooms])
    offsets, start = [np.zeros(1, np.int64)], 0
    for g in grooms:
        offsets.append(g.offsets[1:] + start)
        start += len(g.points)
    return Groom(points, np.concatenate(offsets), grooms[0].up, grooms[0].scale_to_m,
                 " + ".join(g.source for g in grooms), np.concatenate([g.index for g in grooms]))


def follow_offsets(P: np.ndarray, copies: int, radius: float, rng) -> np.ndarray:
    """``copies`` follow hairs of each strand of ``P`` (S, m, 3): (copies, S, m, 3).

    Each is its guide moved by an offset drawn uniformly in the disc of ``radius``
    perpendicular to the root tangent, rotated with the polyline's segment
    directions (parallel transport), so it stays across the strand at constant length.
    """
    S, m, _ = P.shape
    t = np.diff(P, axis=1)
    t /= np.linalg.norm(t, axis=2, keepdims=True)
    out = np.empty((copies, S, m, 3))
    for c in range(copies):
        a = rng.normal(size=(S, 3))
        a -= np.sum(a * t[:, 0], axis=1, keepdims=True) * t[:, 0]
        a /= np.linalg.norm(a, axis=1, keepdims=True)
        off = a * (radius * np.sqrt(rng.uniform(size=(S, 1))))
        out[c, :, 0] = P[:, 0] + off
        out[c, :, 1] = P[:, 1] + off
        for i in range(2, m):
            t1, t2 = t[:, i - 2], t[:, i - 1]
            v = np.cross(t1, t2)
            cos = np.sum(t1 * t2, axis=1, keepdims=True)
            # Rodrigues' rotation taking t1 to t2, applied to the offset
            off = off * cos + np.cross(v, off) + v * np.sum(v * off, axis=1, keepdims=True) / np.maximum(1.0 + cos, 1e-12)
            out[c, :, i] = P[:, i] + off
    return out


def full_head(n: int, seed: int = SEED, base: Groom | None = None, guide_count: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Points (metres) and offsets of an ``n``-strand head: guides, or guides and follow hairs.
    ``guide_count`` > 0 first keeps that many guides (spread over the scalp), so a small head can be dense."""
    base = base or guides()
    counts = np.diff(base.offsets)
    G, m = base.n_strands, int(counts[0])
    if not np.all(counts == m):
        raise ValueError("the guides must all have the same point count")
    P = base.points.reshape(G, m, 3)
    if 0 < guide_count < G:
        P = P[np.sort(select_guides(P[:, 0], guide_count, seed))]
        G = guide_count
    if n <= G:
        keep = np.sort(select_guides(P[:, 0], n, seed))
        strands = P[keep]
    else:
        rng = np.random.default_rng(seed)
        copies = math.ceil((n - G) / G)
        follow = follow_offsets(P, copies, FOLLOW_RADIUS, rng).reshape(-1, m, 3)
        pick = np.sort(rng.choice(len(follow), n - G, replace=False))
        strands = np.concatenate([P, follow[pick]])
    offsets = np.arange(0, m * (n + 1), m, dtype=np.int64)
    return np.ascontiguousarray(strands.reshape(-1, 3)), offsets


def write(n: int, path: Path, seed: int = SEED, base: Groom | None = None, guide_count: int = 0) -> Path:
    points, offsets = full_head(n, seed, base, guide_count)
    kept = f" from {guide_count} guides" if guide_count else ""
    write_hdf5_curves(Path(path), points, offsets, up=(0.0, 1.0, 0.0),
                      source=f"ruby short + long, {n} strands{kept} (bench/full_head.py, seed {seed})", command="bench")
    return Path(path)


if __name__ == "__main__":
    write(int(sys.argv[1]), Path(sys.argv[2]), guide_count=int(sys.argv[3]) if len(sys.argv) > 3 else 0)
