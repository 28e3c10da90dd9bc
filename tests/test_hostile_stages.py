"""Hostile and inconsistent stage files: every command that reads one refuses it where it is read.

Each case copies a small valid model (``hairinv invert samples/settled.h5 samples/body.obj``: 40
strands, 337 elements, 168 contacts), breaks it with h5py, and runs the real CLI in a subprocess: exit
code 2, one line on stderr naming the file and the problem, no traceback, nothing written. Then a real
``hairinv`` killed with SIGKILL while it writes over an earlier output leaves that output as it was.

Runtime: about 30-50 s with a warm numba cache on two cores (the upper figure with other jobs on them):
one inversion and one detection (2-3 s), about 60 refusals (0.3-1.3 s each, interpreter start-up and
imports; four at a time), and three detections killed as they write (1-2 s each). The refusals run no
numerical kernel, but for a model edited in a way only its equilibrium shows (simulate and verify check it
with the statics kernels before they start).
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from types import SimpleNamespace
from pathlib import Path

import h5py
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from conftest import ENV, FINITE_DIFFERENCE, SAMPLES, UP, energy_gradient, hairinv, three_strands_on_the_body
from hairinv import config, stages
from hairinv.model import Material, stiffness
from hairinv.rod.helix import points_at

# The model's sizes (samples/settled.h5 inverted with its default settings on the sample body).
S = 40
HOSTILE = "hostile.h5"

#: Each command that reads a stage file, with ``F`` for the hostile file; ``valid.h5`` is the unbroken model.
COMMANDS = {
    "fit": ["fit", "F", "-o", "out.h5"],
    "detect": ["detect", "F", "body.obj", "-o", "out.h5"],
    "invert": ["invert", "F", "body.obj", "-o", "out.h5"],
    "simulate": ["simulate", "F", "body.obj", "--seconds", "0.1", "-o", "out.h5"],
    "verify": ["verify", "F", "body.obj", "--seconds", "0.1", "-o", "out.h5"],
    "export": ["export", "F", "-o", "out.obj"],
    "info": ["info", "F"],
    "diff": ["diff", "valid.h5", "F"],
    "status": ["status", "F"],  # the file's metadata only
    "status --check": ["status", "--check", "F"],
}

# Hypothesis: a handful of examples per family, the same ones on every run.
FEW = settings(max_examples=5, deadline=None, derandomize=True, database=None,
               suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])


@pytest.fixture(scope="module")
def valid(tmp_path_factory) -> Path:
    """A folder holding ``model.h5`` (curves, helices, contacts, model), ``frames.h5`` (the same with a
    hand-made two-frame ``/frames``) and ``body.obj``."""
    folder = tmp_path_factory.mktemp("hostile")
    for name in ("settled.h5", "body.obj"):
        shutil.copyfile(SAMPLES / name, folder / name)
    result = hairinv(folder, "invert", "settled.h5", "body.obj", "-o", "model.h5")
    assert result.returncode == 0, result.stderr
    shutil.copyfile(folder / "model.h5", folder / "frames.h5")
    with h5py.File(folder / "frames.h5", "r+") as fh:
        h = fh["helices"]
        frames = fh.create_group("frames")
        frames["time"] = np.array([0.0, 1 / 30])
        frames["omega"] = np.stack([h["omega"][()]] * 2)
        frames["root"] = np.stack([h["root"][()]] * 2)
        frames["frame0"] = np.stack([h["frame0"][()]] * 2)
        frames["body_transform"] = np.stack([np.eye(4)] * 2)
        frames["displacement"] = np.zeros(2)
        frames["strand_displacement"] = np.zeros((2, S))
        frames.attrs.update(fps=30.0, init="inverted", scene="still", trimmed=False, body_removed=False)
        frames.attrs["config"] = "{}"
        frames.attrs["inputs"] = "[]"
    with h5py.File(folder / "model.h5", "r") as fh:
        assert len(fh["helices/offsets"]) == S + 1 and len(fh["contacts/mu"]) > 0
    for name in ("model.h5", "frames.h5"):
        assert hairinv(folder, "info", name).returncode == 0
    return folder


# --------------------------------------------------------------------------- editing and running


def replace(fh, name: str, value) -> None:
    """Replace the dataset ``name`` by ``value`` (any dtype and shape)."""
    del fh[name]
    fh[name] = value


def edit(name: str, change):
    """An edit replacing the dataset ``name`` by ``change(a copy of its array)``."""
    def apply(fh):
        replace(fh, name, change(fh[name][()].copy()))
    return apply


def setitem(index, value):
    def change(a):
        a[index] = value
        return a
    return change


def set_attr(name: str, key: str, value):
    def apply(fh):
        fh[name].attrs[key] = value
    return apply


def first_hair_contact(fh) -> int:
    return int(np.flatnonzero(fh["contacts/strand"][()][:, 1] >= 0)[0])


def run_refused(valid: Path, source: str, apply, command: str, folder: Path | None = None, env: dict | None = None):
    """Copy ``source`` of ``valid`` as ``hostile.h5`` into a fresh folder, break it with ``apply(h5py file)``,
    run ``command`` on it (with ``env`` added to the environment); return (result, the folder's files before,
    after)."""
    folder = Path(folder or tempfile.mkdtemp(dir=valid))
    shutil.copyfile(valid / source, folder / HOSTILE)
    for name in ("body.obj", "model.h5"):
        os.link(valid / name, folder / (name if name != "model.h5" else "valid.h5"))
    with h5py.File(folder / HOSTILE, "r+") as fh:
        apply(fh)
    before = sorted(p.name for p in folder.iterdir())
    args = [HOSTILE if a == "F" else a for a in COMMANDS[command]]
    if env is None:
        result = hairinv(folder, *args)
    else:
        result = subprocess.run([sys.executable, "-m", "hairinv_cli.main", *args], cwd=folder, env={**ENV, **env},
                                capture_output=True, text=True, timeout=600)
    return result, before, sorted(p.name for p in folder.iterdir())


def check_refused(outcome, *fragments: str) -> str:
    """Exit 2, one line naming the hostile file with every fragment, no traceback, no file written."""
    result, before, after = outcome
    assert result.returncode == 2, (result.returncode, result.stdout[-2000:], result.stderr[-2000:])
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    line = lines[0]
    assert line.startswith(f"hairinv: error: {HOSTILE}: "), line
    for fragment in fragments:
        assert fragment in line, (fragment, line)
    assert "Traceback" not in result.stderr and "internal error" not in result.stderr
    assert "wrote" not in result.stdout
    assert after == before  # no output, no temporary file
    return line


# --------------------------------------------------------------------------- the cases

S_PAST_END = 10.0  # m beyond the strand's end


def _s_past_end(fh):
    s = fh["contacts/s"][()]
    s[0, 0] += S_PAST_END
    replace(fh, "contacts/s", s)


def _curves_one_strand_short(fh):
    offsets = fh["curves/offsets"][()]
    replace(fh, "curves/points", fh["curves/points"][()][:offsets[-2]])
    replace(fh, "curves/offsets", offsets[:-1])


def _hair_contact(value):
    def apply(fh):
        edit("contacts/strand", setitem((first_hair_contact(fh), 1), value))(fh)
    return apply


def _hair_contact_swapped(fh):
    i = first_hair_contact(fh)
    edit("contacts/strand", lambda a: np.concatenate([a[:i], a[i:i + 1, ::-1], a[i + 1:]]))(fh)


def _huge(name: str, shape):
    def apply(fh):
        del fh[name]
        fh.create_dataset(name, shape=shape, dtype="f8")  # declared, never written: nothing on disk
    return apply


def _delete(name: str):
    def apply(fh):
        del fh[name]
    return apply


def _delete_attr(name: str, key: str):
    def apply(fh):
        del fh[name].attrs[key]
    return apply


def _uint_strand(fh):
    a = fh["contacts/strand"][()].astype(np.uint64)
    a[first_hair_contact(fh), 1] = np.iinfo(np.uint64).max  # would read as -1, the body, cast to int64
    replace(fh, "contacts/strand", a)


def _element_beside(fh):
    """The first contact's element moved to the next element of the same strand, away from its arc length."""
    element = fh["contacts/element"][()]
    strand = int(fh["contacts/strand"][0, 0])
    offsets = fh["helices/offsets"][()]
    e = int(element[0, 0])
    element[0, 0] = e + 1 if e + 1 < offsets[strand + 1] else e - 1
    replace(fh, "contacts/element", element)


