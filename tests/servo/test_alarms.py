"""Alarm messages say one thing about torque; servos in alarm are rebooted and say what it was."""

from __future__ import annotations

import pytest

from limbctl.errors import ServoAlarm
from limbctl.servo.alarms import (
    Rebooted,
    alarm_message,
    held_torque,
    reboot_servos_in_alarm,
    switched_off,
)
from tests.safety.support import configured_rig


@pytest.fixture
def rig(sim):
    with configured_rig(sim.port) as rig:
        yield rig


def alarm_of(rig) -> ServoAlarm:
    for _ in range(200):  # the simulator latches on its next physics step
        try:
            rig.bus.check_alarms()
        except ServoAlarm as alarm:
            return alarm
    raise AssertionError("no alarm was raised")


@pytest.mark.parametrize(
    ("torque", "servo", "cause", "said", "unsaid"),
    [
        # a voltage alarm is not in the factory Shutdown mask: the servo keeps its torque on
        (True, 1, "voltage", ["servo 1: input voltage", "servo 1 keeps torque on"], ["torque off"]),
        (
            True,
            2,
            "temperature",
            [
                "servo 2: overheating",
                "servo 2 has torque off, and it cannot be switched on until it is rebooted",
                "`limbctl reboot`",
            ],
            ["keeps torque on", "ServoBus"],
        ),
        # the servo itself switches nothing off: its torque was never on
        (
            False,
            1,
            "voltage",
            ["servo 1 has torque off"],
            ["switched torque off", "keeps torque on"],
        ),
    ],
    ids=["voltage-keeps-torque", "overheating-torque-off", "torque-never-on"],
)
def test_an_alarm_message_says_the_servos_torque_as_it_is_and_a_reboot_clears_it(
    sim, rig, torque, servo, cause, said, unsaid
):
    rig.set_torque(torque)
    if cause == "voltage":
        sim.set_voltage(servo, 5.0)
    else:
        sim.set_temperature(servo, 90.0)
    message = str(alarm_of(rig))
    assert all(words in message for words in said), message
    assert not any(words in message for words in unsaid), message
    if cause == "voltage" and torque:
        assert rig.torque_enabled() == (True, True)
    if cause == "temperature":  # reboot_servos_in_alarm reboots only it and says what it was
        sim.set_temperature(2, 30.0)  # the cause is fixed
        rebooted = reboot_servos_in_alarm(rig.bus)
        assert rebooted == [Rebooted(2, ("overheating",))]
        assert "servo 2 was in alarm (overheating): rebooted" in rebooted[0].describe()
        assert rig.bus.read_hardware_errors() == {1: (), 2: ()}
        assert rig.torque_enabled() == (True, False)  # servo 1 untouched, servo 2 restarted
        assert reboot_servos_in_alarm(rig.bus) == []


def test_the_alarm_alone_says_nothing_about_torque_hold_says_each_joints_and_off_says_switched():
    message = alarm_message({2: ("overheating", "overload")})
    assert message.startswith("hardware error reported (servo 2: overheating, overload).")
    assert "torque" not in message and message.endswith("then `limbctl reboot`")
    assert held_torque({"pan": True, "tilt": True}) == "holding the last safe pose (torque on)"
    assert held_torque({"pan": False, "tilt": True}, after_alarm=True) == (
        "pan torque off as the servo reports it; tilt holding the last safe pose (torque on)"
    )
    # both on, or one unread; one or both already off: tests/safety/test_faults.py (ALARM_STATES)
    assert switched_off({"pan": True, "tilt": True}) == "torque switched off"
    assert switched_off({"pan": None, "tilt": True}) == "torque switched off"
