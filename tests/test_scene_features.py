"""A scene models only what it requires (docs/scenes.md, "What a scene models").

Switching a feature off removes its work and changes only what it should: hair-hair contact off leaves
exactly the body contacts and runs no hair-hair detection; no body (or contacts.body off) leaves exactly
the hair-hair contacts and queries no body; frictionless contacts get no tangential force and satisfy
the optimality conditions of the frictionless problem (checked with contact Jacobians by finite
differences of the centre line, not with the solver's own rows); no stability check leaves the forces
and the rest shape bit for bit and runs no eigen-check; without gravity and contacts the rest shape is
the input. The cost of each switch is timed in bench/scene_cost_bench.py, not here.

The groom is ``samples/settled_curly.h5`` (40 curly strands settled on the sample bust, with its
super-helices), so nothing is fitted.
"""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from conftest import SAMPLES, TIGHT
from hairinv import config
from hairinv.config import MaterialSettings
from hairinv.features import detect_features, invert_features, simulate_features
from hairinv.invert import invert
from hairinv.model import BODY, Material
from hairinv.pipeline import prepare
from hairinv.rod.helix import points_at

GROOM = SAMPLES / "settled_curly.h5"
HAIRINV = str(Path(sys.executable).with_name("hairinv"))
BODY_FILE = SAMPLES / "body.obj"
# central differences of a centre-line point at step FD_STEP (1/m): round-off ~ 1e-16 |x| / FD_STEP, and
# truncation ~ FD_STEP^2 times the third derivative; on this groom 5e-12 m against normal rows up to
# 2e-3 m (3e-10 at a step of 1e-6)
FD_STEP = 1e-4
# the optimality conditions hold to the solver's tolerance and the finite differences' error, relative to
# each contact's sum of |terms| of u_N = H_N K^-1 (t - q0) + gamma r_N (they cancel to ~1e-7 of it)
KKT = 1e-5


def settings(**contacts) -> config.Settings:
    s = config.resolve()
    return dataclasses.replace(s, contacts=dataclasses.replace(s.contacts, **contacts))


def arrays(contacts):
    return (contacts.strand, contacts.s, contacts.point, contacts.frame, contacts.mu, contacts.gap)


def assert_same_contacts(a, b):
    assert a.n_contacts == b.n_contacts
    for x, y in zip(arrays(a), arrays(b)):
        np.testing.assert_array_equal(x, y)


def forbid(monkeypatch, target: str, what: str):
    """Make ``target`` raise if anything calls it: the work it stands for must not be done."""
    def refuse(*args, **kwargs):
        raise AssertionError(f"{what} ran although the feature is off")
    monkeypatch.setattr(target, refuse)


@pytest.fixture(scope="module")
def everything():
    """The groom's contacts with every feature on (body and hair-hair)."""
    scene = prepare(GROOM, BODY_FILE, settings())
    c = scene.contacts
    # the comparisons below mean something only if both kinds are there
    assert c.n_body > 0 and c.n_hair > 0
    return scene


def test_hair_hair_off_gives_exactly_the_body_contacts_and_runs_no_hair_hair_detection(everything, monkeypatch):
    forbid(monkeypatch, "hairinv.contacts.detect.hair_pairs", "hair-hair detection")
    forbid(monkeypatch, "hairinv.contacts.detect.refine_pairs", "hair-hair refinement")
    scene = prepare(GROOM, BODY_FILE, settings(hair_hair=False))
    on = everything.contacts
    assert scene.contacts.n_hair == 0
    assert_same_contacts(scene.contacts, on.subset(on.strand[:, 1] == BODY))
    assert "hair_hair_contact" in scene.features.skipped and "body_contact" in scene.features.modelled
    assert "contacts.hair_hair = false" in scene.features.line()


@pytest.mark.parametrize("how", ["no body file", "contacts.body off"])
def test_without_a_body_exactly_the_hair_hair_contacts_and_no_body_query(everything, monkeypatch, how):
    forbid(monkeypatch, "hairinv.pipeline.BodyMesh.from_mesh", "building the body's search tree")
    forbid(monkeypatch, "hairinv.contacts.detect.element_body_contacts", "body queries")
    if how == "no body file":
        scene = prepare(GROOM, None, settings())
        why = "no body mesh given"
    else:
        scene = prepare(GROOM, BODY_FILE, settings(body=False))
        why = "contacts.body = false"
    on = everything.contacts
    assert scene.contacts.n_body == 0
    assert_same_contacts(scene.contacts, on.subset(on.strand[:, 1] != BODY))
    assert why in scene.features.skipped["body_contact"]


