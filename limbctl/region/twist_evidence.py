"""The twist band never reaches past the taught evidence: the cap on its limits, and where it cuts.

Every taught sample lies inside the true region, so a true upper limit ``u`` no steeper than
``s`` = CAP_SLOPE satisfies, at a direction ``x`` (the lower limit mirrored),

    u(x) >= max_i (t_i - s angle(x, x_i))          (over the samples i near x)

Where the stops around a node spread enough to read their slope ``g`` the cap is also read along it

    u(x) >= max_i (t_i - max(rise(x), rise(e_i)) - CURVATURE r_i^2 / 2),
    rise(y) = g(y) . (x_i - x) + (SLOPE_SLACK + 2 se(y)) r_i

(``r_i = angle(x, x_i)``, ``se`` the plane's slope error, ``e_i`` the node nearest the sample:
the path's slope at either end bounds its rise wherever the truth bends one way between them;
``rise(e_i)`` left out where no slope is read at ``e_i``); where none is read the limit is held
(:func:`_held`) within a steep cone and the bound (:func:`curvature_floors`).
:func:`cap_limits` clips both limits to the caps (the *cut*; :func:`unsupported_places` names
where it is large). Why and what was measured: docs/decisions/twist.md, "The evidence cap".
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, QhullError, cKDTree

from limbctl.geometry.gimbal import direction_to_pan_tilt
from limbctl.region import twist_fit_kernels as fk

#: Steepest true band limit the cap assumes (rad/rad): a shoulder's 0.5-0.7; flatter keeps more.
CAP_SLOPE = 0.5
#: How far (deg) a capped limit may pass the cone: the grid reads it ~0.4 deg above between nodes.
CAP_SLACK_DEG = 0.5
#: Weight width (deg, one sigma) of the local slope's plane. Not tuned: 3 and 5 gave the same cap.
SLOPE_SIGMA_DEG = 3.0
#: The stops' least spread (deg, one sigma) to read a slope (1.5 left curved seed 2 3.07 deg past).
SLOPE_SPREAD_DEG = 0.75
#: The stops' least effective count to read a slope: through 3 the plane's error reads 0.
MIN_SLOPE_STOPS = 4.0
#: Standard errors of the plane's slope added to SLOPE_SLACK: two, a ~95 % bound. Not tuned.
SLOPE_CONFIDENCE = 2.0
#: The true slope's play (rad/rad) beyond the plane's error, and its bending (deg^-1; bumps 0.19)
#: where it turns between the path's ends (bending one way, the slopes read at both ends bound it).
SLOPE_SLACK = 0.15
CURVATURE_PER_DEG = 0.06
#: A cut (deg) above this inside the swing region is reported: dense teachings left 1.0-1.2.
REPORT_CUT_DEG = 1.5
#: Samples near a cap that witness a held stop (a hand's hold leaves 4-10; 3 re-asked a dense dip).
MIN_WITNESSES = 2
WITNESS_DEG = 3.0
#: Within this of the cap (deg) a sample is at it: a hand's stop scatters a few tenths of a degree.
WITNESS_BAND_DEG = 1.5
#: Cuts are judged at nodes this close (deg) to a taught direction: beyond, the band closes.
REPORT_NEAR_DEG = 3.0
#: Places reported are grouped on a grid of this size (deg of pan and of tilt): the guide's cells.
PLACE_DEG = 15.0
#: The hold's cone slope (rad/rad): MAX_SLOPE. Not tuned; where a slope is read it never binds.
HOLD_SLOPE = 1.0
#: How far (deg) a held limit may pass the steep cone: the grid reads it ~0.75 above. Not tuned.
HOLD_SLACK_DEG = 0.5
#: The slope cap's reach (deg): farther samples vouch only as the steep cone does; 5, 6 each failed.
REACH_DEG = 5.5

#: The bound's slope (rad/rad), where the hold acts: families' curved limits 1.81 (seeds 0-39).
BOUND_SLOPE = 2.0
#: The bound's outward bending (deg^-1): families up to 0.216 (seeds 0-39), the shoulder 0.04.
BOUND_CURVATURE_PER_DEG = 0.25
#: The bound's slack (deg): at 0.75 the trajectory test held 98.99 % of its samples (bound 99 %).
BOUND_SLACK_DEG = 0.85
#: Points per block of the floor's facet planes (memory: block x facets floats).
FLOOR_BLOCK = 256


@dataclass(frozen=True)
class UnsupportedPlace:
    """A stretch of a band limit the teaching could not support: ``pan_deg``, ``tilt_deg`` where
    (the direction of the largest cut in its cell), ``side`` ``"upper"`` or ``"lower"`` (which
    twist stop), ``cut_deg`` how far (deg) the cap keeps the limit short of the teaching's reading
    there."""

    pan_deg: float
    tilt_deg: float
    side: str
    cut_deg: float

    def words(self) -> str:
        """The request, in words."""
        way = "upper (positive)" if self.side == "upper" else "lower (negative)"
        return (
            f"turn the limb to its {way} twist stop near pan {self.pan_deg:+.0f}, "
            f"tilt {self.tilt_deg:+.0f} (band held {self.cut_deg:.1f} deg short there)"
        )


def cap_limits(
    up: np.ndarray,
    lo: np.ndarray,
    bounded: np.ndarray,
    nodes: np.ndarray,
    start: np.ndarray,
    members: np.ndarray,
    d: np.ndarray,
    limit: np.ndarray,
    ref: np.ndarray,
    stops: tuple[np.ndarray, np.ndarray] | None = None,
    within: np.ndarray | None = None,
    floors: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Band limits (M,), (M,) relative to the node centres ``ref`` (M,) (rad) clipped to the
    evidence cap, and the cuts (M,), (M,) (rad, >= 0) that ask for a stop (0 where
    MIN_WITNESSES samples witness the cap).

    ``bounded`` (M,) marks the nodes whose band is not free; nodes, samples and neighbourhoods
    as :func:`limbctl.region.twist_fit_kernels.evidence_caps` takes them, held (:func:`_held`)
    where no local slope was read (among the nodes ``within`` (M,) bool, when given). Where the
    clipped limits cross, or no sample lies near, the band closes to no width.
    """
    at = (nodes, start, members, d, limit, ref)
    cap_up, cap_lo, n_up, n_lo = fk.evidence_caps(
        *at, CAP_SLOPE, math.radians(WITNESS_DEG), math.radians(WITNESS_BAND_DEG)
    )
    # where the local slope was read, the cap promises for any truth within its margin of it
    read_up = read_lo = np.zeros(nodes.shape[0], dtype=bool)
    # held only among the taught directions: beyond them the band closes toward them by design
    holdable = bounded if within is None else bounded & within
    if stops is not None:
        cap_up, cap_lo, n_up, n_lo, read_up, read_lo = _along_slope(
            (cap_up, cap_lo, n_up, n_lo), nodes, start, members, d, limit, ref, stops, holdable
        )
    slack = math.radians(CAP_SLACK_DEG)
    # no sample near: nothing is supported
    cap_up = np.where(np.isfinite(cap_up), cap_up + slack, -np.inf)
    cap_lo = np.where(np.isfinite(cap_lo), cap_lo - slack, np.inf)
    new_up = np.where(bounded, np.fmin(up, cap_up), up)
    new_lo = np.where(bounded, np.fmax(lo, cap_lo), lo)
    open_up, open_lo = holdable & ~read_up, holdable & ~read_lo
    held_up, held_lo = _held(new_up, new_lo, open_up, open_lo, at)
    new_up = np.fmin(new_up, held_up)
    new_lo = np.fmax(new_lo, held_lo)
    # a cut asks for a stop unless one was held near the node (and the hold does not bind)
    ask_up = (n_up < MIN_WITNESSES) | np.isfinite(held_up)
    ask_lo = (n_lo < MIN_WITNESSES) | np.isfinite(held_lo)
    # the bound, where the hold acts; what it takes off a witnessed cap asks for a stop too
    bound_up, bound_lo = _held(
        new_up, new_lo, open_up, open_lo, at, BOUND_SLOPE, BOUND_SLACK_DEG, floors
    )
    from_up = np.where(ask_up, up, np.where(np.isfinite(bound_up), new_up, -np.inf))
    from_lo = np.where(ask_lo, lo, np.where(np.isfinite(bound_lo), new_lo, np.inf))
    held_up, held_lo = np.fmin(held_up, bound_up), np.fmax(held_lo, bound_lo)
    new_up = np.fmin(new_up, held_up)
    new_lo = np.fmax(new_lo, held_lo)
    crossed = new_up < new_lo
    near = np.isfinite(cap_up) & np.isfinite(cap_lo)
    top, bottom = np.fmin(cap_up, held_up), np.fmax(cap_lo, held_lo)
    middle = np.clip(0.5 * (np.where(near, top, 0.0) + np.where(near, bottom, 0.0)), lo, up)
    # caps that cross (only far samples around): the twist between them nearest the centre
    gap = near & (top < bottom)
    middle = np.where(gap, np.clip(0.5 * (up + lo), top, bottom), middle)
    new_up = np.where(crossed, middle, new_up)
    new_lo = np.where(crossed, middle, new_lo)
    cut_up = np.fmax(from_up - new_up, 0.0)
    cut_lo = np.fmax(new_lo - from_lo, 0.0)
    return new_up, new_lo, cut_up, cut_lo


