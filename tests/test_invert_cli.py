"""``hairinv detect`` and ``hairinv invert`` end to end, checked from the files they write.

The model file is checked against the physics the stage-file contract states,
recomputed here from the file alone: stiffness from the material attributes,
the generalized gravity force and the contact Jacobians from the kernels
(both verified against finite differences of an independent energy and of
positions in tests/test_statics.py), assembled here contact by contact rather
than through hairinv.contacts.rows.

Runtime: about 30-60 s warm (three inversions of small grooms, one on sintel).
"""

from __future__ import annotations

import json
import shutil

import h5py
import numpy as np
import pytest

from conftest import SAMPLES, assert_refused, hairinv, real_path, snapshot
from hairinv import stages
from hairinv.rod.statics import gravity_forces, point_jacobian
from hairinv.testing import cone_violation

# The equilibrium holds by construction up to round-off of sums over a strand.
EQUILIBRIUM = 1e-8
# A force on its cone's boundary may leave it by round-off of the local solve.
CONE = 1e-10


def equilibrium_residual(path) -> tuple[float, float]:
    """``max |K (q - q0) - F_g - H^T r|`` relative to ``max |F_g|``, and the worst cone violation."""
    with h5py.File(path, "r") as fh:
        h, c, m = fh["helices"], fh["contacts"], fh["model"]
        root, frame0, offsets = h["root"][()], h["frame0"][()], h["offsets"][()]
        length, omega = h["length"][()], h["omega"][()]
        strand, s, frame, mu = c["strand"][()], c["s"][()], c["frame"][()], c["mu"][()]
        q0, r = m["omega_rest"][()], m["force"][()]
        E, G, rho, radius = (float(m.attrs[k]) for k in ("youngs_modulus", "shear_modulus", "density", "radius"))
        gravity = np.asarray(m.attrs["gravity"], float)
    I, J = np.pi * radius ** 4 / 4, np.pi * radius ** 4 / 2
    K = length[:, None] * np.array([E * I, E * I, G * J])
    lam = rho * np.pi * radius ** 2
    F_g = np.zeros_like(omega)
    for k in range(len(offsets) - 1):
        a, z = offsets[k], offsets[k + 1]
        gravity_forces(root[k], frame0[k], omega[a:z], length[a:z], lam, gravity, F_g[a:z])
    contact = np.zeros_like(omega)
    for i in range(len(mu)):
        world = frame[i].T @ r[i]  # the force on A; B gets the opposite
        for side, sign in ((0, 1.0), (1, -1.0)):
            k = strand[i, side]
            if k < 0:
                continue
            a, z = offsets[k], offsets[k + 1]
            jac = np.empty((z - a, 3, 3))
            point_jacobian(root[k], frame0[k], omega[a:z], length[a:z], s[i, side], jac)
            contact[a:z] += sign * jac @ world
    residual = K * (omega - q0) - F_g - contact
    cone = float(cone_violation(r, mu).max()) / np.abs(r).max() if len(r) else 0.0
    return np.abs(residual).max() / np.abs(F_g).max(), cone


@pytest.fixture(scope="module")
def inverted(tmp_path_factory):
    """``hairinv invert wavy.h5 body.obj --guides 30`` from curves: fit and detect run first."""
    folder = tmp_path_factory.mktemp("invert")
    shutil.copyfile(SAMPLES / "wavy.h5", folder / "wavy.h5")
    shutil.copyfile(SAMPLES / "body.obj", folder / "body.obj")
    result = hairinv(folder, "invert", "wavy.h5", "body.obj", "--guides", "30", "-o", "model.h5")
    return folder, result


def test_invert_runs_every_missing_stage(inverted):
    folder, result = inverted
    assert result.returncode == 0, result.stderr
    out = result.stdout
    for fragment in ("fitted 30 strands", "declared", "hair-body", "solver:", "rest shape", "wrote"):
        assert fragment in out
    stage = stages.read_stage(folder / "model.h5")
    assert list(stage.groups) == ["curves", "helices", "contacts", "model"]
    model = stage["model"]
    assert model.attrs["target"] == "actual"
    assert len(model["force"]) == len(stage["contacts"]["mu"]) > 0
    assert model["residual_history"].shape[1] == 2
    inputs = [entry["name"] for entry in model.inputs]
    assert inputs == ["wavy.h5", "body.obj"]


