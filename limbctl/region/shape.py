"""From scattered limb directions to the closed boundary loops of the region they fill: thin,
alpha complex, peel, trace the loops, widen each arc (docs/region.md, steps 1-4). Radians."""

from __future__ import annotations

import heapq

import numpy as np
from scipy.spatial import cKDTree

from limbctl.region import shape_kernels
from limbctl.region.gaps import line_gap
from limbctl.region.loops import StationBuckets, chord, loops_to_edges, vertex_turns
from limbctl.region.mesh import circumradius, inside_reference, spherical_delaunay
from limbctl.region.union_find import UnionFind

#: Share of points the alpha scale joins into one piece: strays (1 %) must not set it.
JOINED_FRACTION = 0.99
#: Arcs either side whose readings a dense arc's own estimate pools: triples its readings.
OWN_ARCS = 1
#: A loop's own depths are read where its median arc's outermost readings lie within this share
#: of the cap: the region families' dense teachings 0.15-0.21 deg at 0.75, their sparse ones and
#: `limbctl eval`'s 2000-sample shoulder 0.53-0.63 (docs/decisions/region.md, "dense edge").
OWN_SPREAD = 1.0 / 3.0
#: Depth (deg) of the bands at and below a pool's outermost reading the area test counts: half
#: the i.i.d. teachings' 1 deg edge band, so both bands lie within it.
BAND_DEG = 0.5
#: Least share the band below holds of the band at the outermost in an area's samples: the dense
#: teachings' median arc 0.72, a hand's traced strokes (samples on a line) 0-0.17.
BELOW_SHARE = 0.4


def thin(d: np.ndarray, spacing: float) -> np.ndarray:
    """Indices of directions ``d`` (N, 3) kept at least ``spacing`` (rad) apart: greedy
    Poisson-disk thinning, outermost first, every direction within ``spacing`` of a kept one."""
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


def learn_alpha(d: np.ndarray, factor: float, quantile: float = 0.9) -> float:
    """The alpha-shape radius (rad) from the gaps inside ``d`` (V, 3): ``factor * quantile`` of the
    circumradii inside the piece joining ``JOINED_FRACTION`` of the points, at least the radius
    joining it."""
    tri = spherical_delaunay(d)
    radius = circumradius(d, tri)
    order = np.argsort(radius)
    n = d.shape[0]
    pieces = UnionFind(n)
    alpha0 = float(radius[order[-1]])
    target = int(np.ceil(JOINED_FRACTION * n))
    for t in order:
        a = pieces.root(tri[t, 0])
        for v in tri[t, 1:]:
            a = pieces.union(a, v)
        if pieces.size[a] >= target:
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


def trace_loops(d: np.ndarray, edges: np.ndarray) -> list[np.ndarray]:
    """Chain directed boundary edges (E, 2) into closed loops of vertex indices (turning most to
    the left where pieces touch at a vertex)."""
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
    d: np.ndarray, alpha: float, max_hole: float, mouth: float = 0.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Delaunay triangles (T, 3) of ``d``, their circumradii (T,) and which are in the region.

    A triangle is in the region when its circumradius is at most ``alpha``, or it belongs to a
    hole: a piece of the other triangles (joined across edges longer than ``mouth``) that does not
    reach the outside across a hull edge longer than ``mouth`` and has an area below ``max_hole``.

    ``d`` (V, 3): unit directions; ``alpha`` (rad): circumradius up to which a triangle is in the
    region; ``max_hole`` (sr): holes with a total area below this are filled; ``mouth`` (rad):
    gaps up to this wide close a piece; 0 (default): every gap lets it through. Returns the
    triangles (T, 3) int, their circumradii (T,) rad and which are in the region (T,) bool.
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
    # pieces of non-region triangles joined across shared edges wider than the mouth
    wide = edge_lengths(d, key[order][shared][0::2]) > mouth
    pieces = UnionFind(t)
    for a, b, w in zip(first, second, wide, strict=True):
        if w and not kept[a] and not kept[b]:
            pieces.union(a, b)
    label = pieces.labels()
    outside = np.zeros(t, dtype=bool)
    # hull edges (one triangle each) wide enough to let the outside in
    open_ = edge_lengths(d, key[order][~shared]) > mouth
    outside[label[owner[order][~shared][open_]]] = True
    area = np.bincount(label, weights=triangle_area(d, tri) * ~kept, minlength=t)
    hole = ~kept & ~outside[label] & (area[label] < max_hole)
    return tri, radius, kept | hole


