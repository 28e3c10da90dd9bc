"""Shared fixtures, named tolerances and builders of the test suite.

- named tolerances and the data's paths;
- the ``hairinv`` command run as a subprocess, and a folder's snapshot;
- hand-made scenes of the inverse problem (strands of known shapes, contacts at known places) with the
  checks taken on them independently of the kernels that solve them: the equilibrium as the gradient of
  an energy, the dense problem, its optimality conditions (from hairinv.testing);
- a hand-made stage file whose every shape has a closed form, evaluated here with Rodrigues' formula
  independently of hairinv.rod.
"""

from __future__ import annotations

import itertools
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hairinv import stages
from hairinv.config import MaterialSettings, SolverSettings
from hairinv.contacts.rows import contact_rows
from hairinv.gravity import generalized_gravity
from hairinv.invert import invert
from hairinv.model import Contacts, Helices, Material, stiffness
from hairinv.rod.helix import points_at
from hairinv.rod.statics import gravity_potential
from hairinv.testing import check_cone_qp, problem_scales

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "samples"
REAL = Path(os.environ.get("HAIRINV_REAL_DATA", ROOT.parent / "shared" / "data" / "real"))

# Round-off: closed forms against each other or against complex-step
# derivatives, relative to the magnitude compared.
ROUNDOFF = 1e-12
# Numerical ODE integration (scipy solve_ivp at rtol 1e-12): its own error.
ODE = 1e-10
# Central finite differences with step h ~ 1e-6: truncation error ~ h^2 |f'''|.
FINITE_DIFFERENCE = 1e-6
# The sweeps' stopping tolerance in the inverse problem's tests, relative to a strand's weight.
TIGHT = 1e-10
# USD stores points as float32: about 1e-7 relative, so 1e-6 m on a groom within 2 m of the origin.
FLOAT32_M = 1e-6


def real_path(*parts) -> Path:
    """A file of the shared real data set, or skip the test with the reason."""
    path = REAL.joinpath(*parts)
    if not path.exists():
        pytest.skip(f"real data not found at {path} (set HAIRINV_REAL_DATA)")
    return path


@pytest.fixture
def rng():
    return np.random.default_rng(20131107)


# ------------------------------------------------------------------------------------- the hairinv command


# no plain progress lines unless a test asks for them (HAIRINV_PROGRESS_SECONDS=0): on a busy machine a stage
# may outlast the 5 s between two lines, and a refusal's stderr would then hold more than its one sentence
os.environ.setdefault("HAIRINV_PROGRESS_SECONDS", "1e9")
ENV = {k: v for k, v in os.environ.items() if k != "HAIRINV_DEBUG"}
ENV["HAIRINV_THREADS"] = "2"


def hairinv(cwd: Path, *args: str) -> subprocess.CompletedProcess:
    """``hairinv *args`` run in ``cwd`` as a subprocess (two threads, no debug output), its output captured."""
    return subprocess.run(
        [sys.executable, "-m", "hairinv_cli.main", *map(str, args)],
        cwd=cwd,
        env=ENV,
        capture_output=True,
        text=True,
        timeout=600,
    )


def inverted_settled(folder: Path) -> Path:
    """``hairinv invert settled.h5 body.obj --guides 12 --target zero`` in ``folder``: a small groom at rest
    (``folder/model.h5``, about 0.01 s of computing per frame of the still scene)."""
    shutil.copyfile(SAMPLES / "settled.h5", folder / "settled.h5")
    shutil.copyfile(SAMPLES / "body.obj", folder / "body.obj")
    result = hairinv(folder, "invert", "settled.h5", "body.obj", "--guides", "12", "--target", "zero",
                     "-o", "model.h5")
    assert result.returncode == 0, result.stderr
    return folder


