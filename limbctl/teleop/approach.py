"""Start a session from wherever the limb is; end one where the next session can start.

:func:`start_session` begins from the limb's present pose:

- inside the region and the hard limits (as :meth:`Gate.is_safe` judges): torque on, the gate
  starts there, at once;
- outside: torque stays off (switched off, saying so, if it was on) so the limb can be moved by
  hand. A :class:`~limbctl.teleop.margin.StartStatus` ("how far and which way") is published and
  printed at ``poll_hz``; the session starts by itself once the limb is inside by
  :data:`~limbctl.teleop.margin.START_MARGIN_DEG`, or gives up after ``wait_s`` with torque off;
- with ``approach_deg_s``: once the limb is inside the hard limits, the servos drive it to the
  nearest pose inside by the margin along a slow great-circle path in which every goal is
  checked (inside the hard limits, one joint step at most, never further outside the region
  than where it started), then the session starts there.

:func:`park` runs after a session: when the last gated pose, rounded to ticks, is not inside by
the margin (a session that ended on the region's edge), the gate drives it that far inside, so
the next start accepts the pose the servos hold.

Every outcome is a value (:class:`StartOutcome`, :class:`ParkOutcome`); no path leaves torque on
after refusing to start.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import IO, Protocol

import numpy as np

from limbctl.errors import BusError, ConfigError
from limbctl.geometry import scalar
from limbctl.teleop.gate import Gate, Outcome
from limbctl.teleop.margin import (
    START_MARGIN_DEG,
    StartStatus,
    assess,
    inside_by_margin,
    nearest_start_pose,
    outside_by,
    within_limits,
)

#: Default seconds a limb outside the region is waited for before the session gives up.
DEFAULT_WAIT_S = 60.0
#: Fastest approach (deg/s): the servos move a limb a person may still be holding; at 30 deg/s
#: a full 90 deg swing takes 3 s, time enough to see it coming and let go or grab it.
MAX_APPROACH_SPEED_DEG_S = 30.0
#: How close (deg) the present pose must come to the approach's target before it starts: a
#: holding servo sits within a couple of ticks (0.18 deg) of its goal; the start pose is then
#: still inside by START_MARGIN_DEG - SETTLE_DEG = 0.15 deg.
SETTLE_DEG = 0.2
#: Longest wait (s) for the limb to reach the approach's target once the last goal is written:
#: the servos' position loop settles in well under 0.5 s.
SETTLE_TIMEOUT_S = 3.0
#: Terminal refreshes: on a terminal every poll; to a log or pipe one line per this many s.
LOG_EVERY_S = 2.0


class StartLimb(Protocol):
    """What starting and parking need of a rig (see :class:`limbctl.servo.rig.Rig`)."""

    def read_pose(self) -> tuple[float, float]: ...

    def write_pose(self, pan: float, tilt: float) -> object: ...

    def set_torque(self, enabled: bool) -> None: ...

    def torque_enabled(self) -> tuple[bool, bool]: ...

    def held_pose(self, pan: float, tilt: float) -> tuple[float, float]: ...


@dataclass(frozen=True)
class StartOptions:
    """How a session starts from a limb outside the region.

    Attributes
    ----------
    wait_s : float
        Give up after this many seconds outside (s).
    approach_deg_s : float or None
        Drive the limb inside with the servos at this speed (deg/s); None: wait for the hand.
    rate_hz : float
        Goals per second along an approach path (the control loop's rate).
    poll_hz : float
        How often a waiting limb is read and its status published.
    max_failed_reads : int
        Consecutive failed reads of a waiting limb before the start gives up (bus failure).
    """

    wait_s: float = DEFAULT_WAIT_S
    approach_deg_s: float | None = None
    rate_hz: float = 200.0
    poll_hz: float = 10.0
    max_failed_reads: int = 20

    def __post_init__(self) -> None:
        if not (math.isfinite(self.wait_s) and self.wait_s > 0):
            raise ConfigError(f"--wait must be a positive number of seconds, got {self.wait_s}")
        speed = self.approach_deg_s
        if speed is not None and not (0 < speed <= MAX_APPROACH_SPEED_DEG_S):
            raise ConfigError(
                f"--approach must be above 0 and at most {MAX_APPROACH_SPEED_DEG_S:.0f} deg/s "
                f"(the servos move a limb a person may be holding), got {speed}"
            )
        if not (self.rate_hz > 0 and self.poll_hz > 0 and self.max_failed_reads >= 1):
            raise ConfigError("rate_hz and poll_hz must be positive, max_failed_reads >= 1")


@dataclass(frozen=True)
class StartOutcome:
    """How the start went; ``exit_code`` is what the command returns when it did not start.

    ``how`` is one of "inside", "moved by hand", "approached" (started), "timed out",
    "stopped", "bus failure" (not started; torque off).
    """

    started: bool
    how: str
    message: str
    waited_s: float
    exit_code: int
    status: StartStatus | None = None


@dataclass(frozen=True)
class ParkOutcome:
    """What :func:`park` did: ``moved`` by ``distance_deg`` to ``pose`` (rad, one angle a
    joint), or why not."""

    moved: bool
    pose: tuple[float, ...] | None
    distance_deg: float = 0.0
    note: str = ""


def _say(stream: IO[str] | None, text: str) -> None:
    if stream is not None:
        stream.write(text + "\n")
        stream.flush()


class _Waiter:
    """Reads the waiting limb, publishes its status and decides; one instance per start."""

    def __init__(
        self,
        limb: StartLimb,
        gate: Gate,
        options: StartOptions,
        stream: IO[str] | None,
        publish: Callable[[StartStatus], None] | None,
        stop: threading.Event,
    ) -> None:
        self.limb, self.gate, self.options = limb, gate, options
        self.stream, self.publish, self.stop = stream, publish, stop
        self.started_at = time.monotonic()
        self.tty = stream is not None and stream.isatty()
        self.last_line_at = -math.inf
        self.status: StartStatus | None = None

    @property
    def waited_s(self) -> float:
        return time.monotonic() - self.started_at

    def read(self) -> tuple[float, float]:
        """The present pose, retried; raises the last BusError after max_failed_reads."""
        for attempt in range(self.options.max_failed_reads):
            try:
                return self.limb.read_pose()
            except BusError:
                if attempt == self.options.max_failed_reads - 1:
                    raise
        raise RuntimeError("unreachable: max_failed_reads >= 1")

    def show(self, pose: tuple[float, float]) -> StartStatus:
        status = assess(self.gate, *pose, self.limb.held_pose, self.waited_s)
        self.status = status
        if self.publish is not None:
            self.publish(status)
        now = time.monotonic()
        if self.stream is not None and (self.tty or now - self.last_line_at >= LOG_EVERY_S):
            self.last_line_at = now
            end = "\x1b[K\r" if self.tty else "\n"
            self.stream.write(f"waiting {self.waited_s:5.1f} s  {status.line()}{end}")
            self.stream.flush()
        return status

    def outcome(self, started: bool, how: str, message: str, code: int) -> StartOutcome:
        if self.tty and self.status is not None:
            self.stream.write("\n")
        return StartOutcome(started, how, message, self.waited_s, code, self.status)


def start_session(
    limb: StartLimb,
    gate: Gate,
    options: StartOptions | None = None,
    stream: IO[str] | None = None,
    publish: Callable[[StartStatus], None] | None = None,
    stop: threading.Event | None = None,
    torque_was_on: bool = False,
) -> StartOutcome:
    """Start the gate from the limb's present pose, waiting for it (or approaching) if outside.

    Parameters
    ----------
    limb : StartLimb
        The configured rig (position mode, hard limits in EEPROM); torque on or off.
    gate : Gate
        Not yet started; on success it has started from the limb's present pose.
    options : StartOptions, optional
    stream : text stream, optional
        Where what happens and the live status line are written (e.g. stderr).
    publish : callable, optional
        Called with each :class:`StartStatus` while the limb is outside (e.g. a live view).
    stop : threading.Event, optional
        Set (Ctrl-C) to give up waiting.
    torque_was_on : bool
        Torque was on before the caller switched it off (e.g. to configure the servos): a limb
        outside is then told that torque went off, as if it had been found on.

    Returns
    -------
    StartOutcome
        On success torque is on and the gate started; otherwise torque is off (or the message
        says it could not be switched off) and ``exit_code`` is 2 (timed out), 130 (stopped)
        or 3 (bus failure).
    """
    options = options or StartOptions()
    stop = stop or threading.Event()
    waiter = _Waiter(limb, gate, options, stream, publish, stop)
    try:
        return _start(waiter, torque_was_on)
    except BusError as exc:
        where = f"servo {exc.servo_id}: " if exc.servo_id is not None else ""
        note = switch_torque_off(limb)
        return waiter.outcome(False, "bus failure", f"{where}{exc} before the start; {note}", 3)


def _start(waiter: _Waiter, torque_was_on: bool) -> StartOutcome:
    limb, gate, options = waiter.limb, waiter.gate, waiter.options
    pose = waiter.read()
    if gate.is_safe(*pose):
        limb.set_torque(True)
        return _begin(waiter, "inside")
    if any(limb.torque_enabled()):
        limb.set_torque(False)
        torque_was_on = True
    if torque_was_on:
        _say(waiter.stream, "the limb is outside: torque switched off so it can be moved by hand")
    approach = options.approach_deg_s
    period = 1.0 / options.poll_hz
    while True:
        status = waiter.show(pose)
        if status.ready:
            limb.set_torque(True)
            begun = _begin(waiter, "moved by hand")
            if begun.started:
                return begun
        elif approach is not None and status.inside_limits and status.target_pan_deg is not None:
            target = (math.radians(status.target_pan_deg), math.radians(status.target_tilt_deg))
            why = _drive(waiter, pose, target, approach)
            if not why:
                begun = _begin(waiter, "approached")
                if begun.started:
                    return begun
                why = begun.message
            limb.set_torque(False)
            _say(waiter.stream, f"approach stopped, torque off ({why}); move the limb by hand")
            approach = None
        if waiter.stop.is_set():
            return waiter.outcome(False, "stopped", "stopped while waiting; torque off", 130)
        if waiter.waited_s >= options.wait_s:
            return waiter.outcome(
                False,
                "timed out",
                f"the limb stayed outside for {options.wait_s:.0f} s ({status.line()}); torque is "
                "off: move it inside the taught region by hand and start again, or pass "
                "--approach DEG_S to let the servos drive it there",
                2,
            )
        waiter.stop.wait(period)
        pose = waiter.read()


def _begin(waiter: _Waiter, how: str) -> StartOutcome:
    """Torque is on: start the gate from the pose the servos now hold, if it is still safe."""
    pose = waiter.read()
    if not waiter.gate.is_safe(*pose):
        waiter.limb.set_torque(False)
        return waiter.outcome(False, how, "the limb left the region as torque came on", 2)
    waiter.gate.start(*pose)
    return waiter.outcome(True, how, "", 0)


def _drive(
    waiter: _Waiter, start: tuple[float, float], target: tuple[float, float], speed_deg_s: float
) -> str:
    """Drive the limb from ``start`` to ``target`` (rad) along a checked great circle.

    Returns an empty string once the limb settled at the target, else why it stopped (torque
    is then still on; the caller switches it off).
    """
    limb, gate, options = waiter.limb, waiter.gate, waiter.options
    step = math.radians(speed_deg_s) / options.rate_hz
    here, goal = scalar.direction(*start), scalar.direction(*target)
    # never further outside than where the hand left it (plus the gate's own tolerance)
    worst_outside = outside_by(gate, *start) + gate.limits.region_tolerance
    pan, tilt = start
    _say(
        waiter.stream,
        f"approach: driving the limb {math.degrees(scalar.angle(here, goal)):.1f} deg at "
        f"{speed_deg_s:g} deg/s to pan {math.degrees(target[0]):+.1f}, tilt "
        f"{math.degrees(target[1]):+.1f} deg",
    )
    limb.set_torque(True)
    while True:
        remaining = scalar.angle(here, goal)
        if remaining <= step:
            new_pan, new_tilt = target
        else:
            new_pan, new_tilt = scalar.pan_tilt(scalar.toward(here, goal, step), pan)
        if not within_limits(gate, new_pan, new_tilt):
            return "the path left the hard limits"
        if max(abs(new_pan - pan), abs(new_tilt - tilt)) > gate.limits.max_joint_step:
            return "the path asked for a joint step above the limit (near the singularity)"
        if outside_by(gate, new_pan, new_tilt) > worst_outside:
            return "the path led further outside the taught region"
        if waiter.stop.is_set():
            return "stopped"
        limb.write_pose(new_pan, new_tilt)
        pan, tilt = new_pan, new_tilt
        here = scalar.direction(pan, tilt)
        if (pan, tilt) == target:
            break
        # a late cycle is not caught up: goals stay a period apart, so the limb never moves
        # faster than the approach speed (a loaded machine makes it slower, never faster)
        waiter.stop.wait(1.0 / options.rate_hz)
    deadline = time.monotonic() + SETTLE_TIMEOUT_S
    while True:
        present = waiter.read()
        off = scalar.angle(scalar.direction(*present), goal)
        if math.degrees(off) <= SETTLE_DEG and gate.is_safe(*present):
            return ""
        if time.monotonic() >= deadline or waiter.stop.is_set():
            return (
                f"the limb did not reach the target within {SETTLE_TIMEOUT_S:.0f} s "
                f"({math.degrees(off):.1f} deg away: is something holding it?)"
            )
        waiter.show(present)
        waiter.stop.wait(1.0 / options.poll_hz)


def switch_torque_off(limb: StartLimb) -> str:
    """Switch torque off; what happened, in words (a bus error is reported, not raised)."""
    try:
        limb.set_torque(False)
    except BusError as exc:
        return f"could not switch torque off ({exc}); cut the servo power"
    return "torque switched off"


def park(
    limb: StartLimb, gate: Gate, rate_hz: float, stop: threading.Event | None = None
) -> ParkOutcome:
    """After a clean session, move the limb inside by the margin if it rests nearer the edge.

    The last pose the gate let through is rounded to ticks as the servos hold it; when that is
    not inside the region and the hard limits by :data:`START_MARGIN_DEG`, the gate itself
    drives the limb (slew-limited, corrected, checked) to the nearest pose that is, one goal
    per ``1 / rate_hz`` s; when it is, it is written once more (the session's last write may
    have failed). Bus errors end the park (reported in ``note``), never raise.
    """
    stop = stop or threading.Event()
    pose = gate.safe_pose
    if pose is None:
        return ParkOutcome(False, None, note="the gate never started")
    margin = math.radians(START_MARGIN_DEG)
    if inside_by_margin(gate, np.array([limb.held_pose(*pose)]), margin)[0]:
        # written once more: the session's last write may have failed, leaving an older goal
        try:
            limb.write_pose(*pose)
        except BusError as exc:
            return ParkOutcome(False, pose, note=f"could not write the last pose again: {exc}")
        return ParkOutcome(False, pose)
    target = nearest_start_pose(gate, *pose, margin, limb.held_pose)
    if target is None:
        return ParkOutcome(
            False, pose, note=f"no pose inside by {START_MARGIN_DEG} deg near the last one"
        )
    target_q = scalar.swing(scalar.direction(*target))
    distance = scalar.angle(scalar.direction(*pose), scalar.direction(*target))
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
