"""The teleoperation control loop: fixed rate, one read and one gated write per cycle.

Each cycle (default 200 Hz):

1. read both present positions (one sync read; retried within the cycle budget);
2. take the newest valid command from the source (bad lines were already refused and counted);
3. the gate turns it into a safe pose (correct, slew limit, IK, hard limits, final check);
4. write both goals (one sync write) — only ever a pose the gate returned;
5. log telemetry and pace to the next period.

A silent source holds the last safe pose. A cycle whose read fails writes nothing (a servo
that is not answering would miss the sync write and leave a pose the gate never produced).
Bus failures are retried; after
``max_failed_cycles`` consecutive failed cycles, or on a servo alarm, the loop ends in the
configured safe state (hold: torque stays on at the last goal; torque-off) with a message naming
the servo and the cause. The loop's outcome is a value (:class:`TeleopSummary`), after ruckig.
"""

from __future__ import annotations

import enum
import json
import math
import threading
import time
from collections import Counter, deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Protocol

import numpy as np

from limbctl.errors import BusError, ConfigError, ServoAlarm
from limbctl.teleop.gate import Gate, GateResult, Outcome
from limbctl.teleop.sources import CommandSource

#: Cycle and gate times kept for the summary's percentiles (the most recent ones).
TIMING_WINDOW = 100_000


class SafeState(enum.Enum):
    """What the loop leaves the rig in after a fault."""

    HOLD = "hold"  # torque stays on; the last gated goal is kept
    TORQUE_OFF = "torque-off"  # torque is switched off; the limb goes limp


class Limb(Protocol):
    """What the loop needs of a rig (see :class:`limbctl.servo.rig.Rig`)."""

    def read_pose(self) -> tuple[float, float]: ...

    def write_pose(self, pan: float, tilt: float) -> object: ...

    def set_torque(self, enabled: bool) -> None: ...

    def torque_enabled(self) -> tuple[bool, bool]: ...


@dataclass(frozen=True)
class LoopConfig:
    """Settings of the control loop.

    Attributes
    ----------
    rate_hz : float
        Cycle rate (Hz).
    silence_s : float
        After this long without a valid command the status says "holding" (the pose is held
        from the first silent cycle on; this only labels it).
    max_failed_cycles : int
        Consecutive cycles whose bus transfer failed before the safe state is entered.
    safe_state : SafeState
        Where a fault leaves the rig.
    duration_s : float or None
        Stop after this long (None: until the source ends or Ctrl-C).
    max_backlog : int
        Most commands of a scripted stream waiting to be gated; older ones are skipped.
    """

    rate_hz: float = 200.0
    silence_s: float = 0.5
    max_failed_cycles: int = 20
    safe_state: SafeState = SafeState.HOLD
    duration_s: float | None = None
    max_backlog: int = 20

    def __post_init__(self) -> None:
        if not (math.isfinite(self.rate_hz) and 1.0 <= self.rate_hz <= 2000.0):
            raise ConfigError(f"rate must be 1..2000 Hz, got {self.rate_hz}")
        if self.max_failed_cycles < 1:
            raise ConfigError("max_failed_cycles must be at least 1")


@dataclass
class TeleopSummary:
    """How a teleop session went; ``exit_code`` is what the CLI returns."""

    cycles: int = 0
    goals_written: int = 0
    outcomes: Counter = field(default_factory=Counter)
    commands: int = 0
    skipped: int = 0
    rejected: int = 0
    bus_errors: int = 0
    failed_cycles: int = 0
    overruns: int = 0
    # the latest TIMING_WINDOW cycles only: a session of hours must not grow without bound
    cycle_times_s: deque = field(default_factory=lambda: deque(maxlen=TIMING_WINDOW))
    gate_times_s: deque = field(default_factory=lambda: deque(maxlen=TIMING_WINDOW))
    ended_by: str = ""
    fault: str = ""
    exit_code: int = 0
    elapsed_s: float = 0.0

    @property
    def rate_hz(self) -> float:
        return self.cycles / self.elapsed_s if self.elapsed_s > 0 else 0.0

    def percentile_ms(self, p: float, gate: bool = False) -> float:
        values = self.gate_times_s if gate else self.cycle_times_s
        return 1e3 * float(np.percentile(values, p)) if values else float("nan")

    def lines(self) -> list[str]:
        outcome = ", ".join(f"{o.value} {n}" for o, n in sorted(self.outcomes.items(), key=str))
        return [
            f"ended by           {self.ended_by}" + (f": {self.fault}" if self.fault else ""),
            f"cycles             {self.cycles} in {self.elapsed_s:.1f} s ({self.rate_hz:.1f} Hz)",
            f"cycle time         p50 {self.percentile_ms(50):.2f} ms, "
            f"p99 {self.percentile_ms(99):.2f} ms, overruns {self.overruns}",
            f"gate time          p50 {self.percentile_ms(50, True):.3f} ms, "
            f"p99 {self.percentile_ms(99, True):.3f} ms",
            f"commands           {self.commands} accepted ({self.skipped} skipped as stale), "
            f"{self.rejected} refused",
            f"gate outcomes      {outcome or 'none'}",
            f"goals written      {self.goals_written}",
            f"bus errors         {self.bus_errors} ({self.failed_cycles} cycles lost)",
        ]


