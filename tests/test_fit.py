"""The fit: recovery of known super-helices, true distances, tolerances met."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from conftest import SAMPLES
from hairinv.config import FitSettings, ImportSettings
from hairinv.fit import fit_groom
from hairinv.groom import Groom, load_groom
from hairinv.rod import fitting
from hairinv.rod.fitting import closest_distances, fit_adaptive
from hairinv.rod.helix import points_at

UP = np.array([0.0, 1.0, 0.0])


def sample_helix(omega, length, root, frame0, per_radian=6.0, minimum=4):
    """Vertices along a known super-helix, dense enough to define it."""
    s = [0.0]
    start = 0.0
    for om, ln in zip(omega, length):
        turn = np.linalg.norm(om) * ln
        count = max(minimum, int(np.ceil(turn * per_radian)))
        s.extend(start + ln * np.arange(1, count + 1) / count)
        start += ln
    s = np.array(s)
    pts = np.empty((len(s), 3))
    points_at(root, frame0, omega, length, s, pts)
    return pts


def fit_one(pts, n, tolerance=0.0, n_max=40, max_iter=200):
    F0 = np.empty((3, 3))
    om = np.zeros((n_max, 3))
    ln = np.zeros(n_max)
    count, worst, status = fit_adaptive(pts, UP, tolerance, n, 1, n_max, max_iter, F0, om, ln)
    return F0, om[:count], ln[:count], worst


def assert_same_curve(root, F_a, om_a, ln_a, F_b, om_b, ln_b, atol):
    total = ln_a.sum()
    s = np.linspace(0.0, total, 500)
    a = np.empty((500, 3))
    b = np.empty((500, 3))
    points_at(root, F_a, om_a, ln_a, s, a)
    points_at(root, F_b, om_b, ln_b, s, b)
    np.testing.assert_allclose(a, b, rtol=0, atol=atol)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("scale", [0.0, 1e-6, 5.0, 20.0])
def test_recovers_a_known_super_helix_to_roundoff(seed, scale):
    """Random omega per element (up to ~2 rad per element, changing between elements)."""
    rng = np.random.default_rng(seed)
    n = 5
    omega = rng.normal(size=(n, 3)) * scale
    length = np.full(n, 0.06)
    root = np.array([0.0, 1.6, 0.05])
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    frame0 = q if np.linalg.det(q) > 0 else -q
    pts = sample_helix(omega, length, root, frame0)
    F0, om, ln, worst = fit_one(pts, n)
    # round-off: coordinates are ~1.6 m, so 1e-12 m is a few hundred ulp along the chain
    assert worst < 1e-12
    assert ln.sum() == pytest.approx(length.sum(), rel=1e-13, abs=1e-15)
    np.testing.assert_allclose(ln, length, rtol=1e-12)
    np.testing.assert_allclose(F0[0], frame0[0], rtol=0, atol=1e-11)
    if scale >= 1.0:
        # gauge-free parameters: twist and curvature magnitude per element
        np.testing.assert_allclose(om[:, 2], omega[:, 2], rtol=0, atol=1e-9 * scale)
        np.testing.assert_allclose(np.hypot(om[:, 0], om[:, 1]), np.hypot(omega[:, 0], omega[:, 1]),
                                   rtol=0, atol=1e-9 * scale)
    else:
        # (nearly) straight: the twist does not move the curve at round-off, so
        # it is not observable and is not compared; the bending is
        np.testing.assert_allclose(np.hypot(om[:, 0], om[:, 1]), np.hypot(omega[:, 0], omega[:, 1]),
                                   rtol=0, atol=1e-6)
    assert_same_curve(root, F0, om, ln, frame0, omega, length, atol=1e-12)


@settings(max_examples=25, deadline=None, derandomize=True)  # the same cases on every run
@given(
    n=st.integers(1, 8),
    seed=st.integers(0, 2**31 - 1),
    scale=st.floats(0.0, 25.0),
    element=st.floats(0.01, 0.08),
)
def test_recovery_property(n, seed, scale, element):
    rng = np.random.default_rng(seed)
    omega = rng.normal(size=(n, 3)) * scale
    length = np.full(n, element)
    root = rng.normal(size=3)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    frame0 = q if np.linalg.det(q) > 0 else -q
    pts = sample_helix(omega, length, root, frame0, per_radian=8.0)
    F0, om, ln, worst = fit_one(pts, n)
    bending = np.hypot(omega[:, 0], omega[:, 1]) * length
    # Round-off where every element bends visibly; where one is nearly
    # straight its twist is ill-conditioned (see the test below).
    tol = 1e-12 if bending.min() >= 0.05 else 1e-8 * length.sum()
    assert worst < tol
    assert_same_curve(root, F0, om, ln, frame0, omega, length, atol=10 * tol)


@pytest.mark.parametrize("seed", range(4))
def test_nearly_straight_strands_match_closely(seed):
    """|omega| ~ 1e-5 1/m: the twist moves the curve only by ~kappa dtau sigma^3,
    so it is ill-conditioned and the optimiser stops in a flat valley; the
    curve is still matched to 1e-8 of its length."""
    rng = np.random.default_rng(seed)
    n = 3
    omega = rng.normal(size=(n, 3)) * 3.5e-5
    length = np.full(n, 0.0625)
    root = rng.normal(size=3)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    frame0 = q if np.linalg.det(q) > 0 else -q
    pts = sample_helix(omega, length, root, frame0, per_radian=8.0)
    F0, om, ln, worst = fit_one(pts, n)
    assert worst < 1e-8 * length.sum()
    assert_same_curve(root, F0, om, ln, frame0, omega, length, atol=1e-8 * length.sum())


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("magnitude", [50.0, 200.0, 1e3, 1e4])
def test_recovers_tight_curls_to_roundoff(seed, magnitude):
    """Near-uniform helices winding up to two turns per element, |omega| up to 1e4 1/m."""
    rng = np.random.default_rng(seed)
    n = 5
    base = rng.normal(size=3)
    base *= magnitude / np.linalg.norm(base)
    omega = base + rng.normal(size=(n, 3)) * 0.05 * magnitude
    length = np.full(n, min(0.06, 12.0 / magnitude))
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    frame0 = q if np.linalg.det(q) > 0 else -q
    root = np.zeros(3)
    pts = sample_helix(omega, length, root, frame0, per_radian=4.0)
    F0, om, ln, worst = fit_one(pts, n)
    assert worst < 1e-12
    np.testing.assert_allclose(om[:, 2], omega[:, 2], rtol=0, atol=1e-8 * magnitude)
    assert_same_curve(root, F0, om, ln, frame0, omega, length, atol=1e-12)


def test_straight_polyline_gives_zero_curvature():
    pts = np.array([[0.0, 1.7, 0.0]]) + np.linspace(0, 0.3, 20)[:, None] * np.array([[0.6, -0.8, 0.0]])
    F0, om, ln, worst = fit_one(pts, 4)
    assert worst < 1e-14
    np.testing.assert_allclose(om, 0.0, atol=1e-9)
    assert ln.sum() == pytest.approx(0.3, rel=1e-14)


@pytest.mark.parametrize("curl, n", [(15.0, 3), (1500.0, 3), (300.0, 30)])
def test_fit_error_is_the_true_distance(rng, curl, n):
    """closest_distances against brute force on a dense sampling of the fitted curve; with |omega| ~ 1500
    1/m each element winds about 12 turns (a coil followed by few elements); 30 elements of a curl that
    comes back near itself, where the scan skips the elements it can rule out."""
    omega = rng.normal(size=(n, 3)) * curl
    length = np.full(n, 0.15 / n)
    root = np.zeros(3)
    frame0 = np.eye(3)
    s_pts = np.linspace(0, 0.15, 25)
    pts = np.empty((25, 3))
    points_at(root, frame0, omega, length, s_pts, pts)
    pts += rng.normal(size=pts.shape) * 1e-3
    pts[0] = root
    offsets = np.array([0, 25])
    mean = np.zeros(1)
    worst = np.zeros(1)
    closest_distances(pts, offsets, root[None], frame0[None], np.array([0, n]), omega, length, mean, worst)
    dense_s = np.linspace(0, 0.15, 200001)
    dense = np.empty((len(dense_s), 3))
    points_at(root, frame0, omega, length, dense_s, dense)
    brute = np.array([np.min(np.linalg.norm(dense - p, axis=1)) for p in pts])
    # brute force over-estimates by at most half the sampling step squared / radius
    assert worst[0] == pytest.approx(brute.max(), abs=1e-8)
    assert mean[0] == pytest.approx(brute.mean(), abs=1e-8)


@pytest.fixture(scope="module")
def wavy_subset():
    path = SAMPLES / "wavy.h5"
    groom, _ = load_groom(path, ImportSettings(guides=40, seed=3))
    return groom


def test_adaptive_fit_meets_the_tolerance_on_a_sample(wavy_subset):
    fit = FitSettings(tolerance=2e-4)
    helices, report = fit_groom(wavy_subset, fit)
    assert report.tolerance_missed == 0
    assert report.overlong == 0  # no loops invented between vertices
    assert np.all(helices.fit_error[:, 1] <= fit.tolerance * (1 + 1e-9))
    assert np.all(helices.fit_error[:, 0] <= helices.fit_error[:, 1])
    counts = np.diff(helices.offsets)
    assert counts.min() >= fit.min_elements
    # no more elements than the vertices determine: 3 n + 3 parameters for 2 (M - 1) distances
    assert np.all(3 * counts + 3 <= 2 * (np.diff(wavy_subset.offsets) - 1))
    # the fitted curves start at the roots and keep the strands' length to within the tolerance scale
    np.testing.assert_array_equal(helices.root, wavy_subset.points[wavy_subset.offsets[:-1]])
    frames = helices.frame0
    np.testing.assert_allclose(np.einsum("sij,skj->sik", frames, frames), np.broadcast_to(np.eye(3), frames.shape),
                               atol=1e-12)


def test_fixed_element_count(wavy_subset):
    helices, report = fit_groom(wavy_subset, FitSettings(elements=6))
    assert np.all(np.diff(helices.offsets) == 6)
    assert report.tolerance_missed == 0  # a fixed count is what was asked for


def test_tighter_tolerance_needs_more_elements_and_fits_closer(wavy_subset):
    loose, _ = fit_groom(wavy_subset, FitSettings(tolerance=1e-3))
    tight, _ = fit_groom(wavy_subset, FitSettings(tolerance=1e-4))
    assert tight.n_elements > loose.n_elements
    assert tight.fit_error[:, 0].mean() < loose.fit_error[:, 0].mean()


def test_groom_of_one_two_point_strand():
    groom = Groom(np.array([[0.0, 1.0, 0.0], [0.0, 0.9, 0.0]]), np.array([0, 2]), UP, 1.0, "test", np.array([0]))
    helices, report = fit_groom(groom, FitSettings())
    assert helices.n_elements == 1
    assert helices.length.sum() == pytest.approx(0.1, rel=1e-14)
    np.testing.assert_allclose(helices.omega, 0.0, atol=1e-9)


def test_fitted_curvature_stays_within_the_data_curvature(wavy_subset):
    """No degenerate shapes (tight corkscrews drawing a nearly straight piece):
    every element's curvature is bounded by the polyline's own discrete
    curvature (turning angle over segment length), with a factor for the
    smoothing of a discrete estimate."""
    helices, _ = fit_groom(wavy_subset, FitSettings())
    pts, off = wavy_subset.points, wavy_subset.offsets
    worst_data = 0.0
    for i in range(len(off) - 1):
        p = pts[off[i]:off[i + 1]]
        d = np.diff(p, axis=0)
        ln = np.linalg.norm(d, axis=1)
        cos = np.sum(d[1:] * d[:-1], axis=1) / (ln[1:] * ln[:-1])
        kappa = np.arccos(np.clip(cos, -1, 1)) / (0.5 * (ln[1:] + ln[:-1]))
        worst_data = max(worst_data, kappa.max())
    fitted = np.hypot(helices.omega[:, 0], helices.omega[:, 1])
    assert fitted.max() <= 3.0 * worst_data


def _residual_at(root, F0, omega, length, s, p, angles=(0.0, 0.0), total_change=0.0):
    """The vertex residuals (fixed fractions of the length) after turning the root tangent by ``angles``
    about its normals and changing the strand length by ``total_change``: the parameters of the fit."""
    F = np.empty((3, 3))
    fitting._rotate_rows(F0, angles[0] * F0[1] + angles[1] * F0[2], F)
    ratio = (length.sum() + total_change) / length.sum()
    n, m = len(omega), len(s)
    r = np.empty(3 * (m - 1))
    fitting._residual(root, F, omega, length * ratio, s * ratio, p, -1, np.empty((n + 1, 3)),
                      np.empty((n + 1, 3, 3)), np.empty(n + 1), r, np.zeros((m, 3)))
    return r


@pytest.mark.parametrize("n", [1, 2, 5, 9])
@pytest.mark.parametrize("odr", [False, True])
def test_normal_equations_match_finite_differences(n, odr):
    """J^T J and J^T r summed element by element (no J formed) against a Jacobian of central differences
    of the residuals: the root tangent's two angles, every omega, the strand length. With the
    orthogonal-distance rows, each interior row is the difference projected on the curve's normal plane."""
    rng = np.random.default_rng(n)
    m = 25
    omega = rng.normal(size=(n, 3)) * 15.0
    length = rng.uniform(0.01, 0.04, n)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    F0 = np.ascontiguousarray(q if np.linalg.det(q) > 0 else -q)
    root = np.array([0.1, 1.6, -0.05])
    s = np.sort(rng.uniform(0.0, length.sum(), m))
    s[0], s[-1] = 0.0, length.sum()
    p = root + rng.normal(size=(m, 3)) * 0.01
    xs, Fs, starts = np.empty((n + 1, 3)), np.empty((n + 1, 3, 3)), np.empty(n + 1)
    r, tang = np.empty(3 * (m - 1)), np.zeros((m, 3))
    fitting._residual(root, F0, omega, length, s.copy(), p, -1, xs, Fs, starts, r, tang)
    npar = 3 + 3 * n
    J = np.empty((3 * (m - 1), npar))
    h = 1e-6
    for c in range(2):
        step = np.zeros(2)
        step[c] = h
        J[:, c] = (_residual_at(root, F0, omega, length, s, p, step)
                   - _residual_at(root, F0, omega, length, s, p, -step)) / (2 * h)
    for c in range(3 * n):
        plus, minus = omega.copy(), omega.copy()
        plus.flat[c] += h
        minus.flat[c] -= h
        J[:, 2 + c] = (_residual_at(root, F0, plus, length, s, p) - _residual_at(root, F0, minus, length, s, p)) / (2 * h)
    dl = 1e-7
    J[:, -1] = (_residual_at(root, F0, omega, length, s, p, total_change=dl)
                - _residual_at(root, F0, omega, length, s, p, total_change=-dl)) / (2 * dl)
    if odr:
        for j in range(1, m - 1):
            t = tang[j]
            rows = J[3 * (j - 1):3 * j]
            rows -= np.outer(t, t @ rows)
    N, g = np.empty((npar, npar)), np.empty(npar)
    fitting._normal_equations(root, omega, length, s, p, xs, Fs, starts, r, tang, odr, N, g)
    scale = np.abs(J.T @ J).max()
    np.testing.assert_allclose(N, J.T @ J, rtol=0, atol=1e-6 * scale)
    np.testing.assert_allclose(g, J.T @ r, rtol=0, atol=1e-6 * np.abs(J.T @ r).max())
    assert np.allclose(N, N.T, rtol=0, atol=0)


