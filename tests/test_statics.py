"""Generalized gravity against an independent gravitational energy.

The potential is recomputed here by dense quadrature of the centerline
(not from the kernel's closed-form first moments), and F_g must equal minus
its derivative, taken by central finite differences.
"""

from __future__ import annotations

import numpy as np
import pytest

from conftest import FINITE_DIFFERENCE, point_load_potential
from hairinv.rod.helix import points_at
from hairinv.rod.statics import gravity_forces, gravity_potential

G = np.array([0.0, -9.81, 0.0])
LAM = 1300.0 * np.pi * (40e-6) ** 2  # kg/m: density 1300 kg/m^3, radius 40 um


def quadrature_potential(root, frame0, omega, length, samples_per_element=400):
    """-lam g . int x ds by composite Simpson on each element (independent of Q)."""
    total = 0.0
    start = 0.0
    for ln in length:
        s = start + np.linspace(0.0, ln, 2 * samples_per_element + 1)
        x = np.empty((len(s), 3))
        points_at(root, frame0, omega, length, s, x)
        w = np.ones(len(s))
        w[1:-1:2] = 4.0
        w[2:-1:2] = 2.0
        integral = (ln / (6 * samples_per_element)) * (w[:, None] * x).sum(axis=0)
        total -= LAM * G @ integral
        start += ln
    return total


def random_strand(rng, n, scale):
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    frame0 = q if np.linalg.det(q) > 0 else -q
    return rng.normal(size=3), frame0, rng.normal(size=(n, 3)) * scale, rng.uniform(0.01, 0.05, size=n)


@pytest.mark.parametrize("scale", [0.0, 1e-3, 10.0, 200.0])
def test_closed_form_potential_matches_quadrature(rng, scale):
    root, frame0, omega, length = random_strand(rng, 6, scale)
    v = gravity_potential(root, frame0, omega, length, LAM, G)
    assert v == pytest.approx(quadrature_potential(root, frame0, omega, length), rel=1e-10, abs=1e-18)


@pytest.mark.parametrize("n", [1, 3, 12])
@pytest.mark.parametrize("scale", [0.0, 5.0, 60.0])
def test_gravity_force_is_minus_the_gradient_of_the_potential(rng, n, scale):
    root, frame0, omega, length = random_strand(rng, n, scale)
    force = np.empty((n, 3))
    gravity_forces(root, frame0, omega, length, LAM, G, force)
    h = 1e-5
    fd = np.empty((n, 3))
    for e in range(n):
        for k in range(3):
            plus, minus = omega.copy(), omega.copy()
            plus[e, k] += h
            minus[e, k] -= h
            fd[e, k] = -(quadrature_potential(root, frame0, plus, length, 60)
                         - quadrature_potential(root, frame0, minus, length, 60)) / (2 * h)
    scale_f = np.abs(fd).max() + 1e-30
    np.testing.assert_allclose(force, fd, rtol=0, atol=1e-6 * scale_f)


def test_hanging_straight_strand_feels_no_bending_force():
    """A straight strand hanging along gravity is in equilibrium without bending."""
    frame0 = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    omega = np.zeros((5, 3))
    force = np.empty((5, 3))
    gravity_forces(np.zeros(3), frame0, omega, np.full(5, 0.06), LAM, G, force)
    np.testing.assert_allclose(force, 0.0, atol=1e-20)


def test_horizontal_cantilever_root_torque_closed_form():
    """Straight horizontal strand: the first element's bending force is the
    gravity moment of the whole strand about the root's end of element 0
    plus the element's own share: lam g L^2 / 2 in total about the root axis."""
    frame0 = np.eye(3)  # t = x (horizontal), n1 = y (up), n2 = z
    n, ell = 4, 0.05
    force = np.empty((n, 3))
    gravity_forces(np.zeros(3), frame0, np.zeros((n, 3)), np.full(n, ell), LAM, G, force)
    # kappa2 (about n2 = z) bends t towards n1: generalized force of element e is
    # the moment of the weight hanging beyond each point of e, integrated over e
    L = n * ell
    for e in range(n):
        a, b = e * ell, (e + 1) * ell
        # int_a^b lam g (L - s)^2 / 2 ds, with the sign of the downward load
        expected = -LAM * 9.81 * ((L - a) ** 3 - (L - b) ** 3) / 6.0
        assert force[e, 1] == pytest.approx(expected, rel=1e-12)
    np.testing.assert_allclose(force[:, 0], 0.0, atol=1e-20)
    np.testing.assert_allclose(force[:, 2], 0.0, atol=1e-20)


