"""Animated bodies: the glTF skinning evaluator against usd-core's UsdSkel and Blender's glTF import, the
samplers against closed forms, the bind pose against trimesh, mesh sequences and USD point caches."""

from __future__ import annotations

import json
import re
import struct
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from conftest import ROOT, ROUNDOFF, real_path
from hairinv.errors import InputError
from hairinv.formats import is_animated_body, read_animated_body
from hairinv.formats.gltf_anim import evaluate_sampler, quaternion_matrix, slerp

# Float32 storage (glTF accessors, USD points, quatf rotations) of coordinates ~1 m: ~6e-8 each, a few
# roundings through a 3-joint chain.
FLOAT32_SKINNING = 1e-6
BLENDER = ROOT.parent / ".venv-blender" / "bin" / "python"
if not BLENDER.exists():
    BLENDER = Path("/work/main/.venv-blender/bin/python")


def fails(path, *fragments: str):
    pattern = re.escape(Path(path).name) + ": " + "".join(".*" + re.escape(f) for f in fragments)
    return pytest.raises(InputError, match=pattern)


# --------------------------------------------------------------------------- a small rig of our own


def axis_angle(axis, angle) -> np.ndarray:
    """Unit quaternion (x, y, z, w) of a rotation by ``angle`` about ``axis``."""
    axis = np.asarray(axis, dtype=np.float64) / np.linalg.norm(axis)
    return np.r_[np.sin(angle / 2) * axis, np.cos(angle / 2)]


def trs(t=(0, 0, 0), q=(0, 0, 0, 1), s=(1, 1, 1)) -> np.ndarray:
    M = np.eye(4)
    M[:3, :3] = quaternion_matrix(q) * np.asarray(s, dtype=np.float64)
    M[:3, 3] = t
    return M


def cylinder(rings=13, around=8, radius=0.2, height=3.0):
    """An open tube along +Y, its vertices weighted to three joints at heights 0, 1, 2."""
    y = np.linspace(0, height, rings)
    a = np.linspace(0, 2 * np.pi, around, endpoint=False)
    Y, A = np.meshgrid(y, a, indexing="ij")
    points = np.c_[radius * np.cos(A).ravel(), Y.ravel(), radius * np.sin(A).ravel()]
    faces = []
    for r in range(rings - 1):
        for k in range(around):
            i, j = r * around + k, r * around + (k + 1) % around
            faces += [(i, i + around, j), (j, i + around, j + around)]
    centres = np.array([0.5, 1.5, 2.5])
    w = np.maximum(0.0, 1.0 - np.abs(points[:, 1:2] - centres))
    w /= w.sum(axis=1, keepdims=True)
    joints = np.argsort(-w, axis=1)[:, :4]  # the (at most two) influences first, zero weights after
    weights = np.take_along_axis(w, joints, axis=1)
    joints = np.c_[joints, np.zeros((len(points), 1), np.int64)]
    weights = np.c_[weights, np.zeros((len(points), 1))]
    return points.astype(np.float32), np.asarray(faces), joints, weights.astype(np.float32)


# The rig: a non-joint parent "root" (turned and moved) over joints j0 -> j1 -> j2, one unit apart.
ROOT_T, ROOT_Q = np.array([0.3, -0.2, 0.1]), axis_angle([1, 2, 0.5], 0.4)
REST_T = [np.zeros(3), np.array([0, 1.0, 0]), np.array([0, 1.0, 0])]
KEYS = np.array([0.0, 0.5, 1.0])  # seconds


def channels(interp_j2="LINEAR"):
    """(joint, path, key values, interpolation) of the rig's animation, all keyed at KEYS."""
    return [
        (0, "translation", np.array([[0, 0, 0], [0.1, 0.05, 0], [0.2, 0.0, -0.1]]), "LINEAR"),
        (0, "rotation", np.array([axis_angle([0, 1, 0], a) for a in (0.0, 0.6, 1.3)]), "LINEAR"),
        (1, "rotation", np.array([axis_angle([0, 0, 1], a) for a in (0.0, 0.8, -0.5)]), "LINEAR"),
        (2, "rotation", np.array([axis_angle([1, 0, 1], a) for a in (0.2, 1.1, 2.4)]), interp_j2),
        (2, "scale", np.array([[1, 1, 1], [1.5, 1, 1.25], [1, 0.75, 1]]), "LINEAR"),  # exact in USD's half3
    ]