def _groom_of(*strands) -> Groom:
    points = np.concatenate(strands)
    offsets = np.concatenate([[0], np.cumsum([len(s) for s in strands])]).astype(np.int64)
    return Groom(points, offsets, UP.copy(), 1.0, "test", np.arange(len(strands), dtype=np.int64))


def test_the_element_count_is_bounded_by_what_the_vertices_determine():
    """3 n + 3 parameters for 2 (M - 1) distances: a 21-point strand carries at most 12 elements, and
    fit.max_elements caps it further when above 0."""
    rng = np.random.default_rng(0)
    zigzag = np.cumsum(rng.normal(size=(21, 3)) * 0.01, axis=0)
    assert fitting.element_cap(zigzag, 0) == 12
    assert fitting.element_cap(zigzag, 5) == 5
    assert fitting.element_cap(zigzag[:4], 0) == 1
    _, report = fit_groom(_groom_of(zigzag), FitSettings())
    assert report.elements.max() <= 12


def _coil(radius, points_per_turn, turns, bend_radius, pitch):
    """A coil wound around a circular arc of radius ``bend_radius`` in the x-y plane (its axis), hanging
    down from the origin: ``points_per_turn`` points per turn, m."""
    t = np.arange(turns * points_per_turn + 1) * 2 * np.pi / points_per_turn
    a = pitch * t / (2 * np.pi) / bend_radius  # angle along the axis
    centre = np.stack([bend_radius * (1 - np.cos(a)), -bend_radius * np.sin(a), np.zeros_like(a)], axis=1)
    tangent = np.stack([np.sin(a), -np.cos(a), np.zeros_like(a)], axis=1)
    normal = np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], axis=1)  # in the plane, off the axis
    binormal = np.cross(tangent, normal)
    ring = radius * (np.cos(t)[:, None] * normal + np.sin(t)[:, None] * binormal)
    return centre + ring - ring[0]


