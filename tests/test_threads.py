"""A simulation gives the same answer, bit for bit, on one thread and on two: every parallel phase of a
step writes only its own strands' or contacts' rows, and the contact solve's order does not depend on the
thread count."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import SAMPLES
from hairinv import config
from hairinv.contacts.body import BodyMesh
from hairinv.dynamics.simulate import Motion, Simulation
from hairinv.model import Material
from hairinv.pipeline import prepare


@pytest.fixture(scope="module")
def scene():
    """150 curly guides on the sample bust with hair-hair contact: more strands than a chunk of the free
    motion (64) and more contacts than a chunk of the rows (256)."""
    settings = config.apply(config.resolve(), {"import": {"guides": 150}, "contacts": {"hair_hair": True}})
    prepared = prepare(SAMPLES / "curly.h5", SAMPLES / "body.obj", settings)
    assert prepared.helices.n_strands == 150 and prepared.contacts.n_contacts > 256
    assert prepared.contacts.n_hair > 0
    return settings, prepared


def _run(scene, monkeypatch, threads: str) -> tuple[np.ndarray, np.ndarray, list]:
    """The naive model (the groom's own shape at rest: it sags onto itself and the body) under a head
    turn, 6 steps."""
    settings, prepared = scene
    monkeypatch.setenv("HAIRINV_THREADS", threads)
    mat = Material.from_settings(settings.material, prepared.up)
    sim = Simulation(prepared.helices, prepared.helices.omega.copy(), mat, BodyMesh.from_mesh(prepared.body),
                     settings.contacts, settings.dynamics, initial=prepared.contacts)
    turning = Motion(mat.gravity, spin=np.array([0.0, 1.5, 0.0]), spin_rate=np.array([0.0, 10.0, 0.0]))
    reports = [sim.step(turning) for _ in range(6)]
    return sim.q.copy(), sim.v.copy(), [(r.contacts, r.sweeps, r.substeps) for r in reports]


def test_one_thread_and_two_give_the_same_motion(scene, monkeypatch):
    q1, v1, r1 = _run(scene, monkeypatch, "1")
    q2, v2, r2 = _run(scene, monkeypatch, "2")
    assert np.abs(q1 - scene[1].helices.omega).max() > 1e-3  # it moved
    assert r1 == r2 and any(sweeps > 0 for _, sweeps, _ in r1)  # the contact solve ran
    assert np.array_equal(q1, q2) and np.array_equal(v1, v2)