def test_interior_point_from_the_command_line(inverted):
    """--method interior-point: the report states the rest-shape bound, /model records it, the equilibrium
    holds as with the sweeps; the default (auto) took the interior point on this small groom."""
    folder, _ = inverted
    result = hairinv(folder, "invert", "model.h5", "body.obj", "--method", "interior-point", "-o", "ip.h5")
    assert result.returncode == 0, result.stderr
    assert "interior-point steps" in result.stdout and "of the optimum" in result.stdout
    with h5py.File(folder / "ip.h5", "r") as fh:
        attrs = dict(fh["model"].attrs)
        assert attrs["method"] == "interior-point" and attrs["interior_steps"] > 0
        assert 0.0 <= attrs["rest_bound"] <= 0.05 and attrs["status"] == "CONVERGED"
    residual, cone = equilibrium_residual(folder / "ip.h5")
    assert residual < EQUILIBRIUM and cone < CONE
    with h5py.File(folder / "model.h5", "r") as fh:
        assert fh["model"].attrs["method"] == "interior-point"
    sweeps = hairinv(folder, "invert", "model.h5", "body.obj", "--method", "sweeps", "-o", "sweeps.h5")
    assert sweeps.returncode == 0, sweeps.stderr
    with h5py.File(folder / "sweeps.h5", "r") as fh:
        attrs = dict(fh["model"].attrs)
        # the sweeps' own bound, met or the residual tolerance met
        assert attrs["method"] == "sweeps" and attrs["rest_bound"] >= 0.0
        assert attrs["status"] != "CONVERGED" or attrs["rest_bound"] <= 0.05 or attrs["relative_residual"] <= 1e-4
    assert "by the forces' duality gap" in sweeps.stdout
    # the input was a model: its forces are not a start for this method, and the report says so
    assert "starts afresh" in result.stdout and "started from the given forces" not in result.stdout


def test_inverted_model_is_an_equilibrium_inside_the_cones(inverted):
    folder, _ = inverted
    residual, cone = equilibrium_residual(folder / "model.h5")
    assert residual < EQUILIBRIUM
    assert cone < CONE


def test_detect_then_invert_reuses_the_stages(inverted):
    folder, _ = inverted
    before = snapshot(folder)
    result = hairinv(folder, "detect", "model.h5", "body.obj", "-o", "contacts.h5")
    assert result.returncode == 0, result.stderr
    assert "using the fitted helices" in result.stdout
    contacts = stages.read_stage(folder / "contacts.h5")
    assert list(contacts.groups) == ["curves", "helices", "contacts"]
    result = hairinv(folder, "invert", "contacts.h5", "body.obj", "-o", "again.h5", "--target", "zero")
    assert result.returncode == 0, result.stderr
    assert "using the fitted helices" in result.stdout and "contacts in contacts.h5" in result.stdout
    again = stages.read_stage(folder / "again.h5")
    assert again["model"].attrs["target"] == "zero"
    assert np.array_equal(again["contacts"]["point"], contacts["contacts"]["point"])
    residual, cone = equilibrium_residual(folder / "again.h5")
    assert residual < EQUILIBRIUM and cone < CONE
    for name, data in before.items():  # nothing given was touched
        assert (folder / name).read_bytes() == data


def test_gravity_only_baseline(inverted):
    folder, _ = inverted
    result = hairinv(folder, "invert", "model.h5", "body.obj", "-o", "gravity.h5", "--target", "gravity-only")
    assert result.returncode == 0, result.stderr
    with h5py.File(folder / "gravity.h5", "r") as fh:
        assert len(fh["contacts"]["mu"]) == len(fh["model"]["force"])
        assert not np.any(fh["model"]["force"][()])
    residual, _ = equilibrium_residual(folder / "gravity.h5")
    assert residual < EQUILIBRIUM
    summary = json.loads(hairinv(folder, "info", "gravity.h5", "--json").stdout)
    assert summary["stages"].endswith("model")