@pytest.mark.parametrize("radius, points_per_turn", [(0.001, 5), (0.002, 5), (0.004, 7)])
def test_a_coil_sampled_at_few_points_per_turn_is_followed(radius, points_per_turn):
    """Curly hair: 25 turns of a coil around a bending axis (10 cm radius), sampled at 5-7 points per turn.
    Every vertex within the tolerance, with at most three elements per turn (a curl is not followed
    vertex by vertex), and the length of a smooth curve through the vertices: within +8 % / -1 % of the
    polyline's, and within 1 % of the coil's own arc length."""
    pitch = 3 * radius
    coil = _coil(radius, points_per_turn, 25, 0.1, pitch)
    helices, report = fit_groom(_groom_of(coil), FitSettings())
    assert report.tolerance_missed == 0 and helices.fit_error[0, 1] <= 2e-4 * (1 + 1e-9)
    assert len(helices.omega) <= 3 * 25
    polyline = np.linalg.norm(np.diff(coil, axis=0), axis=1).sum()
    fitted = helices.length.sum()
    assert 0.99 * polyline <= fitted <= 1.08 * polyline
    # the coil's own length: per turn, the hypotenuse of the ring's circumference and the pitch (to first
    # order in radius / bend radius)
    own = 25 * np.hypot(2 * np.pi * radius, pitch)
    assert fitted == pytest.approx(own, rel=0.01)


