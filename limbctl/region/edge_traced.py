"""The traced edge: a curve walked out to where the taught samples put the edge, station by station.

The smooth edge of :mod:`limbctl.region.edge_smooth` fits small circles over one window for the
whole loop: exact on a round region, but a window wide enough to average sparse samples spans an
egg's tight end or a kidney's dent, and the gate then refuses it. The traced edge follows any
shape the data resolve, bays included; it needs the edge to be taught densely enough that a
short window holds enough samples (:func:`trace_window`). All angles below are in radians.

Starting from a data-supported loop, resampled to stations ``TRACE_STEP_DEG`` apart, each of
``TRACE_ITERATIONS`` rounds does:

1. *Read the samples against the curve*. Each taught direction ``d`` belongs to its nearest
   station ``k`` and reads its depth beyond the great circle tangent there,
   ``o = asin(d . t_k)`` (``t_k`` the outward normal), at the station's arc-length position.
   Stations are close, so the tangent stands for the curve: the readings are the samples'
   depths relative to the curve, whatever its shape.
2. *Estimate the edge at every station* (:func:`edge_estimate`) from the readings within
   ``+- h`` along the curve: the upper concave majorant of the (position, depth) points,
   evaluated at the station (the line through two of them that passes over all the others and
   is lowest there; a lone deep point lifts a station only as far as the line from it does),
   plus the expected gap between that line and the edge
   (:func:`limbctl.region.gaps.majorant_gap`). A station whose own readings all lie deeper
   than ``h`` lies over a hole in the taught edge (:func:`over_hole`: a recorder that missed
   part of the edge trace leaves only interior samples there); its readings are left out and
   the stations left without readings take the estimates interpolated between the hole's
   ends (:func:`bridged_estimates`), so the curve bridges the hole instead of digging a notch
   to the interior samples.
3. *Move* each station out (or in) by its estimate, smoothed along the curve (Gaussian, ``h/2``).
4. *Smooth* the curve by local quadratic regression of its positions (:func:`local_quadratic`,
   Gaussian weights of width ``TRACE_SMOOTH_DEG``): circles and other quadratic stretches come
   through unchanged, sample noise is averaged away. Smoothing may move a station outward by
   at most ``TRACE_SMOOTH_CAP_DEG`` per round: across a bay narrower than the smoothing width it
   would otherwise bridge the bay, and the next round's estimate pulls the curve back only by
   what the samples say.

A final lift moves stations out where a taught direction next to them still lies beyond.

*Held to the evidence* (asked for by :class:`limbctl.region.edge_choice.TracedEdge` when the
free curve bridged a stretch the samples surround; an outer loop's curve only, a hole's loop
bounds what the region leaves out and bridges nothing): after every round, and on the final
curve resampled ``HELD_STEP_DEG`` apart (``HOLD_PASSES`` times), a station farther than
``HOLD_DEG`` from every taught direction moves in to ``HOLD_DEG`` from one
(:func:`held_in`). A taught direction lies inside the truth, so the curve lies at most
``HOLD_DEG`` outside it, up to its chords: across a bay or notch the estimates would bridge
(the bay's walls lie beyond the stations' tangents) the curve follows the taught samples
round the bay instead; where the hand traced the edge about 1 deg inside, the curve stays
within ``HOLD_DEG`` of that trace.

Measured (``benchmarks/bench_envelope.py``: 1000 i.i.d. samples, dense middle, sparse edge, 5
teaching seeds): on the 39 x 23 deg small kidney the gate's mean angle to the ideal correction
is 0.36-0.48 deg (the supported edge: 1.0-1.1 deg), on the 48 x 26 deg egg 0.37-0.56 deg
(supported: 1.1-1.2 deg), with every output inside or within 1 deg of the true region. Regions
taught too sparsely (windows wider than ``TRACE_MAX_WINDOW_DEG``: the 113 x 78 deg BEAN and
KIDNEY at 1000 samples) are refused (:class:`limbctl.region.edge_choice.TracedEdge`). Sharp
corners come out rounded.
"""

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

