"""Numba kernels that answer the region's queries from its arcs alone, for meshes a fit may throw
away (no lookup grid), as :func:`limbctl.region.mesh_kernels.query` does. Radians. No fastmath."""

from __future__ import annotations

import math

import numpy as np

from limbctl.geometry.jit import njit
from limbctl.region.mesh_kernels import (
    CONTAIN_TOLERANCE,
    _angle,
    _dot,
    _frame,
    edge_foot,
    slerp_into,
)


@njit
def arc_bounds(vertices, edges):
    """Unit midpoints (E, 3), half lengths (E,) rad and the longest half length of the arcs."""
    n_edges = edges.shape[0]
    mids = np.empty((n_edges, 3))
    half = np.empty(n_edges)
    longest = 0.0
    for e in range(n_edges):
        a = vertices[edges[e, 0]]
        b = vertices[edges[e, 1]]
        # component by component: a whole row brings in numba's shape checks, seconds to compile
        mx = a[0] + b[0]
        my = a[1] + b[1]
        mz = a[2] + b[2]
        norm = math.sqrt(mx * mx + my * my + mz * mz)
        mids[e, 0] = mx / norm
        mids[e, 1] = my / norm
        mids[e, 2] = mz / norm
        half[e] = 0.5 * _angle(a, b)
        longest = max(longest, half[e])
    return mids, half, longest


@njit
def nearest_midpoint(p, mids) -> int:
    """Index of the arc whose midpoint (``mids`` (E, 3)) is nearest ``p`` (3,), the first of
    equal ones; -1 when there are no arcs."""
    nearest = -1
    best_dot = -np.inf
    for e in range(mids.shape[0]):
        # p . mids[e], without handing a row to a kernel (edge_foot says why)
        dot = p[0] * mids[e, 0] + p[1] * mids[e, 1] + p[2] * mids[e, 2]
        if dot > best_dot:
            best_dot = dot
            nearest = e
    return nearest


@njit
def nearest_widened(p, vertices, edges, margins, mids, half, reach, tie, best_point):
    """The nearest widened arc of ``p`` (3,): its index, ``angle - margin`` and angle (rad); its
    point into ``best_point`` (3,). A later arc wins only when nearer by more than ``tie``."""
    closest = nearest_midpoint(p, mids)
    best_arc = -1
    best_key = np.inf
    best_angle = np.inf
    if closest < 0:
        return best_arc, best_key, best_angle
    top = _angle(p, mids[closest]) + half[closest] - margins[closest]
    limit = math.cos(min(top + reach + 1e-9, math.pi))
    for e in range(edges.shape[0]):
        if p[0] * mids[e, 0] + p[1] * mids[e, 1] + p[2] * mids[e, 2] < limit:
            continue
        angle, x, y, z = edge_foot(p, vertices, edges, e)
        if angle - margins[e] < best_key - tie:
            best_key = angle - margins[e]
            best_angle = angle
            best_arc = e
            best_point[0] = x
            best_point[1] = y
            best_point[2] = z
    return best_arc, best_key, best_angle


#: Slack (rad) of the midpoint bound: far above a cosine's rounding (1e-16), costing nothing.
SLACK = 1e-6


@njit
def within_widening(p, vertices, edges, margins, mids, reach_cos) -> bool:
    """Whether some arc's widening holds ``p`` (3,) (within CONTAIN_TOLERANCE); arcs whose
    midpoint lies beyond ``reach_cos[e]`` (:data:`SLACK` wider) are not measured."""
    for e in range(edges.shape[0]):
        if p[0] * mids[e, 0] + p[1] * mids[e, 1] + p[2] * mids[e, 2] < reach_cos[e]:
            continue
        if edge_foot(p, vertices, edges, e)[0] - margins[e] <= CONTAIN_TOLERANCE:
            return True
    return False