def test_a_sharp_kink_gives_no_loop():
    """A polyline turning by 60 degrees at one vertex, points every 4 mm: the fit may cut the corner or
    round it, but not wind around it. Its length stays within +8 % / -1 % of the polyline's and every
    point of the fitted curve stays near the polyline."""
    s = np.arange(0.0, 0.1, 0.004)
    a = np.stack([np.zeros_like(s), -s, np.zeros_like(s)], axis=1)
    turn = np.radians(60.0)
    b = a[-1] + np.stack([np.sin(turn) * s[1:], -np.cos(turn) * s[1:], np.zeros_like(s[1:])], axis=1)
    kinked = np.concatenate([a, b])
    helices, report = fit_groom(_groom_of(kinked), FitSettings())
    polyline = np.linalg.norm(np.diff(kinked, axis=0), axis=1).sum()
    fitted = helices.length.sum()
    assert 0.99 * polyline <= fitted <= 1.08 * polyline
    dense = np.empty((2001, 3))
    points_at(helices.root[0], helices.frame0[0], helices.omega, helices.length, np.linspace(0, fitted, 2001), dense)
    # distance of every curve point to the polyline's segments: a loop would leave it
    seg_a, seg_b = kinked[:-1], kinked[1:]
    d = seg_b - seg_a
    u = np.clip(np.einsum("psk,sk->ps", dense[:, None] - seg_a[None], d) / np.einsum("sk,sk->s", d, d), 0, 1)
    away = np.linalg.norm(dense[:, None] - (seg_a[None] + u[..., None] * d[None]), axis=2).min(axis=1)
    assert away.max() < 2e-3