def _held(up, lo, open_up, open_lo, at, slope=HOLD_SLOPE, slack_deg=HOLD_SLACK_DEG, floors=None):
    """The hold: limits (M,), (M,) (rad, relative to the node centres, the last of ``at``) where
    the cone of ``slope`` (rad/rad) about the samples, raised to ``floors`` (M,), (M,) (NaN: none)
    when given, plus ``slack_deg`` (deg) lies inside ``up``, ``lo`` (M,) at the nodes ``open_up``,
    ``open_lo`` (M,) bool; +-inf elsewhere. ``at``: (nodes, start, members, d, limit, ref) as
    :func:`limbctl.region.twist_fit_kernels.evidence_caps` takes them."""
    cone_up, cone_lo, _, _ = fk.evidence_caps(*at, slope, 0.0, 0.0)
    if floors is not None:
        # NaN (outside the samples' hull) leaves the cone
        cone_up, cone_lo = np.fmax(cone_up, floors[0]), np.fmin(cone_lo, floors[1])
    slack = math.radians(slack_deg)
    cone_up, cone_lo = cone_up + slack, cone_lo - slack
    # NaN (no sample near) compares False: the cap has closed the band there already
    binds_up = open_up & (cone_up < up)
    binds_lo = open_lo & (cone_lo > lo)
    return np.where(binds_up, cone_up, np.inf), np.where(binds_lo, cone_lo, -np.inf)


