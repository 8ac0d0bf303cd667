"""Start a three-servo session from outside the region by driving in; park it after.

The three-servo twin of :mod:`limbctl.teleop.approach`, on SO(3) instead of the sphere of
directions. "Inside by the margin" is :func:`limbctl.teleop.start3.safe_with_margin`: the pose
the servos would hold is safe for :class:`~limbctl.teleop.gate3.Gate3`, and stays safe with any
one joint moved by the margin either way.

:func:`nearest_start_pose3` finds such a pose near the present one. Candidates, all built on
``c = correct(q)``, the region's orientation nearest the present ``q``:

- on along the shortest rotation from ``q`` through ``c``, ``s`` margins past ``c`` (the inward
  way across a smooth edge of swing or twist);
- rings around ``c``: ``r(a, s m) * c``, the rotation by ``s`` margins about each of
  :data:`RING_AXES` (corners and necks, and the twist's own stops, where the way in is a turn
  about the limb's axis);

with ``s`` over :data:`~limbctl.teleop.margin.SEARCH_RADII`. Each is rounded to ticks as the
servos would hold it; the first, nearest ``q`` by geodesic angle, that is inside by the margin
wins.

:func:`drive3` moves the limb there along the shortest rotation at a speed the user chose, each
goal checked: inside the hard limits, no joint step above the gate's, never further outside the
region than where the limb started (plus the gate's tolerance). :func:`park3` is the gate itself
driving the limb from the session's last pose to the nearest pose inside by the margin.

Angles in radians unless a name ends in ``_deg``; orientations as unit quaternions (4,),
scalar first.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import IO, Any

import numpy as np

from limbctl.errors import BusError
from limbctl.geometry.gimbal import pan_tilt_roll_scalar, pose_quat_scalar
from limbctl.geometry.quat import multiply
from limbctl.teleop.approach import SETTLE_DEG, SETTLE_TIMEOUT_S, ParkOutcome
from limbctl.teleop.gate import Outcome
from limbctl.teleop.gate3 import Gate3, Pose3, geodesic, toward, turn_by
from limbctl.teleop.margin import SEARCH_RADII, START_MARGIN_DEG, status_line

#: Axes (world frame) the search rings turn the nearest orientation about: the six faces and
#: eight corners of a cube, so every rotation axis lies within 35 deg of one of them; +x is
#: among them, which is the limb's own axis at rest and near it in a region about +x.
RING_AXES = np.array(
    [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]]
    + [[sx, sy, sz] for sx in (1, -1) for sy in (1, -1) for sz in (1, -1)],
    dtype=np.float64,
)
RING_AXES /= np.linalg.norm(RING_AXES, axis=1, keepdims=True)

#: (pan, tilt, roll) rad -> the pose the servos hold once it is written (clamped, rounded).
HeldPose3 = Callable[[Pose3], Pose3]


def safe_with_margin(gate: Gate3, pose: Pose3, margin: float) -> bool:
    """True when ``pose`` and the six poses with one joint moved by +-``margin`` (rad) are safe."""
    if not gate.is_safe(*pose):
        return False
    for k in range(3):
        for sign in (-1.0, 1.0):
            moved = list(pose)
            moved[k] += sign * margin
            if not gate.is_safe(*moved):
                return False
    return True


def outside_by3(gate: Gate3, pose: Pose3) -> float:
    """Rotation (rad) from ``pose`` to the region's nearest orientation; 0 inside."""
    q = pose_quat_scalar(*pose)
    if bool(gate.envelope.contains(q)):
        return 0.0
    return geodesic(q, gate.envelope.correct(q))