def write_glb(path, points, faces, joints, weights, chans, root_q=ROOT_Q, mesh_node_t=(0, 0, 0), skinned=True):
    """A GLB of the rig written from the specification: nodes root, j0, j1, j2, body (mesh, skin); not
    ``skinned``: the body is a plain mesh node, child of j2."""
    blob, views, accessors = bytearray(), [], []

    def add(array, component, kind, **extra):
        data = np.ascontiguousarray(array).tobytes()
        while len(blob) % 4:
            blob.append(0)
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data)})
        blob.extend(data)
        count = len(array) if kind != "SCALAR" else np.asarray(array).size
        accessors.append({"bufferView": len(views) - 1, "componentType": component, "count": count, "type": kind,
                          **extra})
        return len(accessors) - 1

    bind_world = [trs(ROOT_T, root_q)]
    for j in range(3):
        bind_world.append(bind_world[-1] @ trs(REST_T[j]))
    inverse_bind = np.stack([np.linalg.inv(M).T for M in bind_world[1:]]).astype(np.float32)  # column-major
    attributes = {
        "POSITION": add(points, 5126, "VEC3", min=points.min(0).tolist(), max=points.max(0).tolist()),
        "JOINTS_0": add(joints.astype(np.uint16), 5123, "VEC4"),
        "WEIGHTS_0": add(weights, 5126, "VEC4"),
    }
    indices = add(faces.astype(np.uint32).ravel(), 5125, "SCALAR")
    ibm = add(inverse_bind.reshape(3, 16), 5126, "MAT4")
    samplers, anim_channels = [], []
    for joint, what, values, interpolation in chans:
        times = KEYS.astype(np.float32)
        output = np.asarray(values, dtype=np.float32)
        kind = "VEC4" if what == "rotation" else "VEC3"
        samplers.append({"input": add(times, 5126, "SCALAR", min=[0.0], max=[1.0]),
                         "output": add(output.reshape(-1, output.shape[-1]), 5126, kind),
                         "interpolation": interpolation})
        anim_channels.append({"sampler": len(samplers) - 1, "target": {"node": 1 + joint, "path": what}})
    doc = {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 4] if skinned else [0]}],
        "nodes": [
            {"name": "root", "translation": ROOT_T.tolist(), "rotation": list(root_q), "children": [1]},
            {"name": "j0", "children": [2]},
            {"name": "j1", "translation": REST_T[1].tolist(), "children": [3]},
            {"name": "j2", "translation": REST_T[2].tolist(), **({} if skinned else {"children": [4]})},
            {"name": "body", "mesh": 0, "translation": list(mesh_node_t), **({"skin": 0} if skinned else {})},
        ],
        "meshes": [{"primitives": [{"attributes": attributes, "indices": indices, "mode": 4}]}],
        **({"skins": [{"joints": [1, 2, 3], "inverseBindMatrices": ibm, "skeleton": 1}]} if skinned else {}),
        "animations": [{"channels": anim_channels, "samplers": samplers}],
        "buffers": [{"byteLength": len(blob)}],
        "bufferViews": views,
        "accessors": accessors,
    }
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    while len(blob) % 4:
        blob.append(0)
    body = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(blob), 0x004E4942) + bytes(blob)
    Path(path).write_bytes(struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body)


