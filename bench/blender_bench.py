"""Benchmark: Blender (the ``bpy`` module of ``make blender``) imports hairinv's USD export of real grooms.

Run alone with ``python bench/blender_bench.py`` (prints the markdown section), or through
``bench/run.py blender``, which writes the section "Blender reads the USD export" of ``docs/benchmarks.md``.

The stage files, made through the command line in ``out/blender_bench/``:

* ruby long (TressFX 2, ``--scale 0.002``), 500 guide strands inverted on its head mesh, and a still
  simulation of 1 s at 30 fps: exported with everything (input, rest shape, 31 frames, the head) as
  ``.usdc`` and ``.usda``;
* ruby long, all 3,000 strands fitted (``--quality draft``): the input shape only, ``.usdc``;
* the sample ``settled_curly`` inverted on ``samples/body.obj`` and the ``motion`` scene for 1 s at 30 fps
  (the bust turns and leans, the hair follows): ``.usdc``;
* the ruby run again with ``basis="catmull-rom"`` (pinned Catmull-Rom cubics, through the library), whose
  curves Blender also tessellates (``--tessellate``): compared with USD's pinned Catmull-Rom.

Each USD file is read twice: with pxr (what was written: counts, points, time samples, the body's points
and transforms) and in Blender, by ``tests/blender_read_usd.py`` in .venv-blender, which imports it
``REPEATS`` times into an empty scene (median import time), then evaluates every frame. Blender's world
positions are compared with pxr's after the conversion Blender applies (metersPerUnit as the root's scale,
+Y up turned +90 degrees about X).
"""

from __future__ import annotations

import json
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from common import DATA, ROOT, WORK as BENCH_WORK, log, machine, machine_markdown, smoke, table  # type: ignore
else:
    from .common import DATA, ROOT, WORK as BENCH_WORK, log, machine, machine_markdown, smoke, table

sys.path.insert(0, str(ROOT))

TITLE = "Blender reads the USD export"
HAIRINV = ROOT / ".venv" / "bin" / "hairinv"
BLENDER_PYTHON = Path(os.environ.get("HAIRINV_BLENDER_PYTHON", ROOT / ".venv-blender" / "bin" / "python"))
SCRIPT = ROOT / "tests" / "blender_read_usd.py"
WORK = BENCH_WORK / "blender_bench"
RUBY = DATA / "ruby" / "ruby_long_hair_16_guide.tfx"
RUBY_HEAD = DATA / "ruby" / "ruby_head.obj"
GUIDES = smoke(500, 10)
SECONDS, FPS = 1.0, 30
REPEATS = smoke(5, 1)
CATMULL = "ruby.still.catmull-rom.usdc"
# Blender is +Z up: a +Y up stage is turned by +90 degrees about X, (x, y, z) -> (x, -z, y).
Y_TO_Z = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def _hairinv(*args) -> float:
    start = time.perf_counter()
    result = subprocess.run([str(HAIRINV), "-q", *map(str, args)], cwd=WORK, capture_output=True, text=True)
    if result.returncode != 0:
        raise RuntimeError(f"hairinv {' '.join(map(str, args))}: {result.stderr.strip()}")
    return time.perf_counter() - start


