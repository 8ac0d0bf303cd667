"""From scattered limb directions to smooth closed boundary loops of the region they fill.

The steps the Rigid Map's gate runs on top of its trained support weights (all angles radians):

1. :func:`thin` keeps a subset of directions at least ``spacing`` apart (greedy Poisson-disk,
   outermost first), so that a 100 Hz hand recording and i.i.d. samples look alike.
2. :func:`learn_alpha` picks the alpha-shape radius from the data's own scale: the gaps the
   points leave inside the region they enclose (strokes of a hand recording cross and enclose
   the empty space between them; that space's empty-circle radii set the scale).
3. :func:`alpha_loops` triangulates, keeps triangles with circumradius <= alpha, fills holes
   smaller than ``max_hole`` and returns the boundary as closed loops, region on the left.
4. :func:`smooth_loop` resamples a loop at even arc length and smooths it with a Gaussian along
   the loop (the vertices of an alpha shape are the outermost points: a jagged polygon).
5. :func:`edge_offsets` learns how far beyond each part of a loop the true edge lies from the
   data near it (an endpoint estimate on the outermost samples' depths) and
   :func:`offset_loop` moves the loop out by that much.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from limbctl.envelope.boundary import (
    boundary_edges,
    circumradius,
    inside_reference,
    spherical_delaunay,
)


def chord(angle: float) -> float:
    """Chord length of an angle (rad) on the unit sphere: ``2 sin(angle / 2)``."""
    return 2.0 * np.sin(0.5 * angle)


def thin(d: np.ndarray, spacing: float) -> np.ndarray:
    """Indices of directions ``d`` (N, 3) kept at least ``spacing`` (rad) apart.

    Greedy Poisson-disk thinning, outermost first (largest angle from the mean direction): every
    direction of ``d`` lies within ``spacing`` of a kept one, and the points that reach farthest
    out are the ones kept.
    """
    mean = d.mean(axis=0)
    norm = np.linalg.norm(mean)
    axis = mean / norm if norm > 1e-9 else d[0]
    order = np.argsort(d @ axis, kind="stable")
    tree = cKDTree(d)
    taken = np.zeros(d.shape[0], dtype=bool)
    keep = []
    for i, near in zip(order, tree.query_ball_point(d[order], chord(spacing)), strict=True):
        if taken[i]:
            continue
        keep.append(i)
        taken[near] = True
    return np.sort(np.asarray(keep, dtype=np.int64))


def _components(n: int, tri: np.ndarray) -> np.ndarray:
    """Label (n,) of the connected component of each vertex under triangles ``tri``."""
    parent = np.arange(n)

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for a, b, c in tri:
        ra, rb, rc = root(a), root(b), root(c)
        parent[rb] = ra
        parent[root(rc)] = ra
    return np.array([root(i) for i in range(n)])


def learn_alpha(d: np.ndarray, factor: float, quantile: float = 0.9) -> float:
    """The alpha-shape radius (rad) from the scale of the gaps inside the data ``d`` (V, 3).

    ``alpha0`` is the smallest circumradius at which the alpha complex joins 99% of the points
    into one piece; the gaps are the Delaunay triangles enclosed by that piece (inside its outer
    loop), and ``alpha = factor * quantile(circumradius of enclosed triangles)``, at least
    ``alpha0``. On i.i.d. samples this is a few times the sample spacing; on hand strokes it is
    the size of the holes between strokes, so they fill while concavities larger than that stay.
    """
    tri = spherical_delaunay(d)
    radius = circumradius(d, tri)
    order = np.argsort(radius)
    n = d.shape[0]
    parent = np.arange(n)
    size = np.ones(n, dtype=np.int64)

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    alpha0 = float(radius[order[-1]])
    target = int(np.ceil(0.99 * n))
    for t in order:
        a = root(tri[t, 0])
        for v in tri[t, 1:]:
            b = root(v)
            if a != b:
                if size[a] < size[b]:
                    a, b = b, a
                parent[b] = a
                size[a] += size[b]
        if size[a] >= target:
            alpha0 = float(radius[t])
            break
    _, _, inside = alpha_complex(d, alpha0, max_hole=4.0 * np.pi)
    if not inside.any():
        return alpha0
    return max(alpha0, factor * float(np.quantile(radius[inside], quantile)))


def tri_centroids(d: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Unit centroid directions (T, 3) of triangles ``tri`` over vertices ``d``."""
    c = d[tri[:, 0]] + d[tri[:, 1]] + d[tri[:, 2]]
    return c / np.linalg.norm(c, axis=1, keepdims=True)


