"""HealthMonitor's verdicts on cycle reads (values in, values out), on a controlled clock."""

from __future__ import annotations

import pytest

from limbctl.errors import ConfigError
from limbctl.servo.cycle import CycleRead, ServoReport
from limbctl.servo.health import HealthLimits, HealthMonitor

HEALTHY = ServoReport(2048, 2048, True, ())


def reads(**reports: ServoReport) -> CycleRead:
    both = {1: HEALTHY, 2: HEALTHY}
    both.update({int(k[1:]): v for k, v in reports.items()})
    return CycleRead(both)


def silent(servo_id: int) -> CycleRead:
    return CycleRead({}, (servo_id,), f"servo {servo_id} did not answer the cycle's read")


def unread(servo_id: int) -> CycleRead:
    """A read while ``servo_id`` is silent and not probed: the other servo answered."""
    other = 2 if servo_id == 1 else 1
    return CycleRead({other: HEALTHY}, (), f"servo {servo_id} silent", 0.0, (servo_id,))


def saturated(present: int, goal: int = 2048, pwm: int = -885, limit: int = 885) -> ServoReport:
    return ServoReport(present, goal, True, (), pwm, limit)


def faults_of(reports, servo: int = 1, step_s: float = 0.005) -> list:
    """A fresh monitor's verdicts on ``reports`` of one servo, one read every ``step_s``."""
    monitor = HealthMonitor()
    return [
        monitor.observe(reads(**{f"s{servo}": r}), step_s * k).fault for k, r in enumerate(reports)
    ]


def test_a_dropout_is_named_after_the_misses_asked_and_reported_with_its_duration():
    monitor = HealthMonitor()
    assert monitor.observe(silent(1), 0.0).notices == (
        "servo 1 stopped answering; holding its last goal",
    ), "not named at the first failed read by default"
    monitor = HealthMonitor(HealthLimits(named_after_misses=3))
    assert monitor.observe(reads(), 0.0).notices == ()
    assert monitor.observe(silent(2), 0.005).notices == ()
    assert monitor.observe(silent(2), 0.010).notices == ()
    third = monitor.observe(silent(2), 0.015)
    assert third.notices == ("servo 2 stopped answering; holding its last goal",)
    assert third.fault is None
    assert monitor.observe(silent(2), 0.2).notices == ()  # named once
    back = monitor.observe(reads(), 0.305)
    assert back.notices == ("servo 2 answered again after 0.300 s silent",)
    assert back.fault is None
    assert [(d.servo_id, d.duration_s) for d in monitor.dropouts] == [(2, pytest.approx(0.3))]
    monitor = HealthMonitor(HealthLimits(named_after_misses=2))
    for k in range(10):  # every other reply lost: never three in a row
        assert monitor.observe(silent(1) if k % 2 else reads(), k * 0.005).notices == ()
    assert monitor.dropouts == []
    # cycles that do not ask a silent servo are no misses
    monitor = HealthMonitor(HealthLimits(named_after_misses=2))
    assert monitor.observe(silent(2), 0.0).notices == ()
    for k in range(1, 9):
        assert monitor.observe(unread(2), 0.005 * k).notices == ()
    assert monitor.observe(silent(2), 0.05).notices == (
        "servo 2 stopped answering; holding its last goal",
    )
    # a probe that answers ends the dropout with its length; one still going on has its length
    monitor = HealthMonitor()
    monitor.observe(silent(2), 1.0)
    monitor.observe(unread(2), 1.1)
    back = monitor.observe(reads(), 1.25)
    assert back.notices == ("servo 2 answered again after 0.250 s silent",)
    assert monitor.silent() == () and monitor.ongoing(2.0) == []
    monitor.observe(silent(1), 1.0)
    (dropout,) = monitor.ongoing(1.3)
    assert (dropout.servo_id, dropout.duration_s, dropout.ongoing) == (1, pytest.approx(0.3), True)
    assert dropout.describe() == "servo 1 still silent when the session ended: 0.300 s so far"


def test_a_silent_servo_is_probed_once_per_interval_and_lost_only_by_a_failed_probe():
    monitor = HealthMonitor(HealthLimits(lost_after_s=0.1))
    monitor.observe(silent(1), 1.0)
    assert monitor.observe(silent(1), 1.09).fault is None
    fault = monitor.observe(silent(1), 1.1).fault
    assert fault.servo_id == 1 and fault.kind == "lost"
    assert "servo 1 lost: no answer for 0.100 s" in fault.message
    monitor = HealthMonitor(HealthLimits(probe_interval_s=0.05, lost_after_s=0.5))
    assert monitor.probes_due(0.0) == ()
    monitor.observe(silent(2), 0.0)  # named at its first failed read
    assert monitor.silent() == (2,)
    due = []
    for k in range(1, 110):  # 5 ms cycles
        now = 0.005 * k
        probe = monitor.probes_due(now)
        due += [now] * len(probe)
        verdict = monitor.observe(silent(2) if probe else unread(2), now)
        if verdict.fault is not None:
            break
    # one probe per 50 ms (50 or 55 ms apart), the last at lost_after_s: its failure is the loss
    gaps = [b - a for a, b in zip([0.0, *due], due[:-1], strict=False)]
    assert min(gaps) >= 0.05 - 1e-9 and max(gaps) <= 0.055 + 1e-9
    assert len(due) == monitor.probes <= 11 and due[-1] == pytest.approx(0.5)
    assert verdict.fault.kind == "lost" and now == pytest.approx(0.5)


