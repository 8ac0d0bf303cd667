"""Where a limb may start from: "inside by a margin", and the nearest such pose.

A start pose must survive what happens between sessions: the last goal is rounded to whole
ticks (up to :func:`limbctl.teleop.gate.written_tolerance_deg` outside the region), and a
holding servo sits a tick or two away from its goal. A limb that waits for its user, or a
session that parks it, therefore aims at a pose *inside by* :data:`START_MARGIN_DEG`: the pose
and a ring of :data:`RING_PROBES` directions at that angle around it all lie inside the region,
and each joint is at least that far inside its hard limits.

Everything here is plain geometry on the gate's region and limits; angles in radians unless a
name ends in ``_deg``. :func:`assess` turns a present pose into a :class:`StartStatus`, the value
a terminal line or a live view shows while the limb waits ("how far and which way").
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np

from limbctl.geometry import scalar
from limbctl.geometry.quat import limb_direction, swing_from_direction, tangent_frame
from limbctl.teleop.gate import Gate

#: How far (deg) inside the region and the hard limits a start or park pose must be. It covers
#: the rounding of a goal to ticks (0.072 deg, written_tolerance_deg) plus a holding servo's
#: compliance of up to 2 ticks per joint (sqrt(2) * 2 * 0.088 = 0.25 deg), with room to spare.
START_MARGIN_DEG = 0.35
#: Directions probed on the ring around a pose: with 12, a straight edge that passes between two
#: probes is still at least cos(15 deg) = 97 % of the margin away.
RING_PROBES = 12
#: Ring radii (multiples of the margin) searched for the nearest start pose: fine near the
#: edge, up to 24 margins (8.4 deg) for narrow necks and corners.
SEARCH_RADII = (1.0, 1.25, 1.5, 2.0, 3.0, 4.0, 6.0, 9.0, 13.0, 18.0, 24.0)
#: Directions tried on each search ring (22.5 deg apart).
SEARCH_DIRECTIONS = 16

#: A pose's rounding to what the servos hold: (pan, tilt) rad -> (pan, tilt) rad.
RoundToTicks = Callable[[float, float], tuple[float, float]]


def _exact(pan: float, tilt: float) -> tuple[float, float]:
    return pan, tilt


def ring(directions: np.ndarray, radius: float, count: int) -> np.ndarray:
    """``count`` unit directions at angle ``radius`` (rad) around each of ``directions`` (N, 3).

    Returns
    -------
    ndarray, shape (N, count, 3)
    """
    out = np.empty((len(directions), count, 3))
    theta = 2.0 * math.pi * np.arange(count) / count
    for i, d in enumerate(directions):
        u, v = tangent_frame(d)
        # p_k = cos(r) d + sin(r) (cos th_k u + sin th_k v)
        tangent = np.cos(theta)[:, None] * u + np.sin(theta)[:, None] * v
        out[i] = math.cos(radius) * d + math.sin(radius) * tangent
    return out


def within_limits(gate: Gate, pan: float, tilt: float, margin: float = 0.0) -> bool:
    """Both joints at least ``margin`` (rad) inside the gate's hard limits (NaN is not)."""
    (pan_min, tilt_min), (pan_max, tilt_max) = gate.limits.joint_min, gate.limits.joint_max
    return (
        pan_min + margin <= pan <= pan_max - margin
        and tilt_min + margin <= tilt <= tilt_max - margin
    )


def inside_by_margin(gate: Gate, poses: np.ndarray, margin: float) -> np.ndarray:
    """Which poses (N, 2) (pan, tilt, rad) are inside the region and the limits by ``margin``.

    Inside the region by ``margin`` means the pose's direction and :data:`RING_PROBES`
    directions at angle ``margin`` around it are all inside (one batched ``contains``).

    Returns
    -------
    ndarray of bool, shape (N,)
    """
    poses = np.asarray(poses, dtype=np.float64).reshape(-1, 2)
    (pan_min, tilt_min), (pan_max, tilt_max) = gate.limits.joint_min, gate.limits.joint_max
    ok = (
        (poses[:, 0] >= pan_min + margin)
        & (poses[:, 0] <= pan_max - margin)
        & (poses[:, 1] >= tilt_min + margin)
        & (poses[:, 1] <= tilt_max - margin)
    )
    if not ok.any():
        return ok
    pan, tilt = poses[ok, 0], poses[ok, 1]
    # d = (cos t cos p, cos t sin p, sin t)
    d = np.stack([np.cos(tilt) * np.cos(pan), np.cos(tilt) * np.sin(pan), np.sin(tilt)], axis=1)
    probes = np.concatenate([d[:, None, :], ring(d, margin, RING_PROBES)], axis=1)
    inside = np.asarray(gate.envelope.contains(swing_from_direction(probes.reshape(-1, 3))))
    ok[np.flatnonzero(ok)] = inside.reshape(len(d), RING_PROBES + 1).all(axis=1)
    return ok