def edge_lengths(d: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """Angle (rad) between the directions of each index pair (K, 2) over ``d`` (V, 3)."""
    a, b = d[pairs[:, 0]], d[pairs[:, 1]]
    # atan2(|a x b|, a . b)
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.sum(a * b, axis=1))


def surrounded(p: np.ndarray, data: np.ndarray, radius: float, max_gap: float) -> np.ndarray:
    """(N,) bool: whether at least three ``data`` (K, 3) within ``radius`` (rad) of each ``p``
    (N, 3) leave no empty sector of bearings wider than ``max_gap`` (rad)."""
    counts, widest = bearing_gaps(p, data, cKDTree(data).query_ball_point(p, chord(radius)))
    return (counts >= 3) & (widest < max_gap)


def bearing_gaps(p: np.ndarray, data: np.ndarray, near: list) -> tuple[np.ndarray, np.ndarray]:
    """Counts (N,) of the rows ``near`` (N lists) of ``data`` (K, 3) about each ``p`` (N, 3), and
    their widest empty sector (N,) rad of bearings seen from it."""
    counts = np.array([len(rows) for rows in near], dtype=np.int64)
    start = np.concatenate([[0], np.cumsum(counts)])
    flat = np.fromiter((j for rows in near for j in rows), dtype=np.int64, count=int(start[-1]))
    widest = shape_kernels.widest_bearing_gaps(
        np.ascontiguousarray(p, dtype=np.float64), np.ascontiguousarray(data), start, flat
    )
    return counts, widest


def peel(
    d: np.ndarray, tri: np.ndarray, kept: np.ndarray, max_length: float, protected: np.ndarray
) -> np.ndarray:
    """Chi-shape peel: the kept mask (T,) of ``tri`` (T, 3) after peeling ``kept`` (T,), longest
    exposed edge (> ``max_length``, rad) first, sparing ``protected`` (T,) and pinches."""
    kept = kept.copy()
    key = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    owners: dict[tuple[int, int], list[int]] = {}
    for (a, b), t in zip(key.tolist(), np.tile(np.arange(tri.shape[0]), 3).tolist(), strict=True):
        owners.setdefault((a, b), []).append(t)

    def exposed(a: int, b: int) -> bool:
        return sum(bool(kept[t]) for t in owners[(min(a, b), max(a, b))]) == 1

    def length(a: int, b: int) -> float:
        return float(edge_lengths(d, np.array([[a, b]]))[0])

    on_boundary = np.zeros(d.shape[0], dtype=np.int64)
    heap: list[tuple[float, int, int, int]] = []
    for t in np.flatnonzero(kept):
        a, b, c = (int(x) for x in tri[t])
        for x, y in ((a, b), (b, c), (c, a)):
            if exposed(x, y):
                on_boundary[x] += 1
                on_boundary[y] += 1
                if length(x, y) > max_length:
                    heapq.heappush(heap, (-length(x, y), x, y, int(t)))
    while heap:
        _, a, b, t = heapq.heappop(heap)
        if not kept[t] or not exposed(a, b) or protected[t]:
            continue
        c = next(int(x) for x in tri[t] if x != a and x != b)
        if on_boundary[c] > 0:
            continue
        kept[t] = False
        # (a, b) leaves the boundary, (a, c) and (c, b) join it: only c gains boundary edges
        on_boundary[c] += 2
        for x, y in ((a, c), (c, b)):
            if length(x, y) > max_length:
                inner = next(s for s in owners[(min(x, y), max(x, y))] if kept[s])
                heapq.heappush(heap, (-length(x, y), x, y, inner))
    return kept


