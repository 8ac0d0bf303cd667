"""The learned edge: a smooth boundary fitted to the data-supported loops and the outermost data.

The loops the region shape traces (:mod:`limbctl.region.shape`) run through taught
samples, so their corners are wherever a sample happened to lie: a command far outside snaps to
one of them, and sparse edges leave the loop inside the true edge. This module replaces each
loop by a smooth curve sampled every ``STEP_DEG`` (all angles below in radians):

1. *Local small circles*. At each station ``k`` of the loop (arc-length position ``s_k``), a
   small circle ``{x : angle(x, n_k) = rho_k}`` is fitted to the loop's vertices ``x_i`` with
   Gaussian weights ``w_ki = exp(-(s_i - s_k)^2 / (2 W^2))``: ``n_k`` is the normal of the
   weighted least-squares plane (the smallest eigenvector of the weighted covariance) on the
   region's side, ``rho_k`` the weighted mean of ``angle(x_i, n_k)``. A boundary that is a
   circle (a cone's) is fitted by one circle whatever ``W``; straight edges by great circles.
2. *Window*. The weighted residual ``r(W)`` of those fits, averaged over the loop, grows with
   ``W`` while the windows still resolve the sampling noise, levels off once they average it,
   and grows again when they span real shape (a corner, a bay). ``W`` is the largest window of
   the ladder ``WINDOWS_DEG`` (from ``START_WINDOW_DEG`` up) before a step grows the residual
   by more than ``GROWTH``.
3. *Edge offset*. The depth of the taught directions nearest to the stations within ``W`` of
   station ``k`` beyond the great circle tangent to its circle there, ``o = asin(d . t_k)``
   (``t_k`` the outward normal; on a convex stretch far samples read shallower than they are,
   never deeper, where the circle's own depth would read a mis-fitted curvature as room to
   grow); the outermost
   ``o_(1) >= ... >= o_(K)`` give the endpoint estimate ``o_(1) + gap`` with ``gap`` their
   mean spacing (:func:`limbctl.region.gaps.spacing_gap`): where the edge lies, not where
   the outermost sample happened to fall. Offsets are smoothed along the loop with the same
   ``W``, raised by smooth bumps (:func:`limbctl.region.loops.lift`) wherever a station would
   leave a taught direction next to it outside, moved out by the sagitta of the chords
   between stations (the polygon of stations circumscribes the curve), and capped at
   ``max_offset``.
4. *Refusal* (:class:`limbctl.region.edge_choice.SmoothEdge`). The strategy refuses where
   the data hold a bay (:func:`protected`: a hole, or a pocket between a loop and its convex
   hull worth more than ``POCKET_SAMPLES`` samples at the data's density) or where the window
   cannot follow the loop's shape at some station (a fit residual above ``RESOLVED_RATIO``
   times the median, :func:`residual_ratio`). What it proposes is then judged like every
   edge (:mod:`limbctl.region.acceptance`). A round, convex taught region (a cone) gets the
   smooth edge; an egg whose tip is tighter than the window, a kidney with a dent and a
   polygon with corners do not (docs/bench_envelope.md lists which edge every benchmark row
   took).
"""

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

#: No station's fit residual may exceed this multiple of the loop's median residual: cones
#: measure 1.01-1.25, eggs and hulls whose tip a window spans 1.5-2.1 (:func:`residual_ratio`).
RESOLVED_RATIO = 1.4
#: Spacing (deg) of the stations of the fitted edge: well inside the smallest window (4.5 deg),
#: and the chords between stations cut at most 0.06 deg into a 20 deg cone (added back).
STEP_DEG = 3.0
#: Window ladder (deg, Gaussian sigma along the loop) the fit chooses its window from: about
#: x1.45 a step, fine enough to stop near where the residual turns up, 4.5 to 60 deg in 8 fits.
WINDOWS_DEG = (4.5, 6.5, 9.0, 13.0, 19.0, 27.0, 40.0, 60.0)
#: The smallest window the choice starts from (deg): narrower windows follow where single
#: samples fell on the supported loop (its vertices) and take that for shape.
START_WINDOW_DEG = 13.0
#: A window (Gaussian sigma) spans at least this many mean vertex spacings of the loop: a
#: circle through fewer vertices takes their noise for curvature.
MIN_VERTICES_PER_WINDOW = 3.0
#: A ladder step may grow the mean fit residual by at most this factor: more than 20 % for a
#: x1.45 wider window means real shape (a corner, a bay) entered it, not more noise averaged.
GROWTH = 1.2
#: Fitted circles are at least this large (deg of angular radius), either side: a few noisy
#: vertices must not fit a circle tighter than any taught edge bends.
MIN_RADIUS_DEG = 5.0
#: A pocket between a loop and its convex hull worth more samples than this is a taught bay:
#: the same bound as a stretch the acceptance lets an edge add (``GAP_EXPECTED``).
POCKET_SAMPLES = 40.0
#: Loop vertices farther (deg) than this from the data's mean are clipped for the hull: the
#: gnomonic projection sends 90 deg to infinity.
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
    """Weighted small-circle fit at every station: poles (K, 3), radii (K,), residuals (K,).

    Weights ``w_ki = exp(-(s_i - s_k)^2 / (2 window^2))`` over the loop's vertices (circular
    distance along the loop); the pole is taken on the region's side (``n . outward <= 0``)
    and the radius kept within ``[MIN_RADIUS_DEG, 180 - MIN_RADIUS_DEG]``.
    """
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
    """The window (rad) by the residual-growth rule of the module docstring.

    The ladder starts at ``START_WINDOW_DEG`` or at ``MIN_VERTICES_PER_WINDOW`` mean vertex
    spacings of the loop, whichever is larger: a circle through a handful of sparse vertices
    takes their noise for curvature.
    """
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
    stations: np.ndarray,
    pole: np.ndarray,
    total: float,
    data: np.ndarray,
    window: float,
) -> np.ndarray:
    """Endpoint estimate (K,) rad of the edge beyond each station's circle (step 3)."""
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
        # o = asin(d . t): signed depth beyond the great circle tangent to the edge at the
        # station (outward normal t); on a convex stretch, samples far along the window read
        # shallower than they are, never deeper
        o = np.arcsin(np.clip(data[rows] @ normal[i], -1.0, 1.0))
        o = -np.sort(-o)[:ORDER_STATISTICS]
        out[i] = o[0] + spacing_gap(o)
    return out