# id: (source file, edit, commands, fragments of the message)
CASES = {
    # the three bugs: heap corruption in invert, an internal error in simulate; silent acceptance; exit 1
    "contact strand index past S": (
        "model.h5", edit("contacts/strand", setitem((0, 0), S + 1)), ["invert", "simulate", "verify"],
        [f"/contacts/strand[0, 0] is {S + 1}", f"[0, {S})"]),
    "contact strand index S": (
        "model.h5", edit("contacts/strand", setitem((0, 0), S)), ["detect", "status --check"],
        [f"/contacts/strand[0, 0] is {S}"]),
    "contact arc length 10 m past its strand": (
        "model.h5", _s_past_end, ["invert", "simulate"], ["/contacts/s[0, 0] is", "off strand"]),
    "fewer forces than contacts": (
        "model.h5", edit("model/force", lambda a: a[:-5]), ["simulate", "invert", "status"],
        ["/model/force has shape", "expected", "contacts (/contacts/strand)"]),
    # contacts
    "side B below -1": ("model.h5", _hair_contact(-2), ["simulate"], ["/contacts/strand[", "side B must be -1"]),
    "side B past S": ("model.h5", _hair_contact(S), ["info"], ["side B must be -1 (the body) or a strand"]),
    "side B as unsigned -1": ("model.h5", _uint_strand, ["info"], ["/contacts/strand", "too large for an index"]),
    "hair contact with A above B": ("model.h5", _hair_contact_swapped, ["status --check"], ["lower strand on side A"]),
    "hair contact with itself": ("model.h5", lambda fh: _hair_contact(int(fh["contacts/strand"][first_hair_contact(
        fh), 0]))(fh), ["info"], ["lower strand on side A"]),
    "negative arc length": (
        "model.h5", edit("contacts/s", setitem((0, 0), -1e-3)), ["status --check"], ["/contacts/s[0, 0] is -0.001 m"]),
    "arc length on the body side": (
        "model.h5", edit("contacts/s", setitem((0, 1), 0.01)), ["info"], ["on a body contact", "must be 0"]),
    "contact element not on its strand": (
        "model.h5", edit("contacts/element", setitem((0, 0), -5)), ["simulate", "status --check"],
        ["/contacts/element[0, 0] is -5, not an element of strand"]),
    "contact element that does not hold its arc length": (
        "model.h5", _element_beside, ["verify"], ["/contacts/element[0, 0] is element", "but /contacts/s[0, 0] is"]),
    "contact element on the body side": (
        "model.h5", edit("contacts/element", setitem((0, 1), 3)), ["info"],
        ["/contacts/element[0, 1] is 3 on a body contact", "must be -1"]),
    "negative friction": ("model.h5", edit("contacts/mu", setitem(3, -0.3)), ["fit"], ["/contacts/mu[3]", ">= 0"]),
    # infinite friction is read (test_infinite_friction_is_read_and_inverted); NaN and -inf are not
    "nan friction": ("model.h5", edit("contacts/mu", setitem(2, np.nan)), ["invert"],
                     ["/contacts/mu[2] is nan", "no NaN and no -inf"]),
    "friction of -inf": ("model.h5", edit("contacts/mu", setitem(4, -np.inf)), ["info"], ["/contacts/mu[4] is -inf"]),
    "contact frame not orthonormal": (
        "model.h5", edit("contacts/frame", setitem((2, 0), [1.0, 1.0, 0.0])), ["fit"],
        ["/contacts/frame[2] is not an orthonormal frame"]),
    "contact arrays of different lengths": (
        "model.h5", edit("contacts/gap", lambda a: a[:-1]), ["diff", "status"], ["/contacts/gap has shape"]),
    "nan in the optional gaps": ("model.h5", edit("contacts/gap", setitem(7, np.nan)), ["info"],
                                 ["/contacts/gap[7] is nan"]),
    "contact strand as floats": (
        "model.h5", edit("contacts/strand", lambda a: a.astype(float)), ["simulate"],
        ["/contacts/strand has dtype float64, expected integer"]),
    "model without helices": ("model.h5", _delete("helices"), ["simulate", "status"],
                              ["has a /model group but no /helices"]),
    "contacts without helices, past S": (  # invert fits such a file again; its strand indices are still checked
        "model.h5", lambda fh: (_delete("helices")(fh), _delete("model")(fh),
                                edit("contacts/strand", setitem((0, 0), S + 1))(fh)),
        ["invert"], [f"/contacts/strand[0, 0] is {S + 1}", f"({S} strands in /curves)"]),
    # curves and helices
    "strand counts of curves and helices differ": (
        "model.h5", _curves_one_strand_short, ["export", "status"],
        [f"holds {S - 1} strands in /curves but {S} in /helices"]),
    "helix offsets past the elements": (
        "model.h5", edit("helices/offsets", setitem(-1, 10**12)), ["fit", "status"],
        ["/helices/offsets ends at 1000000000000"]),
    "helix offsets decreasing": (
        "model.h5", edit("helices/offsets", setitem(5, 0)), ["info"], ["/helices/offsets is not a valid CSR"]),
    "scalar offsets": ("model.h5", edit("curves/offsets", lambda a: np.int64(0)), ["fit"],
                       ["/curves/offsets has shape ()"]),
    "zero element length": (
        "model.h5", edit("helices/length", setitem(9, 0.0)), ["info"], ["/helices/length[9] is 0", "> 0"]),
    "left-handed root frame": (
        "model.h5", edit("helices/frame0", setitem(4, np.diag([1.0, 1.0, -1.0]))), ["simulate"],
        ["/helices/frame0[4] is a left-handed frame"]),
    # model
    "omega_rest of another groom": (
        "model.h5", edit("model/omega_rest", lambda a: a[:100]), ["status", "status --check"],
        ["/model/omega_rest has shape"]),
    "negative radius": ("model.h5", set_attr("model", "radius", -5e-5), ["simulate"], ["attribute radius is -5e-05"]),
    "radius as text": ("model.h5", set_attr("model", "radius", "thin"), ["verify", "status"],
                       ["attribute radius is 'thin'"]),
    "infinite Young's modulus": ("model.h5", set_attr("model", "youngs_modulus", np.inf), ["info"],
                                 ["attribute youngs_modulus is inf"]),
    "Young's modulus of 1e-300 Pa": ("model.h5", set_attr("model", "youngs_modulus", 1e-300), ["simulate"],
                                     ["attribute youngs_modulus is 1e-300", "from 1000 to 1e+14 Pa"]),
    "shear modulus of 0": ("model.h5", set_attr("model", "shear_modulus", 0.0), ["verify"],
                           ["attribute shear_modulus is 0.0", "from 100 to 1e+14 Pa"]),
    "gravity of 1e6 m/s^2": ("model.h5", set_attr("model", "gravity", np.array([0.0, -1e6, 0.0])), ["info"],
                             ["attribute gravity", "of length 0 or from 0.001 to 1000 m/s^2"]),
    "gravity not finite": ("model.h5", set_attr("model", "gravity", np.array([0.0, np.nan, 0.0])), ["info"],
                           ["attribute gravity"]),
    "missing material": ("model.h5", _delete_attr("model", "shear_modulus"), ["simulate", "status"],
                         ["/model lacks the attribute 'shear_modulus'"]),
    "unknown target": ("model.h5", set_attr("model", "target", "sideways"), ["info"], ["attribute target"]),
    "zero stiffening": ("model.h5", edit("model/stiffening", setitem(0, 0.0)), ["info"],
                        ["/model/stiffening[0] is 0"]),
    "nan stability margin": ("model.h5", edit("model/stability_margin", setitem(1, np.nan)), ["export"],
                             ["/model/stability_margin[1] is nan"]),
    "model without contacts": ("model.h5", _delete("contacts"), ["simulate"],
                               ["has shape", "C = 0 contacts (the file has no /contacts group)"]),
    # a model of the same layout that no longer holds its helices in equilibrium (eq. 4): edited after
    # the inversion (checked by simulate and verify, which start from it, with the statics kernels)
    "helices changed after the model was inverted": (
        "model.h5", edit("helices/omega", lambda a: a * 1.01), ["simulate", "verify"],
        ["/model does not hold /helices in equilibrium with its forces", "1/m from the one its forces give at element",
         "invert it again"]),
    "material changed after the model was inverted": (
        "model.h5", set_attr("model", "youngs_modulus", 7.0e9), ["verify"],
        ["/model does not hold /helices in equilibrium"]),
    "forces changed after the model was inverted": (
        "model.h5", edit("model/force", lambda a: a * 1.5), ["simulate"],
        ["/model does not hold /helices in equilibrium"]),
    # frames
    "frames going back in time": ("frames.h5", edit("frames/time", setitem(1, -1.0)), ["export"],
                                  ["/frames/time[1] is -1 s"]),
    "frames of another element layout": (
        "frames.h5", edit("frames/omega", lambda a: a[:, :-1]), ["diff", "status"], ["/frames/omega has shape"]),
    "body transform not rigid": (
        "frames.h5", edit("frames/body_transform", setitem((1, 3, 0), 1.0)), ["info"], ["not a rigid transform"]),
    "trimmed without a layout": ("frames.h5", set_attr("frames", "trimmed", True), ["export", "status"],
                                 ["trimmed = True"]),
    # the file as a whole
    "absurd declared size": ("model.h5", _huge("model/omega_target", (10**11, 3)), ["info", "status --check"],
                             ["GB of memory to read", "/model/omega_target"]),
    "absurd declared size, from its shape": ("model.h5", _huge("model/omega_target", (10**11, 3)), ["status"],
                                             ["/model/omega_target has shape (100000000000, 3)"]),
    "newer schema": ("model.h5", lambda fh: fh.attrs.__setitem__("schema_version", 99), ["status"],
                     ["schema 99", "upgrade hairinv"]),
    "schema version as text": ("model.h5", lambda fh: fh.attrs.__setitem__("schema_version", "one"), ["info"],
                               ["schema_version attribute that is not an integer"]),
    "config not JSON": ("model.h5", set_attr("contacts", "config", "{contacts"), ["simulate", "status"],
                        ["/contacts attribute config is not JSON"]),
    "inputs not records": ("model.h5", set_attr("model", "inputs", "[1, 2]"), ["verify"],
                           ["/model attribute inputs is not a JSON list of records"]),
    "command record without inputs' hashes": (
        "model.h5", lambda fh: fh.attrs.__setitem__("command", '{"subcommand": "invert", "inputs": [{"name": 1}]}'),
        ["status"], ["command attribute that has inputs that are not records"]),
    "dataset that is a group": ("model.h5", lambda fh: (_delete("model/force")(fh), fh.create_group("model/force")),
                                ["simulate", "status"], ["/model/force is not a dataset"]),
}

