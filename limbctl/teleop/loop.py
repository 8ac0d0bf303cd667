"""The teleoperation control loop: one sync read and one gated sync write per cycle."""

from __future__ import annotations

import enum
import math
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import IO, Protocol

import numpy as np

from limbctl.errors import BusError, ConfigError, ServoAlarm
from limbctl.geometry.gimbal import quat_to_pan_tilt
from limbctl.servo.alarms import alarm_alone, held_torque, switched_off
from limbctl.servo.cycle import CycleRead
from limbctl.servo.health import HealthLimits, HealthMonitor, ServoFault
from limbctl.teleop.approach import JOINT_NAMES, StartLimb
from limbctl.teleop.cycle import Cycle, CycleState, CycleTimings, TeleopSummary
from limbctl.teleop.gate import Gate, GateResult, Outcome
from limbctl.teleop.pacing import Pacer
from limbctl.teleop.report import Telemetry
from limbctl.teleop.sources import CommandSource
from limbctl.teleop.status import status_line_for


class SafeState(enum.Enum):
    """What the loop leaves the rig in after a fault."""

    HOLD = "hold"  # torque stays on; the last gated goal is kept
    TORQUE_OFF = "torque-off"  # torque is switched off; the limb goes limp


class Limb(StartLimb, Protocol):
    """What the loop needs of a rig (see :class:`limbctl.servo.rig.Rig`)."""

    @property
    def ids(self) -> tuple[int, ...]: ...

    def read_cycle(self, attempts: int = 1, ids: Sequence[int] | None = None) -> CycleRead: ...

    def pose_of(self, read: CycleRead) -> tuple[float, ...]: ...


@dataclass(frozen=True)
class LoopConfig:
    """Settings of the control loop.

    Attributes
    ----------
    rate_hz, silence_s : float
        Cycle rate (Hz; 200: 0.6 deg a cycle at 120 deg/s, real servos keep up, README); after this
        long (s) without a valid command the gate holds (0.5: a person sees a stall).
    max_failed_cycles, read_attempts : int
        Failed reads in a row, no silent servo named, before the safe state (20: 100 ms); tries of
        the cycle's read before the cycle holds (2 rides through one lost reply).
    health, safe_state : HealthLimits, SafeState
        When a silent servo is lost, how far and long a servo may lag; where a fault leaves the rig.
    duration_s, max_backlog : float or None, int
        Stop after this long (None: at the source's end or Ctrl-C); most commands of a scripted
        stream waiting to be gated (older skipped; 20: 100 ms).
    on_cycle : callable (Cycle) -> None, optional
        Called in the loop's thread with every cycle; must return at once (its exceptions
        propagate out of :func:`run`).
    """

    rate_hz: float = 200.0
    silence_s: float = 0.5
    max_failed_cycles: int = 20
    read_attempts: int = 2
    health: HealthLimits = HealthLimits()
    safe_state: SafeState = SafeState.HOLD
    duration_s: float | None = None
    max_backlog: int = 20
    on_cycle: Callable[[Cycle], None] | None = None

    def __post_init__(self) -> None:
        # below 1 Hz the slew limit per cycle gets coarse; above 2 kHz no bus keeps up
        if not (math.isfinite(self.rate_hz) and 1.0 <= self.rate_hz <= 2000.0):
            raise ConfigError(f"rate must be 1..2000 Hz, got {self.rate_hz}")
        if self.max_failed_cycles < 1:
            raise ConfigError("max_failed_cycles must be at least 1")
        if self.read_attempts < 1:
            raise ConfigError("read_attempts must be at least 1")


def _command_deg(q: np.ndarray) -> tuple[float, float]:
    pan, tilt = quat_to_pan_tilt(q)
    return math.degrees(float(pan)), math.degrees(float(tilt))


