"""Numba kernels that build the region's lookup grid (:mod:`limbctl.region.mesh_kernels`).
Cells are handled in ``BLOCK x BLOCK`` blocks: a block finds the few arcs any of its cells can
need, and each cell tests only those, in the same order as all. No fastmath."""

from __future__ import annotations

import math

import numpy as np

from limbctl.geometry.jit import njit
from limbctl.region.direct_kernels import arc_bounds, nearest_midpoint
from limbctl.region.mesh_kernels import _angle, _dot, _frame, _polar_point, edge_foot


@njit
def _polar_into(theta, phi, axis, u, v, out) -> None:
    """Write into ``out`` (3,) the direction at polar angles ``theta``, ``phi`` (rad) about
    ``axis`` (frame ``u``, ``v``), as the queries compute it."""
    st = math.sin(theta)
    ct = math.cos(theta)
    cp = math.cos(phi)
    sp = math.sin(phi)
    for k in range(3):
        out[k] = ct * axis[k] + st * (cp * u[k] + sp * v[k])


@njit
def _cell_geometry(cell, n_theta, n_phi, axis, u, v, centre, corner):
    """A grid cell's centre into ``centre`` (3,) and a radius (rad) every point of the cell
    lies within (``corner`` (3,) is scratch)."""
    i = cell // n_phi
    j = cell % n_phi
    t0 = i * math.pi / n_theta
    p0 = -math.pi + j * 2.0 * math.pi / n_phi
    dt = math.pi / n_theta
    dp = 2.0 * math.pi / n_phi
    _polar_into(t0 + 0.5 * dt, p0 + 0.5 * dp, axis, u, v, centre)
    r = 0.0
    for a in range(2):
        for b in range(2):
            _polar_into(t0 + a * dt, p0 + b * dp, axis, u, v, corner)
            r = max(r, _angle(centre, corner))
    # the widest point of a cell edge lies on its middle; 1 % covers it (cells are < 3 deg)
    return r * 1.01 + 1e-12


#: Cells per block side: 8 x 8 cells of ~1 deg keep a block's arc list short.
BLOCK = 8


@njit
def _block_cells(block, blocks_phi, n_theta, n_phi):
    """The cells (K,) of one block, row by row."""
    bi, bj = block // blocks_phi, block % blocks_phi
    i1, j1 = min(n_theta, (bi + 1) * BLOCK), min(n_phi, (bj + 1) * BLOCK)
    cells = np.empty((i1 - bi * BLOCK) * (j1 - bj * BLOCK), dtype=np.int64)
    k = 0
    for i in range(bi * BLOCK, i1):
        for j in range(bj * BLOCK, j1):
            cells[k] = i * n_phi + j
            k += 1
    return cells


@njit
def _block_arcs(block, blocks_phi, frame, geometry, dist, block_arcs, block_arc_dist, from_block):
    """The arcs one block's cells can need into its row of ``block_arcs`` (blocks, E), their
    angles (rad) from the block's centre into its row of ``block_arc_dist``; returns their number.
    Each cell's angle from the block's centre goes into ``from_block``; ``dist`` (E,) is scratch.
    Arcs whose midpoint cannot meet the block's widened bounds are not measured. ``frame`` and
    ``geometry`` are :func:`build_grid`'s."""
    grid_shape, axis, u, v = frame
    centres, radius, vertices, edges, margins, mids, _, _, max_margin, longest_half = geometry
    arcs, arc_dist = block_arcs[block], block_arc_dist[block]
    n_theta, n_phi = grid_shape[0], grid_shape[1]
    bi, bj = block // blocks_phi, block % blocks_phi
    i1, j1 = min(n_theta, (bi + 1) * BLOCK), min(n_phi, (bj + 1) * BLOCK)
    # the block's centre: the middle of its polar rectangle
    theta = 0.5 * (bi * BLOCK + i1) * math.pi / n_theta
    c = _polar_point(theta, -math.pi + 0.5 * (bj * BLOCK + j1) * 2.0 * math.pi / n_phi, axis, u, v)
    spread = 0.0
    r = 0.0
    for i in range(bi * BLOCK, i1):
        for j in range(bj * BLOCK, j1):
            cell = i * n_phi + j
            from_block[cell] = _angle(c, centres[cell])
            spread = max(spread, from_block[cell])
            r = max(r, radius[cell])
    # an upper bound on the smallest key: every point of an arc lies within its half length
    # of its midpoint, so the arc whose midpoint is nearest (largest dot) gives one
    nearest = nearest_midpoint(c, mids)
    top = np.inf
    if nearest >= 0:
        top = (
            _angle(c, mids[nearest])
            + 0.5 * _angle(vertices[edges[nearest, 0]], vertices[edges[nearest, 1]])
            - margins[nearest]
        )
    # an arc kept or minimising lies within x of C (its key <= top + 2 D + 2 r + max margin,
    # its margin <= max margin), so its midpoint within x + its half length
    x = max(top + 2.0 * spread + 2.0 * r + 2.0 * max_margin, spread + r) + 1e-9
    near = math.cos(min(x + longest_half + 1e-9, math.pi))
    best = np.inf
    for e in range(edges.shape[0]):
        dist[e] = np.inf
        if _dot(c, mids[e]) < near:
            continue
        dist[e] = edge_foot(c, vertices, edges, e)[0]
        best = min(best, dist[e] - margins[e])
    # 1e-9 rad of slack for rounding: a few arcs too many cost nothing
    limit = best + 2.0 * spread + 2.0 * r + max_margin + 1e-9
    n = 0
    for e in range(edges.shape[0]):
        if dist[e] - margins[e] <= limit or dist[e] <= spread + r + 1e-9:
            arcs[n] = e
            arc_dist[n] = dist[e]
            n += 1
    return n


