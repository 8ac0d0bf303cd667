"""The twist band never reaches past the taught evidence: the cap on its limits, and where it cuts.

The band's readings (:mod:`limbctl.region.twist_band`) bridge between stops and extrapolate
beside the swing edge; where the stops lie far apart a bridged limit can lie degrees past the
true stop (a truth curving away between two stops, a notch, a corner the hand never turned at).
Every taught sample lies inside the true region, so a true upper limit ``u`` that changes by at
most ``s`` = CAP_SLOPE (rad of twist per rad of direction) satisfies at a direction ``x``

    u(x) >= max_i (t_i - s angle(x, x_i))          (over the samples i near x)

and a learned upper limit at most CAP_SLACK_DEG above the right side lies within that of the truth
(the lower limit likewise, mirrored). That cone holds only for truths no steeper than ``s``: a
stop high on a steep bump 8 deg away vouches for a limit ``(slope - s) 8 deg`` past the truth at
the bump's foot. So where the stops around a node spread enough to read their slope ``g`` (a
weighted plane through them), the cap is also read along it:

    u(x) >= max_i (t_i - g . (x_i - x) - (SLOPE_SLACK + 2 se) r_i - CURVATURE r_i^2 / 2)

(``r_i = angle(x, x_i)``, ``se`` the plane's slope error), which holds for a truth whose slope at
``x`` lies within the margin of ``g`` and bends at most CURVATURE, whatever its steepness; the
lower of the two caps is kept (:func:`limbctl.region.twist_fit_kernels.gradient_caps`). Its
stops are read twice: against the band's readings, then against the capped band, since a
reading that bridged a dip leaves the dip's own stops below its limit.

Where no slope is read (too few stops around, or along a line) the cone alone would cap, and
its promise fails on truths steeper than ``s`` by up to ``(slope - s) r``. There the limit is
*held* (:func:`_held`) also within the steep cone ``max_i (t_i - HOLD_SLOPE r_i) +
HOLD_SLACK_DEG``: what the samples near the node themselves show, within 0.5 deg of any truth
no steeper than the band's readings believe; the cut it makes asks for a stop. Where a slope is
read, a sample farther than REACH_DEG vouches along it only as far as that steep cone lets it: a
bump bending past the slope cap's curvature bound is exceeded most from far samples.

Where the hold acts, the limit is also kept within BOUND_SLACK_DEG of *the bound*: the least
limit of any truth holding every sample whose slope is at most BOUND_SLOPE and whose limit bends
outward by at most BOUND_CURVATURE_PER_DEG, the larger of the cone ``max_i (t_i - BOUND_SLOPE
r_i)`` and the concave floor through the samples (:func:`curvature_floors`): the hold's cone
promises only for truths no steeper than HOLD_SLOPE, the bound for steeper ones that bend
little between the samples.

:func:`cap_limits` clips both limits to the caps; where no sample lies within the band's
neighbourhood the band closes to its centre. The clip is the *cut*: where it is large, the
evidence is too sparse to keep the bound and still cover the region, and
:func:`unsupported_places` names those places (pan, tilt and which stop) for the guide and for
``train``: a stop taught there lifts the cap.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, QhullError, cKDTree

from limbctl.geometry.gimbal import direction_to_pan_tilt
from limbctl.region import twist_fit_kernels as fk

#: Steepest true band limit the cap assumes (rad of twist per rad of direction): a shoulder's
#: rotation range changes by ~0.5 deg per deg of elevation, 0.7 with its centre's drift (the
#: benchmark's shoulder, :mod:`limbctl.envelope.synthetic_twist`). A steeper truth may be
#: exceeded by (slope - CAP_SLOPE) times the distance to the nearest stop; a flatter cap keeps
#: more of a sparse teaching (docs/decisions/twist.md, "The evidence cap").
CAP_SLOPE = 0.5
#: How far (deg) a capped limit may lie beyond the cone through the taught samples: the promise is
#: 1 deg beyond the truth, and the band's bilinear grid (BAND_STEP_DEG 1.5) reads a cone of slope
#: CAP_SLOPE up to CAP_SLOPE x 1.5 / 2 ~ 0.4 deg above its value between nodes. 0.75 brought
#: bench_twist's error back to 0.399 / 0.392 deg (seeds 0, 2; 0.415 / 0.420 at 0.5, 0.388 /
#: 0.380 without the cap) but leaves ~1.1 deg to the promise.
CAP_SLACK_DEG = 0.5
#: The local slope's reading (:func:`limbctl.region.twist_fit_kernels.gradient_caps`): weight
#: width (deg, one sigma) of the plane through the stops around a node. The region families'
#: narrowest bumps (8 deg, one sigma) turn their slope by ~0.2 per 3 deg; the second reading's
#: REFINE_SIGMA_DEG (5) averages over more. Not tuned: 3 and 5 gave the same cap (38.05 deg) at
#: the worst node of the curved family's seed 2, dense teaching.
SLOPE_SIGMA_DEG = 3.0
#: The stops' least spread (deg, one sigma) about their weighted mean for the slope to be read:
#: beside the swing edge the stops lie along it. At 1.5 the worst node of the curved family's
#: seed 2, dense teaching (0.4 deg inside the outline) read no slope and the band stayed 3.07 deg
#: past the truth; at 0.75, with the slope's error in the margin (SLOPE_CONFIDENCE), 0.40.
SLOPE_SPREAD_DEG = 0.75
#: The stops' least effective count (``(sum w)^2 / sum w^2``) for the slope to be read:
#: through 3 stops the plane fits exactly and its error reads 0 (the curved family's seed 5,
#: sparse teaching read a slope 0.6 rad/rad off the truth's and lay 1.41 deg past it; at 4,
#: 0.69 deg; 6 did no better, 0.84). Where none is read the hold and its bound act, and what
#: they cut asks for a stop (docs/decisions/twist.md, "A slope from too few stops").
MIN_SLOPE_STOPS = 4.0
#: Standard errors of the plane's slope added to SLOPE_SLACK: two, a ~95 % bound. Not tuned.
SLOPE_CONFIDENCE = 2.0
#: How far (rad/rad) the true slope at a node may differ from the plane's, beyond its error, and
#: how fast (deg of slope per deg, i.e. deg^-1) the true limit's slope may change. The families'
#: bumps bend up to 0.19 deg^-1, a shoulder's limits ~0.02. At 0.25 and 0.15 the dense i.i.d.
#: teachings listed places wherever the nearest stop lay 3-4 deg away (the linear family's
#: seed 2: 5 places, the curved seed 0: 20; the fixed cone alone 0 and 9); at 0.15 and 0.06:
#: 0 and 9, the curved seed 1 band 2.10 deg past the truth before the stops were re-read, 0.64
#: after (5.31 with the cone alone). Beyond the nearest stops, where a bump bends more, the cap is
#: the max over all stops: the nearest ones (within ~1-2 deg in a dense teaching) set it.
SLOPE_SLACK = 0.15
CURVATURE_PER_DEG = 0.06
#: A cut (deg) larger than this at a place inside the swing region is reported: the cap then keeps
#: the limit more than this short of where the teaching's readings put it, i.e. short of the stop.
#: A dense i.i.d. teaching left cuts of 1.0-1.2 deg at five unwitnessed places where the reading
#: bridged slightly past its stops (tests/region/test_twist_evidence.py); its stops lie 0.2 deg
#: inside the truth, so such a cut still holds the region 2 deg inside.
REPORT_CUT_DEG = 1.5
#: A cap is witnessed (a stop was held at it, :func:`cap_limits`) by this many samples within
#: WITNESS_DEG of the node and WITNESS_BAND_DEG of the cap: a hand's hold at a stop leaves 4-10
#: samples at 125 Hz; a twist sweeping past leaves ~1 deg between samples, and 20 samples drawn
#: across a band's middle put ~0.7 near their top. A dense i.i.d. teaching (4000 stops over
#: 1.7 sr) put only 2 upper stops within 3 deg of the bottom of a dip (tests/region/
#: test_twist_evidence.py): at 3 its cut was asked for again.
MIN_WITNESSES = 2
WITNESS_DEG = 3.0
#: Within this of the cap (deg) a sample is at it: a hand's stop scatters a few tenths of a degree.
WITNESS_BAND_DEG = 1.5
#: Cuts are judged at nodes with a taught direction within this (deg): beyond the taught
#: directions (the swing region's margins) the band closes toward the taught twists by design,
#: and a place without samples is the swing guide's hole to ask for.
REPORT_NEAR_DEG = 3.0
#: Places reported are grouped on a grid of this size (deg of pan and of tilt): the guide's cells.
PLACE_DEG = 15.0
#: The hold (:func:`_held`): where no local slope was read for a limit, the cone alone caps it,
#: and a truth steeper than CAP_SLOPE is exceeded by (slope - CAP_SLOPE) x the distance of the
#: stop that set the cap: 3.9 deg on the region families' curved bands (bumps up to ~1 deg per
#: deg), the cap set by a stop 7.8 deg away. There the limit is also kept within a cone of
#: HOLD_SLOPE about every sample, which promises HOLD_SLACK_DEG at a node for any truth no
#: steeper than HOLD_SLOPE: MAX_SLOPE of the band's readings (the steepest limit either reading
#: believes). Not tuned; where a slope is read (dense stops) it never binds.
HOLD_SLOPE = 1.0
#: How far (deg) a held limit may lie beyond the steep cone, as CAP_SLACK_DEG beyond the cone: the
#: promise is 1 deg past the truth, and the bilinear grid reads a cone of slope HOLD_SLOPE up to
#: HOLD_SLOPE x 1.5 / 2 ~ 0.75 deg above its value between nodes. Not tuned: the families'
#: teachings (seeds 0-2, quick) then lie at most 0.74 deg past the truth, the worst where a slope
#: was read (docs/decisions/twist.md, "The hold").
HOLD_SLACK_DEG = 0.5
#: The slope cap's reach (deg): among the taught directions, a sample farther than this from a
#: node vouches along the read slope only as far as the steep cone (HOLD_SLOPE) lets it, so its
#: bound holds if either the slope's assumptions or the steep cone's do. The curved families'
#: dense teachings had caps set by samples 7.5-8 deg away along a slope read 0.3 off the truth's
#: on a bump bending ~0.2 deg^-1 (curved seed 5: 3.2 deg past the truth). The truth's bending
#: beyond CURVATURE_PER_DEG costs HOLD_SLACK_DEG at sqrt(2 x 0.5 / 0.06) = 4.1 deg, but at 5
#: the shoulder teaching of tests/region/test_twist_band.py held 2.24 % of its lower limit more
#: than 2 deg short (bound 2 %), and at 6 a bump's dense test teaching stayed 1.35 deg past the
#: truth (tests/region/test_twist_evidence.py, a sharper bump than the kept test's); 5.5 passes
#: both (the kept test's bump 0.97 deg past the truth).
REACH_DEG = 5.5

#: The bound (:func:`cap_limits`'s last cap, where the hold acts): a limit at most BOUND_SLACK_DEG
#: above the least limit of any truth holding every sample whose slope is at most BOUND_SLOPE
#: (rad/rad) and whose limit bends outward by at most BOUND_CURVATURE_PER_DEG: the larger of
#: the cone ``max_i (t_i - BOUND_SLOPE r_i)`` and the concave floor (:func:`curvature_floors`).
#: There the band keeps within that of any truth either the hold's cone or this bound assumes.
#: BOUND_SLOPE: the region families' curved limits slope up to 1.48 deg per deg on seeds 0-8
#: (1.56 at most on seeds 0-19), the benchmark's shoulder 0.96, the demo's 0.3; its cost falls on
#: nodes whose nearest stop lies far, where the floor does not reach.
BOUND_SLOPE = 1.5
#: The families' curved limits bend outward up to 0.215 deg^-1 (seed 5; seed 4 0.15, 0.14 or less
#: on seeds 0-3 and 6-8), the shoulder's 0.04. At 0.25 the shoulder teaching of
#: tests/region/test_twist_band.py held 97.6 % of its lower limit within 2 deg (bound 98 %),
#: at 0.15 98.2 % (main: 98.2 %): a truth bending more (seed 5's bumps) may be exceeded by the
#: difference times the floor's sag factor (docs/decisions/twist.md, "The bound").
BOUND_CURVATURE_PER_DEG = 0.15
#: The promise is 1 deg; the bilinear grid (BAND_STEP_DEG 1.5) reads a limit bending 0.2 deg^-1
#: up to 0.2 x 1.5^2 / 4 ~ 0.11 deg past its value between nodes. At 0.75 the trajectory test of
#: tests/region/test_twist_band.py held 98.99 % of its own samples within 0.5 deg (bound 99 %),
#: at 0.85 99.2 %.
BOUND_SLACK_DEG = 0.85
#: Points per block of the floor's facet planes (memory: block x facets floats).
FLOOR_BLOCK = 256


@dataclass(frozen=True)
class UnsupportedPlace:
    """A stretch of a band limit the teaching could not support.

    Attributes
    ----------
    pan_deg, tilt_deg : float
        Where (the direction of the largest cut in its cell).
    side : str
        ``"upper"`` or ``"lower"``: which twist stop.
    cut_deg : float
        How far (deg) the cap keeps the limit short of the teaching's reading there.
    """

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
    evidence cap (module docstring), and the cuts (M,), (M,) (rad, >= 0) of each that ask for a
    stop: 0 where MIN_WITNESSES samples within WITNESS_DEG of the node lie within
    WITNESS_BAND_DEG of the cap (a stop held there: the cut corrects a reading that bridged
    past it, and teaching more would not lift it).

    ``bounded`` (M,) marks the nodes whose band is not free (free twist is left as read); nodes,
    samples and neighbourhoods as :func:`limbctl.region.twist_fit_kernels.evidence_caps` takes
    them, held (:func:`_held`) where no local slope was read (among the nodes ``within`` (M,)
    bool, when given). Where the clipped limits cross (or no sample lies near), both go to their
    middle (or to 0; where the caps themselves cross, to the twist between them nearest the
    reading's centre): a band of no width.
    """
    cap_up, cap_lo, n_up, n_lo = fk.evidence_caps(
        nodes,
        start,
        members,
        d,
        limit,
        ref,
        CAP_SLOPE,
        math.radians(WITNESS_DEG),
        math.radians(WITNESS_BAND_DEG),
    )
    # where the local slope was read, the cap promises for any truth within its margin of it
    read_up = read_lo = np.zeros(nodes.shape[0], dtype=bool)
    # held only among the taught directions (``within``): beyond them, the swing region's margins,
    # the band closes toward the taught twists by design and the gate's answers run along it
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
    held_up, held_lo = _held(
        new_up,
        new_lo,
        holdable & ~read_up,
        holdable & ~read_lo,
        nodes,
        start,
        members,
        d,
        limit,
        ref,
    )
    new_up = np.fmin(new_up, held_up)
    new_lo = np.fmax(new_lo, held_lo)
    # a cut where a stop was held near the node corrects the reading; elsewhere (and wherever
    # the hold binds) it asks for one
    ask_up = (n_up < MIN_WITNESSES) | np.isfinite(held_up)
    ask_lo = (n_lo < MIN_WITNESSES) | np.isfinite(held_lo)
    # the bound: where the hold acts, also within BOUND_SLACK_DEG of the least limit of any
    # truth no steeper than BOUND_SLOPE and bending outward by no more than
    # BOUND_CURVATURE_PER_DEG; what it takes off a witnessed cap asks for a stop too
    bound_up, bound_lo = _held(
        new_up,
        new_lo,
        holdable & ~read_up,
        holdable & ~read_lo,
        nodes,
        start,
        members,
        d,
        limit,
        ref,
        BOUND_SLOPE,
        BOUND_SLACK_DEG,
        floors,
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
    # caps that cross each other (only far samples around): any twist between them breaks one
    # side's promise by as much; the one nearest the reading's centre, which bridged from the
    # stops of both sides, keeps the side toward the band's middle
    gap = near & (top < bottom)
    middle = np.where(gap, np.clip(0.5 * (up + lo), top, bottom), middle)
    new_up = np.where(crossed, middle, new_up)
    new_lo = np.where(crossed, middle, new_lo)
    cut_up = np.fmax(from_up - new_up, 0.0)
    cut_lo = np.fmax(new_lo - from_lo, 0.0)
    return new_up, new_lo, cut_up, cut_lo


def _held(
    up,
    lo,
    open_up,
    open_lo,
    nodes,
    start,
    members,
    d,
    limit,
    ref,
    slope=HOLD_SLOPE,
    slack_deg=HOLD_SLACK_DEG,
    floors=None,
):
    """The hold: upper and lower limits (M,), (M,) (rad, relative to ``ref``) where it binds on
    the capped limits ``up``, ``lo`` (M,), +-inf elsewhere. It binds at the nodes ``open_up``,
    ``open_lo`` (M,) bool where the cone of ``slope`` (rad/rad: HOLD_SLOPE, or BOUND_SLOPE for
    the bound) about the samples, raised to the ``floors`` (M,), (M,) (rad, relative to
    ``ref``; NaN: none) when given, plus ``slack_deg`` (deg), lies inside the limit."""
    cone_up, cone_lo, _, _ = fk.evidence_caps(nodes, start, members, d, limit, ref, slope, 0.0, 0.0)
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
    (M,) (rad) the cuts there; one place per PLACE_DEG cell of (pan, tilt) and side, at the node
    of its largest cut.
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
    could not support, judged at nodes with a taught direction of ``d`` (N, 3) within
    REPORT_NEAR_DEG (beyond the taught directions the band closes toward the taught twists by
    design, and a place without samples is the swing guide's hole to ask for) and, when given,
    where ``inside`` (a function of directions (M, 3) -> (M,) bool: the swing region) holds
    them."""
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
    """Whether each plane point ``p`` (M, 2) lies inside the convex hull of ``xy`` (N, 2) (rad):
    among the taught directions, where the hold may bind; all of them when the samples span no
    area."""
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
    ``k |x|^2 / 2`` (and the lower mirrored). NaN outside the samples' convex hull, where it
    bounds nothing."""
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
