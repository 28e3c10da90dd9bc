"""Per-frame body meshes as an animated body: ``body.####.obj`` (a run of ``#`` stands for the frame
number, any number of digits at least that many) or a folder of ``.obj`` / ``.ply`` files.

Frame ``n`` is at ``n / fps`` seconds (the frame number is read from the file name, its last run of digits in
a folder), the convention of USD time codes; between frames the vertices are interpolated linearly. Every
frame must have the first frame's vertex count and triangles (constant topology). The files state no units,
up axis or frame rate: give ``fps`` (24 is assumed otherwise, and said).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..errors import InputError
from .animated import AnimatedBody, lerp_samples
from .base import SEQUENCE, mesh_reader_for, register_animated_reader

__all__ = ["read_sequence", "sequence_frames"]

DEFAULT_FPS = 24.0
_KINDS = (".obj", ".ply")


def sequence_frames(path: Path) -> list[tuple[int, Path]]:
    """The (frame number, file) pairs of a ``#`` pattern or a folder, by frame number."""
    path = Path(path)
    if path.is_dir():
        files = [f for f in path.iterdir() if f.is_file() and f.suffix.lower() in _KINDS]
        kinds = {f.suffix.lower() for f in files}
        if len(kinds) > 1:
            raise InputError(f"holds both {' and '.join(sorted(kinds))} files; a body sequence is of one kind", path)
        frames = []
        for f in files:
            digits = re.findall(r"\d+", f.stem)
            if not digits:
                raise InputError(f"holds {f.name}, whose name has no frame number", path)
            frames.append((int(digits[-1]), f))
    else:
        head, hashes, tail = re.match(r"^(.*?)(#+)([^#]*)$", path.name).groups()
        if "#" in head:
            raise InputError("has more than one run of '#'; one run stands for the frame number", path)
        pattern = re.compile(re.escape(head) + r"(\d{%d,})" % len(hashes) + re.escape(tail) + "$")
        folder = path.parent
        if not folder.is_dir():
            raise InputError("is in a folder that does not exist", path)
        frames = [(int(m.group(1)), folder / m.group(0)) for m in map(pattern.match, (f.name for f in folder.iterdir()))
                  if m]
    if not frames:
        raise InputError("matches no frame files (.obj or .ply)", path)
    frames.sort()
    numbers = [n for n, _ in frames]
    if len(set(numbers)) != len(numbers):
        raise InputError("has two files with the same frame number", path)
    return frames


def _probe(path: Path) -> bool:
    try:
        return bool(sequence_frames(path))
    except InputError:
        return False


@register_animated_reader(SEQUENCE, probe=_probe)
def read_sequence(path: Path, fps: float | None = None) -> AnimatedBody:
    """Read a mesh sequence at ``fps`` frames per second (24 assumed when not given)."""
    path = Path(path)
    notes = []
    if fps is None:
        fps = DEFAULT_FPS
        notes.append(f"a mesh sequence states no frame rate: {fps:g} fps assumed")
    if not fps > 0:
        raise InputError(f"a mesh sequence needs a positive frame rate; got {fps}", path)
    frames = sequence_frames(path)
    first = None
    samples = []
    for number, file in frames:
        mesh = mesh_reader_for(file)(file)
        vertices, faces = np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64)
        if first is None:
            first = (file, vertices, faces)
        elif len(vertices) != len(first[1]):
            raise InputError(f"has {len(vertices)} vertices where the first frame ({first[0].name}) has "
                             f"{len(first[1])}; a body sequence needs one topology", file)
        elif faces.shape != first[2].shape or not np.array_equal(faces, first[2]):
            raise InputError(f"has other triangles than the first frame ({first[0].name}); a body sequence "
                             "needs one topology", file)
        samples.append(vertices)
    samples = np.stack(samples)
    times = np.array([n for n, _ in frames], dtype=np.float64) / float(fps)
    return AnimatedBody(vertices=samples[0], faces=first[2], times=times, fps=float(fps), format="mesh-sequence",
                        evaluate=lambda t: lerp_samples(times, samples, t), notes=tuple(notes))
