"""Skinned and animated glTF 2.0 bodies (``.glb``, ``.gltf``): linear blend skinning driven by the animation.

A GLB is a 12-byte header (``glTF``, version 2, total length), a JSON chunk and an optional BIN chunk; a
``.gltf`` is the JSON alone, its buffers in files beside it or in ``data:`` URIs. Every mesh instance of the
default scene is read (triangles only) and concatenated in traversal order, as trimesh concatenates them:

- a node with a ``skin``: ``v(t) = sum_k w_k  J_{j_k}(t) B_{j_k} v``, the joints' world matrices ``J`` at ``t``
  (the whole node hierarchy, ancestors of the skeleton included) times their inverse bind matrices ``B``; the
  mesh node's own transform is ignored, as the specification says;
- any other mesh node: its world matrix at ``t`` times its positions.

The animation's samplers are evaluated at ``t`` exactly (:func:`evaluate_sampler`): LINEAR (lerp; slerp for
rotations), STEP and CUBICSPLINE (Hermite with the stored tangents), on translation, rotation and scale. Only
the first animation is played. glTF is metres and +Y up by definition; it has no frame rate, so ``fps`` is
the inverse of the most common key spacing. The rest pose is each mesh placed by its node's own transform,
the pose trimesh (and every static reader) loads.
"""

from __future__ import annotations

import base64
import json
import struct
from pathlib import Path

import numpy as np

from ..errors import InputError
from .animated import AnimatedBody
from .base import register_animated_reader

__all__ = ["read_gltf_animated", "evaluate_sampler", "is_animated_gltf", "read_gltf_document"]

_COMPONENTS = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_JSON, _BIN = 0x4E4F534A, 0x004E4942
_TRIANGLES = 4


def read_gltf_document(path: Path) -> tuple[dict, list[bytes]]:
    """The JSON document and its buffers (bytes) of a ``.glb`` or ``.gltf`` file."""
    path = Path(path)
    data = path.read_bytes()
    if path.suffix.lower() == ".gltf" or data[:1] == b"{":
        doc = _json(data, path)
        return doc, _external_buffers(doc, path, None)
    if len(data) < 12 or data[:4] != b"glTF":
        raise InputError("is not a GLB file (it does not start with the 12-byte 'glTF' header)", path)
    _, version, length = struct.unpack_from("<4sII", data)
    if version != 2:
        raise InputError(f"is a glTF {version} file; only glTF 2.0 is read", path)
    if length > len(data):
        raise InputError(f"is truncated: its header says {length} bytes, the file has {len(data)}", path)
    chunks, offset = [], 12
    while offset + 8 <= length:
        size, kind = struct.unpack_from("<II", data, offset)
        if offset + 8 + size > length:
            raise InputError(f"is truncated: a chunk of {size} bytes at byte {offset} runs past the end", path)
        chunks.append((kind, data[offset + 8: offset + 8 + size]))
        offset += 8 + size
    if not chunks or chunks[0][0] != _JSON:
        raise InputError("has no JSON chunk first, as GLB requires", path)
    doc = _json(chunks[0][1], path)
    binary = chunks[1][1] if len(chunks) > 1 and chunks[1][0] == _BIN else None
    return doc, _external_buffers(doc, path, binary)