#: Spacing (deg) of the traced curve's stations: half the smooth edge's, to follow an egg's
#: tip, and at least two stations either side of the smallest half window.
TRACE_STEP_DEG = 1.5
#: Rounds of read, estimate, move, smooth: each round's smoothing moves out at most
#: TRACE_SMOOTH_CAP_DEG, so the curve can settle a few degrees from where it started.
TRACE_ITERATIONS = 10
#: Width (deg, Gaussian sigma along the curve) of the local quadratic smoothing: averages
#: the estimates of several windows while a 10 deg circle shrinks only 0.14 deg a round.
TRACE_SMOOTH_DEG = 6.0
#: The most (deg) one round's smoothing may move a station outward: smoothing across a bay
#: narrower than its width would bridge it; the next estimate pulls a station back this much.
TRACE_SMOOTH_CAP_DEG = 0.25
#: The estimate window is chosen so the outermost samples are about this far apart (deg):
#: an estimate's noise is about one spacing, well under the 0.5 deg accuracy target.
TRACE_SPACING_DEG = 0.2
#: Smallest half window (deg) along the curve: two stations either side, however dense.
TRACE_MIN_WINDOW_DEG = 3.0
#: Largest half window (deg): wider windows span corners and dents and average them away;
#: sparser edges are refused (see the module docstring).
TRACE_MAX_WINDOW_DEG = 10.0
#: Depth (deg) of the band inside the loop the edge's sample density is counted in: near the
#: edge, where a region taught densely in the middle is sparser.
DENSITY_BAND_DEG = 3.0
#: Samples up to this far (deg) beyond the curve still count in the band: the supported loop's
#: own samples sit on it, up to rounding and the resampled chords.
BAND_BEYOND_DEG = 0.05
#: After the lift every taught direction lies at least this far (deg) inside, not on the edge
#: where rounding decides: far below a servo tick (0.088 deg).
LIFT_MARGIN_DEG = 0.01
#: The farthest (deg) a station of an outer loop's traced curve may lie from every taught
#: sample (:func:`held_in`): a taught sample lies inside the truth, so the curve lies at most
#: this far outside it; 0.75 leaves a quarter of the 1 deg bound to the chords between
#: stations. At 1.0 a hand's trace 1-1.4 deg inside would be followed more closely, but the
#: dense i.i.d. teachings' samples lie at the edge and the bound itself would be the slack.
HOLD_DEG = 0.75
#: Spacing (deg) of an outer loop's final stations, each held to the evidence: a chord of
#: this length across a right-angled concave corner passes a quarter of it beyond the
#: corner, small beside the 1 deg bound, and the lift's chords cut convex corners as little.
HELD_STEP_DEG = 0.5
#: Resample-and-hold passes at HELD_STEP_DEG: each pass puts stations on the chords the last
#: one stretched (dense teachings of the families' outlines 0-3: chords left 0.55-0.73 deg
#: long, the curve within 0.87-1.01 deg of a taught sample everywhere along them).
HOLD_PASSES = 3
#: The farthest (deg) a station walks in along its normal to reach the evidence: one round's
#: move (``max_offset_deg``, 3 deg) past where the round before held it.
WALK_DEG = 3.0
#: Step (deg) of a station's walk: it ends at most this much deeper than the bound asks.
WALK_STEP_DEG = 0.05
#: The farthest (deg) a held curve may lie from every taught sample anywhere along it (its
#: chords and folds cut included), or it is refused: the 1 deg bound of docs/region.md.
HELD_REACH_DEG = 1.0
#: Spacing (deg) of the points :func:`evidence_reach` checks: small beside the bound.
REACH_STEP_DEG = 0.1
#: Stations (HELD_STEP_DEG apart) a fold of held stations may span: stations moved in by up to
#: a round's move (3 deg) toward samples on a bay's two walls fold over about twice that.
FOLD_WINDOW = 20
#: Outermost readings per window the majorant is built from: the majorant and its
#: ORDER_STATISTICS smallest residuals lie among them, and the pair search stays 40 x 40.
TOP_READINGS = 40


