"""mesh_kernels.edge_foot: nearest_on_arc's answer bit for bit, from the arc's rows."""

import numpy as np

from limbctl.region.mesh_kernels import edge_foot, nearest_on_arc


def unit(rows: np.ndarray) -> np.ndarray:
    return rows / np.linalg.norm(rows, axis=-1, keepdims=True)


def test_edge_foot_is_nearest_on_arc_bit_for_bit():
    rng = np.random.default_rng(7)
    vertices = unit(rng.normal(size=(60, 3)))
    # a repeated vertex (no great circle), antipodes, and near neighbours
    vertices[1] = vertices[0]
    vertices[3] = -vertices[2]
    vertices[5] = unit(vertices[4] + 1e-9)
    edges = np.stack([np.arange(0, 60, 2), np.arange(1, 60, 2)], axis=1).astype(np.int64)
    points = unit(rng.normal(size=(200, 3)))
    # the arcs' own vertices and the poles of their great circles (no foot)
    a, b = vertices[edges[:, 0]], vertices[edges[:, 1]]
    points = np.concatenate([points, a, b, unit(np.cross(a[2:], b[2:]))])
    out = np.empty(3)
    for p in points:
        for e in range(edges.shape[0]):
            angle = nearest_on_arc(p, vertices[edges[e, 0]], vertices[edges[e, 1]], out)
            got = edge_foot(p, vertices, edges, e)
            assert np.array_equal([angle, *out], list(got), equal_nan=True), (p, e)
