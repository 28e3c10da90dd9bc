"""The interior-point method (``solver.method = "interior-point"``) on the inverse problem.

Checked against the mathematics, not against itself:

- optimality conditions of its answer on the dense problem (forces in the
  Coulomb cones, ``W r + b`` in the dual cones, complementarity);
- the rest shape against Clarabel's on the same SOCQP, and the duality-gap
  bound it reports against the distance it actually has from the optimum
  (computed here from a tight solve);
- extremes: mu 0 (solved exactly by the steps), 1e6 and inf (outside the range
  its steps take as they are: the sweeps finish), gamma tiny and huge, a single
  contact;
- the two factorisations (CHOLMOD, SuperLU) give the same steps;
- ``solver.method = auto`` takes it where its factorisation is affordable, the sweeps elsewhere.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.sparse

from conftest import (UP, check_optimality, dense_problem, horizontal_strand, make_contacts, material, resting_scene,
                      solve, strands, three_strands_on_the_body, two_strand_scene)
from hairinv.errors import InputError
from hairinv.gravity import generalized_gravity
from hairinv.invert import invert
from hairinv.config import SolverSettings
from hairinv.contacts.rows import contact_rows
from hairinv.model import stiffness
from hairinv.solver import interior as interior_method
from hairinv.solver.problem import CONE, ConeProblem, InteriorSettings


def solve_interior(rows, d, gamma, b, mu, rest_tolerance=1e-3, max_iterations=80, max_seconds=0.0, backend=None,
                   progress=None, max_gflop=None):
    """:func:`hairinv.solver.interior.solve` of the problem and settings these arguments give."""
    strand = np.zeros((rows.n_contacts, 2), dtype=np.int64)
    problem = ConeProblem.of(rows, d, gamma, b, mu, strand, 1, 1.0)
    settings = InteriorSettings(rest_tolerance, max_iterations, max_seconds, backend, max_gflop)
    return interior_method.solve(problem, CONE, settings, progress=progress)


def sag(helices, mat) -> float:
    """1/m, the largest curvature change gravity alone would cause (20 to 50 1/m in these scenes)."""
    return float(np.abs(generalized_gravity(helices, mat).ravel() / stiffness(helices, mat)).max())


def ip(helices, mat, share: float = 1e-5) -> dict:
    """Interior-point settings with the rest-shape tolerance ``share`` of the scene's sag: at the paper's
    gamma (1e-16 of W's diagonal) the steps reach 1e-9 to 1e-6 of it before round-off stops them."""
    return {"method": "interior-point", "rest_tolerance": share * sag(helices, mat), "max_iterations": 200}


def four_strands_in_a_pile():
    """Three strands on the body and a fourth lying across all three (hair-hair contacts at three places)."""
    helices, body = three_strands_on_the_body(0.3)
    specs = [horizontal_strand(curl=c, root=(0.0, 0.0, z)) for c, z in ((0.0, 0.0), (2.0, 0.05), (-4.0, 0.1))]
    specs.append((np.array([0.09, 0.004, -0.02]), (0.0, 0.0, 1.0), np.zeros((6, 3)), np.full(6, 0.025)))
    helices = strands(specs)
    tilted = UP + np.array([0.3, 0.0, 0.2])
    c = [(0, s, -1, 0.0, UP, 0.3) for s in (0.06, 0.08, 0.1)]
    c += [(1, s, -1, 0.0, tilted / np.linalg.norm(tilted), 0.3) for s in (0.05, 0.07, 0.09, 0.11)]
    c += [(2, s, -1, 0.0, UP, 0.3) for s in (0.07, 0.09, 0.115)]
    c += [(k, 0.09, 3, 0.02 + 0.05 * k, -UP, 0.3) for k in range(3)]  # strand 3 above strands 0-2
    c += [(3, 0.14, -1, 0.0, UP, 0.3)]
    return helices, make_contacts(helices, c)


SCENES = [resting_scene, two_strand_scene, four_strands_in_a_pile]


def rest_of(helices, mat, H, r):
    K = stiffness(helices, mat)
    return helices.omega.ravel() - (generalized_gravity(helices, mat).ravel() + H.T @ r.ravel()) / K


def rms(dq) -> float:
    return float(np.sqrt(np.mean(np.sum(dq.reshape(-1, 3) ** 2, axis=1))))


@pytest.mark.parametrize("scene", SCENES)
def test_meets_the_optimality_conditions(scene):
    helices, contacts = scene() if scene is four_strands_in_a_pile else scene(mu=0.3)
    mat = material()
    settings = ip(helices, mat)
    model, report = solve(helices, contacts, mat, **settings)
    r = report.result
    assert r.status == "CONVERGED" and r.method == "interior-point" and r.interior_steps > 0 and r.sweeps == 0
    assert r.rest_bound <= settings["rest_tolerance"]
    W, b, _, _ = dense_problem(helices, contacts, mat, model)
    check_optimality(W, b, model.force, contacts.mu, rtol=1e-6)


@pytest.mark.parametrize("scene", SCENES)
@pytest.mark.parametrize("mu", [0.3, 2.0])
def test_rest_shape_matches_clarabel_and_the_bound_holds(scene, mu):
    pytest.importorskip("clarabel")
    import scipy.sparse

    from hairinv.solver.reference import solve_socqp_clarabel

    helices, contacts = scene() if scene is four_strands_in_a_pile else scene(mu=mu)
    contacts.mu[:] = mu
    mat = material()
    tight, report = solve(helices, contacts, mat)  # the sweeps, to 1e-10 of a strand's weight
    _, b, H, d = dense_problem(helices, contacts, mat, tight)
    r_ref, info = solve_socqp_clarabel(scipy.sparse.csr_matrix(H), d, 1e-3, b, contacts.mu, tol=1e-13)
    q_ref = rest_of(helices, mat, H, r_ref)
    scale = sag(helices, mat)
    if info["status"] == "Solved":
        assert np.abs(tight.omega_rest.ravel() - q_ref).max() <= 1e-6 * scale
    # looser runs: the distance they report bounds the one they have from the optimum
    rows = contact_rows(helices, contacts)
    bounds = []
    for tol in (1e-1 * scale, 1e-3 * scale, 1e-5 * scale):
        res = solve_interior(rows, d, 1e-3, b.reshape(-1, 3), contacts.mu, rest_tolerance=tol)
        assert res.status == "CONVERGED" and res.rest_bound <= tol
        assert rms(rest_of(helices, mat, H, res.r) - tight.omega_rest.ravel()) <= res.rest_bound + 1e-9 * scale
        bounds.append(res.rest_bound)
    assert bounds == sorted(bounds, reverse=True)


@pytest.mark.parametrize("scene", SCENES)
@pytest.mark.parametrize("frictionless", ["all", "every other"])
def test_frictionless_contacts_are_solved_exactly_by_the_steps_alone(scene, frictionless):
    """mu = 0 (all contacts, or every other one beside mu = 0.3): the steps solve it, with no sweep to
    finish; tangential forces exactly 0; the optimality conditions of the problem as declared (cone, dual
    cone, complementarity) hold; the rest shape is within the reported bound of the sweeps' tight one."""
    helices, contacts = scene() if scene is four_strands_in_a_pile else scene(mu=0.3)
    contacts.mu[:] = 0.3
    contacts.mu[:: 1 if frictionless == "all" else 2] = 0.0
    mat = material()
    model, report = solve(helices, contacts, mat, **ip(helices, mat))
    r = report.result
    assert r.status == "CONVERGED" and r.interior_steps > 0 and r.sweeps == 0
    assert r.method == "interior-point" and r.bound_from == "interior-point"
    assert np.all(model.force[contacts.mu == 0.0, 1:] == 0.0)
    W, b, _, _ = dense_problem(helices, contacts, mat, model)
    check_optimality(W, b, model.force, contacts.mu, rtol=1e-6)
    tight, _ = solve(helices, contacts, mat)  # the sweeps, to 1e-10 of a strand's weight
    assert rms(model.omega_rest - tight.omega_rest) <= r.rest_bound + 1e-9 * sag(helices, mat)


@pytest.mark.parametrize("mu", [1e6, np.inf])
def test_friction_outside_the_steps_range_is_finished_by_the_sweeps(mu):
    helices, contacts = two_strand_scene(mu=mu)
    mat = material()
    model, report = solve(helices, contacts, mat, **ip(helices, mat))
    r = report.result
    assert r.status == "CONVERGED" and r.interior_steps > 0
    # the steps solved another cone: the bound reported is the sweeps', on the problem as declared, and says so
    assert r.method == "interior-point" and r.bound_from == "sweeps" and 0.0 <= r.rest_bound < np.inf
    assert any("by the forces' duality gap" in line for line in report.lines())
    W, b, _, _ = dense_problem(helices, contacts, mat, model)
    check_optimality(W, b, model.force, contacts.mu, rtol=1e-7)


@pytest.mark.parametrize("gamma", [1e-12, 1e9])
def test_extreme_gamma(gamma):
    helices, contacts = four_strands_in_a_pile()
    mat = material()
    model, report = solve(helices, contacts, mat, gamma=gamma, **ip(helices, mat))
    assert report.result.status == "CONVERGED"
    assert np.all(np.isfinite(model.force)) and np.all(np.isfinite(model.omega_rest))
    W, b, _, _ = dense_problem(helices, contacts, mat, model)
    check_optimality(W, b, model.force, contacts.mu, rtol=1e-6)


def test_a_single_contact_and_none():
    helices, contacts = resting_scene(n_contacts=1)
    mat = material()
    model, report = solve(helices, contacts, mat, **ip(helices, mat))
    assert report.result.status == "CONVERGED"
    W, b, _, _ = dense_problem(helices, contacts, mat, model)
    check_optimality(W, b, model.force, contacts.mu, rtol=1e-6)
    empty, report = solve(helices, None, mat, **ip(helices, mat))
    assert report.result.status == "CONVERGED" and report.contacts == 0


def test_every_factorisation_takes_the_same_steps():
    helices, contacts = four_strands_in_a_pile()
    mat = material()
    probe, _ = solve(helices, contacts, mat)
    _, b, H, d = dense_problem(helices, contacts, mat, probe)
    rows = contact_rows(helices, contacts)
    tol = 1e-3 * sag(helices, mat)  # well above round-off, where all take the same steps
    runs = {backend: solve_interior(rows, d, 1e-3, b.reshape(-1, 3), contacts.mu, rest_tolerance=tol,
                                    backend=backend) for backend in ("supernodal", "cholmod", "superlu")}
    a = runs["supernodal"]
    assert a.backend == "supernodal" and a.status == "CONVERGED"
    for s in runs.values():
        assert s.status == "CONVERGED" and s.iterations == a.iterations
        assert rms(rest_of(helices, mat, H, a.r) - rest_of(helices, mat, H, s.r)) <= 1e-9 * sag(helices, mat)


def test_settings_are_checked():
    helices, contacts = resting_scene()
    for bad in ({"method": "newton"}, {"rest_tolerance": 0.0}, {"rest_tolerance": float("nan")},
                {"max_iterations": 0}):
        with pytest.raises(InputError):
            invert(helices, contacts, material(), SolverSettings(**bad))


def test_factor_cost_is_counted_exactly_and_too_large_falls_back_to_the_sweeps():
    """The count is checked against the factor of a dense Cholesky of the same pattern under the same order;
    a groom over the cap is refused by the method and solved by the sweeps, with a note."""
    import scipy.sparse

    from hairinv.solver import interior

    helices, contacts = four_strands_in_a_pile()
    rows = contact_rows(helices, contacts)
    factor = interior._Factor(rows.ptr, rows.cols, rows.n_dofs, "cholmod")
    # a random SPD matrix with the system's pattern, factored densely: its non-zero pattern is the factor's
    lower = scipy.sparse.csc_matrix((np.random.default_rng(0).uniform(0.1, 1.0, len(factor.Si)), factor.Si,
                                     factor.Sp), shape=(rows.n_dofs,) * 2)
    full = (lower + lower.T).toarray()
    full += np.diag(np.abs(full).sum(axis=1) + 1.0)
    p = factor.order
    L = np.linalg.cholesky(full[np.ix_(p, p)])
    counts = np.count_nonzero(np.abs(L) > 0.0, axis=0)
    assert factor.flops == float(np.sum(counts.astype(float) ** 2))
    mat = material()
    res = solve_interior(rows, np.ones(rows.n_dofs), 1e-3, np.ones((contacts.n_contacts, 3)), contacts.mu,
                         max_gflop=0.5 * factor.flops / 1e9)
    assert res.status == "TOO_LARGE" and np.all(res.r == 0.0)
    original = interior.MAX_GFLOP
    try:
        interior.MAX_GFLOP = 0.5 * factor.flops / 1e9
        fallback, rep = solve(helices, contacts, mat, method="interior-point")
    finally:
        interior.MAX_GFLOP = original
    assert rep.result.method == "sweeps" and rep.result.sweeps > 0 and rep.result.status == "CONVERGED"
    assert any("solved by the sweeps instead" in n for n in rep.notes)


def test_each_ordering_is_counted_exactly_and_the_cheapest_is_kept():
    """AMD and METIS's nested dissection are both counted (against a dense Cholesky of a random matrix of the
    same pattern under each) and the factor keeps the cheaper; nested dissection is a permutation."""
    import scipy.sparse

    from hairinv.solver import interior

    helices, contacts = four_strands_in_a_pile()
    rows = contact_rows(helices, contacts)
    factor = interior._Factor(rows.ptr, rows.cols, rows.n_dofs, "cholmod")
    lower = scipy.sparse.csc_matrix((np.ones(len(factor.Si)), factor.Si, factor.Sp), shape=(rows.n_dofs,) * 2)
    pattern = (lower + lower.T).tocsc()
    full = (lower + lower.T).toarray() * np.random.default_rng(1).uniform(0.1, 1.0, (rows.n_dofs,) * 2)
    full = full + full.T
    full += np.diag(np.abs(full).sum(axis=1) + 1.0)
    counted = {}
    for name, (order, flops) in factor.candidates.items():
        assert np.array_equal(np.sort(order), np.arange(rows.n_dofs))
        L = np.linalg.cholesky(full[np.ix_(order, order)])
        counted[name] = float(np.sum(np.count_nonzero(np.abs(L) > 0.0, axis=0).astype(float) ** 2))
        # the second candidate is counted only up to the first's cost
        assert flops == counted[name] or (flops == np.inf and counted[name] > min(counted.values()))
    assert set(counted) == ({"amd", "metis"} if interior.nested_dissection(pattern) is not None else {"amd"})
    assert factor.flops == min(counted.values()) and counted[factor.ordering] == factor.flops


def test_a_system_with_too_many_entries_is_declined_before_it_is_ordered(monkeypatch):
    """The cap is on the entries of the system's lower triangle: those of ``I + H'H`` (counted here from the
    contacts' incidence), one entry over it declines the method before any ordering or factorisation."""
    from hairinv.solver import interior

    helices, contacts = four_strands_in_a_pile()
    rows = contact_rows(helices, contacts)
    counts = np.diff(rows.ptr)
    incidence = scipy.sparse.csr_matrix((np.ones(len(rows.cols)), (np.repeat(np.arange(len(counts)), counts),
                                                                   rows.cols)), shape=(len(counts), rows.n_dofs))
    entries = scipy.sparse.tril(incidence.T @ incidence + scipy.sparse.eye(rows.n_dofs)).nnz
    monkeypatch.setattr(interior, "_MAX_ENTRIES", entries)
    ordered = []
    monkeypatch.setattr(interior, "nested_dissection", lambda pattern: ordered.append(1))
    res = solve_interior(rows, np.ones(rows.n_dofs), 1e-3, np.ones((contacts.n_contacts, 3)), contacts.mu)
    assert res.status != "TOO_LARGE" and ordered
    ordered.clear()
    monkeypatch.setattr(interior, "_MAX_ENTRIES", entries - 1)
    res = solve_interior(rows, np.ones(rows.n_dofs), 1e-3, np.ones((contacts.n_contacts, 3)), contacts.mu)
    assert res.status == "TOO_LARGE" and np.all(res.r == 0.0) and not ordered


def test_the_flop_cap_is_the_counted_cost_itself():
    """A groom costing exactly the cap is solved and one flop over it is declined: the count decides there,
    not the entries' lower bound (which lies below it on this pile)."""
    from hairinv.solver import interior

    helices, contacts = four_strands_in_a_pile()
    rows = contact_rows(helices, contacts)
    factor = interior._Factor(rows.ptr, rows.cols, rows.n_dofs, "supernodal")
    assert factor.system.entries ** 2 / rows.n_dofs < factor.flops - 1
    args = (rows, np.ones(rows.n_dofs), 1e-3, np.ones((contacts.n_contacts, 3)), contacts.mu)
    assert solve_interior(*args, max_gflop=factor.flops / 1e9).status != "TOO_LARGE"
    assert solve_interior(*args, max_gflop=(factor.flops - 1) / 1e9).status == "TOO_LARGE"


def test_auto_takes_the_interior_point_where_it_is_affordable_and_the_sweeps_elsewhere(monkeypatch):
    """solver.method = auto: the interior-point method on a small groom, ignoring a start (and
    saying so); over ``AUTO_GFLOP`` the sweeps, from that start, with a note. Either answer is the optimum."""
    import hairinv.inverse.method as inv

    helices, contacts = four_strands_in_a_pile()
    mat = material()
    # the sweeps to 1e-10 of a strand's weight, with the default's friction reserve and bounded forces
    # (this pile needs about 30,000 sweeps there)
    tight, rep = solve(helices, contacts, mat, friction_reserve=SolverSettings().friction_reserve,
                       gamma_relative=SolverSettings().gamma_relative, max_sweeps=60000)
    assert rep.result.status == "CONVERGED"
    scale = sag(helices, mat)
    auto = SolverSettings(method="auto", rest_tolerance=1e-6 * scale, max_iterations=200)
    start = tight.force * 0.5

    class Bar:
        """Records the unit it counts in at each report, as the command's progress bar would show it."""

        def __init__(self):
            self.unit, self.seen = "sweep", []

        def __call__(self, n, value, *bound):
            self.seen.append(self.unit)

        def interior(self, steps):
            self.unit = "step"
            return self

    bar = Bar()
    model, rep = invert(helices, contacts, mat, auto, start=start, progress=bar)
    assert bar.seen and set(bar.seen) == {"step"}
    assert rep.result.method == "interior-point" and rep.result.status == "CONVERGED" and rep.result.sweeps == 0
    assert rms(model.omega_rest - tight.omega_rest) <= rep.result.rest_bound + 1e-9 * scale
    assert any("afresh" in n for n in rep.notes) and not any("started from the given" in n for n in rep.notes)
    monkeypatch.setattr(inv, "AUTO_GFLOP", 1e-12)
    bar = Bar()
    swept, rep = invert(helices, contacts, mat, dataclasses.replace(auto, tolerance=1e-10, max_sweeps=60000),
                        start=start, progress=bar)
    # the declined interior-point method leaves the bar counting sweeps
    assert bar.seen and set(bar.seen) == {"sweep"}
    assert rep.result.method == "sweeps" and rep.result.status == "CONVERGED"
    assert any("solver.method = auto: the sweeps solved this groom" in n for n in rep.notes)
    assert any("started from the given forces" in n for n in rep.notes)
    assert np.abs(swept.omega_rest - tight.omega_rest).max() <= 1e-6 * scale


def test_a_round_off_pivot_is_retried_with_the_diagonal_shifted(monkeypatch):
    """The supernodal path's retry: the entries it scales are the diagonal of the permuted system, scaled by
    1 + 1e-10 and nothing else, and the factor then solves the shifted system."""
    from hairinv.solver import interior, supernodal

    helices, contacts = four_strands_in_a_pile()
    rows = contact_rows(helices, contacts)
    factor = interior._Factor(rows.ptr, rows.cols, rows.n_dofs, "supernodal")
    sn = factor.supernodal
    assert np.array_equal(sn.Li[sn.Lp[:-1]], np.arange(rows.n_dofs))  # the first entry of each column
    C = rows.n_contacts
    rng = np.random.default_rng(3)
    M = rng.standard_normal((C, 3, 3))
    Binv = M @ M.transpose(0, 2, 1)
    factor.system.assemble(rows.vals, Binv, factor.Sx)
    before = factor.Sx[sn.source]
    real = supernodal.SupernodalCholesky._factor_values
    calls = []

    def once_refused(self):
        calls.append(self.values.copy())
        if len(calls) == 1:
            raise ArithmeticError("non-positive pivot")
        real(self)

    monkeypatch.setattr(supernodal.SupernodalCholesky, "_factor_values", once_refused)
    factor.factor(rows.vals, Binv)
    assert len(calls) == 2 and np.array_equal(calls[0], before)
    expected = before.copy()
    expected[sn.Lp[:-1]] *= 1.0 + 1e-10
    assert np.array_equal(calls[1], expected)
    lower = scipy.sparse.csc_matrix((expected, sn.Li, sn.Lp), shape=(rows.n_dofs,) * 2).toarray()
    S = lower + np.tril(lower, -1).T
    w = rng.standard_normal(rows.n_dofs)
    x = factor.solve(w)[sn.perm]  # the permuted system's solution
    assert np.linalg.norm(S @ x - w[sn.perm]) <= 1e-9 * np.linalg.norm(w) * np.linalg.cond(S)
