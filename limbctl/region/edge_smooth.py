"""The smooth edge: local small circles fitted to the data-supported loops, every ``STEP_DEG``;
refused at a held bay (:func:`protected`) or a loop the window cannot follow
(:func:`residual_ratio`). Radians; docs/region.md, "Edge strategies"."""

from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from limbctl.geometry.quat import tangent_frame
from limbctl.region.gaps import ORDER_STATISTICS, spacing_gap
from limbctl.region.loops import (
    StationBuckets,
    lift,
    loop_area,
    loop_gaps,
    loop_length,
    nearest_station,
    resample_loop,
    smooth_along,
)

#: Largest station/median fit residual: cones measure 1.01-1.25, eggs' tips 1.5-2.1.
RESOLVED_RATIO = 1.4
#: Station spacing (deg): well inside the smallest window (4.5 deg).
STEP_DEG = 3.0
#: Window ladder (deg, Gaussian sigma): x1.45 a step, 4.5 to 60 deg in 8 fits.
WINDOWS_DEG = (4.5, 6.5, 9.0, 13.0, 19.0, 27.0, 40.0, 60.0)
#: Smallest window chosen (deg): narrower ones take where samples fell for shape.
START_WINDOW_DEG = 13.0
#: A window spans at least this many vertex spacings: fewer fit noise as curvature.
MIN_VERTICES_PER_WINDOW = 3.0
#: Most a ladder step may grow the residual: more than 20 % means shape, not noise.
GROWTH = 1.2
#: Smallest fitted circle (deg): a few noisy vertices must not fit a tighter one.
MIN_RADIUS_DEG = 5.0
#: A pocket worth more samples is a taught bay: the acceptance's ``GAP_EXPECTED``.
POCKET_SAMPLES = 40.0
#: Vertices are clipped to this angle (deg) for the hull: gnomonic sends 90 to infinity.
HULL_REACH_DEG = 89.0


def outward_at_stations(loop: np.ndarray, s: np.ndarray, at_vertex: np.ndarray) -> np.ndarray:
    """Outward pole (K, 3) of the loop arc each station lies on: ``-(a x b) / |a x b|``."""
    nxt = np.roll(loop, -1, axis=0)
    pole = -np.cross(loop, nxt)
    pole /= np.maximum(np.linalg.norm(pole, axis=1, keepdims=True), 1e-15)
    e = np.clip(np.searchsorted(at_vertex, s, side="right") - 1, 0, loop.shape[0] - 1)
    return pole[e]