def write_usdskel(path, points, faces, joints, weights, chans, codes_per_second=24.0):
    """The same rig as UsdSkel: the root's transform on the Skeleton prim, the joints' transforms in a
    SkelAnimation sampled at the key times, the mesh bound with geomBindTransform = root^-1."""
    from pxr import Gf, Usd, UsdGeom, UsdSkel, Vt

    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    stage.SetTimeCodesPerSecond(codes_per_second)
    stage.SetStartTimeCode(0)
    stage.SetEndTimeCode(KEYS[-1] * codes_per_second)
    UsdSkel.Root.Define(stage, "/Rig")
    skel = UsdSkel.Skeleton.Define(stage, "/Rig/Skel")
    root = trs(ROOT_T, ROOT_Q)
    UsdGeom.Xformable(skel.GetPrim()).AddTransformOp().Set(Gf.Matrix4d(root.T.tolist()))
    names = ["j0", "j0/j1", "j0/j1/j2"]
    skel.CreateJointsAttr(names)
    local = [trs(t) for t in REST_T]
    bind = [local[0], local[0] @ local[1], local[0] @ local[1] @ local[2]]
    skel.CreateBindTransformsAttr(Vt.Matrix4dArray([Gf.Matrix4d(M.T.tolist()) for M in bind]))
    skel.CreateRestTransformsAttr(Vt.Matrix4dArray([Gf.Matrix4d(M.T.tolist()) for M in local]))
    anim = UsdSkel.Animation.Define(stage, "/Rig/Skel/Anim")
    anim.CreateJointsAttr(names)
    translations, rotations, scales = anim.CreateTranslationsAttr(), anim.CreateRotationsAttr(), anim.CreateScalesAttr()
    for k, t in enumerate(KEYS):
        T = [REST_T[j].copy() for j in range(3)]
        R = [np.array([0, 0, 0, 1.0]) for _ in range(3)]
        S = [np.ones(3) for _ in range(3)]
        for joint, what, values, _ in chans:
            {"translation": T, "rotation": R, "scale": S}[what][joint] = np.asarray(values[k], dtype=np.float32)
        code = Usd.TimeCode(t * codes_per_second)
        translations.Set(Vt.Vec3fArray([Gf.Vec3f(*map(float, v)) for v in T]), code)
        rotations.Set(Vt.QuatfArray([Gf.Quatf(float(q[3]), Gf.Vec3f(*map(float, q[:3]))) for q in R]), code)
        scales.Set(Vt.Vec3hArray([Gf.Vec3h(*map(float, s)) for s in S]), code)
    UsdSkel.BindingAPI.Apply(skel.GetPrim()).CreateAnimationSourceRel().SetTargets([anim.GetPath()])
    mesh = UsdGeom.Mesh.Define(stage, "/Rig/Body")
    mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, p)) for p in points]))
    mesh.CreateFaceVertexCountsAttr([3] * len(faces))
    mesh.CreateFaceVertexIndicesAttr([int(i) for i in faces.ravel()])
    binding = UsdSkel.BindingAPI.Apply(mesh.GetPrim())
    binding.CreateSkeletonRel().SetTargets([skel.GetPath()])
    binding.CreateJointIndicesPrimvar(False, 4).Set(Vt.IntArray([int(i) for i in joints.ravel()]))
    binding.CreateJointWeightsPrimvar(False, 4).Set(Vt.FloatArray([float(w) for w in weights.ravel()]))
    binding.CreateGeomBindTransformAttr(Gf.Matrix4d(np.linalg.inv(root).T.tolist()))
    stage.GetRootLayer().Save()


@pytest.fixture
def rig():
    return cylinder()


def test_gltf_skinning_matches_usdskel(tmp_path, rig):
    pytest.importorskip("pxr")
    glb, usda = tmp_path / "rig.glb", tmp_path / "rig.usda"
    write_glb(glb, *rig, channels())
    write_usdskel(usda, *rig, channels())
    ours, theirs = read_animated_body(glb), read_animated_body(usda)
    assert ours.format == "gltf-skin" and theirs.format == "usd-skel"
    assert ours.joints == ("j0", "j1", "j2") and theirs.joints == ("j0", "j1", "j2")
    np.testing.assert_array_equal(ours.faces, theirs.faces)
    np.testing.assert_allclose(ours.times, KEYS, rtol=0, atol=ROUNDOFF)
    np.testing.assert_allclose(theirs.times, KEYS, rtol=0, atol=ROUNDOFF)
    np.testing.assert_allclose(ours.vertices, theirs.vertices, rtol=0, atol=FLOAT32_SKINNING)  # bind pose
    moved = 0.0
    # keys, LINEAR (slerp) between them, held after; at quarters of an interval the interpolated scale is exact in
    # USD's half3, which rounds it (1.1 would come back as 1.0996)
    for t in (0.0, 0.125, 0.25, 0.5, 0.625, 0.75, 0.875, 1.0, 1.5):
        np.testing.assert_allclose(ours.vertices_at(t), theirs.vertices_at(t), rtol=0, atol=FLOAT32_SKINNING)
        moved = max(moved, np.abs(ours.vertices_at(t) - ours.vertices).max())
    assert moved > 0.5  # the rig bends: the comparison is not of two rest poses


