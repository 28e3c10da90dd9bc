"""Import USD files into Blender headless and say what came in, as JSON.

Runs inside Blender's Python (the ``bpy`` module of ``make blender``'s .venv-blender), not hairinv's::

    .venv-blender/bin/python tests/blender_read_usd.py OUT.usda [OUT2.usdc ...] [--json FILE] [--npz FILE]
        [--frames start,end|all|N,M,...] [--sample N] [--repeat N] [--tessellate]

For each file: an empty scene (``read_factory_settings(use_empty=True)``), ``bpy.ops.wm.usd_import`` with
its default options (as File > Import > USD), then

- ``blender``: Blender's version; ``scene``: frame range, fps and unit settings after the import;
- ``objects``: each imported object with its type, parent, world matrix, modifiers and constraints (the
  cache file and USD path they read); curves objects (Blender's hair ``Curves`` type) with their curve and
  point counts, points per curve (min, max), their attributes (name, domain, type, min and max) and the
  world-space points of ``--sample`` curves spread over the groom; meshes with their vertex and face counts
  and face sizes;
- ``frames``: for each frame asked for (``--frames``, by default the scene's first and last), the
  evaluated objects (cache modifiers and constraints applied): world-space sample points, world matrix,
  and the largest distance any point moved since the first frame asked for;
- ``tessellated`` (with ``--tessellate``, after the frames): each curves object converted to a mesh, i.e.
  its curves evaluated as Blender draws them (curve type, resolution), vertex count;
- ``import_seconds``: the operator's wall time, one per ``--repeat`` (each on a fresh empty scene).

``--npz FILE`` also writes every point in world space: ``<file index>/<object>/points`` (as imported),
``/counts`` (points per curve), ``/frame<N>`` (evaluated at frame N), ``/attr/<name>`` (each other attribute
as stored: vectors in the object's local space), ``/tessellated``; meshes' vertices likewise.
World space is Blender's: metres (the importer's unit scale on the root object), +Z up.
"""

from __future__ import annotations

import json
import sys
import time

import bpy
import numpy as np


def _args(argv):
    files, opts = [], {"json": None, "npz": None, "frames": "start,end", "sample": 4, "repeat": 1, "tessellate": False}
    it = iter(argv)
    for arg in it:
        if arg == "--tessellate":
            opts["tessellate"] = True
        elif arg.startswith("--"):
            key = arg[2:]
            if key not in opts:
                raise SystemExit(f"unknown option {arg}")
            opts[key] = next(it)
        else:
            files.append(arg)
    opts["sample"], opts["repeat"] = int(opts["sample"]), int(opts["repeat"])
    return files, opts


def _matrix(obj) -> np.ndarray:
    return np.array(obj.matrix_world, dtype=np.float64)


