"""Sorts for the region's kernels, written out: numba's own sorts compile for seconds each.

Both are bottom-up merge sorts, O(N log N), with ``<`` as the only comparison: for keys
without NaN, :func:`argsort_stable` gives the permutation of ``np.argsort(keys,
kind="stable")`` and :func:`sort_values` the values of ``np.sort`` (any correct sort gives the
same values). ``tests/region/test_sort_kernels.py`` compares them with numpy.
"""

from __future__ import annotations

import numpy as np

from limbctl.geometry.jit import njit


@njit
def _merge_pass(keys, src, dst, width) -> None:
    """Merge each pair of sorted runs of ``width`` indices of ``src`` into ``dst`` by ``keys``,
    the left run first on equal keys (stable)."""
    n = src.shape[0]
    for lo in range(0, n, 2 * width):
        mid = min(lo + width, n)
        hi = min(lo + 2 * width, n)
        i = lo
        j = mid
        k = lo
        while i < mid and j < hi:
            if keys[src[j]] < keys[src[i]]:
                dst[k] = src[j]
                j += 1
            else:
                dst[k] = src[i]
                i += 1
            k += 1
        while i < mid:
            dst[k] = src[i]
            i += 1
            k += 1
        while j < hi:
            dst[k] = src[j]
            j += 1
            k += 1


@njit
def argsort_stable(keys):
    """Indices (N,) int64 that sort ``keys`` (N,) ascending, equal keys in index order."""
    n = keys.shape[0]
    order = np.empty(n, dtype=np.int64)
    spare = np.empty(n, dtype=np.int64)
    for i in range(n):
        order[i] = i
    width = 1
    while width < n:
        _merge_pass(keys, order, spare, width)
        order, spare = spare, order
        width *= 2
    return order


@njit
def sort_values(values) -> None:
    """Sort ``values`` (N,) float64 ascending, in place."""
    order = argsort_stable(values)
    copy = values.copy()
    for i in range(values.shape[0]):
        values[i] = copy[order[i]]