def test_both_contact_kinds_off_declare_nothing():
    scene = prepare(GROOM, BODY_FILE, settings(body=False, hair_hair=False))
    assert scene.contacts.n_contacts == 0
    assert set(scene.features.skipped) == {"body_contact", "hair_hair_contact"} and not scene.features.modelled


def jacobian_normal_rows(helices, contacts, h=FD_STEP) -> np.ndarray:
    """``n . d(x_A - x_B)/dq`` of every contact, (C, 3E), by central differences of the centre line
    (:func:`hairinv.rod.helix.points_at`), independently of the solver's contact rows."""
    C, E = contacts.n_contacts, helices.n_elements
    out = np.zeros((C, 3 * E))
    normal = contacts.frame[:, 0]
    for side, sign in ((0, 1.0), (1, -1.0)):
        for k in np.unique(contacts.strand[:, side]):
            if k < 0:
                continue
            which = np.flatnonzero(contacts.strand[:, side] == k)
            a, z = helices.offsets[k], helices.offsets[k + 1]
            s = np.ascontiguousarray(contacts.s[which, side])
            for e in range(a, z):
                for c in range(3):
                    pts = []
                    for step in (h, -h):
                        om = helices.omega[a:z].copy()
                        om[e - a, c] += step
                        x = np.empty((len(s), 3))
                        points_at(helices.root[k], helices.frame0[k], om, helices.length[a:z], s, x)
                        pts.append(x)
                    dx = (pts[0] - pts[1]) / (2 * h)
                    out[which, 3 * e + c] += sign * np.einsum("ij,ij->i", normal[which], dx)
    return out


def test_frictionless_contacts_get_no_tangential_force_and_meet_the_frictionless_optimality_conditions(everything):
    """mu = 0 everywhere: the problem is min 1/2 r'Wr + b'r over r_T = 0, r_N >= 0, whose optimality
    conditions are r_N >= 0, u_N = (W r + b)_N >= 0, r_N u_N = 0. With q0 = q - K^-1 (F_g + H^T r),
    W r + b = H K^-1 (t - q0) + gamma_c r (target t, unit weights), so u_N is read off the model's rest
    shape with H's normal rows by finite differences and K from the material's closed form."""
    scene = everything
    helices = scene.helices
    contacts = dataclasses.replace(scene.contacts, mu=np.zeros(scene.contacts.n_contacts))
    s = settings(mu_body=0.0, mu_hair=0.0)
    mat = Material.from_settings(s.material, scene.up)
    # the residual alone stops the sweeps: rest_tolerance far below what they reach (the interior point's
    # frictionless solve: tests/test_interior.py)
    solver = dataclasses.replace(s.solver, method="sweeps", tolerance=TIGHT, max_sweeps=50000, stabilize="off",
                                 check_stability=False, rest_tolerance=1e-300)
    model, report = invert(helices, contacts, mat, solver)
    assert report.result.status == "CONVERGED"
    r = model.force
    assert np.all(r[:, 1:] == 0.0)  # exactly: solved as a 1-D problem, not a cone with a tiny force
    assert report.carrying > 0 and np.all(r[:, 0] >= 0.0)  # the cone of mu = 0: r_N >= 0
    force = r[:, 0].max()
    area = np.pi * mat.radius ** 4
    K = (helices.length[:, None] * np.array([mat.youngs_modulus * area / 4, mat.youngs_modulus * area / 4,
                                             mat.shear_modulus * area / 2])).ravel()
    HN = jacobian_normal_rows(helices, contacts)
    d = (model.omega_target - model.omega_rest).ravel() / K
    gamma = model.gamma if model.contact_gamma is None else model.contact_gamma  # each contact's weight
    uN = HN @ d + gamma * r[:, 0]
    scale = np.abs(HN) @ np.abs(d) + gamma * r[:, 0]
    assert np.all(uN >= -KKT * scale)  # the dual cone: no contact pulls
    carrying = r[:, 0] > 0
    assert np.all(np.abs(uN[carrying]) <= KKT * scale[carrying])  # complementarity: loaded contacts do not open
    assert np.count_nonzero(uN > 1e-2 * scale) > 0  # and some contacts are clearly open (the test can tell)
    # and it is not the frictional answer: friction changes the forces of this groom
    rough, _ = invert(helices, scene.contacts, mat, solver)
    assert np.abs(rough.force[:, 1:]).max() > 1e-3 * force