def _written(path: Path) -> dict:
    """What the USD file holds, read with pxr: metres per unit, the turn onto Blender's +Z, and for each prim its
    points (per time code where animated) and counts; the body's points placed by its transform per time."""
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(path))
    mpu = UsdGeom.GetStageMetersPerUnit(stage)
    turn = Y_TO_Z if UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y else np.eye(3)
    out = {"mpu": mpu, "turn": turn, "up": str(UsdGeom.GetStageUpAxis(stage)),
           "fps": stage.GetTimeCodesPerSecond() if stage.HasAuthoredTimeCodeRange() else None,
           "range": (stage.GetStartTimeCode(), stage.GetEndTimeCode()) if stage.HasAuthoredTimeCodeRange() else None,
           "prims": {}}
    for prim in stage.Traverse():
        if prim.IsA(UsdGeom.BasisCurves):
            curves = UsdGeom.BasisCurves(prim)
            attr = curves.GetPointsAttr()
            codes = attr.GetTimeSamples()
            frames = {int(c): np.array(attr.Get(Usd.TimeCode(c)), dtype=np.float64) for c in codes}
            out["prims"][prim.GetName()] = {
                "kind": "curves", "counts": np.array(curves.GetCurveVertexCountsAttr().Get()),
                "default": np.array(attr.Get(Usd.TimeCode.Default()), dtype=np.float64), "frames": frames,
                "widths": np.array(curves.GetWidthsAttr().Get(), dtype=np.float64),
                "type": str(curves.GetTypeAttr().Get()), "basis": str(curves.GetBasisAttr().Get()),
                "wrap": str(curves.GetWrapAttr().Get()),
                "primvars": sorted(p.GetPrimvarName() for p in UsdGeom.PrimvarsAPI(prim).GetAuthoredPrimvars())}
        elif prim.IsA(UsdGeom.Mesh):
            mesh = UsdGeom.Mesh(prim)
            points = np.array(mesh.GetPointsAttr().Get(), dtype=np.float64)
            transform = prim.GetAttribute("xformOp:transform")
            codes = transform.GetTimeSamples() if transform else []
            placed = {}
            for c in codes or [None]:
                M = np.array(UsdGeom.Xformable(prim).GetLocalTransformation(
                    Usd.TimeCode(c) if c is not None else Usd.TimeCode.Default()))
                placed[int(c) if c is not None else None] = points @ M[:3, :3] + M[3, :3]  # USD: row vectors
            out["prims"][prim.GetName()] = {"kind": "mesh", "faces": len(mesh.GetFaceVertexCountsAttr().Get()),
                                            "vertices": len(points), "placed": placed}
    return out


def _blender(path: Path, animated: bool, tessellate: bool = False) -> tuple[dict, dict, float]:
    json_out, npz_out = path.with_suffix(".blender.json"), path.with_suffix(".blender.npz")
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    start = time.perf_counter()
    result = subprocess.run([str(BLENDER_PYTHON), str(SCRIPT), str(path), "--repeat", str(REPEATS),
                             "--frames", "all" if animated else "start,end", "--json", str(json_out),
                             "--npz", str(npz_out), *(["--tessellate"] if tessellate else [])],
                            capture_output=True, text=True, env=env)
    wall = time.perf_counter() - start
    if result.returncode != 0:
        raise RuntimeError(f"Blender on {path.name}: {result.stderr.strip()[-2000:]}")
    report = json.loads(json_out.read_text())
    arrays = {k.split("/", 1)[1]: v for k, v in np.load(npz_out).items()}
    return report, arrays, wall


def _world(points: np.ndarray, written: dict) -> np.ndarray:
    return (points * written["mpu"]) @ written["turn"].T


def _catmull_rom(p0, p1, p2, p3, t):
    """The uniform Catmull-Rom segment from p1 (t = 0) to p2 (t = 1), for arrays of segments (S, 3)."""
    t = np.asarray(t, dtype=np.float64)[None, :, None]
    p0, p1, p2, p3 = (p[:, None, :] for p in (p0, p1, p2, p3))
    return 0.5 * (2 * p1 + (p2 - p0) * t + (2 * p0 - 5 * p1 + 4 * p2 - p3) * t ** 2
                  + (3 * p1 - p0 - 3 * p2 + p3) * t ** 3)


def drawn_against_pinned(points: np.ndarray, counts: np.ndarray, drawn: np.ndarray, resolution: int) -> dict:
    """Blender's tessellation of Catmull-Rom curves (``drawn``, ``resolution`` points per segment) against USD's
    pinned Catmull-Rom through the same ``points``: the largest distance at the same parameter on the inner
    segments, and on the end segments both at the same parameter and to the pinned curve (its shape);
    and on the end segments the largest distance to Blender's own rule, the end point repeated."""
    t = np.arange(resolution + 1) / resolution
    dense = np.linspace(0.0, 1.0, 2001)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    drawn_starts = np.concatenate([[0], np.cumsum((counts - 1) * resolution + 1)[:-1]])
    inner, end_param, end_shape, end_repeated = 0.0, 0.0, 0.0, 0.0
    for start, at, n in zip(starts, drawn_starts, counts):
        P = points[start:start + n]
        pinned = np.vstack([2 * P[0] - P[1], P, 2 * P[-1] - P[-2]])
        repeated = np.vstack([P[0], P, P[-1]])
        segments = drawn[at:at + (n - 1) * resolution + 1]
        blender = np.stack([segments[i * resolution:(i + 1) * resolution + 1] for i in range(n - 1)])
        usd = _catmull_rom(pinned[:-3], pinned[1:-2], pinned[2:-1], pinned[3:], t)
        if n > 3:
            inner = max(inner, float(np.abs(blender[1:-1] - usd[1:-1]).max()))
        for i in (0, n - 2):
            end_param = max(end_param, float(np.linalg.norm(blender[i] - usd[i], axis=1).max()))
            curve = _catmull_rom(*(pinned[i + j:i + j + 1] for j in range(4)), dense)[0]
            end_shape = max(end_shape, float(np.linalg.norm(blender[i][:, None] - curve[None], axis=2).min(1).max()))
            own = _catmull_rom(*(repeated[i + j:i + j + 1] for j in range(4)), t)[0]
            end_repeated = max(end_repeated, float(np.linalg.norm(blender[i] - own, axis=1).max()))
    segment = np.median(np.linalg.norm(np.diff(points, axis=0), axis=1))
    return {"inner_m": inner, "end_parameter_m": end_param, "end_shape_m": end_shape,
            "end_repeated_m": end_repeated, "median_segment_m": float(segment)}


