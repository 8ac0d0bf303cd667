"""Sorts for the region's kernels, written out (numba's own compile for seconds each), with ``<``
only: :func:`largest_stable` gives ``np.argsort(-values, kind="stable")[:k]``,
:func:`sort_values` the values of ``np.sort`` (without NaN)."""

from __future__ import annotations

import numpy as np

from limbctl.geometry.jit import njit

#: Run length sorted by insertion before merging: the 10-50 values sorted need no buffer.
RUN = 16


@njit
def largest_stable(values, k):
    """Indices (min(k, N),) int64 of the ``k`` largest of ``values`` (N,), largest first, ties in
    index order; insertion, O(N) when most values fall below the ``k``-th."""
    n = values.shape[0]
    k = min(k, n)
    out = np.empty(k, dtype=np.int64)
    if k == 0:
        return out
    count = 0
    for m in range(n):
        x = values[m]
        if count == k:
            # not above the k-th: an equal one comes later in index order, so after it
            if not x > values[out[k - 1]]:
                continue
            p = k - 1
        else:
            p = count
            count += 1
        # kept values smaller than x move down one; equal ones stay ahead (stable)
        while p > 0 and values[out[p - 1]] < x:
            out[p] = out[p - 1]
            p -= 1
        out[p] = m
    return out


@njit
def sort_values(values) -> None:
    """Sort ``values`` (N,) float64 ascending, in place: insertion sort of runs of :data:`RUN`,
    then bottom-up merges of the runs (a buffer of N only when N > :data:`RUN`)."""
    n = values.shape[0]
    for lo in range(0, n, RUN):
        hi = min(lo + RUN, n)
        for i in range(lo + 1, hi):
            x = values[i]
            p = i
            while p > lo and x < values[p - 1]:
                values[p] = values[p - 1]
                p -= 1
            values[p] = x
    if n <= RUN:
        return
    src = values
    dst = np.empty(n)
    swapped = False
    width = RUN
    while width < n:
        for lo in range(0, n, 2 * width):
            mid = min(lo + width, n)
            hi = min(lo + 2 * width, n)
            i = lo
            j = mid
            k = lo
            while i < mid and j < hi:
                if src[j] < src[i]:
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
        src, dst = dst, src
        swapped = not swapped
        width *= 2
    if swapped:
        for i in range(n):
            values[i] = src[i]
