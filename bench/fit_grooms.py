#!/usr/bin/env python
"""Test grooms for the super-helix fit: strand shapes the fit finds hard.

The main fit benchmark (``bench/fit_bench.py``) measures the fit
(``hairinv.fit.fit_groom``) on smooth strands of 16 to 32 points. Real
inputs also come with small corners left by a kinematic drape,
waves and tight curls, coarse procedural sampling and capture noise. Each
function below makes one such kind over the test mannequin of
``bench/grooms.py`` (roots on its scalp, strands draped over it with its
code) and returns a ``hairinv.groom.Groom`` in metres, +Y up, deterministic
given its ``seed``. Strands are 10-40 cm long unless a kind says otherwise.

The kinds
    ``draped_kinks(spacing=0.004, ...)``
        Straight hair draped over the mannequin, a point every ``spacing``,
        with the corners a kinematic drape leaves where points were pushed
        out of the body: along the part of a strand that rests on the body,
        a few dents (``dents`` per strand, ``depth`` deep, ``width`` wide)
        push it into the skin, and every point that ends inside is projected
        back out to ``floor`` above the surface, one by one, with no
        smoothing. A strand gets corners of a few degrees to about 30
        degrees at a few points, where it meets the surface.
    ``waved(amplitude=0.006, period=0.06, ...)``
        The same drape with a sine wave across the strand: perpendicular to
        the draped path, in a plane that turns slowly along it (a
        rotation-minimising frame turned by a per-strand rate), growing from
        the root as the path rises from the skin (over its first 2-4 cm).
        The path is held ``amplitude`` further from the body, so the wave
        stays outside it.
    ``coiled(radius=0.004, points_per_turn=6, pitch=None, ...)``
        Curly hair: a helical coil of ``radius`` around the draped path (the
        coil's axis is the path's tangent; the coil turns in a
        rotation-minimising frame along the path), advancing ``pitch`` along
        the path per turn (default three radii), sampled at exactly
        ``points_per_turn`` points per turn; the path is held ``radius``
        further from the body and the coil grows from the root as the path
        rises. Radius and pitch vary by +-10 % from strand to strand; the
        handedness and phase are random.
        ``mixed=True`` winds tight coils (``radius``, e.g. 1 mm) on one part
        of each strand (the root or the tip side, at random, 35-65 % of its
        length) and a slow wave (``wave_amplitude``, ``wave_period``,
        sampled every ``spacing``) on the rest, blended over 1 cm.
    ``coarse(n_points=21, length=0.23, n_strands=500, ...)``
        A procedural groom: strands of about ``length`` (+-``length_jitter``)
        with exactly ``n_points`` points each (1.15 cm apart for the
        defaults), leaving the scalp at an angle and gently curved (a
        random smooth curvature of about ``curvature`` 1/m, plus a droop
        toward gravity), steering clear of the body and then pushed smoothly
        out of it where it still comes too close.
    ``noisy(sigma=0.0002, spacing=(0.002, 0.006), ...)``
        A capture: draped strands sampled at uneven steps (uniform in
        ``spacing``) with Gaussian noise of ``sigma`` on every coordinate of
        every point.

``variants()`` lists named variants of these kinds (``Variant(name, make,
held_out)``; ``make()`` returns the groom and takes keyword overrides, e.g.
``make(n_strands=200)``), split into development variants and held-out ones
that differ in seeds and parameter values.

Command line (from the project root)::

    .venv/bin/python bench/fit_grooms.py OUTDIR [NAME ...] [--strands N]

writes the named variants (default: all) as ``OUTDIR/<name>.h5`` hairinv
stage files holding ``/curves`` (metres, up = +Y) and prints a line of
figures per groom; then, e.g.::

    .venv/bin/hairinv fit OUTDIR/coil_r1_ppt6.h5 -o OUTDIR/coil_r1_ppt6.fit.h5
"""

from __future__ import annotations

import argparse
import functools
import sys
import time
from pathlib import Path
from typing import Callable, NamedTuple

import numpy as np
from scipy.interpolate import CubicSpline

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

import grooms  # noqa: E402  (the mannequin and the drape; it also puts the project root and samples/ on sys.path)
from grooms import (  # noqa: E402
    DS,
    G,
    arclength,
    comb_direction,
    drape_paths,
    mannequin,
    pack,
    resample_to,
    rise,
    scalp_roots,
    smooth_paths,
    smoothstep,
    tangential,
    turning_angles,
    unit,
)