def compare(path: Path, written: dict, report: dict, arrays: dict) -> dict:
    """Counts read against written, the largest distance between Blender's points and pxr's (over every point
    and frame), what the importer did with each prim and primvar."""
    read = report["files"][0]
    objects = {o["name"]: o for o in read["objects"]}
    row = {"file": path.name, "bytes": path.stat().st_size, "import": statistics.median(read["import_seconds"]),
           "imports": read["import_seconds"], "frames_seconds": read["frames_seconds"], "scene": read["scene"],
           "prims": {}, "objects": {n: o["type"] for n, o in objects.items()},
           "custom_properties": sorted({p for o in objects.values() for p in o["custom_properties"]})}
    worst = 0.0
    for name, prim in written["prims"].items():
        obj = objects.get(name)
        info: dict = {"object": obj["type"] if obj else None}
        if obj is None:
            row["prims"][name] = info
            continue
        if prim["kind"] == "curves":
            info.update(curves_written=len(prim["counts"]), curves_read=obj["curves"],
                        points_written=int(prim["counts"].sum()), points_read=obj["points"],
                        counts_equal=arrays[f"{name}/counts"].tolist() == prim["counts"].tolist(),
                        primvars=prim["primvars"],
                        attributes=[a["name"] for a in obj["attributes"]],
                        modifiers=[m["type"] for m in obj["modifiers"]])
            radius = arrays.get(f"{name}/attr/radius")
            info["radius_is_half_width"] = bool(radius is not None and
                                                np.allclose(2 * radius, prim["widths"], rtol=1e-6))
            if prim["frames"]:
                deviations = [np.abs(arrays[f"{name}/frame{k}"] - _world(p, written)).max()
                              for k, p in prim["frames"].items() if f"{name}/frame{k}" in arrays]
                info["frames_written"], info["frames_compared"] = len(prim["frames"]), len(deviations)
                first = min(prim["frames"])
                info["data_is_first_sample"] = bool(np.abs(arrays[f"{name}/points"]
                                                           - _world(prim["frames"][first], written)).max() < 1e-6)
                info["data_is_default"] = bool(np.abs(arrays[f"{name}/points"]
                                                      - _world(prim["default"], written)).max() < 1e-6)
                info["default_to_first_m"] = float(np.abs(_world(prim["default"] - prim["frames"][first],
                                                                  written)).max())
                moved = [f[name].get("moved_since_first", 0.0) for f in read["frames"].values()]
                info["moved_m"] = max(moved)
            else:
                deviations = [np.abs(arrays[f"{name}/points"] - _world(prim["default"], written)).max()]
            info["deviation_m"] = float(max(deviations))
        else:
            info.update(faces_written=prim["faces"], faces_read=obj["faces"], vertices_written=prim["vertices"],
                        vertices_read=obj["vertices"], face_sizes=obj["face_sizes"],
                        constraints=[c["type"] for c in obj["constraints"]])
            deviations = []
            for k, placed in prim["placed"].items():
                key = f"{name}/frame{k}" if k is not None else None
                if key is None or key not in arrays:  # not animated: any frame Blender evaluated
                    key = next(a for a in arrays if a.startswith(f"{name}/frame"))
                deviations.append(np.abs(arrays[key] - _world(placed, written)).max())
            info["deviation_m"] = float(max(deviations))
            info["frames_compared"] = len(deviations)
            moved = [f[name].get("moved_since_first", 0.0) for f in read["frames"].values()]
            info["moved_m"] = max(moved)
        worst = max(worst, info.get("deviation_m", 0.0))
        row["prims"][name] = info
    row["deviation_m"] = worst
    rest = written["prims"].get("Rest")
    if "tessellated" in read and rest is not None:
        info = read["tessellated"]["Rest"]
        row["tessellated"] = dict(info)
        if rest["type"] == "linear":
            row["tessellated"]["through_vertices_m"] = float(np.abs(arrays["Rest/tessellated"]
                                                                     - _world(rest["default"], written)).max())
        elif rest["basis"] == "catmullRom" and rest["type"] == "cubic":
            (resolution,) = info["resolution"]
            row["tessellated"].update(drawn_against_pinned(_world(rest["default"], written), rest["counts"],
                                                           arrays["Rest/tessellated"], resolution))
        row["tessellated"].update(type=rest["type"], basis=rest["basis"], wrap=rest["wrap"])
    return row


