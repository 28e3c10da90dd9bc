"""The promise end to end, on a groom of a kind nobody tuned for: standing hair.

A generated mohawk (bench/grooms.py: spikes of strands rising from the head's
mid-line, leaning on each other), 60 guide strands, default settings: inverted,
it stays still for 2 s (``hairinv verify``); inverted with ``--stabilize off`` and
the declared friction used to the full (``solver.friction_reserve = 0``) it does
not, and the strands that move are among those stabilisation stiffens. (With the
friction reserve alone, the default 0.1, these spikes hold for the 2 s too: their
contacts stick, with a margin, where the stability check holds the forces fixed.)

Runtime: about 40 s warm (one groom generated, two inversions, two 2 s checks).
"""

from __future__ import annotations

import json
import subprocess
import sys

import h5py
import numpy as np
import pytest

from conftest import ROOT, hairinv
from hairinv import stages
from hairinv.gravity import generalized_gravity
from hairinv.inverse.stability import stability_margins
from hairinv.model import Contacts, Helices, material_from_group, rest_from_group, stiffening_from_group, stiffness
from hairinv.contacts.rows import contact_rows


@pytest.fixture(scope="module")
def mohawk(tmp_path_factory):
    folder = tmp_path_factory.mktemp("still")
    made = subprocess.run([sys.executable, str(ROOT / "bench" / "grooms.py"), "-o", str(folder), "mohawk"],
                          capture_output=True, text=True, timeout=600)
    assert made.returncode == 0, made.stderr
    return folder


@pytest.fixture(scope="module")
def inverted(mohawk):
    """The 60-guide mohawk inverted with the defaults (stiffened.h5), with --stabilize off and no friction
    reserve (off.h5), and with --stabilize off alone (unstiffened.h5); their printed reports."""
    reports = {}
    for name, extra in (("stiffened.h5", []),
                        ("off.h5", ["--stabilize", "off", "--set", "solver.friction_reserve=0"]),
                        ("unstiffened.h5", ["--stabilize", "off"])):
        result = hairinv(mohawk, "invert", "mohawk.h5", "mannequin.obj", "--guides", "60", *extra, "-o", name)
        assert result.returncode == 0, result.stderr
        reports[name] = result.stdout
    return mohawk, reports


def verify(folder, model):
    result = hairinv(folder, "verify", model, "mannequin.obj", "--seconds", "2", "--json")
    return result.returncode, json.loads(result.stdout)


def test_a_mohawk_inverted_with_the_defaults_stays_still_and_without_stiffening_does_not(inverted):
    mohawk, reports = inverted
    assert "every strand rests in a stable equilibrium" in reports["stiffened.h5"]
    assert "rest in an unstable equilibrium" in reports["off.h5"]
    with h5py.File(mohawk / "stiffened.h5", "r") as fh:
        factor = fh["model/stiffening"][()]
    with h5py.File(mohawk / "off.h5", "r") as fh:
        assert "stiffening" not in fh["model"]
    assert 0 < np.count_nonzero(factor > 1.0) < len(factor)
    code, still = verify(mohawk, "stiffened.h5")
    assert code == 0 and still["verdict"] == "PASS"
    assert still["seconds_simulated"] == pytest.approx(2.0)
    assert still["largest"]["displacement_m"] < 1e-4
    code, moved = verify(mohawk, "off.h5")
    assert code == 1 and moved["verdict"] == "FAIL"
    assert moved["n_moved"] > 0 and moved["stopped_early"]


def test_stiffened_strands_hold_under_their_forces_held_fixed_with_the_forces_kept(inverted):
    """Read back from the files: stiffening under the forces held fixed keeps the inversion's forces
    (bit for bit those of --stabilize off), the stiffened model is an exact equilibrium with them,
    K_a (q - q0_a) = F_g + H^T r, and with its factors every strand's Hessian, gravity's and the
    forces' own share included, is positive on every motion; with the material's own stiffness the
    strands where it is not are among those stiffened."""
    mohawk, _ = inverted
    groups = {name: stages.read_stage(mohawk / name) for name in ("stiffened.h5", "unstiffened.h5")}
    on, off = groups["stiffened.h5"], groups["unstiffened.h5"]
    force = np.asarray(on[stages.MODEL]["force"], dtype=np.float64)
    assert np.array_equal(force, np.asarray(off[stages.MODEL]["force"]))
    helices = Helices.from_group(on[stages.HELICES])
    contacts = Contacts.from_group(on[stages.CONTACTS])
    mat = material_from_group(on[stages.MODEL])
    factor = stiffening_from_group(on[stages.MODEL], helices.n_strands)
    assert factor is not None and np.any(factor > 1.0)
    rows = contact_rows(helices, contacts)
    load = generalized_gravity(helices, mat).ravel() + rows.rmatvec(force)
    K_a = stiffness(helices, mat, factor)
    q = helices.omega.ravel()
    residual = K_a * (q - rest_from_group(on[stages.MODEL]).ravel()) - load
    assert np.abs(residual).max() <= 1e-9 * np.abs(load).max()
    carrying = force[:, 0] > 0.0
    fixed = stability_margins(helices, mat, K_a, rows, contacts, carrying, force)[3]
    assert fixed.min() > 0.0
    plain = stability_margins(helices, mat, stiffness(helices, mat), rows, contacts, carrying, force)[3]
    assert np.any(plain < 0.0) and np.all(factor[plain < 0.0] > 1.0)