from hairinv.groom import Groom, strand_lengths  # noqa: E402

UP = np.array([0.0, 1.0, 0.0])
LENGTH = (0.10, 0.40)  # m, strand lengths of the draped kinds
FINE = 4  # the draped path is refined to DS / FINE (0.5 mm) before waves and coils are wound around it


# --------------------------------------------------------------------------
# Shared pieces
# --------------------------------------------------------------------------


def _groom(strands, source: str) -> Groom:
    points, offsets = pack(strands)
    return Groom(points, offsets, UP.copy(), 1.0, source, np.arange(len(offsets) - 1, dtype=np.int64))


def _source(kind: str, **params) -> str:
    return f"bench/fit_grooms.py {kind}(" + ", ".join(f"{k}={v}" for k, v in sorted(params.items())) + ")"


def _drape(n_strands, seed, length, gap, extra=0.0, body=None, jitter=0.0003, root_rise=0.01, smooth=True):
    """Centre lines draped over the mannequin with ``bench/grooms.py``'s drape.

    Roots are spread evenly over the scalp and combed from a centre parting;
    each strand keeps ``gap`` (+-``jitter``) plus ``extra`` (room for a wave
    or a coil wound around the path) from the skin, reached over
    ``root_rise`` of arc or more where rising that fast would bend it by more
    than about 50 / m. Returns the body, the seeded
    generator (for the caller's further draws), the paths (K, S, 3) in steps
    of ``DS``, the strands' lengths (drawn from ``length``), their gaps and
    the rise length.
    """
    body = body or mannequin()
    rng = np.random.default_rng(seed)
    roots = scalp_roots(body, n_strands, rng)
    _, n0 = body.query(roots)
    comb = comb_direction(roots, n0)
    lengths = rng.uniform(*length, n_strands)
    gaps = gap + rng.uniform(-jitter, jitter, n_strands)
    root_rise = max(root_rise, np.sqrt(6.0 * (gap + extra) / 50.0))  # bends by at most about 50 / m

    def need_at(s):
        return (gaps + extra) * rise(s, root_rise)

    steps = int(np.ceil((lengths.max() + 0.01) / DS))
    paths = drape_paths(body, roots, comb, lambda k: need_at(k * DS), steps, hold=root_rise)
    if smooth:
        s_grid = np.arange(steps + 1)[:, None] * DS
        paths = smooth_paths(body, paths, need_at(s_grid) * np.ones((1, n_strands)))
    return body, rng, paths, lengths, gaps, root_rise


def _refine(paths, factor=FINE):
    """Paths (K, S, 3) through a cubic spline, ``factor`` times as finely sampled."""
    k = np.arange(len(paths))
    fine = np.linspace(0, len(paths) - 1, (len(paths) - 1) * factor + 1)
    return CubicSpline(k, paths, axis=0)(fine)


def rotation_minimising_frames(p, u0):
    """Unit normals ``u``, ``v`` along polylines ``p`` (K, S, 3) by the double reflection method
    (Wang, Juettler, Zheng and Liu 2008): ``u`` starts as ``u0`` (S, 3) made normal to the first tangent
    and turns about the tangent as little as possible; ``v = t x u``."""
    t = unit(np.gradient(p, axis=0))
    u = np.empty_like(p)
    u[0] = unit(tangential(u0, t[0]))
    for k in range(len(p) - 1):
        v1 = p[k + 1] - p[k]
        c1 = np.maximum(np.sum(v1 * v1, axis=-1, keepdims=True), 1e-300)
        r_l = u[k] - (2.0 / c1) * np.sum(v1 * u[k], axis=-1, keepdims=True) * v1
        t_l = t[k] - (2.0 / c1) * np.sum(v1 * t[k], axis=-1, keepdims=True) * v1
        v2 = t[k + 1] - t_l
        c2 = np.sum(v2 * v2, axis=-1, keepdims=True)
        r = np.where(c2 > 1e-24, r_l - (2.0 / np.maximum(c2, 1e-300)) * np.sum(v2 * r_l, axis=-1, keepdims=True) * v2,
                     r_l)
        u[k + 1] = unit(tangential(r, t[k + 1]))
    return u, np.cross(t, u)


