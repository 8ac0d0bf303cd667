"""Numba kernels that learn the twist band (:mod:`limbctl.region.twist_band`) from samples: per
node the upper hull's height, a plane through the stops, the evidence caps. Numpy twins live in
``tests/region/test_twist_fit_kernels.py``. No fastmath.
"""

from __future__ import annotations

import math

import numpy as np

from limbctl.geometry.jit import njit
from limbctl.region.linalg_kernels import det, solve
from limbctl.region.sort_kernels import sort_values
from limbctl.region.twist_kernels import wrap


@njit
def upper_hull(px, py, t, top) -> float:
    """Height at the origin of the upper concave hull of points ``(px, py, t)`` (K,), over the
    ``top`` highest ``t``; NaN when no triangle holds the origin. Exact for points on a plane.
    """
    order = np.argsort(-t)[: min(top, t.shape[0])]
    best = -np.inf
    m = order.shape[0]
    for a in range(m):
        ia = order[a]
        for b in range(a + 1, m):
            ib = order[b]
            for c in range(b + 1, m):
                ic = order[c]
                # l_a = cross(p_b, p_c) / A, l_b = cross(p_c, p_a) / A, l_c = cross(p_a, p_b) / A
                cab = px[ia] * py[ib] - py[ia] * px[ib]
                cbc = px[ib] * py[ic] - py[ib] * px[ic]
                cca = px[ic] * py[ia] - py[ic] * px[ia]
                area = cab + cbc + cca
                if area == 0.0:
                    continue
                la, lb, lc = cbc / area, cca / area, cab / area
                if la >= 0.0 and lb >= 0.0 and lc >= 0.0:
                    v = la * t[ia] + lb * t[ib] + lc * t[ic]
                    if v > best:
                        best = v
    return best if best > -np.inf else np.nan


@njit
def fit_nodes(nodes, start, members, d, tau, top, free_gap, slope):
    """Band centre and half-width (rad) at each node direction (M, 3) from the samples near it.

    ``members[start[i]:start[i + 1]]`` are the rows of ``d`` (N, 3), ``tau`` (N,) near node ``i``,
    unwrapped about the middle of their arc (free, half-width pi, when no gap reaches
    ``free_gap``). Each limit is the upper hull's height, at least ``max_i (t_i - slope |x_i|)``;
    NaN under 3 samples.
    """
    m = nodes.shape[0]
    centre = np.full(m, np.nan)
    half = np.full(m, np.nan)
    for i in range(m):
        idx = members[start[i] : start[i + 1]]
        k = idx.shape[0]
        if k < 3:
            continue
        ts = np.empty(k)
        for a in range(k):
            ts[a] = wrap(tau[idx[a]])
        sort_values(ts)
        gap = ts[0] + 2.0 * math.pi - ts[k - 1]
        gap_start = ts[k - 1]
        for a in range(k - 1):
            if ts[a + 1] - ts[a] > gap:
                gap = ts[a + 1] - ts[a]
                gap_start = ts[a]
        if gap < free_gap:
            centre[i] = 0.0
            half[i] = math.pi
            continue
        # the occupied arc runs from gap_start + gap over 2 pi - gap: its middle
        ref = gap_start + gap + 0.5 * (2.0 * math.pi - gap)
        node = nodes[i]
        e1, e2 = _node_frame(node)
        px = np.empty(k)
        py = np.empty(k)
        t = np.empty(k)
        for a in range(k):
            j = idx[a]
            px[a] = d[j, 0] * e1[0] + d[j, 1] * e1[1] + d[j, 2] * e1[2]
            py[a] = d[j, 0] * e2[0] + d[j, 1] * e2[1] + d[j, 2] * e2[2]
            t[a] = wrap(tau[j] - ref)
        up = upper_hull(px, py, t, top)
        lo = -upper_hull(px, py, -t, top)
        for a in range(k):
            # one sample bounds a limit of slope <= slope: u(node) >= t_a - slope |x_a|
            r = slope * math.sqrt(px[a] * px[a] + py[a] * py[a])
            if not up >= t[a] - r:
                up = t[a] - r
            if not lo <= t[a] + r:
                lo = t[a] + r
        if not up >= lo:
            continue
        centre[i] = ref + 0.5 * (up + lo)
        half[i] = 0.5 * (up - lo)
    return centre, half


