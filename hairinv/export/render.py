"""PNG rendered by Blender (``--plot render``): the groom on its body, lit, as a still.

The strands are a Blender hair Curves object (Cycles draws them as curve primitives) with a Principled Hair
BSDF (brown, by melanin), the body a smooth grey mesh, under one sun and a grey sky. The groom is the last
frame of ``/frames`` on the body posed as in that frame (a shot's deforming body as the frames keep it),
else the input shape on the body at rest. The
camera looks at the strands' bounding sphere from the front of the picture (``--plot groom``'s front view:
along -Z of the groom's frame turned Y-up), turned 25 degrees about the up axis and raised 10 degrees, its
lens framing the sphere with a margin. A rod 0.1 mm across is under a pixel at that distance: each strand is
drawn ``STRAND_PIXELS`` pixels across where the rod is thinner, and the report says how thick.

hairinv does not import bpy: it writes the scene's arrays and a spec into a temporary folder and runs
:mod:`hairinv.export._blender_scene` with a Python that has bpy (:func:`blender_python`): the one named by
``$HAIRINV_BLENDER_PYTHON``, this Python if it imports bpy, or ``.venv-blender`` (``make blender``) beside
hairinv's source or in the working folder. Cycles renders on the CPU with few samples, denoised, so a still
takes a few seconds (:data:`SAMPLES`). The PNG is then written through the atomic writer.
"""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ..atomic import write_bytes
from ..errors import InputError, RunError
from .source import OutputAxes

__all__ = ["SIZE", "blender_python", "camera", "export_render"]

#: px, width and height of the render
SIZE = (640, 640)
#: Cycles samples per pixel, then OpenImageDenoise at its fast setting; light bounces. On the sample wavy groom
#: (280 strands on the bust) 16 samples render in 13 s on two cores shared at a load of 9 (8 samples: 8 s, 32
#: samples undenoised at 800 px: 31 s; the denoiser at its default quality adds 25 s); 8 samples leave the
#: hair grainy in the shade.
SAMPLES, BOUNCES = 16, 4
#: px: the least width a strand is drawn with (a rod 0.1 mm across is a tenth of a pixel on a head framed whole)
STRAND_PIXELS = 1.5
#: the camera: 50 mm lens on a 36 mm sensor (40 degrees across), the bounding sphere filling 1 / MARGIN of it
LENS_MM, SENSOR_MM, MARGIN = 50.0, 36.0, 1.15
#: degrees: the camera turned from the front about the up axis, and raised above the horizontal
AZIMUTH, ELEVATION = 25.0, 10.0
#: melanin of the hair material (0: white, 1: black): a mid brown
MELANIN = 0.6
#: s, the longest a render may take before it is stopped
TIMEOUT = 600
#: Blender's environment made by ``make blender`` (Makefile ``BLENDER_VENV``)
BLENDER_VENV = ".venv-blender"
SCENE_SCRIPT = Path(__file__).with_name("_blender_scene.py")


def _has_bpy() -> bool:
    try:
        return importlib.util.find_spec("bpy") is not None
    except (ImportError, ValueError):
        return False


def blender_python(output=None) -> Path:
    """A Python that imports bpy: ``$HAIRINV_BLENDER_PYTHON``, this one, or ``.venv-blender/bin/python`` beside
    hairinv's source (a checkout) or in the working folder.

    Raises
    ------
    InputError
        None found, saying how to get one.
    """
    named = os.environ.get("HAIRINV_BLENDER_PYTHON")
    if named:
        if not Path(named).is_file():
            raise InputError(f"HAIRINV_BLENDER_PYTHON names {named}, which is not a file; it should be a Python that "
                             "imports bpy", output)
        return Path(named)
    if _has_bpy():
        return Path(sys.executable)
    for folder in (Path(__file__).resolve().parents[2], Path.cwd()):
        candidate = folder / BLENDER_VENV / "bin" / "python"
        if candidate.is_file():
            return candidate
    raise InputError("a render needs Blender as a Python module (bpy), which was not found: `make blender` in the "
                     f"hairinv checkout installs it in {BLENDER_VENV}, or set HAIRINV_BLENDER_PYTHON to a Python "
                     "that imports bpy", output)


def camera(points: np.ndarray, front: np.ndarray, up: np.ndarray, size: tuple[int, int] = SIZE) -> dict:
    """Where the camera stands to frame ``points`` (n, 3), m: its ``location``, the ``target`` it looks at (the
    centre of their bounding sphere), ``distance`` to it and the ``pixel`` size there (m), viewed from the
    direction ``front`` (unit, towards the viewer) turned by :data:`AZIMUTH` about ``up`` and raised by
    :data:`ELEVATION`."""
    low, high = points.min(axis=0), points.max(axis=0)
    target = 0.5 * (low + high)
    radius = max(float(np.linalg.norm(points - target, axis=1).max()), 1e-6)
    a, e = np.radians(AZIMUTH), np.radians(ELEVATION)
    side = np.cross(up, front)
    towards = np.cos(e) * (np.cos(a) * front + np.sin(a) * side) + np.sin(e) * up
    half = np.arctan(0.5 * SENSOR_MM / LENS_MM)  # the half angle across (square image: both ways)
    distance = MARGIN * radius / np.sin(half)
    pixel = 2.0 * distance * np.tan(half) / max(size)
    return {"location": target + distance * towards, "target": target, "distance": distance, "pixel": pixel}


