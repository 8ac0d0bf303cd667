import numpy as np
import pytest

from limbctl.region.sort_kernels import RUN, largest_stable, sort_values


@pytest.mark.parametrize("n", [0, 1, 2, 3, 7, 40, 41, 64, 1000])
@pytest.mark.parametrize("k", [0, 1, 12, 40])
def test_largest_is_numpys_stable_argsort_of_the_negated_ties_included(n, k):
    rng = np.random.default_rng(n)
    # few distinct values: many ties, whose order the stable sort must keep; -0.0 beside 0.0
    ties = rng.integers(-3, 4, size=n).astype(float)
    ties[::5] = -0.0
    # and spread values; ascending input: every value displaces the kept ones (the slowest case)
    for keys in (ties, rng.normal(size=n), np.arange(n, dtype=float)):
        np.testing.assert_array_equal(largest_stable(keys, k), np.argsort(-keys, kind="stable")[:k])


@pytest.mark.parametrize("n", [0, 1, 5, RUN, RUN + 1, 2 * RUN + 1, 333, 1000])
def test_sort_values_is_numpys_sort(n):
    rng = np.random.default_rng(n)
    for values in (rng.normal(size=n), rng.integers(-3, 4, size=n).astype(float)):
        expected = np.sort(values)
        sort_values(values)
        np.testing.assert_array_equal(values, expected)
