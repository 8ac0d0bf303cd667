"""Start a session from wherever the limb is; no refusal leaves torque on."""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import IO

from limbctl.errors import BusError, ConfigError
from limbctl.teleop.approach import JOINT_NAMES, StartLimb, drive
from limbctl.teleop.gate import Gate
from limbctl.teleop.margin import SphereMargins, margins_for

#: Default seconds a limb outside the region is waited for before the session gives up.
DEFAULT_WAIT_S = 60.0
#: Fastest approach (deg/s): a person may still hold the limb; 90 deg take 3 s to see coming.
MAX_APPROACH_SPEED_DEG_S = 30.0
#: Terminal refreshes: on a terminal every poll; to a log or pipe one line per this many s.
LOG_EVERY_S = 2.0


@dataclass(frozen=True)
class StartOptions:
    """How a session starts from a limb outside: it gives up after ``wait_s`` (s);
    ``approach_deg_s`` (deg/s; None: wait for the hand) drives it in at ``rate_hz`` goals a second;
    a waiting limb is read ``poll_hz`` times a second, ``max_failed_reads`` in a row end it."""

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


def status_line(
    where: str, ready: bool, inside_limits: bool, outside_deg: float | None, advice: str
) -> str:
    """A waiting limb's status line (``outside_deg`` None: inside the region)."""
    problems = []
    if not inside_limits:
        problems.append("beyond the rig's hard limits")
    if outside_deg is not None:
        problems.append(f"{outside_deg:.1f} deg outside the taught region")
    if not problems and not ready:
        problems.append("on the region's edge")
    state = "; ".join(problems) if problems else "ready"
    return f"limb at {where} ({state}): {advice}"


def _move_words(joint: int, change: float) -> str:
    """How to move ``joint`` (chain index) by ``change`` (deg), in words."""
    if joint == 0:
        return f"turn it {'left' if change > 0 else 'right'} {abs(change):.1f} deg"
    if joint == 1:
        return f"{'raise' if change > 0 else 'lower'} it {abs(change):.1f} deg"
    return f"roll it {change:+.1f} deg about its axis"


@dataclass(frozen=True)
class StartStatus:
    """Where a waiting limb is and where it must go before the session may start.

    Attributes
    ----------
    pose_deg, move_deg : tuple of float, (n,)
        The present pose, and the joint changes to the target (0 without one), deg in chain order.
    ready, inside_region, inside_limits : bool
        Inside the region and the hard limits by the margin; each check without the margin.
    outside_deg, distance_deg, waited_s : float
        How far outside the region (deg, 0 inside); angle to the target (deg); seconds waited.
    target_deg : tuple of float or None
        The nearest pose inside by the margin (deg); None when ready or none nearby.
    """

    pose_deg: tuple[float, ...]
    ready: bool
    inside_region: bool
    inside_limits: bool
    outside_deg: float
    distance_deg: float
    target_deg: tuple[float, ...] | None
    move_deg: tuple[float, ...]
    waited_s: float = 0.0

    def advice(self) -> str:
        """Which way to move the limb, in words."""
        if self.ready:
            return "inside the taught region: starting"
        if self.target_deg is None:
            return (
                "no pose far enough inside the taught region is near; move the limb toward "
                "the middle of what you taught"
            )
        moves = [_move_words(k, c) for k, c in enumerate(self.move_deg) if abs(c) >= 0.05]
        said = " and ".join(moves[-2:])
        said = ", ".join([*moves[:-2], said]) if said else "a hair"
        return f"move the limb {self.distance_deg:.1f} deg: " + said

    def line(self) -> str:
        """One status line: where the limb is, what is wrong, which way to move it."""
        where = ", ".join(f"{n} {a:+.1f} deg" for n, a in zip(JOINT_NAMES, self.pose_deg))
        outside = None if self.inside_region else self.outside_deg
        return status_line(where, self.ready, self.inside_limits, outside, self.advice())

    def as_dict(self) -> dict:
        """The status as plain JSON-ready values (for a live view or a log)."""
        return {"kind": "start", **asdict(self), "advice": self.advice()}


def assess(margins: SphereMargins, pose: tuple[float, ...], waited_s: float = 0.0) -> StartStatus:
    """The :class:`StartStatus` of a limb at ``pose`` (rad, as read from the servos)."""
    ready = margins.ready(pose)
    outside = margins.outside_by(pose)
    target = None if ready else margins.nearest(pose)
    distance, move = 0.0, (0.0,) * len(pose)
    if target is not None:
        distance = margins.angle(margins.point(pose), margins.point(target))
        move = tuple(t - p for t, p in zip(target, pose, strict=True))
    return StartStatus(
        pose_deg=tuple(math.degrees(a) for a in pose),
        ready=ready,
        inside_region=outside == 0.0,
        inside_limits=margins.within_limits(pose),
        outside_deg=math.degrees(outside),
        distance_deg=math.degrees(distance),
        target_deg=None if target is None else tuple(math.degrees(a) for a in target),
        move_deg=tuple(math.degrees(m) for m in move),
        waited_s=waited_s,
    )


@dataclass(frozen=True)
class StartOutcome:
    """How the start went (``how``: "inside", "moved by hand", "approached", "timed out", ...)."""

    started: bool
    how: str
    message: str
    waited_s: float
    exit_code: int
    status: StartStatus | None = None


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
        self.margins = margins_for(gate, limb)
        self.stream, self.publish, self.stop = stream, publish, stop
        self.started_at = time.monotonic()
        self.tty = stream is not None and stream.isatty()
        self.last_line_at = -math.inf
        self.status: StartStatus | None = None

    @property
    def waited_s(self) -> float:
        return time.monotonic() - self.started_at

    def read(self) -> tuple[float, ...]:
        """The present pose, retried; raises the last BusError after max_failed_reads."""
        for attempt in range(self.options.max_failed_reads):
            try:
                return self.limb.read_pose()
            except BusError:
                if attempt == self.options.max_failed_reads - 1:
                    raise
        raise RuntimeError("unreachable: max_failed_reads >= 1")

    def show(self, pose: tuple[float, ...]) -> StartStatus:
        status = assess(self.margins, pose, self.waited_s)
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

    ``gate`` (not yet started) is started from the present pose on success; ``stream`` gets the
    messages and live status line, ``publish`` each :class:`StartStatus` while outside; ``stop``
    (Ctrl-C) gives up; ``torque_was_on``: the caller switched torque off (said to a limb outside).
    Returns the outcome: started with torque on, or torque off and ``exit_code`` 2 (timed out),
    130 (stopped) or 3 (bus failure)."""
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
    waiter.margins.warm()
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
        elif approach is not None and status.inside_limits and status.target_deg is not None:
            target = tuple(math.radians(a) for a in status.target_deg)
            why = drive(
                limb, waiter.margins, pose, target, approach, options.rate_hz, waiter.stop,
                waiter.read, waiter.show, waiter.stream, options.poll_hz,
            )  # fmt: skip
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


def switch_torque_off(limb: StartLimb) -> str:
    """Switch torque off; what happened, in words (a bus error is reported, not raised)."""
    try:
        limb.set_torque(False)
    except BusError as exc:
        return f"could not switch torque off ({exc}); cut the servo power"
    return "torque switched off"
