"""Shared fixtures and named tolerances of the test suite."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

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


def real_path(*parts) -> Path:
    """A file of the shared real data set, or skip the test with the reason."""
    path = REAL.joinpath(*parts)
    if not path.exists():
        pytest.skip(f"real data not found at {path} (set HAIRINV_REAL_DATA)")
    return path


@pytest.fixture
def rng():
    return np.random.default_rng(20131107)