def _world(points: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    return points @ matrix[:3, :3].T + matrix[:3, 3]


def _positions(data, kind: str) -> np.ndarray:
    if kind == "CURVES":
        out = np.empty(len(data.points) * 3, dtype=np.float32)
        data.attributes["position"].data.foreach_get("vector", out)
    else:
        out = np.empty(len(data.vertices) * 3, dtype=np.float32)
        data.vertices.foreach_get("co", out)
    return out.reshape(-1, 3).astype(np.float64)


def _offsets(data) -> np.ndarray:
    out = np.empty(len(data.curves) + 1, dtype=np.int64)
    values = np.empty(len(data.curves) + 1, dtype=np.int32)
    data.curve_offset_data.foreach_get("value", values)
    out[:] = values
    return out


_KINDS = {"FLOAT": ("value", 1, np.float32), "INT": ("value", 1, np.int32), "INT8": ("value", 1, np.int32),
          "BOOLEAN": ("value", 1, bool), "FLOAT_VECTOR": ("vector", 3, np.float32)}


def _values(attr) -> np.ndarray:
    """An attribute's values as stored (the object's local space for vectors), float64; empty if not numeric."""
    if attr.data_type not in _KINDS or not len(attr.data):
        return np.zeros(0)
    field, width, dtype = _KINDS[attr.data_type]
    values = np.empty(len(attr.data) * width, dtype=dtype)
    attr.data.foreach_get(field, values)
    values = values.astype(np.float64)
    return values.reshape(-1, 3) if width == 3 else values


def _attribute(attr) -> dict:
    out = {"name": attr.name, "domain": attr.domain, "data_type": attr.data_type, "size": len(attr.data)}
    values = _values(attr)
    if values.size:
        out["min"], out["max"] = float(values.min()), float(values.max())
        out["first"] = values[:3].tolist()
    return out


def _sample(n_curves: int, n: int) -> list[int]:
    return sorted(set(np.linspace(0, n_curves - 1, min(n, n_curves)).round().astype(int).tolist()))


def _frames(spec: str, scene) -> list[int]:
    start, end = scene.frame_start, scene.frame_end
    if spec == "all":
        return list(range(start, end + 1))
    if spec == "start,end":
        return sorted({start, end})
    return [int(f) for f in spec.split(",")]


def _object(obj, sample: list[int] | None, arrays: dict, prefix: str) -> dict:
    matrix = _matrix(obj)
    out = {"name": obj.name, "type": obj.type, "parent": obj.parent.name if obj.parent else None,
           "matrix_world": matrix.tolist(),
           "modifiers": [{"type": m.type, "object_path": getattr(m, "object_path", None),
                          "cache_file": m.cache_file.filepath if getattr(m, "cache_file", None) else None}
                         for m in obj.modifiers],
           "constraints": [{"type": c.type, "object_path": getattr(c, "object_path", None),
                            "cache_file": c.cache_file.filepath if getattr(c, "cache_file", None) else None}
                           for c in obj.constraints],
           "hidden": {"viewport": obj.hide_viewport, "render": obj.hide_render},
           "custom_properties": sorted(obj.keys()) + sorted(obj.data.keys() if obj.data else [])}
    data = obj.data
    if obj.type == "CURVES":
        offsets = _offsets(data)
        counts = np.diff(offsets)
        points = _world(_positions(data, "CURVES"), matrix)
        out.update(curves=len(data.curves), points=len(data.points),
                   points_per_curve={"min": int(counts.min()), "max": int(counts.max())},
                   attributes=[_attribute(a) for a in data.attributes],
                   sample={str(k): points[offsets[k]:offsets[k + 1]].tolist() for k in sample or []})
        arrays[f"{prefix}/{obj.name}/points"] = points
        arrays[f"{prefix}/{obj.name}/counts"] = counts
        for attr in data.attributes:
            if attr.name not in ("position", "curve_type") and not attr.name.startswith("."):
                arrays[f"{prefix}/{obj.name}/attr/{attr.name}"] = _values(attr)
    elif obj.type == "MESH":
        sizes = np.empty(len(data.polygons), dtype=np.int32)
        data.polygons.foreach_get("loop_total", sizes)
        out.update(vertices=len(data.vertices), faces=len(data.polygons),
                   face_sizes={str(int(s)): int((sizes == s).sum()) for s in np.unique(sizes)},
                   attributes=[a.name for a in data.attributes if not a.name.startswith(".")])
        arrays[f"{prefix}/{obj.name}/points"] = _world(_positions(data, "MESH"), matrix)
    return out


def _evaluated(obj, depsgraph, sample, arrays, prefix, frame, first) -> dict:
    ev = obj.evaluated_get(depsgraph)
    matrix = np.array(ev.matrix_world, dtype=np.float64)
    points = _world(_positions(ev.data, obj.type), matrix)
    out = {"matrix_world": matrix.tolist(), "points": len(points), "visible": obj.visible_get()}
    if obj.type == "CURVES":
        offsets = _offsets(ev.data)
        out["curves"] = len(offsets) - 1
        out["sample"] = {str(k): points[offsets[k]:offsets[k + 1]].tolist() for k in sample or []}
    key = f"{prefix}/{obj.name}/frame{frame}"
    arrays[key] = points
    if first is not None and first.shape == points.shape:
        out["moved_since_first"] = float(np.linalg.norm(points - first, axis=1).max())
    return out


def read(path: str, opts: dict, index: int, arrays: dict) -> dict:
    seconds = []
    for _ in range(opts["repeat"]):
        bpy.ops.wm.read_factory_settings(use_empty=True)
        start = time.perf_counter()
        result = bpy.ops.wm.usd_import(filepath=path)
        seconds.append(time.perf_counter() - start)
    scene = bpy.context.scene
    prefix = str(index)
    out = {"file": path, "result": sorted(result), "import_seconds": seconds,
           "scene": {"frame_start": scene.frame_start, "frame_end": scene.frame_end,
                     "frame_current": scene.frame_current, "fps": scene.render.fps,
                     "fps_base": scene.render.fps_base, "unit_system": scene.unit_settings.system,
                     "scale_length": scene.unit_settings.scale_length},
           "cache_files": [{"name": c.name, "filepath": c.filepath, "scale": c.scale, "is_sequence": c.is_sequence}
                           for c in bpy.data.cache_files],
           "materials": [m.name for m in bpy.data.materials]}
    samples = {o.name: _sample(len(o.data.curves), opts["sample"]) for o in bpy.data.objects if o.type == "CURVES"}
    out["objects"] = [_object(o, samples.get(o.name), arrays, prefix) for o in sorted(bpy.data.objects,
                                                                                    key=lambda o: o.name)]
    frames, firsts = {}, {}
    start = time.perf_counter()
    for n, frame in enumerate(_frames(opts["frames"], scene)):
        scene.frame_set(frame)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        frames[str(frame)] = {o.name: _evaluated(o, depsgraph, samples.get(o.name), arrays, prefix, frame,
                                                 firsts.get(o.name))
                              for o in bpy.data.objects if o.type in ("CURVES", "MESH")}
        if n == 0:
            firsts = {o.name: arrays[f"{prefix}/{o.name}/frame{frame}"] for o in bpy.data.objects
                      if o.type in ("CURVES", "MESH")}
    out["frames"] = frames
    out["frames_seconds"] = time.perf_counter() - start
    if opts["tessellate"]:
        out["tessellated"] = {name: _tessellate(bpy.data.objects[name], arrays, prefix) for name in samples}
    return out


def _tessellate(obj, arrays: dict, prefix: str) -> dict:
    """The curves as Blender draws them: the object converted to a mesh (Object > Convert > Mesh) at the current
    frame, each curve evaluated at its type and resolution; its vertices in world space as ``<name>/tessellated``."""
    types = obj.data.attributes.get("curve_type")
    kinds = sorted({d.value for d in types.data}) if types else [0]  # absent: every curve Catmull-Rom (0)
    resolution = obj.data.attributes.get("resolution")
    resolutions = sorted({d.value for d in resolution.data}) if resolution else [12]  # absent: 12
    for other in bpy.context.view_layer.objects:
        other.select_set(False)
    obj.select_set(True)
    bpy.context.view_layer.objects.active = obj
    name = obj.name
    bpy.ops.object.convert(target="MESH")
    mesh = bpy.data.objects[name]
    points = _world(_positions(mesh.data, "MESH"), _matrix(mesh))
    arrays[f"{prefix}/{name}/tessellated"] = points
    return {"curve_types": [{0: "CATMULL_ROM", 1: "POLY", 2: "BEZIER", 3: "NURBS"}.get(k, str(k)) for k in kinds],
            "resolution": resolutions, "points": len(points), "edges": len(mesh.data.edges)}


def main(argv) -> int:
    files, opts = _args(argv)
    arrays: dict[str, np.ndarray] = {}
    report = {"blender": bpy.app.version_string, "files": [read(f, opts, i, arrays) for i, f in enumerate(files)]}
    text = json.dumps(report)
    if opts["json"]:
        with open(opts["json"], "w") as fh:
            fh.write(text)
    else:
        print(text)
    if opts["npz"]:
        np.savez(opts["npz"], **arrays)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