RUNS = [(case, command) for case, (_, _, commands, _) in CASES.items() for command in commands]


@pytest.fixture(scope="module")
def refusals(valid):
    """Every (case, command) of :data:`CASES` run, several at a time (each waits on a subprocess)."""
    def run(item):
        case, command = item
        source, apply, _, _ = CASES[case]
        return item, run_refused(valid, source, apply, command)

    with ThreadPoolExecutor(max_workers=4) as pool:  # the subprocesses' start-up takes the time
        return dict(pool.map(run, RUNS))


@pytest.mark.parametrize("case, command", RUNS, ids=[f"{command}: {case}" for case, command in RUNS])
def test_hostile_stage_file_is_refused(refusals, case, command):
    check_refused(refusals[(case, command)], *CASES[case][3])


@pytest.mark.parametrize("command", ["simulate", "verify"])
def test_a_body_refused_for_its_data_is_named_by_simulate_and_verify(valid, tmp_path, command):
    """A body of degenerate triangles only, given to a valid model, is refused in one line naming the body
    file (as detect and invert name it), exit 2, nothing written."""
    shutil.copyfile(valid / "model.h5", tmp_path / "model.h5")
    (tmp_path / "flat.obj").write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n")
    result = hairinv(tmp_path, command, "model.h5", "flat.obj", "--seconds", "0.1", "-o", "out.h5")
    assert result.returncode == 2, (result.stdout[-2000:], result.stderr[-2000:])
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hairinv: error: flat.obj: ") and "degenerate" in lines[0], lines
    assert not (tmp_path / "out.h5").exists() and "Traceback" not in result.stderr


