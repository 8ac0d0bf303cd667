"""The traced edge: a curve walked out to where the taught samples put the edge, station by station
(docs/region.md, "Edge strategies"; rad), held within ``HOLD_DEG`` of a sample (:func:`held_in`)."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from limbctl.region.gaps import ORDER_STATISTICS, majorant_gap, spacing_gap
from limbctl.region.loops import (
    StationBuckets,
    chord,
    lift,
    loop_area,
    loop_length,
    nearest_station,
    resample_loop,
    signed_offset,
    smooth_along,
    station_positions,
)
from limbctl.region.trace_kernels import station_moves

#: Station spacing (deg): half the smooth edge's, to follow an egg's tip.
TRACE_STEP_DEG = 1.5
#: Rounds of read, estimate, move, smooth: enough to settle a few degrees from the start.
TRACE_ITERATIONS = 10
#: Smoothing width (deg, Gaussian sigma): a 10 deg circle shrinks only 0.14 deg a round.
TRACE_SMOOTH_DEG = 6.0
#: Most (deg) one round's smoothing moves a station out: more would bridge narrow bays.
TRACE_SMOOTH_CAP_DEG = 0.25
#: Spacing (deg) of a window's outermost samples: its noise, under the 0.5 deg target.
TRACE_SPACING_DEG = 0.2
#: Smallest half window (deg) along the curve: two stations either side, however dense.
TRACE_MIN_WINDOW_DEG = 3.0
#: Largest half window (deg): wider ones average corners and dents away; refused.
TRACE_MAX_WINDOW_DEG = 10.0
#: Depth (deg) inside the loop where the edge's sample density is counted.
DENSITY_BAND_DEG = 3.0
#: Samples this far (deg) beyond the curve still count: the loop's own, up to rounding.
BAND_BEYOND_DEG = 0.05
#: After the lift taught directions lie this far (deg) inside: far below a tick (0.088).
LIFT_MARGIN_DEG = 0.01
#: Farthest (deg) a held station lies from every sample: a quarter of the 1 deg bound for chords.
HOLD_DEG = 0.75
#: Held stations' spacing (deg): a chord cuts a quarter of it past a right-angled corner.
HELD_STEP_DEG = 0.5
#: Resample-and-hold passes: dense teachings' chords left 0.55-0.73 deg long after 3.
HOLD_PASSES = 3
#: Farthest (deg) a station walks in: one round's move (3 deg).
WALK_DEG = 3.0
#: Step (deg) of a station's walk: it ends at most this much deeper than the bound asks.
WALK_STEP_DEG = 0.05
#: Farthest (deg) a held curve may lie from every sample: the 1 deg bound of docs/region.md.
HELD_REACH_DEG = 1.0
#: Spacing (deg) of the points :func:`evidence_reach` checks: small beside the bound.
REACH_STEP_DEG = 0.1
#: Stations a fold may span: moves of up to 3 deg from a bay's two walls fold about 6 deg.
FOLD_WINDOW = 20
#: Outermost readings a window's majorant is built from: its pair search stays 40 x 40.
TOP_READINGS = 40


def station_normals(curve: np.ndarray) -> np.ndarray:
    """Outward unit normals (K, 3) of a closed counter-clockwise curve (K, 3): the pole of the
    chord through each station's neighbours, projected onto the tangent plane."""
    pole = -np.cross(np.roll(curve, 1, axis=0), np.roll(curve, -1, axis=0))
    t = pole - np.einsum("ij,ij->i", pole, curve)[:, None] * curve
    return t / np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-15)


