"""The simulator against physics it must reproduce: closed-form contact laws, an independent
integration of the same equations of motion, energy, and the extremes."""

from __future__ import annotations

import dataclasses
import pathlib

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from conftest import horizontal_strand, material, strands
from hairinv.config import DynamicsSettings, Settings
from hairinv.dynamics import contact
from hairinv.dynamics.contact import (REACH, CoulombSettings, contact_velocities, coulomb_problem, desaxce_residual,
                                      reachable)
from hairinv.dynamics.contact import solve_coulomb as _solve_coulomb
from hairinv.dynamics.inertia import inertia_terms
from hairinv.dynamics.simulate import Motion, Simulation
from hairinv.rod.helix import points_at
from hairinv.rod.statics import gravity_forces, gravity_potential
from hairinv.solver.rows import ContactRows
from hairinv.testing import coulomb_violations, in_cone

NO_CONTACTS = dataclasses.replace(Settings().contacts, body=False, hair_hair=False)


def solve_coulomb(rows, gamma, b, mu, strand, n_strands, velocity_scale, tolerance, max_sweeps, r0, s=None,
                  part_of=None, max_rounds=20, stall_rounds=3, Wd=None):
    """:func:`hairinv.dynamics.contact.solve_coulomb` of the problem and settings these arguments give."""
    problem = coulomb_problem(rows, gamma, b, mu, strand, n_strands, velocity_scale, s=s, part_of=part_of)
    return _solve_coulomb(problem, CoulombSettings(tolerance, max_sweeps, max_rounds, stall_rounds), r0, Wd=Wd)


# ---------------------------------------------------------------- one and two contacts, closed forms

def _isotropic_rows(weights):
    """Rows Z_i^T on three private coordinates per contact, so that W = diag(w_i I)."""
    n = len(weights)
    ptr = np.arange(0, 3 * n + 1, 3, dtype=np.int64)
    cols = np.arange(3 * n, dtype=np.int64)
    vals = np.zeros((3 * n, 3))
    for i, w in enumerate(weights):
        vals[3 * i:3 * i + 3] = np.sqrt(w) * np.eye(3)
    return ContactRows(ptr, cols, vals, 3 * n)


def _solve(weights, b, mu):
    rows = _isotropic_rows(weights)
    n = len(weights)
    strand = np.stack([np.arange(n), -np.ones(n, np.int64)], axis=1).astype(np.int64)
    return solve_coulomb(rows, np.zeros(n), np.asarray(b, float), np.asarray(mu, float), strand, n, 1.0, 1e-10,
                         500, np.zeros((n, 3))), rows


@pytest.mark.parametrize("case", ["take-off", "stick", "slide"])
def test_one_contact_against_closed_forms(case):
    w, mu = 2.0, 0.4
    b = {"take-off": [0.3, 0.5, -0.2], "stick": [-1.0, 0.1, 0.2], "slide": [-1.0, 0.6, -0.8]}[case]
    result, rows = _solve([w], [b], [mu])
    r = result.r[0]
    b = np.array(b)
    if case == "take-off":  # moving apart: no force
        expected = np.zeros(3)
    elif case == "stick":  # the force that stops the contact, inside the cone
        expected = -b / w
        assert np.hypot(*expected[1:]) < mu * expected[0]
    else:  # sliding: the normal force stops the approach, friction at the cone's edge opposes the slip
        rn = -b[0] / w
        slip = b[1:] / np.linalg.norm(b[1:])
        expected = np.array([rn, *(-mu * rn * slip)])
        assert np.linalg.norm(b[1:]) > mu * w * rn
    assert result.status == "CONVERGED"
    assert np.allclose(r, expected, atol=1e-9)
    u = contact_velocities(rows, np.zeros(1), b[None, :], result.r)[0]
    if case == "slide":  # Coulomb: no normal velocity, slip along the friction force, exactly opposed
        assert abs(u[0]) < 1e-9
        assert np.allclose(np.cross(np.r_[0, u[1:]], np.r_[0, r[1:]]), 0.0, atol=1e-9)
        assert np.dot(u[1:], r[1:]) < 0


def test_two_contacts_one_sticking_one_sliding():
    result, _ = _solve([1.0, 3.0], [[-2.0, 0.1, 0.0], [-3.0, 0.0, 5.0]], [0.5, 0.2])
    assert result.status == "CONVERGED"
    assert np.allclose(result.r[0], [2.0, -0.1, 0.0], atol=1e-9)
    assert np.allclose(result.r[1], [1.0, 0.0, -0.2], atol=1e-9)


def test_zero_friction_has_no_tangential_force():
    result, _ = _solve([1.5], [[-3.0, 2.0, 1.0]], [0.0])
    assert np.allclose(result.r[0], [2.0, 0.0, 0.0], atol=1e-9)


def test_a_contact_solve_that_stops_improving_stops_there_and_keeps_its_best_iterate(monkeypatch):
    """Hair-hair contact (solved contact by contact): once ``stall_rounds`` rounds in a row have not
    halved the residual, the solve ends with its best iterate; with 0 it goes on to the fail-safe."""
    weights, mu = [1.0, 3.0], [0.5, 0.2]
    b = np.array([[-2.0, 0.1, 0.0], [-3.0, 0.0, 5.0]])
    exact = np.array([[2.0, -0.1, 0.0], [1.0, 0.0, -0.2]])  # test_two_contacts_one_sticking_one_sliding
    rows = _isotropic_rows(weights)
    strand = np.array([[0, 1], [1, 2]], np.int64)  # hair-hair: no strand-by-strand blocks
    real = contact.gauss_seidel.solve
    rounds, iterates = [], []

    def stalled(problem, law, *args, **kwargs):
        # every convex round lands at the same distance from the answer, as a stalled Gauss-Seidel
        # does; the direct De Saxce fail-safe is left as it is
        result = real(problem, law, *args, **kwargs)
        if law.desaxce:
            return result
        rounds.append(result.sweeps)
        iterates.append(1.5 * result.r)
        return dataclasses.replace(result, r=iterates[-1])

    monkeypatch.setattr(contact.gauss_seidel, "solve", stalled)

    def solve(stall_rounds):
        rounds.clear()
        iterates.clear()
        return solve_coulomb(rows, np.zeros(2), b, np.array(mu), strand, 3, 1.0, 1e-10, 10_000, np.zeros((2, 3)),
                             stall_rounds=stall_rounds)

    early = solve(3)
    assert len(rounds) == 4  # the first round, then three that do not halve its residual
    assert early.status == "MAX_ITERS" and early.sweeps == sum(rounds)
    best = min(h for _, h in early.history)
    assert early.residual == best > 1e-3
    residuals = [desaxce_residual(rows, np.zeros(2), b, np.array(mu), r) for r in iterates]
    assert np.array_equal(early.r, iterates[int(np.argmin(residuals))]) and min(residuals) == best
    full = solve(0)
    assert len(rounds) == 20  # max_rounds
    assert full.status == "CONVERGED"
    assert np.allclose(full.r, exact, atol=1e-9)


def _rows_of(W):
    """Rows Z^T of one contact on three private coordinates with Z^T Z = W (W symmetric, PSD)."""
    lam, Q = np.linalg.eigh(W)
    vals = (Q * np.sqrt(np.maximum(lam, 0.0))).T.copy()  # column c of H: sqrt(lam_c) q_c
    return ContactRows(np.array([0, 3], np.int64), np.arange(3, dtype=np.int64), vals, 3)


def _rotation(seed):
    q, _ = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    return q


@pytest.mark.parametrize("ratio, kept", [(1e-12, False), (0.5 * REACH, False), (2.0 * REACH, True)])
def test_only_the_velocities_a_contact_can_reach_are_asked_for(ratio, kept):
    """Along each eigenvector of W_ii the demand is kept whole or dropped whole, by its eigenvalue."""
    Q = _rotation(3)
    lam = np.array([ratio, 0.4, 1.0]) * 7.0
    W = (Q * lam) @ Q.T
    demand = np.array([[0.3, -1.2, 0.7]])
    out = reachable(W[None], demand)[0]
    along = Q.T @ demand[0]
    expected = np.array([along[0] if kept else 0.0, along[1], along[2]])
    assert np.allclose(Q.T @ out, expected, atol=1e-12)