def test_gltf_step_rotation_holds_the_key_pose(tmp_path, rig):
    pytest.importorskip("pxr")
    glb, usda = tmp_path / "rig.glb", tmp_path / "rig.usda"
    write_glb(glb, *rig, channels("STEP"))
    write_usdskel(usda, *rig, channels())
    ours, theirs = read_animated_body(glb), read_animated_body(usda)
    for key, t in ((0.5, 0.875), (0.0, 0.375)):  # j2's rotation is that of the previous key
        still = ours.vertices_at(t)
        linear = theirs.vertices_at(t)
        assert np.abs(still - linear).max() > 1e-3
        # only j2's rotation steps: rebuild the expected pose from a rig whose j2 rotation is keyed flat
        flat = [c if c[:2] != (2, "rotation") else (2, "rotation", np.repeat(c[2][[KEYS.tolist().index(key)]], 3, 0),
                                                     "LINEAR") for c in channels()]
        write_usdskel(tmp_path / "flat.usda", *rig, flat)
        expected = read_animated_body(tmp_path / "flat.usda").vertices_at(t)
        np.testing.assert_allclose(still, expected, rtol=0, atol=FLOAT32_SKINNING)


def test_mesh_node_carried_by_the_animated_hierarchy(tmp_path, rig):
    # Every channel of the rig turns about one axis per joint by less than a half turn between keys, so
    # LINEAR's slerp is the lerp of the angle: the world matrix of j2 at any t in closed form.
    glb = tmp_path / "carried.glb"
    write_glb(glb, *rig, channels(), mesh_node_t=(0.1, 0.2, 0.3), skinned=False)
    body = read_animated_body(glb)
    assert body.format == "gltf-animated" and body.joints == ()
    angles = {0: ([0, 1, 0], (0.0, 0.6, 1.3)), 1: ([0, 0, 1], (0.0, 0.8, -0.5)), 2: ([1, 0, 1], (0.2, 1.1, 2.4))}
    translation = np.array([[0, 0, 0], [0.1, 0.05, 0], [0.2, 0.0, -0.1]])
    scale = np.array([[1, 1, 1], [1.5, 1, 1.25], [1, 0.75, 1]])
    points = rig[0].astype(np.float64)
    for t in (0.0, 0.2, 0.5, 0.7, 1.0):
        lerp = lambda keys: np.array([np.interp(t, KEYS, np.asarray(keys)[:, i]) for i in range(3)])  # noqa: E731
        turn = {j: axis_angle(axis, np.interp(t, KEYS, a)) for j, (axis, a) in angles.items()}
        world = (trs(ROOT_T, ROOT_Q) @ trs(lerp(translation), turn[0]) @ trs(REST_T[1], turn[1])
                 @ trs(REST_T[2], turn[2], lerp(scale)) @ trs((0.1, 0.2, 0.3)))
        expected = points @ world[:3, :3].T + world[:3, 3]
        np.testing.assert_allclose(body.vertices_at(t), expected, rtol=0, atol=FLOAT32_SKINNING)


