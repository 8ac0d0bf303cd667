"""Brute-force :func:`limbctl.region.grid_kernels.build_grid`: every arc from every cell centre."""

from __future__ import annotations

import numpy as np

from limbctl.geometry.jit import njit
from limbctl.region.grid_kernels import _cell_geometry, _sort_by_key
from limbctl.region.mesh_kernels import _frame, nearest_on_arc


@njit
def build_grid_reference(vertices, edges, margins, axis, grid_shape, inside):
    """:func:`build_grid` by brute force: every arc measured from every cell's centre."""
    n_theta, n_phi = grid_shape[0], grid_shape[1]
    n_cells = n_theta * n_phi
    n_edges = edges.shape[0]
    u, v = _frame(axis)
    centre = np.empty(3)
    corner = np.empty(3)
    tmp = np.empty(3)
    dist = np.empty((n_cells, n_edges))
    radius = np.empty(n_cells)
    deep = np.zeros(n_cells, dtype=np.bool_)
    start = np.zeros(n_cells + 1, dtype=np.int64)
    for cell in range(n_cells):
        radius[cell] = _cell_geometry(cell, n_theta, n_phi, axis, u, v, centre, corner)
        for e in range(n_edges):
            dist[cell, e] = nearest_on_arc(
                centre, vertices[edges[e, 0]], vertices[edges[e, 1]], tmp
            )
        r = radius[cell]
        best_key = np.min(dist[cell] - margins)
        deep[cell] = (inside[cell] and np.min(dist[cell]) >= r) or (best_key + r <= 0.0)
        count = 0
        if not deep[cell]:
            for e in range(n_edges):
                if dist[cell, e] - margins[e] <= best_key + 2.0 * r or dist[cell, e] <= r:
                    count += 1
        start[cell + 1] = start[cell] + count
    cell_edges = np.empty(start[n_cells], dtype=np.int64)
    cell_keys = np.empty(start[n_cells])
    for cell in range(n_cells):
        if deep[cell]:
            continue
        r = radius[cell]
        best_key = np.min(dist[cell] - margins)
        k = start[cell]
        for e in range(n_edges):
            if dist[cell, e] - margins[e] <= best_key + 2.0 * r or dist[cell, e] <= r:
                cell_edges[k] = e
                cell_keys[k] = dist[cell, e] - margins[e]
                k += 1
        _sort_by_key(cell_edges[start[cell] : k], cell_keys[start[cell] : k])
    return deep, start, cell_edges, cell_keys
