"""The radix orders (hairinv/_sorting.py) against numpy's stable argsort, on inputs large enough to take the
radix path, with ties, digits every key shares, and the extremes of the key range."""

import numpy as np
import pytest

from hairinv._sorting import SMALL, float_order, stable_order

N = SMALL + 4321


@pytest.mark.parametrize("case", ["few values", "wide", "shared high digits", "one value", "top bit", "11-bit edge"])
def test_stable_order_is_numpys_stable_argsort(case):
    rng = np.random.default_rng(7)
    keys = {
        "few values": rng.integers(0, 5, N),  # ties everywhere: their order is the test
        "wide": rng.integers(0, 2**40, N),
        "shared high digits": (3 << 50) + rng.integers(0, 2**12, N),  # the middle passes move nothing
        "one value": np.full(N, 123456789),  # every pass skipped
        "top bit": rng.integers(2**62 - 1000, 2**62, N) * 2 - rng.integers(0, 2, N),  # up to 2**63 - 1
        "11-bit edge": rng.integers(0, 2, N) * (2**22 - 1),  # 22 bits: exactly two passes
    }[case].astype(np.int64)
    order = stable_order(keys)
    assert order.dtype == np.int64
    np.testing.assert_array_equal(order, np.argsort(keys, kind="stable"))


def test_float_order_is_numpys_stable_argsort():
    rng = np.random.default_rng(11)
    values = np.abs(rng.normal(size=N)) * 1e-3
    values[::5] = 0.0
    values[1::97] = -0.0  # as 0.0
    values[2::101] = np.inf
    values[3::89] = 5e-324  # the smallest subnormal
    values[4::13] = values[6::13][:len(values[4::13])]  # ties among ordinary values
    np.testing.assert_array_equal(float_order(values), np.argsort(values, kind="stable"))


@pytest.mark.parametrize("bad", [-1.0, np.nan])
def test_float_order_refuses_negatives_and_nan(bad):
    values = np.ones(N)
    values[17] = bad
    with pytest.raises(ValueError):
        float_order(values)
    with pytest.raises(ValueError):
        stable_order(np.where(np.arange(N) == 17, -1, 1))