class Telemetry:
    """One JSON line per cycle: command, gated pose, written goal and present pose (degrees)."""

    def __init__(self, stream: IO[str]) -> None:
        self._stream = stream

    def write(
        self,
        t: float,
        command_deg: tuple[float, float] | None,
        result: GateResult | None,
        present_rad: tuple[float, float] | None,
        written: bool,
        cycle_s: float,
    ) -> None:
        row = {
            "t": round(t, 6),
            "cmd": None if command_deg is None else [round(v, 4) for v in command_deg],
            "out": None
            if result is None
            else [round(math.degrees(result.pan), 4), round(math.degrees(result.tilt), 4)],
            "outcome": None if result is None else result.outcome.value,
            "written": written,
            "present": None
            if present_rad is None
            else [round(math.degrees(v), 4) for v in present_rad],
            "cycle_ms": round(1e3 * cycle_s, 3),
        }
        self._stream.write(json.dumps(row) + "\n")


def _command_deg(q: np.ndarray) -> tuple[float, float]:
    from limbctl.geometry.gimbal import quat_to_pan_tilt

    pan, tilt = quat_to_pan_tilt(q)
    return math.degrees(float(pan)), math.degrees(float(tilt))


def run(
    limb: Limb,
    gate: Gate,
    source: CommandSource,
    config: LoopConfig,
    telemetry: Telemetry | None = None,
    status: IO[str] | None = None,
    stop: threading.Event | None = None,
) -> TeleopSummary:
    """Run the loop until the source ends, the duration passes, ``stop`` is set, or a fault.

    Parameters
    ----------
    limb : Limb
        The rig (already connected, configured, torque on).
    gate : Gate
        Not yet started; it starts from the limb's present pose.
    source : CommandSource
        Started command source.
    config : LoopConfig
    telemetry : Telemetry, optional
    status : text stream, optional
        Where a one-line status is refreshed twice a second (e.g. stderr).
    stop : threading.Event, optional
        Set from a signal handler to end the loop cleanly.

    Returns
    -------
    TeleopSummary
        ``exit_code`` 0 for a clean end (source ended, duration, stop), 3 for a fault.
    """
    summary = TeleopSummary()
    period = 1.0 / config.rate_hz
    stop = stop or threading.Event()

    # the start pose, read with the same patience as a running loop (a dropped reply is normal)
    present: tuple[float, float] | None = None
    last_error: BusError | None = None
    for _ in range(config.max_failed_cycles):
        try:
            present = limb.read_pose()
            break
        except ServoAlarm as exc:
            _enter_safe_state(limb, config, summary, exc)
            return summary
        except BusError as exc:
            summary.bus_errors += 1
            last_error = exc
    if present is None:
        cause = f"could not read the start pose {config.max_failed_cycles} times: {last_error}"
        _enter_safe_state(limb, config, summary, BusError(cause, last_error.servo_id))
        return summary
    gate.start(*present)

    start = time.perf_counter()
    next_tick = start
    last_command_at = start
    last_status = start
    status_every = 0.5 if status is not None and status.isatty() else 5.0
    failed_in_a_row = 0
    target_q: np.ndarray | None = None
    pending: deque = deque()
    target_deg: tuple[float, float] | None = None

    while True:
        cycle_start = time.perf_counter()
        elapsed = cycle_start - start
        if stop.is_set():
            summary.ended_by = "stopped"
            break
        if config.duration_s is not None and elapsed >= config.duration_s:
            summary.ended_by = "duration"
            break

        # 1. present pose; a failed read means a servo may not be listening: this cycle holds
        # (a sync write that one servo misses would leave a pose the gate never produced)
        present_now: tuple[float, float] | None = None
        try:
            present_now = limb.read_pose()
        except ServoAlarm as exc:
            _enter_safe_state(limb, config, summary, exc)
            break
        except BusError as exc:
            summary.bus_errors += 1
            last_error = exc

        # 2. next valid command: realtime sources (UDP, keyboard, leader) keep only the newest;
        # scripted streams (stdin, replay) are gated in order, one per cycle, with a bounded
        # backlog so a fast producer cannot build up latency
        commands = source.poll()
        if commands:
            summary.commands += len(commands)
            pending.extend(commands)
            keep = 1 if source.latest_only else config.max_backlog
            while len(pending) > keep:
                pending.popleft()
                summary.skipped += 1
        if pending:
            target_q = pending.popleft().q
            target_deg = _command_deg(target_q)
            last_command_at = cycle_start
        summary.rejected = source.stats.rejected

        # 3. gate
        gate_start = time.perf_counter()
        if target_q is None:
            result = gate.hold("no command yet")
        elif present_now is None:
            result = gate.hold("the bus failed this cycle")
        else:
            result = gate.step(target_q)
        summary.gate_times_s.append(time.perf_counter() - gate_start)
        summary.outcomes[result.outcome] += 1
        if cycle_start - last_command_at > config.silence_s:
            target_q = None  # a silent source: hold from here on

        # 4. write (only what the gate returned)
        written = False
        if result.outcome is not Outcome.HELD:
            try:
                limb.write_pose(result.pan, result.tilt)
                written = True
                summary.goals_written += 1
            except ServoAlarm as exc:
                _enter_safe_state(limb, config, summary, exc)
                break
            except BusError as exc:
                summary.bus_errors += 1
                last_error = exc
                present_now = None
        if present_now is None:
            failed_in_a_row += 1
            summary.failed_cycles += 1
            if failed_in_a_row >= config.max_failed_cycles:
                _enter_safe_state(
                    limb,
                    config,
                    summary,
                    BusError(
                        f"the bus failed {failed_in_a_row} cycles in a row; last error: "
                        f"{last_error}",
                        getattr(last_error, "servo_id", None),
                    ),
                )
                break
        else:
            failed_in_a_row = 0

        cycle_s = time.perf_counter() - cycle_start
        summary.cycle_times_s.append(cycle_s)
        summary.cycles += 1
        if telemetry is not None:
            telemetry.write(elapsed, target_deg, result, present_now, written, cycle_s)
        if status is not None and cycle_start - last_status >= status_every:
            last_status = cycle_start
            _print_status(status, summary, elapsed)

        if source.finished and not pending and not result.slewed:
            # end of input: every command was gated and the last one reached (or held)
            summary.ended_by = "end of input"
            break

        # 5. pace: wait for the next period; if late by a whole period, start afresh
        next_tick += period
        delay = next_tick - time.perf_counter()
        if delay > 0:
            stop.wait(delay)
        elif delay < -period:
            summary.overruns += 1
            next_tick = time.perf_counter()

    summary.elapsed_s = time.perf_counter() - start
    if status is not None:
        _print_status(status, summary, summary.elapsed_s)
        if status.isatty():
            status.write("\n")
    return summary