def _json(data: bytes, path: Path) -> dict:
    try:
        doc = json.loads(data.decode("utf-8").rstrip(" \x00"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"has a JSON part that cannot be parsed ({exc})", path) from None
    if not isinstance(doc, dict):
        raise InputError("has a JSON part that is not an object", path)
    return doc


def _external_buffers(doc: dict, path: Path, binary: bytes | None) -> list[bytes]:
    buffers = []
    for i, buffer in enumerate(doc.get("buffers", [])):
        uri = buffer.get("uri")
        if uri is None:
            if binary is None:
                raise InputError(f"buffer {i} has no URI and the file has no BIN chunk", path)
            data = binary
        elif uri.startswith("data:"):
            data = base64.b64decode(uri.partition(",")[2])
        else:
            source = path.parent / uri
            if not source.is_file():
                raise InputError(f"names a buffer file {uri!r} that is not beside it", path)
            data = source.read_bytes()
        if len(data) < buffer.get("byteLength", 0):
            raise InputError(f"is truncated: buffer {i} holds {len(data)} of its {buffer['byteLength']} bytes", path)
        buffers.append(data)
    return buffers


class _Reader:
    """Accessors of one document, decoded to numpy with the file named in every error."""

    def __init__(self, doc: dict, buffers: list[bytes], path: Path):
        self.doc, self.buffers, self.path = doc, buffers, path

    def accessor(self, index: int, integer: bool = False) -> np.ndarray:
        """Accessor ``index`` as (count, width): float64 (normalized integers scaled as glTF says) or, with
        ``integer``, int64."""
        try:
            acc = self.doc["accessors"][index]
            dtype = np.dtype(_COMPONENTS[acc["componentType"]]).newbyteorder("<")
            width, count = _WIDTH[acc["type"]], int(acc["count"])
        except (KeyError, IndexError, TypeError):
            raise InputError(f"has a malformed or missing accessor {index}", self.path) from None
        if "sparse" in acc:
            raise InputError(f"accessor {index} is sparse, which is not read", self.path)
        if "bufferView" not in acc:
            values = np.zeros((count, width), dtype)
        else:
            view = self.doc["bufferViews"][acc["bufferView"]]
            data = self.buffers[view["buffer"]]
            start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
            stride = view.get("byteStride") or width * dtype.itemsize
            end = start + stride * (count - 1) + width * dtype.itemsize if count else start
            if end > view.get("byteOffset", 0) + view["byteLength"] or end > len(data):
                raise InputError(f"is truncated: accessor {index} runs past the end of its buffer", self.path)
            values = np.ndarray((count, width), dtype, buffer=data, offset=start, strides=(stride, dtype.itemsize))
        if integer:
            return values.astype(np.int64)
        out = values.astype(np.float64)
        if acc.get("normalized") and dtype.kind in "iu":
            info = np.iinfo(dtype)
            out = np.maximum(out / info.max, -1.0)
        return out


# --------------------------------------------------------------------------- transforms


def quaternion_matrix(q) -> np.ndarray:
    """3x3 rotation of a unit quaternion ``(x, y, z, w)``, glTF's order."""
    x, y, z, w = np.asarray(q, dtype=np.float64) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def trs_matrix(translation, rotation, scale) -> np.ndarray:
    """The 4x4 ``T R S`` of a glTF node."""
    M = np.eye(4)
    M[:3, :3] = quaternion_matrix(rotation) * np.asarray(scale, dtype=np.float64)
    M[:3, 3] = translation
    return M


def slerp(a: np.ndarray, b: np.ndarray, s: float) -> np.ndarray:
    """Spherical linear interpolation of unit quaternions along the shorter arc (glTF's LINEAR rotation)."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    d = float(np.dot(a, b))
    if d < 0.0:
        b, d = -b, -d
    if d > 1.0 - 1e-12:  # (nearly) the same rotation: the chord is the arc to round-off
        q = (1.0 - s) * a + s * b
        return q / np.linalg.norm(q)
    theta = np.arccos(min(d, 1.0))
    return (np.sin((1.0 - s) * theta) * a + np.sin(s * theta) * b) / np.sin(theta)


def evaluate_sampler(times: np.ndarray, values: np.ndarray, interpolation: str, t: float,
                     rotation: bool = False) -> np.ndarray:
    """A glTF animation sampler's output at time ``t`` (held at the first/last key outside the keys).

    Parameters
    ----------
    times : (K,) float64, seconds, increasing
    values : (K, n) float64 for LINEAR and STEP; (K, 3, n) for CUBICSPLINE (in-tangent, value, out-tangent)
    interpolation : ``"LINEAR"``, ``"STEP"`` or ``"CUBICSPLINE"``
    rotation : quaternions ``(x, y, z, w)``: LINEAR slerps, CUBICSPLINE normalises its result
    """
    cubic = interpolation == "CUBICSPLINE"
    point = values[:, 1] if cubic else values
    if t <= times[0] or len(times) == 1:
        return point[0].copy()
    if t >= times[-1]:
        return point[-1].copy()
    k = int(np.searchsorted(times, t, side="right")) - 1
    dt = times[k + 1] - times[k]
    s = (t - times[k]) / dt
    if interpolation == "STEP":
        return point[k].copy()
    if interpolation == "LINEAR":
        return slerp(point[k], point[k + 1], s) if rotation else (1.0 - s) * point[k] + s * point[k + 1]
    # Hermite: p0 = v_k, m0 = dt b_k (out-tangent of k), p1 = v_{k+1}, m1 = dt a_{k+1} (in-tangent of k+1)
    s2, s3 = s * s, s * s * s
    out = ((2 * s3 - 3 * s2 + 1) * values[k, 1] + (s3 - 2 * s2 + s) * dt * values[k, 2]
           + (-2 * s3 + 3 * s2) * values[k + 1, 1] + (s3 - s2) * dt * values[k + 1, 0])
    return out / np.linalg.norm(out) if rotation else out


# --------------------------------------------------------------------------- the document as a rig


class _Rig:
    """Nodes, animation channels and mesh instances of a glTF document, evaluated at any time."""

    def __init__(self, doc: dict, buffers: list[bytes], path: Path):
        self.path = path
        reader = _Reader(doc, buffers, path)
        nodes = doc.get("nodes", [])
        self.names = [node.get("name", f"node{i}") for i, node in enumerate(nodes)]
        self.trs, self.fixed = [], []
        for node in nodes:
            if "matrix" in node:
                self.fixed.append(np.array(node["matrix"], dtype=np.float64).reshape(4, 4).T)  # column-major
                self.trs.append(None)
            else:
                trs = (np.array(node.get("translation", [0, 0, 0]), dtype=np.float64),
                       np.array(node.get("rotation", [0, 0, 0, 1]), dtype=np.float64),
                       np.array(node.get("scale", [1, 1, 1]), dtype=np.float64))
                self.trs.append(trs)
                self.fixed.append(trs_matrix(*trs))
        self.order = self._traversal(doc, nodes)
        self.notes = []
        self.channels = self._channels(doc, reader)
        animations = doc.get("animations", [])
        if len(animations) > 1:
            self.notes.append(f"the file holds {len(animations)} animations; the first is played")
        self.instances = self._instances(doc, reader)

    def _traversal(self, doc, nodes) -> list[tuple[int, int]]:
        """(node, parent or -1) in depth-first order from the default scene's roots."""
        scenes = doc.get("scenes", [])
        if scenes:
            roots = scenes[doc.get("scene", 0)].get("nodes", [])
        else:
            children = {c for node in nodes for c in node.get("children", [])}
            roots = [i for i in range(len(nodes)) if i not in children]
        order, stack, seen = [], [(r, -1) for r in reversed(roots)], set()
        while stack:
            node, parent = stack.pop()
            if node in seen or not 0 <= node < len(nodes):
                raise InputError(f"has a node hierarchy that is not a tree (node {node})", self.path)
            seen.add(node)
            order.append((node, parent))
            stack.extend((c, node) for c in reversed(nodes[node].get("children", [])))
        return order

    def _channels(self, doc, reader) -> list[tuple[int, str, np.ndarray, np.ndarray, str]]:
        animations = doc.get("animations", [])
        if not animations:
            return []
        animation, channels = animations[0], []
        for channel in animation.get("channels", []):
            target = channel.get("target", {})
            node, what = target.get("node"), target.get("path")
            if node is None or what not in ("translation", "rotation", "scale"):
                continue  # morph-target weights and extension targets do not move vertices we read
            if self.trs[node] is None:
                raise InputError(f"animates node {self.names[node]!r}, which has a matrix (glTF forbids it)",
                                 self.path)
            sampler = animation["samplers"][channel["sampler"]]
            interpolation = sampler.get("interpolation", "LINEAR")
            if interpolation not in ("LINEAR", "STEP", "CUBICSPLINE"):
                raise InputError(f"has an animation sampler with unknown interpolation {interpolation!r}", self.path)
            times = reader.accessor(sampler["input"])[:, 0]
            values = reader.accessor(sampler["output"])
            if interpolation == "CUBICSPLINE":
                values = values.reshape(len(times), 3, values.shape[1])
            elif len(values) != len(times):
                raise InputError(f"has a sampler with {len(times)} key times and {len(values)} values", self.path)
            if len(times) == 0 or np.any(np.diff(times) <= 0):
                raise InputError("has a sampler whose key times do not increase", self.path)
            channels.append((node, what, times, values, interpolation))
        return channels

    def _instances(self, doc, reader) -> list[dict]:
        instances, nodes = [], doc.get("nodes", [])
        for node, _ in self.order:
            if "mesh" not in nodes[node]:
                continue
            skin = doc["skins"][nodes[node]["skin"]] if "skin" in nodes[node] else None
            for primitive in doc["meshes"][nodes[node]["mesh"]].get("primitives", []):
                mode = primitive.get("mode", _TRIANGLES)
                if mode != _TRIANGLES:
                    continue  # points and lines bound no volume
                attributes = primitive["attributes"]
                if "POSITION" not in attributes:
                    raise InputError(f"has a primitive of mesh node {self.names[node]!r} without POSITION", self.path)
                positions = reader.accessor(attributes["POSITION"])
                if "indices" in primitive:
                    faces = reader.accessor(primitive["indices"], integer=True).reshape(-1, 3)
                else:
                    faces = np.arange(len(positions) // 3 * 3, dtype=np.int64).reshape(-1, 3)
                if len(faces) and (faces.min() < 0 or faces.max() >= len(positions)):
                    raise InputError(f"mesh node {self.names[node]!r} has indices past its vertices", self.path)
                if primitive.get("targets") and not any("morph" in note for note in self.notes):
                    self.notes.append("morph targets are not applied (the skin and the node motion are)")
                instance = {"node": node, "positions": positions, "faces": faces}
                if skin is not None:
                    instance.update(self._skinning(skin, attributes, reader, node, len(positions)))
                instances.append(instance)
        if not instances:
            raise InputError("holds no triangle mesh in its default scene", self.path)
        return instances

    def _skinning(self, skin, attributes, reader, node, n) -> dict:
        sets = sorted(int(k.split("_")[1]) for k in attributes if k.startswith("JOINTS_"))
        if not sets:
            raise InputError(f"mesh node {self.names[node]!r} has a skin but no JOINTS_0", self.path)
        joints = np.hstack([reader.accessor(attributes[f"JOINTS_{s}"], integer=True) for s in sets])
        weights = np.hstack([reader.accessor(attributes[f"WEIGHTS_{s}"]) for s in sets])
        joint_nodes = np.asarray(skin["joints"], dtype=np.int64)
        if joints.shape != weights.shape or len(joints) != n:
            raise InputError(f"mesh node {self.names[node]!r} has joints and weights of different sizes", self.path)
        if joints.size and (joints.min() < 0 or joints.max() >= len(joint_nodes)):
            raise InputError(f"mesh node {self.names[node]!r} names joints its skin does not have", self.path)
        if "inverseBindMatrices" in skin:
            inverse_bind = reader.accessor(skin["inverseBindMatrices"]).reshape(-1, 4, 4).transpose(0, 2, 1)
        else:
            inverse_bind = np.broadcast_to(np.eye(4), (len(joint_nodes), 4, 4))
        return {"joint_nodes": joint_nodes, "inverse_bind": np.ascontiguousarray(inverse_bind),
                "joints": joints, "weights": weights}

    @property
    def joint_names(self) -> tuple[str, ...]:
        seen = []
        for instance in self.instances:
            for j in instance.get("joint_nodes", ()):
                if self.names[j] not in seen:
                    seen.append(self.names[j])
        return tuple(seen)

    def times(self) -> np.ndarray:
        if not self.channels:
            return np.zeros(1)
        return np.unique(np.concatenate([times for _, _, times, _, _ in self.channels]))

    def world(self, t: float | None) -> list[np.ndarray]:
        """World matrices of every node at ``t`` (None: the nodes' own transforms, the rest pose)."""
        local = list(self.fixed)
        if t is not None and self.channels:
            trs = {}
            for node, what, times, values, interpolation in self.channels:
                current = trs.setdefault(node, list(self.trs[node]))
                k = ("translation", "rotation", "scale").index(what)
                current[k] = evaluate_sampler(times, values, interpolation, t, rotation=what == "rotation")
            for node, (translation, rotation, scale) in trs.items():
                local[node] = trs_matrix(translation, rotation, scale)
        world = [None] * len(local)
        for node, parent in self.order:
            world[node] = local[node] if parent < 0 else world[parent] @ local[node]
        return world

    def vertices(self, t: float | None) -> np.ndarray:
        world = self.world(t)
        out = []
        for instance in self.instances:
            p = instance["positions"]
            if t is None or "joint_nodes" not in instance:
                M = world[instance["node"]]
                out.append(p @ M[:3, :3].T + M[:3, 3])
                continue
            # linear blend skinning: sum_k w_k (J_k B_k) [p, 1]
            skinning = np.stack([world[j] for j in instance["joint_nodes"]]) @ instance["inverse_bind"]
            blended = np.einsum("vk,vkab->vab", instance["weights"], skinning[instance["joints"]][:, :, :3, :])
            out.append(np.einsum("vab,vb->va", blended[:, :, :3], p) + blended[:, :, 3])
        return np.concatenate(out)

    def faces(self) -> np.ndarray:
        faces, base = [], 0
        for instance in self.instances:
            faces.append(instance["faces"] + base)
            base += len(instance["positions"])
        return np.concatenate(faces)


def _rig(path: Path) -> _Rig:
    doc, buffers = read_gltf_document(path)
    try:
        return _Rig(doc, buffers, path)
    except (KeyError, IndexError, TypeError, ValueError) as exc:
        raise InputError(f"has a glTF document that cannot be read ({type(exc).__name__}: {exc})", path) from None


def is_animated_gltf(path: Path) -> bool:
    """Whether a glTF file has a skin or an animation (else it is a static body, read by trimesh); a file that
    is not readable glTF raises the reader's :class:`InputError` (truncated, not GLB ...)."""
    doc, _ = read_gltf_document(path)
    return bool(doc.get("skins") or doc.get("animations"))


@register_animated_reader(".glb", ".gltf", probe=is_animated_gltf)
def read_gltf_animated(path: Path, fps: float | None = None) -> AnimatedBody:
    """Read a skinned and/or animated glTF body; ``fps`` overrides the rate guessed from the key spacing."""
    path = Path(path)
    rig = _rig(path)
    times = rig.times()
    notes = list(rig.notes)
    if fps is None and len(times) > 1:
        spacing = np.diff(times)
        fps = float(np.round(1.0 / np.median(spacing), 3))
        notes.append(f"glTF states no frame rate: {fps:g} fps from the key spacing")
    return AnimatedBody(
        vertices=rig.vertices(None), faces=rig.faces(), times=times, fps=fps,
        format="gltf-skin" if rig.joint_names else "gltf-animated", evaluate=rig.vertices,
        joints=rig.joint_names, scale_to_m=1.0, up="y", notes=tuple(notes),
    )