def station_normals(curve: np.ndarray) -> np.ndarray:
    """Outward unit normals (K, 3) of a closed counter-clockwise curve (K, 3) at its stations.

    The pole of the chord through the two neighbours, ``-(c_{k-1} x c_{k+1})``, projected onto
    the tangent plane at ``c_k``.
    """
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
    """Half window (rad) for the edge estimates (inf when no sample lies near the curve).

    The samples within ``DENSITY_BAND_DEG`` inside the curve (or up to ``BAND_BEYOND_DEG``
    beyond it) give the edge's density ``rho`` (per sr); a window of ``2 h`` then holds
    ``rho 2h`` samples per radian of depth, and the outermost ones lie ``1 / (rho 2h)`` apart.
    ``h`` makes that ``TRACE_SPACING_DEG``, at least ``TRACE_MIN_WINDOW_DEG``; above
    ``TRACE_MAX_WINDOW_DEG`` the edge is taught too sparsely and :func:`trace_edge` refuses it.
    """
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
    """Where the edge lies (rad, relative to the curve) at a station, from nearby readings.

    ``u`` (M,) are the readings' positions along the curve relative to the station, ``o`` (M,)
    their depths. The upper concave majorant at ``u = 0`` is the highest chord value
    ``o_i + (o_j - o_i) (0 - u_i) / (u_j - u_i)`` over pairs with ``u_i < 0 <= u_j``; the edge
    lies :func:`limbctl.region.gaps.majorant_gap` beyond it (from the residuals below the
    chord). With readings on one side only (or fewer than ``ORDER_STATISTICS``), the outermost
    depth plus their mean spacing (:func:`limbctl.region.gaps.spacing_gap`).
    """
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
    """:func:`edge_estimate` (K,) rad at every station, from the readings of the stations
    ``i - reach .. i + reach`` (0 where they hold none): the numba kernel
    :func:`limbctl.region.trace_kernels.station_moves`.

    ``s`` (K,) are the stations' positions along the curve of length ``total`` (rad),
    ``owner`` (N,) and ``depth`` (N,) each reading's station and depth (:func:`readings`).
    """
    buckets = StationBuckets(owner, s.shape[0])
    return station_moves(s, total, owner, depth, buckets.order, buckets.bounds, reach, TOP_READINGS)


def over_hole(owner: np.ndarray, depth: np.ndarray, stations: int, limit: float) -> np.ndarray:
    """Which of the stations (K,) bool lie over a hole in the taught edge.

    A station lies over a hole when it owns readings (``owner`` (N,), ``depth`` (N,) rad,
    :func:`readings`) but none of them within ``limit`` (rad) of the curve: its nearest taught
    directions are interior samples, deeper than its window reaches along the curve, and say
    nothing of where the edge lies there (a recorder that missed part of the edge trace).
    """
    outermost = np.full(stations, -np.inf)
    np.maximum.at(outermost, owner, depth)
    return np.isfinite(outermost) & (outermost < -limit)


