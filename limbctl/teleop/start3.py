"""Start and run a teleop session on a three-servo rig (pan, tilt, roll).

As the two-servo session (:mod:`limbctl.teleop.lifecycle`), on SO(3):

1. with torque off, the pose is read at ``poll_hz``; it is taken once the pose the servos would
   hold there (rounded to ticks) is inside by the margin
   (:func:`~limbctl.teleop.approach3.safe_with_margin`: safe for :meth:`Gate3.is_safe` with
   every joint moved by START_MARGIN_DEG either way), so the limb may still drift a little
   between that read and torque on;
2. with ``approach_deg_s`` and the limb inside the hard limits, the servos instead drive it to
   the nearest pose inside by the margin along the shortest rotation, every goal checked
   (:func:`~limbctl.teleop.approach3.drive3`); a refused or stopped approach switches torque
   off and waits for the hand;
3. that pose is written as the goal and torque goes on, so the servos hold the limb where it is;
   the control loop then starts the gate from the pose it reads;
4. after ``wait_s`` without such a pose the session does not start (exit code 2);
5. after a clean end the limb is parked inside by the margin
   (:func:`~limbctl.teleop.approach3.park3`), so the next session starts at once.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

from limbctl.errors import BusError, SafetyError
from limbctl.geometry.gimbal import pose_quat_scalar
from limbctl.teleop.approach import LOG_EVERY_S, StartOptions, StartOutcome, switch_torque_off
from limbctl.teleop.approach3 import StartStatus3, assess3, drive3, park3, safe_with_margin
from limbctl.teleop.gate3 import Gate3
from limbctl.teleop.lifecycle import SessionResult
from limbctl.teleop.loop import LoopConfig, run
from limbctl.teleop.margin import START_MARGIN_DEG
from limbctl.teleop.report import Telemetry, open_telemetry
from limbctl.teleop.sources import CommandSource


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
    publish: Callable[[StartStatus3], None] | None = None,
) -> StartOutcome:
    """Wait (torque off) until the limb rests safely inside, or drive it in with
    ``options.approach_deg_s``; then hold it there (torque on).

    While the limb is outside, its :class:`~limbctl.teleop.approach3.StartStatus3` (how far and
    which way) goes to ``publish`` every poll and to ``stream``: an updating line on a terminal,
    one line every LOG_EVERY_S s to a log or pipe."""
    lines: list[float] = []  # when a status line was written (an updating one on a terminal)
    outcome = _start_three(rig, gate, options, stream, stop or threading.Event(), publish, lines)
    if lines and stream is not None and stream.isatty():
        stream.write("\n")  # the updating line stays; what follows starts below it
    return outcome


def _start_three(
    rig: Any,
    gate: Gate3,
    options: StartOptions,
    stream: IO[str] | None,
    stop: threading.Event,
    publish: Callable[[StartStatus3], None] | None,
    lines: list[float],
) -> StartOutcome:
    approach = options.approach_deg_s
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
            held = rig.held_pose(*rig.read_pose())
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
            status = assess3(gate, held, lambda p: rig.held_pose(*p), waited, margin)
            _show(stream, status, lines)
            if publish is not None:
                publish(status)
            if approach is not None and gate.limits.inside(*held):
                target = (
                    None
                    if status.target is None
                    else rig.held_pose(*(math.radians(a) for a in status.target))
                )
                why = "no pose inside by the margin near the limb" if target is None else ""
                if target is not None:
                    try:
                        why = drive3(
                            rig, gate, held, target, approach, options.rate_hz, stop, stream
                        )
                    except BusError as exc:
                        note = switch_torque_off(rig)
                        waited = time.monotonic() - started
                        return StartOutcome(
                            False, "bus failure", f"{exc} during the approach; {note}", waited, 3
                        )
                    if not why:
                        rig.write_pose(*target)
                        return StartOutcome(True, "approached", "", time.monotonic() - started, 0)
                    rig.set_torque(False)
                _say(stream, f"approach stopped, torque off ({why}); move the limb by hand")
                approach = None
        stop.wait(1.0 / options.poll_hz)


def _show(stream: IO[str] | None, status: StartStatus3, lines: list[float]) -> None:
    """Write the status line (updating on a terminal, else every LOG_EVERY_S s); ``lines`` gets
    the time of each line written."""
    now = time.monotonic()
    if stream is None:
        return
    tty = stream.isatty()
    if tty or not lines or now - lines[-1] >= LOG_EVERY_S:
        stream.write(
            f"waiting {status.waited_s:5.1f} s  {status.line()}" + ("\x1b[K\r" if tty else "\n")
        )
        stream.flush()
        lines.append(now)


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
    publish: Callable[[StartStatus3], None] | None = None,
) -> SessionResult:
    """Start (waiting or approaching), then open the command source with ``open_source()``, run
    the control loop and park; the same value as the two-servo session.

    The source opens only once the limb is held inside: a replayed stream paced by its ``"t"``
    then starts with the loop, instead of running on (and going stale) while the start waits.
    """
    stop = stop or threading.Event()
    telemetry_file = open_telemetry(telemetry_path)
    try:
        start = start_three(rig, gate, starting, stream, stop, publish)
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
    parked = park3(rig, gate, config.rate_hz, stop) if summary.ended_by != "fault" else None
    return SessionResult(start, summary, parked)