def test_no_stability_check_changes_nothing_but_the_check(everything, monkeypatch):
    scene = everything
    s = settings()
    mat = Material.from_settings(s.material, scene.up)
    checked, checked_report = invert(scene.helices, scene.contacts, mat, dataclasses.replace(s.solver, stabilize="off"))
    assert checked.stability_margin is not None and checked_report.checked
    forbid(monkeypatch, "hairinv.inverse.stabilize.stability_margins", "the stability check")
    forbid(monkeypatch, "hairinv.inverse.stabilize.group_margins", "the joint stability check")
    solver = dataclasses.replace(s.solver, stabilize="off", check_stability=False)
    model, report = invert(scene.helices, scene.contacts, mat, solver)
    assert model.stiffening is None and model.omega_rest_stiffened is None  # the material's own: factors 1
    assert model.stability_margin is None and not report.checked and report.unstable == 0
    np.testing.assert_array_equal(model.force, checked.force)
    np.testing.assert_array_equal(model.omega_rest, checked.omega_rest)
    assert not any("stable equilibrium" in line for line in report.lines())
    features = invert_features(s.contacts, solver, mat.gravity, True)
    assert set(features.skipped) == {"stability_check", "stiffening"}


def test_stiffening_without_the_check_is_refused_in_one_sentence():
    from hairinv.errors import InputError
    from hairinv.invert import validate_settings

    with pytest.raises(InputError, match="check_stability = false skips the check that stiffening needs"):
        validate_settings(dataclasses.replace(config.resolve().solver, check_stability=False))


def test_without_gravity_or_contacts_the_rest_shape_is_the_input(everything):
    mat = Material.from_settings(MaterialSettings(gravity=0.0), everything.up)
    assert np.all(mat.gravity == 0.0)
    model, report = invert(everything.helices, None, mat, config.resolve().solver)
    np.testing.assert_array_equal(model.omega_rest, everything.helices.omega)
    assert report.unstable == 0
    features = invert_features(config.resolve().contacts, config.resolve().solver, mat.gravity, True)
    assert features.skipped["gravity"] == "material.gravity = 0"


def test_negative_gravity_is_refused_in_one_sentence():
    from hairinv.errors import InputError

    with pytest.raises(InputError, match="material.gravity is .*; it must be a number from 0.001 to 1000 m/s"):
        Material.from_settings(MaterialSettings(gravity=-1.0), (0.0, 1.0, 0.0))


def test_simulate_models_only_what_the_scene_has(everything, monkeypatch):
    """The still scene: no body motion, no trim; the body removed: no body contact and no body queries
    (its search tree is never built), the hair-hair contacts kept."""
    from hairinv.dynamics.run import run_scene
    from hairinv.dynamics.scene import Scene

    scene = everything
    s = settings()
    mat = Material.from_settings(s.material, scene.up)
    model, _ = invert(scene.helices, scene.contacts, mat, dataclasses.replace(s.solver, stabilize="off",
                                                                             check_stability=False))
    group = model.group({}, [])
    still = simulate_features(s.contacts, mat.gravity, True, Scene.load("still"), "inverted", False)
    assert "body is fixed" in still.skipped["body_motion"] and "trim" in still.skipped
    assert {"gravity", "body_contact", "hair_hair_contact", "friction"} <= set(still.modelled)
    removed_scene = Scene.load("remove-body")
    removed = simulate_features(s.contacts, mat.gravity, True, removed_scene, "inverted", False)
    assert removed.skipped["body_contact"] == "the scene removes the body"
    forbid(monkeypatch, "hairinv.dynamics.run.BodyMesh.from_mesh", "building the body's search tree")
    frames = run_scene(scene.helices, group, scene.contacts, scene.body, removed_scene, s, seconds=0.05, fps=20)
    assert frames.body_removed and all(f.n_body == 0 for f in frames.log)
    assert frames.log[0].contacts == scene.contacts.n_hair
    # contacts.body off in a still scene: no body queries either
    off = dataclasses.replace(s, contacts=dataclasses.replace(s.contacts, body=False))
    hair_only = scene.contacts.strand[:, 1] >= 0
    group.datasets["force"] = model.force[hair_only]
    frames = run_scene(scene.helices, group, scene.contacts.subset(hair_only), scene.body, Scene.load("still"),
                       off, seconds=0.05, fps=20)
    assert all(f.n_body == 0 for f in frames.log)