def edge_margins(
    loops: list[np.ndarray],
    data: np.ndarray,
    window: float,
    top: int,
    max_margin: float | list[np.ndarray],
    max_bridge: float = np.inf,
    traced_arc: float = 0.0,
    corner_turn: float = np.pi,
) -> tuple[list[np.ndarray], bool]:
    """How far (rad) to widen each arc of the loops so the region reaches the true edge. Each
    direction of ``data`` (N, 3) belongs to its nearest arc. An arc's margin is the endpoint
    estimate (:func:`limbctl.region.gaps.line_gap`) of the ``top`` outermost depths beyond its great
    circle of the data of the arcs within ``window`` (rad) along the loop, or, if less, on a loop
    whose samples resolve its edge as an area's (:func:`area_resolved`), of the own depths past the
    loop of its and ``OWN_ARCS`` arcs' data either side where they lie within the cap; at least
    the depth of every sample outside it, at most ``max_margin`` (or per loop (M,) caps).
    An arc longer than ``max_bridge`` only covers the samples beyond it; an arc cutting a traced
    concave corner is held by :func:`corner_limits`. Per loop (M,), ``i`` for arc ``i -> i + 1``;
    and whether any loop's own depths were read."""
    vertices, edges = loops_to_edges(loops)
    nearest, angle = shape_kernels.nearest_arcs(data, vertices, edges)
    outside = ~inside_reference(data, vertices, edges)
    signed = np.where(outside, angle, -angle)
    need = np.zeros(edges.shape[0])
    np.maximum.at(need, nearest[outside], angle[outside])
    out, read, start = [], False, 0
    for number, lp in enumerate(loops):
        m = lp.shape[0]
        cap = max_margin if np.isscalar(max_margin) else max_margin[number]
        pole = -np.cross(lp, np.roll(lp, -1, axis=0))
        pole /= np.linalg.norm(pole, axis=1, keepdims=True)
        seg = edge_lengths(lp, np.column_stack([np.arange(m), (np.arange(m) + 1) % m]))
        # arc-length position of each arc's middle along the loop
        middle = np.cumsum(seg) - 0.5 * seg
        total = float(seg.sum())
        # the data of each arc of this loop
        buckets = StationBuckets(nearest - start, m)
        est = np.zeros(m)
        around = np.arange(-OWN_ARCS, OWN_ARCS + 1)
        owns = [-np.sort(-signed[buckets.rows((e + around) % m)]) for e in range(m)]
        dense = area_resolved(owns, top, cap)
        read |= dense
        for e in np.flatnonzero(seg <= max_bridge):
            # circular distance along the loop between arc middles
            apart = np.abs(middle - middle[e])
            near = np.flatnonzero(np.minimum(apart, total - apart) <= window)
            rows = buckets.rows(near)
            if rows.size == 0:
                continue
            # o = asin(x . n): signed angle beyond the arc's great circle
            vals = -np.sort(-np.arcsin(np.clip(data[rows] @ pole[e], -1.0, 1.0)))[:top]
            est[e] = vals[0] + line_gap(vals)
            # dense (within the cap): own depths, free of this arc's tilt and the loop's turns
            own = owns[e]
            if dense and own.size >= top and own[0] - own[top - 1] <= cap:
                est[e] = min(est[e], own[0] + line_gap(own[:top]))
        margin = np.clip(np.maximum(est, need[start : start + m]), 0.0, cap)
        limit = corner_limits(lp, margin, seg, max_bridge, traced_arc, corner_turn)
        out.append(np.maximum(np.minimum(margin, limit), need[start : start + m]))
        start += m
    return out, read


def area_resolved(owns: list[np.ndarray], top: int, cap: float) -> bool:
    """Whether a loop's samples resolve its edge as an area's do, judged at its median arc of
    those with ``top`` own depths (``owns``, per arc, outermost first, rad): the ``top`` outermost
    within ``OWN_SPREAD`` of ``cap`` (rad) of each other (dense), and the ``BAND_DEG`` band below
    the outermost's band holding at least ``BELOW_SHARE`` as many (an area, not a traced stroke:
    :func:`limbctl.region.gaps.line_gap` reads order statistics of an area's density)."""
    full = [o for o in owns if o.size >= top]
    if not full:
        return False
    band = np.radians(BAND_DEG)
    spread = np.median([o[0] - o[top - 1] for o in full])
    below = [
        np.sum((o < o[0] - band) & (o >= o[0] - 2 * band)) / np.sum(o >= o[0] - band) for o in full
    ]
    return bool(spread <= OWN_SPREAD * cap and np.median(below) >= BELOW_SHARE)