def _interp_rows(x, xp, fp):
    """``fp`` (N, 3) at ``x`` by linear interpolation over ``xp`` (N,)."""
    return np.stack([np.interp(x, xp, fp[:, c]) for c in range(3)], axis=1)


def _cut(curve, length):
    """``curve`` (N, 3) cut at polyline length ``length``: its points up to there and the cut point (which
    replaces the last point before it when that is less than half a segment away)."""
    s = arclength(curve)
    n = int(np.searchsorted(s, length, side="right"))
    if n >= len(curve):
        return curve
    w = (length - s[n - 1]) / (s[n] - s[n - 1])
    end = curve[n - 1] + w * (curve[n] - curve[n - 1])
    keep = n - 1 if (w < 0.5 and n > 2) else n
    return np.vstack([curve[:keep], end[None]])


def _lift(body, strands, need_fn):
    """Each strand's points projected out (one by one) to ``need_fn(arc length, strand)`` where they came closer."""
    points, offsets = pack(strands)
    s = np.concatenate([arclength(st) for st in strands])
    owner = np.repeat(np.arange(len(strands)), np.diff(offsets))
    points = body.project_out(points, need_fn(s, owner))
    return [points[offsets[i]:offsets[i + 1]] for i in range(len(strands))]


# --------------------------------------------------------------------------
# The kinds
# --------------------------------------------------------------------------


def draped_kinks(n_strands=300, spacing=0.004, seed=1, length=LENGTH, gap=0.002, dents=(1, 4),
                 depth=(0.0015, 0.004), width=(0.003, 0.015), floor=0.0005, body=None) -> Groom:
    """Straight draped hair with the small corners of a kinematic drape.

    Parameters
    ----------
    spacing : float, m
        Vertex spacing along the strand.
    gap : float, m
        Distance of the draped layer from the skin.
    dents : (int, int)
        Range of dents per strand (uniform, inclusive), placed where the strand rests on the body
        (within ``gap`` + 1 mm of it, beyond 3 cm from the root); a strand hanging free has none.
    depth, width : (float, float), m
        Ranges of a dent's depth (toward the body) and its Gaussian half-width along the strand.
        The steeper a dent (depth over width), the sharper the corners where it meets the surface.
    floor : float, m
        Distance from the surface to which points pushed inside are projected back out.
    """
    body, rng, paths, lengths, gaps, root_rise = _drape(n_strands, seed, length, gap, body=body)
    strands = [resample_to(paths[:, i], lengths[i], spacing) for i in range(n_strands)]
    strands = _lift(body, strands, lambda s, who: gaps[who] * rise(s, root_rise))
    counts = rng.integers(dents[0], dents[1] + 1, n_strands)
    out = []
    for i, st in enumerate(strands):
        s = arclength(st)
        d, n = body.query(st)
        resting = np.flatnonzero((d < gaps[i] + 0.001) & (s > 0.03))
        # draws are made for every strand, so a strand's dents do not depend on its neighbours' contact
        centre_pick = rng.random(counts[i])
        dent_depth = rng.uniform(*depth, counts[i])
        dent_width = rng.uniform(*width, counts[i])
        if len(resting) == 0:
            out.append(st)
            continue
        centres = s[resting[(centre_pick * len(resting)).astype(int)]]
        push = np.zeros(len(st))
        for c, h, w in zip(centres, dent_depth, dent_width):
            push = np.maximum(push, h * np.exp(-0.5 * ((s - c) / w) ** 2))
        push *= 1.0 - smoothstep(gaps[i] + 0.002, gaps[i] + 0.006, d)  # only where it lies on the body
        moved = body.project_out(st - push[:, None] * n, np.minimum(floor, gaps[i] * rise(s, root_rise)))
        moved[0] = st[0]
        out.append(moved)
    return _groom(out, _source("draped_kinks", n_strands=n_strands, spacing=spacing, seed=seed, length=length,
                               gap=gap, dents=dents, depth=depth, width=width, floor=floor))