def test_a_coarse_smooth_strand_and_a_noisy_one_are_reported_with_their_reasons():
    """A smooth curve sampled every 2 cm cannot be pinned to 0.2 mm between its vertices; a finely sampled
    strand with 0.5 mm noise cannot be followed within 0.2 mm by a smooth rod. Both miss the tolerance, and
    the report names each and says why; the coarse fit's length stays within +8 % / -1 %."""
    t = np.linspace(0.0, 0.3, 16)
    coarse = np.stack([0.05 * np.sin(25 * t), -t, 0.03 * np.cos(18 * t)], axis=1)
    rng = np.random.default_rng(1)
    u = np.linspace(0.0, 0.3, 101)
    noisy = np.stack([0.02 * np.sin(8 * u), -u, np.zeros_like(u)], axis=1) + rng.normal(size=(101, 3)) * 5e-4
    helices, report = fit_groom(_groom_of(coarse, noisy), FitSettings())
    assert report.missed.tolist() == [True, True]
    assert report.sagitta[0] > 2e-4 and report.smooth[0] > 0.3 and report.smooth[1] < 0.0
    assert report.noise[0] == 0.0 and report.noise[1] == pytest.approx(5e-4, rel=0.2)
    text = "\n".join(report.lines())
    assert "1 are sampled too coarsely" in text and "1 have vertices that scatter" in text
    assert "worst strands" in text and "1 (" in text and "0 (" in text
    fitted = np.add.reduceat(helices.length, helices.offsets[:-1])
    polyline = np.linalg.norm(np.diff(coarse, axis=0), axis=1).sum()
    assert 0.99 * polyline <= fitted[0] <= 1.08 * polyline


