"""Every Protocol 2.0 instruction and error number of firmware_sim, through the real SDK."""

from __future__ import annotations

import time

import serial
from dynamixel_sdk import (
    COMM_RX_TIMEOUT,
    COMM_SUCCESS,
    GroupBulkRead,
    GroupBulkWrite,
    GroupSyncRead,
    GroupSyncWrite,
)

from firmware_sim.protocol import Instruction, build_packet, crc16
from firmware_sim.wire import RIG_BAUD
from tests.safety.support import wait_for

# e-Manual addresses (XL430-W250)
ID, RETURN_DELAY, DRIVE_MODE, OPERATING_MODE, HOMING_OFFSET = 7, 9, 10, 11, 20
MAX_POSITION_LIMIT, TORQUE_ENABLE, LED, STATUS_RETURN_LEVEL = 48, 64, 65, 68
REGISTERED, HARDWARE_ERROR, GOAL_VELOCITY, PROFILE_ACCEL = 69, 70, 104, 108
GOAL_POSITION, MOVING, PRESENT_POSITION = 116, 122, 132
INDIRECT_ADDRESS_1, INDIRECT_DATA_1 = 168, 224
XL430_MODEL = 1060


def ok(result):
    """Assert an SDK (result, error) pair succeeded; return the error byte."""
    comm, error = result[-2], result[-1]
    assert comm == COMM_SUCCESS, f"communication failed: {comm}"
    return error


def raw_exchange(port_name: str, packet: bytes, expect: int, timeout_s: float = 1.0) -> bytes:
    """Send raw bytes with pyserial and read ``expect`` bytes back (or what came in time)."""
    with serial.Serial(port_name, baudrate=RIG_BAUD, timeout=timeout_s) as link:
        link.reset_input_buffer()
        link.write(packet)
        return link.read(expect)