def test_gltf_with_its_buffer_beside_it(tmp_path, rig):
    glb = tmp_path / "rig.glb"
    write_glb(glb, *rig, channels())
    data = glb.read_bytes()
    n = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20:20 + n])
    doc["buffers"][0]["uri"] = "rig.bin"
    (tmp_path / "rig.bin").write_bytes(data[20 + n + 8:])
    (tmp_path / "rig.gltf").write_text(json.dumps(doc))
    for t in (0.0, 0.4):
        np.testing.assert_array_equal(read_animated_body(tmp_path / "rig.gltf").vertices_at(t),
                                      read_animated_body(glb).vertices_at(t))
    (tmp_path / "rig.bin").unlink()
    with fails(tmp_path / "rig.gltf", "rig.bin"):
        read_animated_body(tmp_path / "rig.gltf")


def test_bind_pose_is_what_trimesh_loads(tmp_path, rig):
    trimesh = pytest.importorskip("trimesh")
    glb = tmp_path / "rig.glb"
    write_glb(glb, *rig, channels(), mesh_node_t=(0.5, 0.0, -0.25))  # the mesh node's own transform places it
    body = read_animated_body(glb)
    mesh = trimesh.load(str(glb), force="mesh", process=False)
    np.testing.assert_allclose(body.vertices, mesh.vertices, rtol=0, atol=ROUNDOFF)
    np.testing.assert_array_equal(body.faces, mesh.faces)


# --------------------------------------------------------------------------- samplers in closed form


def test_linear_sampler_lerps_and_slerps():
    times = np.array([1.0, 3.0])
    values = np.array([[0.0, 2.0, -4.0], [1.0, 6.0, 0.0]])
    np.testing.assert_allclose(evaluate_sampler(times, values, "LINEAR", 2.5), [0.75, 5.0, -1.0], atol=ROUNDOFF)
    np.testing.assert_array_equal(evaluate_sampler(times, values, "LINEAR", 0.0), values[0])  # held before
    np.testing.assert_array_equal(evaluate_sampler(times, values, "LINEAR", 9.0), values[1])  # and after
    a, b = axis_angle([0, 0, 1], 0.2), axis_angle([0, 0, 1], 1.4)
    q = evaluate_sampler(times, np.stack([a, b]), "LINEAR", 1.5, rotation=True)  # a quarter of the way
    np.testing.assert_allclose(q, axis_angle([0, 0, 1], 0.2 + 0.25 * 1.2), atol=ROUNDOFF)
    # the shorter arc: -b is the same rotation as b
    np.testing.assert_allclose(slerp(a, -b, 0.25), axis_angle([0, 0, 1], 0.5), atol=ROUNDOFF)


def test_step_sampler_holds_the_previous_key():
    times = np.array([0.0, 1.0, 2.0])
    values = np.array([[1.0], [5.0], [7.0]])
    assert evaluate_sampler(times, values, "STEP", 0.999)[0] == 1.0
    assert evaluate_sampler(times, values, "STEP", 1.0)[0] == 5.0
    assert evaluate_sampler(times, values, "STEP", 1.5)[0] == 5.0


@pytest.mark.parametrize("s", [0.0, 0.3, 0.5, 0.9])
def test_cubicspline_sampler_is_hermite(s):
    # keys at t = 2 and t = 4 (dt = 2); the Hermite cubic through v0 = 1, v1 = 3 with slopes m0 = 0.5 and
    # m1 = -1 per second (out-tangent of key 0, in-tangent of key 1): p(s) = h00 v0 + h10 dt m0 + h01 v1 + h11 dt m1
    dt, v0, v1, m0, m1 = 2.0, 1.0, 3.0, 0.5, -1.0
    values = np.array([[[9.0], [v0], [m0]], [[m1], [v1], [9.0]]])  # (K, [in, value, out], n); 9s unused
    expected = ((2 * s**3 - 3 * s**2 + 1) * v0 + (s**3 - 2 * s**2 + s) * dt * m0 + (-2 * s**3 + 3 * s**2) * v1
                + (s**3 - s**2) * dt * m1)
    got = evaluate_sampler(np.array([2.0, 4.0]), values, "CUBICSPLINE", 2.0 + s * dt)
    np.testing.assert_allclose(got, [expected], rtol=0, atol=ROUNDOFF)