def test_the_blocks_left_undecomposed_have_no_weak_direction():
    """``reachable`` decomposes only blocks that pass a cheap test; on blocks of every shape, from
    isotropic to rank one, near REACH on both sides, it equals the decomposition of every block."""
    rng = np.random.default_rng(11)
    n = 3000
    lam = np.sort(10.0 ** rng.uniform(-14, 0, size=(n, 3)), axis=1) * 10.0 ** rng.uniform(-3, 6, size=(n, 1))
    lam[:300, 0] = lam[:300, 2] * REACH * rng.uniform(0.9, 1.1, 300)  # at the threshold
    lam[300:600, :2] = lam[300:600, 2:3] * REACH * rng.uniform(0.9, 1.1, (300, 2))  # two weak directions
    Q = np.array([_rotation(k) for k in range(n)])
    W = np.einsum("cij,cj,ckj->cik", Q, lam, Q)
    demand = rng.normal(size=(n, 3))
    out = reachable(W, demand)
    l, V = np.linalg.eigh(W)
    along = np.einsum("cik,ci->ck", V, demand) * (l >= REACH * l[:, 2:3])
    expected = np.einsum("cik,ck->ci", V, along)
    assert np.allclose(out, expected, rtol=0, atol=1e-9 * np.abs(demand).max())
    weak = (l < REACH * l[:, 2:3]).any(axis=1)
    assert 0.2 * n < weak.sum() < 0.95 * n  # the sample has both kinds
    assert np.array_equal(out[~weak], demand[~weak])


def test_a_push_the_contact_point_cannot_follow_takes_no_huge_impulse():
    """A point near a root that cannot move along ``n0`` (a direction inside the friction cone),
    with a push out along the normal: asked as is, the compliance of 1e-9 alone bounds the impulse
    along ``n0`` (``-(b . n0) / gamma``, newton-seconds on hair); asked only what it can reach, the
    impulse is that of an ordinary contact and the reachable part of the push is met."""
    a, mu, w = np.radians(10.0), 0.3, 2.0
    n0 = np.array([np.cos(a), np.sin(a), 0.0])
    W = w * (np.eye(3) - np.outer(n0, n0))  # the point moves freely across n0, not along it
    rows = _rows_of(W)
    gamma = np.array([1e-9 * w])
    free = W @ np.array([-0.1, 0.05, 0.02])  # the free motion: in the range of H, so of W (approaching)
    push = np.array([[0.05, 0.0, 0.0]])  # a contact found inside, pushed out
    strand = np.array([[0, -1]], np.int64)

    def solve(b):
        return solve_coulomb(rows, gamma, b, np.array([mu]), strand, 1, 1.0, 1e-10, 2000, np.zeros((1, 3)))

    raw = solve(free[None] - push)
    assert np.linalg.norm(raw.r) > 1e6 / w, "the scene does not test what it claims"
    Wd = W[None]
    asked = free[None] - reachable(Wd, push)
    result = solve(asked)
    assert result.status == "CONVERGED"
    assert np.linalg.norm(result.r) < 10.0 * np.linalg.norm(asked) / w
    u = contact_velocities(rows, gamma, asked, result.r)[0]
    # the solution of the law: normal velocity at least what was asked across n0, and complementary
    assert u[0] >= -1e-9
    assert abs(u[0] * result.r[0, 0]) < 1e-9


def _strand_contacts(rng, counts, n_dofs=24, spread=0.05):
    """Body contacts on strands with ``counts[k]`` contacts each, on the strand's private coordinates,
    with nearly parallel rows (contacts along one strand), and a mix of approaching and separating b."""
    ptr, cols, vals, strand = [0], [], [], []
    for k, m in enumerate(counts):
        base = rng.normal(size=(n_dofs, 3))
        for _ in range(m):
            cols += list(range(k * n_dofs, (k + 1) * n_dofs))
            vals.append(base + spread * rng.normal(size=(n_dofs, 3)))
            ptr.append(ptr[-1] + n_dofs)
            strand.append([k, -1])
    rows = ContactRows(np.array(ptr), np.array(cols), np.concatenate(vals), n_dofs * len(counts))
    n = rows.n_contacts
    b = rng.normal(size=(n, 3))
    b[:, 0] -= 0.5  # mostly approaching
    return rows, np.array(strand, np.int64), b


def _strands_by_newton(rows, strand, b, gamma, mus, target, iterations):
    """Each strand's body contacts from zero by the strands' Newton kernel: ``(r, f, done, Wd)``."""
    from hairinv.dynamics.contact import strand_groups
    from hairinv.solver.blocks import group_newton

    members, group_ptr, block_ptr, blocks, Wd = strand_groups(rows, gamma, strand)
    r = np.zeros((rows.n_contacts, 3))
    f = np.zeros(rows.n_dofs)
    done = np.zeros(len(group_ptr) - 1, np.bool_)
    group_newton(rows.ptr, rows.cols, rows.vals, gamma, b, mus, members, group_ptr, block_ptr, blocks, Wd, r, f,
                  target, iterations, True, True, 0, len(done), done)
    return r, f, done, Wd


def _desaxce_violation(rows, gamma, b, mu, r):
    """Largest violation of ``K ∋ r ⟂ u~ ∈ K*`` (u~ = u + mu |u_T| e_N; hairinv.testing), from dense W assembled
    here."""
    Z = rows.to_sparse().toarray()
    W = Z @ Z.T + np.diag(np.repeat(gamma, 3))
    worst = coulomb_violations(W, b, r, mu).worst()
    return max(worst["primal"], worst["dual"], worst["complementarity"])


@pytest.mark.parametrize("mu", [0.0, 0.3, 1.0, 2.5, np.inf])
def test_the_stacked_de_saxce_fb_jacobian_is_its_derivative(mu):
    """The Jacobian the strand's Newton steps use, against central differences of the stacked FB
    function ``phi_i = FB(x_i, u~_i)`` written here from ``fb_function`` (scaled forces
    ``x_i = rho_i r_i``, a different rho per contact, contacts with different mu in one group)."""
    from hairinv.solver.blocks import _group_merit
    from hairinv.solver.local import fb_function

    rng = np.random.default_rng(3)
    m = 4
    n = 3 * m
    A = rng.normal(size=(n, n)) * np.repeat([1.0, 10.0, 0.1, 3.0], 3)
    W = A @ A.T + 0.1 * np.eye(n)
    q = rng.normal(size=n)
    rho = np.array([0.5, 30.0, 0.02, 2.0])
    mus = np.array([mu, 0.3, mu, 1.0])
    x = rng.normal(size=n)
    x[::3] = np.abs(x[::3]) + 0.5  # in the interior of the cones' neighbourhood: away from the kinks

    def phi_of(x):
        u = W @ (x / np.repeat(rho, 3)) + q
        out = np.empty(n)
        for a in range(m):
            ua = u[3 * a:3 * a + 3].copy()
            if np.isfinite(mus[a]):
                ua[0] += mus[a] * np.hypot(ua[1], ua[2])
            fb_function(x[3 * a:3 * a + 3].copy(), ua, mus[a], out[3 * a:3 * a + 3])
        return out

    u, phi, G = np.empty(n), np.empty(n), np.empty((n, n))
    merit, _ = _group_merit(W, n, q, rho, mus, x, u, phi, G, np.empty((3, 3)), np.empty((3, 3)), True,
                            True, True)
    np.testing.assert_allclose(phi, phi_of(x), rtol=0, atol=1e-12 * np.abs(phi).max())
    assert merit == pytest.approx(0.5 * phi @ phi, rel=1e-12)
    eps = 1e-6
    numeric = np.column_stack([(phi_of(x + eps * e) - phi_of(x - eps * e)) / (2 * eps) for e in np.eye(n)])
    assert np.abs(G - numeric).max() <= 1e-6 * np.abs(numeric).max()


