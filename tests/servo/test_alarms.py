"""Alarm messages say one thing about torque; servos in alarm are rebooted and say what it was.

Through the real SDK on the simulator: a voltage alarm (not in the factory Shutdown mask: torque
stays on; on a servo whose torque was never on it stays off), an overheating shutdown (torque
off). The words the loop's safe states use (the alarm alone, then each joint's torque) are
values in, values out.
"""

from __future__ import annotations

import pytest

from calib import default_sim_profile
from limbctl.errors import ServoAlarm
from limbctl.servo.alarms import (
    Rebooted,
    alarm_message,
    held_torque,
    reboot_servos_in_alarm,
    switched_off,
)
from limbctl.servo.bus import ServoBus
from limbctl.servo.rig import Rig

PROFILE = default_sim_profile()


@pytest.fixture
def rig(sim):
    with ServoBus.from_profile(PROFILE, port=sim.port) as bus:
        rig = Rig(PROFILE, bus)
        rig.configure()
        rig.set_torque(True)
        yield rig


def alarm_of(rig) -> ServoAlarm:
    for _ in range(200):  # the simulator latches on its next physics step
        try:
            rig.bus.check_alarms()
        except ServoAlarm as alarm:
            return alarm
    raise AssertionError("no alarm was raised")


def test_voltage_alarm_message_says_torque_stays_on(sim, rig):
    sim.set_voltage(1, 5.0)
    message = str(alarm_of(rig))
    assert "servo 1: input voltage" in message
    assert "servo 1 keeps torque on" in message
    assert "torque off" not in message
    assert rig.torque_enabled() == (True, True)


def test_overheating_message_says_torque_is_off(sim, rig):
    sim.set_temperature(2, 90.0)
    message = str(alarm_of(rig))
    assert "servo 2: overheating" in message
    assert "servo 2 has torque off, and it cannot be switched on until it is rebooted" in message
    assert "keeps torque on" not in message
    assert "`limbctl reboot`" in message and "ServoBus" not in message


def test_an_alarm_on_a_servo_whose_torque_was_never_on_does_not_say_switched_off(sim, rig):
    rig.set_torque(False)
    sim.set_voltage(1, 5.0)  # not in the Shutdown mask: the servo itself switches nothing off
    message = str(alarm_of(rig))
    assert "servo 1 has torque off" in message
    assert "switched torque off" not in message and "keeps torque on" not in message


def test_the_alarm_alone_says_nothing_about_torque():
    message = alarm_message({2: ("overheating", "overload")})
    assert message.startswith("hardware error reported (servo 2: overheating, overload).")
    assert "torque" not in message and message.endswith("then `limbctl reboot`")


@pytest.mark.parametrize(
    "reported, said",
    [
        ({"pan": True, "tilt": True}, "torque switched off"),
        ({"pan": None, "tilt": True}, "torque switched off"),
        (
            {"pan": True, "tilt": False},
            "torque switched off on pan; tilt torque was already off (as the servo reported it)",
        ),
        (
            {"pan": False, "tilt": False},
            "pan and tilt torque was already off (as the servos reported it); it stays off",
        ),
    ],
)
def test_the_torque_off_safe_state_tells_switched_from_already_off(reported, said):
    assert switched_off(reported) == said


def test_hold_says_each_joints_torque_once():
    assert held_torque({"pan": True, "tilt": True}) == "holding the last safe pose (torque on)"
    both = held_torque({"pan": False, "tilt": True}, after_alarm=True)
    assert (
        both
        == "pan torque off as the servo reports it; tilt holding the last safe pose (torque on)"
    )


def test_reboot_servos_in_alarm_reboots_only_those_and_says_what_it_was(sim, rig):
    sim.set_temperature(2, 90.0)
    alarm_of(rig)
    sim.set_temperature(2, 30.0)  # the cause is fixed
    rebooted = reboot_servos_in_alarm(rig.bus)
    assert rebooted == [Rebooted(2, ("overheating",))]
    assert "servo 2 was in alarm (overheating): rebooted" in rebooted[0].describe()
    assert rig.bus.read_hardware_errors() == {1: (), 2: ()}
    assert rig.torque_enabled() == (True, False)  # servo 1 untouched, servo 2 restarted
    assert reboot_servos_in_alarm(rig.bus) == []