BAD = {
    "missing body": (["invert", "wavy.h5", "nobody.obj", "-o", "out.h5"], "nobody.obj", "no such file"),
    "body is not a mesh": (["invert", "wavy.h5", "notes.txt", "-o", "out.h5"], "notes.txt", ""),
    "unknown target": (["invert", "wavy.h5", "body.obj", "-o", "out.h5", "--set", "solver.target=best"],
                       "best", "target"),
    "negative gamma": (["invert", "wavy.h5", "body.obj", "-o", "out.h5", "--gamma", "-1"], "gamma", ""),
    "negative distance": (["detect", "wavy.h5", "body.obj", "-o", "out.h5", "--body-distance", "-0.1"],
                          "body_distance", ""),
    "output is the body": (["invert", "wavy.h5", "body.obj", "-o", "body.obj"], "body.obj", "input"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_input(tmp_path, case):
    args, name, fragment = BAD[case]
    shutil.copyfile(SAMPLES / "wavy.h5", tmp_path / "wavy.h5")
    shutil.copyfile(SAMPLES / "body.obj", tmp_path / "body.obj")
    (tmp_path / "notes.txt").write_text("precious\n")
    assert_refused(tmp_path, args, name, fragment)


def test_sintel_end_to_end(tmp_path):
    """The real sintel groom on its bust at 8 mm per unit (the data README's estimate)."""
    hair = real_path("sintel", "GEO-sintel_hair_emit.001-sintel_hair.tfx")
    body = real_path("sintel", "sintel.obj")
    result = hairinv(tmp_path, "invert", hair, body, "--scale", "0.008", "-o", "sintel.h5",
                     "--set", "solver.max_sweeps=300")
    assert result.returncode == 0, result.stderr
    assert "hair-body" in result.stdout
    with h5py.File(tmp_path / "sintel.h5", "r") as fh:
        assert len(fh["helices"]["offsets"]) - 1 == 228
        n_body = int((fh["contacts"]["strand"][:, 1] < 0).sum())
        assert n_body > 0
        assert np.any(fh["model"]["force"][:, 0] > 0)
    residual, cone = equilibrium_residual(tmp_path / "sintel.h5")
    assert residual < EQUILIBRIUM and cone < CONE


def test_output_piped_into_a_closed_reader_still_writes_the_file(inverted):
    """``hairinv detect ... | head -1``: the reader leaves early; the job still finishes."""
    import subprocess
    import sys

    from conftest import ENV

    folder, _ = inverted
    proc = subprocess.Popen([sys.executable, "-m", "hairinv_cli.main", "detect", "model.h5", "body.obj",
                             "-o", "piped.h5"], cwd=folder, env=ENV, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    proc.stdout.close()  # nobody reads: every print meets a broken pipe
    _, err = proc.communicate(timeout=600)
    assert proc.returncode == 0, err
    assert stages.read_stage(folder / "piped.h5").last_stage == "contacts"


def _objective(path) -> float:
    """``1/2 sum_e w_e |q0_e - t_e|^2 + gamma/2 |r|^2``, the inversion's objective, from the file alone; on
    strands stiffened for stability the forces minimise the stiffened problem's, whose rest shape is
    ``omega_rest_stiffened`` (docs/stage-files.md)."""
    with h5py.File(path, "r") as fh:
        m = fh["model"]
        rest = m["omega_rest_stiffened"][()] if "omega_rest_stiffened" in m else m["omega_rest"][()]
        dq = rest - m["omega_target"][()]
        r = m["force"][()]
        return float(0.5 * np.sum(m["target_weight"][()] * np.sum(dq ** 2, axis=1))
                     + 0.5 * float(m.attrs["gamma"]) * np.sum(r ** 2))


def test_inverting_a_model_again_starts_from_its_forces(inverted):
    """A run stopped at the sweep cap, inverted again, continues from its forces instead of from zero."""
    folder, _ = inverted
    cap = ("--set", "solver.max_sweeps=20", "--method", "sweeps")
    first = hairinv(folder, "invert", "model.h5", "body.obj", "-o", "short.h5", "--set", "solver.warm_start=false",
                    *cap)
    assert first.returncode == 0, first.stderr
    assert "starting from the forces" not in first.stdout
    again = hairinv(folder, "invert", "short.h5", "body.obj", "-o", "longer.h5", *cap)
    assert again.returncode == 0, again.stderr
    assert "starting from the forces of the model in short.h5 (20 sweeps, MAX_ITERS" in again.stdout
    with h5py.File(folder / "short.h5", "r") as a, h5py.File(folder / "longer.h5", "r") as b:
        assert a["model"].attrs["status"] == "MAX_ITERS"
        assert b["model"].attrs["prior_sweeps"] == 20 and a["model"].attrs["prior_sweeps"] == 0
        # the second run's first residual is the first run's last: it started from exactly those forces
        assert b["model"]["residual_history"][0, 1] == pytest.approx(float(a["model"].attrs["residual"]), rel=1e-9)
        assert b["model"]["residual_history"][0, 1] < a["model"]["residual_history"][0, 1]
    # the sweeps never raise the objective, so the continued run's is lower still
    assert _objective(folder / "longer.h5") < _objective(folder / "short.h5")
    residual, cone = equilibrium_residual(folder / "longer.h5")
    assert residual < EQUILIBRIUM and cone < CONE
    fresh = hairinv(folder, "invert", "short.h5", "body.obj", "-o", "fresh.h5", "--set", "solver.warm_start=false",
                    *cap)
    assert fresh.returncode == 0, fresh.stderr
    with h5py.File(folder / "short.h5", "r") as a, h5py.File(folder / "fresh.h5", "r") as c:
        assert np.array_equal(c["model"]["force"][()], a["model"]["force"][()])  # the same 20 sweeps from zero
        assert c["model"].attrs["prior_sweeps"] == 0
    # another problem (here another target): its forces are no start for this one
    other = hairinv(folder, "invert", "short.h5", "body.obj", "-o", "zero.h5", "--target", "zero", *cap)
    assert other.returncode == 0, other.stderr
    assert "inverted with another target: starting afresh" in other.stdout
    with h5py.File(folder / "zero.h5", "r") as z:
        assert z["model"].attrs["prior_sweeps"] == 0


def test_stored_contacts_that_do_not_fit_the_run_are_detected_again(inverted):
    """Contacts are reused only for the body they were detected against, and never from a gravity-only model."""
    folder, _ = inverted
    with h5py.File(folder / "model.h5", "r") as fh:
        declared = len(fh["contacts"]["mu"])
    result = hairinv(folder, "invert", "model.h5", "body.obj", "-o", "gravity.h5", "--target", "gravity-only")
    assert result.returncode == 0, result.stderr
    result = hairinv(folder, "invert", "gravity.h5", "body.obj", "-o", "from_gravity.h5",
                     "--set", "solver.max_sweeps=20")
    assert result.returncode == 0, result.stderr
    assert "belong to a gravity-only model, which declares none; detecting them again" in result.stdout
    assert "starting from the forces" not in result.stdout
    with h5py.File(folder / "from_gravity.h5", "r") as fh:
        assert len(fh["contacts"]["mu"]) == declared > 0
    moved = (folder / "body.obj").read_text() + "# the same mesh, another file\n"
    (folder / "body2.obj").write_text(moved)
    result = hairinv(folder, "invert", "model.h5", "body2.obj", "-o", "body2.h5", "--set", "solver.max_sweeps=20")
    assert result.returncode == 0, result.stderr
    assert "were detected against another body; detecting them again" in result.stdout
    assert "starting from the forces" not in result.stdout
    # without a body argument, the stored contacts (and the model's forces) are used as they are
    result = hairinv(folder, "invert", "model.h5", "-o", "no_body.h5", "--set", "solver.max_sweeps=20",
                     "--method", "sweeps")
    assert result.returncode == 0, result.stderr
    assert f"using the {declared} contacts in model.h5" in result.stdout
    assert "starting from the forces of the model in model.h5" in result.stdout
    # a file with contacts but no helices: the helices are fitted again, and the contacts with them
    stage = stages.read_stage(folder / "model.h5")
    stages.write_stage(folder / "no_helices.h5", [stage["curves"], stage["contacts"]], "test")
    result = hairinv(folder, "invert", "no_helices.h5", "body.obj", "-o", "refitted.h5", "--guides", "20",
                     "--set", "solver.max_sweeps=20")
    assert result.returncode == 0, result.stderr
    assert "belong to helices that are not in the file; detecting them again" in result.stdout
    residual, cone = equilibrium_residual(folder / "refitted.h5")
    assert residual < EQUILIBRIUM and cone < CONE
