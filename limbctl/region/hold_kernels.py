"""Numba kernels of the hold's crossing searches (:mod:`limbctl.region.edge_hold`): which arcs of
a set of closed loops cross, and a held loop's first fold: one pass over the pairs, stopping at
the first answer, with no (N, N) or (K, window) temporaries. Their one test, two points on two
sides of a great circle, is inlined into each (numba's ``inline="always"``): a helper compiled
on its own is one more compile on a first run (tests/test_first_run.py counts them). No
fastmath: every answer is a sign compared against a bound.
"""

from __future__ import annotations

import numpy as np

from limbctl.geometry.jit import njit

#: Ends this close (rad) to a great circle lie on it: held arcs' rounding is 1e-16.
ON_CIRCLE_RAD = 1e-12


@njit(inline="always")
def _across(pole, k, x, i, y, j) -> bool:
    """Whether points ``x[i]`` and ``y[j]`` (rows of (N, 3) arrays) lie clearly on two sides of
    the great circle of unit pole ``pole[k]``: their sine distances to it of opposite signs,
    neither within ``ON_CIRCLE_RAD``."""
    u = pole[k, 0] * x[i, 0] + pole[k, 1] * x[i, 1] + pole[k, 2] * x[i, 2]
    v = pole[k, 0] * y[j, 0] + pole[k, 1] * y[j, 1] + pole[k, 2] * y[j, 2]
    return u * v < 0.0 and abs(u) > ON_CIRCLE_RAD and abs(v) > ON_CIRCLE_RAD


@njit
def crossing_arcs(a, b, pole, mid, owner, index, size):
    """Which arcs ``a -> b`` (N, 3 each; unit ``pole``, ``mid = a + b``) cross a non-adjacent arc.

    Arc ``r`` crosses arc ``s`` when each one's ends lie on two sides of the other's great circle
    and their midpoints face the same way; arcs of one loop (``owner`` (N,)) are adjacent when
    their places ``index`` (N,) in it are 1 apart, or first and last (``size`` (N,) the loop's
    length). Returns (N,) bool.
    """
    n = a.shape[0]
    hit = np.zeros(n, dtype=np.bool_)
    for r in range(n):
        for s in range(n):
            if owner[r] == owner[s]:
                apart = abs(index[r] - index[s])
                if apart <= 1 or apart == size[r] - 1:
                    continue
            # r's ends on two sides of s's great circle, s's of r's, and facing the same way
            if not (_across(pole, s, a, r, b, r) and _across(pole, r, a, s, b, s)):
                continue
            if mid[r, 0] * mid[s, 0] + mid[r, 1] * mid[s, 1] + mid[r, 2] * mid[s, 2] > 0.0:
                hit[r] = True
                break
    return hit


@njit
def first_fold(a, unit, window):
    """The first chords of the closed loop ``a`` (K, 3) that cross: ``(i, j)``, chord ``i -> i+1``
    crossing chord ``i+j -> i+j+1``, the least ``j`` in ``2 .. window`` and then the least ``i``;
    ``(-1, -1)`` when none does. ``unit`` (K, 3): each chord's unit pole.
    """
    k = a.shape[0]
    for j in range(2, window + 1):
        for i in range(k):
            i1 = (i + 1) % k
            c = (i + j) % k
            d = (c + 1) % k
            # chord c -> d's ends on two sides of chord i's great circle, and i's of c's
            if not (_across(unit, i, a, c, a, d) and _across(unit, c, a, i, a, i1)):
                continue
            # the chords' midpoints face the same way: (a_i + a_i1) . (a_c + a_d) > 0
            facing = 0.0
            for m in range(3):
                facing += (a[i, m] + a[i1, m]) * (a[c, m] + a[d, m])
            if facing > 0.0:
                return i, j
    return -1, -1