@pytest.mark.parametrize("command", ["invert", "simulate"])
def test_no_numerical_kernel_runs_before_the_refusal(valid, tmp_path, command):
    """The contact index past S is refused before any numba kernel runs: with an empty numba cache folder,
    a kernel called would be compiled and written there (every kernel is cached); the folder stays empty."""
    cache = tmp_path / "numba-cache"
    cache.mkdir()
    check_refused(run_refused(valid, "model.h5", edit("contacts/strand", setitem((0, 0), S + 1)), command,
                              env={"NUMBA_CACHE_DIR": str(cache)}), "/contacts/strand[0, 0]")
    assert [p for p in cache.rglob("*") if p.is_file()] == []


def test_status_without_check_does_not_read_the_values(valid):
    """``status`` checks what the metadata shows: a wrong value in an array of the right shape (an arc length
    off its strand) is found by ``status --check``, which reads the arrays, and plain ``status`` says it did
    not read them."""
    result, before, after = run_refused(valid, "model.h5", _s_past_end, "status")
    assert result.returncode == 0 and after == before, result.stderr
    assert result.stdout.strip() == f"{HOSTILE}: current (its arrays were not read; --check checks them too)"
    check_refused(run_refused(valid, "model.h5", _s_past_end, "status --check"), "/contacts/s[0, 0] is", "off strand")


