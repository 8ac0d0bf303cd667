import numpy as np
import pytest

from limbctl.region.sort_kernels import argsort_stable, sort_values


@pytest.mark.parametrize("n", [0, 1, 2, 3, 7, 64, 1000])
def test_argsort_is_numpys_stable_argsort_ties_included(n):
    rng = np.random.default_rng(n)
    # few distinct values: many ties, whose order the stable sort must keep; -0.0 beside 0.0
    keys = rng.integers(-3, 4, size=n).astype(float)
    keys[::5] = -0.0
    np.testing.assert_array_equal(argsort_stable(keys), np.argsort(keys, kind="stable"))
    spread = rng.normal(size=n)
    np.testing.assert_array_equal(argsort_stable(spread), np.argsort(spread, kind="stable"))


@pytest.mark.parametrize("n", [0, 1, 5, 333])
def test_sort_values_is_numpys_sort(n):
    values = np.random.default_rng(n).normal(size=n)
    expected = np.sort(values)
    sort_values(values)
    np.testing.assert_array_equal(values, expected)
