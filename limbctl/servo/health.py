"""Per-cycle servo health: silent, lost, torque off, alarm, or not following (docs/safety.md)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, fields

from limbctl.errors import ConfigError
from limbctl.servo.alarms import alarm_message
from limbctl.servo.control_table import TICKS_PER_REV
from limbctl.servo.cycle import CycleRead, ReadCycle, ServoReport, read_around_silent

DEG_PER_TICK = 360.0 / TICKS_PER_REV


@dataclass(frozen=True)
class HealthLimits:
    """When a servo's state becomes a fault.

    Attributes
    ----------
    lost_after_s, probe_interval_s : float
        A servo silent this long is lost (s): the budget for noticing a fault (issue 13); how often
        a silent servo is probed (s): one reply timeout (~12 ms) per interval.
    named_after_misses : int
        Missed reads in a row before a servo is named silent (the read already had two tries).
    max_tracking_error_deg, tracking_grace_s : float
        Largest |present - goal| of a following servo (deg; a healthy one lags <= 3.6 deg), and how
        long (s) the error may exceed it (a full-speed reversal takes 0.26 s).
    progress_window_s, min_progress_deg : float
        Span (s) over which a lagging servo's progress is measured (several ticks of motion); the
        progress per window (or per ``blocked_window_s``) that counts as following (deg).
    pwm_saturation, blocked_error_deg, blocked_window_s : float
        Fraction of PWM Limit at which the drive is saturated (healthy moves: <= 31 %); distance
        from its goal (deg, > 3.6) and time (s, 30 reads at 200 Hz) saturated without closing in
        that count as blocked.
    """

    lost_after_s: float = 0.5
    named_after_misses: int = 1
    probe_interval_s: float = 0.05
    max_tracking_error_deg: float = 15.0
    tracking_grace_s: float = 0.4
    progress_window_s: float = 0.1
    min_progress_deg: float = 1.0
    pwm_saturation: float = 0.9
    blocked_error_deg: float = 5.0
    blocked_window_s: float = 0.15

    def __post_init__(self) -> None:
        for name in (f.name for f in fields(self)):
            if not getattr(self, name) > 0:
                raise ConfigError(f"{name} must be > 0, got {getattr(self, name)!r}")
        if self.pwm_saturation > 1.0:
            raise ConfigError(
                f"pwm_saturation is a fraction of PWM Limit, got {self.pwm_saturation}"
            )


@dataclass(frozen=True)
class ServoFault:
    """Why the servos can no longer be driven: the servo, what kind, and the message."""

    servo_id: int
    kind: str  # "lost", "torque off", "alarm", "not following"
    message: str
    bits: tuple[str, ...] = ()


@dataclass(frozen=True)
class Dropout:
    """A servo that was silent and answered again (or still had not when the session ended)."""

    servo_id: int
    started_s: float
    duration_s: float
    ongoing: bool = False

    def describe(self) -> str:
        if self.ongoing:
            return (
                f"servo {self.servo_id} still silent when the session ended: "
                f"{self.duration_s:.3f} s so far"
            )
        return f"servo {self.servo_id} answered again after {self.duration_s:.3f} s silent"


@dataclass(frozen=True)
class Health:
    """The verdict on one cycle: notices to print, and a fault that ends driving (or None)."""

    notices: tuple[str, ...] = ()
    fault: ServoFault | None = None


@dataclass
class HealthMonitor:
    """Judges each cycle read; see the module docstring. ``now`` is a monotonic time in s."""

    limits: HealthLimits = field(default_factory=HealthLimits)
    silent_since: dict[int, float] = field(default_factory=dict)
    misses: dict[int, int] = field(default_factory=dict)
    # servo id -> when it was last asked (a failed read or a probe), while silent
    asked_at: dict[int, float] = field(default_factory=dict)
    # servo id -> [since when it lags without making way (s), window start (s), present then]
    lagging_since: dict[int, list[float]] = field(default_factory=dict)
    # servo id -> [since when it is saturated and off its goal (s), its error then (deg)]
    saturated_since: dict[int, list[float]] = field(default_factory=dict)
    dropouts: list[Dropout] = field(default_factory=list)
    probes: int = 0

    def silent(self) -> tuple[int, ...]:
        """The servos silent since their last read or probe."""
        return tuple(self.silent_since)

    def probes_due(self, now: float) -> tuple[int, ...]:
        """The silent servos to probe this cycle: every ``probe_interval_s``, and at lost."""
        due = tuple(
            servo_id
            for servo_id, since in self.silent_since.items()
            if now - self.asked_at[servo_id] >= self.limits.probe_interval_s
            or now - since >= self.limits.lost_after_s
        )
        self.probes += len(due)
        return due

    def read(self, read: ReadCycle, ids: Sequence[int], now: float, attempts: int) -> CycleRead:
        """This cycle's read of ``ids`` through ``read`` (``Rig.read_cycle``), around the silent."""
        silent = self.silent()
        if not silent:
            return read(attempts, ids)
        return read_around_silent(read, ids, silent, self.probes_due(now), attempts)

    def ongoing(self, now: float) -> list[Dropout]:
        """The dropouts of named silent servos still going on at ``now``."""
        return [
            Dropout(servo_id, since, now - since, ongoing=True)
            for servo_id, since in self.silent_since.items()
            if self.misses[servo_id] >= self.limits.named_after_misses
        ]

    def observe(self, read: CycleRead, now: float) -> Health:
        """The verdict on ``read``, taken at time ``now`` (s)."""
        notices: list[str] = []
        for servo_id in read.silent:
            self.silent_since.setdefault(servo_id, now)
            self.asked_at[servo_id] = now
            self.misses[servo_id] = self.misses.get(servo_id, 0) + 1
            if self.misses[servo_id] == self.limits.named_after_misses:
                notices.append(f"servo {servo_id} stopped answering; holding its last goal")
        for servo_id in list(self.silent_since):
            if servo_id in read.reports:
                started = self.silent_since.pop(servo_id)
                del self.asked_at[servo_id]
                if self.misses.pop(servo_id) >= self.limits.named_after_misses:
                    dropout = Dropout(servo_id, started, now - started)
                    self.dropouts.append(dropout)
                    notices.append(dropout.describe())
        fault = self._lost(read, now) or self._judge(read, now)
        return Health(tuple(notices), fault)

    def _lost(self, read: CycleRead, now: float) -> ServoFault | None:
        for servo_id in read.silent:
            since = self.silent_since[servo_id]
            if now - since >= self.limits.lost_after_s:
                return ServoFault(
                    servo_id,
                    "lost",
                    f"servo {servo_id} lost: no answer for {now - since:.3f} s: check its power "
                    f"supply and cable",
                )
        return None

    def _judge(self, read: CycleRead, now: float) -> ServoFault | None:
        found = {
            i: report.hardware_error for i, report in read.reports.items() if report.hardware_error
        }
        if found:
            servo_id, bits = next(iter(found.items()))
            return ServoFault(servo_id, "alarm", alarm_message(found), bits)
        for servo_id, report in read.reports.items():
            if not report.torque_on:
                return ServoFault(
                    servo_id,
                    "torque off",
                    f"servo {servo_id} reports torque off while it is being driven (switched "
                    f"off, or it restarted after a brown-out): the limb is not held",
                )
        for servo_id, report in read.reports.items():
            error_deg = abs(report.present - report.goal) * DEG_PER_TICK
            fault = self._blocked(servo_id, report, error_deg, now) or self._lagging(
                servo_id, report, error_deg, now
            )
            if fault is not None:
                return fault
        return None

    def _blocked(
        self, servo_id: int, report: ServoReport, error_deg: float, now: float
    ) -> ServoFault | None:
        """Saturated and off its goal for ``blocked_window_s`` without closing in: blocked."""
        limits = self.limits
        saturated = abs(report.pwm) >= limits.pwm_saturation * report.pwm_limit
        if not (saturated and error_deg > limits.blocked_error_deg):
            self.saturated_since.pop(servo_id, None)
            return None
        state = self.saturated_since.setdefault(servo_id, [now, error_deg])
        since, error_then = state
        if now - since < limits.blocked_window_s:
            return None
        if error_then - error_deg >= limits.min_progress_deg:
            state[:] = [now, error_deg]  # it is getting there: judged anew
            return None
        return ServoFault(
            servo_id,
            "not following",
            f"servo {servo_id} does not follow (blocked): {error_deg:.1f} deg from its goal with "
            f"its drive saturated (PWM {report.pwm} of {report.pwm_limit}) for {now - since:.2f} "
            f"s, not closing in: the limb is blocked or overloaded: free it, check the load",
        )

    def _lagging(
        self, servo_id: int, report: ServoReport, error_deg: float, now: float
    ) -> ServoFault | None:
        """Far from its goal for ``tracking_grace_s`` without making way toward it."""
        if error_deg <= self.limits.max_tracking_error_deg:
            self.lagging_since.pop(servo_id, None)
            return None
        lag = self.lagging_since.setdefault(servo_id, [now, now, report.present])
        since, window_start, present_then = lag
        if now - window_start >= self.limits.progress_window_s:
            toward = 1 if report.goal > report.present else -1
            progress_deg = (report.present - present_then) * toward * DEG_PER_TICK
            if progress_deg >= self.limits.min_progress_deg:
                since = now  # it is making way: following, judged anew
            lag[:] = [since, now, report.present]
        if now - since < self.limits.tracking_grace_s:
            return None
        return ServoFault(
            servo_id,
            "not following",
            f"servo {servo_id} does not follow: {error_deg:.1f} deg from its goal for "
            f"{now - since:.2f} s (limit {self.limits.max_tracking_error_deg:g} deg): "
            f"the limb is blocked or overloaded: free it, check the load",
        )