def _scene(source) -> tuple[np.ndarray, np.ndarray, object, np.ndarray | None, str, str]:
    """The strands shown (points in the stage frame, m, and offsets), the body mesh or None, its pose (None: as
    it is), what the strands are, and where they are shown (``on the body PATH``, or ``with no body (why)``)."""
    if source.frames is not None and source.n_frames:
        last = source.n_frames - 1
        strands = source.frame(last)
        if source.body_removed:
            return strands.points, strands.offsets, None, None, strands.label, "with no body (the scene removed it)"
        if source.body_animated:  # a shot: the deforming body as the frame keeps it, in place
            return (strands.points, strands.offsets, source.body_mesh(last), None, strands.label,
                    "on the shot's animated body, as the frames keep it")
        pose, label, points, offsets = source.body_transform(last), strands.label, strands.points, strands.offsets
    else:
        pose, label, points, offsets = None, "the input shape", source.points, source.offsets
    mesh, note = source.body()
    if mesh is None:
        return points, offsets, None, None, label, f"with no body ({note})"
    return points, offsets, mesh, pose, label, f"on the body {note.removeprefix('body: ')}"


def export_render(source, path: Path, report) -> None:
    """Render ``source`` (:class:`~hairinv.export.source.ExportSource`) to the PNG ``path`` with Blender."""
    python = blender_python(path)
    points, offsets, mesh, pose, shown, where = _scene(source)
    axes = OutputAxes.onto(source.up, "z")  # Blender is +Z up, in metres
    # the front of the matplotlib picture (its viewer at +Z of the groom turned Y-up), in Blender's frame
    front = axes.rotation @ OutputAxes.onto(source.up, "y").rotation.T @ np.array([0.0, 0.0, 1.0])
    up = np.array([0.0, 0.0, 1.0])
    hair = axes.points(points)
    view = camera(hair, front, up)
    rod, _ = source.radius
    radius = max(rod, 0.5 * STRAND_PIXELS * view["pixel"])
    vertices, faces = np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    if mesh is not None:
        vertices = np.asarray(mesh.vertices, dtype=np.float64)
        if pose is not None:
            vertices = vertices @ pose[:3, :3].T + pose[:3, 3]
        vertices, faces = axes.points(vertices), np.asarray(mesh.faces, dtype=np.int64)
    sun = -np.cross(up, front) * 0.5 + front + 1.2 * up  # from the front, above, a little to the side
    with tempfile.TemporaryDirectory(prefix="hairinv-render-") as folder:
        folder = Path(folder)
        np.savez(folder / "scene.npz", points=hair, offsets=np.asarray(offsets, dtype=np.int64), radius=radius,
                 body_vertices=vertices, body_faces=faces)
        spec = {"arrays": str(folder / "scene.npz"), "output": str(folder / "still.png"), "size": list(SIZE),
                "samples": SAMPLES, "denoise": True, "bounces": BOUNCES, "threads": int(os.environ.get("HAIRINV_THREADS", "0") or 0),
                "camera": view["location"].tolist(), "target": view["target"].tolist(), "lens_mm": LENS_MM,
                "sensor_mm": SENSOR_MM, "sun": (sun / np.linalg.norm(sun)).tolist(), "melanin": MELANIN}
        (folder / "spec.json").write_text(json.dumps(spec))
        env = dict(os.environ)
        if Path(python) != Path(sys.executable):  # Blender's own environment: none of this one's paths
            env = {k: v for k, v in env.items() if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")}
        began = time.perf_counter()
        try:
            done = subprocess.run([str(python), str(SCENE_SCRIPT), str(folder / "spec.json")], capture_output=True,
                                  text=True, env=env, timeout=TIMEOUT)
        except subprocess.TimeoutExpired:
            raise RunError(f"Blender did not finish the render within {TIMEOUT} s; nothing was written") from None
        seconds = time.perf_counter() - began
        still = folder / "still.png"
        if done.returncode != 0 or not still.is_file():
            said = [line for line in (done.stderr + done.stdout).strip().splitlines() if line.strip()]
            raise RunError(f"Blender ({python}) could not render the still (exit {done.returncode}"
                           + (f": {said[-1].strip()}" if said else "") + "); nothing was written")
        version = next((json.loads(line)["blender"] for line in done.stdout.splitlines()
                        if line.startswith('{"blender"')), "?")
        write_bytes(path, still.read_bytes())
    thick = (f"strands drawn {2e3 * radius:.2g} mm across" if radius > rod
             else f"strands {2e3 * rod:.2g} mm across, the rod's diameter")
    report.lines.append(f"wrote {path}: PNG, {SIZE[0]} x {SIZE[1]} px, rendered by Blender {version} (Cycles, CPU, "
                        f"{SAMPLES} samples) in {seconds:.1f} s")
    report.lines.append(f"shows {shown} {where}; {thick}" + (" (the rod's would be under a pixel)" if radius > rod
                                                             else ""))
    if mesh is None and not source.body_removed and "records no body" not in where:
        report.warnings.append(f"warning: {source.name}: {where.removeprefix('with no body (')[:-1]}; the render "
                               "has no body")