def outside_by(gate: Gate, pan: float, tilt: float) -> float:
    """Angle (rad) by which the pose's direction lies outside the region; 0 inside."""
    d = scalar.direction(pan, tilt)
    q = scalar.swing(d)
    if bool(gate.envelope.contains(q)):
        return 0.0
    return scalar.angle(d, scalar.limb(gate.envelope.correct(q)))


def nearest_start_pose(
    gate: Gate,
    pan: float,
    tilt: float,
    margin: float = math.radians(START_MARGIN_DEG),
    round_to_ticks: RoundToTicks = _exact,
) -> tuple[float, float] | None:
    """The pose nearest ``(pan, tilt)`` (rad) that is inside by ``margin`` once rounded to ticks.

    Candidates: past the region's nearest boundary point along the line from the pose (the
    inward way across a smooth edge), then rings of :data:`SEARCH_RADII` around that point
    (corners, necks). Among those whose rounded pose is inside by ``margin``, the one nearest
    the present direction wins. None when no candidate qualifies (a region thinner than twice
    the margin near the pose).

    Returns
    -------
    (pan, tilt) in rad, already rounded to ticks, or None
    """
    d = np.asarray(scalar.direction(pan, tilt))
    nearest = limb_direction(gate.envelope.correct(swing_from_direction(d)))
    # the nearest point of the region, pulled into the hard limits with twice the margin
    base_pan, base_tilt = scalar.pan_tilt(tuple(nearest), pan)
    (pan_min, tilt_min), (pan_max, tilt_max) = gate.limits.joint_min, gate.limits.joint_max
    base_pan = min(max(base_pan, pan_min + 2 * margin), pan_max - 2 * margin)
    base_tilt = min(max(base_tilt, tilt_min + 2 * margin), tilt_max - 2 * margin)
    base = np.asarray(scalar.direction(base_pan, base_tilt))

    candidates = [base[None, :]]
    gap = scalar.angle(tuple(d), tuple(base))
    if gap > margin * 1e-3:
        # across the edge: from d through base and on by s, d' = toward(d, base, gap + s)
        steps = [gap + s * margin for s in SEARCH_RADII]
        candidates.append(np.array([scalar.toward(tuple(d), tuple(base), s) for s in steps]))
    for radius in SEARCH_RADII:
        candidates.append(ring(base[None, :], radius * margin, SEARCH_DIRECTIONS)[0])
    directions = np.concatenate(candidates)
    rounded = np.array(
        [round_to_ticks(*scalar.pan_tilt(tuple(c), base_pan)) for c in directions], dtype=float
    )
    ok = inside_by_margin(gate, rounded, margin)
    if not ok.any():
        return None
    rounded_dirs = np.stack(
        [
            np.cos(rounded[:, 1]) * np.cos(rounded[:, 0]),
            np.cos(rounded[:, 1]) * np.sin(rounded[:, 0]),
            np.sin(rounded[:, 1]),
        ],
        axis=1,
    )
    # angle to the present direction, acos(clip(d . c)): only the order matters here
    closeness = np.where(ok, rounded_dirs @ d, -np.inf)
    best = rounded[int(np.argmax(closeness))]
    return float(best[0]), float(best[1])


def status_line(
    where: str, ready: bool, inside_limits: bool, outside_deg: float | None, advice: str
) -> str:
    """A waiting limb's status line: ``where`` it is, what is wrong (beyond the hard limits,
    ``outside_deg`` outside the region, None inside; on the edge), then the ``advice``."""
    problems = []
    if not inside_limits:
        problems.append("beyond the rig's hard limits")
    if outside_deg is not None:
        problems.append(f"{outside_deg:.1f} deg outside the taught region")
    if not problems and not ready:
        problems.append("on the region's edge")
    state = "; ".join(problems) if problems else "ready"
    return f"limb at {where} ({state}): {advice}"