def fit_edge(loop: np.ndarray, data: np.ndarray, max_offset: float) -> tuple[np.ndarray, float]:
    """The smooth edge (K, 3) of one data-supported ``loop`` (M, 3), steps 1-3.

    ``data`` (N, 3) are the taught directions; ``max_offset`` (rad) caps the edge offset.
    Also returns how well the window resolves the loop's shape (:func:`residual_ratio`).
    """
    stations, s, at_vertex = resample_loop(loop, np.radians(STEP_DEG))
    total = loop_length(loop)
    outward = outward_at_stations(loop, s, at_vertex)
    window = choose_window(loop, at_vertex, s, total, outward)
    pole, rho, resid = circle_fits(loop, at_vertex, s, total, outward, window)
    base = on_circle(stations, pole, rho)
    offset = smooth_along(edge_offsets(base, pole, total, data, window), s, total, window)
    offset += lift(sample_need(base, pole, rho, data) - offset, s, total, 0.5 * window)
    # stations out by the sagitta of a chord: the chords between them then lie on or outside
    # the curve, not inside it; sagitta = step^2 / (8 tan rho) for a circle of angular
    # radius rho (geodesic curvature 1 / tan rho), none where it curves the other way
    step = total / s.shape[0]
    offset += np.maximum(step**2 / (8.0 * np.tan(np.minimum(rho, 0.5 * np.pi - 1e-9))), 0.0)
    return on_circle(base, pole, rho + np.minimum(offset, max_offset)), residual_ratio(resid)


def residual_ratio(resid: np.ndarray) -> float:
    """The largest station fit residual over the median one, of ``resid`` (K,) rad.

    Where one window fits the whole loop, every station's residual is the sampling noise
    (ratio near 1: 1.01-1.25 on cones). Where the window spans real shape it cannot follow, a
    tip of an egg or a corner, the residual there is the misfit (1.5-2.1 measured on egg
    and hull shapes), the circle there cuts inside the tip, and the offsets that make up for
    it push the neighbouring flanks 1-2 deg past the true edge.
    """
    return float(np.max(resid) / max(float(np.median(resid)), 1e-12))


def sample_need(base: np.ndarray, pole: np.ndarray, rho: np.ndarray, data: np.ndarray):
    """Offset (K,) rad each station needs to hold the taught directions around it.

    The largest depth ``angle(d, n_k) - rho_k`` of the data nearest to station ``k`` or to
    its two neighbours (-inf where there are none).
    """
    k = base.shape[0]
    owner = nearest_station(data, base)
    need = np.full(k, -np.inf)
    for shift in (-1, 0, 1):
        station = (owner + shift) % k
        depth = np.arccos(np.clip(np.einsum("ij,ij->i", data, pole[station]), -1.0, 1.0))
        np.maximum.at(need, station, depth - rho[station])
    return need


def pockets(loop: np.ndarray, data: np.ndarray) -> list[tuple[int, int, float]]:
    """The bays of a loop (M, 3): stretches between consecutive vertices of its convex hull.

    Returns ``(a, b, worth)`` per hull edge whose stretch ``a -> b`` of the loop leaves a
    pocket, ``worth = rho * area`` the samples a teacher at the data's mean density ``rho``
    (``N / area of the loop``) would have put into it. The hull is taken in the gnomonic
    projection about the data's mean direction (great circles map to lines), vertices
    farther than ``HULL_REACH_DEG`` from it clipped to that angle.
    """
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
    """(K,) bool: stations on a bay the data hold (a pocket worth > ``POCKET_SAMPLES``).

    A hole (a loop running clockwise) is protected whole: its edge is concave throughout.
    """
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
