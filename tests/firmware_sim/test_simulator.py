"""The simulated bus is as strict as the wire: bauds, IDs, collisions, wire time, EEPROM files."""

import os
import time
import tty

import pytest
import serial
from dynamixel_sdk import COMM_RX_TIMEOUT, COMM_SUCCESS, PacketHandler

from firmware_sim import SimulatedBus
from firmware_sim.control_table import Register, get_model
from firmware_sim.eeprom import EepromFile
from firmware_sim.protocol import build_status
from firmware_sim.servo import Servo
from firmware_sim.simulator import Simulator
from firmware_sim.wire import (
    BAUD_BY_VALUE,
    FACTORY_BAUD,
    collide,
    host_baud,
    value_for_baud,
    wire_s,
)
from tests.firmware_sim.test_cli import sdk_at

ID, BAUD_RATE, TORQUE_ENABLE = 7, 8, 64
XL430 = 1060


def test_a_factory_servos_id_and_baud_change_as_lerobot_sets_them(tmp_path):
    """LeRobot's setup_motors flow through the SDK alone on the one factory-fresh servo connected
    (slot 2): write ID, then baud (collisions, finding by baud: tests/servo/test_scan.py)."""
    with SimulatedBus(factory=2, connect=(2,), link=tmp_path / "tty") as sim:
        packet, port = PacketHandler(2.0), sdk_at(sim.port, FACTORY_BAUD)
        assert packet.ping(port, 1) == (XL430, COMM_SUCCESS, 0)
        assert packet.write1ByteTxRx(port, 1, TORQUE_ENABLE, 1) == (COMM_SUCCESS, 0)
        assert packet.write1ByteTxRx(port, 1, ID, 5) == (COMM_SUCCESS, 7)  # EEPROM, torque on
        assert packet.write1ByteTxRx(port, 1, TORQUE_ENABLE, 0) == (COMM_SUCCESS, 0)
        assert packet.write1ByteTxRx(port, 1, ID, 5) == (COMM_SUCCESS, 0)
        assert packet.ping(port, 1)[1] == COMM_RX_TIMEOUT
        # the servo answers this write at the old rate, then listens at the new one only
        assert packet.write1ByteTxRx(port, 5, BAUD_RATE, 3) == (COMM_SUCCESS, 0)
        assert packet.ping(port, 5)[1] == COMM_RX_TIMEOUT
        assert port.setBaudRate(1_000_000)
        assert packet.ping(port, 5) == (XL430, COMM_SUCCESS, 0)
        assert packet.broadcastPing(port)[0] == {5: [XL430, 46]}
        port.closePort()


def test_mixed_models_share_a_bus_and_the_roll_id_must_be_a_listed_servo_not_pan_or_tilt():
    sim = Simulator(ids=(1, 2, 3), model="xl430-w250,xl330-m288,xm430-w350")
    assert [s.model.model_number for s in sim.servos] == [1060, 1200, 1020]
    with pytest.raises(ValueError, match="names 2 models for 3 servos; give 1 or 3"):
        Simulator(ids=(1, 2, 3), model="xl430-w250,xl330-m288")
    with pytest.raises(ValueError, match="--connect \\[3\\] names slots beyond \\[1, 2\\]"):
        Simulator(factory=2, connect=(3,))
    with pytest.raises(ValueError, match="roll joint's servo 4"):
        Simulator(ids=(1, 2, 3), roll_id=4)
    with pytest.raises(ValueError, match="roll joint's servo 2"):
        Simulator(ids=(1, 2, 3), roll_id=2)
    two = Simulator(ids=(1, 2, 3))
    assert not two.world.has_roll  # servo 3 is a free shaft unless named the roll


def test_an_eeprom_survives_a_power_cycle_ram_does_not_and_another_models_is_refused(tmp_path):
    first = Servo(1, get_model("xl430-w250"), 2048.0)
    assert not EepromFile(tmp_path, 1).load(first)  # no file yet: factory-fresh
    store = EepromFile(tmp_path, 1)
    first.write(7, bytes([2]))  # ID 2
    first.write(8, bytes([6]))  # 4 Mbps
    first.write(65, bytes([1]))  # LED (RAM)
    store.save(first)
    again = Servo(1, get_model("xl430-w250"), 2048.0)
    assert EepromFile(tmp_path, 1).load(again)
    assert (again.servo_id, again.value(Register.BAUD_RATE)) == (2, 6)
    assert again.value(Register.LED) == 0
    xl = Servo(1, get_model("xl430-w250"), 2048.0)
    xl.write(7, bytes([3]))
    EepromFile(tmp_path, 1).save(xl)
    with pytest.raises(ValueError, match=r"servo-1.eeprom is not the EEPROM of a XL330-M288"):
        EepromFile(tmp_path, 1).load(Servo(1, get_model("xl330-m288"), 2048.0))


def test_baud_values_wire_time_a_reply_takes_and_colliding_replies(tmp_path):
    assert [value_for_baud(b) for b in (9600, 57_600, 4_000_000, 4_500_000)] == [0, 1, 6, 7]
    assert BAUD_BY_VALUE[3] == 1_000_000
    with pytest.raises(ValueError, match="no X-series servo runs at 12345 baud; choose one of"):
        value_for_baud(12345)
    assert wire_s(132, 57_600) == pytest.approx(132 * 10 / 57_600)  # 22.9 ms
    assert wire_s(5, None) == 0.0
    # PING: 10 bytes out, 14 back at 9600 baud = 25 ms at least, plus 500 us Return Delay Time
    with SimulatedBus(ids=(1,), baud=9600, link=tmp_path / "tty") as sim:
        port = sdk_at(sim.port, 9600)
        start = time.monotonic()
        assert PacketHandler(2.0).ping(port, 1)[1] == COMM_SUCCESS
        assert time.monotonic() - start >= (10 + 14) * 10 / 9600 + 500e-6
        port.closePort()
    reply = build_status(1, 0, bytes([0x24, 0x04, 46]))
    assert collide([reply]) == reply
    garbled = collide([reply, reply])  # even identical replies: the second is a little late
    assert reply not in garbled
    assert not garbled.startswith(b"\xff\xff\xfd\x00")  # the header itself is broken


@pytest.mark.parametrize("baud", [9600, 57_600, 1_000_000, 4_000_000, 4_500_000])
def test_the_hosts_speed_is_read_from_the_pty(baud):
    master, slave = os.openpty()
    try:
        tty.setraw(slave)
        with serial.Serial(os.ttyname(slave), baudrate=baud):
            assert host_baud(master) == baud  # 4.5 Mbps is a custom rate (termios2)
    finally:
        os.close(master)
        os.close(slave)
