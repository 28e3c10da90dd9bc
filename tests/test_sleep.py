"""Sleeping strands (hairinv.dynamics.sleep): a still run with sleeping is the run without it, stopped;
a sleeping island wakes when the body's motion changes, when the body moves near it, and when a strand
hits it; each time the run goes on as the run in which nothing sleeps.
"""

from __future__ import annotations

import dataclasses
import shutil

import numpy as np
import pytest
import trimesh

from conftest import SAMPLES, hairinv, horizontal_strand, material, strands
from hairinv import simulation
from hairinv.config import Settings, Sources
from hairinv.contacts import detect_contacts
from hairinv.contacts.body import BodyMesh
from hairinv.dynamics.simulate import Motion, Simulation
from hairinv.dynamics.skin import Binding, SkinnedBody
from hairinv.dynamics.sleep import SLEEP_STEPS, islands
from hairinv.invert import invert
from hairinv.rod.helix import strand_points


def _points(helices, q, per=9):
    S = helices.n_strands
    strand = np.repeat(np.arange(S), per)
    total = np.add.reduceat(helices.length, helices.offsets[:-1])
    s = np.tile(np.linspace(0.0, 1.0, per), S) * total[strand]
    return strand_points(helices.root, helices.frame0, helices.offsets, q, helices.length, strand, s).reshape(S, per, 3)


def _box(extents, center):
    box = trimesh.creation.box(extents=extents)
    box.apply_translation(center)
    return box


def test_islands_are_the_components_of_the_hair_hair_contacts():
    pair = np.array([[0, 1], [1, 2], [3, -1], [4, 5], [2, -1]])
    label = islands(7, pair)
    assert label[0] == label[1] == label[2]
    assert len({label[0], label[3], label[4], label[6]}) == 4 and label[4] == label[5]


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    """``hairinv invert settled_curly.h5 body.obj``: 40 curly strands at rest, with hair-hair contacts."""
    folder = tmp_path_factory.mktemp("sleep")
    shutil.copyfile(SAMPLES / "settled_curly.h5", folder / "settled_curly.h5")
    shutil.copyfile(SAMPLES / "body.obj", folder / "body.obj")
    result = hairinv(folder, "invert", "settled_curly.h5", "body.obj", "-o", "model.h5")
    assert result.returncode == 0, result.stderr
    return folder


def test_a_still_run_with_sleeping_is_the_run_without_it(model, monkeypatch):
    """The still scene for 0.5 s: every strand falls asleep after ``SLEEP_STEPS`` steps at rest, and from
    then on no step builds a contact row; every frame's shape is the one of the run where nothing
    sleeps, to round-off, and so are the contacts it reports."""
    import hairinv.dynamics.simulate as simulate

    def run(speed):
        return simulation.simulate(model / "model.h5", scene="still", seconds=0.5,
                                   sources=Sources(sets=(f"dynamics.sleep_speed={speed}",)))

    awake = run(0)
    rows = []
    real = simulate.contact_rows
    monkeypatch.setattr(simulate, "contact_rows", lambda *a, **k: rows.append(1) or real(*a, **k))
    asleep = run(1e-6)
    steps = int(round(0.5 / 0.01))
    assert len(rows) <= SLEEP_STEPS + 2 < steps  # the steps before the groom slept (and the warm-up's)
    helices = awake.helices
    a, b = awake.frames, asleep.frames
    assert a.omega.shape == b.omega.shape
    for qa, qb in zip(a.omega, b.omega):
        assert np.max(np.linalg.norm(_points(helices, qa) - _points(helices, qb), axis=2)) < 1e-12
    count = [[f.contacts for f in frames.log] for frames in (a, b)]
    assert count[0] == count[1] and count[0][-1] > 0


def _two_strands_on_a_floor(above=1e-3):
    """Strand A lies along x ``above`` (m) a floor, inverted with its contacts: at rest. Strand B, 0.2 m long, rooted
    30 mm above A and crossing it 0.12 m from its root (along z), straight at rest: it falls onto A and the floor.

    Every contact solve runs to the tolerance (``dynamics.stall_rounds`` 0): a solve stopped on a stall ends
    wherever its rounds were, and two runs a round-off apart may stop in different places (with one stalled round,
    one step of 40 ends above the tolerance in one run and not in the other, and they end 0.57 um apart), which
    is not what these tests compare. At most 50 sweeps a step, as when these tests were written: with 200 (the
    default since 2026-12-08) the two runs of the first test end 17 nm apart."""
    helices = strands([horizontal_strand(n=6, total=0.12),
                       (np.array([0.06, 0.03, -0.12]), (0.0, 0.0, 1.0), np.zeros((8, 3)), np.full(8, 0.025))])
    floor = _box((1.0, 0.2, 1.0), (0.3, -0.1 - above, 0.0))
    body = BodyMesh.from_mesh(floor)
    settings = Settings()
    contacts, _ = detect_contacts(helices, body, settings.contacts)
    assert set(contacts.strand[:, 0]) == {0} and np.all(contacts.strand[:, 1] < 0)
    mat = material()
    model, _ = invert(helices, contacts, mat, settings.solver)
    rest = helices.omega.copy()
    a = slice(helices.offsets[0], helices.offsets[1])
    rest[a] = model.omega_rest[a]

    def sim(speed):
        return Simulation(helices, rest, mat, body, settings.contacts,
                          dataclasses.replace(settings.dynamics, sleep_speed=speed, stall_rounds=0, max_sweeps=50),
                          initial=contacts,
                          initial_force=model.force)
    return helices, mat, sim


