"""The simulated bus is as strict as the wire: baud rates, ID/baud changes, collisions,
factory-fresh servos, one slot at a time, and time on the wire."""

import json
import math
import time

import numpy as np
import pytest
from dynamixel_sdk import COMM_RX_TIMEOUT, COMM_SUCCESS, PacketHandler, PortHandler

from firmware_sim import SimulatedBus
from firmware_sim.orientation import chain_quat
from firmware_sim.simulator import Simulator
from firmware_sim.wire import FACTORY_BAUD

ID, BAUD_RATE, TORQUE_ENABLE = 7, 8, 64
XL430 = 1060


def sdk_at(port_name: str, baud: int) -> PortHandler:
    port = PortHandler(port_name)
    assert port.setBaudRate(baud)
    return port


def test_id_and_baud_change_as_on_real_servos_found_as_lerobot_finds_them(tmp_path):
    """LeRobot's setup_motors flow through the SDK alone: broadcast ping per baud until one
    servo answers (none at another baud), write its ID, then its baud, and find it again at the
    new ID and baud; EEPROM writes are refused while torque is on."""
    with SimulatedBus(factory=1, link=tmp_path / "tty") as sim:
        packet, port = PacketHandler(2.0), PortHandler(sim.port)
        found = {}
        for baud in (1_000_000, FACTORY_BAUD):
            assert port.setBaudRate(baud)
            found, _ = packet.broadcastPing(port)
            if found:
                break
        assert (baud, found) == (FACTORY_BAUD, {1: [XL430, 46]})
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


def test_factory_fresh_servos_all_answer_as_id_1_and_collide(tmp_path):
    with SimulatedBus(factory=2, link=tmp_path / "tty") as sim:
        packet = PacketHandler(2.0)
        port = sdk_at(sim.port, FACTORY_BAUD)
        model, result, _ = packet.ping(port, 1)
        assert result != COMM_SUCCESS  # two clean replies would be a lie: they garble
        found, _ = packet.broadcastPing(port)
        assert found == {}
        port.closePort()
    with SimulatedBus(factory=2, connect=(2,), link=tmp_path / "tty") as sim:
        port = sdk_at(sim.port, FACTORY_BAUD)
        assert PacketHandler(2.0).ping(port, 1) == (XL430, COMM_SUCCESS, 0)
        port.closePort()


def test_mixed_models_share_a_bus():
    sim = Simulator(ids=(1, 2, 3), model="xl430-w250,xl330-m288,xm430-w350")
    assert [s.model.model_number for s in sim.servos] == [1060, 1200, 1020]
    with pytest.raises(ValueError, match="names 2 models for 3 servos; give 1 or 3"):
        Simulator(ids=(1, 2, 3), model="xl430-w250,xl330-m288")
    with pytest.raises(ValueError, match="--connect \\[3\\] names slots beyond \\[1, 2\\]"):
        Simulator(factory=2, connect=(3,))


def test_a_reply_takes_its_bytes_wire_time(tmp_path):
    # PING: 10 bytes out, 14 back at 9600 baud = 25 ms at least, plus 500 us Return Delay Time
    with SimulatedBus(ids=(1,), baud=9600, link=tmp_path / "tty") as sim:
        port = sdk_at(sim.port, 9600)
        start = time.monotonic()
        assert PacketHandler(2.0).ping(port, 1)[1] == COMM_SUCCESS
        assert time.monotonic() - start >= (10 + 14) * 10 / 9600 + 500e-6
        port.closePort()


def test_simulator_with_a_roll_joint_logs_the_full_orientation(tmp_path):
    log = tmp_path / "goals.jsonl"
    with SimulatedBus(ids=(1, 2, 3), roll_id=3, goal_log=log, link=tmp_path / "tty") as sim:
        port, packet = PortHandler(sim.port), PacketHandler(2.0)
        assert port.openPort()
        try:
            goals = {1: 2185 + 200, 2: 1890 - 150, 3: 1960 + 300}
            for servo_id, tick in goals.items():
                result, error = packet.write4ByteTxRx(port, servo_id, 116, tick)
                assert (result, error) == (0, 0)
        finally:
            port.closePort()
    rows = [json.loads(line) for line in log.read_text().splitlines()]
    assert [r["id"] for r in rows] == [1, 2, 3]
    last = rows[-1]
    rad = 2 * math.pi / 4096
    expected = chain_quat(200 * rad, 150 * rad, 300 * rad)
    assert np.allclose(last["limb_q"], expected, atol=1e-12)
    assert last["limb_q"][0] >= 0
    pan, tilt = 200 * rad, 150 * rad
    d = [math.cos(tilt) * math.cos(pan), math.cos(tilt) * math.sin(pan), math.sin(tilt)]
    assert np.allclose(last["limb_dir"], d)


def test_roll_id_must_be_a_listed_servo_other_than_pan_and_tilt():
    with pytest.raises(ValueError, match="roll joint's servo 4"):
        Simulator(ids=(1, 2, 3), roll_id=4)
    with pytest.raises(ValueError, match="roll joint's servo 2"):
        Simulator(ids=(1, 2, 3), roll_id=2)
    two = Simulator(ids=(1, 2, 3))
    assert not two.world.has_roll  # servo 3 is a free shaft unless named the roll