def test_a_miss_is_put_down_to_noise_only_where_the_noise_accounts_for_it():
    """A strand whose vertices scatter a little (sigma 0.014 mm: its largest deviation of 101,
    sigma sqrt(2 ln 101 + 4) = 0.05 mm, is well within 0.2 mm) but which misses the tolerance by a kink
    is reported as kinked, with a tolerance that would hold it (0.204 mm rounded up, not down to 0.2);
    one whose noise leaves 0.3 mm is reported as noisy."""
    from hairinv.fit import FitReport

    def report(sigma, worst):
        return FitReport(1, np.array([20]), np.array([[5e-5, worst]]), 1, 0.0, tolerance=2e-4,
                         length_ratio=np.ones(1), sagitta=np.array([1e-5]), missed=np.array([True]),
                         smooth=np.array([-0.6]), noise=np.array([sigma]),
                         noisy=np.array([sigma * np.sqrt(2 * np.log(101) + 4) > 2e-4]))

    text = "\n".join(report(1.4e-5, 2.044e-4).lines())
    assert "bend sharper (kinks)" in text and "scatter" not in text
    assert "raise fit.tolerance to 0.21 mm" in text
    text = "\n".join(report(6e-5, 4e-4).lines())
    assert "scatter about a smooth curve" in text and "kinks" not in text
    assert "raise fit.tolerance to 0.4 mm" in text


def test_sampling_figures_closed_forms():
    """On a circle of radius R sampled every h: the smooth curve's length is the arc (chords times
    (a/2)/sin(a/2)), the sagitta estimate h a / 8 with a the turning per vertex, and consecutive second
    differences are parallel (correlation 1 but for the ends)."""
    R, k = 0.05, 40
    a = 2 * np.pi / 60
    phi = a * np.arange(k)
    circle = np.stack([R * np.cos(phi), R * np.sin(phi), np.zeros(k)], axis=1)
    arc, sag, smooth, noise = np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(1)
    fitting.sampling_figures(circle, np.array([0, k]), arc, sag, smooth, noise)
    assert arc[0] == pytest.approx(R * a * (k - 1), rel=1e-12)
    h = 2 * R * np.sin(a / 2)
    assert sag[0] == pytest.approx(h * a / 8, rel=1e-9)
    assert smooth[0] == pytest.approx((k - 3) / (k - 2) * np.cos(a), rel=1e-9)
    assert noise[0] == 0.0


@pytest.mark.parametrize("points_per_turn", [5, 6, 8])
def test_a_coil_is_not_taken_for_noise(points_per_turn):
    """On a helix sampled evenly, each vertex's deviation from its chord turns by one step about the axis,
    so consecutive deviations correlate as cos(2 pi / n) at n points per turn (times (k-1)/k for k of
    them): positive down to 5 points per turn, and no noise is estimated."""
    t = np.arange(0, 10 * points_per_turn + 1) * (2 * np.pi / points_per_turn)
    helix = np.ascontiguousarray(np.stack([0.001 * np.cos(t), 0.001 * np.sin(t), 0.0005 * t], axis=1))
    rho, sigma = fitting._scatter(helix)
    k = len(t) - 2
    assert rho == pytest.approx((k - 1) / k * np.cos(2 * np.pi / points_per_turn), rel=1e-9)
    assert sigma == 0.0