# --------------------------------------------------------------------------- infinite friction, accepted


def _sticking_scene(path: Path) -> tuple:
    """A stage file of three strands resting on 10 body contacts of infinite friction (conftest's scene),
    with the default settings' records, so that ``invert`` uses its contacts: (helices, contacts)."""
    helices, contacts = three_strands_on_the_body(np.inf)
    settings = config.resolve("default")
    points, offsets = [], [0]
    for k in range(helices.n_strands):
        a, z = helices.offsets[k], helices.offsets[k + 1]
        s = np.linspace(0.0, helices.length[a:z].sum(), 13)
        out = np.empty((len(s), 3))
        points_at(helices.root[k], helices.frame0[k], helices.omega[a:z], helices.length[a:z], s, out)
        points.append(out)
        offsets.append(offsets[-1] + len(s))
    curves = stages.Group(stages.CURVES, {"points": np.concatenate(points), "offsets": np.array(offsets)},
                          attrs={"up": UP, "scale_to_m": 1.0, "source": "made by the test"})
    stages.write_stage(path, [curves, helices.group(settings.fit, []), contacts.group(settings.contacts, [])], "test")
    return helices, contacts


def test_infinite_friction_is_read_and_inverted(tmp_path):
    """mu = inf (a sticking contact: the half-space r_N >= 0, which the solver handles) is read, inverted by
    the real CLI from the file's own contacts, and summarised as valid JSON."""
    helices, contacts = _sticking_scene(tmp_path / "scene.h5")
    assert np.all(stages.read_stage(tmp_path / "scene.h5")["contacts"]["mu"] == np.inf)
    result = hairinv(tmp_path, "invert", "scene.h5", "-o", "model.h5")
    assert result.returncode == 0, result.stderr
    assert f"using the {contacts.n_contacts} contacts in scene.h5" in result.stdout
    stage = stages.read_stage(tmp_path / "model.h5")
    assert np.all(stage["contacts"]["mu"] == np.inf)
    model = stage["model"]
    force = model["force"]
    assert model.attrs["status"] == "CONVERGED" and np.all(np.isfinite(force)) and np.all(force[:, 0] >= 0.0)
    assert np.count_nonzero(force[:, 0] > model.attrs["carrying_threshold"]) > 0
    # the model is an equilibrium of the material it records, under its forces (central differences of the energy)
    mat = Material(*(model.attrs[k] for k in ("youngs_modulus", "shear_modulus", "density", "radius")),
                   np.asarray(model.attrs["gravity"]))
    grad, weight = energy_gradient(helices, contacts, SimpleNamespace(force=force, omega_rest=model["omega_rest"]),
                                   mat)
    load = np.abs(stiffness(helices, mat) * (helices.omega - model["omega_rest"]).ravel()).max()
    assert np.abs(grad).max() <= FINITE_DIFFERENCE * max(weight, load)
    summary = hairinv(tmp_path, "export", "model.h5", "-o", "model.json")
    assert summary.returncode == 0, summary.stderr
    groups = json.loads((tmp_path / "model.json").read_text())["groups"]  # strict JSON: no Infinity
    assert groups["contacts"]["mu_infinite"] == contacts.n_contacts and groups["contacts"]["mu"] is None


