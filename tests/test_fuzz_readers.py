"""Corrupt hairstyle and body files: bits flipped, bytes cut off, counts and coordinates overwritten.

Each corrupt file is read and fitted (a body: read and made a queryable mesh) as the commands do. What is
allowed: it reads (the damage was harmless: a coordinate moved, a strand shortened) and fits to finite
helices, or it is refused with an :class:`InputError` naming the file. Anything else (an exception from a
reader or a kernel, non-finite helices) is a defect: on the command line it would be an internal error
instead of one clear sentence.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest

from hairinv.config import FitSettings, ImportSettings
from hairinv.contacts.body import BodyMesh
from hairinv.errors import InputError
from hairinv.fit import fit_groom
from hairinv.formats import read_mesh, write_curves
from hairinv.groom import load_groom

ROOT = Path(__file__).resolve().parents[1]
CASES = 24  # corrupt files per format


def small_groom(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Six wavy strands of 12 points hanging from a row of roots, in metres."""
    rng = np.random.default_rng(seed)
    strands = []
    for s in range(6):
        t = np.linspace(0.0, 0.2, 12)
        strands.append(np.column_stack([0.01 * s + 0.004 * np.sin(30 * t + s), -t, 0.003 * np.cos(25 * t)])
                       + rng.normal(0.0, 1e-5, (12, 3)))
    points = np.concatenate(strands)
    offsets = np.arange(0, 6 * 12 + 1, 12, dtype=np.int64)
    return points, offsets


def corrupt(data: bytes, rng: np.random.Generator) -> bytes:
    """One of: bits flipped, the end cut off, four bytes overwritten with a huge or negative count, a float
    overwritten with NaN, infinity or 1e37."""
    out = bytearray(data)
    kind = rng.integers(4)
    if kind == 0:
        for _ in range(int(rng.integers(1, 9))):
            i = int(rng.integers(len(out)))
            out[i] ^= 1 << int(rng.integers(8))
    elif kind == 1:
        out = out[:int(rng.integers(len(out)))]
    elif kind == 2:
        i = int(rng.integers(0, max(1, len(out) - 4)))
        out[i:i + 4] = struct.pack("<i", int(rng.choice([2**31 - 1, -7, 2**30, 0])))
    else:
        i = int(rng.integers(0, max(1, len(out) - 4)))
        out[i:i + 4] = struct.pack("<f", float(rng.choice([np.nan, np.inf, 1e37, -1e37])))
    return bytes(out)


def read_and_fit(path: Path) -> None:
    """What ``hairinv fit`` does with the file: refused as bad input naming it, or fitted to finite helices."""
    try:
        groom, _ = load_groom(path, ImportSettings(units="m"))
        helices, _ = fit_groom(groom, FitSettings())
    except InputError as error:  # refused: the sentence names the file
        assert path.name in str(error), str(error)
    else:  # read: the fit is finite
        for name in ("root", "frame0", "omega", "length"):
            assert np.all(np.isfinite(getattr(helices, name))), name
        assert np.all(helices.length > 0.0)


@pytest.mark.parametrize("suffix", [".data", ".hair", ".usda", ".obj"])
def test_corrupt_hairstyle_files_are_read_and_fitted_or_refused(tmp_path, suffix):
    points, offsets = small_groom()
    clean = tmp_path / f"clean{suffix}"
    write_curves(clean, points, offsets)
    read_and_fit(clean)  # the clean file itself fits
    data = clean.read_bytes()
    rng = np.random.default_rng(sum(map(ord, suffix)))
    for case in range(CASES):
        path = tmp_path / f"corrupt{case}{suffix}"
        path.write_bytes(corrupt(data, rng))
        read_and_fit(path)


def test_a_straight_strand_with_a_point_thrown_far_along_it_fits():
    """One point of a straight strand moved 1.7 m along the strand's own line, as a flipped exponent bit does:
    the chords there turn exactly back on themselves, which the first guess of the curvature cannot use (its
    3 x 3 system was singular, an internal error)."""
    from hairinv.groom import Groom

    points, offsets = small_groom()
    straight = np.column_stack([np.full(20, 0.04), np.linspace(1.6, 1.9, 20), np.zeros(20)])
    straight[6, 1] -= 1.7
    points = np.concatenate([points, straight])
    offsets = np.append(offsets, offsets[-1] + 20)
    groom = Groom(points, offsets, np.array([0.0, 1.0, 0.0]), 1.0, "spike", np.arange(7, dtype=np.int64))
    helices, report = fit_groom(groom, FitSettings())
    assert np.all(np.isfinite(helices.omega)) and np.all(np.isfinite(helices.root))


def test_corrupt_body_meshes_are_read_or_refused(tmp_path):
    clean = (ROOT / "samples" / "body.obj").read_bytes()
    rng = np.random.default_rng(7)
    for case in range(CASES):
        path = tmp_path / f"corrupt{case}.obj"
        out = bytearray(clean)
        # text: bytes replaced by digits, signs, letters or line breaks, or the end cut off
        if case % 3 == 0:
            out = out[:int(rng.integers(len(out)))]
        else:
            for _ in range(int(rng.integers(1, 20))):
                out[int(rng.integers(len(out)))] = ord(rng.choice(list("0123456789-.eE \nvfnan")))
        path.write_bytes(bytes(out))
        try:
            mesh = read_mesh(path)
            BodyMesh.from_mesh(mesh)
        except InputError as error:
            assert path.name in str(error), str(error)