@pytest.mark.parametrize("mu", [0.0, 0.3, 1.0, np.inf])
def test_a_strands_body_contacts_solved_together_meet_the_de_saxce_law(mu):
    """Each strand's body contacts solved at once (Newton on the stacked De Saxce FB function): the
    forces are in the cones, the De Saxce velocities in the dual cones and complementary, checked on
    the dense W; and a strand it does not finish is finished by the rounds that follow."""
    from hairinv.solver.gauss_seidel import accumulate_f

    rng = np.random.default_rng(5)
    rows, strand, b = _strand_contacts(rng, [1, 2, 3, 4, 5, 3, 2, 4])
    n = rows.n_contacts
    gamma, mus, target = np.full(n, 1e-9), np.full(n, mu), 1e-10
    r, f, done, Wd = _strands_by_newton(rows, strand, b, gamma, mus, target, 30)
    assert done.all()
    assert _desaxce_violation(rows, gamma, b, mus, r) < 1e-8 * np.abs(b).max()
    assert desaxce_residual(rows, gamma, b, mus, r, Wd) <= target  # the solver's own stop test agrees
    ones = np.ones(rows.n_dofs)
    expected_f = np.empty(rows.n_dofs)
    accumulate_f(rows.ptr, rows.cols, rows.vals, ones, r, expected_f)
    np.testing.assert_allclose(f, expected_f, atol=1e-12 * np.abs(f).max())  # f kept up to date
    assert np.abs(r).max() > 0 and (r[:, 0] > 0).sum() < n, "no mix of touching and separating contacts"

    # strands 1 and 4 restarted from zero and no Newton step: the fixed point of convex problems, strand by
    # strand, finishes them, and leaves the others
    r0 = r.copy()
    redo = np.isin(strand[:, 0], [1, 4])
    r0[redo] = 0.0
    contact.GROUP_NEWTON_ITERS, saved = 0, contact.GROUP_NEWTON_ITERS
    try:
        result = solve_coulomb(rows, gamma, b, mus, strand, 8, 1.0, target, 500, r0)
    finally:
        contact.GROUP_NEWTON_ITERS = saved
    assert result.status == "CONVERGED" and result.sweeps > 1
    assert _desaxce_violation(rows, gamma, b, mus, result.r) < 1e-8 * np.abs(b).max()
    # the strands already solved are left as they were, up to the rounding of their scaled forces' projection
    assert np.abs(result.r[~redo] - r[~redo]).max() <= 1e-12 * np.abs(r).max()


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("mu", [0.3, 1.0])
def test_strands_newton_leaves_are_finished_by_the_fixed_point_of_convex_problems(seed, mu):
    """Each strand's first contact sits near its root: the coordinates move it a hundredth as much as the
    others (W_ii 1e-4 of theirs), which stalls Newton on the stacked FB function for some strands. The
    fixed point of convex problems on each such strand's block finishes them: the De Saxce conditions
    hold, checked on the dense W."""
    from hairinv.solver.rows import ContactRows

    rng = np.random.default_rng(seed)
    counts = [5, 6, 4, 8]
    rows, strand, b = _strand_contacts(rng, counts)
    vals = rows.vals.copy()
    for i in np.r_[0, np.cumsum(counts)[:-1]]:
        vals[rows.ptr[i]:rows.ptr[i + 1]] *= 1e-2
    rows = ContactRows(rows.ptr, rows.cols, vals, rows.n_dofs)
    n = rows.n_contacts
    gamma, mus, target = np.full(n, 1e-9), np.full(n, mu), 1e-10
    _, _, done, Wd = _strands_by_newton(rows, strand, b, gamma, mus, target, contact.GROUP_NEWTON_ITERS)
    assert not done.all(), "Newton alone finishes every strand: the case does not test the fixed point"
    result = solve_coulomb(rows, gamma, b, mus, strand, len(counts), 1.0, target, 200, np.zeros((n, 3)))
    assert result.status == "CONVERGED"
    assert desaxce_residual(rows, gamma, b, mus, result.r, Wd) <= target
    assert _desaxce_violation(rows, gamma, b, mus, result.r) < 1e-6 * np.abs(b).max()


# ---------------------------------------------------------------- free motion of one strand

def _strand(n=4, total=0.08, curl=0.0):
    return strands([horizontal_strand(n=n, total=total, curl=curl)])


def _sim(helices, rest, h, mat=None, **dyn):
    settings = dataclasses.replace(DynamicsSettings(damping=0.0, air_damping=0.0, time_step=h), **dyn)
    return Simulation(helices, rest, mat or material(), None, NO_CONTACTS, settings)


def _tip(helices, q):
    out = np.empty((1, 3))
    points_at(helices.root[0], helices.frame0[0], q, helices.length, np.array([helices.length.sum()]), out)
    return out[0]


def test_free_swing_matches_an_independent_integration():
    """A straight strand released horizontally, no contact, no damping: the tip's path against
    scipy's adaptive Runge-Kutta on M q'' = F_g - K (q - q0) + b(q, q') (the kernels checked in
    test_inertia.py and test_statics.py), to 1 % of the distance it falls."""
    helices = _strand()
    mat = material()
    settings = DynamicsSettings(damping=0.0, air_damping=0.0, time_step=2e-5, max_turn=1.0)
    rot = mat.linear_density * settings.inertia_radius ** 2 / 4.0
    stiff = np.array([mat.bending, mat.bending, mat.twisting])[None, :] * helices.length[:, None]
    n = helices.n_elements

    def rhs(_t, y):
        q, v = y[:3 * n].reshape(n, 3), y[3 * n:].reshape(n, 3)
        M, bias = inertia_terms(helices.root[0], helices.frame0[0], q, helices.length, v, mat.linear_density, rot)
        g = np.empty((n, 3))
        gravity_forces(helices.root[0], helices.frame0[0], q, helices.length, mat.linear_density, mat.gravity, g)
        force = g.ravel() - (stiff * q).ravel() + bias
        return np.concatenate([v.ravel(), np.linalg.solve(M, force)])

    T = 0.03
    ref = solve_ivp(rhs, (0.0, T), np.zeros(6 * n), rtol=1e-9, atol=1e-9, method="DOP853")
    q_ref = ref.y[:3 * n, -1].reshape(n, 3)
    sim = Simulation(helices, np.zeros_like(helices.omega), mat, None, NO_CONTACTS, settings)
    for _ in range(int(round(T / settings.time_step))):
        sim.step(Motion.still(mat.gravity))
    start, tip, tip_ref = _tip(helices, helices.omega), _tip(helices, sim.q), _tip(helices, q_ref)
    fall = np.linalg.norm(tip_ref - start)
    assert fall > 1e-3
    assert np.linalg.norm(tip - tip_ref) < 0.01 * fall


def test_undamped_swing_never_gains_energy():
    """Kinetic + elastic + gravitational energy over 1,000 steps without damping: linearly implicit
    Euler may lose energy, never gain it (beyond 0.1 % of the energy exchanged)."""
    helices = _strand(curl=20.0)
    mat = material()
    sim = _sim(helices, np.zeros_like(helices.omega), 1e-3, mat)

    def energy():
        M, _ = inertia_terms(helices.root[0], helices.frame0[0], sim.q, helices.length, sim.v, sim.lam, sim.rot)
        v = sim.v.ravel()
        return 0.5 * v @ M @ v, sim.elastic_energy() + gravity_potential(
            helices.root[0], helices.frame0[0], sim.q, helices.length, sim.lam, mat.gravity)

    energies, exchanged = [], 0.0
    for _ in range(1000):
        sim.step(Motion.still(mat.gravity))
        kinetic, potential = energy()
        energies.append(kinetic + potential)
        exchanged = max(exchanged, kinetic)
    energies = np.array(energies)
    assert exchanged > 0
    assert np.all(np.diff(energies) <= 1e-3 * exchanged)
    assert energies[-1] > energies[0] - exchanged  # it swings, it does not just stop


