"""Drive a limb in from outside the region, and park it after a session, for any chain."""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import IO, Any, Protocol

from limbctl.errors import BusError
from limbctl.teleop.gate import Outcome
from limbctl.teleop.margin import START_MARGIN_DEG, SphereMargins

#: How close (deg) the limb must settle to the approach's target: a holding servo sits within
#: two ticks (0.18 deg), leaving the start pose 0.15 deg inside.
SETTLE_DEG = 0.2
#: Longest wait (s) to settle after the last goal: the position loop settles in under 0.5 s.
SETTLE_TIMEOUT_S = 3.0
#: Joint names, in chain order, as status and approach lines print them.
JOINT_NAMES = ("pan", "tilt", "roll")


class StartLimb(Protocol):
    """What starting and parking need of a rig; poses are joint angles (rad)."""

    joints: tuple[Any, ...]

    def read_pose(self) -> tuple[float, ...]: ...

    def write_pose(self, *pose: float) -> object: ...

    def set_torque(self, enabled: bool) -> None: ...

    def torque_enabled(self) -> tuple[bool, ...]: ...


@dataclass(frozen=True)
class ParkOutcome:
    """What :func:`park` did: ``moved`` by ``distance_deg`` to ``pose`` (rad), or why not."""

    moved: bool
    pose: tuple[float, ...] | None
    distance_deg: float = 0.0
    note: str = ""


def where(pose: tuple[float, ...]) -> str:
    """``pose`` (rad) in words: "pan +10.0, tilt -5.0 deg"."""
    joints = ", ".join(f"{n} {math.degrees(a):+.1f}" for n, a in zip(JOINT_NAMES, pose))
    return joints + " deg"


def drive(
    limb: StartLimb,
    margins: SphereMargins,
    start: tuple[float, ...],
    target: tuple[float, ...],
    speed_deg_s: float,
    rate_hz: float,
    stop: threading.Event,
    read: Callable[[], tuple[float, ...]],
    settling: Callable[[tuple[float, ...]], object],
    stream: IO[str] | None = None,
    poll_hz: float = 10.0,
) -> str:
    """Drive the limb from ``start`` to ``target`` (rad) at ``speed_deg_s`` on a checked shortest
    path and read it at ``poll_hz`` until within :data:`SETTLE_DEG`; "" once settled, else why
    not."""
    gate, m = margins.gate, margins
    step = math.radians(speed_deg_s) / rate_hz
    here, goal = m.point(start), m.point(target)
    # never further outside than where the hand left it (plus the gate's own tolerance)
    worst_outside = m.outside_by(start) + gate.limits.region_tolerance
    pose = start
    if stream is not None:
        stream.write(
            f"approach: driving the limb {math.degrees(m.angle(here, goal)):.1f} deg at "
            f"{speed_deg_s:g} deg/s to {where(target)}\n"
        )
        stream.flush()
    limb.set_torque(True)
    while True:
        remaining = m.angle(here, goal)
        if remaining <= step:
            new = target
        else:
            new = m.pose_of(m.toward(here, goal, step), pose)
        if not m.within_limits(new):
            return "the path left the hard limits"
        if max(abs(a - b) for a, b in zip(new, pose, strict=True)) > gate.limits.max_joint_step:
            return "the path asked for a joint step above the limit (near the singularity)"
        if m.outside_by(new) > worst_outside:
            return "the path led further outside the taught region"
        if stop.is_set():
            return "stopped"
        limb.write_pose(*new)
        pose = new
        here = m.point(pose)
        if pose == target:
            break
        # a late cycle is not caught up: never faster than the approach speed
        stop.wait(1.0 / rate_hz)
    deadline = time.monotonic() + SETTLE_TIMEOUT_S
    while True:
        present = read()
        off = m.angle(m.point(present), goal)
        if math.degrees(off) <= SETTLE_DEG and gate.is_safe(*present):
            return ""
        if time.monotonic() >= deadline or stop.is_set():
            return (
                f"the limb did not reach the target within {SETTLE_TIMEOUT_S:.0f} s "
                f"({math.degrees(off):.1f} deg away: is something holding it?)"
            )
        settling(present)
        stop.wait(1.0 / poll_hz)


def park(
    limb: StartLimb, margins: SphereMargins, rate_hz: float, stop: threading.Event | None = None
) -> ParkOutcome:
    """After a clean session, drive the limb through the gate inside by the margin if the pose held
    is nearer the edge (else write it once more); bus errors end it in ``note``."""
    stop = stop or threading.Event()
    gate, m = margins.gate, margins
    pose = gate.safe_pose
    if pose is None:
        return ParkOutcome(False, None, note="the gate never started")
    if m.held_inside(m.held_pose(*pose)):
        # written once more: the session's last write may have failed, leaving an older goal
        try:
            limb.write_pose(*pose)
        except BusError as exc:
            return ParkOutcome(False, pose, note=f"could not write the last pose again: {exc}")
        return ParkOutcome(False, pose)
    target = m.nearest(pose)
    if target is None:
        return ParkOutcome(
            False, pose, note=f"no pose inside by {START_MARGIN_DEG} deg near the last one"
        )
    target_q = m.orientation(target)
    distance = m.angle(m.point(pose), m.point(target))
    # a few cycles more than the slew limit needs, for the joint-step limit near the poles
    cycles = math.ceil(distance / gate.limits.max_step) + 10
    for _ in range(cycles):
        result = gate.step(target_q)
        if result.outcome is Outcome.HELD:
            return ParkOutcome(False, pose, note=f"the gate held: {result.reason}")
        try:
            limb.write_pose(*result.pose)
        except BusError as exc:
            return ParkOutcome(False, gate.safe_pose, note=f"could not park: {exc}")
        if not result.slewed:
            return ParkOutcome(True, result.pose, math.degrees(distance))
        stop.wait(1.0 / rate_hz)  # a period between goals, late or not: never faster
    return ParkOutcome(False, gate.safe_pose, note="the gate did not reach the park pose")