def _along_slope(cone, nodes, start, members, d, limit, ref, stops, limited):
    """The cone's caps and witnesses ``cone`` lowered to the caps read along the local slope
    (:func:`limbctl.region.twist_fit_kernels.gradient_caps`) where the stops ``stops`` (upper,
    lower; (N,) bool each) around a node spread enough to read it."""
    cap_up, cap_lo, n_up, n_lo = cone
    args = (
        math.radians(SLOPE_SIGMA_DEG),
        math.radians(SLOPE_SPREAD_DEG),
        SLOPE_SLACK,
        SLOPE_CONFIDENCE,
        math.degrees(CURVATURE_PER_DEG),
        math.radians(WITNESS_DEG),
        math.radians(WITNESS_BAND_DEG),
        math.radians(REACH_DEG),
        HOLD_SLOPE,
        limited,
        MIN_SLOPE_STOPS,
        # each sample's nearest node: the far end of its path, whose slope bounds the rise too
        cKDTree(nodes).query(d)[1].astype(np.int64),
    )
    g_up, w_up = fk.gradient_caps(nodes, start, members, d, limit, stops[0], ref, *args)
    g_lo, w_lo = fk.gradient_caps(nodes, start, members, d, -limit, stops[1], -ref, *args)
    g_lo = -g_lo
    lower_up = g_up < cap_up  # NaN (slope unknown) compares False: the cone stays
    higher_lo = g_lo > cap_lo
    return (
        np.where(lower_up, g_up, cap_up),
        np.where(higher_lo, g_lo, cap_lo),
        np.where(lower_up, w_up, n_up),
        np.where(higher_lo, w_lo, n_lo),
        np.isfinite(g_up),
        np.isfinite(g_lo),
    )