# ---------------------------------------------------------------- extremes

@pytest.mark.parametrize("name, youngs, h, curl", [
    ("very stiff", 4e12, 0.01, 0.0),
    ("very soft", 4e5, 0.01, 0.0),
    ("tiny step", 4e9, 1e-5, 0.0),
    ("large step", 4e9, 0.1, 0.0),
    ("extremely curly", 4e9, 0.01, 500.0),
])
def test_extremes_stay_finite_and_lose_energy(name, youngs, h, curl):
    """Released from a shape away from its rest shape, with the default damping: the motion stays
    finite and the strand ends with less energy than it started with."""
    helices = _strand(n=6, total=0.12, curl=curl)
    mat = material(youngs_modulus=youngs)
    rest = np.zeros_like(helices.omega)
    sim = Simulation(helices, rest, mat, None, NO_CONTACTS, DynamicsSettings(time_step=h))

    def potential():
        return sim.elastic_energy() + gravity_potential(helices.root[0], helices.frame0[0], sim.q, helices.length,
                                                        sim.lam, mat.gravity)

    start = potential()
    steps = max(1, int(round(min(0.2, 50 * h) / h)))
    for _ in range(steps):
        sim.step(Motion.still(mat.gravity))
        assert np.all(np.isfinite(sim.q))
    assert potential() + sim.kinetic_energy() <= start + 1e-12 * abs(start)


def _floor(depth, x=0.3):
    """A flat floor (a box as the body) whose top face is ``depth`` m below the strand's plane,
    under x in ``x +- 0.5``."""
    import trimesh

    from hairinv.contacts.body import BodyMesh

    floor = trimesh.creation.box(extents=(1.0, 0.2, 1.0))
    floor.apply_translation((x, -0.1 - depth, 0.0))
    return BodyMesh.from_mesh(floor)


def _inverted_on_a_floor(**dynamics):
    """A horizontal strand lying on a floor 1 mm below it, inverted with its contacts, and the
    simulation started from that model (``dynamics``: settings changed from the defaults):
    (helices, body, material, simulation). Nothing sleeps unless ``dynamics`` says so: the steps
    themselves are what is tested (sleeping: tests/test_sleep.py)."""
    from hairinv.contacts import detect_contacts
    from hairinv.invert import invert

    helices = _strand(n=6, total=0.12)
    body = _floor(1e-3)
    settings = Settings()
    contacts, _ = detect_contacts(helices, body, settings.contacts)
    assert contacts.n_body >= 4
    mat = material()
    model, _ = invert(helices, contacts, mat, settings.solver)
    sim = Simulation(helices, model.omega_rest, mat, body, settings.contacts,
                     dataclasses.replace(settings.dynamics, **{"sleep_speed": 0.0, **dynamics}), initial=contacts,
                     initial_force=model.force)
    return helices, body, mat, sim


def test_a_strand_resting_along_the_body_stays_put():
    """A strand lying on a flat floor along its whole length (a box as the body), inverted with its
    contacts: the simulation keeps it where it is."""
    helices, _, mat, sim = _inverted_on_a_floor()
    start = _tip(helices, helices.omega)
    for _ in range(50):
        sim.step(Motion.still(mat.gravity))
    assert np.linalg.norm(_tip(helices, sim.q) - start) < 1e-7


