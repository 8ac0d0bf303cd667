"""Alarm messages say one thing about torque; servos in alarm are rebooted and say what it was.

Through the real SDK on the simulator: a voltage alarm (not in the factory Shutdown mask: torque
stays on) and an overheating shutdown (torque off).
"""

from __future__ import annotations

import pytest

from calib import default_sim_profile
from limbctl.errors import ServoAlarm
from limbctl.servo.alarms import Rebooted, reboot_servos_in_alarm
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
    assert "servo 2 switched torque off and keeps it off until it is rebooted" in message
    assert "keeps torque on" not in message


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