@njit
def refine_nodes(nodes, start, members, d, limit, stop, ref, sigma, max_slope):
    """Band limits at nodes (M,), relative to ``ref`` (M,), from a weighted plane through the stops.

    ``limit`` (N,) are the unwrapped twists, ``stop`` (N,) bool the samples at the stop; weights
    ``exp(-angle^2 / (2 sigma^2))``. NaN where fewer than 3 stops, they lie on a line, or the
    plane slopes more than ``max_slope`` (rad/rad).
    """
    m = nodes.shape[0]
    out = np.full(m, np.nan)
    for i in range(m):
        node = nodes[i]
        e1, e2 = _node_frame(node)
        a = np.zeros((3, 3))
        b = np.zeros(3)
        count = 0
        for k in range(start[i], start[i + 1]):
            j = members[k]
            if not stop[j]:
                continue
            x = d[j, 0] * e1[0] + d[j, 1] * e1[1] + d[j, 2] * e1[2]
            y = d[j, 0] * e2[0] + d[j, 1] * e2[1] + d[j, 2] * e2[2]
            c = d[j, 0] * node[0] + d[j, 1] * node[1] + d[j, 2] * node[2]
            ang2 = 2.0 * (1.0 - c)
            w = math.exp(-ang2 / (2.0 * sigma * sigma))
            # the sample's limit relative to the node's centre
            t = limit[j] - ref[i]
            row = (1.0, x, y)
            for r in range(3):
                b[r] += w * row[r] * t
                for s in range(3):
                    a[r, s] += w * row[r] * row[s]
            count += 1
        if count < 3:
            continue
        # well conditioned: the stops spread in both directions around the node
        if det(a) <= 1e-12 * a[0, 0] ** 3:
            continue
        sol = solve(a, b)
        if math.hypot(sol[1], sol[2]) <= max_slope:
            out[i] = sol[0]
    return out


@njit
def evidence_caps(nodes, start, members, d, limit, ref, slope, near, band):
    """The widest band limits (M,), (M,) the taught twists near each node support, relative
    to ``ref`` (M,) (rad), and how many samples witness each (M,), (M,).

    ``up(n) = max_j (limit_j - ref_n - slope angle(n, d_j))``, ``lo`` likewise with ``min`` and
    ``+``, over ``members[start[n]:start[n + 1]]``; witnesses lie within ``near`` (rad) of the node
    and ``band`` (rad) of the cap. NaN caps where a node has no samples.
    """
    m = nodes.shape[0]
    up = np.full(m, np.nan)
    lo = np.full(m, np.nan)
    n_up = np.zeros(m, dtype=np.int64)
    n_lo = np.zeros(m, dtype=np.int64)
    for i in range(m):
        if start[i + 1] == start[i]:
            continue
        best_up = -np.inf
        best_lo = np.inf
        for k in range(start[i], start[i + 1]):
            j = members[k]
            angle = _angle(nodes[i], d[j])
            t = limit[j] - ref[i]
            if t - slope * angle > best_up:
                best_up = t - slope * angle
            if t + slope * angle < best_lo:
                best_lo = t + slope * angle
        up[i] = best_up
        lo[i] = best_lo
        for k in range(start[i], start[i + 1]):
            j = members[k]
            if _angle(nodes[i], d[j]) <= near:
                t = limit[j] - ref[i]
                if t >= best_up - band:
                    n_up[i] += 1
                if t <= best_lo + band:
                    n_lo[i] += 1
    return up, lo, n_up, n_lo