# --------------------------------------------------------------------------- families (hypothesis)


def _count_sized(fh) -> list[str]:
    """The datasets of a model file whose rows are counted by the file (not ``residual_history``)."""
    out = []
    for group, layout in stages.LAYOUT.items():
        for key, (_, dims) in layout.items():
            if group in fh and key in fh[group] and dims[0] != "n" and len(fh[group][key]) > 0:
                out.append(f"{group}/{key}")
    return out


@FEW
@given(data=st.data())
def test_out_of_range_contact_index(valid, data):
    with h5py.File(valid / "model.h5", "r") as fh:
        strand = fh["contacts/strand"][()]
    side = data.draw(st.sampled_from([0, 1]), label="side")
    row = data.draw(st.integers(0, len(strand) - 1), label="row")
    low = -2 if side == 1 else -1
    value = data.draw(st.one_of(st.integers(S, 2**62), st.integers(-2**62, low)), label="value")
    command = data.draw(st.sampled_from(["invert", "simulate", "info"]), label="command")
    check_refused(run_refused(valid, "model.h5", edit("contacts/strand", setitem((row, side), value)), command),
                  f"/contacts/strand[{row}, {side}] is {value}")


@FEW
@given(data=st.data())
def test_truncated_dataset(valid, data):
    with h5py.File(valid / "frames.h5", "r") as fh:
        names = _count_sized(fh)
        name = data.draw(st.sampled_from(names), label="dataset")
        shape = fh[name].shape
    axis = data.draw(st.integers(0, len(shape) - 1), label="axis")
    keep = data.draw(st.integers(0, shape[axis] - 1), label="keep")
    command = data.draw(st.sampled_from(["info", "fit", "status"]), label="command")
    cut = (slice(None),) * axis + (slice(0, keep),)
    check_refused(run_refused(valid, "frames.h5", edit(name, lambda a: a[cut]), command), f"/{name}")


