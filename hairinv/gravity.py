"""Gravity on the super-helices, for the inversion and the dynamics alike.

``F_g(q)``, the generalized gravity force of eq. (4), and the gravity the solvers' tolerances are
relative to.
"""

from __future__ import annotations

import numpy as np

from ._jit import jit
from ._parallel import run_chunks
from .config import MaterialSettings
from .model import Helices, Material
from .rod.statics import gravity_forces

__all__ = ["generalized_gravity", "tolerance_gravity"]


@jit
def _gravity_chunk(root, frame0, offsets, omega, length, lam, gravity, out, lo, hi):
    for s in range(lo, hi):
        a = offsets[s]
        z = offsets[s + 1]
        gravity_forces(root[s], frame0[s], omega[a:z], length[a:z], lam, gravity, out[a:z])


def generalized_gravity(helices: Helices, material: Material) -> np.ndarray:
    """``F_g(q)`` of every element, (E, 3), J m."""
    out = np.zeros((helices.n_elements, 3))

    def work(lo: int, hi: int) -> None:
        _gravity_chunk(helices.root, helices.frame0, helices.offsets, helices.omega, helices.length,
                       material.linear_density, material.gravity, out, lo, hi)

    run_chunks(work, helices.n_strands, 256)
    return out


def tolerance_gravity(material: Material) -> float:
    """m/s^2: the gravity of the weight the solver's tolerance is relative to: the material's, or, in a scene
    without gravity (where every weight is zero and no residual could meet a tolerance relative to one),
    the default 9.81 m/s^2."""
    g = float(np.linalg.norm(material.gravity))
    return g if g > 0.0 else MaterialSettings().gravity