def _wound(body, rng, paths, lengths, gaps, root_rise, *, radius=0.0, pitch=None, points_per_turn=6,
           amplitude=0.0, period=0.06, spacing=0.004, mixed=False, turn_rate=8.0, ramp=0.02, jitter=0.10):
    """Waves and coils wound around draped centre lines.

    A strand's offset from its path at path arc length ``s`` is a coil
    ``r(s) (cos th u + sin th v)`` plus a wave ``a(s) sin(2 pi s / P + phi) w(s)``,
    with ``u``, ``v`` a rotation-minimising frame along the path starting away
    from the body, ``w`` turned from ``u`` by ``psi0 + omega s`` (``|omega| <=
    turn_rate`` rad/m), and ``th = th0 +- 2 pi s / pitch``; ``r`` and ``a``
    grow from 0 over ``ramp`` (the path's rise from the skin). Points are placed
    by a clock along the path: ``points_per_turn / pitch`` points per metre of
    path where there is a coil, so that every turn has exactly
    ``points_per_turn`` points, and ``1 / spacing`` where there is none.
    Each strand is cut at its polyline length ``lengths[i]``.
    """
    n_strands = paths.shape[1]
    base = _refine(paths)
    _, normal = body.query(base[0])
    u, v = rotation_minimising_frames(base, normal)
    sb = arclength(base)
    coil = radius > 0
    wave = amplitude > 0
    r_i = radius * rng.uniform(1 - jitter, 1 + jitter, n_strands)
    pitch_i = (3.0 * radius if pitch is None else pitch) * rng.uniform(1 - jitter, 1 + jitter, n_strands)
    th0 = rng.uniform(0, 2 * np.pi, n_strands)
    hand = rng.choice([-1.0, 1.0], n_strands)
    period_i = period * rng.uniform(1 - jitter, 1 + jitter, n_strands)
    phi = rng.uniform(0, 2 * np.pi, n_strands)
    psi0 = rng.uniform(0, 2 * np.pi, n_strands)
    omega = rng.uniform(-turn_rate, turn_rate, n_strands)
    split = rng.uniform(0.35, 0.65, n_strands) * lengths  # mixed: where the coil gives way to the wave
    coil_at_tip = rng.random(n_strands) < 0.5
    out = []
    for i in range(n_strands):
        s = sb[:, i]
        grow = smoothstep(0.0, ramp, s)
        if mixed:
            to_tip = smoothstep(split[i] - 0.005, split[i] + 0.005, s)
            coil_w = to_tip if coil_at_tip[i] else 1.0 - to_tip
            wave_w = 1.0 - coil_w
        else:
            coil_w = np.full(len(s), 1.0 if coil else 0.0)
            wave_w = np.full(len(s), 1.0 if wave else 0.0)
        # the clock: samples per metre of path, integrated
        rate = coil_w * points_per_turn / max(pitch_i[i], 1e-12) + (1.0 - coil_w) / spacing if coil else \
            np.full(len(s), 1.0 / spacing)
        clock = np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) * np.diff(s))])
        q = np.interp(np.arange(int(clock[-1]) + 1), clock, s)  # path arc length of every sample
        c = _interp_rows(q, s, base[:, i])
        uu = _interp_rows(q, s, u[:, i])
        vv = _interp_rows(q, s, v[:, i])
        t = unit(_interp_rows(q, s, np.gradient(base[:, i], axis=0)))
        uu = unit(tangential(uu, t))
        vv = np.cross(t, uu)
        off = np.zeros_like(c)
        if coil:
            r = r_i[i] * np.interp(q, s, grow * coil_w)
            th = th0[i] + hand[i] * 2 * np.pi * q / pitch_i[i]
            off += r[:, None] * (np.cos(th)[:, None] * uu + np.sin(th)[:, None] * vv)
        if wave:
            a = amplitude * np.interp(q, s, grow * wave_w)
            psi = psi0[i] + omega[i] * q
            w = np.cos(psi)[:, None] * uu + np.sin(psi)[:, None] * vv
            off += (a * np.sin(2 * np.pi * q / period_i[i] + phi[i]))[:, None] * w
        out.append(_cut(c + off, lengths[i]))
    return _lift(body, out, lambda s, who: gaps[who] * rise(s, root_rise))