@FEW
@given(data=st.data())
def test_non_finite_number(valid, data):
    with h5py.File(valid / "frames.h5", "r") as fh:
        names = [n for n in _count_sized(fh) if fh[n].dtype.kind == "f"]
        name = data.draw(st.sampled_from(names), label="dataset")
        shape = fh[name].shape
    index = tuple(data.draw(st.integers(0, n - 1), label=f"index {k}") for k, n in enumerate(shape))
    allowed = [np.nan, -np.inf] + ([] if tuple(name.split("/")) in stages.MAY_BE_INFINITE else [np.inf])
    value = data.draw(st.sampled_from(allowed), label="value")
    command = data.draw(st.sampled_from(["info", "fit", "status --check"]), label="command")
    check_refused(run_refused(valid, "frames.h5", edit(name, setitem(index, value)), command),
                  f"/{name}{list(index)} is {value}")


# --------------------------------------------------------------------------- a run killed while it writes

# Runs the real CLI with two seams in third-party calls, to stop it at a chosen moment of its write: the
# third dataset written (the temporary file holds part of the stage file, flushed to disk), or the rename
# of the complete temporary file over the output. There it creates MARKER and waits to be killed.
PAUSED = r"""
import os, sys, time
import h5py

mode, marker = sys.argv[1], sys.argv[2]
real_create, real_replace, made = h5py.Group.create_dataset, os.replace, []


def pause():
    open(marker, "w").close()
    time.sleep(600)


def create_dataset(self, *args, **kwargs):
    dataset = real_create(self, *args, **kwargs)
    made.append(dataset.name)
    if mode == "mid-write" and len(made) == 3:
        self.file.flush()
        pause()
    return dataset


def replace(src, dst, *args, **kwargs):
    if mode == "before-rename":
        pause()
    return real_replace(src, dst, *args, **kwargs)


h5py.Group.create_dataset = create_dataset
os.replace = replace
from hairinv_cli.main import main

sys.argv = ["hairinv", *sys.argv[3:]]
main()
"""

WRITE = ["detect", "model.h5", "body.obj", "-o", "out.h5"]  # reuses the model's contacts: no detection to wait for


@pytest.fixture(scope="module")
def previous(valid, tmp_path_factory) -> Path:
    """A folder with the model, the body and ``out.h5``, the output of an earlier run of :data:`WRITE`."""
    folder = tmp_path_factory.mktemp("killed")
    for name in ("model.h5", "body.obj"):
        shutil.copyfile(valid / name, folder / name)
    result = hairinv(folder, *WRITE)
    assert result.returncode == 0, result.stderr
    return folder


def _temporaries(folder: Path) -> list[Path]:
    return sorted(folder.glob(".out.h5.*.tmp"))


def _kill(process: subprocess.Popen) -> None:
    os.kill(process.pid, signal.SIGKILL)
    process.wait(timeout=30)
    assert process.returncode == -signal.SIGKILL