class ControlLoop:
    """The loop's state between cycles; each :meth:`step` is one cycle and returns its value.
    ``limb`` is connected, configured, torque on; ``gate`` not yet started (:meth:`start` starts it
    from the present pose); ``source`` started; ``stop`` set (a signal handler) ends the loop."""

    def __init__(
        self,
        limb: Limb,
        gate: Gate,
        source: CommandSource,
        config: LoopConfig,
        stop: threading.Event | None = None,
    ) -> None:
        self.limb, self.gate, self.source, self.config = limb, gate, source, config
        self.stop = stop or threading.Event()
        self.summary = TeleopSummary()
        self.period = 1.0 / config.rate_hz
        self.pacer = Pacer(self.period)
        self._last_error: BusError | None = None
        self.health = HealthMonitor(config.health)
        self._failed_in_a_row = 0
        # servo id -> Torque Enable as its latest read reported it (for the safe state's words)
        self._torque_seen: dict[int, bool] = {}
        self._dropouts_noted = False
        self._pending: deque = deque()
        self._target_q: np.ndarray | None = None
        self._target_deg: tuple[float, float] | None = None
        self._refused_reasons: tuple[str, ...] = ()
        self._started_at = self._last_command_at = 0.0

    def start(self) -> Cycle:
        """Read the start pose (``max_failed_cycles`` tries), start the gate: RUNNING or FAULT."""
        present: tuple[float, float] | None = None
        for _ in range(self.config.max_failed_cycles):
            try:
                present = self.limb.read_pose()
                break
            except ServoAlarm as exc:
                return self._fault(alarm_alone(exc), 0.0)
            except BusError as exc:
                self.summary.bus_errors += 1
                self._last_error = exc
        if present is None:
            attempts = self.config.max_failed_cycles
            cause = f"could not read the start pose {attempts} times: {self._last_error}"
            return self._fault(BusError(cause, self._last_error.servo_id), 0.0)
        self.gate.start(*present)
        self._started_at = self._last_command_at = time.perf_counter()
        self.pacer.start(self._started_at)
        return Cycle(index=0, t=0.0, state=CycleState.RUNNING, present=present)

    def step(self) -> Cycle:
        """One cycle: read, take the next command, gate, write; returns what happened."""
        summary, config = self.summary, self.config
        cycle_start = time.perf_counter()
        t = cycle_start - self._started_at
        if self.stop.is_set():
            return self._end("stopped", t)
        if config.duration_s is not None and t >= config.duration_s:
            return self._end("duration", t)

        # 1. present pose and health; a failed read holds (a write one servo misses is no gate pose)
        present: tuple[float, float] | None = None
        silent = False
        try:
            read = self.health.read(self.limb.read_cycle, self.limb.ids, t, config.read_attempts)
        except BusError as exc:  # the port itself failed
            read = CycleRead({}, (), str(exc))
            self._last_error = exc
        self._torque_seen.update((i, report.torque_on) for i, report in read.reports.items())
        verdict = self.health.observe(read, t)
        summary.notices.extend(f"{t:.3f} s: {notice}" for notice in verdict.notices)
        if verdict.fault is not None:
            return self._fault(_servo_error(verdict.fault), t, notices=verdict.notices)
        if read.ok:
            present = self.limb.pose_of(read)
        else:
            summary.bus_errors += 1
            missing = read.silent + read.unread
            silent = bool(missing)
            if self._last_error is None or str(self._last_error) != read.problem:
                self._last_error = BusError(read.problem, missing[0] if silent else None)

        # 2. next valid command
        self._take_command(cycle_start)

        # 3. gate
        gate_start = time.perf_counter()
        if self._target_q is None:
            result = self.gate.hold("source silent" if self._target_deg else "no command yet")
        elif present is None:
            result = self.gate.hold("the bus failed this cycle")
        else:
            result = self.gate.step(self._target_q)
        gate_s = time.perf_counter() - gate_start
        summary.gate_times_s.append(gate_s)
        summary.outcomes[result.outcome] += 1
        if cycle_start - self._last_command_at > config.silence_s:
            self._target_q = None  # a silent source: hold from here on

        # 4. write (only what the gate returned)
        written = False
        if result.outcome is not Outcome.HELD:
            try:
                self.limb.write_pose(*result.pose)
                written = True
                summary.wrote(result.pose)
            except ServoAlarm as exc:
                return self._fault(alarm_alone(exc), t, result)
            except BusError as exc:
                summary.bus_errors += 1
                self._last_error = exc
                present = None
        felt = self.source.feel(self.gate, result, present is not None)  # a felt leader's push
        summary.notices.extend(f"{t:.3f} s: {notice}" for notice in felt)
        if present is None:
            summary.failed_cycles += 1
            # a named silent servo is judged by the health monitor (lost_after_s)
            self._failed_in_a_row = 0 if silent else self._failed_in_a_row + 1
            if self._failed_in_a_row >= config.max_failed_cycles:
                cause = BusError(
                    f"the bus failed {self._failed_in_a_row} cycles in a row; last error: "
                    f"{self._last_error}",
                    getattr(self._last_error, "servo_id", None),
                )
                return self._fault(cause, t, result)
        else:
            self._failed_in_a_row = 0

        cycle_s = time.perf_counter() - cycle_start
        summary.cycle_times_s.append(cycle_s)
        summary.cycles += 1
        state, ended_by = CycleState.RUNNING, ""
        if self.source.finished and not self._pending and not result.slewed:
            # end of input: every command was gated and the last one reached (or held)
            state, ended_by = CycleState.FINISHED, "end of input"
            summary.ended_by = ended_by
        return Cycle(
            index=summary.cycles - 1,
            t=t,
            state=state,
            complete=True,
            command_deg=self._target_deg,
            command_q=summary.last_command_q,
            result=result,
            present=present,
            written=written,
            timings=CycleTimings(cycle_s=cycle_s, gate_s=gate_s),
            ended_by=ended_by,
            refused=summary.rejected,
            notices=verdict.notices + felt,
            refused_reasons=self._refused_reasons,
        )

    def pace(self) -> None:
        """Wait for the next slot (a felt leader watches its snap meanwhile)."""
        self.pacer.wait(self.stop, getattr(self.source, "idle_work", None))
        self.summary.overruns = self.pacer.overruns

    def finish(self) -> TeleopSummary:
        """The session's summary; exit code 2 when every line was refused (unless a fault)."""
        summary = self.summary
        if self._started_at:
            summary.elapsed_s = time.perf_counter() - self._started_at
        self._note_dropouts(summary.elapsed_s)
        summary.rejected = self.source.stats.rejected
        summary.refusal_lines = self.source.stats.refusals.lines()
        if summary.all_refused and summary.exit_code == 0:
            summary.exit_code = 2
        return summary

    def _note_dropouts(self, t: float) -> None:
        """The summary's dropouts: those that ended, then those still going on at ``t``."""
        if self._dropouts_noted:
            return
        self._dropouts_noted = True
        ongoing = self.health.ongoing(t)
        self.summary.dropouts = list(self.health.dropouts) + ongoing
        self.summary.notices.extend(f"{t:.3f} s: {dropout.describe()}" for dropout in ongoing)

    def _take_command(self, now: float) -> None:
        """Take the newest command (realtime sources) or the next of a bounded backlog."""
        commands = self.source.poll()
        if commands:
            self.summary.commands += len(commands)
            self._pending.extend(commands)
            keep = 1 if self.source.latest_only else self.config.max_backlog
            while len(self._pending) > keep:
                self._pending.popleft()
                self.summary.skipped += 1
        if self._pending:
            self._target_q = self.summary.last_command_q = self._pending.popleft().q
            self._target_deg = _command_deg(self._target_q)
            self._last_command_at = now
        self.summary.rejected = self.source.stats.rejected
        self._refused_reasons = tuple(self.source.stats.refusals.take_recent())

    def _end(self, ended_by: str, t: float) -> Cycle:
        self.source.release()  # a felt leader stops pushing when the session ends
        self.summary.ended_by = ended_by
        return self._last_cycle(CycleState.FINISHED, t, ended_by)

    def _last_cycle(self, state: CycleState, t: float, ended_by: str, **more) -> Cycle:
        return Cycle(
            index=self.summary.cycles,
            t=t,
            state=state,
            command_deg=self._target_deg,
            ended_by=ended_by,
            refused=self.summary.rejected,
            **more,
        )

    def _fault(
        self,
        cause: BusError,
        t: float,
        result: GateResult | None = None,
        notices: tuple[str, ...] = (),
    ) -> Cycle:
        self.source.release()  # a felt leader stops pushing before anything else
        _enter_safe_state(self.limb, self.config, self.summary, cause, self._torque_seen)
        self._note_dropouts(t)
        return self._last_cycle(
            CycleState.FAULT, t, "fault", result=result, fault=self.summary.fault, notices=notices
        )