def circle_fits(
    loop: np.ndarray,
    at_vertex: np.ndarray,
    s: np.ndarray,
    total: float,
    outward: np.ndarray,
    window: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Weighted small-circle fit at every station: poles (K, 3), radii (K,) rad, residuals (K,) rad.
    Weights ``exp(-(s_i - s_k)^2 / (2 window^2))`` over the loop's vertices; the pole on the
    region's side, the radius within ``[MIN_RADIUS_DEG, 180 - MIN_RADIUS_DEG]``."""
    gap = loop_gaps(s, at_vertex, total)
    w = np.exp(-0.5 * (gap / window) ** 2)
    # the four nearest vertices always count: a fit needs three points off one great circle
    nearest = np.argsort(gap, axis=1)[:, :4]
    np.put_along_axis(w, nearest, np.maximum(np.take_along_axis(w, nearest, axis=1), 1e-3), 1)
    w /= w.sum(axis=1, keepdims=True)
    mean = w @ loop
    # weighted covariance sum_i w_ki x_i x_i^T - mean mean^T, per station
    cov = np.einsum("ki,ia,ib->kab", w, loop, loop) - np.einsum("ka,kb->kab", mean, mean)
    _, vecs = np.linalg.eigh(cov)
    pole = vecs[:, :, 0]
    pole *= np.where(np.einsum("ij,ij->i", pole, outward) > 0.0, -1.0, 1.0)[:, None]
    ang = np.arccos(np.clip(pole @ loop.T, -1.0, 1.0))
    rho = np.sum(w * ang, axis=1)
    resid = np.sqrt(np.sum(w * (ang - rho[:, None]) ** 2, axis=1))
    lo = np.radians(MIN_RADIUS_DEG)
    return pole, np.clip(rho, lo, np.pi - lo), resid


def on_circle(x: np.ndarray, pole: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """The point (K, 3) at angle ``rho`` from ``pole`` on the great circle through ``x``."""
    u = x - np.einsum("ij,ij->i", x, pole)[:, None] * pole
    u /= np.maximum(np.linalg.norm(u, axis=1, keepdims=True), 1e-15)
    return np.cos(rho)[:, None] * pole + np.sin(rho)[:, None] * u


def choose_window(
    loop: np.ndarray, at_vertex: np.ndarray, s: np.ndarray, total: float, outward: np.ndarray
) -> float:
    """The window (rad) by the residual-growth rule, from at least ``START_WINDOW_DEG`` or
    ``MIN_VERTICES_PER_WINDOW`` mean vertex spacings."""
    floor = max(START_WINDOW_DEG, np.degrees(MIN_VERTICES_PER_WINDOW * total / loop.shape[0]))
    ladder = [np.radians(w) for w in WINDOWS_DEG if w >= floor] or [np.radians(WINDOWS_DEG[-1])]
    best = ladder[0]
    last = float(np.mean(circle_fits(loop, at_vertex, s, total, outward, best)[2]))
    for window in ladder[1:]:
        r = float(np.mean(circle_fits(loop, at_vertex, s, total, outward, window)[2]))
        if r > GROWTH * max(last, 1e-12):
            break
        best, last = window, r
    return best


def edge_offsets(
    stations: np.ndarray, pole: np.ndarray, total: float, data: np.ndarray, window: float
) -> np.ndarray:
    """Endpoint estimate (K,) rad of the edge beyond each station's circle."""
    k = stations.shape[0]
    # each datum belongs to its nearest station; a station reads those within +- window
    buckets = StationBuckets(nearest_station(data, stations), k)
    reach = max(1, int(round(window / (total / k))))
    # outward unit normal of the circle at each station: (x (x . n) - n) / |...|
    normal = stations * np.einsum("ij,ij->i", stations, pole)[:, None] - pole
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-15)
    out = np.zeros(k)
    for i in range(k):
        rows = buckets.around(i, reach)
        if rows.size == 0:
            continue
        # o = asin(d . t): signed depth beyond the tangent great circle (outward normal t)
        o = np.arcsin(np.clip(data[rows] @ normal[i], -1.0, 1.0))
        o = -np.sort(-o)[:ORDER_STATISTICS]
        out[i] = o[0] + spacing_gap(o)
    return out


def fit_edge(loop: np.ndarray, data: np.ndarray, max_offset: float) -> tuple[np.ndarray, float]:
    """The smooth edge (K, 3) of one data-supported ``loop`` (M, 3), and its :func:`residual_ratio`;
    ``data`` (N, 3) the taught directions, ``max_offset`` (rad) the edge offset's cap."""
    stations, s, at_vertex = resample_loop(loop, np.radians(STEP_DEG))
    total = loop_length(loop)
    outward = outward_at_stations(loop, s, at_vertex)
    window = choose_window(loop, at_vertex, s, total, outward)
    pole, rho, resid = circle_fits(loop, at_vertex, s, total, outward, window)
    base = on_circle(stations, pole, rho)
    offset = smooth_along(edge_offsets(base, pole, total, data, window), s, total, window)
    offset += lift(sample_need(base, pole, rho, data) - offset, s, total, 0.5 * window)
    # out by a chord's sagitta, so the chords lie on or outside the curve: step^2 / (8 tan rho)
    # for a circle of angular radius rho, none where it curves the other way
    step = total / s.shape[0]
    offset += np.maximum(step**2 / (8.0 * np.tan(np.minimum(rho, 0.5 * np.pi - 1e-9))), 0.0)
    return on_circle(base, pole, rho + np.minimum(offset, max_offset)), residual_ratio(resid)


def residual_ratio(resid: np.ndarray) -> float:
    """The largest station fit residual over the median one, of ``resid`` (K,) rad: near 1 where one
    window fits the loop, above where it spans a tip or corner it cannot follow."""
    return float(np.max(resid) / max(float(np.median(resid)), 1e-12))


def sample_need(base: np.ndarray, pole: np.ndarray, rho: np.ndarray, data: np.ndarray):
    """Offset (K,) rad each station needs to hold the taught directions (N, 3) nearest it or
    its two neighbours (-inf where there are none)."""
    k = base.shape[0]
    owner = nearest_station(data, base)
    need = np.full(k, -np.inf)
    for shift in (-1, 0, 1):
        station = (owner + shift) % k
        depth = np.arccos(np.clip(np.einsum("ij,ij->i", data, pole[station]), -1.0, 1.0))
        np.maximum.at(need, station, depth - rho[station])
    return need


def pockets(loop: np.ndarray, data: np.ndarray) -> list[tuple[int, int, float]]:
    """The bays of a loop (M, 3), between consecutive vertices of its (gnomonic) convex hull:
    ``(a, b, worth)`` per pocket ``a -> b``, ``worth`` the samples mean density would put in it."""
    centre = data.mean(axis=0)
    centre /= np.linalg.norm(centre)
    u, v = tangent_frame(centre)
    z = np.maximum(loop @ centre, np.cos(np.radians(HULL_REACH_DEG)))
    try:
        hull = sorted(ConvexHull(np.column_stack([loop @ u / z, loop @ v / z])).vertices.tolist())
    except QhullError:
        return [(0, loop.shape[0] - 1, np.inf)]
    rho = data.shape[0] / max(abs(loop_area(loop)), 1e-12)
    m = loop.shape[0]
    out = []
    for i, a in enumerate(hull):
        b = hull[(i + 1) % len(hull)]
        stretch = [(a + k) % m for k in range(((b - a) % m) + 1)]
        if len(stretch) >= 3:
            out.append((a, b, rho * abs(loop_area(loop[stretch]))))
    return out


def protected(
    loop: np.ndarray, data: np.ndarray, s: np.ndarray, at_vertex: np.ndarray
) -> np.ndarray:
    """(K,) bool: stations on a bay the data hold (a pocket worth > ``POCKET_SAMPLES``); all of
    a hole (a clockwise loop)."""
    if loop_area(loop) < 0.0:
        return np.ones(s.shape[0], dtype=bool)
    total = loop_length(loop)
    mask = np.zeros(s.shape[0], dtype=bool)
    for a, b, worth in pockets(loop, data):
        if worth <= POCKET_SAMPLES:
            continue
        start, length = at_vertex[a], (at_vertex[b] - at_vertex[a]) % total
        mask |= (s - start) % total <= length
    return mask