def waved(amplitude=0.006, period=0.06, n_strands=300, spacing=0.003, seed=1, length=LENGTH, gap=0.002,
          turn_rate=8.0, body=None) -> Groom:
    """Wavy draped hair: a sine wave of ``amplitude`` (m) and ``period`` (m, +-10 % per strand) across the
    draped path, in a plane turning by at most ``turn_rate`` rad per metre along it; a point every ``spacing``
    (m, along the path)."""
    body, rng, paths, lengths, gaps, root_rise = _drape(n_strands, seed, length, gap, extra=amplitude, body=body)
    strands = _wound(body, rng, paths, lengths, gaps, root_rise, amplitude=amplitude, period=period,
                     spacing=spacing, turn_rate=turn_rate, ramp=root_rise)
    return _groom(strands, _source("waved", amplitude=amplitude, period=period, n_strands=n_strands, spacing=spacing,
                                   seed=seed, length=length, gap=gap, turn_rate=turn_rate))


def coiled(radius=0.004, points_per_turn=6, pitch=None, n_strands=300, seed=1, length=LENGTH, gap=0.002,
           mixed=False, wave_amplitude=0.005, wave_period=0.08, spacing=0.003, body=None) -> Groom:
    """Curly hair: a coil of ``radius`` (m) around the draped path, ``pitch`` (m, default 3 radii) along the
    path per turn, ``points_per_turn`` points per turn (radius and pitch +-10 % per strand).

    With ``mixed``, the coil covers the root or the tip side of each strand (35-65 % of its length) and a slow
    wave (``wave_amplitude``, ``wave_period``, a point every ``spacing``) the rest.
    """
    extra = max(radius, wave_amplitude if mixed else 0.0)
    body, rng, paths, lengths, gaps, root_rise = _drape(n_strands, seed, length, gap, extra=extra, body=body)
    strands = _wound(body, rng, paths, lengths, gaps, root_rise, radius=radius, pitch=pitch,
                     points_per_turn=points_per_turn, amplitude=wave_amplitude if mixed else 0.0,
                     period=wave_period, spacing=spacing, mixed=mixed, ramp=root_rise)
    params = dict(radius=radius, points_per_turn=points_per_turn, pitch=pitch, n_strands=n_strands, seed=seed,
                  length=length, gap=gap)
    if mixed:
        params.update(mixed=True, wave_amplitude=wave_amplitude, wave_period=wave_period, spacing=spacing)
    return _groom(strands, _source("coiled", **params))


def coarse(n_points=21, length=0.23, n_strands=500, seed=1, length_jitter=0.05, curvature=12.0, droop=6.0,
           lift=0.5, gap=0.004, steering=60.0, look=0.015, body=None) -> Groom:
    """A procedural groom: ``n_points`` points per strand, evenly spaced along strands of ``length``
    (+-``length_jitter`` of it, m).

    A strand leaves its root along the comb direction tilted off the scalp (``lift`` is the weight of the
    scalp normal added to the comb direction: 0.5 tilts it by about 27 degrees) and bends with a curvature
    vector made of three random sine waves per normal direction (wavelengths 6-40 cm, root-mean-square
    about ``curvature`` 1/m) plus ``droop`` 1/m toward gravity, integrated in 1 mm steps. Where a strand
    would reach the body within ``look`` (m) heading into it, it turns away at up to ``steering`` 1/m, and a
    step that still comes closer than ``gap`` is projected back out to it; the path is then smoothed
    (``bench/grooms.py``'s smoothing and projection) and resampled.
    """
    body = body or mannequin()
    rng = np.random.default_rng(seed)
    roots = scalp_roots(body, n_strands, rng)
    _, n0 = body.query(roots)
    comb = comb_direction(roots, n0)
    lengths = length * rng.uniform(1 - length_jitter, 1 + length_jitter, n_strands)
    ds = 0.001
    steps = int(np.ceil(lengths.max() * 1.05 / ds))
    waves = 3
    lam = rng.uniform(0.06, 0.40, (2, waves, n_strands))
    amp = rng.normal(0.0, curvature / np.sqrt(waves), (2, waves, n_strands))
    ph = rng.uniform(0, 2 * np.pi, (2, waves, n_strands))
    t = unit(comb + lift * n0)
    e1 = unit(tangential(n0, t))
    p = roots.copy()
    out = [p.copy()]
    for k in range(steps):
        s = k * ds
        kap = np.sum(amp * np.sin(2 * np.pi * s / lam + ph), axis=1)  # (2, S)
        e2 = np.cross(t, e1)
        kv = kap[0][:, None] * e1 + kap[1][:, None] * e2 + droop * tangential(G[None, :], t)
        # steer clear of the body: turn away from it where the strand would reach it within ``look``
        da, na = body.query(p + t * look)
        inward = -np.sum(t * na, axis=1)
        steer = steering * (da < gap + 0.002) * np.clip(inward / 0.2, 0.0, 1.0)
        kv += steer[:, None] * unit(tangential(na, t))
        mag = np.linalg.norm(kv, axis=1)
        dirn = kv / np.maximum(mag, 1e-12)[:, None]
        ang = (mag * ds)[:, None]
        t_new = unit(t * np.cos(ang) + dirn * np.sin(ang))
        q = body.project_out(p + t_new * ds, gap * rise(s + ds, 0.01))
        t_new = unit(q - p)
        e1 = unit(tangential(e1, t_new))
        t = t_new
        p = q
        out.append(p.copy())
    paths = np.stack(out)
    s_grid = np.arange(steps + 1)[:, None] * ds
    need = gap * rise(s_grid, 0.01) * np.ones((1, n_strands))
    paths = smooth_paths(body, paths, need, passes=((0.008,), (0.004,)), ds=ds)
    strands = []
    for i in range(n_strands):
        sa = arclength(paths[:, i])
        q = np.linspace(0.0, min(lengths[i], sa[-1]), n_points)
        strands.append(_interp_rows(q, sa, paths[:, i]))
    return _groom(strands, _source("coarse", n_points=n_points, length=length, n_strands=n_strands, seed=seed,
                                   length_jitter=length_jitter, curvature=curvature, droop=droop, lift=lift, gap=gap))