def readings(curve: np.ndarray, data: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Owner station (N,) and depth (N,) rad beyond the curve of each taught direction (N, 3)."""
    owner = nearest_station(data, curve)
    normal = station_normals(curve)
    depth = np.arcsin(np.clip(np.einsum("ij,ij->i", data, normal[owner]), -1.0, 1.0))
    return owner, depth


def trace_window(curve: np.ndarray, data: np.ndarray) -> float:
    """Half window ``h`` (rad) putting a ``2 h`` window's outermost samples ``TRACE_SPACING_DEG``
    apart (``1 / (rho 2h)``, ``rho`` the density near the curve); inf with no sample near."""
    _, depth = readings(curve, data)
    band = np.radians(DENSITY_BAND_DEG)
    count = int(np.sum((depth > -band) & (depth <= np.radians(BAND_BEYOND_DEG))))
    if count == 0:
        return float(np.inf)
    rho = count / (loop_length(curve) * band)
    return float(
        max(1.0 / (2.0 * rho * np.radians(TRACE_SPACING_DEG)), np.radians(TRACE_MIN_WINDOW_DEG))
    )


def edge_estimate(u: np.ndarray, o: np.ndarray) -> float:
    """Where the edge lies (rad, relative to the curve) at a station, from nearby readings. ``u``
    (M,) are the readings' positions along the curve relative to the station, ``o`` (M,) their
    depths. The upper concave majorant at ``u = 0`` plus :func:`limbctl.region.gaps.majorant_gap`;
    with readings on one side only (or fewer than ``ORDER_STATISTICS``), the outermost depth plus
    :func:`limbctl.region.gaps.spacing_gap`."""
    top = np.argsort(-o, kind="stable")[:TOP_READINGS]
    u, o = u[top], o[top]
    left = u < 0.0
    if o.size < ORDER_STATISTICS or not left.any() or left.all():
        o = np.sort(o)[::-1][:ORDER_STATISTICS]
        return float(o[0] + spacing_gap(o))
    ul, ol, ur, orr = u[left], o[left], u[~left], o[~left]
    # the chord from (u_i, o_i) to (u_j, o_j) at u = 0, for every left-right pair
    frac = -ul[:, None] / (ur[None, :] - ul[:, None])
    chord = ol[:, None] + (orr[None, :] - ol[:, None]) * frac
    i, j = np.unravel_index(np.argmax(chord), chord.shape)
    at_station = chord[i, j]
    slope = (orr[j] - ol[i]) / (ur[j] - ul[i])
    resid = np.sort(at_station + slope * u - o)[:ORDER_STATISTICS]
    return float(at_station + majorant_gap(resid))


def station_estimates(
    s: np.ndarray, total: float, owner: np.ndarray, depth: np.ndarray, reach: int
) -> np.ndarray:
    """:func:`edge_estimate` (K,) rad per station at ``s`` (K,) along a curve ``total`` long, from
    readings ``owner``, ``depth`` (N,) within ``reach`` stations either side."""
    buckets = StationBuckets(owner, s.shape[0])
    return station_moves(s, total, owner, depth, buckets.order, buckets.bounds, reach, TOP_READINGS)


def over_hole(owner: np.ndarray, depth: np.ndarray, stations: int, limit: float) -> np.ndarray:
    """Which stations (K,) bool own readings but none within ``limit`` rad of the curve."""
    outermost = np.full(stations, -np.inf)
    np.maximum.at(outermost, owner, depth)
    return np.isfinite(outermost) & (outermost < -limit)


def bridged_estimates(
    s: np.ndarray, total: float, owner: np.ndarray, depth: np.ndarray, reach: int, h: float
) -> np.ndarray:
    """The :func:`station_estimates` (K,) rad without the readings over a hole, interpolated along
    the curve where a window is left empty."""
    k = s.shape[0]
    hole = over_hole(owner, depth, k, h)
    if not hole.any():
        return station_estimates(s, total, owner, depth, reach)
    kept = ~hole[owner]
    estimate = station_estimates(s, total, owner[kept], depth[kept], reach)
    counts = np.bincount(owner[kept], minlength=k)
    # readings in the window i - reach .. i + reach (circular)
    window = sum(np.roll(counts, shift) for shift in range(-reach, reach + 1))
    read = np.flatnonzero(window > 0)
    if read.size == 0 or read.size == k:
        return estimate
    # linear along the curve, circularly: the read stations repeated one loop either side
    at = np.concatenate([s[read] - total, s[read], s[read] + total])
    value = np.tile(estimate[read], 3)
    empty = window == 0
    estimate[empty] = np.interp(s[empty], at, value)
    return estimate


def local_quadratic(curve: np.ndarray, sigma: float) -> np.ndarray:
    """Local quadratic regression (K, 3) of a closed curve's evenly spaced stations (K, 3). Each
    station is replaced by ``a`` of ``a + b v + c v^2`` fitted over arc-length offsets ``v`` in
    units of ``sigma`` (weights ``exp(-v^2 / 2)``), renormalised: exact on quadratic stretches; a
    circle of radius ``r`` shrinks by about ``sigma^4 / (8 r^3)``.

    Element by element, no BLAS or LAPACK call: a traced edge is the same on every CPU (a matrix
    product's rounding follows the CPU's BLAS kernel, and the trace's rounds amplified it into a
    different edge, docs/decisions/region.md); offsets in units of ``sigma`` keep the 3 x 3
    system well conditioned (in radians its entries spanned sigma^4, 1e-5 for 3 deg).
    """
    s, total = station_positions(curve)
    v = signed_offset(s[None, :], s[:, None], total) / sigma
    w = np.exp(-0.5 * v * v)
    # weighted powers w v^p (p = 0 .. 4): the normal equations (X^T W X) beta = X^T W c of
    # the basis (1, v, v^2) hold sums m_p of w v^p on the left and r_a of w v^a c on the right
    powers = [w]
    for _ in range(4):
        powers.append(powers[-1] * v)
    m0, m1, m2, m3, m4 = (p.sum(axis=1)[:, None] for p in powers)
    r0, r1, r2 = (
        np.stack([(powers[a] * curve[:, k]).sum(axis=1) for k in range(3)], axis=1)
        for a in range(3)
    )
    # a by Cramer's rule: det [r m1 m2; r1 m2 m3; r2 m3 m4] / det [m0 m1 m2; m1 m2 m3; m2 m3 m4]
    minor = m2 * m4 - m3 * m3
    det = m0 * minor - m1 * (m1 * m4 - m3 * m2) + m2 * (m1 * m3 - m2 * m2)
    out = (r0 * minor - m1 * (r1 * m4 - m3 * r2) + m2 * (r1 * m3 - m2 * r2)) / det
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def trace_edge(
    loop: np.ndarray, data: np.ndarray, max_offset: float, hold: bool = False
) -> np.ndarray | None:
    """The traced edge (K, 3) of a supported ``loop`` (M, 3) from taught ``data`` (N, 3), one
    round moving at most ``max_offset`` (rad); None when taught too sparsely."""
    step = np.radians(TRACE_STEP_DEG)
    curve, _, _ = resample_loop(loop, step)
    h = trace_window(curve, data)
    if h > np.radians(TRACE_MAX_WINDOW_DEG):
        return None
    cap = np.radians(TRACE_SMOOTH_CAP_DEG)
    # an outer loop's curve stays within reach of the evidence (a hole's bridges nothing)
    held = hold and loop_area(loop) > 0.0
    tree, bound = cKDTree(data), np.radians(HOLD_DEG)
    for _ in range(TRACE_ITERATIONS):
        k = curve.shape[0]
        s, total = station_positions(curve)
        owner, depth = readings(curve, data)
        reach = max(1, int(round(h * k / total)))
        estimate = bridged_estimates(s, total, owner, depth, reach, h)
        move = smooth_along(estimate, s, total, 0.5 * h)
        normal = station_normals(curve)
        curve = _moved(curve, normal, np.minimum(move, max_offset))
        # smoothing: outward by at most ``cap`` a round
        normal = station_normals(curve)
        smooth = local_quadratic(curve, np.radians(TRACE_SMOOTH_DEG))
        out = np.arcsin(np.clip(np.einsum("ij,ij->i", smooth, normal), -1.0, 1.0))
        far = out > cap
        smooth[far] = _moved(curve[far], normal[far], np.full(int(far.sum()), cap))
        curve, _, _ = resample_loop(smooth, step)
        if held:
            curve = held_in(curve, data, tree, bound)
    if held:
        # finer stations, each held: a chord cuts less past a corner (a hold may stretch one)
        step = np.radians(HELD_STEP_DEG)
        for _ in range(HOLD_PASSES):
            curve = held_in(resample_loop(curve, step)[0], data, tree, bound)
    # lift: no taught direction left beyond the chords next to the station it belongs to
    s, total = station_positions(curve)
    for _ in range(2):
        need = chord_need(curve, data) + np.radians(LIFT_MARGIN_DEG)
        curve = _moved(curve, station_normals(curve), lift(need, s, total, step))
    return curve


def chord_need(curve: np.ndarray, data: np.ndarray) -> np.ndarray:
    """How far (K,) rad each station must move out so the chords hold the taught directions (N, 3)
    (beyond either chord at a convex station, both at a reflex one); -inf where none needs it."""
    k = curve.shape[0]
    nxt = np.roll(curve, -1, axis=0)
    pole = -np.cross(curve, nxt)
    pole /= np.maximum(np.linalg.norm(pole, axis=1, keepdims=True), 1e-15)
    owner = nearest_station(data, curve)
    before = np.einsum("ij,ij->i", data, pole[(owner - 1) % k])
    after = np.einsum("ij,ij->i", data, pole[owner])
    # convex at k: the next station lies inside the previous chord's great circle
    convex = np.einsum("ij,ij->i", nxt, np.roll(pole, 1, axis=0))[owner] <= 0.0
    depth = np.arcsin(
        np.clip(np.where(convex, np.maximum(before, after), np.minimum(before, after)), -1.0, 1.0)
    )
    need = np.full(k, -np.inf)
    for shift in (-1, 0, 1):
        np.maximum.at(need, (owner + shift) % k, depth)
    return need


def _moved(curve: np.ndarray, normal: np.ndarray, by: np.ndarray) -> np.ndarray:
    """Stations (K, 3) moved ``by`` (K,) rad along their unit normals (K, 3), on the sphere."""
    out = np.cos(by)[:, None] * curve + np.sin(by)[:, None] * normal
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def held_in(curve: np.ndarray, data: np.ndarray, tree: cKDTree, bound: float) -> np.ndarray:
    """The stations of ``curve`` (K, 3) held within ``bound`` (rad) of ``data`` (N, 3): walked in
    along the normal (at most ``WALK_DEG``), else to ``bound`` from the nearest; folds cut out."""
    dist, nearest = tree.query(curve)
    far = np.flatnonzero(dist > chord(bound))
    if far.size == 0:
        return curve
    x, normal = curve[far], station_normals(curve)[far]
    depth = np.radians(np.arange(1, int(WALK_DEG / WALK_STEP_DEG) + 1) * WALK_STEP_DEG)
    # (F, D, 3): each far station moved in by each depth
    moved = (
        np.cos(depth)[None, :, None] * x[:, None, :]
        - np.sin(depth)[None, :, None] * (normal[:, None, :])
    )
    near, _ = tree.query(moved.reshape(-1, 3))
    reached = near.reshape(moved.shape[:2]) <= chord(bound)
    got = reached.any(axis=1)
    out = curve.copy()
    out[far[got]] = moved[np.flatnonzero(got), np.argmax(reached[got], axis=1)]
    # along the great circle from the nearest sample y toward the station, ``bound`` from y
    rest = far[~got]
    y = data[nearest[rest]]
    t = curve[rest] - np.einsum("ij,ij->i", curve[rest], y)[:, None] * y
    t /= np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-15)
    out[rest] = np.cos(bound) * y + np.sin(bound) * t
    return unfolded(out / np.linalg.norm(out, axis=1, keepdims=True))


def unfolded(curve: np.ndarray, window: int = FOLD_WINDOW) -> np.ndarray:
    """``curve`` (K, 3), closed, with stations ``i+1 .. j`` replaced by the crossing point wherever
    chord ``i -> i+1`` crosses chord ``j -> j+1`` at most ``window`` stations on."""
    while True:
        k = curve.shape[0]
        if k < 2 * window + 4:
            return curve
        a, b = curve, np.roll(curve, -1, axis=0)
        pole = np.cross(a, b)
        hit = None
        for j in range(2, window + 1):
            c, d = np.roll(a, -j, axis=0), np.roll(b, -j, axis=0)
            pole2 = np.roll(pole, -j, axis=0)
            # the chords cross when each one's ends lie on opposite sides of the other's circle
            cross = (np.einsum("ij,ij->i", pole, c) * np.einsum("ij,ij->i", pole, d) < 0.0) & (
                np.einsum("ij,ij->i", pole2, a) * np.einsum("ij,ij->i", pole2, b) < 0.0
            )
            if cross.any():
                i = int(np.flatnonzero(cross)[0])
                hit = (i, j) if hit is None or i < hit[0] else hit
        if hit is None:
            return curve
        i, j = hit
        x = np.cross(pole[i], pole[(i + j) % k])
        x /= np.linalg.norm(x)
        x = x if x @ curve[i] > 0.0 else -x
        drop = (i + 1 + np.arange(j)) % k
        keep = np.ones(k, dtype=bool)
        keep[drop] = False
        curve = curve.copy()
        curve[drop[0]] = x
        keep[drop[0]] = True
        curve = curve[keep]


def evidence_reach(curve: np.ndarray, data: np.ndarray) -> float:
    """The farthest (rad) any point of ``curve`` (K, 3) lies from every taught direction (N, 3)."""
    points, _, _ = resample_loop(curve, np.radians(REACH_STEP_DEG))
    dist, _ = cKDTree(data).query(points)
    return float(2.0 * np.arcsin(min(0.5 * float(dist.max()), 1.0)))
