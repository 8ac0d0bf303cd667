"""Guided, hand-held calibration: each joint's zero tick and direction, written to a profile."""

from __future__ import annotations

import dataclasses
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from calib.profile import RigProfile
from limbctl.errors import BusTimeout, ConfigError, CorruptReply, SafetyError

#: A joint moving less than this (ticks, about 0.35 deg) counts as still.
STILL_TICKS = 4
#: How long the limb must be still to take a reading (s).
STILL_S = 0.75
#: A deliberate move is at least this many ticks (about 13 deg).
MOVE_TICKS = 150
#: Sampling period while waiting (s).
PERIOD_S = 0.01
#: Failed reads in a row (half a second at ``PERIOD_S``) that mean a servo or cable is gone.
MAX_FAILED_READS = 50


class TickReader(Protocol):
    def read_ticks(self) -> tuple[int, int]: ...

    def set_torque(self, enabled: bool) -> None: ...


@dataclass(frozen=True)
class CalibrationResult:
    """Zero ticks and directions found."""

    pan_zero: int
    tilt_zero: int
    pan_direction: int
    tilt_direction: int
    roll_zero: int | None = None  # None: a two-servo rig
    roll_direction: int | None = None


def wait_still(
    reader: TickReader,
    accept: Callable[[tuple[int, int]], bool],
    timeout_s: float,
    stop: threading.Event,
) -> tuple[int, int]:
    """The mean ticks once the limb is still for ``STILL_S`` at a pose ``accept`` likes."""
    window: deque[tuple[float, tuple[int, int]]] = deque()
    deadline = time.monotonic() + timeout_s
    failed_in_a_row = 0
    while time.monotonic() < deadline and not stop.is_set():
        now = time.monotonic()
        try:
            ticks = reader.read_ticks()
        except (BusTimeout, CorruptReply) as exc:
            failed_in_a_row += 1
            if failed_in_a_row >= MAX_FAILED_READS:
                raise type(exc)(
                    f"calibration stopped, nothing was written: {MAX_FAILED_READS} reads in a "
                    f"row failed, the last: {exc}",
                    exc.servo_id,
                ) from exc
            stop.wait(PERIOD_S)
            continue
        failed_in_a_row = 0
        window.append((now, ticks))
        while window and now - window[0][0] > STILL_S:
            window.popleft()
        span_ok = now - window[0][0] >= STILL_S * 0.95
        if span_ok and accept(ticks):
            joints = list(zip(*(t[1] for t in window), strict=True))
            if all(max(j) - min(j) <= STILL_TICKS for j in joints):
                return tuple(round(sum(j) / len(j)) for j in joints)  # type: ignore[return-value]
        stop.wait(PERIOD_S)
    if stop.is_set():
        raise ConfigError("calibration interrupted; nothing was written")
    raise ConfigError(
        f"the limb was not held still at the asked pose within {timeout_s:.0f} s; "
        "run `limbctl calibrate` again and hold each pose for a second"
    )


def find_zero_and_directions(
    reader: TickReader,
    say: Callable[[str], None] = print,
    timeout_s: float = 60.0,
    stop: threading.Event | None = None,
) -> CalibrationResult:
    """Run the guided steps (torque off; four with a roll joint) and return what they found."""
    stop = stop or threading.Event()
    reader.set_torque(False)
    steps = 4 if len(getattr(reader, "joints", ())) == 3 else 3
    say(
        f"Torque is off. 1/{steps}: hold the limb straight ahead (along +x), level, and keep still."
    )
    rest = wait_still(reader, lambda t: True, timeout_s, stop)
    say(f"   rest ticks: pan {rest[0]}, tilt {rest[1]}")
    say(f"2/{steps}: turn the limb to the LEFT by 30-60 deg, keep it level, and hold still.")
    turned = wait_still(reader, lambda t: abs(t[0] - rest[0]) >= MOVE_TICKS, timeout_s, stop)
    if abs(turned[1] - rest[1]) > abs(turned[0] - rest[0]) / 3:
        raise ConfigError(
            "the tilt joint moved a lot while turning left; keep the limb level and run "
            "`limbctl calibrate` again"
        )
    say(f"   turned: pan {turned[0]} ticks")
    say(f"3/{steps}: bring it back straight ahead, then RAISE it by 20-45 deg and hold still.")
    raised = wait_still(
        reader,
        lambda t: abs(t[1] - rest[1]) >= MOVE_TICKS and abs(t[0] - rest[0]) <= MOVE_TICKS // 3,
        timeout_s,
        stop,
    )
    say(f"   raised: tilt {raised[1]} ticks")
    roll = {}
    if steps == 4:
        say(
            "4/4: bring it back straight ahead and level, then TURN it about its own axis by "
            "30-60 deg, right-handed (thumb along the limb, pointing out), and hold still."
        )
        turned_roll = wait_still(
            reader,
            lambda t: (
                abs(t[2] - rest[2]) >= MOVE_TICKS
                and max(abs(t[0] - rest[0]), abs(t[1] - rest[1])) <= MOVE_TICKS // 3
            ),
            timeout_s,
            stop,
        )
        say(f"   turned about its axis: roll {turned_roll[2]} ticks")
        roll = {"roll_zero": rest[2], "roll_direction": 1 if turned_roll[2] > rest[2] else -1}
    return CalibrationResult(
        pan_zero=rest[0],
        tilt_zero=rest[1],
        pan_direction=1 if turned[0] > rest[0] else -1,
        tilt_direction=1 if raised[1] > rest[1] else -1,
        **roll,
    )


def profile_from_calibration(
    base: RigProfile,
    result: CalibrationResult,
    name: str,
    port: str,
    pan_limits_deg: tuple[float, float],
    tilt_limits_deg: tuple[float, float],
) -> RigProfile:
    """``base`` (bus, end stops, roll limits) with the calibrated joints and limits (deg)."""
    for label, (lo, hi) in (("pan", pan_limits_deg), ("tilt", tilt_limits_deg)):
        if not lo < 0.0 < hi:
            raise SafetyError(f"{label} limits must contain the rest pose 0: got {lo}..{hi}")
    joints = {
        label: dataclasses.replace(
            joint,
            zero_tick=zero,
            direction=direction,
            min_deg=float(limits[0]),
            max_deg=float(limits[1]),
        )
        for label, joint, zero, direction, limits in (
            ("pan", base.pan, result.pan_zero, result.pan_direction, pan_limits_deg),
            ("tilt", base.tilt, result.tilt_zero, result.tilt_direction, tilt_limits_deg),
        )
    }
    if base.twists and result.roll_zero is not None and result.roll_direction is not None:
        joints["roll"] = dataclasses.replace(
            base.joints[-1][1], zero_tick=result.roll_zero, direction=result.roll_direction
        )
    return dataclasses.replace(base.with_joints(**joints), name=name, port=port, source=None)