def _enter_safe_state(
    limb: Limb, config: LoopConfig, summary: TeleopSummary, cause: BusError
) -> None:
    where = f"servo {cause.servo_id}: " if cause.servo_id is not None else ""
    summary.fault = f"{where}{cause}"
    summary.ended_by = "fault"
    summary.exit_code = 3
    if config.safe_state is SafeState.TORQUE_OFF:
        try:
            limb.set_torque(False)
            summary.fault += " — torque switched off"
        except BusError as exc:
            summary.fault += f" — could not switch torque off ({exc}); cut the servo power"
    else:
        summary.fault += " — " + _hold_state(limb)


def _hold_state(limb: Limb) -> str:
    """What HOLD really left: torque as the servos report it (an alarm may have cut it)."""
    try:
        torque = limb.torque_enabled()
    except BusError as exc:
        return (
            f"torque state unknown (cannot read it: {exc}); each servo keeps the last goal the "
            "gate gave it unless its firmware shut it down; cut the servo power if the limb "
            "must not move"
        )
    if all(torque):
        return "holding the last safe pose (torque on)"
    off = [name for name, on in zip(("pan", "tilt"), torque, strict=True) if not on]
    on = [name for name, on in zip(("pan", "tilt"), torque, strict=True) if on]
    held = f"; {' and '.join(on)} holding the last safe pose (torque on)" if on else ""
    return (
        f"{' and '.join(off)} torque off (shut down by the servo's firmware: reboot it once the "
        f"cause is fixed){held}"
    )


def _print_status(stream: IO[str], summary: TeleopSummary, elapsed: float) -> None:
    n = max(1, sum(summary.outcomes.values()))
    share = {o: 100.0 * summary.outcomes[o] / n for o in Outcome}
    rate = summary.cycles / elapsed if elapsed > 0 else 0.0
    stream.write(
        ("\r" if stream.isatty() else "")
        + f"{elapsed:7.1f} s  {rate:6.1f} Hz  pass {share[Outcome.PASSED]:5.1f}%  "
        f"corr {share[Outcome.CORRECTED]:5.1f}%  clamp {share[Outcome.CLAMPED]:4.1f}%  "
        f"held {share[Outcome.HELD]:5.1f}%  refused {summary.rejected}  "
        f"bus errors {summary.bus_errors}   " + ("" if stream.isatty() else "\n")
    )
    stream.flush()


def open_telemetry(path: str | Path | None) -> IO[str] | None:
    """Open a telemetry file for line-buffered writing (None: no telemetry)."""
    if path is None:
        return None
    return open(path, "w", buffering=1, encoding="utf-8")