def test_every_instruction_and_error_number_through_the_sdk(sdk, sim):
    """Ping, read/write errors, REG_WRITE, stuffing, indirect, reboot, sync/bulk, CLEAR."""
    assert sdk.packet.ping(sdk.port, 2) == (XL430_MODEL, COMM_SUCCESS, 0)
    assert sdk.packet.ping(sdk.port, 7)[1] == COMM_RX_TIMEOUT
    found, result = sdk.packet.broadcastPing(sdk.port)
    assert result == COMM_SUCCESS and found == {1: [XL430_MODEL, 46], 2: [XL430_MODEL, 46]}
    replies = raw_exchange(sdk.port.port_name, build_packet(0xFE, Instruction.PING), 28)
    assert [replies[4], replies[14 + 4]] == [1, 2]
    p, port = sdk.packet, sdk.port
    assert ok(p.write1ByteTxRx(port, 1, LED, 1)) == 0
    assert p.read1ByteTxRx(port, 1, LED) == (1, COMM_SUCCESS, 0)
    assert ok(p.write1ByteTxRx(port, 1, LED, 2)) == 4  # data range
    assert ok(p.writeTxRx(port, 1, GOAL_POSITION, 2, [0, 8])) == 5  # data length: 2 of 4 bytes
    assert ok(p.write4ByteTxRx(port, 1, MAX_POSITION_LIMIT, 3000)) == 0
    assert ok(p.write1ByteTxRx(port, 1, TORQUE_ENABLE, 1)) == 0
    assert ok(p.write4ByteTxRx(port, 1, GOAL_POSITION, 3500)) == 6  # data limit
    assert ok(p.write1ByteTxRx(port, 1, OPERATING_MODE, 1)) == 7  # EEPROM locked by torque
    assert ok(p.write2ByteTxRx(port, 1, 0, 5)) == 7  # model number is read-only
    assert ok(p.readTxRx(port, 1, 150, 4)) == 7  # nothing defined at 150..153
    assert ok(p.write1ByteTxRx(port, 1, TORQUE_ENABLE, 0)) == 0
    assert ok(p.write1ByteTxRx(port, 1, OPERATING_MODE, 2)) == 4  # no mode 2 on the XL430
    assert ok(p.txRxPacket(port, [0, 0, 0, 0, 1, 3, 0, 0x7F, 0, 0])) == 2  # no instruction 0x7F
    # ACTION without REG_WRITE, read back with pyserial: error 2
    assert raw_exchange(port.port_name, build_packet(1, Instruction.ACTION), 11)[8] == 2
    bad = bytearray(build_packet(1, Instruction.READ, bytes([PRESENT_POSITION, 0, 4, 0])))
    bad[-1] ^= 0xFF
    reply = raw_exchange(port.port_name, bytes(bad), 11)
    assert reply[4] == 1 and reply[7] == 0x55 and reply[8] == 3
    assert crc16(reply[:-2]) == reply[-2] | (reply[-1] << 8)
    assert ok(p.regWriteTxRx(port, 2, LED, 1, [1])) == 0
    assert p.read1ByteTxRx(port, 2, REGISTERED) == (1, COMM_SUCCESS, 0)
    assert p.read1ByteTxRx(port, 2, LED)[0] == 0
    assert p.action(port, 0xFE) == COMM_SUCCESS
    assert p.read1ByteTxRx(port, 2, LED) == (1, COMM_SUCCESS, 0)
    assert p.read1ByteTxRx(port, 2, REGISTERED)[0] == 0
    # Goal Velocity -1 (FF FF FF FF) followed by Profile Acceleration 253 (FD 00 00 00)
    data = [0xFF, 0xFF, 0xFF, 0xFF, 0xFD, 0x00, 0x00, 0x00]
    assert ok(p.writeTxRx(port, 1, GOAL_VELOCITY, 8, data)) == 0  # the SDK stuffs this one
    assert p.readTxRx(port, 1, GOAL_VELOCITY, 8) == (data, COMM_SUCCESS, 0)
    request = build_packet(1, Instruction.READ, bytes([GOAL_VELOCITY, 0, 8, 0]))
    reply = raw_exchange(port.port_name, request, 20)
    assert b"\xff\xff\xfd\xfd" in reply[7:] and reply[5] == 13  # LEN counts the stuffing FD
    for k in range(4):
        assert ok(p.write2ByteTxRx(port, 1, INDIRECT_ADDRESS_1 + 2 * k, PRESENT_POSITION + k)) == 0
    direct = p.read4ByteTxRx(port, 1, PRESENT_POSITION)[0]
    assert p.read4ByteTxRx(port, 1, INDIRECT_DATA_1) == (direct, COMM_SUCCESS, 0)
    assert ok(p.write4ByteTxRx(port, 1, HOMING_OFFSET, 42)) == 0
    assert ok(p.write1ByteTxRx(port, 1, LED, 1)) == 0
    assert ok(p.reboot(port, 1)) == 0
    assert p.read1ByteTxRx(port, 1, LED)[0] == 0
    assert p.read4ByteTxRx(port, 1, HOMING_OFFSET)[0] == 42
    writer = GroupSyncWrite(port, p, HOMING_OFFSET, 4)
    writer.addParam(1, (100).to_bytes(4, "little"))
    writer.addParam(2, (-200).to_bytes(4, "little", signed=True))
    assert writer.txPacket() == COMM_SUCCESS
    assert p.read4ByteTxRx(port, 1, HOMING_OFFSET)[0] == 100
    assert p.read4ByteTxRx(port, 2, HOMING_OFFSET)[0] == (-200) & 0xFFFFFFFF
    bulk = GroupBulkWrite(port, p)
    bulk.addParam(1, LED, 1, [1])
    bulk.addParam(2, HOMING_OFFSET, 4, [0, 0, 0, 0])
    assert bulk.txPacket() == COMM_SUCCESS
    truth = {k: v["raw_tick"] for k, v in sim.truth()["servos"].items()}
    expected = {1: round(truth[1]) + 100, 2: round(truth[2])}
    reader = GroupSyncRead(port, p, PRESENT_POSITION, 4)
    assert reader.addParam(1) and reader.addParam(2)
    for read in (reader.txRxPacket, reader.fastSyncRead):
        assert read() == COMM_SUCCESS
        assert {i: reader.getData(i, PRESENT_POSITION, 4) for i in (1, 2)} == expected
    bulk_reader = GroupBulkRead(port, p)
    assert bulk_reader.addParam(1, LED, 1) and bulk_reader.addParam(2, PRESENT_POSITION, 4)
    for read in (bulk_reader.txRxPacket, bulk_reader.fastBulkRead):
        assert read() == COMM_SUCCESS
        assert bulk_reader.getData(1, LED, 1) == 1
        assert bulk_reader.getData(2, PRESENT_POSITION, 4) == expected[2]
    # CLEAR of the multi-turn count, and result fail while moving or with an error latched
    assert ok(p.write1ByteTxRx(port, 1, OPERATING_MODE, 4)) == 0  # extended position
    assert ok(p.write4ByteTxRx(port, 1, HOMING_OFFSET, 4096 * 2)) == 0
    before = p.read4ByteTxRx(port, 1, PRESENT_POSITION)[0]
    assert before >= 4096 * 2
    assert ok(p.clearMultiTurn(port, 1)) == 0
    after = p.read4ByteTxRx(port, 1, PRESENT_POSITION)[0]
    assert after == before  # homing offset still counts; only whole shaft turns are cleared
    bad = build_packet(1, Instruction.CLEAR, bytes([0x01, 0, 0, 0, 0]))
    assert raw_exchange(port.port_name, bad, 11)[8] == 4
    # CLEAR while moving: result fail
    assert ok(p.write4ByteTxRx(port, 1, PROFILE_ACCEL + 4, 20)) == 0  # slow profile velocity
    assert ok(p.write1ByteTxRx(port, 1, TORQUE_ENABLE, 1)) == 0
    target = after + 2000
    assert ok(p.write4ByteTxRx(port, 1, GOAL_POSITION, target)) == 0
    wait_for(lambda: p.read1ByteTxRx(port, 1, MOVING)[0], 2.0, "the servo to start moving")
    assert ok(p.clearMultiTurn(port, 1)) == 1
    # torque on cannot be enabled while a hardware error is latched: result fail
    sim.set_temperature(2, 90.0)
    wait_for(lambda: p.read1ByteTxRx(port, 2, HARDWARE_ERROR)[0], 2.0, "overheating")
    assert ok(p.write1ByteTxRx(port, 2, TORQUE_ENABLE, 1)) == 0x80 | 1