def test_the_stage_files_record_what_was_modelled(tmp_path):
    """End to end: an inversion without gravity, hair-hair contact or a body writes a model that every
    command reads back (zero gravity is a valid /model), whose rest shape is the input, with its
    ``features`` attribute; a still simulation of it does not move and records its own."""
    model = tmp_path / "model.h5"
    run = subprocess.run([HAIRINV, "invert", str(GROOM), "--no-hair-hair", "--set", "material.gravity=0",
                          "-o", str(model)], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert "skipped: gravity (material.gravity = 0), hair-body contact (no body mesh given), hair-hair contact" \
        in run.stdout
    with h5py.File(model, "r") as fh:
        np.testing.assert_array_equal(fh["model/omega_rest"][()], fh["helices/omega"][()])
        assert fh["contacts/strand"].shape == (0, 2)
        recorded = json.loads(fh["model"].attrs["features"])
        assert recorded["skipped"].keys() == {"gravity", "body_contact", "hair_hair_contact", "friction"}
        assert json.loads(fh["contacts"].attrs["features"])["modelled"] == []
    frames = tmp_path / "frames.h5"
    run = subprocess.run([HAIRINV, "simulate", str(model), "--seconds",
                          "0.1", "-o", str(frames)], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert "skipped: gravity" in run.stdout and "body motion (the scene's body is fixed" in run.stdout
    with h5py.File(frames, "r") as fh:
        assert fh["frames/displacement"][()].max() == 0.0
        assert "trim" in json.loads(fh["frames"].attrs["features"])["skipped"]
    # verify says what its still simulation models, as simulate does
    run = subprocess.run([HAIRINV, "verify", str(model), "--seconds", "0.05"], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert "skipped: gravity" in run.stdout and "body motion (the scene's body is fixed" in run.stdout
    # info and the JSON summary say it too, per group
    run = subprocess.run([HAIRINV, "info", "--json", str(frames)], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    groups = json.loads(run.stdout)["groups"]
    assert groups["model"]["features"]["skipped"]["gravity"] == "material.gravity = 0"
    assert "hair_hair_contact" in groups["contacts"]["features"]["skipped"]
    assert groups["frames"]["features"]["skipped"]["trim"] == "the scene has no [trim]"
    text = subprocess.run([HAIRINV, "info", str(frames)], capture_output=True, text=True).stdout
    assert "skipped: gravity material.gravity = 0" in text
    # a file whose attribute is not what hairinv writes (another tool's) is summarised without it
    with h5py.File(frames, "r+") as fh:
        fh["frames"].attrs["features"] = "not json"
        fh["model"].attrs["features"] = json.dumps(["gravity"])
    run = subprocess.run([HAIRINV, "info", "--json", str(frames)], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    groups = json.loads(run.stdout)["groups"]
    assert "features" not in groups["frames"] and "features" not in groups["model"]
    assert "features" in groups["contacts"]


def test_detect_features_say_why():
    on = config.resolve().contacts
    assert detect_features(on, True).line() == "modelled: hair-body contact, hair-hair contact; skipped: nothing"
    assert detect_features(on, False).skipped == {"body_contact": "no body mesh given"}


def test_contacts_reused_from_the_file_model_what_their_detection_modelled(tmp_path):
    """``invert`` of a detected file without the body: the body contacts found against it are solved for, and
    the report and the model's ``features`` say so (with their friction); a file that does not record its
    contacts' features models body contact where it has some."""
    detected = tmp_path / "detected.h5"
    run = subprocess.run([HAIRINV, "detect", str(GROOM), str(BODY_FILE), "-o", str(detected)],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    with h5py.File(detected, "r") as fh:
        body_contacts = int(np.count_nonzero(fh["contacts/strand"][:, 1] < 0))
    assert body_contacts > 0
    for recorded in (True, False):
        if not recorded:
            with h5py.File(detected, "r+") as fh:
                del fh["contacts"].attrs["features"]
        model = tmp_path / f"model_{recorded}.h5"
        run = subprocess.run([HAIRINV, "invert", str(detected), "-o", str(model)], capture_output=True, text=True)
        assert run.returncode == 0, run.stderr
        assert f"({body_contacts} body" in run.stdout
        line = next(text for text in run.stdout.splitlines() if text.startswith("modelled:"))
        assert "hair-body contact" in line.split("; skipped:")[0] and "mu_body" in line, line
        with h5py.File(model, "r") as fh:
            assert "body_contact" in json.loads(fh["model"].attrs["features"])["modelled"]