@pytest.mark.parametrize("sigma, spacing", [(2e-4, (0.004, 0.004)), (3e-4, (0.0015, 0.005)), (1e-4, (0.002, 0.006))])
def test_the_noise_of_scattered_vertices_is_estimated(sigma, spacing):
    """Gaussian noise of deviation sigma per coordinate on a straight line sampled at even or uneven steps:
    consecutive deviations from the chords correlate near -2/3 (for even steps, exactly -2/3 in
    expectation: e_j = n_j - (n_j-1 + n_j+1)/2) and the noise is recovered to the accuracy a median of
    400 samples allows (about 5 %); without the noise, uneven steps alone are no scatter."""
    rng = np.random.default_rng(7)
    s = np.concatenate([[0.0], np.cumsum(rng.uniform(*spacing, 400))])
    line = np.stack([0.1 * s, -s, 0.3 * s], axis=1)
    rho, est = fitting._scatter(np.ascontiguousarray(line + rng.normal(0.0, sigma, line.shape)))
    assert -0.8 < rho < -0.5
    assert est == pytest.approx(sigma, rel=0.15)
    smooth_rho, smooth_sigma = fitting._scatter(np.ascontiguousarray(line))
    assert smooth_sigma < 1e-12


def test_a_coarse_wiggle_is_not_taken_for_noise():
    """A 16-point guide every 10 mm with a wiggle of 3.3 cm period (as some real guides have): its
    deviations from the chords anticorrelate like noise, but 16 vertices cannot tell a wiggle from noise,
    so no noise is estimated, the fit is not loosened to one (it stays within 2 tolerances of every
    vertex), and the report calls the strand too coarse, not noisy."""
    s = np.arange(16) * 0.01
    wiggle = np.ascontiguousarray(np.stack([0.003 * np.sin(2 * np.pi * s / 0.033), -s,
                                            0.002 * np.cos(2 * np.pi * s / 0.07)], axis=1))
    rho, sigma = fitting._scatter(wiggle)
    assert rho < 0.0 and sigma == 0.0
    helices, report = fit_groom(_groom_of(wiggle), FitSettings())
    assert report.noise[0] == 0.0 and helices.fit_error[0, 1] < 2 * 2e-4
    text = "\n".join(report.lines())
    assert "1 are sampled too coarsely" in text and "noise" not in text


def test_a_noisy_strand_is_fitted_by_the_curve_under_the_noise():
    """A wave (2 cm amplitude) sampled every 3 mm with 0.3 mm of noise per coordinate: the vertices cannot
    be followed within 0.2 mm by a rod with the elements they determine, so the fit aims at the curve under
    the noise. Measured against that noise-free curve, the fit is closer on average than the vertices
    themselves are (they lie 1.25 sigma from it on average, a Rayleigh mean); the strand is reported off
    the tolerance with its noise estimate, and its length stays within +8 % / -1 % of the polyline's once
    the length the noise adds to the chords is taken off."""
    rng = np.random.default_rng(3)
    u = np.arange(0.0, 0.25, 0.003)
    clean = np.stack([0.02 * np.sin(12 * u), -u, 0.01 * np.cos(7 * u)], axis=1)
    noisy = clean + rng.normal(0.0, 3e-4, clean.shape)
    noisy[0] = clean[0]
    helices, report = fit_groom(_groom_of(noisy), FitSettings())
    assert report.missed.tolist() == [True]
    assert report.noise[0] == pytest.approx(3e-4, rel=0.25)
    mean, worst = np.zeros(1), np.zeros(1)
    closest_distances(np.ascontiguousarray(clean), np.array([0, len(clean)]), helices.root, helices.frame0,
                      helices.offsets, helices.omega, helices.length, mean, worst)
    vertices_off = np.linalg.norm(noisy - clean, axis=1).mean()
    assert mean[0] < 0.7 * vertices_off
    text = "\n".join(report.lines())
    assert f"scatter about a smooth curve (noise of about {1e3 * report.noise[0]:.2g} mm" in text
    # Noise lengthens a chord h by 2 sigma^2 / h in expectation (its normal part |dn|^2 / 2h, dn of variance
    # 2 sigma^2 per coordinate, two coordinates normal): the bound holds against the polyline less that.
    chords = np.linalg.norm(np.diff(noisy, axis=0), axis=1)
    polyline = chords.sum() - (2 * report.noise[0] ** 2 / chords).sum()
    assert 0.99 * polyline <= helices.length.sum() <= 1.08 * polyline
    assert helices.length.sum() < chords.sum()