def enclosed(p: np.ndarray, loops: list[np.ndarray]) -> np.ndarray:
    """(N,) bool: directions ``p`` (N, 3) inside the closed loops (region on their left)."""
    if not loops:
        return np.zeros(p.shape[0], dtype=bool)
    vertices, edges = loops_to_edges(loops)
    return inside_reference(p, vertices, edges)


def loops_to_edges(loops: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Stack loops into vertices (V, 3) and directed edges (V, 2) joining consecutive points."""
    vertices = np.vstack(loops)
    idx = []
    start = 0
    for lp in loops:
        i = np.arange(start, start + lp.shape[0])
        idx.append(np.column_stack([i, np.roll(i, -1)]))
        start += lp.shape[0]
    return vertices, np.vstack(idx)


def loop_area(loop: np.ndarray) -> float:
    """Signed area (sr) enclosed by a loop (M, 3): positive when the region is on its left.

    Sum of the signed spherical triangles (c, a, b) from the loop's mean direction ``c``:
    ``2 atan2(det(c, a, b), 1 + c.a + a.b + b.c)``.
    """
    c = loop.mean(axis=0)
    c /= np.linalg.norm(c)
    a = loop
    b = np.roll(loop, -1, axis=0)
    det = np.cross(a, b) @ c
    den = 1.0 + a @ c + np.sum(a * b, axis=1) + b @ c
    return float(np.sum(2.0 * np.arctan2(det, den)))


def trace_loops(d: np.ndarray, edges: np.ndarray) -> list[np.ndarray]:
    """Chain directed boundary edges (E, 2) into closed loops of vertex indices.

    At a vertex with several outgoing edges (two pieces touching at a point) the loop takes the
    one turning most to the left, which keeps each piece's boundary separate.
    """
    outgoing: dict[int, list[int]] = {}
    for e, (a, _) in enumerate(edges):
        outgoing.setdefault(int(a), []).append(e)
    used = np.zeros(edges.shape[0], dtype=bool)
    loops = []
    for first in range(edges.shape[0]):
        if used[first]:
            continue
        loop = []
        e = first
        while not used[e]:
            used[e] = True
            a, v = int(edges[e, 0]), int(edges[e, 1])
            loop.append(a)
            choices = [c for c in outgoing.get(v, []) if not used[c]]
            if not choices:
                break
            if len(choices) == 1:
                e = choices[0]
                continue
            # heading at v: -(a - (a.v) v); turn to each candidate b: atan2(v.(h x t), h.t)
            pv = d[v]
            heading = -(d[a] - (d[a] @ pv) * pv)
            best, best_turn = choices[0], -np.inf
            for c in choices:
                b = d[edges[c, 1]]
                t = b - (b @ pv) * pv
                turn = np.arctan2(pv @ np.cross(heading, t), heading @ t)
                if turn > best_turn:
                    best, best_turn = c, turn
            e = best
        if len(loop) >= 3:
            loops.append(np.asarray(loop, dtype=np.int64))
    return loops


def triangle_area(d: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Area (T,) in sr of spherical triangles: ``2 atan2(|det(a,b,c)|, 1 + a.b + b.c + c.a)``."""
    a, b, c = d[tri[:, 0]], d[tri[:, 1]], d[tri[:, 2]]
    det = np.abs(np.einsum("ij,ij->i", a, np.cross(b, c)))
    den = 1.0 + np.sum(a * b, axis=1) + np.sum(b * c, axis=1) + np.sum(c * a, axis=1)
    return 2.0 * np.arctan2(det, den)


def alpha_complex(
    d: np.ndarray, alpha: float, max_hole: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Delaunay triangles (T, 3) of ``d``, their circumradii (T,) and which are in the region.

    A triangle is in the region when its circumradius is at most ``alpha``, or when it belongs
    to a hole: a piece of the other triangles (joined across shared edges) that does not reach
    the outside of the triangulation, with a total area below ``max_hole`` (sr).
    """
    tri = spherical_delaunay(d)
    radius = circumradius(d, tri)
    kept = radius <= alpha
    t = tri.shape[0]
    key = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    owner = np.tile(np.arange(t), 3)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    order = np.argsort(inverse, kind="stable")
    pairs = owner[order].reshape(-1)
    shared = counts[inverse[order]] == 2
    first = pairs[shared][0::2]
    second = pairs[shared][1::2]
    # pieces of non-region triangles joined across shared edges (union-find)
    parent = np.arange(t)

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for a, b in zip(first, second, strict=True):
        if not kept[a] and not kept[b]:
            parent[root(a)] = root(b)
    label = np.array([root(i) for i in range(t)])
    outside = np.zeros(t, dtype=bool)
    outside[label[owner[order][~shared]]] = True
    area = np.bincount(label, weights=triangle_area(d, tri) * ~kept, minlength=t)
    hole = ~kept & ~outside[label] & (area[label] < max_hole)
    return tri, radius, kept | hole


def alpha_loops(d: np.ndarray, alpha: float, max_hole: float) -> list[np.ndarray]:
    """Boundary loops (each (M, 3) directions, region on the left) of the alpha shape of ``d``.

    Holes with an area below ``max_hole`` (sr) are filled (see :func:`alpha_complex`). Returns
    an empty list when no triangle has circumradius <= ``alpha``.
    """
    tri, _, inside = alpha_complex(d, alpha, max_hole)
    if not inside.any():
        return []
    return [d[idx] for idx in trace_loops(d, boundary_edges(tri[inside]))]


def resample(loop: np.ndarray, step: float) -> np.ndarray:
    """Points (K, 3) evenly ``~step`` (rad) apart along a closed loop (M, 3)."""
    closed = np.vstack([loop, loop[:1]])
    seg = np.arccos(np.clip(np.sum(closed[1:] * closed[:-1], axis=1), -1.0, 1.0))
    s = np.concatenate([[0.0], np.cumsum(seg)])
    count = max(8, int(np.ceil(s[-1] / step)))
    t = np.linspace(0.0, s[-1], count, endpoint=False)
    out = np.column_stack([np.interp(t, s, closed[:, k]) for k in range(3)])
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def smooth_loop(loop: np.ndarray, step: float, sigma: float) -> np.ndarray:
    """Resample a loop at ``step`` and smooth it with a Gaussian of ``sigma`` (rad) along it.

    ``p_i <- normalise(sum_j g(j) p_{i+j})`` with ``g(j) ~ exp(-(j step)^2 / (2 sigma^2))``,
    circularly; the width is limited to a sixth of the loop so small loops keep their shape.
    """
    pts = resample(loop, step)
    k = pts.shape[0]
    s = min(sigma / step, k / 6.0)
    if s < 0.5:
        return pts
    half = min(int(np.ceil(3.0 * s)), (k - 1) // 2)
    j = np.arange(-half, half + 1)
    g = np.exp(-(j * j) / (2.0 * s * s))
    g /= g.sum()
    out = np.zeros_like(pts)
    for w, shift in zip(g, j, strict=True):
        out += w * np.roll(pts, -shift, axis=0)
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def outward_normals(loop: np.ndarray) -> np.ndarray:
    """Unit outward normals (M, 3) of a loop (region on the left): ``t x p`` normalised."""
    t = np.roll(loop, -1, axis=0) - np.roll(loop, 1, axis=0)
    n = np.cross(t, loop)
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def edge_offsets(
    loops: list[np.ndarray],
    data: np.ndarray,
    window: float,
    top: int,
    max_extension: float,
    step: float,
) -> list[np.ndarray]:
    """How far (rad) to move each loop point outward so the loop sits at the true edge.

    Each data direction (N, 3) is assigned to its nearest loop point and measured along that
    point's outward normal, ``o = asin(d . n)``. Over a window of +- ``window`` (rad) along the
    loop, the outermost depths ``o_(1) >= ... >= o_(top)`` give the endpoint estimate
    ``o_(1) + min(gap, max_extension)`` (see :func:`_gap_beyond`). The estimates are Gaussian
    smoothed along the loop, and never below the depth of any sample assigned to the point.
    """
    flat = np.vstack(loops)
    owner = np.concatenate([np.full(lp.shape[0], i) for i, lp in enumerate(loops)])
    normals = np.vstack([outward_normals(lp) for lp in loops])
    _, nearest = cKDTree(flat).query(data)
    depth = np.arcsin(np.clip(np.sum(data * normals[nearest], axis=1), -1.0, 1.0))
    out = []
    start = 0
    for i, lp in enumerate(loops):
        m = lp.shape[0]
        mine = owner[nearest] == i
        local = nearest[mine] - start
        o = depth[mine]
        need = np.full(m, -np.inf)
        np.maximum.at(need, local, o)
        half = min(int(np.ceil(window / step)), (m - 1) // 2)
        order = np.argsort(local, kind="stable")
        local, o = local[order], o[order]
        bounds = np.searchsorted(local, np.arange(m + 1))
        est = np.full(m, np.nan)
        for v in range(m):
            idx = [(v + j) % m for j in range(-half, half + 1)]
            vals = np.concatenate([o[bounds[k] : bounds[k + 1]] for k in idx])
            if vals.size == 0:
                continue
            vals = -np.sort(-vals)[:top]
            est[v] = vals[0] + min(_gap_beyond(vals), max_extension)
        if np.isnan(est).all():
            est[:] = 0.0
        else:
            # windows without data take the nearest estimate along the loop
            known = np.flatnonzero(~np.isnan(est))
            pos = np.arange(m)
            est = np.interp(pos, known, est[known], period=m)
        sm = _smooth_values(est, window / step)
        out.append(np.maximum(sm, need))
        start += m
    return out


def _gap_beyond(vals: np.ndarray) -> float:
    """How far beyond the outermost of sorted depths ``vals`` (K,) the edge is expected.

    Near an edge with locally even density the outermost depths fall on a line,
    ``E[o_(i)] = edge - i g``; the least-squares line through ``(i, o_(i))``, i = 1..K, gives
    the edge at ``i = 0``, and the result is ``max(edge - o_(1), 0)``.
    """
    k = vals.size
    if k < 3:
        return 0.0
    i = np.arange(1, k + 1, dtype=np.float64)
    # slope and intercept of the least-squares line o = c + s i
    slope = np.sum((i - i.mean()) * (vals - vals.mean())) / np.sum((i - i.mean()) ** 2)
    intercept = vals.mean() - slope * i.mean()
    return max(float(intercept - vals[0]), 0.0)


def _smooth_values(values: np.ndarray, s: float) -> np.ndarray:
    """Circular Gaussian smoothing of ``values`` (M,) with width ``s`` samples."""
    m = values.shape[0]
    s = min(s, m / 6.0)
    if s < 0.5:
        return values.copy()
    half = min(int(np.ceil(3.0 * s)), (m - 1) // 2)
    j = np.arange(-half, half + 1)
    g = np.exp(-(j * j) / (2.0 * s * s))
    g /= g.sum()
    out = np.zeros(m)
    for w, shift in zip(g, j, strict=True):
        out += w * np.roll(values, -shift)
    return out


def offset_loop(loop: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Move each loop point (M, 3) by ``offsets`` (M,) rad along its outward normal."""
    n = outward_normals(loop)
    # p' = cos(o) p + sin(o) n
    out = np.cos(offsets)[:, None] * loop + np.sin(offsets)[:, None] * n
    return out / np.linalg.norm(out, axis=1, keepdims=True)
