"""Numba kernels that build the direction-space region's lookup grid (see
:mod:`limbctl.region.mesh_kernels` for the grid and the queries that read it).

:func:`build_grid` decides, per cell, whether it lies deep inside and which boundary arcs can be
nearest to a point in it. Cells are handled in blocks of ``BLOCK x BLOCK``: a block first finds
the few arcs any of its cells can need, and each cell then tests only those, with the same
arithmetic on the same arcs in the same order as testing all of them (the same grid).
No fastmath: every comparison sees NaN as failing.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from limbctl.region.mesh_kernels import _angle, _dot, _frame, _polar_point, nearest_on_arc


@nb.njit(cache=True)
def _edge_bounds(vertices, edges):
    """Unit midpoint (E, 3) and half length (E,) rad of each boundary arc."""
    n_edges = edges.shape[0]
    mids = np.empty((n_edges, 3))
    half = np.empty(n_edges)
    for e in range(n_edges):
        a = vertices[edges[e, 0]]
        b = vertices[edges[e, 1]]
        m = a + b
        m /= math.sqrt(_dot(m, m))
        mids[e] = m
        half[e] = 0.5 * _angle(a, b)
    return mids, half


@nb.njit(cache=True)
def _cell_geometry(cell, n_theta, n_phi, axis, u, v):
    """Centre (3,) of a grid cell and a radius (rad) that every point of the cell lies within."""
    i = cell // n_phi
    j = cell % n_phi
    t0 = i * math.pi / n_theta
    p0 = -math.pi + j * 2.0 * math.pi / n_phi
    dt = math.pi / n_theta
    dp = 2.0 * math.pi / n_phi
    centre = _polar_point(t0 + 0.5 * dt, p0 + 0.5 * dp, axis, u, v)
    r = 0.0
    for a in range(2):
        for b in range(2):
            corner = _polar_point(t0 + a * dt, p0 + b * dp, axis, u, v)
            r = max(r, _angle(centre, corner))
    # the widest point of a cell edge lies on its middle; 1 % covers it (cells are < 3 deg)
    return centre, r * 1.01 + 1e-12


#: Cells per side of the grid's blocks (theta and phi): a block finds the arcs its cells can need
#: once, so each cell tests those few instead of all; 8 x 8 cells of ~1 deg keep that list short.
BLOCK = 8


@nb.njit(cache=True)
def _block(
    block,
    blocks_phi,
    grid_shape,
    axis,
    u,
    v,
    vertices,
    edges,
    margins,
    max_margin,
    centres,
    radius,
    tmp,
):
    """The cells (K,) of one block, their geometry into ``centres``/``radius``, and the arcs
    (A,) in order that any of them can need.

    With ``C`` the block's centre, ``D`` its cells' centres' largest angle from ``C`` and
    ``r`` their largest radius: a cell's candidates and both its minimisers (key and plain)
    have ``key_e(C) <= min key(C) + 2 D + 2 r + max margin`` or ``angle(C, e) <= D + r``
    (each angle moves by at most ``D`` from ``C`` to a cell's centre).
    """
    n_theta, n_phi = grid_shape[0], grid_shape[1]
    bi, bj = block // blocks_phi, block % blocks_phi
    i1, j1 = min(n_theta, (bi + 1) * BLOCK), min(n_phi, (bj + 1) * BLOCK)
    cells = np.empty((i1 - bi * BLOCK) * (j1 - bj * BLOCK), dtype=np.int64)
    k = 0
    for i in range(bi * BLOCK, i1):
        for j in range(bj * BLOCK, j1):
            cells[k] = i * n_phi + j
            centres[cells[k]], radius[cells[k]] = _cell_geometry(
                cells[k], n_theta, n_phi, axis, u, v
            )
            k += 1
    # the block's centre: the middle of its polar rectangle
    theta = 0.5 * (bi * BLOCK + i1) * math.pi / n_theta
    c = _polar_point(theta, -math.pi + 0.5 * (bj * BLOCK + j1) * 2.0 * math.pi / n_phi, axis, u, v)
    spread = 0.0
    r = 0.0
    for cell in cells:
        spread = max(spread, _angle(c, centres[cell]))
        r = max(r, radius[cell])
    dist = np.empty(edges.shape[0])
    best = np.inf
    for e in range(edges.shape[0]):
        dist[e] = nearest_on_arc(c, vertices[edges[e, 0]], vertices[edges[e, 1]], tmp)
        best = min(best, dist[e] - margins[e])
    # 1e-9 rad of slack for rounding: a few arcs too many cost nothing
    limit = best + 2.0 * spread + 2.0 * r + max_margin + 1e-9
    arcs = np.empty(edges.shape[0], dtype=np.int64)
    n = 0
    for e in range(edges.shape[0]):
        if dist[e] - margins[e] <= limit or dist[e] <= spread + r + 1e-9:
            arcs[n] = e
            n += 1
    return cells, arcs[:n]


#: Candidate arcs a cell keeps from its first pass (most cells have about a dozen); a cell with
#: more finds them again once the grid's arrays are sized.
FIRST_PASS_ARCS = 32


@nb.njit(cache=True)
def _cell(
    cell,
    inside,
    arcs,
    centres,
    radius,
    vertices,
    edges,
    margins,
    mids,
    half,
    reach,
    max_margin,
    tmp,
    dist,
    out_edges,
    out_keys,
):
    """One cell: (deep, bound, number of candidates); the first ``len(out_edges)`` candidates
    (in arc order) and their keys into ``out_edges``/``out_keys``.

    ``arcs`` (A,) must hold the cell's candidates and both minimisers (:func:`_block`),
    ``reach`` is the longest half arc plus the largest margin, ``dist`` (A,) scratch.
    """
    centre, r = centres[cell], radius[cell]
    # an upper bound on the smallest key: every point of an arc lies within its half length of
    # its midpoint, so the arc whose midpoint is nearest (largest dot) gives one
    nearest = -1
    best_dot = -np.inf
    for e in arcs:
        dot = _dot(centre, mids[e])
        if dot > best_dot:
            best_dot = dot
            nearest = e
    top = np.inf
    if nearest >= 0:
        top = _angle(centre, mids[nearest]) + half[nearest] - margins[nearest]
    # a minimiser (key or plain) or a candidate (key <= top + 2 r, or within r) lies within
    # x = max(top + 2 r, r) + max margin of the centre, so its midpoint within x + half + margin:
    # the longest arc's bound first (cheap), then the arc's own
    x = max(top + 2.0 * r, r) + max_margin
    limit = math.cos(min(x + reach + 1e-9, math.pi))
    best_key = np.inf
    best_plain = np.inf
    for s in range(arcs.shape[0]):
        e = arcs[s]
        dist[s] = np.inf
        dot = _dot(centre, mids[e])
        if dot < limit or dot < math.cos(min(x + half[e] + margins[e] + 1e-9, math.pi)):
            continue
        dist[s] = nearest_on_arc(centre, vertices[edges[e, 0]], vertices[edges[e, 1]], tmp)
        best_key = min(best_key, dist[s] - margins[e])
        best_plain = min(best_plain, dist[s])
    deep = (inside[cell] and best_plain >= r) or (best_key + r <= 0.0)
    bound = best_key + 2.0 * r
    if deep:
        return deep, bound, 0
    k = 0
    for s in range(arcs.shape[0]):
        e = arcs[s]
        # arcs not measured lie beyond x: neither condition holds for them
        if dist[s] - margins[e] <= bound or dist[s] <= r:
            if k < out_edges.shape[0]:
                out_edges[k] = e
                out_keys[k] = dist[s] - margins[e]
            k += 1
    return deep, bound, k


@nb.njit(cache=True, parallel=True)
def build_grid(vertices, edges, margins, axis, grid_shape, inside):
    """Cell depth status and sorted candidate arcs (module docstring) -> deep, start, arcs, keys.

    ``inside`` (cells,) says whether each cell's centre lies in the mesh; ``margins`` (E,) is
    each arc's widening (rad). A cell is deep when all of it lies in the mesh (centre inside,
    the boundary at least the cell radius ``r`` away) or in one arc's widening
    (``min_e (angle(centre, e) - m_e) <= -r``). Otherwise its candidates are the arcs with
    ``key_e = angle(centre, e) - m_e <= min_key + 2 r`` (the nearest widened arc of any point
    of the cell is among them: pruned by the smallest upper bound ``min_key + r``) and the arcs
    within ``r`` of the centre (every arc crossing the path centre -> point), sorted by key.
    """
    n_theta, n_phi = grid_shape[0], grid_shape[1]
    n_cells = n_theta * n_phi
    u, v = _frame(axis)
    mids, half = _edge_bounds(vertices, edges)
    max_margin = 0.0
    reach = 0.0
    for e in range(edges.shape[0]):
        max_margin = max(max_margin, margins[e])
        reach = max(reach, half[e])
    reach += max_margin
    deep = np.zeros(n_cells, dtype=np.bool_)
    counts = np.zeros(n_cells, dtype=np.int64)
    bound = np.empty(n_cells)
    radius = np.empty(n_cells)
    centres = np.empty((n_cells, 3))
    first_edges = np.empty((n_cells, FIRST_PASS_ARCS), dtype=np.int64)
    first_keys = np.empty((n_cells, FIRST_PASS_ARCS))
    blocks_phi = (n_phi + BLOCK - 1) // BLOCK
    n_blocks = ((n_theta + BLOCK - 1) // BLOCK) * blocks_phi
    for block in nb.prange(n_blocks):
        tmp = np.empty(3)
        cells, arcs = _block(
            block,
            blocks_phi,
            grid_shape,
            axis,
            u,
            v,
            vertices,
            edges,
            margins,
            max_margin,
            centres,
            radius,
            tmp,
        )
        dist = np.empty(arcs.shape[0])
        for cell in cells:
            deep[cell], bound[cell], counts[cell] = _cell(
                cell,
                inside,
                arcs,
                centres,
                radius,
                vertices,
                edges,
                margins,
                mids,
                half,
                reach,
                max_margin,
                tmp,
                dist,
                first_edges[cell],
                first_keys[cell],
            )
    start = np.zeros(n_cells + 1, dtype=np.int64)
    for cell in range(n_cells):
        start[cell + 1] = start[cell] + counts[cell]
    cell_edges = np.empty(start[n_cells], dtype=np.int64)
    cell_keys = np.empty(start[n_cells])
    for block in nb.prange(n_blocks):
        tmp = np.empty(3)
        cells, arcs = _block(
            block,
            blocks_phi,
            grid_shape,
            axis,
            u,
            v,
            vertices,
            edges,
            margins,
            max_margin,
            centres,
            radius,
            tmp,
        )
        dist = np.empty(arcs.shape[0])
        for cell in cells:
            k0, k = start[cell], start[cell + 1]
            if k - k0 <= FIRST_PASS_ARCS:
                cell_edges[k0:k] = first_edges[cell, : k - k0]
                cell_keys[k0:k] = first_keys[cell, : k - k0]
            else:
                _cell(
                    cell,
                    inside,
                    arcs,
                    centres,
                    radius,
                    vertices,
                    edges,
                    margins,
                    mids,
                    half,
                    reach,
                    max_margin,
                    tmp,
                    dist,
                    cell_edges[k0:k],
                    cell_keys[k0:k],
                )
            order = np.argsort(cell_keys[k0:k], kind="mergesort")
            cell_edges[k0:k] = cell_edges[k0:k][order]
            cell_keys[k0:k] = cell_keys[k0:k][order]
    return deep, start, cell_edges, cell_keys
