"""Scheduled faults (``firmware-sim --event``): parsing, timing, and their effect over the pty."""

from __future__ import annotations

import pytest
from dynamixel_sdk import COMM_RX_TIMEOUT, COMM_SUCCESS, PacketHandler

from firmware_sim.control_table import Register
from firmware_sim.events import EventSchedule, ScheduledEvent, parse_event
from firmware_sim.wire import RIG_BAUD
from tests.firmware_sim.test_cli import await_voltage_error, sdk_at, served
from tests.safety.support import wait_for

ID, TORQUE_ENABLE, HARDWARE_ERROR, PRESENT_PWM = 7, 64, 70, 124
VOLTAGE_BIT, OVERHEATING_BIT, OVERLOAD_BIT, ALERT = 0x01, 0x04, 0x20, 0x80


@pytest.mark.parametrize(
    "text, message",
    [
        ("1:vanish:1", "T:KIND:ID:VALUE"),
        ("1:melt:1:2", "one of vanish, voltage, temperature, restart, push"),
        ("1:push:1:nan", "finite number of %"),
        ("x:vanish:1:2", "must be numbers"),
        ("1:vanish:1.5:2", "ID an integer"),
        ("-1:vanish:1:2", ">= 0"),
        ("nan:vanish:1:2", "finite"),
        ("1:vanish:300:2", "0..252"),
        ("1:vanish:1:-2", "s >= 0"),
        ("1:voltage:1:inf", "V >= 0"),
    ],
)
def test_parse_event_names_what_is_wrong(text, message):
    with pytest.raises(ValueError, match=message.replace(".", r"\.")):
        parse_event(text)


def test_a_schedule_applies_each_event_once_by_the_id_it_names_restart_and_push_included(
    stepped,
):
    sim, clock = stepped(ids=(1, 2))
    schedule = EventSchedule([parse_event("2:voltage:1:5"), parse_event("1:vanish:2:0.5")])
    schedule.check(sim)
    assert schedule.apply_due(sim) == 0
    clock.t = 1.0
    assert schedule.apply_due(sim) == 1
    assert not sim.faults.present(2, 1.2) and sim.faults.present(2, 1.5)
    assert sim.servo(1).environment.voltage != 5.0
    clock.t = 3.0
    assert schedule.apply_due(sim) == 1
    assert sim.servo(1).environment.voltage == 5.0
    assert schedule.apply_due(sim) == 0 and schedule.events == []
    sim, clock = stepped(factory=2)
    with pytest.raises(ValueError, match=r"servos in slots 1, 2 all answer as ID 1: an event "):
        EventSchedule([parse_event("0:voltage:1:5")]).check(sim)
    sim.servo(2).write(ID, bytes([9]))  # slot 2 set up as ID 9
    with pytest.raises(ValueError, match="no servo answers as ID 2; the servos answer as 1, 9"):
        EventSchedule([parse_event("0:voltage:2:5")]).check(sim)
    schedule = EventSchedule([parse_event("1:voltage:9:5"), parse_event("2:voltage:9:7")])
    schedule.check(sim)
    clock.t = 1.0
    assert schedule.apply_due(sim) == 1
    assert sim.servo(2).environment.voltage == 5.0
    assert sim.servo(1).environment.voltage != 5.0
    sim.servo(2).write(ID, bytes([4]))  # renumbered again before the second event
    clock.t = 2.0
    assert schedule.apply_due(sim) == 0
    assert schedule.skipped == [
        "event at 2 s (voltage:9:7): no servo answers as ID 9 now (the servos answer as 1, 4): "
        "not applied"
    ]
    assert sim.servo(2).environment.voltage == 5.0
    sim, clock = stepped(ids=(1, 2))
    servo = sim.servo(2)
    servo.write(64, bytes([1]))  # torque on
    servo.write(168, (132).to_bytes(2, "little"))  # Indirect Address 1 -> Present Position
    schedule = EventSchedule([parse_event("1:restart:2:0.25")])
    clock.t = 1.0
    assert schedule.apply_due(sim) == 1
    assert not servo.torque_on
    assert servo.read(168, 2) == (224).to_bytes(2, "little"), "the indirect map is unmapped"
    assert not sim.faults.present(2, 1.2) and sim.faults.present(2, 1.25)
    assert sim.servo(1).torque_on is False and sim.faults.present(1, 1.0)
    sim, clock = stepped(ids=(1, 2))
    servo = sim.servo(1)
    servo.write(64, bytes([1]))  # torque on: the servo holds its pose
    schedule = EventSchedule([parse_event("0.5:push:1:300"), parse_event("2:push:1:0")])
    clock.t = 0.5
    sim.advance()
    assert schedule.apply_due(sim) == 1
    clock.t = 0.6
    sim.advance()
    servo.refresh(sim.now())  # what a READ would return now
    # 300 % of stall is beyond what the motor holds: deflected 6 deg, drive at the PWM Limit
    assert servo.value(Register.PRESENT_PWM) == -885
    goal, present = servo.value(Register.GOAL_POSITION), servo.value(Register.PRESENT_POSITION)
    assert abs(present - goal) == pytest.approx(6.0 / 360 * 4096, abs=2)
    assert servo.value(Register.HARDWARE_ERROR_STATUS) == 0
    clock.t = 1.2  # over 0.5 s of overload: the firmware's shutdown
    sim.advance()
    servo.refresh(sim.now())
    assert servo.value(Register.HARDWARE_ERROR_STATUS) == OVERLOAD_BIT and not servo.torque_on
    clock.t = 2.0
    assert schedule.apply_due(sim) == 1
    assert sim.truth()["servos"][1]["load_percent"] == 0.0  # torque off, let go
    assert parse_event("2.5:vanish:1:0.5") == ScheduledEvent(2.5, "vanish", 1, 0.5)
    assert parse_event("0:voltage:2:5") == ScheduledEvent(0.0, "voltage", 2, 5.0)
    assert parse_event(" 1 : temperature : 2 : -5 ") == ScheduledEvent(1.0, "temperature", 2, -5.0)
    assert parse_event("3:push:1:-300") == ScheduledEvent(3.0, "push", 1, -300.0)


def test_command_line_events_reach_the_servos(tmp_path):
    link, events = tmp_path / "ttyDXL", ("0:vanish:3:60", "0:voltage:1:5", "0:push:2:-250")
    options = [arg for event in events for arg in ("--event", event)]
    with served(["--ids", "1,2,3", "--link", str(link), *options]) as (process, ready):
        assert "ready" in ready
        port, packet = sdk_at(link, RIG_BAUD), PacketHandler(2.0)
        # servo 1 sees 5 V, below its 6.0 V limit: input voltage error and the alert
        await_voltage_error(packet, port, 1)
        assert packet.read1ByteTxRx(port, 1, TORQUE_ENABLE) == (0, COMM_SUCCESS, ALERT)
        # servo 2, pushed toward fewer ticks: its drive saturates positive (two's complement 885)
        assert packet.write1ByteTxRx(port, 2, TORQUE_ENABLE, 1)[:1] == (COMM_SUCCESS,)
        wait_for(lambda: packet.read2ByteTxRx(port, 2, PRESENT_PWM)[0] == 885, 5, "PWM 885 on 2")
        # servo 3 has vanished for the whole test
        assert packet.ping(port, 3)[1] == COMM_RX_TIMEOUT
        port.closePort()
        process.terminate()
        assert process.wait(timeout=10) == 0