def assert_refused(folder: Path, args, name: str, fragment: str) -> None:
    """``hairinv *args`` in ``folder`` exits 2 with one line naming ``name`` and saying ``fragment``,
    no traceback, and leaves every file of ``folder`` as it was."""
    before = snapshot(folder)
    result = hairinv(folder, *args)
    assert result.returncode == 2, (result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and name in lines[0] and fragment in lines[0], result.stderr
    assert "Traceback" not in result.stderr
    assert snapshot(folder) == before


def snapshot(folder: Path) -> dict[str, bytes]:
    """Every file of ``folder`` (recursively) with its bytes."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def eight_strand_model(folder: Path, strands: int = 8, body: Path | None = None) -> Path:
    """``strands`` strands of the sample straight groom (spread over it) inverted on ``body`` (default
    samples/turn.glb, the mannequin turning its head: inverted on its bind pose) by the command line, as
    ``folder/eight.model.h5``; a fast model for shots (tests/test_shots.py, tests/test_blender.py)."""
    from hairinv import formats

    curves = formats.read_curves(SAMPLES / "straight.h5")
    keep = np.linspace(0, curves.n_strands - 1, strands).astype(int)
    pieces = [curves.points[curves.offsets[k]:curves.offsets[k + 1]] for k in keep]
    formats.write_curves(folder / "eight.h5", np.concatenate(pieces), np.r_[0, np.cumsum([len(p) for p in pieces])])
    done = hairinv(folder, "invert", "eight.h5", str(body or SAMPLES / "turn.glb"), "-o", "eight.model.h5")
    assert done.returncode == 0, done.stderr
    return folder / "eight.model.h5"


# ---------------------------------------------------------------------- hand-made scenes of the inverse problem


UP = np.array([0.0, 1.0, 0.0])


def material(**changes) -> Material:
    return Material.from_settings(MaterialSettings(**changes), UP)


def strands(specs) -> Helices:
    """Helices from ``[(root, tangent, omega (N,3), length (N,)), ...]``; n1 is the up axis projected."""
    roots, frames, omegas, lengths, offsets = [], [], [], [], [0]
    for root, tangent, omega, length in specs:
        t = np.asarray(tangent, float) / np.linalg.norm(tangent)
        n1 = UP - (UP @ t) * t
        n1 = n1 / np.linalg.norm(n1) if np.linalg.norm(n1) > 1e-8 else np.array([1.0, 0.0, 0.0])
        frames.append(np.array([t, n1, np.cross(t, n1)]))
        roots.append(root)
        omegas.append(np.asarray(omega, float))
        lengths.append(np.asarray(length, float))
        offsets.append(offsets[-1] + len(length))
    return Helices(np.array(roots, float), np.array(frames), np.array(offsets, np.int64),
                   np.concatenate(lengths), np.concatenate(omegas), np.zeros((len(specs), 2)))


def frame_from_normal(normal) -> np.ndarray:
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    t1 = np.cross(n, a)
    t1 /= np.linalg.norm(t1)
    return np.array([n, t1, np.cross(n, t1)])


def point_on(helices, strand, s) -> np.ndarray:
    a, z = helices.offsets[strand], helices.offsets[strand + 1]
    out = np.empty((1, 3))
    points_at(helices.root[strand], helices.frame0[strand], helices.omega[a:z], helices.length[a:z],
              np.array([float(s)]), out)
    return out[0]


def make_contacts(helices, specs) -> Contacts:
    """Contacts from ``[(strand A, s_A, strand B or -1, s_B, normal, mu), ...]``."""
    strand = np.array([[a, b] for a, _, b, _, _, _ in specs], np.int64)
    s = np.array([[sa, sb] for _, sa, _, sb, _, _ in specs], float)
    point = np.array([point_on(helices, a, sa) for a, sa, _, _, _, _ in specs])
    frame = np.array([frame_from_normal(n) for *_, n, _ in specs])
    mu = np.array([m for *_, m in specs], float)
    return Contacts(strand, s, point, frame, mu)


def horizontal_strand(n=6, total=0.12, curl=0.0, root=(0.0, 0.0, 0.0)):
    """A strand leaving its root horizontally along +x, optionally curled about the up axis."""
    omega = np.zeros((n, 3))
    omega[:, 1] = curl
    return (np.array(root, float), (1.0, 0.0, 0.0), omega, np.full(n, total / n))


def three_strands_on_the_body(mu):
    """Three horizontal strands (straight, curled, curled the other way) resting on 3-4 body contacts
    each, with upright and tilted normals, friction ``mu``: (helices, contacts)."""
    tilted = UP + np.array([0.3, 0.0, 0.2])
    helices = strands([horizontal_strand(curl=c, root=(0.0, 0.0, z)) for c, z in ((0.0, 0.0), (2.0, 0.05),
                                                                                  (-4.0, 0.1))])
    specs = [(0, s, -1, 0.0, UP, mu) for s in (0.06, 0.08, 0.1)]
    specs += [(1, s, -1, 0.0, tilted / np.linalg.norm(tilted), mu) for s in (0.05, 0.07, 0.09, 0.11)]
    specs += [(2, s, -1, 0.0, UP, mu) for s in (0.07, 0.09, 0.115)]
    return helices, make_contacts(helices, specs)


def resting_scene(mu=0.3, n_contacts=3):
    """One horizontal strand on point supports below it (a body pushing up)."""
    helices = strands([horizontal_strand()])
    spots = np.linspace(0.05, 0.115, n_contacts)
    contacts = make_contacts(helices, [(0, s, -1, 0.0, UP, mu) for s in spots])
    return helices, contacts


def two_strand_scene(mu=0.3):
    """Strand 1 lies across strand 0 and rests on it and on the body."""
    helices = strands([
        horizontal_strand(n=5, total=0.1),
        (np.array([0.06, 0.002, -0.05]), (0.0, 0.0, 1.0), np.zeros((5, 3)), np.full(5, 0.02)),
    ])
    contacts = make_contacts(helices, [
        (0, 0.08, -1, 0.0, UP, mu),
        (0, 0.06, 1, 0.05, -UP, mu),  # strand 1 above strand 0: the normal points from B (1) to A (0)
        (1, 0.09, -1, 0.0, (0.0, 1.0, 0.3), mu),
    ])
    return helices, contacts


def solve(helices, contacts, mat=None, **solver):
    """Invert by the sweeps to ``TIGHT`` (the interior-point method's own tests: tests/test_interior.py), with
    the friction as declared (no reserve: ``test_friction_reserve`` tests the reserve) and the paper's single
    ``gamma`` (``test_gamma_relative`` tests the per-contact one); the residual alone stops the sweeps
    (``rest_tolerance`` far below what they reach: ``test_rest_gap`` tests that stop)."""
    settings = SolverSettings(**{"tolerance": TIGHT, "max_sweeps": 20000, "method": "sweeps", "friction_reserve": 0.0,
                                 "gamma_relative": 0.0, "rest_tolerance": 1e-300, **solver})
    model, report = invert(helices, contacts, mat or material(), settings)
    return model, report


def energy_gradient(helices, contacts, model, mat, h=1e-5):
    """d/dq of elastic + gravity potential + contact work, by central differences (see module docstring)."""
    q = helices.omega.copy()
    K = stiffness(helices, mat).reshape(-1, 3)
    world = np.einsum("cji,cj->ci", contacts.frame, model.force)  # C^T r

    def strand_energy(s, omega):
        a, z = helices.offsets[s], helices.offsets[s + 1]
        args = (helices.root[s], helices.frame0[s], omega, helices.length[a:z])
        v = gravity_potential(*args, mat.linear_density, mat.gravity)
        for c in range(contacts.n_contacts):
            for side, sign in ((0, 1.0), (1, -1.0)):
                if contacts.strand[c, side] == s:
                    x = np.empty((1, 3))
                    points_at(*args, np.array([contacts.s[c, side]]), x)
                    v -= sign * world[c] @ (x[0] - helices.root[s])  # from the (fixed) root: less round-off
        return v

    grad = K * (q - model.omega_rest)
    for s in range(helices.n_strands):
        a, z = helices.offsets[s], helices.offsets[s + 1]
        for e in range(z - a):
            for k in range(3):
                om = q[a:z].copy()
                om[e, k] += h
                vp = strand_energy(s, om)
                om[e, k] -= 2 * h
                vm = strand_energy(s, om)
                grad[a + e, k] += (vp - vm) / (2 * h)
    return grad, np.abs(generalized_gravity(helices, mat)).max()


def point_load_potential(root, frame0, omega, length, s, force):
    """-sum_k f_k . x(s_k), from the centerline points themselves (independent of the Jacobians); the
    root's constant share is left out, so that second differences do not lose digits to it."""
    x = np.empty((len(s), 3))
    points_at(root, frame0, omega, length, np.asarray(s, dtype=np.float64), x)
    return -float(np.sum(force * (x - root)))


def dense_problem(helices, contacts, mat, model):
    """The model's cone QP assembled densely: ``W = H D H^T + gamma I``, ``b = H D (F_g - K (q - t))`` with
    ``D = w K^-2``; returns ``(W, b, H, d)``, ``d`` the diagonal of ``D``."""
    rows = contact_rows(helices, contacts)
    H = rows.to_sparse().toarray()
    K = stiffness(helices, mat)
    d = model.target_weight.repeat(3) / K ** 2
    F_g = generalized_gravity(helices, mat).ravel()
    b = H @ (d * (F_g - K * (helices.omega.ravel() - model.omega_target.ravel())))
    gamma = model.gamma if model.contact_gamma is None else np.repeat(model.contact_gamma, 3)
    W = H @ (d[:, None] * H.T) + np.diag(np.broadcast_to(gamma, len(H)))
    return W, b, H, d


def check_optimality(W, b, r, mu, rtol):
    """Cone, dual cone and complementarity of the dense problem at ``r`` (hairinv.testing), relative to the
    scale of the data: ``|r_T|`` within ``rtol F`` of ``mu r_N``, ``|u_T|`` within ``rtol S`` of ``u_N / mu``
    (``u_N`` within ``rtol S`` of 0 where ``mu = 0``), ``|r . u|`` within ``rtol F S``, with ``F`` the largest
    force and ``S`` the largest velocity term."""
    force, speed = problem_scales(W, b, r)
    mu = np.asarray(mu, dtype=np.float64)
    # hairinv.testing measures the excess of |r_T| over mu r_N divided by max(1, mu), and that of |u_T| over
    # u_N / mu multiplied by min(1, mu): the bounds carry those factors, so each inequality keeps rtol itself
    check_cone_qp(W, b, r, mu, primal=rtol * force / np.maximum(1.0, mu),
                  dual=rtol * speed * np.where(mu > 0.0, np.minimum(1.0, mu), 1.0),
                  complementarity=rtol * force * speed)


# ------------------------------------------------- a hand-made stage file, evaluated independently of hairinv.rod


def _rotate(v: np.ndarray, axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues: ``v`` (n, 3) turned by ``angle`` about the unit ``axis``."""
    c, s = np.cos(angle), np.sin(angle)
    return v * c + np.cross(axis, v) * s + np.outer(v @ axis, axis) * (1.0 - c)


def _step(x: np.ndarray, F: np.ndarray, omega: np.ndarray, sigma: float):
    """Point and frame after ``sigma`` along one element from (x, F): the frame (rows t, n1, n2) turns about
    ``W = kappa1 n1 + kappa2 n2 + tau t`` at the rate |W|; x(sigma) = x + the integral of t."""
    W = omega[0] * F[1] + omega[1] * F[2] + omega[2] * F[0]
    k = float(np.linalg.norm(W))
    t = F[0]
    if k * sigma < 1e-12:
        return x + sigma * t, F.copy()
    b = W / k
    along = (t @ b) * b
    across = t - along
    point = x + sigma * along + np.sin(k * sigma) / k * across + (1.0 - np.cos(k * sigma)) / k * np.cross(b, across)
    return point, _rotate(F, b, k * sigma)


def centerline(root, frame0, omega, length, s) -> np.ndarray:
    """Points at arc lengths ``s`` of one strand (clamped to its length)."""
    starts = np.concatenate([[0.0], np.cumsum(length)])
    xs, Fs = [np.asarray(root, float)], [np.asarray(frame0, float)]
    for e in range(len(length)):
        x, F = _step(xs[-1], Fs[-1], omega[e], length[e])
        xs.append(x)
        Fs.append(F)
    out = []
    for sj in np.clip(s, 0.0, starts[-1]):
        e = min(int(np.searchsorted(starts, sj, side="right")) - 1, len(length) - 1)
        out.append(_step(xs[e], Fs[e], omega[e], sj - starts[e])[0])
    return np.array(out)


def vertex_arc_lengths(points, offsets, element_offsets, length) -> list[np.ndarray]:
    """docs/export.md: vertex i at L * c_i / c_n (c the chord length from the root, L the fitted length)."""
    out = []
    for k in range(len(offsets) - 1):
        p = points[offsets[k]:offsets[k + 1]]
        c = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
        out.append(c / c[-1] * length[element_offsets[k]:element_offsets[k + 1]].sum())
    return out


def evaluate(points, offsets, element_offsets, length, roots, frames, omega) -> np.ndarray:
    """Every strand's centerline at its vertices' arc lengths."""
    s = vertex_arc_lengths(points, offsets, element_offsets, length)
    return np.concatenate([centerline(roots[k], frames[k], omega[element_offsets[k]:element_offsets[k + 1]],
                                      length[element_offsets[k]:element_offsets[k + 1]], s[k])
                           for k in range(len(offsets) - 1)])


UP_Z = np.array([0.0, 0.0, 1.0])
# Strand 0 hangs along -Z with three helical elements, strand 1 is straight; 2 cm apart.
FRAME0 = np.array([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])  # rows t, n1, n2 = t x n1
ROOTS = np.array([[0.0, 0.0, 0.0], [0.02, 0.0, 0.0]])
ELEMENT_OFFSETS = np.array([0, 3, 5])
LENGTH = np.array([0.031, 0.042, 0.027, 0.05, 0.05])  # m; no vertex (every 5 mm) on an element joint
OMEGA = np.array([[5.0, 0.0, 0.0], [0.0, 8.0, 2.0], [3.0, -4.0, 10.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
OMEGA_REST = np.array([[10.0, 0.0, 0.0], [0.0, 20.0, 0.0], [3.0, 4.0, 0.0], [0.0, 6.0, 0.0], [0.0, 6.0, 0.0]])
OMEGA_REST_STIFFENED = OMEGA_REST.copy()
OMEGA_REST_STIFFENED[3:] = [0.0, 3.0, 1.0]
RADIUS = 5e-5
FPS = 25.0
N_FRAMES = 3


def _contact_frames(rng, n):
    q, _ = np.linalg.qr(rng.normal(size=(n, 3, 3)))
    return np.where(np.linalg.det(q)[:, None, None] < 0, -q, q)  # proper rotations, rows orthonormal


def body_motion(k: int) -> np.ndarray:
    T = np.eye(4)
    a = 0.1 * k
    T[:3, :3] = [[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]]
    T[:3, 3] = [0.001 * k, 0.0, 0.002 * k]
    return T


# /model/stability_margin of the stiffened hand-made model: strand 0 stable, strand 1 not
STABILITY_MARGIN = np.array([0.3, -0.05])


def make_stage(path, *, up=UP_Z, scale_to_m=0.01, model=True, stiffened=False, frames=True, rng=None, growth=0.1,
               init=None):
    """Write the hand-made stage file; returns a dict of what the tests compare with.

    Frame k's shape is ``OMEGA * (1 + growth k)``, its roots moved by ``body_motion(k)``; ``init`` is the
    ``/frames`` attribute (None: not recorded)."""
    rng = np.random.default_rng(7) if rng is None else rng
    # the input vertices lie on the fitted curve, every 5 mm of arc
    s_in = [np.linspace(0.0, LENGTH[a:z].sum(), round(LENGTH[a:z].sum() / 0.005) + 1)
            for a, z in itertools.pairwise(ELEMENT_OFFSETS)]
    points = np.concatenate([centerline(ROOTS[k], FRAME0, OMEGA[ELEMENT_OFFSETS[k]:ELEMENT_OFFSETS[k + 1]],
                                        LENGTH[ELEMENT_OFFSETS[k]:ELEMENT_OFFSETS[k + 1]], s_in[k]) for k in range(2)])
    offsets = np.concatenate([[0], np.cumsum([len(s) for s in s_in])]).astype(np.int64)
    frame0 = np.stack([FRAME0, FRAME0])
    groups = [
        stages.Group(stages.CURVES, {"points": points, "offsets": offsets},
                     attrs={"source": "hand-made", "scale_to_m": scale_to_m, "up": np.asarray(up, float)},
                     config={"import": {"flip": ""}}),
        stages.Group(stages.HELICES, {"root": ROOTS, "frame0": frame0, "offsets": ELEMENT_OFFSETS, "length": LENGTH,
                                      "omega": OMEGA, "fit_error": np.array([[1e-5, 3e-5], [2e-5, 4e-5]])}),
    ]
    truth = {"points": points, "offsets": offsets}
    s_v = vertex_arc_lengths(points, offsets, ELEMENT_OFFSETS, LENGTH)
    if model:
        # four contacts: body at strand 0's vertex 2; body and hair-hair at its vertex 5, the latter at
        # strand 1's vertex 3 (pushing it the other way) with a body contact there too; each placed off
        # the vertex, nearer to it than to its neighbours
        def near(k, i, f):
            return s_v[k][i] + f * (s_v[k][i + 1] - s_v[k][i])

        strand = np.array([[0, -1], [0, -1], [0, 1], [1, -1]])
        s = np.array([[near(0, 2, 0.3), 0.0], [near(0, 4, 0.8), 0.0], [near(0, 5, 0.1), near(1, 3, 0.4)],
                      [near(1, 2, 0.7), 0.0]])
        frame = _contact_frames(rng, 4)
        force = np.array([[2e-4, 1e-5, -2e-5], [1e-4, 0.0, 3e-5], [5e-5, -1e-5, 0.0], [3e-5, 1e-5, 1e-5]])
        world = np.array([frame[c].T @ force[c] for c in range(4)])
        expected_force = np.zeros(len(points))
        expected_force[offsets[0] + 2] = np.linalg.norm(world[0])
        expected_force[offsets[0] + 5] = np.linalg.norm(world[1] + world[2])
        expected_force[offsets[1] + 3] = np.linalg.norm(world[3] - world[2])
        truth["contact_force"] = expected_force
        groups.append(stages.Group(stages.CONTACTS, {"strand": strand, "s": s, "point": np.zeros((4, 3)),
                                                     "frame": frame, "mu": np.full(4, 0.3)}))
        data = {"omega_rest": OMEGA_REST, "omega_target": np.zeros_like(OMEGA), "target_weight": np.ones(5),
                "force": force}
        if stiffened:
            data["stiffening"] = np.array([1.0, 2.0])
            data["omega_rest_stiffened"] = OMEGA_REST_STIFFENED
            data["stability_margin"] = STABILITY_MARGIN
        groups.append(stages.Group(stages.MODEL, data, attrs={
            "youngs_modulus": 4e9, "shear_modulus": 1.5e9, "density": 1300.0, "radius": RADIUS,
            "gravity": -9.81 * np.asarray(up, float), "gamma": 1e-6, "target": "actual", "iterations": 1,
            "residual": 0.0, "seconds": 0.0, "stable_under": "forces"}))
    if frames:
        T = np.stack([body_motion(k) for k in range(N_FRAMES)])
        groups.append(stages.Group(stages.FRAMES, {
            "time": np.arange(N_FRAMES) / FPS,
            "omega": np.stack([OMEGA * (1.0 + growth * k) for k in range(N_FRAMES)]),
            "root": np.stack([ROOTS @ T[k, :3, :3].T + T[k, :3, 3] for k in range(N_FRAMES)]),
            "frame0": np.stack([frame0 @ T[k, :3, :3].T for k in range(N_FRAMES)]),
            "body_transform": T}, attrs={"fps": FPS} if init is None else {"fps": FPS, "init": init}))
    stages.write_stage(path, groups, "test")
    return truth


def expected_rest(truth, stiffened=False):
    rest = OMEGA_REST_STIFFENED if stiffened else OMEGA_REST
    return evaluate(truth["points"], truth["offsets"], ELEMENT_OFFSETS, LENGTH, ROOTS, np.stack([FRAME0, FRAME0]), rest)


def expected_frame(truth, k):
    T = body_motion(k)
    roots = ROOTS @ T[:3, :3].T + T[:3, 3]
    frames = np.stack([FRAME0, FRAME0]) @ T[:3, :3].T
    return evaluate(truth["points"], truth["offsets"], ELEMENT_OFFSETS, LENGTH, roots, frames,
                    OMEGA * (1.0 + 0.1 * k))


def obj_mesh(path):
    """Vertices (n, 3) and faces (lists of 0-based indices) of an OBJ file, read here."""
    v, f = [], []
    for line in path.read_text().splitlines():
        words = line.split()
        if words and words[0] == "v":
            v.append([float(w) for w in words[1:4]])
        elif words and words[0] == "f":
            f.append([int(w.split("/")[0]) - 1 for w in words[1:]])
    return np.array(v), f
