"""USD curves as pinned Catmull-Rom cubics (``hairinv export ... --basis catmull-rom``).

The curve is evaluated here from the file's points with the Catmull-Rom basis and USD's pinned wrap (a
phantom point reflected beyond each end, ``2 P_0 - P_1`` and ``2 P_n-1 - P_n-2``): it passes through every
vertex, and between two vertices it follows the fitted super-helix (the closed-form centerline of the hand-made
stage file) far more closely than the straight segment of the linear curves.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from pxr import Usd, UsdGeom

from conftest import (ELEMENT_OFFSETS, FLOAT32_M, FRAME0, LENGTH, OMEGA, ROOTS, centerline, make_stage,
                      vertex_arc_lengths)
from hairinv.errors import InputError
from hairinv.export import export

# Within one helix the cubic's error between vertices h = 5 mm apart is O(h^4), the segment's h^2 k / 8
# (25 um at k = 8 1/m); measured 0.01 um against 25 um. The cubic must be this many times closer there.
CLOSER = 100.0
# Samples of the closed-form centerline the distances are measured to, and the error of that sampling
# (half a sample spacing of ~5 um, squared over the curvature radius: far below a micrometre).
DENSE = 20001
DENSE_ERROR = 1e-8


def catmull_rom_pinned(P: np.ndarray, t: float) -> np.ndarray:
    """Points at parameter ``t`` in [0, 1] of every segment of a pinned Catmull-Rom curve through ``P``."""
    Q = np.concatenate([[2 * P[0] - P[1]], P, [2 * P[-1] - P[-2]]])
    p0, p1, p2, p3 = Q[:-3], Q[1:-2], Q[2:-1], Q[3:]
    return 0.5 * (2 * p1 + (p2 - p0) * t + (2 * p0 - 5 * p1 + 4 * p2 - p3) * t ** 2
                  + (-p0 + 3 * p1 - 3 * p2 + p3) * t ** 3)


def test_catmull_rom_curves_pass_through_the_vertices_and_follow_the_helix(tmp_path):
    truth = make_stage(tmp_path / "syn.h5", frames=False)
    report = export(tmp_path / "syn.h5", tmp_path / "cubic.usda", basis="catmull-rom")
    assert "cubic pinned Catmull-Rom" in report.lines[0]
    stage = Usd.Stage.Open(str(tmp_path / "cubic.usda"))
    metres = UsdGeom.GetStageMetersPerUnit(stage)
    for path in ("/Root/Hair", "/Root/Rest"):
        curves = UsdGeom.BasisCurves(stage.GetPrimAtPath(path))
        assert curves.GetTypeAttr().Get() == UsdGeom.Tokens.cubic
        assert curves.GetBasisAttr().Get() == UsdGeom.Tokens.catmullRom
        assert curves.GetWrapAttr().Get() == UsdGeom.Tokens.pinned
        # one width per vertex is what vertex interpolation asks of a pinned cubic
        counts = np.array(curves.GetCurveVertexCountsAttr().Get())
        assert curves.ComputeInterpolationForSize(int(counts.sum()), Usd.TimeCode.Default()) == UsdGeom.Tokens.vertex
    hair = UsdGeom.BasisCurves(stage.GetPrimAtPath("/Root/Hair"))
    points = np.array(hair.GetPointsAttr().Get(), dtype=np.float64) * metres
    assert np.abs(points - truth["points"]).max() < FLOAT32_M
    s_v = vertex_arc_lengths(truth["points"], truth["offsets"], ELEMENT_OFFSETS, LENGTH)
    smooth_seen = 0
    for k, (a, z) in enumerate(itertools.pairwise(truth["offsets"])):
        P = points[a:z]
        np.testing.assert_allclose(catmull_rom_pinned(P, 0.0), P[:-1], atol=1e-15)
        np.testing.assert_allclose(catmull_rom_pinned(P, 1.0), P[1:], atol=1e-15)
        e0, e1 = ELEMENT_OFFSETS[k], ELEMENT_OFFSETS[k + 1]
        dense = centerline(ROOTS[k], FRAME0, OMEGA[e0:e1], LENGTH[e0:e1],
                           np.linspace(0.0, LENGTH[e0:e1].sum(), DENSE))

        def off_curve(X):  # distance to the closed-form centerline (sampled every ~5 um)
            return np.array([np.linalg.norm(dense - x, axis=1).min() for x in X])

        cubic, linear = off_curve(catmull_rom_pinned(P, 0.5)), off_curve(0.5 * (P[:-1] + P[1:]))
        # everywhere at least twice as close (the ends' phantom points and the elements' joints, where the
        # curvature jumps, are where a cubic through the vertices gains least)
        assert np.all(cubic <= 0.5 * linear + DENSE_ERROR)
        # segments whose four control points lie on one element (one helix): the cubic's O(h^4) error
        element = np.searchsorted(np.cumsum(LENGTH[e0:e1]), s_v[k], side="right")
        window = np.lib.stride_tricks.sliding_window_view(np.concatenate([[-1], element, [-2]]), 4)
        smooth = (window == window[:, :1]).all(axis=1) & (linear > 1e-5)
        smooth_seen += int(smooth.sum())
        assert np.all(cubic[smooth] * CLOSER < linear[smooth]), (cubic[smooth], linear[smooth])
    assert smooth_seen >= 10


def test_linear_stays_the_default_and_a_bad_basis_is_refused(tmp_path):
    make_stage(tmp_path / "syn.h5", frames=False)
    export(tmp_path / "syn.h5", tmp_path / "linear.usda")
    stage = Usd.Stage.Open(str(tmp_path / "linear.usda"))
    hair = UsdGeom.BasisCurves(stage.GetPrimAtPath("/Root/Hair"))
    assert hair.GetTypeAttr().Get() == UsdGeom.Tokens.linear
    with pytest.raises(InputError, match="--basis takes linear or catmull-rom"):
        export(tmp_path / "syn.h5", tmp_path / "bad.usda", basis="bezier")
    assert not (tmp_path / "bad.usda").exists()
    with pytest.raises(InputError, match="--basis applies to USD"):
        export(tmp_path / "syn.h5", tmp_path / "bad.obj", basis="catmull-rom")


def test_the_command_line_takes_the_basis(tmp_path):
    from conftest import hairinv

    make_stage(tmp_path / "syn.h5", frames=False)
    result = hairinv(tmp_path, "export", "syn.h5", "-o", "cubic.usdc", "--basis", "catmull-rom")
    assert result.returncode == 0, result.stderr
    stage = Usd.Stage.Open(str(tmp_path / "cubic.usdc"))
    assert UsdGeom.BasisCurves(stage.GetPrimAtPath("/Root/Hair")).GetBasisAttr().Get() == UsdGeom.Tokens.catmullRom
    refused = hairinv(tmp_path, "export", "syn.h5", "-o", "lines.obj", "--basis", "catmull-rom")
    assert refused.returncode == 2 and "--basis applies to USD" in refused.stderr
    assert not (tmp_path / "lines.obj").exists()