@dataclass(frozen=True)
class StartStatus:
    """Where a waiting limb is and where it must go before the session may start.

    Angles in degrees. ``move_pan_deg`` > 0 turns the limb left (toward +y), ``move_tilt_deg``
    > 0 raises it. The app prints :meth:`line` and may publish :meth:`as_dict` to a live view.

    Attributes
    ----------
    pan_deg, tilt_deg : float
        The present pose.
    ready : bool
        Inside the region and the hard limits by :data:`START_MARGIN_DEG`: the session starts.
    inside_region, inside_limits : bool
        Each check on its own (without the margin).
    outside_deg : float
        How far the limb direction lies outside the region (0 inside).
    distance_deg : float
        Angle from the present direction to the target (0 when ready).
    target_pan_deg, target_tilt_deg : float or None
        The nearest pose inside by the margin; None when none was found nearby.
    move_pan_deg, move_tilt_deg : float
        Joint changes from the present pose to the target (0 when ready or no target).
    waited_s : float
        Seconds spent waiting so far.
    """

    pan_deg: float
    tilt_deg: float
    ready: bool
    inside_region: bool
    inside_limits: bool
    outside_deg: float
    distance_deg: float
    target_pan_deg: float | None
    target_tilt_deg: float | None
    move_pan_deg: float
    move_tilt_deg: float
    waited_s: float = 0.0

    def advice(self) -> str:
        """Which way to move the limb, in words (empty when ready)."""
        if self.ready:
            return "inside the taught region: starting"
        if self.target_pan_deg is None:
            return (
                "no pose far enough inside the taught region is near; move the limb toward "
                "the middle of what you taught"
            )
        moves = []
        if abs(self.move_pan_deg) >= 0.05:
            way = "left" if self.move_pan_deg > 0 else "right"
            moves.append(f"turn it {way} {abs(self.move_pan_deg):.1f} deg")
        if abs(self.move_tilt_deg) >= 0.05:
            way = "raise" if self.move_tilt_deg > 0 else "lower"
            moves.append(f"{way} it {abs(self.move_tilt_deg):.1f} deg")
        return f"move the limb {self.distance_deg:.1f} deg: " + (" and ".join(moves) or "a hair")

    def line(self) -> str:
        """One status line: where the limb is, what is wrong, which way to move it."""
        where = f"pan {self.pan_deg:+.1f} deg, tilt {self.tilt_deg:+.1f} deg"
        outside = None if self.inside_region else self.outside_deg
        return status_line(where, self.ready, self.inside_limits, outside, self.advice())

    def as_dict(self) -> dict:
        """The status as plain JSON-ready values (for a live view or a log)."""
        return {"kind": "start", **asdict(self), "advice": self.advice()}


def assess(
    gate: Gate,
    pan: float,
    tilt: float,
    round_to_ticks: RoundToTicks = _exact,
    waited_s: float = 0.0,
) -> StartStatus:
    """The :class:`StartStatus` of a limb at ``(pan, tilt)`` (rad, as read from the servos)."""
    margin = math.radians(START_MARGIN_DEG)
    ready = bool(inside_by_margin(gate, np.array([[pan, tilt]]), margin)[0])
    outside = outside_by(gate, pan, tilt)
    target = None if ready else nearest_start_pose(gate, pan, tilt, margin, round_to_ticks)
    distance = move_pan = move_tilt = 0.0
    if target is not None:
        distance = scalar.angle(scalar.direction(pan, tilt), scalar.direction(*target))
        move_pan, move_tilt = target[0] - pan, target[1] - tilt
    return StartStatus(
        pan_deg=math.degrees(pan),
        tilt_deg=math.degrees(tilt),
        ready=ready,
        inside_region=outside == 0.0,
        inside_limits=within_limits(gate, pan, tilt),
        outside_deg=math.degrees(outside),
        distance_deg=math.degrees(distance),
        target_pan_deg=None if target is None else math.degrees(target[0]),
        target_tilt_deg=None if target is None else math.degrees(target[1]),
        move_pan_deg=math.degrees(move_pan),
        move_tilt_deg=math.degrees(move_tilt),
        waited_s=waited_s,
    )