@njit(inline="always")
def _node_frame(node):
    """Tangent frame (3,), (3,) at unit ``node`` (3,): helper +z, or +y near the z axis."""
    if abs(node[2]) < 0.9:
        e1 = np.array([-node[1], node[0], 0.0])
    else:
        e1 = np.array([node[2], 0.0, -node[0]])
    e1 /= math.sqrt(e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2])
    e2 = np.array(
        [
            node[1] * e1[2] - node[2] * e1[1],
            node[2] * e1[0] - node[0] * e1[2],
            node[0] * e1[1] - node[1] * e1[0],
        ]
    )
    return e1, e2


@njit
def _angle(a, b) -> float:
    """Angle (rad) between unit vectors (3,): ``2 asin(|a - b| / 2)``."""
    dx = b[0] - a[0]
    dy = b[1] - a[1]
    dz = b[2] - a[2]
    return 2.0 * math.asin(min(1.0, 0.5 * math.sqrt(dx * dx + dy * dy + dz * dz)))


@njit(error_model="numpy")  # as its former prange body: a zero weight sum gives NaN, not an error
def gradient_caps(
    nodes,
    start,
    members,
    d,
    limit,
    stop,
    ref,
    sigma,
    spread,
    slack,
    confidence,
    curvature,
    near,
    band,
    reach,
    steep,
    limited,
    min_stops,
    ends,
):
    """One limit's cap (M,) read along its local slope, relative to ``ref`` (M,) (rad), and its
    witnesses (M,); the upper limit (for the lower pass the twists negated and negate the cap).

    The slope ``g`` is the weighted plane's through the stops (as :func:`refine_nodes`), read
    at every node (:func:`_node_slope`). A sample ``j`` at ``v`` from node ``n`` lies above the
    limit there by at most ``max(g_n . v + m_n r, g_e . v + m_e r)``, ``e = ends[j]`` the node
    nearest the sample (the slope along the path at its two ends, each with its margin ``m``,
    bounds the rise wherever the truth bends one way between them); where the end's slope is
    not read, the node's alone. So
    ``cap(n) = max_j (limit_j - ref_n - that rise - curvature r^2 / 2)``. NaN where the stops'
    effective count ``(sum w)^2 / sum w^2`` is under ``min_stops`` or they spread less than
    ``spread`` (rad) in some direction. At ``limited`` (M,) nodes a sample beyond ``reach``
    (rad) bounds the cap by the ``steep`` (rad/rad) cone too.
    """
    m = nodes.shape[0]
    cap = np.full(m, np.nan)
    wit = np.zeros(m, dtype=np.int64)
    # the slope (a tangent vector) and its margin at every node, NaN where not read
    gx = np.full(m, np.nan)
    gy = np.full(m, np.nan)
    gz = np.full(m, np.nan)
    margin = np.full(m, np.nan)
    for i in range(m):
        gx[i], gy[i], gz[i], margin[i] = _node_slope(
            nodes[i],
            start[i],
            start[i + 1],
            members,
            d,
            limit,
            stop,
            ref[i],
            sigma,
            spread,
            slack,
            confidence,
            min_stops,
        )
    for i in range(m):
        if not math.isfinite(margin[i]):
            continue
        node = nodes[i]
        best = -np.inf
        for k in range(start[i], start[i + 1]):
            j = members[k]
            angle = _angle(node, d[j])
            # the path's tangent at the node (the sample less its part along the node)
            along = d[j, 0] * node[0] + d[j, 1] * node[1] + d[j, 2] * node[2]
            vx = d[j, 0] - along * node[0]
            vy = d[j, 1] - along * node[1]
            vz = d[j, 2] - along * node[2]
            rise = gx[i] * vx + gy[i] * vy + gz[i] * vz + margin[i] * angle
            e = ends[j]
            if e >= 0 and math.isfinite(margin[e]):
                far = gx[e] * vx + gy[e] * vy + gz[e] * vz + margin[e] * angle
                if far > rise:
                    rise = far
            t = limit[j] - ref[i] - rise - 0.5 * curvature * angle * angle
            if limited[i] and angle > reach:
                # beyond the reach the steep cone bounds too: it holds if either assumption does
                cone = limit[j] - ref[i] - steep * angle
                if cone < t:
                    t = cone
            if t > best:
                best = t
        cap[i] = best
        for k in range(start[i], start[i + 1]):
            j = members[k]
            if _angle(node, d[j]) <= near and limit[j] - ref[i] >= best - band:
                wit[i] += 1
    return cap, wit


