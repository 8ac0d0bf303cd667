"""Numba kernels of the region's shape (:mod:`limbctl.region.shape`). No fastmath."""

from __future__ import annotations

import math

import numpy as np

from limbctl.geometry.jit import njit
from limbctl.region.direct_kernels import arc_bounds, nearest_widened
from limbctl.region.sort_kernels import sort_values

#: Arcs within this (rad) of each other are equally near: above rounding, below any margin.
TIE = 1e-12


@njit
def widest_bearing_gaps(p: np.ndarray, data: np.ndarray, start: np.ndarray, near: np.ndarray):
    """The widest empty sector (rad) about each ``p`` (N, 3) of its neighbours
    ``data[near[start[i]:start[i + 1]]]``, bearings in :func:`limbctl.geometry.quat.tangent_frame`
    (2 pi for fewer than one neighbour)."""
    n = p.shape[0]
    out = np.full(n, 2.0 * np.pi)
    for i in range(n):
        count = start[i + 1] - start[i]
        if count < 1:
            continue
        x, y, z = p[i, 0], p[i, 1], p[i, 2]
        # u = h x p with h = (0, 0, 1): (-y, x, 0); with h = (0, 1, 0): (z, 0, -x)
        if abs(z) < 0.9:
            ux, uy, uz = -y, x, 0.0
        else:
            ux, uy, uz = z, 0.0, -x
        norm = math.sqrt(ux * ux + uy * uy + uz * uz)
        ux, uy, uz = ux / norm, uy / norm, uz / norm
        # v = p x u
        vx, vy, vz = y * uz - z * uy, z * ux - x * uz, x * uy - y * ux
        bearing = np.empty(count)
        for k in range(count):
            s = data[near[start[i] + k]]
            bearing[k] = math.atan2(
                s[0] * vx + s[1] * vy + s[2] * vz, s[0] * ux + s[1] * uy + s[2] * uz
            )
        sort_values(bearing)
        widest = bearing[0] + 2.0 * np.pi - bearing[count - 1]
        for k in range(1, count):
            widest = max(widest, bearing[k] - bearing[k - 1])
        out[i] = widest
    return out


@njit
def nearest_arcs(data: np.ndarray, vertices: np.ndarray, edges: np.ndarray):
    """The nearest arc (N,) of ``edges`` (E, 2) over ``vertices`` (V, 3) to each direction of
    ``data`` (N, 3) and its angle (N,) rad; of arcs within :data:`TIE` the first wins."""
    mids, half, longest = arc_bounds(vertices, edges)
    no_margins = np.zeros(edges.shape[0])
    nearest = np.full(data.shape[0], -1, dtype=np.int64)
    angle = np.full(data.shape[0], np.inf)
    point = np.empty(3)
    for i in range(data.shape[0]):
        nearest[i], _, angle[i] = nearest_widened(
            data[i], vertices, edges, no_margins, mids, half, longest, TIE, point
        )
    return nearest, angle
