"""The inverse problem: equilibrium, optimality conditions, a conic solver, extremes.

Scenes are built by hand (strands with known shapes, contacts at known
places: tests/conftest.py), so every check is independent of contact detection:

- equilibrium: the gradient of the total energy
  ``1/2 (q - q0)^T K (q - q0) + V_g(q) - sum_i (C_i^T r_i) . x(s_i; q)``
  (elastic + gravitational potential + the contact forces as fixed external
  forces at their material points) vanishes at ``q``. It is taken by central
  finite differences of the potential and of centerline positions, not from
  the kernels that built the problem;
- optimality: ``r`` in the Coulomb cones, ``W r + b`` in the dual cones,
  complementarity (hairinv.testing), with ``W`` assembled densely;
- the same SOCQP solved by Clarabel (interior point) gives the same forces.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from conftest import (FINITE_DIFFERENCE, TIGHT, UP, check_optimality, dense_problem, energy_gradient, horizontal_strand,
                      make_contacts, material, resting_scene, solve, strands, three_strands_on_the_body,
                      two_strand_scene)
from hairinv.config import SolverSettings
from hairinv.contacts.rows import contact_rows
from hairinv.errors import InputError
from hairinv.gravity import generalized_gravity
from hairinv.inverse.problem import target_shape
from hairinv.invert import invert
from hairinv.model import Contacts, Material, stiffness
from hairinv.testing import delassus_scaling, in_cone, natural_residual, project_cone


def primal_dual(helices, contacts, mat, model, r, y=None):
    """The inverse problem's objective ``P(r) = 1/2 |q0(r) - t|^2 + 1/2 sum_c gamma_c |r_c|^2`` (the rest shape
    from the equilibrium, ``q0 = q - (F_g + H^T r) / K``) and its Lagrange dual
    ``G(y) = -1/2 |y|^2 + y . (t - q + F_g / K) - sum_c |P_K(-(H y / K)_c)|^2 / (2 gamma_c)``, derived here
    from ``P`` with a multiplier ``y`` of the equilibrium (scaled by ``K``): ``G(y) <= P(r)`` for every ``y`` and
    forces ``r`` in the cones. ``y`` defaults to ``t - q0(r)``, the rest shape's own deviation. Targets weighted
    1 (the default). Returns ``(P(r), G(y))``."""
    _, _, H, _ = dense_problem(helices, contacts, mat, model)
    K = stiffness(helices, mat)
    F_g = generalized_gravity(helices, mat).ravel()
    q, t = helices.omega.ravel(), model.omega_target.ravel()
    gamma = np.broadcast_to(model.gamma if model.contact_gamma is None else model.contact_gamma, len(r))
    q0 = rest_of(helices, mat, H, r).ravel()
    P = 0.5 * np.sum((q0 - t) ** 2) + 0.5 * np.sum(gamma * np.sum(r ** 2, axis=1))
    y = t - q0 if y is None else y
    v = (H @ (y / K)).reshape(-1, 3)
    G = -0.5 * y @ y + y @ (t - q + F_g / K) \
        - np.sum(np.sum(project_cone(-v, contacts.mu) ** 2, axis=1) / (2.0 * gamma))
    return P, G


@pytest.mark.parametrize("scene", [resting_scene, two_strand_scene])
def test_equilibrium_from_an_independent_energy(scene):
    helices, contacts = scene()
    mat = material()
    model, report = solve(helices, contacts, mat)
    assert report.result.status == "CONVERGED"
    assert report.carrying > 0  # the scene is built so that contacts carry weight
    grad, scale = energy_gradient(helices, contacts, model, mat)
    assert np.abs(grad).max() <= FINITE_DIFFERENCE * scale


@pytest.mark.parametrize("scene", [resting_scene, two_strand_scene])
@pytest.mark.parametrize("mu", [0.0, 0.3, 1e6])
def test_optimality_conditions(scene, mu):
    helices, contacts = scene(mu=mu)
    mat = material()
    model, report = solve(helices, contacts, mat)
    assert report.result.status == "CONVERGED"
    W, b, _, _ = dense_problem(helices, contacts, mat, model)
    check_optimality(W, b, model.force, contacts.mu, rtol=1e-7)
    if mu == 0.0:
        assert np.all(model.force[:, 1:] == 0.0)


@pytest.mark.parametrize("scene", [resting_scene, two_strand_scene])
@pytest.mark.parametrize("reserve", [0.1, 0.5])
def test_friction_reserve(scene, reserve):
    """solver.friction_reserve: the forces are the optimum over the cones of mu (1 - reserve), checked by the
    optimality conditions there and against Clarabel on those cones, so every loaded contact keeps that
    margin inside its declared cone; and the model is still an exact equilibrium of the input shape."""
    pytest.importorskip("clarabel")
    import scipy.sparse

    from hairinv.solver.reference import solve_socqp_clarabel

    helices, contacts = scene(mu=0.3)
    mat = material()
    # gamma of the order of W's diagonal: the forces are unique and well conditioned (test_matches_clarabel)
    probe, _ = solve(helices, contacts, mat, max_sweeps=1)
    gamma = float(np.mean(np.diag(dense_problem(helices, contacts, mat, probe)[0])))
    model, report = solve(helices, contacts, mat, gamma=gamma, friction_reserve=reserve)
    assert report.result.status == "CONVERGED"
    W, b, H, d = dense_problem(helices, contacts, mat, model)
    reduced = contacts.mu * (1.0 - reserve)
    check_optimality(W, b, model.force, reduced, 1e-6)
    r_ref, _ = solve_socqp_clarabel(scipy.sparse.csr_matrix(H), d, gamma, b, reduced, tol=1e-13)
    np.testing.assert_allclose(model.force, r_ref, rtol=0, atol=1e-6 * np.abs(r_ref).max())
    r = model.force
    assert np.all(in_cone(r, reduced, atol=0.0, rtol=1e-12))  # exactly: the forces are projected onto them
    # the answer changes exactly where the declared problem's optimum uses more friction than the reserve leaves
    declared, _ = solve(helices, contacts, mat, gamma=gamma)
    rd = declared.force
    beyond = ~in_cone(rd, reduced, atol=0.0, rtol=1e-6)
    changed = np.abs(declared.force - r).max() > 1e-6 * np.abs(r).max()
    assert changed == bool(np.any(beyond))
    grad, scale = energy_gradient(helices, contacts, model, mat)
    assert np.abs(grad).max() <= FINITE_DIFFERENCE * scale


def test_friction_reserve_is_checked():
    helices, contacts = resting_scene()
    for bad in (-0.1, 1.0, np.nan):
        with pytest.raises(InputError, match="friction_reserve"):
            invert(helices, contacts, material(), SolverSettings(friction_reserve=bad))
    for bad in (-1e-4, 1.0, np.nan):
        with pytest.raises(InputError, match="gamma_relative"):
            invert(helices, contacts, material(), SolverSettings(gamma_relative=bad))


@pytest.mark.parametrize("scene", [resting_scene, two_strand_scene])
@pytest.mark.parametrize("relative", [1e-4, 1e-2])
def test_gamma_relative(scene, relative):
    """solver.gamma_relative: each contact weighs max(gamma, relative * the mean of its diagonal of H D H^T),
    read here from the dense matrix; the sweeps' forces satisfy the optimality conditions of that problem,
    and their objective and rest shape match Clarabel's given those weights; the interior point's rest shape lies within its own bound of
    Clarabel's; the added weights' term is no larger than at the paper's optimum; and the model is an exact
    equilibrium of the input shape."""
    pytest.importorskip("clarabel")
    import scipy.sparse

    from hairinv.solver.reference import solve_socqp_clarabel

    helices, contacts = scene(mu=0.3)
    mat = material()
    model, report = solve(helices, contacts, mat, gamma_relative=relative)
    assert report.result.status == "CONVERGED" and model.gamma_relative == relative
    W, b, H, d = dense_problem(helices, contacts, mat, model)
    plain = H @ (d[:, None] * H.T)
    expected = np.maximum(1e-3, relative * np.diag(plain).reshape(-1, 3).mean(axis=1))
    np.testing.assert_allclose(model.contact_gamma, expected, rtol=1e-12)
    check_optimality(W, b, model.force, contacts.mu, 1e-6)
    r_ref, _ = solve_socqp_clarabel(scipy.sparse.csr_matrix(H), d, expected, b, contacts.mu, tol=1e-13)
    objective = lambda r: 0.5 * r.ravel() @ W @ r.ravel() + b @ r.ravel()  # noqa: E731
    assert objective(model.force) <= objective(r_ref) + 1e-9 * abs(objective(r_ref))
    K = stiffness(helices, mat)
    F_g = generalized_gravity(helices, mat).ravel()
    rest_ref = helices.omega.ravel() - (F_g + H.T @ r_ref.ravel()) / K
    scale_q = np.abs(F_g / K).max()
    assert np.abs(model.omega_rest.ravel() - rest_ref).max() <= 1e-6 * scale_q
    grad, scale = energy_gradient(helices, contacts, model, mat)
    assert np.abs(grad).max() <= FINITE_DIFFERENCE * scale
    # against the paper's problem: adding the two optimality inequalities, the weight added to each contact
    # (gamma_c - gamma) can only lower sum_c (gamma_c - gamma) |r_c|^2
    paper, _ = solve(helices, contacts, mat)
    added = expected - 1e-3
    assert np.sum(added * np.sum(model.force ** 2, axis=1)) \
        <= np.sum(added * np.sum(paper.force ** 2, axis=1)) * (1 + 1e-6)
    # the interior point on the same problem, within its bound of Clarabel's rest shape
    steps, rep = solve(helices, contacts, mat, gamma_relative=relative, method="interior-point",
                       rest_tolerance=1e-6 * scale_q)
    distance = np.sqrt(np.mean(np.sum((steps.omega_rest.ravel() - rest_ref).reshape(-1, 3) ** 2, axis=1)))
    assert rep.result.method == "interior-point" and distance <= rep.result.rest_bound + 1e-9 * scale_q


@pytest.mark.parametrize("scene", [resting_scene, two_strand_scene])
@pytest.mark.parametrize("mu", [0.0, 0.3, 2.0])
def test_matches_clarabel(scene, mu):
    """At the paper's gamma, W = H K^-2 H^T + gamma I has a condition number
    near 1e16: forces along directions the strands cannot feel (an axial pull
    on a straight strand) are fixed only by gamma, below any interior-point
    tolerance. What the objective does fix is the rest shape, so compare q0
    there; with gamma of the order of W's diagonal the forces are unique and
    well conditioned, so compare the forces themselves."""
    pytest.importorskip("clarabel")
    import scipy.sparse

    from hairinv.solver.reference import solve_socqp_clarabel

    helices, contacts = scene(mu=mu)
    mat = material()
    K = stiffness(helices, mat)
    F_g = generalized_gravity(helices, mat).ravel()
    for gamma in (1e-3, None):
        if gamma is None:
            probe, _ = solve(helices, contacts, mat, max_sweeps=1)
            W, *_ = dense_problem(helices, contacts, mat, probe)
            gamma = float(np.mean(np.diag(W)))
        model, report = solve(helices, contacts, mat, gamma=gamma)
        assert report.result.status == "CONVERGED"
        _, b, H, d = dense_problem(helices, contacts, mat, model)
        r_ref, info = solve_socqp_clarabel(scipy.sparse.csr_matrix(H), d, gamma, b, contacts.mu, tol=1e-13)
        q0_ref = helices.omega.ravel() - (F_g + H.T @ r_ref.ravel()) / K
        sag = np.abs(F_g / K).max()
        W = H @ (d[:, None] * H.T) + gamma * np.eye(len(H))
        objective = lambda r: 0.5 * r.ravel() @ W @ r.ravel() + b @ r.ravel()  # noqa: E731
        # never worse than the interior point, whatever its accuracy
        assert objective(model.force) <= objective(r_ref) + 1e-12 * abs(objective(r_ref))
        if info["status"] == "Solved":  # Clarabel may stop at AlmostSolved at condition 1e16
            assert np.abs(model.omega_rest.ravel() - q0_ref).max() <= 1e-6 * sag
        if gamma > 1.0:
            assert np.abs(model.force - r_ref).max() <= 1e-6 * np.abs(r_ref).max()


@pytest.mark.parametrize("mu", [0.0, 0.3, 2.0])
def test_body_contacts_only_are_solved_strand_by_strand_at_once(mu, monkeypatch):
    """Without hair-hair contacts each strand's contacts are solved together by Newton before any
    Gauss-Seidel sweep. Three strands (curled differently, three and four nearly parallel contacts
    each, upright and tilted normals): at a 1e-6 tolerance no sweep is needed; at 1e-10 the forces
    satisfy the optimality conditions on the dense W assembled here, after at most a twentieth of
    the sweeps Gauss-Seidel needs from zero forces (165 to 3,465 here)."""
    import hairinv.inverse.method as inverse

    helices, contacts = three_strands_on_the_body(mu)
    mat = material()
    _, loose = solve(helices, contacts, mat, tolerance=1e-6)
    assert loose.result.status == "CONVERGED" and loose.result.sweeps == 0
    assert any("each strand's contacts were first solved together" in line for line in loose.lines())
    model, report = solve(helices, contacts, mat)
    assert report.result.status == "CONVERGED" and report.carrying > 0
    W, b, _, _ = dense_problem(helices, contacts, mat, model)
    check_optimality(W, b, model.force, contacts.mu, rtol=1e-7)
    monkeypatch.setattr(inverse, "_strands_at_once", lambda *args: None)
    _, plain = solve(helices, contacts, mat)
    assert plain.result.status == "CONVERGED" and plain.result.sweeps >= 20 * report.result.sweeps


def test_no_contacts_is_the_gravity_only_inversion_exactly():
    helices, _ = resting_scene()
    mat = material()
    empty = Contacts.empty()
    model, report = solve(helices, empty, mat)
    baseline, _ = solve(helices, None, mat, target="gravity-only")
    K = stiffness(helices, mat)
    expected = helices.omega.ravel() - generalized_gravity(helices, mat).ravel() / K
    assert np.array_equal(model.omega_rest.ravel(), expected)
    assert np.array_equal(baseline.omega_rest, model.omega_rest)
    assert report.contacts == 0 and report.result.sweeps == 0


def test_huge_gamma_tends_to_gravity_only_and_tiny_gamma_converges():
    helices, contacts = resting_scene()
    mat = material()
    gravity_only, _ = solve(helices, None, mat, target="gravity-only")
    # W's diagonal is about 1e13 here; with gamma far above it forces vanish as O(|b| / gamma)
    stiff_model, _ = solve(helices, contacts, mat, gamma=1e24)
    assert np.abs(stiff_model.force).max() < 1e-14
    assert np.allclose(stiff_model.omega_rest, gravity_only.omega_rest, rtol=0, atol=1e-6)
    loose, report = solve(helices, contacts, mat, gamma=1e-12)
    assert report.result.status == "CONVERGED"
    W, b, _, _ = dense_problem(helices, contacts, mat, loose)
    check_optimality(W, b, loose.force, contacts.mu, rtol=1e-6)


def test_strand_entirely_resting_on_the_body_keeps_its_shape():
    """A straight strand on a floor with a support under every element: the
    floor can carry nearly all of the weight, so the rest shape stays close to
    the input where gravity-only needs a large curvature."""
    n = 8
    helices = strands([horizontal_strand(n=n, total=0.16)])
    s = (np.arange(n) + 0.99) * 0.02
    contacts = make_contacts(helices, [(0, si, -1, 0.0, UP, 0.3) for si in s])
    mat = material()
    # eight supports under eight elements: W is ill-conditioned (about 1e5) and
    # Gauss-Seidel needs thousands of sweeps per decade of residual here
    model, report = solve(helices, contacts, mat, tolerance=1e-5)
    baseline, _ = solve(helices, None, mat, target="gravity-only")
    assert report.result.status == "CONVERGED"
    W, b, _, _ = dense_problem(helices, contacts, mat, model)
    check_optimality(W, b, model.force, contacts.mu, rtol=1e-4)
    sag_gravity_only = np.abs(baseline.omega_rest - helices.omega).max()
    sag = np.abs(model.omega_rest - helices.omega).max()
    assert sag_gravity_only > 10.0  # 1/m: the unsupported rod needs real curvature
    assert sag < 2e-3 * sag_gravity_only
    # the supports carry the weight: total normal force ~ the strand's weight
    weight = mat.linear_density * 9.81 * 0.16
    assert model.force[:, 0].sum() == pytest.approx(weight, rel=0.1)
    assert report.unstable == 0


@pytest.mark.parametrize("target", ["actual", "zero", "uniform", "tip"])
def test_targets(target):
    helices = strands([horizontal_strand(n=4, curl=7.0)])
    helices.omega[:, 0] = [1.0, 2.0, 3.0, 4.0]
    t = target_shape(helices, target)
    expected = {"actual": helices.omega, "zero": np.zeros((4, 3)),
                "uniform": np.tile([2.5, 7.0, 0.0], (4, 1)), "tip": np.tile([4.0, 7.0, 0.0], (4, 1))}[target]
    assert np.allclose(t, expected)


def test_target_zero_pulls_the_rest_shape_towards_straight():
    """Curled strand resting on supports: with target zero the contacts are used
    to make q0 straighter than with target actual."""
    helices = strands([horizontal_strand(n=6, curl=-3.0)])
    contacts = make_contacts(helices, [(0, s, -1, 0.0, UP, 0.3) for s in (0.06, 0.09, 0.115)])
    mat = material()
    actual, _ = solve(helices, contacts, mat, target="actual")
    zero, _ = solve(helices, contacts, mat, target="zero")
    assert np.linalg.norm(zero.omega_rest) < np.linalg.norm(actual.omega_rest)


def test_unsupported_upright_strand_is_flagged_unstable():
    """A 30 cm strand standing straight up is far past the critical height
    (about 12 cm for a 0.1 mm hair at 4 GPa); a 3 cm one is below it."""
    tall = strands([(np.zeros(3), UP, np.zeros((6, 3)), np.full(6, 0.05))])
    short = strands([(np.zeros(3), UP, np.zeros((6, 3)), np.full(6, 0.005))])
    mat = material()
    _, tall_report = solve(tall, None, mat, target="gravity-only")
    _, short_report = solve(short, None, mat, target="gravity-only")  # (never stiffened: the baseline)
    assert tall_report.unstable == 1
    assert short_report.unstable == 0


@pytest.mark.parametrize("height, held_unstable", [(0.16, 0), (0.30, 1)])
def test_holding_the_tip_raises_the_critical_height(height, held_unstable):
    """An upright strand whose tip touches a side wall (a contact that carries no force).
    Under its own weight a clamped-free column buckles past (7.84 EI / lam g)^(1/3) (about
    12 cm here); pinned at the tip, past (52.5 EI / lam g)^(1/3), 1.88 times higher
    (Greenhill; Wang, Wang & Reddy 2005). Both strands are unstable as inverted (the wall is
    not loaded); held at every contact, the 16 cm one is stable and the 30 cm one is not."""
    mat = material()
    critical = (7.837 * mat.bending / (mat.linear_density * np.linalg.norm(mat.gravity))) ** (1 / 3)
    assert 0.16 > 1.2 * critical and 0.16 < 0.85 * 1.88 * critical < 0.30
    helices = strands([(np.zeros(3), UP, np.zeros((8, 3)), np.full(8, height / 8))])
    contacts = make_contacts(helices, [(0, height, -1, 0.0, (1.0, 0.0, 0.0), 0.3)])
    model, report = solve(helices, contacts, mat, stabilize="off")
    assert np.abs(model.force).max() == 0.0
    assert report.unstable == 1
    assert report.unstable_held == held_unstable


def test_results_do_not_depend_on_the_thread_count(monkeypatch):
    """Two halves of the strands are swept at once; the order of the updates,
    and so every bit of the answer, is the same on one thread or two."""
    specs = [horizontal_strand(n=5, total=0.1, root=(0.0, 0.0, 0.002 * k)) for k in range(8)]
    helices = strands(specs)
    down = (0.0, 1.0, -0.2)
    contacts = make_contacts(helices, [(k, 0.08, -1, 0.0, UP, 0.3) for k in range(8)]
                             + [(k, 0.06, k + 1, 0.055, down, 0.3) for k in range(7)])
    from hairinv.solver.gauss_seidel import split_strands, sweep_plan

    part_of = split_strands(helices.root, contacts.strand)
    order, halves, colours = sweep_plan(contacts.strand, helices.n_strands, contacts.s, part_of)
    assert len(halves) == 2 and sorted(order) == list(range(contacts.n_contacts))
    touched = [set(contacts.strand[order[lo:hi]].ravel()) - {-1} for lo, hi in halves]
    assert not touched[0] & touched[1]
    answers = []
    monkeypatch.setattr("hairinv.solver.gauss_seidel._MIN_HALVES", 0)  # threads even for this small scene,
    monkeypatch.setattr("hairinv.solver.gauss_seidel._MIN_PIECES", 0)  # in the sweeps and the other passes
    for threads in ("1", "2"):
        monkeypatch.setenv("HAIRINV_THREADS", threads)
        model, report = solve(helices, contacts, material(), max_sweeps=50)
        answers.append(model.force)
    assert np.array_equal(answers[0], answers[1])


def test_time_budget_stops_at_the_next_check():
    helices, contacts = two_strand_scene()  # (hair-hair contact: Gauss-Seidel sweeps from the start)
    model, report = solve(helices, contacts, material(), max_seconds=1e-9, check_every=3)
    assert report.result.status == "MAX_ITERS" and report.result.sweeps == 3
    grad, scale = energy_gradient(helices, contacts, model, material())
    assert np.abs(grad).max() <= FINITE_DIFFERENCE * scale  # still an exact equilibrium


@pytest.mark.parametrize("name", ["straight", "wavy", "curly"])
def test_samples_end_to_end(name):
    """Fit, detect and invert 20 guide strands of each sample groom on the sample bust:
    exact equilibrium (against the independent energy), forces in the cones, and a
    rest shape at least as close to the input as the gravity-only one (r = 0 is
    feasible and the solver never raises the objective)."""
    from conftest import SAMPLES
    from hairinv import config
    from hairinv.pipeline import prepare

    settings = config.apply(config.resolve(), {"import": {"guides": 20}, "solver": {"max_sweeps": 200}})
    scene = prepare(SAMPLES / f"{name}.h5", SAMPLES / "body.obj", settings)
    assert scene.contacts.n_body > 0
    mat = Material.from_settings(settings.material, scene.up)
    model, report = invert(scene.helices, scene.contacts, mat, settings.solver)
    baseline, _ = invert(scene.helices, None, mat, dataclasses.replace(settings.solver, target="gravity-only"))
    grad, scale = energy_gradient(scene.helices, scene.contacts, model, mat)
    assert np.abs(grad).max() <= FINITE_DIFFERENCE * scale
    r = model.force
    assert np.all(in_cone(r, scene.contacts.mu, atol=1e-300, rtol=1e-12))
    drift = np.sum((model.omega_rest - scene.helices.omega) ** 2)
    drift_gravity = np.sum((baseline.omega_rest - scene.helices.omega) ** 2)
    assert drift <= drift_gravity
    assert report.carrying > 0


def test_natural_residual_of_a_contact_with_zero_delassus_block_is_nan_not_an_exception():
    """A contact whose rows are zero (nothing moves it) with no regularisation has ``W_ii = 0``: its
    residual divides by zero. The kernel must report that as NaN (the solvers then stop with
    NUMERICAL_ERROR), never raise from inside a kernel."""
    from hairinv.solver.gauss_seidel import natural_residuals

    ptr = np.array([0, 1, 2], dtype=np.int64)
    cols = np.array([0, 1], dtype=np.int64)
    vals = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    f = np.array([0.0, -2.0])
    gamma = np.zeros(2)
    Wd = np.zeros((2, 3, 3))
    Wd[1] = np.diag([1.0, 0.0, 0.0])
    b = np.array([[-1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    mu = np.array([0.5, 0.5])
    r = np.zeros((2, 3))
    out = np.empty(2)
    worst = natural_residuals(ptr, cols, vals, f, gamma, Wd, b, mu, r, False, False, out)
    assert np.isnan(worst)
    assert not np.isfinite(out[0])
    # the well-posed contact's own residual is still right: u = -2 pushes in, so r_N should be
    # 2 / rho = 6 (rho = trace / 3 = 1/3), and r = 0 is off by exactly that
    assert out[1] == pytest.approx(6.0)


def test_a_start_far_from_the_optimum_reaches_the_same_optimum():
    """The problem is convex: a warm start (forces out of the cones, ten times too large) is projected onto
    the cones and converges to the optimum a cold start finds; the optimum, given as the start, takes no sweep."""
    helices, contacts = two_strand_scene(mu=0.3)
    mat = material()
    settings = SolverSettings(tolerance=TIGHT, max_sweeps=20000, method="sweeps", friction_reserve=0.0,
                              rest_tolerance=1e-300)
    cold, _ = invert(helices, contacts, mat, settings)
    wild = np.random.default_rng(0).normal(size=(contacts.n_contacts, 3)) * 10 * np.abs(cold.force).max()
    warm, report = invert(helices, contacts, mat, settings, start=wild, prior_sweeps=7)
    assert report.result.status == "CONVERGED" and warm.prior_sweeps == 7
    assert any("started from the given forces" in line for line in report.lines())
    W, b, _, _ = dense_problem(helices, contacts, mat, warm)
    # the first residual is the natural map at the projected start, recomputed here from the dense W
    start = project_cone(wild, contacts.mu)
    assert not np.allclose(start, wild)
    u = (W @ start.ravel() + b).reshape(-1, 3)
    expected = natural_residual(start, u, contacts.mu, delassus_scaling(W)).max()
    assert report.result.history[0][1] == pytest.approx(expected, rel=1e-9)
    check_optimality(W, b, warm.force, contacts.mu, rtol=1e-7)
    # the forces need not be unique to the tolerance (W is barely definite), the rest shape and objective are
    scale = np.abs(cold.omega_rest).max()
    assert np.allclose(warm.omega_rest, cold.omega_rest, rtol=0, atol=1e-7 * scale)

    def objective(r):
        return 0.5 * r.ravel() @ W @ r.ravel() + b @ r.ravel()
    assert objective(warm.force) == pytest.approx(objective(cold.force), rel=1e-9)
    again, report = invert(helices, contacts, mat, settings, start=cold.force)
    assert report.result.sweeps == 0 and np.array_equal(again.force, cold.force)
    with pytest.raises(InputError, match="one row of 3 per contact"):
        invert(helices, contacts, mat, settings, start=np.zeros((contacts.n_contacts + 1, 3)))


def test_a_model_of_another_gamma_relative_is_not_a_start():
    """Forces found with another solver.gamma_relative (or none: a file written before it) solve another
    problem: inverting such a model again starts afresh and says why; the same fraction continues."""
    from hairinv.inverse.method import warm_start

    helices, contacts = resting_scene()
    mat = material()
    old, _ = solve(helices, contacts, mat, gamma_relative=0.0)
    group = old.group({}, [])
    assert "gamma_relative" not in group.attrs and "contact_gamma" not in group.datasets
    now = SolverSettings(method="sweeps")
    forces, _, line, _ = warm_start(group, mat, now, "old.h5", helices.n_strands)
    assert forces is None and "another solver.gamma_relative: starting afresh" in line
    same, _ = solve(helices, contacts, mat, gamma_relative=now.gamma_relative, friction_reserve=now.friction_reserve)
    group = same.group({}, [])
    assert group.attrs["gamma_relative"] == now.gamma_relative and len(group.datasets["contact_gamma"]) == 3
    forces, _, line, _ = warm_start(group, mat, dataclasses.replace(now, tolerance=TIGHT), "same.h5", helices.n_strands)
    assert forces is not None and "starting afresh" not in line


@pytest.mark.parametrize("scene", [resting_scene, two_strand_scene])
@pytest.mark.parametrize("mu", [0.0, 0.3, np.inf])
def test_rest_gap(scene, mu):
    """The sweeps' bound on the rest shape's distance from the optimum (``rest_gap``): for forces in the cones
    it is ``sqrt(2 (P(r) - G(y)) / elements)`` with the dual derived here (:func:`primal_dual`); the dual is a
    lower bound of the optimum at any multiplier; the distance of any forces' rest shape from the optimum is
    within the bound; the bound vanishes at the optimum; and with a loose ``rest_tolerance`` the sweeps stop
    on it (CONVERGED while the residual is far above its tolerance), report it and write it to the model."""
    from hairinv.solver import gauss_seidel
    from hairinv.solver.problem import CONE, ConeProblem, SweepSettings

    helices, contacts = scene(mu=mu)
    mat = material()
    best, report = solve(helices, contacts, mat, gamma_relative=1e-2)
    assert report.result.status == "CONVERGED"
    E = helices.n_elements
    W, b, H, d = dense_problem(helices, contacts, mat, best)
    gammas = best.contact_gamma
    rows = contact_rows(helices, contacts)
    scale_q = np.abs(generalized_gravity(helices, mat).ravel() / stiffness(helices, mat)).max()
    P_best, G_best = primal_dual(helices, contacts, mat, best, best.force)
    assert abs(P_best - G_best) <= 1e-10 * abs(P_best)  # no gap at the optimum: the dual is the right one
    rng = np.random.default_rng(1)

    def kernel_bound(r):
        problem = ConeProblem.of(rows, d, gammas, b.reshape(-1, 3), contacts.mu, contacts.strand, helices.n_strands,
                                 1.0)
        return gauss_seidel.solve(problem, CONE, SweepSettings(TIGHT, max_sweeps=0), start=r).rest_bound

    big = np.abs(best.force).max()
    for k in range(5):
        r = project_cone(best.force + rng.normal(size=best.force.shape) * big * 10.0 ** -k, contacts.mu)
        P, G = primal_dual(helices, contacts, mat, best, r)
        bound = kernel_bound(r)
        assert bound == pytest.approx(np.sqrt(2.0 * (P - G) / E), rel=1e-7)
        distance = np.sqrt(np.mean(np.sum((rest_of(helices, mat, H, r) - best.omega_rest) ** 2, axis=1)))
        assert distance <= bound * (1 + 1e-9) + 1e-9 * scale_q
        # weak duality, the inequality the bound rests on: the dual at r's own multiplier, and near the optimal
        # one, is below the optimum
        assert G <= P_best + 1e-12 * abs(P_best)
        y_best = (best.omega_target - best.omega_rest).ravel()
        y = y_best + rng.normal(size=3 * E) * np.abs(y_best).max() * 10.0 ** -k
        assert primal_dual(helices, contacts, mat, best, r, y)[1] <= P_best + 1e-12 * abs(P_best)
    assert kernel_bound(best.force) <= 1e-6 * scale_q
    # a loose rest_tolerance stops the sweeps on the bound
    loose = 0.3 * kernel_bound(np.zeros_like(best.force))
    model, report = solve(helices, contacts, mat, gamma_relative=1e-2, rest_tolerance=loose, check_every=1)
    result = report.result
    assert result.status == "CONVERGED" and result.rest_bound <= loose
    if scene is two_strand_scene:  # (body contacts alone are solved at once by Newton before any sweep)
        assert result.relative_residual > 1e3 * TIGHT
    distance = np.sqrt(np.mean(np.sum((model.omega_rest - best.omega_rest) ** 2, axis=1)))
    assert distance <= result.rest_bound
    assert any("by the forces' duality gap" in line for line in report.lines())
    assert model.group({}, []).attrs["rest_bound"] == result.rest_bound


def rest_of(helices, mat, H, r):
    """``q0 = q - (F_g + H^T r) / K``, (E, 3)."""
    K = stiffness(helices, mat)
    return (helices.omega.ravel() - (generalized_gravity(helices, mat).ravel() + H.T @ r.ravel()) / K).reshape(-1, 3)


def test_the_order_the_contacts_are_given_in_does_not_change_the_optimum():
    """The sweeps store the contacts in their own update order and return the forces in the caller's: given the
    contacts shuffled, the forces are the same contacts' forces (the optimum is unique with a gamma per
    contact), to the solve's tolerance."""
    specs = [horizontal_strand(n=5, total=0.1, root=(0.0, 0.0, 0.002 * k)) for k in range(6)]
    helices = strands(specs)
    down = (0.0, 1.0, -0.2)
    contacts = make_contacts(helices, [(k, 0.08, -1, 0.0, UP, 0.3) for k in range(6)]
                             + [(k, 0.06, k + 1, 0.055, down, 0.3) for k in range(5)]
                             + [(k, 0.09, k + 1, 0.085, down, 0.5) for k in range(5)])
    model, report = solve(helices, contacts, material(), gamma_relative=1e-2)
    assert report.result.status == "CONVERGED" and report.carrying > 0
    perm = np.random.default_rng(4).permutation(contacts.n_contacts)
    assert not np.array_equal(perm, np.arange(contacts.n_contacts))
    shuffled, report_shuffled = solve(helices, contacts.subset(perm), material(), gamma_relative=1e-2)
    assert report_shuffled.result.status == "CONVERGED"
    np.testing.assert_allclose(shuffled.force, model.force[perm], rtol=0, atol=1e-6 * np.abs(model.force).max())
    np.testing.assert_allclose(shuffled.omega_rest, model.omega_rest, rtol=0,
                               atol=1e-6 * np.abs(model.omega_rest).max())