#: Candidates a cell keeps in its first pass (most have a dozen); more are found again.
FIRST_PASS_ARCS = 32


@njit
def _cell(cell, inside, arcs, arc_dist, from_block, geometry, dist, out_edges, out_keys):
    """One cell: (deep, candidate count); its candidates and keys into ``out_edges``, ``out_keys``.
    ``arcs`` (A,) hold the block's arcs, ``arc_dist`` (A,) their angles (rad) from its centre,
    ``from_block`` the cell's; ``geometry`` holds what :func:`build_grid` shares with every
    cell: centres, radii, vertices, edges, margins, arc midpoints and half lengths, ``reach``
    (the longest half arc plus the largest margin), the largest margin and the longest half."""
    centres, radius, vertices, edges, margins, mids, half, reach, max_margin, _ = geometry
    centre, r = centres[cell], radius[cell]
    if inside[cell]:
        # deep when no arc comes within r: each arc's angle from the cell's centre is at least
        # its angle from the block's centre less ``from_block``
        clear = True
        for s in range(arcs.shape[0]):
            if arc_dist[s] - from_block - 1e-9 <= r:
                clear = False
                break
        if clear:
            return True, 0
    # an upper bound on the smallest key: the block's arcs hold the minimiser, and each arc's
    # angle from the cell's centre is within ``from_block`` of its angle from the block's
    top = np.inf
    for s in range(arcs.shape[0]):
        top = min(top, arc_dist[s] + from_block - margins[arcs[s]])
    top += 1e-9
    # a minimiser (key or plain) or a candidate (key <= top + 2 r, or within r) lies within
    # x = max(top + 2 r, r) + max margin of the centre, so its midpoint within x + half + margin
    x = max(top + 2.0 * r, r) + max_margin
    limit = math.cos(min(x + reach + 1e-9, math.pi))
    best_key = np.inf
    best_plain = np.inf
    for s in range(arcs.shape[0]):
        e = arcs[s]
        dist[s] = np.inf
        closest = arc_dist[s] - from_block - 1e-9
        if closest - margins[e] > top + 2.0 * r and closest > r:
            continue
        dot = _dot(centre, mids[e])
        if dot < limit or dot < math.cos(min(x + half[e] + margins[e] + 1e-9, math.pi)):
            continue
        dist[s] = edge_foot(centre, vertices, edges, e)[0]
        best_key = min(best_key, dist[s] - margins[e])
        best_plain = min(best_plain, dist[s])
    deep = (inside[cell] and best_plain >= r) or (best_key + r <= 0.0)
    bound = best_key + 2.0 * r
    if deep:
        return deep, 0
    k = 0
    for s in range(arcs.shape[0]):
        e = arcs[s]
        # arcs not measured lie beyond x: neither condition holds for them
        if dist[s] - margins[e] <= bound or dist[s] <= r:
            if k < out_edges.shape[0]:
                out_edges[k] = e
                out_keys[k] = dist[s] - margins[e]
            k += 1
    return deep, k


