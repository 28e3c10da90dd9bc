"""Stability of an inverted equilibrium, and the per-strand stiffening that ensures it.

Closed forms: Greenhill's critical height of a column clamped at its foot under
its own weight (``(7.837 EI / lam g)^(1/3)``), so the critical stiffness factor of
a column of height ``L`` is ``lam g L^3 / (7.837 EI)``; Euler's critical load of a
column clamped at one end and pinned at the other, ``20.19 EI / L^2``, which tests
the contact forces' own share of the Hessian (a held point's reaction).
"""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from conftest import ROUNDOFF, TIGHT, UP, make_contacts, material, strands
from hairinv import stages
from hairinv.config import FitSettings, SolverSettings
from hairinv.gravity import generalized_gravity
from hairinv.inverse.stability import stability_margins
from hairinv.invert import invert
from hairinv.model import rest_from_group, stiffening_from_group, stiffness
from hairinv.contacts.rows import contact_rows

# the element count of the test columns: a column of N constant-curvature elements buckles within
# about 1 / N^2 of the continuous column's load (the check measured below)
ELEMENTS = 24
DISCRETIZATION = 0.01


def solve(helices, contacts, mat, **solver):
    settings = SolverSettings(**{"tolerance": TIGHT, "max_sweeps": 20000, **solver})
    return invert(helices, contacts, mat, settings)


def column(height, n=ELEMENTS, up=True):
    tangent = UP if up else -UP
    return strands([(np.zeros(3), tangent, np.zeros((n, 3)), np.full(n, height / n))])


@pytest.mark.parametrize("height", [0.2, 0.3])
def test_a_standing_column_is_stiffened_to_greenhills_critical_factor(height):
    """No contact: the factor that makes the column stable is Greenhill's, times the margin."""
    mat = material()
    helices = column(height)
    model, report = solve(helices, None, mat)
    critical = mat.linear_density * np.linalg.norm(mat.gravity) * height ** 3 / (7.837 * mat.bending)
    assert critical > 1.5  # past the critical height: it needs stiffening
    margin = SolverSettings().stiffen_margin
    assert model.stiffening[0] / margin == pytest.approx(critical, rel=DISCRETIZATION)
    # held fixed, the forces (none here) are kept: the factor is final without solving again
    assert report.unstable == 0 and report.stiffened_rounds == 0
    # the column needs nothing else, so the gravity-only figure is the same strand's factor
    assert report.gravity_only_factor == pytest.approx(model.stiffening[0] / margin, rel=1e-9)


def test_the_closed_form_factor_matches_the_recomputed_eigenvalue():
    """Scaling K by a scales K^-1/2 V'' K^-1/2 by 1/a: lambda(a) = 1 - (1 - lambda(1)) / a. Checked by
    recomputing the Hessian's eigenvalue at several factors, and the sign change bracketed (what a
    bisection on the factor would find)."""
    mat = material()
    helices = column(0.25, n=12)
    lam1 = stability_margins(helices, mat, stiffness(helices, mat))[1][0]
    assert lam1 < 0
    for a in (0.5, 2.0, 1 - lam1, 10.0):
        lam = stability_margins(helices, mat, stiffness(helices, mat, np.array([a])))[1][0]
        assert lam == pytest.approx(1 - (1 - lam1) / a, abs=1e-9)
    below = stability_margins(helices, mat, stiffness(helices, mat, np.array([0.999 * (1 - lam1)])))[1][0]
    above = stability_margins(helices, mat, stiffness(helices, mat, np.array([1.001 * (1 - lam1)])))[1][0]
    assert below < 0 < above


@pytest.mark.parametrize("ratio, unstable", [(0.8, False), (1.2, True)])
def test_a_held_tip_pushed_along_the_strand_buckles_at_eulers_load(ratio, unstable):
    """A strand hanging from its root with its tip held by a contact that pushes it up: a column
    clamped at the root and pinned at the tip under end compression P, which buckles at
    P = 20.19 EI / L^2. Only the reaction's own share of the Hessian, -r . d^2 x, can see this
    (gravity is made negligible: density 1 kg/m^3)."""
    mat = material(density=1.0)
    L = 0.1
    helices = column(L, up=False)
    contacts = make_contacts(helices, [(0, L, -1, 0.0, UP, 0.3)])
    P = ratio * 20.19 * mat.bending / L ** 2
    assert mat.linear_density * np.linalg.norm(mat.gravity) * L < 1e-3 * P
    rows = contact_rows(helices, contacts)
    force = np.array([[P, 0.0, 0.0]])
    carrying = np.array([True])
    stiff = stiffness(helices, mat)
    supported, free, held, _ = stability_margins(helices, mat, stiff, rows, contacts, carrying, force)
    assert free[0] > 0  # hanging, it is stable by itself
    assert (supported[0] < 0) == unstable and (held[0] < 0) == unstable
    # without the reaction's share the held tip looks stable whatever the push
    supported, _, _, _ = stability_margins(helices, mat, stiff, rows, contacts, carrying)
    assert supported[0] > 0