def test_a_sleeping_strand_wakes_when_a_falling_strand_hits_it():
    """A is asleep before B reaches it; B's first contact with A wakes A in that very step, B pushes on A,
    and the run is the run without sleeping. A lies 3 mm above the floor, so that B comes to rest on it (with
    A 1 mm above, B rests on the floor beside it and touches A for at most a step, with or without a force)."""
    helices, mat, make = _two_strands_on_a_floor(above=3e-3)
    sleepy, awake = make(1e-6), make(0.0)
    a_asleep, touched, load = [], [], []
    for _ in range(40):
        sleepy.step(Motion.still(mat.gravity))
        awake.step(Motion.still(mat.gravity))
        a_asleep.append(bool(sleepy.sleepers.asleep[0]))
        pair = sleepy.contacts.strand
        touched.append(bool(np.any((pair[:, 0] + pair[:, 1] == 1) & (pair[:, 1] >= 0))))
        hair = awake.tracker.pair[:, 1] >= 0
        load.append(float(np.abs(awake.tracker.impulse[hair]).max(initial=0.0)))
    hit = touched.index(True)
    assert a_asleep[SLEEP_STEPS] and all(a_asleep[SLEEP_STEPS:hit])  # asleep until the hit
    assert not a_asleep[hit] and sleepy.sleepers.woken >= 1
    assert not sleepy.sleepers.asleep[1]  # B never slept: it was falling
    assert sum(f > 0 for f in load[hit:]) >= 10  # B pushes on A, and rests on it
    assert np.max(np.linalg.norm(_points(helices, sleepy.q) - _points(helices, awake.q), axis=2)) < 1e-8


def test_a_strand_falling_onto_another_faster_than_the_contact_distance_a_step_lands_on_it(monkeypatch):
    """B falls onto A at up to 0.8 m/s, 8 mm a step, eight times ``hair_distance``, in whole steps (no halving:
    ``max_turn`` 10 rad): the pair is searched as far as B's own motion over the step reaches, so B lands on A
    and rests there, above it where they cross. With the strands' own motion left out of the search (the
    detection of the step's start alone), B passes through A to the floor. The same where the fast pairs take a
    second search (``ContactTracker._swept``: a whole detection under the wisp rule, which takes no per-strand
    reach)."""
    from hairinv.dynamics import tracking
    from hairinv.dynamics.tracking import ContactTracker

    def crossing(make, limit_own: bool, second_search: bool = False):
        if limit_own:
            monkeypatch.setattr(ContactTracker, "own_sweep", lambda self, state, h: np.zeros(len(self.own)))
        helices, mat, sim_of = make
        sim = sim_of(0.0)
        sim.settings = dataclasses.replace(sim.settings, max_turn=10.0)
        searched = []
        if second_search:  # every detection whole, under rules with the wisp rule
            monkeypatch.setattr(tracking, "_PARTIAL_SHARE", 0.0)
            sim.tracker.detect_settings = dataclasses.replace(sim.tracker.detect_settings, wisp=True)
            swept = ContactTracker._swept

            def counted(self, h, fresh, redone, reach):
                out = swept(self, h, fresh, redone, reach)
                searched.append(out.n_contacts > fresh.n_contacts)
                return out
            monkeypatch.setattr(ContactTracker, "_swept", counted)
        above, farthest = [], 0.0
        pb_last = _points(helices, sim.q, per=33)[1]
        for _ in range(40):
            sim.step(Motion.still(mat.gravity))
            pa, pb = _points(helices, sim.q, per=33)
            farthest = max(farthest, float(np.linalg.norm(pb - pb_last, axis=1).max()))
            pb_last = pb
            # where B crosses A's line (z = 0), its height above A's point at the same x
            k = int(np.argmin(np.abs(pb[:, 2])))
            j = int(np.argmin(np.abs(pa[:, 0] - pb[k, 0])))
            above.append(pb[k, 1] - pa[j, 1])
        monkeypatch.undo()
        if second_search:
            assert any(searched)  # the second search found pairs the first had not
        return np.array(above), sim, farthest

    made = _two_strands_on_a_floor(above=3e-3)
    above, sim, farthest = crossing(made, limit_own=False)
    assert farthest > 5 * Settings().contacts.hair_distance  # B's points move that far in a step
    hair = sim.tracker.pair[:, 1] >= 0
    assert np.all(above > 0.0)  # B never passes below A where they cross
    assert np.abs(sim.tracker.impulse[hair]).max(initial=0.0) > 0.0  # and rests on it, pressing on it
    assert above[-1] < 2e-3  # (down on A: the two radii apart, not held up in the air)
    through, _, _ = crossing(_two_strands_on_a_floor(above=3e-3), limit_own=True)
    assert through[-1] < 0.0  # without the sweep: through A
    above, sim, _ = crossing(_two_strands_on_a_floor(above=3e-3), limit_own=False, second_search=True)
    assert np.all(above > 0.0) and above[-1] < 2e-3