def _prepare() -> dict:
    """The stage files and the USD exports; returns their paths and the seconds each command took."""
    WORK.mkdir(parents=True, exist_ok=True)
    for p in WORK.iterdir():
        if p.is_file():
            p.unlink()
    shutil.copyfile(ROOT / "samples" / "settled_curly.h5", WORK / "curly.h5")
    shutil.copyfile(ROOT / "samples" / "body.obj", WORK / "body.obj")
    seconds = {}
    log(f"blender: ruby long, {GUIDES} guides, invert")
    seconds["ruby invert"] = _hairinv("invert", RUBY, RUBY_HEAD, "--scale", "0.002", "--guides", GUIDES,
                                      "-o", "ruby.model.h5")
    log("blender: ruby long, still simulation")
    seconds["ruby still"] = _hairinv("simulate", "ruby.model.h5", "--seconds", SECONDS, "--fps", FPS,
                                     "-o", "ruby.still.h5")
    log("blender: ruby long, all strands, fit")
    seconds["ruby fit"] = _hairinv("fit", RUBY, "--scale", "0.002", "--quality", "draft", "-o", "ruby_all.fit.h5")
    log("blender: settled_curly, invert and motion")
    seconds["curly"] = _hairinv("invert", "curly.h5", "body.obj", "-o", "curly.model.h5")
    seconds["curly"] += _hairinv("simulate", "curly.model.h5", "--scene", "motion", "--seconds", SECONDS,
                                 "--fps", FPS, "-o", "curly.motion.h5")
    exports = [("ruby.still.h5", "ruby.still.usdc", True, True), ("ruby.still.h5", "ruby.still.usda", True, False),
               ("ruby_all.fit.h5", "ruby_all.fit.usdc", False, False),
               ("curly.motion.h5", "curly.motion.usdc", True, False)]
    out = {}
    for stage, usd, animated, tessellate in exports:
        out[usd] = {"stage": stage, "animated": animated, "tessellate": tessellate,
                    "export_seconds": _hairinv("export", stage, "-o", usd)}
    # --basis catmull-rom, through the library (hairinv.export.export): the same shapes as pinned cubics
    from hairinv.export import export

    start = time.perf_counter()
    export(WORK / "ruby.still.h5", WORK / CATMULL, basis="catmull-rom")
    out[CATMULL] = {"stage": "ruby.still.h5", "animated": True, "export_seconds": time.perf_counter() - start,
                    "tessellate": True}
    return {"seconds": seconds, "exports": out}


def _yes(flag: bool) -> str:
    return "yes" if flag else "no"


def _cubic_sentence(cubic: dict, linear: dict | None) -> str:
    drawn_linear = (f" Linear curves come in as Blender's {', '.join(linear['curve_types'])} type and are drawn as "
                    f"the segments between the vertices ({linear['points']:,} points drawn, within "
                    f"{linear['through_vertices_m']:.1e} m of the vertices)." if linear else "")
    return (f"- **Cubic curves** (`{cubic['type']}`, `{cubic['basis']}`, `{cubic['wrap']}`): Blender's "
            f"{', '.join(cubic['curve_types'])} curve type, resolution {', '.join(map(str, cubic['resolution']))}; "
            f"between the second and the second-last vertex Blender draws USD's Catmull-Rom segments (within "
            f"{cubic['inner_m']:.1e} m at the same parameter). On each strand's first and last segment it repeats "
            f"the end vertex where USD's `pinned` wrap uses the phantom point 2 P0 - P1 (Blender's own rule within "
            f"{cubic['end_repeated_m']:.1e} m): the same end points, and a curve within "
            f"{1e3 * cubic['end_shape_m']:.3f} mm of the pinned one ({1e3 * cubic['end_parameter_m']:.2f} mm apart "
            f"at the same parameter; vertices {1e3 * cubic['median_segment_m']:.1f} mm apart, median)."
            + drawn_linear)