def corner_limits(
    loop: np.ndarray,
    margin: np.ndarray,
    seg: np.ndarray,
    max_bridge: float,
    traced_arc: float,
    corner_turn: float,
) -> np.ndarray:
    """Largest margin (M,) rad each arc of a loop (M, 3) may take at a traced concave corner. A
    corner arc turns concavely at both ends by at least ``corner_turn`` (rad) together, a neighbour
    is traced (at most ``traced_arc`` long) and none of the three is longer than ``max_bridge``; it
    may widen only to where its neighbours, widened by ``margin`` (M,), meet. Other arcs: ``inf``.
    ``seg`` (M,) are the arcs' lengths (rad)."""
    m = loop.shape[0]
    limit = np.full(m, np.inf)
    turn = vertex_turns(loop)
    e = np.arange(m)
    p, q = (e - 1) % m, (e + 1) % m
    corner = (
        (turn < 0.0)
        & (turn[q] < 0.0)
        & (-(turn + turn[q]) >= corner_turn)
        & (np.minimum(seg[p], seg[q]) <= traced_arc)
        & (np.maximum(np.maximum(seg[p], seg[q]), seg) <= max_bridge)
    )
    e, p, q = e[corner], p[corner], q[corner]
    if e.size == 0:
        return limit
    nxt = np.roll(loop, -1, axis=0)
    pole = -np.cross(loop, nxt)
    pole /= np.linalg.norm(pole, axis=1, keepdims=True)
    n1, n2 = pole[p], pole[q]
    s1, s2 = np.sin(margin[p]), np.sin(margin[q])
    # x = a n1 + b n2 + g (n1 x n2) with n1 . x = s1, n2 . x = s2, |x| = 1 (c = n1 . n2)
    c = np.einsum("ij,ij->i", n1, n2)
    det = np.maximum(1.0 - c * c, 1e-12)
    base = ((s1 - c * s2) / det)[:, None] * n1 + ((s2 - c * s1) / det)[:, None] * n2
    k = np.cross(n1, n2)
    g = np.sqrt(np.maximum(1.0 - np.einsum("ij,ij->i", base, base), 0.0) / det)
    middle = loop[e] + nxt[e]
    # of the two meeting points, the one on the arc's side of the sphere
    sign = np.where(np.einsum("ij,ij->i", k, middle) >= 0.0, 1.0, -1.0)
    x = base + (sign * g)[:, None] * k
    limit[e] = np.maximum(np.arcsin(np.clip(np.einsum("ij,ij->i", x, pole[e]), -1.0, 1.0)), 0.0)
    return limit


def carve(d: np.ndarray, tri: np.ndarray, kept: np.ndarray, points: np.ndarray) -> np.ndarray:
    """A copy of ``kept`` (T,) without, for each of ``points`` (P, 3), the triangle of ``tri``
    (T, 3) over ``d`` (V, 3) whose exposed edge lies nearest (no pinching)."""
    kept = kept.copy()
    rows = np.flatnonzero(kept)
    directed = np.concatenate([tri[rows][:, [0, 1]], tri[rows][:, [1, 2]], tri[rows][:, [2, 0]]])
    owner = np.tile(rows, 3)
    key = np.sort(directed, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    exposed = counts[inverse.ravel()] == 1
    edges, owner = directed[exposed], owner[exposed]
    a, b = d[edges[:, 0]], d[edges[:, 1]]
    on_boundary = np.zeros(d.shape[0], dtype=bool)
    on_boundary[edges.ravel()] = True
    # distance to each exposed arc: to its great circle where the foot falls inside, else an end
    pole = np.cross(a, b)
    pole /= np.maximum(np.linalg.norm(pole, axis=1, keepdims=True), 1e-15)
    for p in np.atleast_2d(points):
        foot = p - (pole @ p)[:, None] * pole
        between = (np.einsum("ij,ij->i", np.cross(a, foot), pole) >= 0) & (
            np.einsum("ij,ij->i", np.cross(foot, b), pole) >= 0
        )
        dist = np.where(between, np.abs(pole @ p), 2.0 - np.maximum(a @ p, b @ p))
        e = int(np.argmin(dist))
        t = int(owner[e])
        third = next(int(x) for x in tri[t] if x != edges[e, 0] and x != edges[e, 1])
        if kept[t] and not on_boundary[third]:
            kept[t] = False
    return kept
