"""Per-cycle health of the servos, judged from each :class:`limbctl.servo.cycle.CycleRead`.

:class:`HealthMonitor` is fed one cycle read per control cycle and answers, as a value, what to
say and whether to stop (docs/safety.md's fault table gives the figures):

- a servo missing ``named_after_misses`` reads in a row is named, and named again with its
  dropout's length when it answers; while silent it is probed every ``probe_interval_s``
  (:meth:`HealthMonitor.probes_due`) and lost (a fault) once silent for ``lost_after_s``;
- Torque Enable reading 0 on a driven servo (switched off, or restarted after a brown-out): a
  fault; so is a hardware error (alarm), naming every servo in alarm;
- a servo that does not follow: *blocked* (drive saturated for ``blocked_window_s`` while
  more than ``blocked_error_deg`` off its goal and not closing in by ``min_progress_deg``),
  or the backstop for one that fails without saturating (further than
  ``max_tracking_error_deg`` for ``tracking_grace_s`` with no ``progress_window_s`` of
  progress toward its goal).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from limbctl.errors import ConfigError
from limbctl.servo.alarms import alarm_message
from limbctl.servo.control_table import TICKS_PER_REV
from limbctl.servo.cycle import CycleRead, ReadCycle, ServoReport, read_around_silent

#: Degrees per encoder tick.
DEG_PER_TICK = 360.0 / TICKS_PER_REV


@dataclass(frozen=True)
class HealthLimits:
    """When a servo's state becomes a fault.

    Attributes
    ----------
    lost_after_s : float
        A servo silent this long is lost (s); the loop holds meanwhile.
    named_after_misses : int
        Reads in a row a servo must miss to be named as silent.
    probe_interval_s : float
        How often a silent servo is asked (one try) whether it is back (s).
    max_tracking_error_deg : float
        Largest |present - goal| of a servo that follows (deg).
    tracking_grace_s : float
        How long the error may exceed the bound before the servo is said not to follow (s).
    progress_window_s : float
        The span over which a lagging servo's progress toward its goal is measured (s).
    min_progress_deg : float
        How far toward its goal a lagging servo must move in one window to be following, and
        how much closer a saturated one must get in ``blocked_window_s`` not to be blocked.
    pwm_saturation : float
        The fraction of its PWM Limit at which a servo's drive counts as saturated.
    blocked_error_deg : float
        How far from its goal a saturated servo must be to count as blocked (deg).
    blocked_window_s : float
        How long a servo must stay saturated and off its goal without closing in (s).
    """

    # the limb may be held blind this long: the time budget for noticing a fault (issue 13)
    lost_after_s: float = 0.5
    # the loop's read already had two tries: naming at the first failed read keeps naming within
    # 100 ms even at the FTDI default latency timer (2 tries x ~35 ms)
    named_after_misses: int = 1
    # a dropout's length is known to within this, and a probe costs one reply timeout per
    # interval (~12 ms of every 50 on the simulator's pty, ~4 ms on a U2D2 at a 1 ms latency timer)
    probe_interval_s: float = 0.05
    # a healthy servo lags its goal by at most 3.6 deg at the 120 deg/s slew limit (measured,
    # docs/bench_faults.md); a torque-less or blocked limb is off by tens of degrees
    max_tracking_error_deg: float = 15.0
    # a servo reversing at full speed decelerates away from its goal for 0.26 s (275 deg/s at
    # 1073 deg/s^2, the set-up's profile) before it can make way toward it; 0.4 s stays under
    # the 0.5 s budget for noticing a fault
    tracking_grace_s: float = 0.4
    # short enough to see the turn within the grace, long enough for several ticks of motion
    progress_window_s: float = 0.1
    # 10 deg/s toward the goal: a servo at a twentieth of its profile velocity is following;
    # a blocked or limp one makes no way toward its goal, or moves away from it
    min_progress_deg: float = 1.0
    # the position controller's drive is clipped at PWM Limit: a servo that cannot reach its
    # goal winds up to it; healthy moves stay far below (simulator <= 31 %, docs/bench_faults.md;
    # 120 deg/s is a third of an XL430's no-load speed), 10 % is left for a noisy reading
    pwm_saturation: float = 0.9
    # above the 3.6 deg a healthy servo lags by, so a saturated but following servo is not blocked
    blocked_error_deg: float = 5.0
    # 30 reads at 200 Hz: a saturated start toward a far goal closes in within it; with the
    # read and the safe state it leaves 0.3 s of the 0.5 s budget
    blocked_window_s: float = 0.15

    def __post_init__(self) -> None:
        for name in (
            "lost_after_s",
            "named_after_misses",
            "probe_interval_s",
            "max_tracking_error_deg",
            "tracking_grace_s",
            "progress_window_s",
            "min_progress_deg",
            "pwm_saturation",
            "blocked_error_deg",
            "blocked_window_s",
        ):
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
        """The silent servos to probe this cycle: each once every ``probe_interval_s``, and any
        whose silence reached ``lost_after_s`` (it is lost only if that probe fails too)."""
        due = tuple(
            servo_id
            for servo_id, since in self.silent_since.items()
            if now - self.asked_at[servo_id] >= self.limits.probe_interval_s
            or now - since >= self.limits.lost_after_s
        )
        self.probes += len(due)
        return due

    def read(self, read: ReadCycle, ids: Sequence[int], now: float, attempts: int) -> CycleRead:
        """This cycle's read through ``read`` (``Rig.read_cycle``) of the servos ``ids``: all of
        them, or, while some are silent, the others and the silent ones whose probe is due."""
        silent = self.silent()
        if not silent:
            return read(attempts, ids)
        return read_around_silent(read, ids, silent, self.probes_due(now), attempts)

    def ongoing(self, now: float) -> list[Dropout]:
        """The dropouts still going on at ``now``: each named silent servo, its length so far."""
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
        # saturated: |Present PWM| >= pwm_saturation x PWM Limit
        saturated = abs(report.pwm) >= limits.pwm_saturation * report.pwm_limit
        if not (saturated and error_deg > limits.blocked_error_deg):
            self.saturated_since.pop(servo_id, None)
            return None
        state = self.saturated_since.setdefault(servo_id, [now, error_deg])
        since, error_then = state
        if now - since < limits.blocked_window_s:
            return None
        # closing in = how much nearer its goal it got over the window
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
            # progress = how far it moved over the window, signed toward its goal now
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