def run(
    limb: Limb,
    gate: Gate,
    source: CommandSource,
    config: LoopConfig,
    telemetry: Telemetry | None = None,
    status: IO[str] | None = None,
    stop: threading.Event | None = None,
) -> TeleopSummary:
    """Run the loop until the source ends, the duration passes, ``stop`` is set, or a fault;
    ``telemetry`` logs every complete cycle, ``status`` (e.g. stderr) gets a one-line status; the
    summary's ``exit_code`` is 0 for a clean end, 3 for a fault."""
    loop = ControlLoop(limb, gate, source, config, stop)
    cycle = loop.start()
    if config.on_cycle is not None:
        config.on_cycle(cycle)
    if cycle.state is not CycleState.RUNNING:
        return loop.finish()
    status_line = status_line_for(status, source) if status is not None else None
    while True:
        cycle = loop.step()
        if status is not None:
            lead = "\n" if status.isatty() else ""  # below the line refreshed in place
            for notice in cycle.notices:
                status.write(f"{lead}{cycle.t:.3f} s: {notice}\n")
        if cycle.complete:
            if telemetry is not None:
                telemetry.write(cycle)
            if status_line is not None:
                status_line.update(cycle, loop.summary)
        if config.on_cycle is not None:
            config.on_cycle(cycle)
        if cycle.state is not CycleState.RUNNING:
            break
        loop.pace()
    summary = loop.finish()
    if status_line is not None:
        status_line.close(summary)
    return summary