def bridged_estimates(
    s: np.ndarray, total: float, owner: np.ndarray, depth: np.ndarray, reach: int, h: float
) -> np.ndarray:
    """:func:`station_estimates` (K,) rad, bridging the stations over a hole (:func:`over_hole`,
    deeper than the half window ``h`` rad).

    Without such stations the estimates are :func:`station_estimates` itself. Otherwise the
    readings of those stations are left out of every window, and each station whose window
    then holds no reading takes the estimate interpolated linearly along the curve between the
    nearest stations either side whose windows hold readings: the curve keeps its course over
    the hole (the supported loop's bridge), moved as the stations at the hole's two ends are:
    a station over a hole moves neither further in nor further out than those two.
    """
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
    """Local quadratic regression (K, 3) of a closed curve's stations (K, 3), evenly spaced.

    At station ``k`` the positions ``c_j`` are fitted by ``a + b u + c u^2`` (``u`` the
    circular arc-length offset, weights ``exp(-u^2 / (2 sigma^2))``) and replaced by ``a``,
    renormalised: exact on quadratic stretches. A circle of angular radius ``r`` is quadratic
    only to second order and shrinks by about ``sigma^4 / (8 r^3)`` (measured for sigma 6 deg:
    0.02 deg at r = 20 deg, 0.14 deg at 10 deg); the next round's estimate moves it back out.
    """
    s, total = station_positions(curve)
    u = signed_offset(s[None, :], s[:, None], total)
    w = np.exp(-0.5 * (u / sigma) ** 2)
    # weighted powers w u^p (p = 0 .. 4): the normal equations (X^T W X) beta = X^T W c of
    # the basis (1, u, u^2) hold sums of w u^(a + b) on the left and w u^a c on the right
    powers = [w]
    for _ in range(4):
        powers.append(powers[-1] * u)
    moment = np.stack([p.sum(axis=1) for p in powers], axis=-1)
    lhs = np.stack([moment[:, a : a + 3] for a in range(3)], axis=1)
    rhs = np.stack([powers[a] @ curve for a in range(3)], axis=1)
    out = np.linalg.solve(lhs, rhs)[:, 0, :]
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def trace_edge(
    loop: np.ndarray, data: np.ndarray, max_offset: float, hold: bool = False
) -> np.ndarray | None:
    """The traced edge (K, 3) of one counter-clockwise data-supported ``loop`` (M, 3).

    ``data`` (N, 3) are the taught directions; ``max_offset`` (rad) caps one round's move;
    ``hold``: an outer loop's curve is held to the evidence (module docstring). None when the
    edge is taught too sparsely (:func:`trace_window`).
    """
    step = np.radians(TRACE_STEP_DEG)
    curve, _, _ = resample_loop(loop, step)
    h = trace_window(curve, data)
    if h > np.radians(TRACE_MAX_WINDOW_DEG):
        return None
    cap = np.radians(TRACE_SMOOTH_CAP_DEG)
    # an outer loop's curve stays within reach of the evidence (a hole's loop bounds what the
    # region leaves out: it bridges nothing)
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
        # finer stations, each held: a chord between two of them cuts far less past a corner
        step = np.radians(HELD_STEP_DEG)
        for _ in range(HOLD_PASSES):
            # a hold may stretch a chord between stations moved toward different samples
            curve = held_in(resample_loop(curve, step)[0], data, tree, bound)
    # lift: no taught direction left beyond the chords next to the station it belongs to (a
    # lifted station moves out only as far as a taught direction beyond its chords)
    s, total = station_positions(curve)
    for _ in range(2):
        need = chord_need(curve, data) + np.radians(LIFT_MARGIN_DEG)
        curve = _moved(curve, station_normals(curve), lift(need, s, total, step))
    return curve


def chord_need(curve: np.ndarray, data: np.ndarray) -> np.ndarray:
    """How far (K,) rad each station must move out to hold the taught directions (N, 3).

    A direction owned by station ``k`` reads its depth beyond the great circles of the two
    chords at ``k`` (``(k-1, k)`` and ``(k, k+1)``, outward poles ``-(a x b)``): outside the
    polygon when beyond either at a convex station, beyond both at a reflex one. Moving the
    three stations ``k-1, k, k+1`` out that far moves both chords past it. -inf where no
    direction needs it.
    """
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
    """The stations of ``curve`` (K, 3) held to the taught evidence ``data`` (N, 3).

    A station farther than ``bound`` (rad) from every taught direction (``tree``, a
    :class:`scipy.spatial.cKDTree` over ``data``) walks in along its inward normal,
    ``WALK_STEP_DEG`` at a time, to the first place within ``bound`` of one; one that gets
    nowhere within ``WALK_DEG`` (the normal runs between strokes) moves straight toward its
    nearest taught direction, to ``bound`` from it. The others stay. A taught direction lies
    inside the truth, so a held station lies at most ``bound`` outside it. Folds the moves
    leave are cut out (:func:`unfolded`).
    """
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
    """``curve`` (K, 3), closed, with its local folds cut out.

    Stations moved in toward samples across a bay tighter than their move cross over each
    other: where the chord ``i -> i+1`` crosses a chord ``j -> j+1`` at most ``window``
    stations on, the stations ``i+1 .. j`` (the fold's loop) are replaced by the crossing
    point, until no such pair is left.
    """
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
    """The farthest (rad) any point of the closed ``curve`` (K, 3), resampled
    ``REACH_STEP_DEG`` apart, lies from every taught direction (N, 3)."""
    points, _, _ = resample_loop(curve, np.radians(REACH_STEP_DEG))
    dist, _ = cKDTree(data).query(points)
    return float(2.0 * np.arcsin(min(0.5 * float(dist.max()), 1.0)))