def test_cubicspline_sampler_reproduces_a_cubic_polynomial():
    # p(t) = t^3 - 2t: a Hermite spline whose keys and tangents come from p is p itself
    p, dp = (lambda t: t**3 - 2 * t), (lambda t: 3 * t**2 - 2)
    times = np.array([-1.0, 0.5, 2.0])
    values = np.array([[[dp(t)], [p(t)], [dp(t)]] for t in times])
    for t in np.linspace(-1, 2, 13):
        np.testing.assert_allclose(evaluate_sampler(times, values, "CUBICSPLINE", t), [p(t)], atol=1e-12)


# --------------------------------------------------------------------------- CesiumMan, a real skinned walk

BLENDER_SCRIPT = """
import sys, bpy, numpy as np
path, out = sys.argv[-2], sys.argv[-1]
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_scene.gltf(filepath=path)
scene = bpy.context.scene
mesh = [o for o in scene.objects if o.type == "MESH"][0]
res = {"fps": np.array(scene.render.fps)}
for f in (1, 12, 25, 48):
    scene.frame_set(f)
    o = mesh.evaluated_get(bpy.context.evaluated_depsgraph_get())
    m = o.to_mesh()
    res[f"f{f}"] = np.array([o.matrix_world @ p.co for p in m.vertices])
    o.to_mesh_clear()
np.savez(out, **res)
"""
# Blender stores the keys as float32 f-curves and skins in float32.
BLENDER_SKINNING = 2e-6