@pytest.mark.parametrize("moment", ["mid-write", "before-rename"])
def test_killed_while_writing_leaves_the_previous_output(previous, tmp_path, moment):
    folder = tmp_path
    for name in ("model.h5", "body.obj", "out.h5"):
        shutil.copyfile(previous / name, folder / name)
    before = (folder / "out.h5").read_bytes()
    marker = folder / "paused"
    process = subprocess.Popen([sys.executable, "-c", PAUSED, moment, str(marker), *WRITE], cwd=folder, env=ENV,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while not marker.exists():
            assert process.poll() is None, "the run ended before it wrote"
            assert time.monotonic() < deadline, "the run never reached its write"
            time.sleep(0.01)
        assert _temporaries(folder), "the write goes through a temporary file beside the output"
    finally:
        _kill(process)
    assert (folder / "out.h5").read_bytes() == before
    stage = stages.read_stage(folder / "out.h5")
    assert list(stage.groups) == ["curves", "helices", "contacts"]
    # the killed run's temporary file stays (nothing runs after SIGKILL), beside the output, not over it,
    # named by the process that wrote it ...
    assert [p.name.startswith(f".out.h5.hairinv-{process.pid}-") for p in _temporaries(folder)] == [True]
    # ... and the next run writing the same output removes it
    again = hairinv(folder, *WRITE)
    assert again.returncode == 0, again.stderr
    assert _temporaries(folder) == []
    assert stages.read_stage(folder / "out.h5").producer.endswith(" detect")
    assert sorted(p.name for p in folder.iterdir()) == ["body.obj", "model.h5", "out.h5", "paused"]


def _paused(folder: Path, moment: str) -> tuple[subprocess.Popen, Path]:
    """:data:`WRITE` run in ``folder`` and stopped at ``moment`` of its write (:data:`PAUSED`), still running;
    its temporary file."""
    marker = folder / f"paused-{moment}"
    process = subprocess.Popen([sys.executable, "-c", PAUSED, moment, str(marker), *WRITE], cwd=folder, env=ENV,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 120
    while not marker.exists():
        if process.poll() is not None or time.monotonic() > deadline:
            if process.poll() is None:
                _kill(process)
            pytest.fail("the run never reached its write")
        time.sleep(0.01)
    mine = [p for p in _temporaries(folder) if p.name.startswith(f".out.h5.hairinv-{process.pid}-")]
    assert len(mine) == 1
    return process, mine[0]


def test_a_live_writers_temporary_is_not_removed(previous, tmp_path):
    """A run that writes the output while another is still writing it leaves the other's temporary file alone
    (it would break a write in progress); once that writer is killed, the next run removes it."""
    folder = tmp_path
    for name in ("model.h5", "body.obj", "out.h5"):
        shutil.copyfile(previous / name, folder / name)
    writing, live = _paused(folder, "mid-write")
    try:
        inode, size = os.stat(live).st_ino, os.stat(live).st_size
        assert size > 0  # the datasets written so far, flushed
        other = hairinv(folder, *WRITE)
        assert other.returncode == 0, other.stderr
        assert _temporaries(folder) == [live] and os.stat(live).st_ino == inode and os.stat(live).st_size == size
        assert writing.poll() is None
    finally:
        _kill(writing)
    assert live.exists()  # nothing runs after SIGKILL
    again = hairinv(folder, *WRITE)
    assert again.returncode == 0, again.stderr
    assert _temporaries(folder) == [] and stages.read_stage(folder / "out.h5").producer.endswith(" detect")


def test_killed_as_soon_as_the_write_starts(previous, tmp_path):
    """The unmodified CLI, killed the moment its temporary file appears: the output is the previous one or
    a complete new one, never a part."""
    folder = tmp_path
    for name in ("model.h5", "body.obj", "out.h5"):
        shutil.copyfile(previous / name, folder / name)
    before = (folder / "out.h5").read_bytes()
    process = subprocess.Popen([sys.executable, "-m", "hairinv_cli.main", *WRITE], cwd=folder, env=ENV,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while not _temporaries(folder) and process.poll() is None:
            assert time.monotonic() < deadline, "the run never reached its write"
            time.sleep(0.0005)
    finally:
        if process.poll() is None:
            _kill(process)
    after = (folder / "out.h5").read_bytes()
    stage = stages.read_stage(folder / "out.h5")
    assert after == before or stage.producer.endswith(" detect")
    assert list(stage.groups) == ["curves", "helices", "contacts"]