def render(rows: list[dict], prepared: dict, blender: str, info: dict) -> str:
    header = ["file", "size", "strands written / curves read", "points written / read", "frames written / played",
              "largest distance, Blender to pxr (m)", f"import, median of {REPEATS} (s)", "every frame evaluated (s)",
              "Blender process, start-up included (s)"]
    body_rows = []
    for r in rows:
        hair = r["prims"]["Hair"]
        frames = hair.get("frames_written", 0)
        scene = r["scene"]
        played = scene["frame_end"] - scene["frame_start"] + 1 if frames else 0
        body_rows.append([f"`{r['file']}`", f"{r['bytes'] / 1e6:.1f} MB",
                          f"{hair['curves_written']:,} / {hair['curves_read']:,}",
                          f"{hair['points_written']:,} / {hair['points_read']:,}",
                          f"{frames} / {played}" if frames else "-",
                          f"{r['deviation_m']:.1e}", f"{r['import']:.3f}",
                          f"{r['frames_seconds']:.2f}", f"{r['wall']:.1f}"])
    ruby = next(r for r in rows if r["file"] == "ruby.still.usdc")
    curly = next(r for r in rows if r["file"] == "curly.motion.usdc")
    hair, head = ruby["prims"]["Hair"], ruby["prims"]["Body"]
    counts_equal = all(p["counts_equal"] for r in rows for p in r["prims"].values() if "counts_equal" in p)
    extra = [a for a in hair["attributes"] if a not in hair["primvars"]]
    lost = [p for p in hair["primvars"] if p not in hair["attributes"]]
    seconds = prepared["seconds"]
    exports = prepared["exports"]
    lines = [
        f"## {TITLE}", "",
        "`bench/blender_bench.py`. Blender, as the `bpy` module from PyPI (`make blender`: .venv-blender), imports "
        "the USD files `hairinv export` writes, headless: an empty scene (`read_factory_settings(use_empty=True)`), "
        "`bpy.ops.wm.usd_import` with its default options (as File > Import > USD), then every frame evaluated "
        "(`tests/blender_read_usd.py`). What it holds is compared with the same file read with pxr, after the "
        "importer's conversion. The files: ruby long (`--scale 0.002`) with "
        f"{GUIDES} guides inverted on its head and a still simulation of {SECONDS:g} s at {FPS} fps, exported with "
        "everything (input, rest shape, frames, head) as `.usdc` and as `.usda`; all 3,000 ruby long strands "
        "fitted at draft quality (input shape only); the sample `settled_curly` inverted on `samples/body.obj` and "
        f"the `motion` scene for {SECONDS:g} s at {FPS} fps (the bust turns and leans); the ruby run again as "
        "pinned Catmull-Rom cubics (`basis=\"catmull-rom\"`, through `hairinv.export.export`), whose curves "
        "Blender also draws (each curves object converted to a mesh: its curves evaluated). Import times are the "
        f"operator's wall time, median of {REPEATS} imports each into a fresh empty scene.", "",
        machine_markdown(info), f"| Blender (bpy) | {blender} |", "",
        table(header, body_rows), "",
        f"Making the inputs (wall clock, each command a subprocess): ruby invert {seconds['ruby invert']:.0f} s, its "
        f"still simulation {seconds['ruby still']:.0f} s, the 3,000-strand fit {seconds['ruby fit']:.0f} s, curly "
        f"invert and motion {seconds['curly']:.0f} s; exports "
        + ", ".join(f"`{k}` {v['export_seconds']:.1f} s" for k, v in exports.items()) + ".", "",
        "What Blender " + blender + " does with them:", "",
        f"- **Curves**: `/Root/Hair` and `/Root/Rest` become hair curves objects (`{hair['object']}`: Blender's "
        f"`Curves` type), as many curves as strands with the same points per curve "
        f"({_yes(counts_equal)} on every file), linear ones as Blender's poly curve type. "
        f"Every point of every frame lies within {max(r['deviation_m'] for r in rows):.1e} m of pxr's (float32).",
        f"- **Units and axes**: the root object `Root` (an empty) carries the stage's `metersPerUnit` as its scale "
        f"(the scene's unit scale stays 1, metres) and, for a +Y up stage, +90 degrees about X: a point (x, y, z) "
        f"of the file is at metersPerUnit (x, -z, y) in Blender's +Z up world.",
        f"- **Widths** become the point attribute `radius`, half the width, in stage units "
        f"(on every point of ruby's groom: {_yes(hair['radius_is_half_width'])}).",
        f"- **Primvars**: all {len(hair['primvars'])} of `/Root/Hair` come in as attributes of the same names, "
        f"uniform on the curves and vertex on the points ({', '.join(f'`{p}`' for p in hair['primvars'])})"
        + (f"; not: {', '.join(lost)}" if lost else "") + f"; besides them Blender's own "
        f"{', '.join(f'`{a}`' for a in extra)}. `rest` is a point vector in the object's space (stage units).",
        f"- **Body**: `/Root/Body` is a mesh of {head['faces_read']:,} faces ({head['faces_written']:,} triangles "
        f"written) and {head['vertices_read']:,} vertices for ruby's head. A moving body's `xformOp:transform` "
        f"samples become a Transform Cache constraint ({', '.join(curly['prims']['Body']['constraints'])}); in the "
        f"curly motion file the bust moves up to {1e3 * curly['prims']['Body']['moved_m']:.0f} mm and Blender "
        f"places it within {curly['prims']['Body']['deviation_m']:.1e} m of pxr at all "
        f"{curly['prims']['Body']['frames_compared']} frames.",
        f"- **Frames**: the time samples of `points` are read through a Mesh Sequence Cache modifier on the "
        f"curves object ({', '.join(hair['modifiers'])}); scene frame N shows time code N, and the importer sets "
        f"the scene's frame range to the stage's ({ruby['scene']['frame_start']}-{ruby['scene']['frame_end']}). "
        f"The curly hair moves up to {1e3 * curly['prims']['Hair']['moved_m']:.0f} mm over the run; ruby's still "
        + (f"run {1e3 * hair['moved_m']:.2g} mm." if hair["moved_m"] else
           "run not at all (its frames are the same float32 numbers)."),
        _cubic_sentence(next(r for r in rows if r["file"] == CATMULL)["tessellated"],
                        ruby.get("tessellated")),
        "", "Dropped or changed:", "",
        f"- the frame rate: the scene stays at Blender's {ruby['scene']['fps']} fps (the stage says "
        f"{FPS}), so the run plays {FPS / ruby['scene']['fps']:.2f} times slower unless the scene's frame rate "
        "is set by hand;",
        f"- the default value of an animated `points` (the input shape): the object's own data is the first "
        f"time sample ({_yes(hair['data_is_first_sample'])}; the input shape: {_yes(hair['data_is_default'])}), "
        f"{1e3 * hair['default_to_first_m']:.3f} mm from the input on ruby; the input shape is not shown at any "
        "frame of an animated file;",
        "- the body's visibility time sample of a remove-body run: the body stays visible "
        "(tests/test_blender.py);",
        "- metadata: prim documentation, the `hairinv:role` custom data and the layer's `customLayerData` "
        f"(custom properties on the imported objects: {', '.join(ruby['custom_properties']) or 'none'}).",
    ]
    return "\n".join(lines) + "\n"


def run() -> str:
    if not BLENDER_PYTHON.exists():
        return (f"## {TITLE}\n\nNot run: Blender's Python was not found at {BLENDER_PYTHON} "
                "(`make blender` installs it).\n")
    if not RUBY.exists():
        return f"## {TITLE}\n\nNot run: the real data was not found at {RUBY} (set HAIRINV_REAL_DATA).\n"
    info = machine()
    prepared = _prepare()
    rows, blender = [], "?"
    for usd, spec in prepared["exports"].items():
        path = WORK / usd
        log(f"blender: {usd}")
        written = _written(path)
        report, arrays, wall = _blender(path, spec["animated"], spec.get("tessellate", False))
        blender = report["blender"]
        row = compare(path, written, report, arrays)
        row["wall"] = wall
        rows.append(row)
        log(f"blender: {usd}: import median {row['import']:.3f} s, largest distance {row['deviation_m']:.1e} m")
    (WORK / "blender_bench.json").write_text(json.dumps({"rows": rows, "prepared": prepared}, indent=1,
                                                        default=str))
    return render(rows, prepared, blender, info)


if __name__ == "__main__":
    print(run())