@njit
def in_loops(p, vertices, edges, axis, u, v, far_inside) -> bool:
    """Whether ``p`` (3,) lies inside the loops: the parity of crossings of the half-meridian
    beyond ``p`` to ``-axis``, against whether ``-axis`` is inside (``far_inside``)."""
    phi = math.atan2(_dot(p, v), _dot(p, u))
    cp = math.cos(phi)
    sp = math.sin(phi)
    theta = _angle(p, axis)
    # n: the meridian plane's normal, -sin(phi) u + cos(phi) v; m: cos(phi) u + sin(phi) v
    n0 = -sp * u[0] + cp * v[0]
    n1 = -sp * u[1] + cp * v[1]
    n2 = -sp * u[2] + cp * v[2]
    m0 = cp * u[0] + sp * v[0]
    m1 = cp * u[1] + sp * v[1]
    m2 = cp * u[2] + sp * v[2]
    crossings = 0
    for e in range(edges.shape[0]):
        # the arc's ends as scalars: no row handed around (edge_foot says why)
        i = edges[e, 0]
        j = edges[e, 1]
        a0, a1, a2 = vertices[i, 0], vertices[i, 1], vertices[i, 2]
        b0, b1, b2 = vertices[j, 0], vertices[j, 1], vertices[j, 2]
        # a.n and b.n, summed from 0 in component order
        an = 0.0
        an += a0 * n0
        an += a1 * n1
        an += a2 * n2
        bn = 0.0
        bn += b0 * n0
        bn += b1 * n1
        bn += b2 * n2
        if (an > 0.0) == (bn > 0.0):
            continue
        # the arc meets the plane at x = (1 - t) a + t b, t = a.n / (a.n - b.n); on the
        # half-meridian when x.m > 0
        t = an / (an - bn)
        x0 = (1.0 - t) * a0 + t * b0
        x1 = (1.0 - t) * a1 + t * b1
        x2 = (1.0 - t) * a2 + t * b2
        xe = 0.0
        xe += x0 * m0
        xe += x1 * m1
        xe += x2 * m2
        xa = 0.0
        xa += x0 * axis[0]
        xa += x1 * axis[1]
        xa += x2 * axis[2]
        if xe > 0.0 and math.atan2(xe, xa) > theta:
            crossings += 1
    return far_inside != (crossings % 2 == 1)


@njit
def query_batch(vertices, edges, margins, axis, far_inside, d, project):
    """Whether each direction of ``d`` (N, 3) is in the region (N,) bool, and when ``project``
    its projection (N, 3) (else (0, 3)). One thread: a pool's compile costs seconds."""
    n = d.shape[0]
    inside = np.empty(n, dtype=np.bool_)
    out = np.empty((n if project else 0, 3))
    mids, half, longest = arc_bounds(vertices, edges)
    max_margin = 0.0
    for e in range(edges.shape[0]):
        max_margin = max(max_margin, margins[e])
    u, v = _frame(axis)
    best_point = np.empty(3)
    if not project:
        # containment alone: any widening holding the direction will do, not the nearest
        reach_cos = np.empty(edges.shape[0])
        for e in range(edges.shape[0]):
            reach_cos[e] = math.cos(min(half[e] + margins[e] + CONTAIN_TOLERANCE + SLACK, math.pi))
        for j in range(n):
            p = d[j]
            inside[j] = within_widening(p, vertices, edges, margins, mids, reach_cos) or in_loops(
                p, vertices, edges, axis, u, v, far_inside
            )
        return inside, out
    for j in range(n):
        p = d[j]
        arc, key, angle = nearest_widened(
            p, vertices, edges, margins, mids, half, longest + max_margin, 0.0, best_point
        )
        inside[j] = key <= CONTAIN_TOLERANCE or in_loops(p, vertices, edges, axis, u, v, far_inside)
        if inside[j] or arc < 0:
            out[j, 0] = p[0]
            out[j, 1] = p[1]
            out[j, 2] = p[2]
        else:
            slerp_into(best_point, p, angle, margins[arc], out[j])
    return inside, out