def _axis_rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Quaternion (4,) of a turn by ``angle`` (rad) about unit ``axis`` (3,)."""
    half = angle / 2.0
    return np.concatenate([[math.cos(half)], math.sin(half) * axis])


def candidates3(gate: Gate3, q: np.ndarray, margin: float) -> list[np.ndarray]:
    """Orientations (4,) that may be inside by ``margin``, near ``q`` (see the module docstring)."""
    nearest = gate.envelope.correct(q)
    out = [nearest]
    gap = geodesic(q, nearest)
    if gap > margin * 1e-3:
        # across the edge: the shortest rotation from q through c, on by s margins past c
        for s in SEARCH_RADII:
            out.append(turn_by(q, nearest, gap + s * margin))
    for s in SEARCH_RADII:
        for axis in RING_AXES:
            turned = multiply(_axis_rotation(axis, s * margin), nearest)
            out.append(-turned if turned[0] < 0.0 else turned)
    return out


def nearest_start_pose3(
    gate: Gate3, pose: Pose3, held_pose: HeldPose3, margin: float = math.radians(START_MARGIN_DEG)
) -> Pose3 | None:
    """The pose nearest ``pose`` (rad) that is inside by ``margin`` once the servos hold it.

    Returns
    -------
    (pan, tilt, roll) in rad, as the servos hold it (rounded to ticks), or None when no
    candidate qualifies (a region thinner than twice the margin near the pose).
    """
    lim = gate.limits
    here = held_pose(pose)
    if safe_with_margin(gate, here, margin):
        return here
    q = pose_quat_scalar(*pose)
    ranked = sorted(candidates3(gate, q, margin), key=lambda c: geodesic(q, c))
    for c in ranked:
        joints = pan_tilt_roll_scalar(c, pose[0], pose[2], lim.roll_min, lim.roll_max)
        held = held_pose(joints)
        if safe_with_margin(gate, held, margin):
            return held
    return None


@dataclass(frozen=True)
class StartStatus3:
    """Where a waiting three-servo limb is and where it must go before the session may start.

    Angles in degrees; a joint change > 0 turns pan left, raises tilt, rolls the limb
    right-handed about its own axis. The app prints :meth:`line` and may publish it to a live
    view (``pan_deg``, ``tilt_deg`` place the limb there).

    Attributes
    ----------
    pan_deg, tilt_deg, roll_deg : float
        The present pose.
    ready : bool
        Inside by the margin (:func:`safe_with_margin`): the session starts.
    inside_limits : bool
        Every joint within its hard limits.
    outside_deg : float
        Rotation from the present orientation to the region's nearest (0 inside).
    target : tuple of float or None
        The nearest pose inside by the margin (pan, tilt, roll); None when none is near.
    distance_deg : float
        Rotation from the present orientation to the target (0 when ready or no target).
    waited_s : float
        Seconds spent waiting so far.
    """

    pan_deg: float
    tilt_deg: float
    roll_deg: float
    ready: bool
    inside_limits: bool
    outside_deg: float
    target: tuple[float, float, float] | None
    distance_deg: float
    waited_s: float = 0.0

    def advice(self) -> str:
        """Which way to move the limb, in words (empty when ready)."""
        if self.ready:
            return "inside the taught region: starting"
        if self.target is None:
            return (
                "no pose far enough inside the taught region is near; move the limb toward the "
                "middle of what you taught"
            )
        words = (("left", "right"), ("raise", "lower"), ("roll", "roll"))
        here = (self.pan_deg, self.tilt_deg, self.roll_deg)
        moves = []
        for (more, less), now, goal in zip(words, here, self.target, strict=True):
            change = goal - now
            if abs(change) >= 0.05:
                if more == "left":
                    moves.append(f"turn it {more if change > 0 else less} {abs(change):.1f} deg")
                elif more == "roll":
                    moves.append(f"roll it {change:+.1f} deg about its axis")
                else:
                    moves.append(f"{more if change > 0 else less} it {abs(change):.1f} deg")
        return f"move the limb {self.distance_deg:.1f} deg: " + (", ".join(moves) or "a hair")

    def line(self) -> str:
        """One status line: where the limb is, what is wrong, which way to move it."""
        where = f"pan {self.pan_deg:+.1f}, tilt {self.tilt_deg:+.1f}, roll {self.roll_deg:+.1f} deg"
        outside = self.outside_deg if self.outside_deg > 0.0 else None
        return status_line(where, self.ready, self.inside_limits, outside, self.advice())

    def as_dict(self) -> dict:
        """The status as plain JSON-ready values (for a live view or a log)."""
        return {"kind": "start", **asdict(self), "advice": self.advice()}


def assess3(
    gate: Gate3,
    pose: Pose3,
    held_pose: HeldPose3,
    waited_s: float = 0.0,
    margin: float = math.radians(START_MARGIN_DEG),
) -> StartStatus3:
    """The :class:`StartStatus3` of a limb at ``pose`` (rad)."""
    held = held_pose(pose)
    ready = safe_with_margin(gate, held, margin)
    target = held if ready else nearest_start_pose3(gate, pose, held_pose, margin)
    q = pose_quat_scalar(*pose)
    distance = 0.0 if ready or target is None else geodesic(q, pose_quat_scalar(*target))
    return StartStatus3(
        *(math.degrees(a) for a in pose),
        ready=ready,
        inside_limits=gate.limits.inside(*pose),
        outside_deg=math.degrees(outside_by3(gate, pose)),
        target=None if target is None else tuple(math.degrees(a) for a in target),  # type: ignore[arg-type]
        distance_deg=math.degrees(distance),
        waited_s=waited_s,
    )


def drive3(
    rig: Any,
    gate: Gate3,
    start: Pose3,
    target: Pose3,
    speed_deg_s: float,
    rate_hz: float,
    stop: threading.Event,
    stream: IO[str] | None = None,
) -> str:
    """Drive the limb from ``start`` to ``target`` (rad) along the shortest rotation, torque on.

    One goal each ``1 / rate_hz`` s, ``speed_deg_s / rate_hz`` of rotation apart. Returns an
    empty string once the limb settled at the target, else why it stopped (torque is then still
    on; the caller switches it off).
    """
    lim = gate.limits
    step = math.radians(speed_deg_s) / rate_hz
    here, goal = pose_quat_scalar(*start), pose_quat_scalar(*target)
    # never further outside than where the hand left it (plus the gate's own tolerance)
    worst_outside = outside_by3(gate, start) + lim.region_tolerance
    if stream is not None:
        stream.write(
            f"approach: driving the limb {math.degrees(geodesic(here, goal)):.1f} deg at "
            f"{speed_deg_s:g} deg/s to pan {math.degrees(target[0]):+.1f}, tilt "
            f"{math.degrees(target[1]):+.1f}, roll {math.degrees(target[2]):+.1f} deg\n"
        )
        stream.flush()
    pose = start
    rig.set_torque(True)
    while True:
        if geodesic(here, goal) <= step:
            new = target
        else:
            q = toward(here, goal, step)
            new = pan_tilt_roll_scalar(q, pose[0], pose[2], lim.roll_min, lim.roll_max)
        if not lim.inside(*new):
            return "the path left the hard limits"
        if max(abs(a - b) for a, b in zip(new, pose, strict=True)) > lim.max_joint_step:
            return "the path asked for a joint step above the limit (near tilt +-90 deg)"
        if outside_by3(gate, new) > worst_outside:
            return "the path led further outside the taught region"
        if stop.is_set():
            return "stopped"
        rig.write_pose(*new)
        pose, here = new, pose_quat_scalar(*new)
        if new == target:
            break
        # a late cycle is not caught up: goals stay a period apart, never faster than the speed
        stop.wait(1.0 / rate_hz)
    deadline = time.monotonic() + SETTLE_TIMEOUT_S
    while True:
        present = rig.read_pose()
        off = math.degrees(geodesic(pose_quat_scalar(*present), goal))
        if off <= SETTLE_DEG and gate.is_safe(*present):
            return ""
        if time.monotonic() >= deadline or stop.is_set():
            return (
                f"the limb did not reach the target within {SETTLE_TIMEOUT_S:.0f} s "
                f"({off:.1f} deg away: is something holding it?)"
            )
        stop.wait(0.01)


def park3(
    rig: Any, gate: Gate3, rate_hz: float, stop: threading.Event | None = None
) -> ParkOutcome:
    """After a clean session, move the limb inside by the margin if it rests nearer the edge.

    As :func:`limbctl.teleop.approach.park`: the gate drives the limb (slew-limited, corrected,
    checked) to :func:`nearest_start_pose3` of the last pose it let through, one goal per
    ``1 / rate_hz`` s; a pose already inside by the margin is written once more. Bus errors end
    the park (reported in ``note``), never raise.
    """
    stop = stop or threading.Event()
    pose = gate.safe_pose
    if pose is None:
        return ParkOutcome(False, None, note="the gate never started")
    margin = math.radians(START_MARGIN_DEG)
    if safe_with_margin(gate, rig.held_pose(*pose), margin):
        try:
            rig.write_pose(*pose)  # the session's last write may have failed
        except BusError as exc:
            return ParkOutcome(False, pose, note=f"could not write the last pose again: {exc}")
        return ParkOutcome(False, pose)
    target = nearest_start_pose3(gate, pose, lambda p: rig.held_pose(*p), margin)
    if target is None:
        return ParkOutcome(
            False, pose, note=f"no pose inside by {START_MARGIN_DEG} deg near the last one"
        )
    target_q = pose_quat_scalar(*target)
    distance = geodesic(pose_quat_scalar(*pose), target_q)
    # a few cycles more than the slew limit needs, for the joint-step limit near tilt +-90
    for _ in range(math.ceil(distance / gate.limits.max_step) + 10):
        result = gate.step(target_q)
        if result.outcome is Outcome.HELD:
            return ParkOutcome(False, pose, note=f"the gate held: {result.reason}")
        try:
            rig.write_pose(*result.pose)
        except BusError as exc:
            return ParkOutcome(False, gate.safe_pose, note=f"could not park: {exc}")
        if not result.slewed:
            return ParkOutcome(True, result.pose, math.degrees(distance))  # type: ignore[arg-type]
        stop.wait(1.0 / rate_hz)  # a period between goals, late or not: never faster
    return ParkOutcome(False, gate.safe_pose, note="the gate did not reach the park pose")