@njit(inline="always", error_model="numpy")
def _node_slope(
    node, first, last, members, d, limit, stop, ref, sigma, spread, slack, confidence, min_stops
):
    """The weighted plane's slope through the stops among ``members[first:last]`` at ``node``
    (3,) (the tangent vector's three components, rad/rad) and its margin ``slack + confidence
    se`` (``se`` the slope's standard error); NaN where too few stops, or too little spread,
    read it."""
    e1, e2 = _node_frame(node)
    a = np.zeros((3, 3))
    b = np.zeros(3)
    count = 0
    weight_sq = 0.0
    for k in range(first, last):
        j = members[k]
        if not stop[j]:
            continue
        x = d[j, 0] * e1[0] + d[j, 1] * e1[1] + d[j, 2] * e1[2]
        y = d[j, 0] * e2[0] + d[j, 1] * e2[1] + d[j, 2] * e2[2]
        angle = _angle(node, d[j])
        w = math.exp(-angle * angle / (2.0 * sigma * sigma))
        t = limit[j] - ref
        row = (1.0, x, y)
        for r in range(3):
            b[r] += w * row[r] * t
            for s in range(3):
                a[r, s] += w * row[r] * row[s]
        count += 1
        weight_sq += w * w
    # the stops' effective count (sum w)^2 / sum w^2 (through 3 the plane's error reads 0)
    if count < 3 or a[0, 0] * a[0, 0] < min_stops * weight_sq:
        return np.nan, np.nan, np.nan, np.nan
    # the stops' weighted spread about their mean, least direction (2 x 2 covariance)
    mx = a[0, 1] / a[0, 0]
    my = a[0, 2] / a[0, 0]
    cxx = a[1, 1] / a[0, 0] - mx * mx
    cyy = a[2, 2] / a[0, 0] - my * my
    cxy = a[1, 2] / a[0, 0] - mx * my
    least = 0.5 * (cxx + cyy) - math.sqrt(0.25 * (cxx - cyy) ** 2 + cxy * cxy)
    if least < spread * spread:
        return np.nan, np.nan, np.nan, np.nan
    sol = solve(a, b)
    # the slope's standard error: weighted scatter / sqrt(effective count) / least spread
    rss = 0.0
    w2 = 0.0
    for k in range(first, last):
        j = members[k]
        if not stop[j]:
            continue
        x = d[j, 0] * e1[0] + d[j, 1] * e1[1] + d[j, 2] * e1[2]
        y = d[j, 0] * e2[0] + d[j, 1] * e2[1] + d[j, 2] * e2[2]
        angle = _angle(node, d[j])
        w = math.exp(-angle * angle / (2.0 * sigma * sigma))
        e = limit[j] - ref - sol[0] - sol[1] * x - sol[2] * y
        rss += w * e * e
        w2 += w * w
    n_eff = a[0, 0] * a[0, 0] / w2
    slope_err = math.sqrt(rss / a[0, 0] / max(n_eff - 3.0, 1.0)) / math.sqrt(least)
    return (
        sol[1] * e1[0] + sol[2] * e2[0],
        sol[1] * e1[1] + sol[2] * e2[1],
        sol[1] * e1[2] + sol[2] * e2[2],
        slack + confidence * slope_err,
    )