@njit
def _sort_by_key(cell_edges, cell_keys) -> None:
    """Sort one cell's candidates (in place) by key, equal keys kept in their order: an
    insertion sort, as a stable sort orders them (a cell holds a few dozen at most)."""
    for a in range(1, cell_keys.shape[0]):
        key = cell_keys[a]
        edge = cell_edges[a]
        b = a - 1
        while b >= 0 and cell_keys[b] > key:
            cell_keys[b + 1] = cell_keys[b]
            cell_edges[b + 1] = cell_edges[b]
            b -= 1
        cell_keys[b + 1] = key
        cell_edges[b + 1] = edge


@njit
def build_grid(vertices, edges, margins, axis, grid_shape, inside):
    """Per cell: deep (bool), and its candidate arcs sorted by key -> deep, start, arcs, keys.
    ``inside`` (cells,) says whether each cell's centre lies in the loops; ``margins`` (E,) widen
    the arcs (rad). A cell of radius ``r`` is deep when all of it lies in the loops or in one
    arc's widening; otherwise its candidates are the arcs with ``key <= min_key + 2 r`` and those
    within ``r`` of its centre. One thread: a pool saved nothing on two cores."""
    n_theta, n_phi = grid_shape[0], grid_shape[1]
    n_cells = n_theta * n_phi
    n_edges = edges.shape[0]
    u, v = _frame(axis)
    mids, half, longest = arc_bounds(vertices, edges)
    max_margin = 0.0
    for e in range(n_edges):
        max_margin = max(max_margin, margins[e])
    reach = longest + max_margin
    deep = np.zeros(n_cells, dtype=np.bool_)
    counts = np.zeros(n_cells, dtype=np.int64)
    radius = np.empty(n_cells)
    centres = np.empty((n_cells, 3))
    first_edges = np.empty((n_cells, FIRST_PASS_ARCS), dtype=np.int64)
    first_keys = np.empty((n_cells, FIRST_PASS_ARCS))
    blocks_phi = (n_phi + BLOCK - 1) // BLOCK
    n_blocks = ((n_theta + BLOCK - 1) // BLOCK) * blocks_phi
    # each block's arcs, found once and read by both passes
    block_arcs = np.empty((n_blocks, n_edges), dtype=np.int64)
    block_arc_dist = np.empty((n_blocks, n_edges))
    block_count = np.zeros(n_blocks, dtype=np.int64)
    from_block = np.empty(n_cells)
    corner = np.empty(3)
    dist = np.empty(n_edges)
    frame = (grid_shape, axis, u, v)
    geometry = (centres, radius, vertices, edges, margins, mids, half, reach, max_margin, longest)
    # first pass, block by block: cells' geometry, arcs, depth, count, first candidates
    for block in range(n_blocks):
        cells = _block_cells(block, blocks_phi, n_theta, n_phi)
        for cell in cells:
            radius[cell] = _cell_geometry(cell, n_theta, n_phi, axis, u, v, centres[cell], corner)
        count = _block_arcs(
            block, blocks_phi, frame, geometry, dist, block_arcs, block_arc_dist, from_block
        )
        block_count[block] = count
        arcs = block_arcs[block, :count]
        arc_dist = block_arc_dist[block, :count]
        for cell in cells:
            deep[cell], counts[cell] = _cell(
                cell,
                inside,
                arcs,
                arc_dist,
                from_block[cell],
                geometry,
                dist,
                first_edges[cell],
                first_keys[cell],
            )
    start = np.zeros(n_cells + 1, dtype=np.int64)
    for cell in range(n_cells):
        start[cell + 1] = start[cell] + counts[cell]
    cell_edges = np.empty(start[n_cells], dtype=np.int64)
    cell_keys = np.empty(start[n_cells])
    # second pass: each cell's candidates, sorted, into its slice (found again if too few kept)
    for block in range(n_blocks):
        arcs = block_arcs[block, : block_count[block]]
        arc_dist = block_arc_dist[block, : block_count[block]]
        for cell in _block_cells(block, blocks_phi, n_theta, n_phi):
            k0, k = start[cell], start[cell + 1]
            if k - k0 <= FIRST_PASS_ARCS:
                # element by element: a slice assignment brings in numba's shape checks
                for s in range(k - k0):
                    cell_edges[k0 + s] = first_edges[cell, s]
                    cell_keys[k0 + s] = first_keys[cell, s]
            else:
                _cell(
                    cell,
                    inside,
                    arcs,
                    arc_dist,
                    from_block[cell],
                    geometry,
                    dist,
                    cell_edges[k0:k],
                    cell_keys[k0:k],
                )
            _sort_by_key(cell_edges[k0:k], cell_keys[k0:k])
    return deep, start, cell_edges, cell_keys