@pytest.mark.parametrize("ratio, unstable", [(0.9, False), (1.1, True)])
def test_a_dead_load_on_the_tip_buckles_at_eulers_clamped_free_load(ratio, unstable):
    """The same strand with its tip pushed by a force held fixed (the point free to move): a column
    clamped at the root and free at the tip under a dead end load, which buckles at
    P = pi^2 EI / (4 L^2), eight times below the pinned tip's load. This is the margin of the contact
    forces held fixed (solver.stable_under = forces)."""
    mat = material(density=1.0)
    L = 0.1
    helices = column(L, up=False)
    contacts = make_contacts(helices, [(0, L, -1, 0.0, UP, 0.3)])
    P = ratio * np.pi ** 2 / 4.0 * mat.bending / L ** 2
    rows = contact_rows(helices, contacts)
    force = np.array([[P, 0.0, 0.0]])
    supported, free, _, fixed = stability_margins(helices, mat, stiffness(helices, mat), rows, contacts,
                                                  np.array([True]), force)
    assert free[0] > 0 and supported[0] > 0  # pinned, the tip holds far more
    assert (fixed[0] < 0) == unstable


def upright_scene():
    """An upright 25 cm strand (past the critical height), its tip leaning on a wall it pushes
    against slightly (tilted, so the wall carries force), and a short hanging strand."""
    tilt = np.zeros((8, 3))
    tilt[:, 1] = 0.5  # a gentle bend towards +x or -x
    helices = strands([(np.zeros(3), UP, tilt, np.full(8, 0.25 / 8)),
                       (np.array([0.05, 0.0, 0.0]), -UP, np.zeros((4, 3)), np.full(4, 0.02))])
    return helices


def test_stabilize_off_repeats_the_unstiffened_inversion_bit_for_bit():
    mat = material()
    helices = upright_scene()
    off, off_report = solve(helices, None, mat, stabilize="off")
    plain, _ = invert(helices, None, mat, SolverSettings(tolerance=TIGHT, max_sweeps=20000), check_stability=False)
    on, on_report = solve(helices, None, mat)
    assert off.stiffening is None and off.omega_rest_stiffened is None and off_report.unstable == 1
    assert np.array_equal(off.omega_rest, plain.omega_rest) and np.array_equal(off.force, plain.force)
    # stiffening changes only the strand that needed it; omega_rest keeps the material-stiffness meaning
    assert on_report.unstable == 0 and on.stiffening[0] > 1.0 and on.stiffening[1] == 1.0
    assert np.array_equal(on.omega_rest, off.omega_rest)
    assert np.array_equal(on.omega_rest_stiffened[8:], off.omega_rest[8:])


def test_a_stiffened_model_is_an_exact_equilibrium_for_old_and_new_readers(tmp_path):
    """Read back from the file: an old reader (material stiffness, omega_rest, no stiffening) sees an
    exact equilibrium, K (q - q0) = F_g (no contacts here); a new one (stiffening and
    omega_rest_stiffened) sees the stiffened strand's own, a K (q - q0s) = F_g."""
    mat = material()
    helices = upright_scene()
    model, _ = solve(helices, None, mat)
    path = tmp_path / "model.h5"
    stages.write_stage(path, [helices.group(FitSettings(), []), model.group({}, [])], "test")
    with h5py.File(path, "r") as fh:
        g = fh["model"]
        required = {"omega_rest", "omega_target", "target_weight", "force"}
        assert required <= set(g.keys())
        q0 = g["omega_rest"][()]
    F = generalized_gravity(helices, mat).ravel()
    K = stiffness(helices, mat)
    q = helices.omega.ravel()
    assert np.abs(K * (q - q0.ravel()) - F).max() <= ROUNDOFF * np.abs(F).max()
    group = stages.read_stage(path)[stages.MODEL]
    factor = stiffening_from_group(group, helices.n_strands)
    Ks = stiffness(helices, mat, factor)
    q0s = rest_from_group(group).ravel()
    assert np.abs(Ks * (q - q0s) - F).max() <= ROUNDOFF * np.abs(F).max()
    assert not np.allclose(q0s, q0.ravel())  # the stiffened strand's rest shape is its own