def _servo_error(fault: ServoFault) -> BusError:
    """The typed error for a fault the health monitor found."""
    if fault.kind == "alarm":
        return ServoAlarm(fault.message, fault.servo_id, fault.bits)
    return BusError(fault.message, fault.servo_id)


def _enter_safe_state(
    limb: Limb,
    config: LoopConfig,
    summary: TeleopSummary,
    cause: BusError,
    torque_seen: dict[int, bool],
) -> None:
    """Apply ``config.safe_state`` and say what it left (``torque_seen``: last read per id)."""
    named = cause.servo_id is not None and not str(cause).startswith(f"servo {cause.servo_id}")
    where = f"servo {cause.servo_id}: " if named else ""
    summary.fault = f"{where}{cause}"
    summary.ended_by = "fault"
    summary.exit_code = 3
    names = dict(zip(limb.ids, JOINT_NAMES[: len(limb.ids)], strict=True))
    if config.safe_state is SafeState.TORQUE_OFF:
        try:
            limb.set_torque(False)
            reported = {name: torque_seen.get(i) for i, name in names.items()}
            summary.fault += " — " + switched_off(reported)
        except BusError as exc:
            summary.fault += f" — could not switch torque off ({exc}); cut the servo power"
    else:
        summary.fault += " — " + _hold_state(limb, isinstance(cause, ServoAlarm))


def _hold_state(limb: Limb, after_alarm: bool) -> str:
    """What HOLD really left: torque as the servos report it (an alarm may have cut it)."""
    try:
        torque = limb.torque_enabled()
    except BusError as exc:
        return (
            f"torque state unknown (cannot read it: {exc}); each servo keeps the last goal the "
            "gate gave it unless its firmware shut it down; cut the servo power if the limb "
            "must not move"
        )
    return held_torque(dict(zip(JOINT_NAMES[: len(torque)], torque, strict=True)), after_alarm)