@pytest.mark.parametrize("scale", [0.0, 8.0, 80.0])
@pytest.mark.parametrize("fraction", [0.0, 0.37, 0.5, 1.0])
def test_point_jacobian_matches_finite_differences_of_positions(rng, scale, fraction):
    from hairinv.rod.statics import point_jacobian

    n = 5
    root, frame0, omega, length = random_strand(rng, n, scale)
    s = fraction * length.sum()
    J = np.empty((n, 3, 3))
    e_s = point_jacobian(root, frame0, omega, length, s, J)
    h = 1e-6
    fd = np.zeros((n, 3, 3))
    for e in range(n):
        for k in range(3):
            plus, minus = omega.copy(), omega.copy()
            plus[e, k] += h
            minus[e, k] -= h
            xp = np.empty((1, 3))
            xm = np.empty((1, 3))
            points_at(root, frame0, plus, length, np.array([s]), xp)
            points_at(root, frame0, minus, length, np.array([s]), xm)
            fd[e, k] = (xp[0] - xm[0]) / (2 * h)
    np.testing.assert_allclose(J, fd, rtol=0, atol=FINITE_DIFFERENCE * (np.abs(fd).max() + 1e-12))
    # elements downstream of the point do not move it
    assert np.all(J[e_s + 1:] == 0.0)
    assert np.all(np.abs(fd[e_s + 1:]) < 1e-12)


def test_assembled_contact_rows_match_finite_differences_of_contact_gaps(rng):
    """``H`` as assembled for many contacts at once (several on one strand, in any order, sharing the
    strand's chain, and hair-hair pairs acting on two strands): each row is the derivative of the
    contact's relative position ``x_A(s_A) - x_B(s_B)`` along its frame."""
    from hairinv.contacts.detect import contact_frames
    from hairinv.model import Contacts, Helices
    from hairinv.contacts.rows import contact_rows

    specs = [random_strand(rng, n, 8.0) for n in (4, 6, 3)]
    offsets = np.cumsum([0] + [len(sp[2]) for sp in specs])
    helices = Helices(np.array([sp[0] for sp in specs]), np.array([sp[1] for sp in specs]), offsets,
                      np.concatenate([sp[3] for sp in specs]), np.concatenate([sp[2] for sp in specs]),
                      np.zeros(len(specs)))
    total = [sp[3].sum() for sp in specs]
    pairs = [(1, -1, 0.8), (0, -1, 0.3), (1, -1, 0.1), (1, 2, 0.5), (0, -1, 0.9), (2, 0, 0.6), (1, -1, 0.45)]
    strand = np.array([(a, b) for a, b, _ in pairs], dtype=np.int64)
    s = np.array([(f * total[a], 0.0 if b < 0 else (1 - f) * total[b]) for a, b, f in pairs])
    frame = contact_frames(rng.normal(size=(len(pairs), 3)) * [1, 1, 1])
    contacts = Contacts(strand, s, np.zeros((len(pairs), 3)), frame, np.full(len(pairs), 0.3),
                        np.zeros(len(pairs)), None)
    H = contact_rows(helices, contacts).to_sparse().toarray()
    # in chunks of two contact sides (a strand's sides split between chunks, each starting its chain
    # afresh): the same entries
    chunked = contact_rows(helices, contacts, run=lambda work, n: [work(lo, min(n, lo + 2)) for lo in range(0, n, 2)])
    np.testing.assert_array_equal(chunked.to_sparse().toarray(), H)
    # the rows taken in another order (as the sweeps store them) are the rows of the contacts so ordered
    order = rng.permutation(len(pairs))
    rows = order[:, None] * 3 + np.arange(3)
    np.testing.assert_array_equal(contact_rows(helices, contacts).take(order).to_sparse().toarray(),
                                  H[rows.ravel()])
    for wrong, error in ((np.array([len(pairs)]), IndexError), (np.array([-1]), IndexError),
                         (np.ones(len(pairs), bool), TypeError), (np.array([0.0]), TypeError)):
        with pytest.raises(error):
            contact_rows(helices, contacts).take(wrong)

    def relative(omega):
        out = np.empty((len(pairs), 3))
        for i, (a, b, _) in enumerate(pairs):
            x = np.empty((1, 3))
            lo, hi = offsets[a], offsets[a + 1]
            points_at(helices.root[a], helices.frame0[a], omega[lo:hi], helices.length[lo:hi], s[i, :1], x)
            out[i] = x[0]
            if b >= 0:
                lo, hi = offsets[b], offsets[b + 1]
                points_at(helices.root[b], helices.frame0[b], omega[lo:hi], helices.length[lo:hi], s[i, 1:], x)
                out[i] -= x[0]
        return np.einsum("cij,cj->ci", frame, out).ravel()

    h = 1e-6
    fd = np.empty_like(H)
    for col in range(H.shape[1]):
        plus, minus = helices.omega.copy(), helices.omega.copy()
        plus.ravel()[col] += h
        minus.ravel()[col] -= h
        fd[:, col] = (relative(plus) - relative(minus)) / (2 * h)
    np.testing.assert_allclose(H, fd, rtol=0, atol=FINITE_DIFFERENCE * np.abs(fd).max())