def test_a_sleeping_strand_wakes_when_the_motion_changes():
    """Asleep under a still body; the body starts to turn: every strand wakes in that step, and follows
    the run without sleeping."""
    helices, mat, make = _two_strands_on_a_floor()
    # B alone: A is what sleeps
    sleepy, awake = make(1e-6), make(0.0)
    still = Motion.still(mat.gravity)
    for _ in range(SLEEP_STEPS + 2):
        sleepy.step(still)
        awake.step(still)
    assert sleepy.sleepers.asleep[0]
    turning = Motion(mat.gravity, spin=np.array([0.0, 2.0, 0.0]), spin_rate=np.array([0.0, 20.0, 0.0]))
    report = sleepy.step(turning)
    awake.step(turning)
    assert not sleepy.sleepers.asleep.any() and report.asleep == 0
    for _ in range(5):
        sleepy.step(turning)
        awake.step(turning)
    assert np.max(np.linalg.norm(_points(helices, sleepy.q) - _points(helices, awake.q), axis=2)) < 1e-8


def test_a_sleeping_strand_wakes_when_the_body_moves_near_it_and_one_far_away_sleeps_on():
    """Two strands held out level from posts over two boards, inverted on them, under a deforming body.
    The first board drops away after 0.065 s: the strand over it wakes at once and falls as it does
    when nothing sleeps; the strand over the other board, 0.2 m away, sleeps on."""
    helices = strands([horizontal_strand(n=6, total=0.12, root=(0.0, 0.0, 0.0)),
                       horizontal_strand(n=6, total=0.12, root=(0.0, 0.0, 0.2))])
    parts = [_box((0.02, 0.02, 0.02), (0.0, -0.0101, 0.0)), _box((0.02, 0.02, 0.02), (0.0, -0.0101, 0.2)),
             _box((0.2, 0.02, 0.1), (0.12, -0.0101, 0.0)), _box((0.2, 0.02, 0.1), (0.12, -0.0101, 0.2))]
    mesh = trimesh.util.concatenate(parts)
    dropping = np.zeros(len(mesh.vertices), bool)
    start = sum(len(p.vertices) for p in parts[:2])
    dropping[start:start + len(parts[2].vertices)] = True
    mat = material()
    settings = Settings()
    contacts_settings = dataclasses.replace(settings.contacts, hair_hair=False)
    body = BodyMesh.from_mesh(mesh)
    contacts, _ = detect_contacts(helices, body, contacts_settings)
    assert set(contacts.strand[:, 0]) == {0, 1}
    model, _ = invert(helices, contacts, mat, settings.solver)
    t0 = 0.065

    def vertices_at(t):
        out = mesh.vertices.copy()
        out[dropping, 1] -= 0.5 * max(t - t0, 0.0)  # down at 0.5 m/s
        return out

    def run(speed):
        skinned = SkinnedBody(vertices_at, mesh.faces, Binding.bind(helices.root, mesh.vertices, mesh.faces),
                              mat.gravity)
        sim = Simulation(helices, model.omega_rest, mat, body, contacts_settings,
                         dataclasses.replace(settings.dynamics, sleep_speed=speed), initial=contacts,
                         initial_force=model.force, stiffening=model.stiffening)
        asleep = []
        h = settings.dynamics.time_step
        for k in range(12):
            sim.step(skinned, h, k * h)
            asleep.append(sim.sleepers.asleep.copy())
        return sim, np.array(asleep)

    sleepy, asleep = run(1e-6)
    awake, _ = run(0.0)
    drop = int(t0 / 0.01)  # the first step over which the board moves: [0.06, 0.07]
    assert asleep[drop - 1].all()
    assert not asleep[drop, 0] and asleep[drop:, 1].all()
    a, b = _points(helices, sleepy.q), _points(helices, awake.q)
    start = _points(helices, helices.omega)
    assert np.max(np.linalg.norm(b[0] - start[0], axis=1)) > 1e-3  # the first strand fell
    assert np.max(np.linalg.norm(a - b, axis=2)) < 1e-8