def test_cesiumman_against_blender(tmp_path):
    path = real_path("cesiumman", "CesiumMan.glb")
    if not BLENDER.exists():
        pytest.skip(f"Blender as a Python module (bpy) not found at {BLENDER}")
    script = tmp_path / "evaluate.py"
    script.write_text(BLENDER_SCRIPT)
    run = subprocess.run([str(BLENDER), str(script), str(path), str(tmp_path / "blender.npz")],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    blender = np.load(tmp_path / "blender.npz")
    body = read_animated_body(path)
    assert body.n_frames == 48 and body.fps == pytest.approx(24.0) and len(body.joints) == 19
    for frame in (1, 12, 25, 48):  # key frames: Blender interpolates rotations per component between keys
        ours = body.vertices_at(frame / float(blender["fps"]))
        as_z_up = np.c_[ours[:, 0], -ours[:, 2], ours[:, 1]]  # Blender turns glTF's +Y up onto +Z
        np.testing.assert_allclose(blender[f"f{frame}"], as_z_up, rtol=0, atol=BLENDER_SKINNING)


def test_cesiumman_bind_pose_and_timing():
    trimesh = pytest.importorskip("trimesh")
    path = real_path("cesiumman", "CesiumMan.glb")
    body = read_animated_body(path)
    mesh = trimesh.load(str(path), force="mesh", process=False)
    np.testing.assert_allclose(body.vertices, mesh.vertices, rtol=0, atol=ROUNDOFF)
    assert body.times[0] == pytest.approx(1 / 24, abs=1e-6) and body.times[-1] == pytest.approx(2.0)
    start = time.perf_counter()
    body.vertices_at(1.0)
    assert time.perf_counter() - start < 1.0  # one frame of 3,273 vertices and 19 joints: milliseconds


# --------------------------------------------------------------------------- sequences and point caches


def write_obj(path, vertices, faces):
    lines = [f"v {x:.17g} {y:.17g} {z:.17g}" for x, y, z in vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    Path(path).write_text("\n".join(lines) + "\n")


def test_obj_sequence_samples_and_linear_interpolation(tmp_path, rng):
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    frames = {n: rng.normal(size=(4, 3)) for n in (3, 4, 6)}  # frame 5 missing: 4 -> 6 spans two frames
    for n, v in frames.items():
        write_obj(tmp_path / f"body.{n:04d}.obj", v, faces)
    (tmp_path / "notes.txt").write_text("not a frame")
    for given in (tmp_path / "body.####.obj", tmp_path):
        body = read_animated_body(given, fps=30)
        np.testing.assert_allclose(body.times, [3 / 30, 4 / 30, 6 / 30], rtol=0, atol=ROUNDOFF)
        for n, v in frames.items():
            np.testing.assert_allclose(body.vertices_at(n / 30), v, rtol=0, atol=ROUNDOFF)
        np.testing.assert_allclose(body.vertices_at(4.5 / 30), 0.75 * frames[4] + 0.25 * frames[6], atol=ROUNDOFF)
        np.testing.assert_allclose(body.vertices_at(0.0), frames[3], atol=ROUNDOFF)
        assert body.fps == 30 and is_animated_body(given)
    assert "24 fps assumed" in read_animated_body(tmp_path / "body.####.obj").notes[0]


def test_transformed_applies_the_groom_transform_at_every_time(tmp_path, rig):
    from hairinv.config import BodySettings
    from hairinv.groom import body_to_groom

    glb = tmp_path / "rig.glb"
    write_glb(glb, *rig, channels())
    body = read_animated_body(glb)
    # a body in centimetres, +Y up, its X flipped, read into a Z-up groom
    M, _ = body_to_groom(BodySettings(units="cm", up="y", flip="x"), 1.0, "z", "", glb)
    moved = body.transformed(M)
    for t in (0.0, 0.3, 1.0):
        np.testing.assert_allclose(moved.vertices_at(t), body.vertices_at(t) @ M[:3, :3].T + M[:3, 3], atol=ROUNDOFF)
    np.testing.assert_array_equal(moved.faces, body.faces[:, ::-1])  # a mirror: triangles reversed, normals out


def test_ply_folder_sequence(tmp_path, rng):
    trimesh = pytest.importorskip("trimesh")
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    frames = {n: rng.normal(size=(4, 3)).astype(np.float32).astype(np.float64) for n in (10, 11)}  # PLY: float32
    for n, v in frames.items():
        trimesh.Trimesh(v, faces, process=False).export(tmp_path / f"walk_{n}.ply")
    body = read_animated_body(tmp_path, fps=25)
    np.testing.assert_allclose(body.times, [10 / 25, 11 / 25], atol=ROUNDOFF)
    np.testing.assert_allclose(body.vertices_at(10.5 / 25), 0.5 * (frames[10] + frames[11]), atol=ROUNDOFF)


def test_sequence_with_changing_vertex_count_is_refused(tmp_path):
    write_obj(tmp_path / "b.0001.obj", np.zeros((4, 3)), [[0, 1, 2], [0, 2, 3]])
    write_obj(tmp_path / "b.0002.obj", np.zeros((5, 3)), [[0, 1, 2], [0, 2, 4]])
    with fails(tmp_path / "b.0002.obj", "5 vertices", "b.0001.obj", "one topology"):
        read_animated_body(tmp_path / "b.####.obj", fps=24)


def test_usd_point_cache(tmp_path, rng):
    pytest.importorskip("pxr")
    from pxr import Gf, Usd, UsdGeom, Vt

    path = tmp_path / "cache.usda"
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)
    stage.SetTimeCodesPerSecond(48)
    stage.SetFramesPerSecond(24)
    mesh = UsdGeom.Mesh.Define(stage, "/Body")
    mesh.CreateFaceVertexCountsAttr([4])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    samples = {0: rng.normal(size=(4, 3)), 10: rng.normal(size=(4, 3))}
    for code, v in samples.items():
        mesh.GetPointsAttr().Set(Vt.Vec3fArray([Gf.Vec3f(*map(float, p)) for p in v]), code)
    UsdGeom.Xformable(mesh.GetPrim()).AddTranslateOp().Set(Gf.Vec3d(1, 2, 3))
    stage.GetRootLayer().Save()
    body = read_animated_body(path)
    assert body.format == "usd-points" and body.scale_to_m == 0.01 and body.up == "z" and body.fps == 24
    np.testing.assert_allclose(body.times, [0, 10 / 48], atol=ROUNDOFF)
    np.testing.assert_array_equal(body.faces, [[0, 1, 2], [0, 2, 3]])
    f32 = {k: v.astype(np.float32).astype(np.float64) + [1, 2, 3] for k, v in samples.items()}
    np.testing.assert_allclose(body.vertices_at(5 / 48), 0.5 * (f32[0] + f32[10]), rtol=0, atol=FLOAT32_SKINNING)
    np.testing.assert_allclose(body.vertices_at(10 / 48), f32[10], rtol=0, atol=FLOAT32_SKINNING)


def test_usd_point_count_changing_in_time_is_refused(tmp_path):
    pytest.importorskip("pxr")
    from pxr import Gf, Usd, UsdGeom, Vt

    path = tmp_path / "grows.usda"
    stage = Usd.Stage.CreateNew(str(path))
    mesh = UsdGeom.Mesh.Define(stage, "/Body")
    mesh.CreateFaceVertexCountsAttr([3])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2])
    for code, n in ((1, 3), (2, 4)):
        mesh.GetPointsAttr().Set(Vt.Vec3fArray([Gf.Vec3f(float(i), 0, 0) for i in range(n)]), code)
    stage.GetRootLayer().Save()
    with fails(path, "4 points at time code 2", "one topology"):
        read_animated_body(path)


