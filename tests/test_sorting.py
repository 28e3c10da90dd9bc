"""The radix orders (hairinv/_sorting.py) against numpy's stable argsort, on inputs large enough to take the
radix path, with ties, digits every key shares, and the extremes of the key range."""

import numpy as np
import pytest

from hairinv._sorting import SMALL, _radix_order, float_order, stable_order

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
        "11-bit edge": rng.integers(2**21, 2**22, N),  # 22 bits, the top one set in every key: two passes
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


@pytest.mark.parametrize("n", [0, 1, 2, 17, 1000])
@pytest.mark.parametrize("high", [1, 2, 2**11, 2**11 + 1, 2**22, 2**33 + 5, 2**63 - 1])
def test_the_radix_kernel_on_few_keys(n, high):
    # the kernel itself, below the size where the public functions hand over to numpy: 1 to 6 passes
    keys = np.random.default_rng(n + high % 1000).integers(0, high, n, dtype=np.int64)
    keys[: n // 3] = keys[n // 2: n // 2 + n // 3]  # ties
    order = _radix_order(keys, int(keys.max(initial=0)).bit_length())
    np.testing.assert_array_equal(order, np.argsort(keys, kind="stable"))


def test_all_zeros_either_sign():
    values = np.zeros(N)
    values[::3] = -0.0
    np.testing.assert_array_equal(float_order(values), np.arange(N))


@pytest.mark.parametrize("n", [10, N])
@pytest.mark.parametrize("bad", [-1.0, np.nan])
def test_float_order_refuses_negatives_and_nan(bad, n):
    values = np.ones(n)
    values[7] = bad
    with pytest.raises(ValueError):
        float_order(values)


@pytest.mark.parametrize("n", [10, N])
def test_stable_order_refuses_what_it_cannot_order_as_numpy_does(n):
    with pytest.raises(ValueError):
        stable_order(np.where(np.arange(n) == 7, -1, 1))
    with pytest.raises(ValueError):  # above int64: would wrap to negative keys
        stable_order(np.full(n, 2**63, dtype=np.uint64))
    with pytest.raises(TypeError):  # floats would be cut to integers
        stable_order(np.full(n, 0.5))