@pytest.mark.parametrize("torque_on", [True, False])
def test_an_alarm_is_told_alone_naming_every_servo_in_alarm_and_torque_off_at_once(torque_on):
    report = ServoReport(2048, 2048, torque_on, ("input voltage",))
    fault = HealthMonitor().observe(reads(s1=report), 0.0).fault
    assert fault.kind == "alarm" and fault.bits == ("input voltage",)
    assert "servo 1: input voltage" in fault.message and "torque" not in fault.message
    assert "limbctl reboot" in fault.message and "ServoBus" not in fault.message
    both = reads(s1=report, s2=ServoReport(2048, 2048, False, ("overheating",)))
    fault = HealthMonitor().observe(both, 0.0).fault
    assert fault.servo_id == 1 and "servo 1: input voltage; servo 2: overheating" in fault.message
    fault = HealthMonitor().observe(reads(s2=ServoReport(2048, 2048, False, ())), 0.0).fault
    assert fault.servo_id == 2 and fault.kind == "torque off"
    assert "servo 2 reports torque off" in fault.message


def test_a_servo_that_does_not_follow_is_a_fault_after_the_grace():
    limits = HealthLimits(max_tracking_error_deg=15.0, tracking_grace_s=0.25)
    monitor = HealthMonitor(limits)
    lagging = ServoReport(2048 + 200, 2048, True, ())  # 17.6 deg behind
    assert monitor.observe(reads(s1=lagging), 0.0).fault is None
    assert monitor.observe(reads(), 0.1).fault is None  # caught up: the grace restarts
    assert monitor.observe(reads(s1=lagging), 0.2).fault is None
    assert monitor.observe(reads(s1=lagging), 0.4).fault is None
    fault = monitor.observe(reads(s1=lagging), 0.45).fault
    assert fault.kind == "not following" and "17.6 deg from its goal" in fault.message
    # pushed away from its goal: not following
    pushed = [ServoReport(2048 - 200 - 5 * k, 2048, True, ()) for k in range(10)]
    fault = faults_of(pushed, step_s=0.05)[-1]
    assert fault is not None and fault.kind == "not following"
    # 40 deg behind a goal that runs away, but moving toward it at ~100 deg/s: following
    monitor = HealthMonitor(HealthLimits(tracking_grace_s=0.25, min_progress_deg=2.0))
    for k in range(20):
        present = 2048 + 23 * k  # 23 ticks = 2.0 deg per 20 ms
        report = ServoReport(present, present + 455, True, ())
        assert monitor.observe(reads(s1=report), 0.02 * k).fault is None


def test_a_servo_saturated_off_its_goal_without_closing_in_is_blocked():
    # defaults: 90 % of PWM Limit, 5 deg, 0.15 s; 6.2 deg from its goal, drive at its limit
    faults = faults_of([saturated(2048 - 70)] * 31)
    assert all(f is None for f in faults[:30])  # 0.145 s
    fault = faults[30]
    assert fault.servo_id == 1 and fault.kind == "not following"
    assert "servo 1 does not follow (blocked): 6.2 deg from its goal" in fault.message
    assert "PWM -885 of 885" in fault.message and "blocked or overloaded" in fault.message
    # judged against the servo's own PWM Limit: 90 % of a lowered one saturates, 88 % does not
    fault = faults_of([saturated(2048 + 80, pwm=450, limit=500)] * 31, servo=2)[-1]
    assert fault is not None and fault.servo_id == 2
    assert faults_of([saturated(2048 + 80, pwm=440, limit=500)] * 100, servo=2) == [None] * 100


@pytest.mark.parametrize(
    "case, reports",
    [
        # saturated, but closing in on its goal at 30 deg/s (a hard start toward a far goal)
        ("closing in", [saturated(2048 - 200 + 2 * k) for k in range(100)]),
        # saturated, 4.4 deg off: within what a loaded but following servo lags by
        ("near its goal", [saturated(2048 - 50)] * 100),
        # off its goal and moving away from it (a reversal), drive well below its limit
        ("not saturated", [saturated(2048 - 100 - k, pwm=-300) for k in range(100)]),
        # saturated for 0.1 s, then a read below: the window starts again
        ("saturation broken", ([saturated(1978)] * 20 + [saturated(1978, pwm=-700)]) * 5),
    ],
)
def test_a_servo_that_is_not_blocked_is_not_called_blocked(case, reports):
    assert faults_of(reports) == [None] * len(reports), case


@pytest.mark.parametrize(
    "bad", [{"lost_after_s": 0.0}, {"pwm_saturation": 1.5}, {"blocked_window_s": 0.0}]
)
def test_limits_must_be_sane(bad):
    with pytest.raises(ConfigError, match=next(iter(bad))):
        HealthLimits(**bad)
