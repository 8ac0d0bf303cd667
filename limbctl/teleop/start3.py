"""Start and run a teleop session on a three-servo rig (pan, tilt, roll).

The two-servo session (:mod:`limbctl.teleop.lifecycle`) starts from a limb outside the region by
waiting for the hand or driving it in along a checked great circle, and parks it after. On three
servos this module starts by waiting only:

1. with torque off, the pose is read at ``poll_hz``; it is taken once the pose the servos would
   hold there (rounded to ticks) is safe for the gate (:meth:`Gate3.is_safe`) and stays safe
   with every joint moved by START_MARGIN_DEG either way, so the limb may still drift a little
   between that read and torque on;
2. that pose is written as the goal and torque goes on, so the servos hold the limb where the
   hand left it; the control loop then starts the gate from the pose it reads;
3. after ``wait_s`` without such a pose the session does not start (exit code 2).

A ``--approach`` is not offered on three servos: the path in from outside would need a search
over SO(3) that the two-servo approach does over directions; the session says so and waits. The
limb is not parked after the session.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

from limbctl.errors import BusError, SafetyError
from limbctl.geometry.gimbal3 import pose_quat_scalar
from limbctl.teleop.approach import StartOptions, StartOutcome
from limbctl.teleop.gate3 import Gate3
from limbctl.teleop.lifecycle import SessionResult
from limbctl.teleop.loop import LoopConfig, run
from limbctl.teleop.report import Telemetry, open_telemetry
from limbctl.teleop.sources import CommandSource

#: Each joint may be this far (deg) off the pose taken and the limb still be safe: as the
#: two-servo start margin (0.35 deg), room for the limb's drift between the read and torque on.
START_MARGIN_DEG = 0.35


def safe_with_margin(gate: Gate3, pose: tuple[float, float, float], margin: float) -> bool:
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


def _say(stream: IO[str] | None, text: str) -> None:
    if stream is not None:
        stream.write(text + "\n")
        stream.flush()


def start_three(
    rig: Any,
    gate: Gate3,
    options: StartOptions,
    stream: IO[str] | None = None,
    stop: threading.Event | None = None,
) -> StartOutcome:
    """Wait (torque off) until the limb rests safely inside, then hold it there (torque on)."""
    stop = stop or threading.Event()
    if options.approach_deg_s is not None:
        _say(stream, "an approach is not offered on a three-servo rig: waiting for the hand")
    margin = math.radians(START_MARGIN_DEG)
    # the region's kernels compile on their first call: here, not in the loop's first cycles
    gate.envelope.correct(pose_quat_scalar(math.pi / 2, 0.0, math.pi / 2))
    started = time.monotonic()
    failed, first = 0, True
    while True:
        waited = time.monotonic() - started
        if stop.is_set():
            return StartOutcome(False, "stopped", "stopped while waiting for the limb", waited, 130)
        if waited > options.wait_s:
            return StartOutcome(
                False,
                "timed out",
                f"the limb stayed outside the taught region (swing and twist) for "
                f"{options.wait_s:g} s; move it inside by hand and start again",
                waited,
                2,
            )
        try:
            held = rig.held_pose3(rig.read_pose())
        except BusError as exc:
            failed += 1
            if failed >= options.max_failed_reads:
                return StartOutcome(False, "bus failure", str(exc), waited, 3)
        else:
            failed = 0
            if safe_with_margin(gate, held, margin):
                rig.write_pose(*held)
                rig.set_torque(True)
                how = "inside" if first else "moved by hand"
                return StartOutcome(True, how, "", waited, 0)
            if first:
                _say(stream, "the limb is outside the taught region: waiting for it (torque off)")
            first = False
        stop.wait(1.0 / options.poll_hz)


def run_session_three(
    rig: Any,
    gate: Gate3,
    open_source: Callable[[], CommandSource],
    config: LoopConfig,
    starting: StartOptions,
    telemetry_path: str | Path | None = None,
    stream: IO[str] | None = None,
    status: IO[str] | None = None,
    stop: threading.Event | None = None,
) -> SessionResult:
    """Start (waiting), then open the command source with ``open_source()`` and run the control
    loop; the same value as the two-servo session, with no park (see the module docstring).

    The source opens only once the limb is held inside: a replayed stream paced by its ``"t"``
    then starts with the loop, instead of running on (and going stale) while the start waits.
    """
    stop = stop or threading.Event()
    telemetry_file = open_telemetry(telemetry_path)
    try:
        start = start_three(rig, gate, starting, stream, stop)
        if not start.started:
            return SessionResult(start)
        telemetry = Telemetry(telemetry_file) if telemetry_file is not None else None
        try:
            opened = open_source()
        except Exception:
            rig.set_torque(False)  # no source after all: leave the limb free, as before the start
            raise
        try:
            with opened as source:
                summary = run(rig, gate, source, config, telemetry, status, stop)  # type: ignore[arg-type]
        except SafetyError:
            rig.set_torque(False)  # the limb moved out as the loop began: leave it free
            raise
    finally:
        if telemetry_file is not None:
            telemetry_file.close()
    return SessionResult(start, summary, None)