def test_status_return_levels_return_delay_and_factory_reset_options(sdk):
    p, port = sdk.packet, sdk.port
    # the new level already governs the answer to the write that sets it
    assert p.write1ByteTxRx(port, 1, STATUS_RETURN_LEVEL, 1)[0] == COMM_RX_TIMEOUT
    assert p.write1ByteTxRx(port, 1, LED, 1)[0] == COMM_RX_TIMEOUT  # writes now silent
    assert p.read1ByteTxRx(port, 1, LED) == (1, COMM_SUCCESS, 0)  # reads still answered
    p.write1ByteTxOnly(port, 1, STATUS_RETURN_LEVEL, 0)
    assert p.read1ByteTxRx(port, 1, LED)[1] == COMM_RX_TIMEOUT
    assert p.ping(port, 1)[1] == COMM_SUCCESS  # PING is always answered
    # level 2 answers the write that sets it: read that answer (sent TxOnly, it misled the next)
    assert ok(p.write1ByteTxRx(port, 1, STATUS_RETURN_LEVEL, 2)) == 0
    assert ok(p.write1ByteTxRx(port, 1, RETURN_DELAY, 254)) == 0
    # the answer cannot come before 254 * 2 us, and it is the read's own (LED is 1)
    start = time.perf_counter()
    assert p.read1ByteTxRx(port, 1, LED) == (1, COMM_SUCCESS, 0)
    assert time.perf_counter() - start >= 254 * 2e-6
    assert ok(p.write1ByteTxRx(port, 2, RETURN_DELAY, 3)) == 0
    assert ok(p.factoryReset(port, 2, 0x02)) == 0  # keep ID and baud
    assert p.read1ByteTxRx(port, 2, RETURN_DELAY) == (250, COMM_SUCCESS, 0)
    assert ok(p.write1ByteTxRx(port, 2, ID, 5)) == 0
    assert ok(p.factoryReset(port, 5, 0x01)) == 0  # keep ID: the baud is back at 57600
    assert p.ping(port, 5)[1] == COMM_RX_TIMEOUT
    assert port.setBaudRate(57600)
    assert p.ping(port, 5)[1] == COMM_SUCCESS
    p.factoryReset(port, 0xFE, 0xFF)  # refused on broadcast: IDs would collide
    assert p.ping(port, 5)[1] == COMM_SUCCESS
    assert ok(p.factoryReset(port, 5, 0xFF)) == 0  # everything, ID back to 1
    assert p.ping(port, 5)[1] == COMM_RX_TIMEOUT
    # unknown option: only the reset servo answers as ID 1 at 57600 (the other is at 4 Mbps)
    assert ok(p.factoryReset(port, 1, 0x03)) == 4