def noisy(sigma=0.0002, spacing=(0.002, 0.006), n_strands=300, seed=1, length=LENGTH, gap=0.003,
          body=None) -> Groom:
    """A capture-like groom: draped strands sampled at uneven steps (uniform in ``spacing``, m) with Gaussian
    noise of ``sigma`` (m) on every coordinate of every point."""
    body, rng, paths, lengths, gaps, root_rise = _drape(n_strands, seed, length, gap, body=body)
    strands = []
    for i in range(n_strands):
        sa = arclength(paths[:, i])
        steps = rng.uniform(*spacing, int(np.ceil(lengths[i] / spacing[0])) + 2)
        q = np.concatenate([[0.0], np.cumsum(steps)])
        q = q[q < lengths[i]]
        st = _interp_rows(q, sa, paths[:, i])
        strands.append(st + rng.normal(0.0, sigma, st.shape))
    return _groom(strands, _source("noisy", sigma=sigma, spacing=spacing, n_strands=n_strands, seed=seed,
                                   length=length, gap=gap))


# --------------------------------------------------------------------------
# Variants
# --------------------------------------------------------------------------


class Variant(NamedTuple):
    """A named groom: ``make(**overrides)`` returns it (a ``functools.partial`` of a kind, so
    ``make.func.__name__`` is the kind and ``make.keywords`` its parameters)."""

    name: str
    make: Callable[..., Groom]
    held_out: bool