def test_static_files_are_not_animated(tmp_path):
    pytest.importorskip("pxr")
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.CreateNew(str(tmp_path / "still.usda"))
    mesh = UsdGeom.Mesh.Define(stage, "/Body")
    mesh.CreatePointsAttr([(0, 0, 0), (1, 0, 0), (0, 1, 0)])
    stage.GetRootLayer().Save()
    assert not is_animated_body(tmp_path / "still.usda")
    assert not is_animated_body(ROOT / "samples" / "body.obj")
    assert not is_animated_body(tmp_path)  # a folder without frames


# --------------------------------------------------------------------------- bad input, the CLI


def test_truncated_glb_is_refused(tmp_path, rig):
    glb = tmp_path / "rig.glb"
    write_glb(glb, *rig, channels())
    data = glb.read_bytes()
    for cut in (8, 40, len(data) - 10):
        short = tmp_path / f"cut{cut}.glb"
        short.write_bytes(data[:cut])
        with fails(short, "GLB" if cut < 12 else "truncated"):
            read_animated_body(short)


def test_alembic_names_the_usd_route(tmp_path):
    path = tmp_path / "walk.abc"
    path.write_bytes(b"Ogawa\x00")
    assert is_animated_body(path)
    with fails(path, "Alembic", "USD"):
        read_animated_body(path)


def test_info_on_an_animated_body(tmp_path, rig):
    from click.testing import CliRunner

    from hairinv_cli.main import main

    glb = tmp_path / "rig.glb"
    write_glb(glb, *rig, channels())
    result = CliRunner().invoke(main, ["info", str(glb)])
    assert result.exit_code == 0, result.output
    assert "frames: 3 at 2 fps, 0 .. 1 s" in result.output and "joints (3): j0, j1, j2" in result.output
    assert "bounds:" in result.output
    summary = json.loads(CliRunner().invoke(main, ["info", "--json", str(glb)]).output)
    assert summary["frames"] == 3 and summary["joints"] == ["j0", "j1", "j2"]
    short = tmp_path / "short.glb"
    short.write_bytes(glb.read_bytes()[:100])
    result = CliRunner().invoke(main, ["info", str(short)])
    assert result.exit_code == 2 and "short.glb: is truncated" in result.output


def test_an_animated_body_given_where_a_static_one_is_read_is_said_to_be_read_in_its_bind_pose(tmp_path, rig):
    """A skinned GLB given as the body of invert says in one note that the groom is placed on its bind pose and
    that simulate plays the animation (its frames, length and joints, counted independently here from the rig
    written); a static mesh says nothing."""
    from hairinv.pipeline import animated_body_lines

    glb = tmp_path / "rig.glb"
    write_glb(glb, *rig, channels())
    lines = animated_body_lines(glb)
    assert len(lines) == 1 and lines[0].startswith("note: rig.glb is animated"), lines
    assert "simulate` plays the animation" in lines[0]
    assert f"{len(KEYS)} frames over {KEYS[-1] - KEYS[0]:.3g} s, 3 joints" in lines[0] and "bind pose" in lines[0]
    obj = tmp_path / "still.obj"
    write_obj(obj, rig[0], rig[1])
    assert animated_body_lines(obj) == []
