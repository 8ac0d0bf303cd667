"""Numba kernel of the traced edge's estimates (:mod:`limbctl.region.edge_traced`): the same
arithmetic in the same order as its numpy loop (tests/region/test_trace_kernels.py). No fastmath."""

from __future__ import annotations

import numpy as np

from limbctl.geometry.jit import njit
from limbctl.region.gaps import MAJORANT_GAP, ORDER_STATISTICS
from limbctl.region.sort_kernels import largest_stable, sort_values


@njit
def _estimate(u, o, top_readings):
    """:func:`limbctl.region.edge_traced.edge_estimate` of readings at positions ``u`` (M,)
    and depths ``o`` (M,) rad, keeping the ``top_readings`` outermost."""
    # the outermost first, equal depths in reading order (np.argsort(-o, kind="stable"))
    top = largest_stable(o, top_readings)
    u = u[top]
    o = o[top]
    n_left = 0
    for a in range(u.shape[0]):
        if u[a] < 0.0:
            n_left += 1
    if o.shape[0] < ORDER_STATISTICS or n_left == 0 or n_left == u.shape[0]:
        outer = o.copy()
        sort_values(outer)
        outer = outer[::-1][:ORDER_STATISTICS]
        k = outer.shape[0]
        gap = (outer[0] - outer[k - 1]) / (k - 1) if k >= 3 else 0.0
        return outer[0] + gap
    ul = np.empty(n_left)
    ol = np.empty(n_left)
    ur = np.empty(u.shape[0] - n_left)
    orr = np.empty(u.shape[0] - n_left)
    a = 0
    b = 0
    for m in range(u.shape[0]):
        if u[m] < 0.0:
            ul[a] = u[m]
            ol[a] = o[m]
            a += 1
        else:
            ur[b] = u[m]
            orr[b] = o[m]
            b += 1
    # the highest chord from (u_i, o_i) to (u_j, o_j) at u = 0 over left-right pairs, the
    # first in row-major order on ties (as numpy's argmax)
    at_station = -np.inf
    best_i = 0
    best_j = 0
    for i in range(ul.shape[0]):
        for j in range(ur.shape[0]):
            frac = -ul[i] / (ur[j] - ul[i])
            chord = ol[i] + (orr[j] - ol[i]) * frac
            if chord > at_station:
                at_station = chord
                best_i = i
                best_j = j
    slope = (orr[best_j] - ol[best_i]) / (ur[best_j] - ul[best_i])
    resid = at_station + slope * u - o
    sort_values(resid)
    return at_station + MAJORANT_GAP * resid[ORDER_STATISTICS - 1] / ORDER_STATISTICS


@njit
def station_moves(s, total, owner, depth, order, bounds, reach, top_readings):
    """The edge estimate (K,) rad at each of K stations (0 where a window holds no reading).

    Parameters
    ----------
    s : ndarray, shape (K,)
        Arc-length positions (rad) of the stations along a closed curve of length ``total``.
    owner, depth : ndarray, shape (N,)
        Each reading's station and its depth (rad) beyond the curve.
    order, bounds : ndarray, shape (N,) and (K + 1,)
        Station ``j`` holds readings ``order[bounds[j]:bounds[j + 1]]``.
    reach : int
        Stations either side in a window (read circularly).
    top_readings : int
        Outermost readings of a window the estimate is built from.
    """
    k = s.shape[0]
    move = np.zeros(k)
    for i in range(k):
        count = 0
        for j in range(i - reach, i + reach + 1):
            station = j % k
            count += bounds[station + 1] - bounds[station]
        if count == 0:
            continue
        u = np.empty(count)
        o = np.empty(count)
        n = 0
        for j in range(i - reach, i + reach + 1):
            station = j % k
            for m in range(bounds[station], bounds[station + 1]):
                row = order[m]
                # signed offset along the loop, in [-total / 2, total / 2)
                u[n] = (s[owner[row]] - s[i] + 0.5 * total) % total - 0.5 * total
                o[n] = depth[row]
                n += 1
        move[i] = _estimate(u, o, top_readings)
    return move