def unsupported_places(
    directions: np.ndarray, cut_up: np.ndarray, cut_lo: np.ndarray
) -> tuple[UnsupportedPlace, ...]:
    """The places (largest cut first) where the cap holds a limit more than REPORT_CUT_DEG short.

    ``directions`` (M, 3) are the band's nodes inside the swing region, ``cut_up``, ``cut_lo``
    (M,) (rad) the cuts there; one place per PLACE_DEG cell of (pan, tilt) and side.
    """
    if directions.shape[0] == 0:
        return ()
    pan, tilt = (np.degrees(a) for a in direction_to_pan_tilt(directions))
    best: dict[tuple[int, int, str], UnsupportedPlace] = {}
    for side, cut in (("upper", cut_up), ("lower", cut_lo)):
        cut_deg = np.degrees(cut)
        for k in np.flatnonzero(cut_deg > REPORT_CUT_DEG):
            key = (int(pan[k] // PLACE_DEG), int(tilt[k] // PLACE_DEG), side)
            if key not in best or best[key].cut_deg < cut_deg[k]:
                best[key] = UnsupportedPlace(float(pan[k]), float(tilt[k]), side, float(cut_deg[k]))
    return tuple(sorted(best.values(), key=lambda p: -p.cut_deg))


def band_unsupported(band, d: np.ndarray, inside=None) -> tuple[UnsupportedPlace, ...]:
    """The places a freshly fitted band (its :attr:`~limbctl.region.twist_band.TwistBand.cuts`)
    could not support, at nodes within REPORT_NEAR_DEG of a taught direction of ``d`` (N, 3)
    and, when given, where ``inside`` (directions (M, 3) -> (M,) bool) holds them."""
    if band.cuts is None:
        return ()
    nodes, cut_up, cut_lo = band.cuts
    near = cKDTree(d).query(
        nodes, distance_upper_bound=2.0 * math.sin(math.radians(REPORT_NEAR_DEG) / 2)
    )
    judged = np.isfinite(near[0])
    if inside is not None:
        judged &= inside(nodes)
    return unsupported_places(nodes[judged], cut_up[judged], cut_lo[judged])


def inside_hull(xy: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Whether each plane point ``p`` (M, 2) lies inside the convex hull of ``xy`` (N, 2) (rad);
    all do when the samples span no area."""
    try:
        rim = ConvexHull(xy).equations
    except (QhullError, ValueError):
        return np.ones(p.shape[0], dtype=bool)
    return np.all(p @ rim[:, :2].T + rim[:, 2] <= 1e-12, axis=1)


def curvature_floors(
    xy: np.ndarray, limit: np.ndarray, node_xy: np.ndarray, ref: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The least upper and greatest lower limit (M,), (M,) (rad, relative to ``ref`` (M,)) at the
    plane points ``node_xy`` (M, 2) (rad) of any truth holding every sample ``(xy, limit)``
    ((N, 2), (N,) rad) whose limits bend toward the band's outside by at most
    BOUND_CURVATURE_PER_DEG: the upper concave hull of ``(x, t - k |x|^2 / 2)`` plus
    ``k |x|^2 / 2`` (and the lower mirrored). NaN outside the samples' convex hull."""
    k = math.degrees(BOUND_CURVATURE_PER_DEG)
    out = []
    for sign in (1.0, -1.0):
        out.append(sign * _concave_floor(xy, sign * limit, node_xy, k) - ref)
    return out[0], out[1]


def _concave_floor(xy, t, p, k):
    """Height (M,) at points ``p`` (M, 2) of the upper concave hull of ``(xy, t - k |xy|^2 / 2)``
    plus ``k |p|^2 / 2`` (rad); NaN outside the hull of ``xy`` or when it spans no area. A
    concave function is the least of its facets' planes everywhere over its domain."""
    out = np.full(p.shape[0], np.nan)
    try:
        hull = ConvexHull(np.column_stack([xy, t - 0.5 * k * np.sum(xy * xy, axis=1)]))
        rim = ConvexHull(xy).equations
    except (QhullError, ValueError):
        return out
    eq = hull.equations[hull.equations[:, 2] > 1e-9]
    # facets a x + b y + c s + e = 0, outward normal up: s = -(a x + b y + e) / c
    slope, offset = -eq[:, :2] / eq[:, 2:3], -eq[:, 3] / eq[:, 2]
    rows = np.flatnonzero(np.all(p @ rim[:, :2].T + rim[:, 2] <= 1e-12, axis=1))
    for first in range(0, rows.size, FLOOR_BLOCK):
        block = rows[first : first + FLOOR_BLOCK]
        q = p[block]
        out[block] = np.min(q @ slope.T + offset, axis=1) + 0.5 * k * np.sum(q * q, axis=1)
    return out