_P = functools.partial
_DEVELOPMENT = [
    ("kinks_sp4", _P(draped_kinks, spacing=0.004, seed=1)),
    ("kinks_sp2_deep", _P(draped_kinks, spacing=0.002, depth=(0.002, 0.005), seed=2)),
    ("waved_a6_p60", _P(waved, amplitude=0.006, period=0.06, seed=1)),
    ("waved_a3_p30_sp2", _P(waved, amplitude=0.003, period=0.03, spacing=0.002, seed=2)),
    ("coil_r1_ppt6", _P(coiled, radius=0.001, points_per_turn=6, seed=1)),
    ("coil_r3_ppt5", _P(coiled, radius=0.003, points_per_turn=5, seed=1)),
    ("coil_r5_ppt8", _P(coiled, radius=0.005, points_per_turn=8, seed=1)),
    ("mixed_r1_ppt6", _P(coiled, radius=0.001, points_per_turn=6, mixed=True, seed=1)),
    ("coarse_21", _P(coarse, seed=1)),
    ("noisy_s02", _P(noisy, sigma=0.0002, seed=1)),
]
_HELD_OUT = [
    ("kinks_sp3_gap3", _P(draped_kinks, spacing=0.003, gap=0.003, seed=3)),
    ("kinks_sp5_many", _P(draped_kinks, spacing=0.005, dents=(3, 6), seed=4)),
    ("waved_a10_p80_sp4", _P(waved, amplitude=0.010, period=0.08, spacing=0.004, seed=3)),
    ("waved_a4_p45_sp25", _P(waved, amplitude=0.004, period=0.045, spacing=0.0025, seed=4)),
    ("coil_r2_ppt7", _P(coiled, radius=0.002, points_per_turn=7, seed=5)),
    ("coil_r4_ppt6", _P(coiled, radius=0.004, points_per_turn=6, seed=6)),
    ("coil_r1_ppt8", _P(coiled, radius=0.001, points_per_turn=8, seed=7)),
    ("coil_r5_ppt5_p20", _P(coiled, radius=0.005, points_per_turn=5, pitch=0.020, seed=8)),
    ("mixed_r1_ppt7", _P(coiled, radius=0.001, points_per_turn=7, mixed=True, wave_amplitude=0.007,
                         wave_period=0.10, seed=9)),
    ("coarse_21_curvy", _P(coarse, length=0.20, curvature=20.0, seed=2)),
    ("noisy_s03_sp1.5-5", _P(noisy, sigma=0.0003, spacing=(0.0015, 0.005), seed=3)),
]


def variants() -> list[Variant]:
    """Every named variant: the development ones (tune on these), then the held-out ones (other seeds and
    parameter values, for checking that what was tuned carries over)."""
    return [Variant(n, f, False) for n, f in _DEVELOPMENT] + [Variant(n, f, True) for n, f in _HELD_OUT]


def describe(groom: Groom) -> str:
    """One line of figures of a groom: strands, points per strand, lengths, spacing, turning angles."""
    counts = np.diff(groom.offsets)
    lengths = strand_lengths(groom.points, groom.offsets)
    seg = np.linalg.norm(np.diff(groom.points, axis=0), axis=1)
    inner = np.ones(len(seg), bool)
    inner[groom.offsets[1:-1] - 1] = False
    seg = seg[inner]
    ang = np.concatenate([turning_angles(groom.points[a:b]) for a, b in zip(groom.offsets[:-1], groom.offsets[1:])
                          if b - a >= 3])
    sharp = np.array([(turning_angles(groom.points[a:b]) > 10).sum() for a, b in
                      zip(groom.offsets[:-1], groom.offsets[1:])])
    return (f"{groom.n_strands} strands, {counts.min()}-{counts.max()} points (median {np.median(counts):g}), "
            f"length {lengths.min() * 100:.1f}-{lengths.max() * 100:.1f} cm, "
            f"segments {seg.min() * 1e3:.2f}-{seg.max() * 1e3:.2f} mm; turning angle median {np.median(ang):.1f}, "
            f"p99 {np.percentile(ang, 99):.1f}, max {ang.max():.1f} deg; "
            f"vertices turning > 10 deg per strand median {np.median(sharp):g}, max {sharp.max()}")


def write(groom: Groom, path: Path) -> None:
    """Write a groom as a hairinv stage file holding ``/curves`` (metres, up = +Y)."""
    grooms.write_groom(path, groom.points, groom.offsets, groom.source)


def main(argv=None) -> int:
    names = [v.name for v in variants()]
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("outdir", help="output folder")
    parser.add_argument("names", nargs="*", metavar="NAME",
                        help=f"variants to write (default: all): {', '.join(names)}")
    parser.add_argument("--strands", type=int, default=None, help="strands per groom (default: each kind's own)")
    args = parser.parse_args(argv)
    chosen = args.names or names
    unknown = [n for n in chosen if n not in names]
    if unknown:
        parser.error(f"unknown variant(s) {', '.join(unknown)}; known: {', '.join(names)}")
    out = Path(args.outdir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    for v in variants():
        if v.name not in chosen:
            continue
        t1 = time.perf_counter()
        groom = v.make(**({"n_strands": args.strands} if args.strands else {}))
        path = out / f"{v.name}.h5"
        write(groom, path)
        print(f"{path} ({'held out' if v.held_out else 'development'}, {time.perf_counter() - t1:.1f} s): "
              f"{describe(groom)}")
    print(f"done in {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