def test_the_stored_margin_is_greenhills_and_says_which_strands_rest_stably(tmp_path):
    """``/model/stability_margin`` read back from the file: a standing column past Greenhill's height
    inverted without stabilisation has ``1 - lambda`` = Greenhill's critical factor (it is unstable); a
    hanging one is stable; with stiffening by ``a = m (1 - lambda)``, ``lambda(a) = 1 - 1 / m`` (the
    closed form above). The summary lists the unstable strand."""
    from hairinv.model import stability_from_group
    from hairinv.summary import summarise

    mat = material()
    height = 0.3
    helices = strands([(np.zeros(3), UP, np.zeros((ELEMENTS, 3)), np.full(ELEMENTS, height / ELEMENTS)),
                       (np.array([0.05, 0.0, 0.0]), -UP, np.zeros((ELEMENTS, 3)), np.full(ELEMENTS, height / ELEMENTS))])
    critical = mat.linear_density * np.linalg.norm(mat.gravity) * height ** 3 / (7.837 * mat.bending)
    m = SolverSettings().stiffen_margin
    margins = {}
    for stabilize in ("off", "stiffen"):
        model, _ = solve(helices, None, mat, stabilize=stabilize)
        path = tmp_path / f"{stabilize}.h5"
        stages.write_stage(path, [helices.group(FitSettings(), []), model.group({}, [])], "test")
        stage = stages.read_stage(path)
        margins[stabilize] = stability_from_group(stage[stages.MODEL], 2)
        assert stage[stages.MODEL].attrs["stable_under"] == "forces"
        summary = summarise(stage)["groups"]["model"]
        assert summary["unstable_strands"] == ([0] if stabilize == "off" else [])
    off, on = margins["off"], margins["stiffen"]
    assert 1.0 - off[0] == pytest.approx(critical, rel=DISCRETIZATION) and off[0] < 0
    assert on[0] == pytest.approx(1.0 - 1.0 / m, abs=1e-9)
    assert off[1] > 0 and on[1] == off[1]  # the hanging column is stable and left alone


@pytest.mark.parametrize("rows", [5, 21, 60])
def test_the_held_margin_is_the_smallest_eigenvalue_on_the_null_space_of_the_held_rows(rows):
    """``_lowest_held`` against its definition: the smallest eigenvalue of ``Z^T A Z`` with ``Z`` an
    orthonormal basis of the null space of the rows (scipy's, by its own SVD), with fewer rows than
    columns, as many, and more (a dense head's strand: more rows than coordinates, with dependent ones:
    two contacts on one spot, or rows that repeat a combination of others); ``inf`` where no motion is left."""
    from scipy.linalg import null_space

    from hairinv.inverse.stability import _lowest_held

    rng = np.random.default_rng(rows)
    m = 21
    B = rng.normal(size=(m, m))
    A = np.eye(m) + 0.3 * (B + B.T)
    C = rng.normal(size=(rows, m)) * rng.uniform(1e-3, 1e2, size=(rows, 1))  # rows of any length
    for dependent in (False, True):
        H = C.copy()
        if dependent:  # rank 8 whatever the row count: every row a combination of eight
            H = rng.normal(size=(rows, 8)) @ rng.normal(size=(8, m))
        Z = null_space(H / np.linalg.norm(H, axis=1, keepdims=True), rcond=1e-12)
        expected = np.linalg.eigvalsh(Z.T @ A @ Z)[0] if Z.shape[1] else np.inf
        got = _lowest_held(A, np.ascontiguousarray(H))
        if np.isinf(expected):
            assert np.isinf(got)
        else:
            assert got == pytest.approx(expected, rel=1e-10, abs=1e-10)


def test_leaving_the_supports_margin_out_changes_no_other_margin():
    """``supported=False`` (what the default stabilisation on the forces held fixed asks for) leaves the
    first margin out, NaN on strands with contacts, and the other three exactly as computed with it."""
    mat = material(density=1.0)
    L = 0.1
    helices = strands([(np.zeros(3), -UP, np.zeros((ELEMENTS, 3)), np.full(ELEMENTS, L / ELEMENTS)),
                       (np.array([0.05, 0.0, 0.0]), UP, np.zeros((6, 3)), np.full(6, 0.02))])
    contacts = make_contacts(helices, [(0, L, -1, 0.0, UP, 0.3), (0, 0.5 * L, -1, 0.0, UP, 0.3)])
    rows = contact_rows(helices, contacts)
    force = np.array([[0.5 * mat.bending / L ** 2, 0.0, 0.0], [0.0, 0.0, 0.0]])
    carrying = np.array([True, False])
    stiff = stiffness(helices, mat)
    full = stability_margins(helices, mat, stiff, rows, contacts, carrying, force)
    lean = stability_margins(helices, mat, stiff, rows, contacts, carrying, force, supported=False)
    assert np.isfinite(full[0][0]) and np.isnan(lean[0][0])
    assert lean[0][1] == full[0][1]  # no contact: the free margin, as before
    for a, b in zip(full[1:], lean[1:]):
        np.testing.assert_array_equal(a, b)