def test_a_step_whose_warm_start_meets_the_tolerance_skips_the_solve_and_its_factored_rows(monkeypatch):
    """A still groom at its equilibrium: the last step's impulses meet the tolerance, checked from ``H``
    and the strands' factors; the step then builds no factored rows, and moves the strand as the full
    solve does, to round-off. Under twice the gravity the warm start fails the check and the solve runs."""
    import hairinv.dynamics.simulate as simulate

    real = simulate.factored_rows
    built = []
    monkeypatch.setattr(simulate, "factored_rows", lambda *a, **k: built.append(1) or real(*a, **k))
    helices, _, mat, quick = _inverted_on_a_floor()
    full = _inverted_on_a_floor()[3]
    full._warm_start = lambda *args: (None, None)
    for _ in range(10):
        a, b = quick.step(Motion.still(mat.gravity)), full.step(Motion.still(mat.gravity))
        assert a.status == b.status == "CONVERGED" and a.sweeps == b.sweeps == 0
    assert len(built) == 10  # the full solve's only
    # round-off of two orders of the same sums: curvatures of a 0.12 m strand within 1e-12 1/m, tips 1e-13 m
    np.testing.assert_allclose(quick.q, full.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(quick.v, full.v, rtol=0, atol=1e-10)
    assert np.linalg.norm(_tip(helices, quick.q) - _tip(helices, full.q)) < 1e-13
    built.clear()
    report = quick.step(Motion.still(2.0 * mat.gravity))
    assert len(built) == 1 and report.sweeps > 0


def test_a_still_groom_meeting_the_contact_law_skips_the_solve_below_the_floor_of_the_compliance():
    """Each contact's compliance gamma (``simulate.COMPLIANCE`` of its W_ii) moves its velocity by gamma r.
    On 40 curly guides at rest (hair-hair contact, forces in part statically indeterminate) the exact
    forces miss the compliant law by 1.1e-8 of g h, which 100 sweeps do not lower: asked for 1e-8 (the
    final preset's tolerance), every step spent all its sweeps. The warm start is accepted when it meets
    the law itself: the groom holds still with no sweep, every contact's relative velocity (H v) within
    the tolerance of zero and its force in its cone, while the compliant residual is over the tolerance."""
    from hairinv import config
    from hairinv.contacts.body import BodyMesh
    from hairinv.dynamics import simulate
    from hairinv.dynamics.contact import factored_blocks
    from hairinv.dynamics.run import _samples
    from hairinv.invert import invert
    from hairinv.model import Material
    from hairinv.pipeline import prepare
    from hairinv.solver.gauss_seidel import natural_residuals
    from hairinv.contacts.rows import contact_rows

    tolerance, sweeps, steps = 1e-8, 100, 3
    settings = config.apply(config.resolve(), {"import": {"guides": 40}})
    samples = pathlib.Path(__file__).resolve().parents[1] / "samples"
    scene = prepare(samples / "curly.h5", samples / "body.obj", settings)
    assert np.any(scene.contacts.strand[:, 1] >= 0)
    mat = Material.from_settings(settings.material, scene.up)
    model, _ = invert(scene.helices, scene.contacts, mat, settings.solver)
    dynamics = dataclasses.replace(settings.dynamics, time_step=0.0025, tolerance=tolerance, max_sweeps=sweeps,
                                   stall_rounds=0)

    def simulation():
        return Simulation(scene.helices, model.rest, mat, BodyMesh.from_mesh(scene.body), settings.contacts,
                          dynamics, initial=scene.contacts, initial_force=model.force, stiffening=model.stiffening)

    forced = simulation()
    forced._warm_start = lambda *args: (None, None)  # every step through the sweeps
    for _ in range(steps):
        report = forced.step(Motion.still(mat.gravity))
    assert report.sweeps == sweeps and report.status == "MAX_ITERS" and report.relative_residual > tolerance

    sim = simulation()
    start = [p.copy() for p in _samples(scene.helices, sim.q)]
    for _ in range(steps):
        report = sim.step(Motion.still(mat.gravity))
        assert report.status == "CONVERGED" and report.sweeps == 0 and report.relative_residual <= tolerance
    scale = sim.velocity_scale * dynamics.time_step
    rows = contact_rows(sim.current(), sim.contacts)
    assert np.max(np.linalg.norm(rows.matvec(sim.v.ravel()), axis=1)) <= tolerance * scale
    r = sim._remember(sim.contacts, dynamics.time_step)[2]  # the last impulses, in the contacts' order and frames
    mu = sim.contacts.mu
    assert np.all(in_cone(r, mu, atol=0.0, rtol=1e-12))
    for a, b in zip(start, _samples(scene.helices, sim.q)):
        assert np.max(np.linalg.norm(a - b, axis=1)) < 1e-12
    # the compliant law alone would have refused these impulses
    Wd = factored_blocks(rows, sim.contacts.strand, scene.helices.offsets, sim.chol, sim.chol_ptr)
    gamma = simulate.compliance(Wd)
    Wd[:, [0, 1, 2], [0, 1, 2]] += gamma[:, None]
    f = sim._mass_solve(rows.rmatvec(r))
    b = rows.matvec(sim.v.ravel() - f)  # H v_free (the groom rests where it started: no push)
    per = np.empty(rows.n_contacts)
    compliant = natural_residuals(rows.ptr, rows.cols, rows.vals, f, gamma, Wd, b, mu, r, True, True, per)
    assert compliant > tolerance * scale


def test_a_failed_contact_solve_halves_the_step_and_stops_the_run_only_at_the_last_halving(monkeypatch):
    """The fail-safe of a contact solve that returns NUMERICAL_ERROR: nothing of the attempt is kept,
    the step is taken as two halves; only a failure at ``max_substeps`` halvings ends the run."""
    import hairinv.dynamics.simulate as simulate

    helices, _, mat, sim = _inverted_on_a_floor()
    real = simulate.solve_coulomb
    calls = []

    def failing(first_n):
        def solve(*args, **kwargs):
            calls.append(1)
            result = real(*args, **kwargs)
            return dataclasses.replace(result, status="NUMERICAL_ERROR") if len(calls) <= first_n else result
        return solve

    start = _tip(helices, helices.omega)
    # the solve itself (not the warm start's check that lets a still groom skip it)
    monkeypatch.setattr(simulate.Simulation, "_warm_start", lambda self, *args: (None, None))
    monkeypatch.setattr(simulate, "solve_coulomb", failing(1))
    report = sim.step(Motion.still(mat.gravity))
    assert len(calls) == 3 and report.substeps == 2  # the failed attempt, then two half steps
    assert np.all(np.isfinite(sim.q)) and np.linalg.norm(_tip(helices, sim.q) - start) < 1e-7

    calls.clear()
    sim.settings = dataclasses.replace(sim.settings, max_substeps=2)
    sim.start_depth = 0  # as a fresh simulation: the next step starts whole
    q = sim.q.copy()
    monkeypatch.setattr(simulate, "solve_coulomb", failing(10**9))
    with pytest.raises(FloatingPointError, match=r"contact solve failed at a step of .* s, halved 2 times: "
                                                 r"NUMERICAL_ERROR after \d+ sweeps, relative residual .*, \d+ contacts"):
        sim.step(Motion.still(mat.gravity))
    assert len(calls) == 3  # the step, its first half, that half's first half
    assert np.array_equal(sim.q, q)  # nothing of a failed step is kept


def test_a_step_starts_as_halved_as_the_last_one_needed_and_tries_one_fewer_after(monkeypatch):
    """An attempt that is thrown away costs a whole step: after a step that needed a halving, the
    next step starts as halved as that step's last substep was (no attempt thrown away); after a
    step that needed no more, the next one tries one halving fewer. The substeps cover the step."""
    import hairinv.dynamics.simulate as simulate

    helices, _, mat, sim = _inverted_on_a_floor()
    real = simulate.solve_coulomb
    calls = []
    failing = {1}  # which calls of the current step fail (1: its first)

    def solve(*args, **kwargs):
        calls.append(1)
        result = real(*args, **kwargs)
        if len(calls) in failing:
            return dataclasses.replace(result, status="NUMERICAL_ERROR")
        return result

    # every step through the solve (not the warm start's check that lets a still groom skip it)
    monkeypatch.setattr(simulate.Simulation, "_warm_start", lambda self, *args: (None, None))
    monkeypatch.setattr(simulate, "solve_coulomb", solve)
    lengths = []
    real_step = sim._step
    monkeypatch.setattr(sim, "_step",
                        lambda motion, h, depth, *rest: lengths.append(h) or real_step(motion, h, depth, *rest))
    h = sim.settings.time_step
    still = Motion.still(mat.gravity)
    report = sim.step(still)
    assert (len(calls), report.substeps, report.rejected, report.depth, report.last_depth) == (3, 2, 1, 1, 1)
    assert sim.start_depth == 1
    calls.clear()
    lengths.clear()
    failing.clear()
    report = sim.step(still)
    # two half steps straight away: nothing thrown away
    assert (len(calls), report.substeps, report.rejected) == (2, 2, 0)
    assert lengths == [0.5 * h, 0.5 * h]
    assert sim.start_depth == 0
    calls.clear()
    report = sim.step(still)
    assert (len(calls), report.substeps, report.rejected) == (1, 1, 0)

    # the first half needs quarters, the second does not: the next step starts at the last substep's depth
    sim.start_depth = 1
    failing.add(1)
    calls.clear()
    lengths.clear()
    report = sim.step(still)
    assert (len(calls), report.substeps, report.rejected, report.depth, report.last_depth) == (4, 3, 1, 2, 1)
    assert lengths == [0.5 * h, 0.25 * h, 0.25 * h, 0.5 * h]
    assert sim.start_depth == 1
    # and the other way round: only the last quarter needs eighths, so the next step starts with eighths
    sim.start_depth = 2
    failing.clear()
    failing.add(4)
    calls.clear()
    lengths.clear()
    report = sim.step(still)
    assert lengths == [0.25 * h] * 4 + [0.125 * h] * 2
    assert (report.substeps, report.rejected, report.depth, report.last_depth) == (5, 1, 3, 3)
    assert sim.start_depth == 3

    # a substep's unconverged solve is the step's, whichever substep it was, and local failures add up
    def unconverged_first(*args, **kwargs):
        calls.append(1)
        result = real(*args, **kwargs)
        return dataclasses.replace(result, status="MAX_ITERS", local_failures=2) if len(calls) == 1 else \
            dataclasses.replace(result, local_failures=1)

    monkeypatch.setattr(simulate, "solve_coulomb", unconverged_first)
    sim.start_depth = 1
    calls.clear()
    report = sim.step(still)
    assert (report.substeps, report.status, report.local_failures) == (2, "MAX_ITERS", 3)

    # the start depth never exceeds the halvings allowed, even when these are lowered between steps
    monkeypatch.setattr(simulate, "solve_coulomb", real)
    sim.start_depth = 3
    sim.settings = dataclasses.replace(sim.settings, max_substeps=0)
    report = sim.step(still)
    assert report.substeps == 1 and sim.start_depth == 0


def test_hair_that_falls_into_the_body_within_one_step_is_pushed_back_out():
    """A strand falling fast onto a floor in full steps (no halving): it crosses the whole detection
    distance within one step, so its contacts are first found inside. They are pushed back out at
    no more than ``push_speed``, not held at the depth they were found at (and no slower than the
    limit near a root allows at the floor's nearest arc, 60 mm: ``simulate.push_limit``)."""
    from hairinv.dynamics import simulate

    helices = _strand(n=6, total=0.12)
    settings = Settings()
    dynamics = dataclasses.replace(settings.dynamics, max_substeps=0)
    mat = material()
    body = _floor(4.5e-3, x=0.56)  # under the outer half
    sim = Simulation(helices, helices.omega.copy(), mat, body, settings.contacts, dynamics)
    h, push = dynamics.time_step, dynamics.push_speed
    # the floor is under x >= 0.06 m, so under arcs of at least that: its slowest push
    slowest = min(push, simulate._PUSH_TURN * dynamics.max_turn * 0.06 / h)
    assert 4.5e-3 > settings.contacts.body_distance
    gaps = []
    for _ in range(80):
        sim.step(Motion.still(5.0 * mat.gravity))
        body_gaps = sim.contacts.gap[sim.contacts.strand[:, 1] < 0]
        gaps.append(float(body_gaps.min()) if len(body_gaps) else np.inf)
    deepest = int(np.argmin(gaps))
    assert gaps[deepest] < -1e-3, "the hair never went in: the scene does not test what it claims"
    # out at the pushes' speed: within depth / (slowest h) steps, and a few more
    out = deepest + int(np.ceil(-gaps[deepest] / (slowest * h))) + 5
    assert out < len(gaps)
    assert max(gaps[deepest:out + 1]) > -1e-5  # (a later detection may find a point sagging below, see below)
    # and it stays out, up to what a later detection may find between the points the contacts sit on
    # (they keep their material points until detection runs again, which it does once a point may have
    # moved by a quarter of the detection distance, here the hair-hair one): a point sagging below the
    # floor there is found at most about that deep, and pushed out in turn
    reach = 0.25 * min(settings.contacts.hair_distance, settings.contacts.body_distance)
    assert min(gaps[out:]) > -reach
    # never much faster than push_speed: the deepest contact may carry no force and be lifted a little
    # faster by the pushes of the others (the step's frictional problem has several solutions, and
    # that is one of them: 1.22 push_speed here), but an unbounded push (room / h) would lift it at
    # 14 times push_speed
    assert np.diff(gaps[deepest:out]).max() <= 1.5 * push * h


@pytest.mark.parametrize("depth, g", [(4.2e-3, 5.0), (4.5e-3, 4.0), (4.5e-3, 5.0), (5.5e-3, 6.0)])
def test_a_strand_dropped_onto_a_floor_comes_to_rest_on_it(depth, g):
    """Dropped from a few mm above a floor at several times gravity, in full steps, a strand lands, is
    pushed out, and lies still: it sleeps (its kinetic energy exactly zero) within 150 steps. An element
    lying along the floor rests on two of its points (``tracking.ContactTracker.persist``): with one contact
    point per element, each moved to the point detection found deepest, these drops rocked for ever between
    two sets of points, each finding the other's 16-37 um inside. No point
    of the strand lies deeper in the floor than a later detection may find between the points the
    contacts sit on (a quarter of the detection distance, as in the test above)."""
    helices = _strand(n=6, total=0.12)
    settings = Settings()
    dynamics = dataclasses.replace(settings.dynamics, max_substeps=0)
    mat = material()
    sim = Simulation(helices, helices.omega.copy(), mat, _floor(depth, x=0.56), settings.contacts, dynamics)
    deepest = 0.0
    for _ in range(150):
        sim.step(Motion.still(g * mat.gravity))
        deepest = min(deepest, float(sim.contacts.gap.min(initial=0.0)))
    assert deepest < -1e-3, "the hair never went in: the scene does not test what it claims"
    assert sim.kinetic_energy() == 0.0
    s = np.linspace(0.0, helices.length.sum(), 2001)
    x = np.empty((len(s), 3))
    points_at(helices.root[0], helices.frame0[0], sim.q, helices.length, s, x)
    over = x[:, 0] >= 0.06  # the floor's top face is at y = -depth, under x >= 0.06 m
    reach = 0.25 * min(settings.contacts.hair_distance, settings.contacts.body_distance)
    assert (x[over, 1] + depth).min() > -reach
    assert sim.contacts.n_contacts > 0 and np.all(sim.contacts.strand[:, 1] < 0)


def _block(x0, x1, top):
    """A narrow box (2 mm across z) under the strand's plane between x0 and x1 (m), its top face at height
    ``top`` (m)."""
    import trimesh

    from hairinv.contacts.body import BodyMesh

    box = trimesh.creation.box(extents=(x1 - x0, 0.2, 2e-3))
    box.apply_translation((0.5 * (x0 + x1), top - 0.1, 0.0))
    return BodyMesh.from_mesh(box)


def test_a_push_near_a_root_is_slowed_so_that_no_element_turns_past_max_turn(monkeypatch):
    """A strand found 0.5 mm inside a block under the second half of its root element: pushed out at
    ``push_speed`` (50 mm/s, 0.5 mm in the step), the root element bends about ``2 d l / s^2`` = 0.15 rad
    in one step, three times ``max_turn`` (0.05 here), and would bend as far in a halved step (the push is the
    gap over the step taken). The push is kept to ``_PUSH_TURN max_turn s`` per step (2.9 mm/s at s = 11.4 mm):
    the contact's normal velocity after the step is that, measured with its own rows, and no element
    turns past ``max_turn``."""
    from hairinv.contacts.rows import contact_rows
    from hairinv.dynamics import simulate
    from hairinv.model import Helices

    helices = _strand(n=6, total=0.12)
    l0 = helices.length[0]
    inside = 0.5e-3
    body = _block(0.5 * l0, l0, inside)
    settings = Settings()
    dynamics = dataclasses.replace(settings.dynamics, max_substeps=0, max_turn=0.05)
    contacts = dataclasses.replace(settings.contacts, hair_hair=False)
    aside = helices.omega.copy()
    aside[0, 0] = 150.0  # the root element bent sideways, clear of the block, for the first step
    x = np.empty((1, 3))
    points_at(helices.root[0], helices.frame0[0], aside, helices.length, np.array([0.5 * l0]), x)
    assert abs(x[0, 2]) > 1e-3 + settings.contacts.body_distance

    def pushed(turn_share: float):
        monkeypatch.setattr(simulate, "_PUSH_TURN", turn_share)
        sim = Simulation(helices, helices.omega.copy(), material(), body, contacts, dynamics)
        sim.q = aside.copy()
        sim.step(Motion.still(np.zeros(3)))
        assert sim.contacts.n_contacts == 0
        sim.q, sim.v = helices.omega.copy(), np.zeros_like(sim.v)  # straight: 0.5 mm inside the block
        report = sim.step(Motion.still(np.zeros(3)))
        c = sim.contacts
        deepest = int(np.argmin(c.gap))
        assert c.gap[deepest] == pytest.approx(-inside, rel=1e-6)  # found inside, as the scene intends
        shape = Helices(helices.root, helices.frame0, helices.offsets, helices.length, helices.omega.copy(),
                        helices.fit_error)
        u = contact_rows(shape, c).matvec(sim.v.ravel())[deepest, 0]
        return report.turn, u, c.s[deepest, 0]

    share = simulate._PUSH_TURN
    turn, u, s = pushed(share)
    unslowed, u_unslowed, _ = pushed(np.inf)
    assert inside / dynamics.time_step >= dynamics.push_speed  # without the limit, pushed at push_speed
    assert u_unslowed == pytest.approx(dynamics.push_speed, rel=1e-3)
    assert unslowed > 2.0 * dynamics.max_turn
    assert u == pytest.approx(share * dynamics.max_turn * s / dynamics.time_step, rel=1e-3)
    assert turn <= dynamics.max_turn


def test_a_push_that_halving_does_not_shrink_is_kept_after_one_halving(monkeypatch):
    """A strand found inside a floor is pushed out by its depth within the step, whatever its length:
    half the step turns the strand as far as the whole one, so halving does not help. The halved
    attempt is kept (and counted); without that rule the step is halved to ``max_substeps``."""
    import copy

    from hairinv.dynamics import simulate

    monkeypatch.setattr(simulate, "_PUSH_TURN", np.inf)  # a push at push_speed even near the root
    helices = _strand(n=6, total=0.12)
    settings = Settings()
    dynamics = dataclasses.replace(settings.dynamics, max_substeps=0, push_speed=10.0)
    sim = Simulation(helices, helices.omega.copy(), material(), _floor(4.5e-3, x=0.56), settings.contacts, dynamics)
    for _ in range(40):  # fall in full steps until contacts are found inside the floor
        sim.step(Motion.still(5.0 * sim.material.gravity))
        if sim.contacts.n_contacts and sim.contacts.gap.min() < -1e-3:
            break
    assert sim.contacts.n_contacts and sim.contacts.gap.min() < -1e-3, "the hair never went in"
    sim.v[:] = 0.0  # from rest, without gravity: only the push turns the strand
    still = Motion.still(np.zeros(3))
    full = copy.deepcopy(sim).step(still)
    assert full.depth == 0 and full.turn > 0.05
    deep = dataclasses.replace(dynamics, max_substeps=6, max_turn=0.6 * full.turn)
    kept = copy.deepcopy(sim)
    kept.settings = deep
    report = kept.step(still)
    # the first half turned further than the whole step (0.23 rad against 0.15): kept; the second half
    # had less left to push and took its halving
    assert report.kept_turning >= 1 and report.turn > full.turn
    assert report.depth <= 2 and report.rejected <= 2
    monkeypatch.setattr(simulate, "_HALVING_GAIN", np.inf)  # halve whenever an element turns too far
    halving = copy.deepcopy(sim)
    halving.settings = deep
    old = halving.step(still)
    # halving made the push's turns larger (0.23, 0.31, 0.40 rad ...), down to the last halving, in more than
    # ten times the substeps (the halvings the turns ask for are taken at once, so fewer attempts are thrown
    # away on the way down than one level at a time: 8 against 2 here)
    assert old.depth == 6 and old.kept_turning == 0 and old.substeps > 10 * report.substeps
    assert old.rejected > 3 * report.rejected


def test_contact_gaps_are_this_shapes_even_when_the_last_detection_is_reused():
    """Without hair-hair contact a detection is reused until a point may have moved by a quarter of
    the body distance; the gaps the step uses must still be those of the shape at its start (the
    exact signed distance at each contact point), never the older shape's the detection was made on."""
    from hairinv.dynamics.simulate import points_on

    helices = _strand(n=6, total=0.12)
    settings = Settings()
    contacts = dataclasses.replace(settings.contacts, hair_hair=False)
    dynamics = dataclasses.replace(settings.dynamics, max_substeps=0)
    body = _floor(10e-3, x=0.56)  # 10 mm below the straight strand
    # a curled shape whose lowest point is 0.3 mm inside the floor
    s = np.linspace(0.0, 0.12, 400)

    def lowest(c):
        q = helices.omega.copy()
        q[:, 1] = c
        x = np.empty((len(s), 3))
        points_at(helices.root[0], helices.frame0[0], q, helices.length, s, x)
        return q, x[:, 1].min()

    sign = 1.0 if lowest(1.0)[1] < 0 else -1.0
    lo, hi = 0.0, 5.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if lowest(sign * mid)[1] < -10.3e-3 else (mid, hi)
    curled = lowest(sign * hi)[0]
    sim = Simulation(helices, curled.copy(), material(), body, contacts, dynamics)
    sim.step(Motion.still(np.zeros(3)))  # the first step, straight and 10 mm above the floor
    sim.q, sim.v = curled.copy(), np.zeros_like(sim.v)
    reused = 0
    for _ in range(10):
        start, before = sim.q.copy(), sim._last_found
        sim.step(Motion.still(material().gravity))
        reused += sim._last_found is before
        c = sim.contacts
        on_body = c.strand[:, 1] < 0
        x = points_on(helices, start, c.strand[on_body, 0], c.s[on_body, 0])
        exact = body.closest(x)[0]
        assert np.abs(c.gap[on_body] - exact).max(initial=0.0) < 1e-8
    assert reused, "no detection was reused: the test does not test what it claims"


def test_strands_that_have_hardly_moved_keep_their_detection():
    """Without hair-hair contact only the strands that may have moved by a quarter of the body
    distance since their own last detection are detected again. Whatever was kept: every element a
    fresh detection of the step's starting shape finds closer than the body distance less twice that
    quarter has a contact in the step, and every gap is the exact signed distance of that shape."""
    from hairinv.contacts import detect_contacts
    from hairinv.dynamics.simulate import points_on

    # strands 0 and 2 lie 1.5 mm above a floor under their outer halves and settle on it; 1 and 3
    # start 7.5 mm above it and fall onto it, finding new contacts
    helices = strands([horizontal_strand(n=6, total=0.12, root=(0.0, y, z))
                       for y, z in ((0.0, 0.0), (6e-3, 0.04), (0.0, 0.08), (6e-3, 0.12))])
    settings = Settings()
    contacts = dataclasses.replace(settings.contacts, hair_hair=False)
    body = _floor(1.5e-3, x=0.56)
    dynamics = dataclasses.replace(settings.dynamics, max_substeps=0)  # a step's contacts are its start's
    sim = Simulation(helices, helices.omega.copy(), material(), body, contacts, dynamics)
    margin = contacts.body_distance - 2 * 0.25 * contacts.body_distance
    partial = 0
    sim.step(Motion.still(material().gravity))  # the first step meets its contacts as detected
    for _ in range(30):
        start = sim.q.copy()
        sim.step(Motion.still(material().gravity))
        partial += 0 < sim._redetected < helices.n_strands
        c = sim.contacts
        on_body = c.strand[:, 1] < 0
        x = points_on(helices, start, c.strand[on_body, 0], c.s[on_body, 0])
        assert np.abs(c.gap[on_body] - body.closest(x)[0]).max(initial=0.0) < 1e-8
        shape = dataclasses.replace(helices, omega=start)
        fresh, _ = detect_contacts(shape, body, contacts)
        near = fresh.element[fresh.gap < margin, 0]
        assert np.isin(near, sim._elements_of(c)[on_body, 0]).all()
    assert partial >= 5, "the strands were never detected apart: the test does not test what it claims"


def _key_rows(c, elements):
    """Each contact as a row (elements, strands, arc lengths, gap), sorted: two detections compared as sets."""
    rows = np.column_stack([elements, c.strand, c.s, c.gap])
    return rows[np.lexsort(rows.T[::-1])]


@pytest.mark.parametrize("cap", [0, 1])
def test_strands_that_have_hardly_moved_keep_their_hair_pairs(cap):
    """With hair-hair contact, once a few strands have moved by a quarter of the hair distance since their
    last detection, only they are detected again: their body contacts and every hair pair with one of them,
    searched against the whole groom; the pairs of two other strands are the last detection's. Without the
    per-element cap every pair is detected on its own, and the strands that did not move are bitwise where
    they were, so the detection is a fresh detection of the new shape, contact for contact. With the cap,
    no element holds more than it, and every pair with a moved strand is one a fresh detection finds, at the
    same distance."""
    from hairinv.contacts import detect_contacts

    # eight strands 0.3 mm apart across a row, each tilted a little, the odd ones the other way: pairs all
    # along them, each element with several neighbours within the hair distance (1 mm)
    helices = strands([(np.array([0.0, 0.0, 3e-4 * k]), (1.0, 0.0, 0.001 * (-1) ** k), np.zeros((6, 3)),
                        np.full(6, 0.02)) for k in range(8)])
    contacts = dataclasses.replace(Settings().contacts, hair_hair=True, layer=False, wisp=False,
                                   max_hair_per_element=cap)
    sim = Simulation(helices, helices.omega.copy(), material(), None, contacts, Settings().dynamics)
    tracker = sim.tracker
    first = tracker.detect(sim.state)
    assert tracker.redetected == helices.n_strands and first.n_hair > 10
    moved = np.array([2, 6])
    q = sim.q.copy()
    for k in moved:  # bent sideways, their tips by about 0.4 mm: with the cap, closer to some elements of the
        # next strands than the pairs those held (which the cap then drops)
        q[helices.offsets[k]:helices.offsets[k + 1], 1] = 0.05
    sim.q = q
    found = tracker.detect(sim.state)
    assert tracker.redetected == len(moved)
    fresh, _ = detect_contacts(dataclasses.replace(helices, omega=q), None,
                               dataclasses.replace(contacts, max_hair_per_element=0))
    touch = np.isin(found.strand, moved).any(axis=1)
    assert touch.any() and (~touch).any()
    np.testing.assert_array_equal(tracker.stale, ~touch)
    elements = tracker.elements_of(found)
    if cap == 0:
        np.testing.assert_array_equal(_key_rows(found, elements), _key_rows(fresh, tracker.elements_of(fresh)))
    else:
        held = np.bincount(elements.ravel(), minlength=helices.n_elements)
        assert held.max() <= cap
        fresh_rows = {tuple(r) for r in _key_rows(fresh, tracker.elements_of(fresh))}
        assert all(tuple(r) in fresh_rows for r in _key_rows(found.subset(touch), elements[touch]))
        unmoved = _key_rows(found.subset(~touch), elements[~touch])
        kept = ~np.isin(first.strand, moved).any(axis=1)
        assert all(tuple(r) in {tuple(x) for x in _key_rows(first.subset(kept), tracker.elements_of(first)[kept])}
                   for r in unmoved)

def test_first_order_body_gaps_are_exact_on_a_flat_floor(monkeypatch):
    """On a flat face the signed distance is affine, so the first-order gap ``gap + n . dx`` of a
    contact that has hardly moved must equal the exact distance to round-off (a missing, or flipped,
    ``n . dx`` would be off by the whole normal motion, which is made large enough here to tell)."""
    from hairinv.contacts.body import BodyMesh
    from hairinv.dynamics.simulate import points_on

    helices, body, mat, sim = _inverted_on_a_floor()
    sim.step(Motion.still(mat.gravity))  # every gap measured exactly here
    c = sim.contacts
    on_body = c.strand[:, 1] < 0
    before = points_on(helices, sim.q, c.strand[on_body, 0], c.s[on_body, 0])
    # bend the strand so its contact points move by up to 1e-10 m, under the 2.5e-10 m the first-order
    # gap is allowed for (tolerance g h^2 / 4)
    bend = np.zeros_like(sim.q)
    bend[:, 1] = 1.0
    moved = points_on(helices, sim.q + 1e-6 * bend, c.strand[on_body, 0], c.s[on_body, 0]) - before
    shifted = sim.q + 1e-6 * bend * (1e-10 / np.abs(moved).max())
    after = points_on(helices, shifted, c.strand[on_body, 0], c.s[on_body, 0])
    normal_motion = np.abs(np.einsum("ij,ij->i", after - before, c.frame[on_body, 0])).max()
    assert normal_motion > 1e-11, "the contacts hardly move along the normal: the test would not tell"
    queried = []
    closest = BodyMesh.closest
    monkeypatch.setattr(BodyMesh, "closest", lambda self, points: queried.append(len(points)) or closest(self, points))
    sim.q = shifted
    sim.step(Motion.still(mat.gravity))
    monkeypatch.setattr(BodyMesh, "closest", closest)
    assert not queried  # the first-order path was taken
    c = sim.contacts
    on_body = c.strand[:, 1] < 0
    exact = body.closest(points_on(helices, shifted, c.strand[on_body, 0], c.s[on_body, 0]))[0]
    assert np.abs(c.gap[on_body] - exact).max() < 1e-3 * normal_motion


def test_a_step_that_turns_k_times_too_far_takes_its_halvings_at_once(monkeypatch):
    """An attempt that turns ``k`` times ``max_turn`` is replaced by ``2^ceil(log2 k)`` substeps straight
    away, not by halves thrown away in turn: the substeps cover the step, and each turns within
    ``max_turn`` where the motion turns about half as far, or less, in half the time (a horizontal strand
    falling from rest under five times gravity, no contact)."""
    import copy

    helices = strands([horizontal_strand(n=4, total=0.08)])
    fall = Motion.still(5.0 * material().gravity)
    probe = _sim(helices, helices.omega.copy(), 0.01, max_turn=10.0)
    whole = copy.deepcopy(probe).step(fall)  # the whole step's turn, nothing halved
    assert whole.depth == 0 and whole.rejected == 0 and whole.turn > 0.0
    for ratio, levels in ((1.5, 1), (3.0, 2), (6.5, 3)):
        sim = _sim(helices, helices.omega.copy(), 0.01, max_turn=whole.turn / ratio)
        lengths = []
        real_step = sim._step
        monkeypatch.setattr(sim, "_step", lambda motion, h, depth, *rest, real=real_step, out=lengths:
                            out.append(h) or real(motion, h, depth, *rest))
        report = sim.step(fall)
        # straight to the depth the turn asks for: no attempt of a length in between
        assert lengths[0] == 0.01 and lengths[1] == 0.01 / 2 ** levels and max(lengths[1:]) == lengths[1]
        assert report.depth >= levels and report.turn <= whole.turn / ratio
        if ratio < 4.0:  # and there, none of the substeps thrown away: they cover the step
            assert lengths[1:] == [0.01 / 2 ** levels] * 2 ** levels
            assert report.rejected == 1 and report.depth == levels


def test_a_halved_step_names_the_strand_that_turned_too_far():
    """Two strands without contact, one at rest and one released far from its rest shape: the
    springing one turns an element past ``max_turn`` in a full step, so the step is halved and the
    report (and the frame log) names it; with room enough, nothing is halved and no strand named."""
    from hairinv.dynamics.run import FrameLog

    helices = strands([horizontal_strand(n=4, total=0.08), horizontal_strand(n=4, total=0.08)])
    rest = helices.omega.copy()
    rest[helices.offsets[1]:helices.offsets[2], 0] += 80.0  # 1/m: strand 1 springs into a curl
    still = Motion.still(np.zeros(3))  # no gravity: strand 0 stays at rest
    sim = _sim(helices, rest, 0.01, max_turn=0.05)
    report = sim.step(still)
    assert report.rejected > 0 and report.turned == 1
    assert np.allclose(sim.q[:helices.offsets[1]], helices.omega[:helices.offsets[1]])
    # the next step starts halved for strand 1's sake: it names strand 1 even if it throws nothing away
    assert sim.start_depth > 0
    report = sim.step(still)
    assert report.turned == 1
    calm = _sim(helices, rest, 0.01, max_turn=10.0)
    report = calm.step(still)
    assert report.rejected == 0 and report.turned == -1
    log = FrameLog(1, 0.04, 0, 0, 0, 0.0, 0, 0.0, 0.0, 0.0, 0.1, halved=3, halved_by=777)
    assert "halved   3 by   777" in log.line()
    assert "halved   0 by     -" in dataclasses.replace(log, halved=0, halved_by=-1).line()


def test_a_contact_problem_with_non_finite_data_is_a_numerical_error_at_once():
    """A NaN in the contact data (here one contact's free velocity) is reported as NUMERICAL_ERROR
    before any sweep, with the warm start returned untouched, never as a converged answer."""
    result, _ = _solve([1.0, 2.0], [[-1.0, 0.0, 0.0], [np.nan, 0.0, 0.0]], [0.5, 0.5])
    assert result.status == "NUMERICAL_ERROR" and result.sweeps == 0
    assert np.array_equal(result.r, np.zeros((2, 3)))
    # the same problem without the NaN is solved: the first contact sticks with r_N = 1 / w
    fine, _ = _solve([1.0, 2.0], [[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]], [0.5, 0.5])
    assert fine.status == "CONVERGED" and fine.r[0, 0] == pytest.approx(1.0) and np.all(fine.r[1] == 0.0)


def test_a_shorter_step_starts_from_the_same_forces():
    """A still groom at its equilibrium holds the same contact forces whatever the step: after steps of
    10 ms, a step of 5 ms (as a halved step is) and one of 2.5 ms start from the forces times their own
    length, which already meet the tolerance: no sweep runs, and the strand stays put. (The impulses of
    the longer step, twice the forces' over a half step, would push the strand up and need the sweeps.)"""
    helices, _, mat, sim = _inverted_on_a_floor()
    still = Motion.still(mat.gravity)
    start = _tip(helices, helices.omega)
    for _ in range(3):
        sim.step(still)
    for h in (0.005, 0.0025, 0.01):
        report = sim.step(still, h)
        assert report.status == "CONVERGED" and report.sweeps == 0, (h, report)
    assert np.linalg.norm(_tip(helices, sim.q) - start) < 1e-9

