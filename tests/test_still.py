"""The promise end to end, on a groom of a kind nobody tuned for: standing hair.

A generated mohawk (bench/grooms.py: spikes of strands rising from the head's
mid-line, leaning on each other), 60 guide strands, default settings: inverted,
it stays still for 2 s (``hairinv verify``); inverted with ``--stabilize off`` it
does not, and the strands that move are among those stabilisation stiffens.

Runtime: about 40 s warm (one groom generated, two inversions, two 2 s checks).
"""

from __future__ import annotations

import json
import subprocess
import sys

import h5py
import numpy as np
import pytest

from conftest import ROOT
from test_cli import hairinv


@pytest.fixture(scope="module")
def mohawk(tmp_path_factory):
    folder = tmp_path_factory.mktemp("still")
    made = subprocess.run([sys.executable, str(ROOT / "bench" / "grooms.py"), "-o", str(folder), "mohawk"],
                          capture_output=True, text=True, timeout=600)
    assert made.returncode == 0, made.stderr
    return folder


def verify(folder, model):
    result = hairinv(folder, "verify", model, "mannequin.obj", "--seconds", "2", "--json")
    return result.returncode, json.loads(result.stdout)


def test_a_mohawk_inverted_with_the_defaults_stays_still_and_without_stiffening_does_not(mohawk):
    reports = {}
    for name, extra in (("stiffened.h5", []), ("off.h5", ["--stabilize", "off"])):
        result = hairinv(mohawk, "invert", "mohawk.h5", "mannequin.obj", "--guides", "60", *extra, "-o", name)
        assert result.returncode == 0, result.stderr
        reports[name] = result.stdout
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