@pytest.mark.parametrize("n,scale", [(1, 5.0), (4, 0.0), (6, 8.0), (5, 80.0)])
def test_gravity_hessian_is_minus_the_derivative_of_the_gravity_force(rng, n, scale):
    """The structured Hessian against central differences of F_g (itself checked against the potential
    above), column by column, on straight, wavy and curly strands; and symmetric, as a Hessian is."""
    from hairinv.rod.statics import gravity_hessian

    root, frame0, omega, length = random_strand(rng, n, scale)
    H = np.empty((3 * n, 3 * n))
    gravity_hessian(root, frame0, omega, length, LAM, G, H)
    fd = np.empty_like(H)
    step = 1e-6 * (1.0 / length.sum() + np.abs(omega).max())
    for col in range(3 * n):
        fp, fm = np.empty((n, 3)), np.empty((n, 3))
        plus, minus = omega.copy(), omega.copy()
        plus.ravel()[col] += step
        minus.ravel()[col] -= step
        gravity_forces(root, frame0, plus, length, LAM, G, fp)
        gravity_forces(root, frame0, minus, length, LAM, G, fm)
        fd[:, col] = -(fp - fm).ravel() / (2 * step)
    scale_h = np.abs(fd).max()
    np.testing.assert_allclose(H, fd, rtol=0, atol=FINITE_DIFFERENCE * scale_h)
    np.testing.assert_allclose(H, H.T, rtol=0, atol=1e-8 * scale_h)


@pytest.mark.parametrize("n", [1, 4, 9])
@pytest.mark.parametrize("scale", [0.0, 8.0, 80.0])
def test_point_load_hessian_is_the_second_derivative_of_the_load_potential(rng, n, scale):
    """The contact forces' share of the stability Hessian: second central differences of the
    potential of dead point loads, evaluated from centerline points only."""
    from hairinv.rod.statics import point_load_hessian

    root, frame0, omega, length = random_strand(rng, n, scale)
    total = length.sum()
    s = np.sort(np.concatenate([rng.uniform(0.0, total, size=4), [0.0, np.cumsum(length)[0], total]]))
    force = rng.normal(size=(len(s), 3)) * 1e-3
    out = np.empty((3 * n, 3 * n))
    point_load_hessian(root, frame0, omega, length, s, force, out)
    assert np.allclose(out, out.T, rtol=0, atol=1e-14)
    h = 1e-2  # second differences: truncation O(h^2) stays below round-off / h^2 down to about here
    fd = np.empty((3 * n, 3 * n))
    flat = omega.ravel()
    for i in range(3 * n):
        for j in range(3 * n):
            def v(di, dj):
                w = flat.copy()
                w[i] += di
                w[j] += dj
                return point_load_potential(root, frame0, w.reshape(-1, 3), length, s, force)
            fd[i, j] = (v(h, h) - v(h, -h) - v(-h, h) + v(-h, -h)) / (4 * h * h)
    scale_of = np.abs(fd).max() + 1e-12
    assert np.abs(out - fd).max() <= 1e-5 * scale_of  # the kernel's own differences: ~1e-10 relative


def test_the_groom_sample_points_are_each_strands_points_evenly_spaced_in_arc_length(rng):
    """``hairinv.dynamics.run._sample_points`` (all strands in one pass) against each strand's own
    ``points_at`` at ``per_element`` points per element and the tip, evenly spaced from root to tip."""
    from hairinv.dynamics.run import _sample_points, _samples
    from hairinv.model import Helices

    specs = [random_strand(rng, n, 8.0) for n in (4, 1, 7, 3)]
    offsets = np.cumsum([0] + [len(sp[2]) for sp in specs])
    helices = Helices(np.array([sp[0] for sp in specs]), np.array([sp[1] for sp in specs]), offsets,
                      np.concatenate([sp[3] for sp in specs]), np.concatenate([sp[2] for sp in specs]),
                      np.zeros(len(specs)))
    for per_element in (1, 2, 4):
        points, ptr = _sample_points(helices, helices.omega, per_element)
        split = _samples(helices, helices.omega, per_element)
        for k, sp in enumerate(specs):
            s = np.linspace(0.0, sp[3].sum(), per_element * len(sp[3]) + 1)
            expected = np.empty((len(s), 3))
            points_at(sp[0], sp[1], sp[2], sp[3], s, expected)
            np.testing.assert_allclose(points[ptr[k]:ptr[k + 1]], expected, rtol=0, atol=1e-15)
            np.testing.assert_array_equal(split[k], points[ptr[k]:ptr[k + 1]])