@pytest.mark.parametrize("points_per_turn", [5, 6, 8])
def test_arc_lengths_are_exact_on_a_helix_and_a_circle(points_per_turn):
    """The vertices' arc lengths from the polyline alone: on a helix sampled evenly (radius 2 mm, pitch
    1.5 mm per radian) sqrt(R^2 + c^2) t, and on a circle R t, to round-off; the circle formula alone
    (turning angle between chords) would miss a coil's length by percents."""
    step = 2 * np.pi / points_per_turn
    t = np.arange(0, 8 * points_per_turn + 1) * step
    R, c = 0.002, 0.0015
    helix = np.ascontiguousarray(np.stack([R * np.cos(t), R * np.sin(t), c * t], axis=1))
    s = np.zeros(len(t))
    fitting._arc_lengths(helix, s)
    np.testing.assert_allclose(s, np.hypot(R, c) * t, rtol=1e-12, atol=1e-15)
    circle = np.ascontiguousarray(np.stack([R * np.cos(t[:points_per_turn]), R * np.sin(t[:points_per_turn]),
                                            np.zeros(points_per_turn)], axis=1))
    s = np.zeros(points_per_turn)
    fitting._arc_lengths(circle, s)
    np.testing.assert_allclose(s, R * t[:points_per_turn], rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("points_per_turn", [5, 6, 8, 12])
def test_vertex_tangent_is_exact_on_a_helix(points_per_turn):
    """The tangent an element aims its end at, from the polyline alone: on a helix sampled evenly
    (radius 1 mm, pitch 3 mm) the helix's own tangent (-R sin t, R cos t, c) / |.| to round-off, where the
    chords' average is degrees off (sin(phi)/phi across the axis); the estimate says the strand coils
    there. On a circle the chords' average is exact and stays as it is; at a kink of a drape it is not
    taken for a coil."""
    step = 2 * np.pi / points_per_turn
    t = np.arange(0, 3 * points_per_turn + 1) * step
    R, c = 0.001, 0.003 / (2 * np.pi)
    helix = np.ascontiguousarray(np.stack([R * np.cos(t), R * np.sin(t), c * t], axis=1))
    out = np.zeros(3)
    for i in range(1, len(t) - 1):
        assert fitting._vertex_tangent(helix, i, out)
        exact = np.array([-R * np.sin(t[i]), R * np.cos(t[i]), c]) / np.hypot(R, c)
        np.testing.assert_allclose(out, exact, atol=1e-12)
    # what the estimate corrects: the chords' average at the last vertex, over a degree off at 12 points
    # per turn and more below
    chords = helix[i + 1] - helix[i - 1]
    assert np.degrees(np.arccos(chords @ exact / np.linalg.norm(chords))) > 1.0
    circle = np.ascontiguousarray(np.stack([R * np.cos(t[:5]), R * np.sin(t[:5]), np.zeros(5)], axis=1))
    fitting._vertex_tangent(circle, 2, out)
    np.testing.assert_allclose(out, [-np.sin(t[2]), np.cos(t[2]), 0.0], atol=1e-12)
    # a drape's corner: straight, a 20 degree turn, straight again (out of plane a little)
    kink = np.array([[0, 0, 0], [4e-3, 0, 0], [8e-3, 0, 0], [8e-3 + 4e-3 * np.cos(0.35), 4e-3 * np.sin(0.35), 1e-4],
                     [8e-3 + 8e-3 * np.cos(0.35), 8e-3 * np.sin(0.35), 3e-4]])
    assert not fitting._vertex_tangent(np.ascontiguousarray(kink), 2, out)
    assert not fitting._vertex_tangent(np.ascontiguousarray(kink), 1, out)
