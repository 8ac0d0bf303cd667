"""One try of each dynamixel-sdk transfer :class:`ServoBus` uses, as an :class:`Attempt`; sync reads
use packet-level calls (the SDK's group sync read drops the error bytes, alert bit included)."""

from __future__ import annotations

import select
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import serial
from dynamixel_sdk import (
    BROADCAST_ID,
    COMM_NOT_AVAILABLE,
    COMM_PORT_BUSY,
    COMM_RX_CORRUPT,
    COMM_RX_TIMEOUT,
    COMM_SUCCESS,
    COMM_TX_FAIL,
    INST_READ,
    INST_WRITE,
    GroupSyncWrite,
    PortHandler,
)

from limbctl.errors import BusError, BusTimeout, CorruptReply, PortError
from limbctl.servo.control_table import ALERT_BIT, Block, Register

#: Protocol 2.0 status packet: header(4) id(1) length(2) instruction(1), then parameters.
_PKT_ID, _PKT_LENGTH_L, _PKT_LENGTH_H, _PKT_INSTRUCTION, _PKT_PARAMETER0 = 4, 5, 6, 7, 8


#: The SDK's assumption for the USB adapter's latency timer (ms): an FTDI chip's default.
SDK_LATENCY_TIMER_MS = 16.0
#: How long a patient transaction (set-up, torque) keeps trying (s): past a busy machine's stalls.
PATIENT_BUDGET_S = 1.0
#: Most attempts of a patient transaction (the budget ends it first: >= 6 ms each on a pty).
PATIENT_MAX_ATTEMPTS = 200


#: Longest single wait (s) in :meth:`TunedPortHandler.readPort`: a fifth of a 200 Hz cycle.
READ_WAIT_S = 0.001


class TunedPortHandler(PortHandler):
    """The SDK's PortHandler, timing replies by the adapter's real latency timer (ms)."""

    def __init__(self, port_name: str, latency_timer_ms: float) -> None:
        super().__init__(port_name)
        self.latency_timer_ms = float(latency_timer_ms)

    def setupPort(self, cflag_baud: int) -> bool:  # noqa: N802 (SDK's name)
        """Open the port as the SDK does, but exclusively (a second controller gets EAGAIN)."""
        if self.is_open:
            self.closePort()
        self.ser = serial.Serial(
            port=self.port_name,
            baudrate=self.baudrate,
            bytesize=serial.EIGHTBITS,
            timeout=0,
            exclusive=True,
        )
        self.is_open = True
        self.ser.reset_input_buffer()
        # one byte on the wire: start bit, 8 data bits, stop bit = 10 bit times (ms)
        self.tx_time_per_byte = (1000.0 / self.baudrate) * 10.0
        return True

    #: Bytes of the last instruction written: still on the wire when the reply's wait starts.
    sent_bytes = 0

    def writePort(self, packet: Any) -> int:  # noqa: N802 (SDK's name)
        self.sent_bytes = len(packet)
        return super().writePort(packet)

    def readPort(self, length: int) -> bytes:  # noqa: N802 (SDK's name)
        """Up to ``length`` bytes, waiting up to ``READ_WAIT_S`` for the first (no spin)."""
        data = self.ser.read(length)
        if data or not self.is_open:
            return data
        remaining_ms = self.packet_timeout - self.getTimeSinceStart()
        if remaining_ms > 0.0:
            select.select([self.ser.fileno()], [], [], min(remaining_ms / 1e3, READ_WAIT_S))
            data = self.ser.read(length)
        return data

    def setPacketTimeout(self, packet_length: int) -> None:  # noqa: N802 (SDK's name)
        self.packet_start_time = self.getCurrentTime()
        # the SDK's rule plus the instruction's own bytes (2.8 ms at 57600 baud)
        self.packet_timeout = (
            self.tx_time_per_byte * (packet_length + self.sent_bytes)
            + 2.0 * self.latency_timer_ms
            + 2.0
        )


@dataclass
class Attempt:
    """One try of a transaction: value, SDK result, id -> status error byte, the culprit servo."""

    value: Any
    result: int
    errors: dict[int, int]
    culprit: int | None = None


def _refused(error: int) -> bool:
    return bool(error & ~ALERT_BIT)


def ping(packets: Any, port: PortHandler, servo_id: int) -> Attempt:
    """PING one servo; the value is its model number."""
    number, result, error = packets.ping(port, servo_id)
    return Attempt(number, result, {servo_id: error}, servo_id)


def _parameters(packet: list[int]) -> int:
    """Parameter bytes of a status packet: LENGTH - instruction, error and CRC(2)."""
    return (packet[_PKT_LENGTH_L] | packet[_PKT_LENGTH_H] << 8) - 4


def _instruction(servo_id: int, instruction: int, parameters: Sequence[int]) -> list[int]:
    """An instruction packet for the SDK's ``txRxPacket`` (which fills in header and CRC)."""
    packet = [0] * (_PKT_PARAMETER0 + len(parameters) + 2)
    packet[_PKT_ID] = servo_id
    packet[_PKT_LENGTH_L] = (len(parameters) + 3) & 0xFF
    packet[_PKT_LENGTH_H] = (len(parameters) + 3) >> 8
    packet[_PKT_INSTRUCTION] = instruction
    packet[_PKT_PARAMETER0 : _PKT_PARAMETER0 + len(parameters)] = list(parameters)
    return packet


def read(packets: Any, port: PortHandler, register: Register | Block, servo_id: int) -> Attempt:
    """READ ``register`` of one servo; a reply not of its size is corrupt (a late reply)."""
    address = [register.address & 0xFF, register.address >> 8]
    size = [register.size & 0xFF, register.size >> 8]
    packet = _instruction(servo_id, INST_READ, address + size)
    reply, result, error = packets.txRxPacket(port, packet)
    value = None
    if result == COMM_SUCCESS and not _refused(error):
        if _parameters(reply) != register.size:
            result = COMM_RX_CORRUPT
        else:
            start = _PKT_PARAMETER0 + 1  # after the error byte
            value = register.decode(reply[start : start + register.size])
    return Attempt(value, result, {servo_id: error}, servo_id)


def write(
    packets: Any, port: PortHandler, register: Register | Block, servo_id: int, data: list[int]
) -> Attempt:
    """WRITE encoded ``data`` to ``register`` of one servo; a reply with parameters is corrupt."""
    address = [register.address & 0xFF, register.address >> 8]
    packet = _instruction(servo_id, INST_WRITE, address + list(data[: register.size]))
    reply, result, error = packets.txRxPacket(port, packet)
    if result == COMM_SUCCESS and _parameters(reply) != 0:
        result = COMM_RX_CORRUPT
    return Attempt(None, result, {servo_id: error}, servo_id)


def reboot(packets: Any, port: PortHandler, servo_id: int) -> Attempt:
    """REBOOT one servo (it answers before restarting)."""
    result, error = packets.reboot(port, servo_id)
    return Attempt(None, result, {servo_id: error}, servo_id)


def sync_read(
    packets: Any, port: PortHandler, register: Register | Block, ids: Sequence[int]
) -> Attempt:
    """SYNC READ: one instruction, one status packet per servo; value is id -> int."""
    result = packets.syncReadTx(port, register.address, register.size, list(ids), len(ids), False)
    if result != COMM_SUCCESS:
        return Attempt(None, result, {})
    values: dict[int, int] = {}
    errors: dict[int, int] = {}
    for servo_id in ids:
        data, result, error = packets.readRx(port, servo_id, register.size)
        if result == COMM_SUCCESS and not _refused(error) and len(data) != register.size:
            result = COMM_RX_CORRUPT
        if result != COMM_SUCCESS:
            return Attempt(None, result, errors, servo_id)
        errors[servo_id] = error
        if len(data) == register.size:
            values[servo_id] = register.decode(data)
    return Attempt(values, COMM_SUCCESS, errors)


def fast_sync_read(
    packets: Any, port: PortHandler, register: Register | Block, ids: Sequence[int]
) -> Attempt:
    """FAST SYNC READ: ONE status packet of ``error, id, data, crc`` per servo; id -> int."""
    result = packets.syncReadTx(port, register.address, register.size, list(ids), len(ids), True)
    if result != COMM_SUCCESS:
        return Attempt(None, result, {})
    packet, result = packets.rxPacket(port, True)
    if result != COMM_SUCCESS:
        return Attempt(None, result, {}, _first_silent(packet, register.size, ids))
    # LEN = instruction + per servo (error + id + data + crc)
    expected = 1 + len(ids) * (register.size + 4)
    length = packet[_PKT_LENGTH_L] | packet[_PKT_LENGTH_H] << 8
    if packet[_PKT_ID] != BROADCAST_ID or length != expected:
        return Attempt(None, COMM_RX_CORRUPT, {})
    values: dict[int, int] = {}
    errors: dict[int, int] = {}
    offset = _PKT_PARAMETER0
    for servo_id in ids:
        error, answered_id = packet[offset], packet[offset + 1]
        if answered_id != servo_id:
            return Attempt(None, COMM_RX_CORRUPT, errors, servo_id)
        errors[servo_id] = error
        values[servo_id] = register.decode(packet[offset + 2 : offset + 2 + register.size])
        offset += register.size + 4
    return Attempt(values, COMM_SUCCESS, errors)


def _first_silent(partial: list[int], size: int, ids: Sequence[int]) -> int | None:
    """The servo whose part is missing from a Fast Sync Read reply cut short (None: not cut)."""
    complete = max(0, len(partial) - _PKT_PARAMETER0) // (size + 4)
    return ids[complete] if complete < len(ids) else None


def sync_write(
    packets: Any, port: PortHandler, register: Register, params: Mapping[int, list[int]]
) -> Attempt:
    """SYNC WRITE encoded data (id -> bytes) to ``register`` of several servos (no reply)."""
    group = GroupSyncWrite(port, packets, register.address, register.size)
    for servo_id, data in params.items():
        group.addParam(servo_id, data)
    return Attempt(None, group.txPacket(), {})


def failure(what: str, outcome: Attempt, attempts: int, baud: int, port_name: str) -> BusError:
    """The typed error for a transaction whose last attempt was ``outcome``."""
    servo = f"servo {outcome.culprit}" if outcome.culprit is not None else "the bus"
    tried = f"after {attempts} attempt{'s' if attempts > 1 else ''}"
    if outcome.result == COMM_RX_TIMEOUT:
        return BusTimeout(
            f"{what}: {servo} did not answer {tried}: check its power supply and cable, and "
            f"that its id and baud ({baud}) match the rig profile (`limbctl motors scan` finds "
            f"them)",
            outcome.culprit,
        )
    if outcome.result == COMM_RX_CORRUPT:
        return CorruptReply(
            f"{what}: replies from {servo} kept failing CRC/framing {tried}: check the cable "
            f"and connectors, keep the bus away from motor power leads, try a lower baud",
            outcome.culprit,
        )
    if outcome.result == COMM_TX_FAIL:
        return PortError(
            f"{what}: could not send on {port_name}: check the adapter and --port",
            outcome.culprit,
        )
    if outcome.result == COMM_PORT_BUSY:
        return BusError(
            f"{what}: the SDK reports the port busy (a transfer of this process did not "
            f"finish): a limbctl bug, please report it with the command you ran"
        )
    if outcome.result == COMM_NOT_AVAILABLE:
        return BusError(f"{what}: not available with Protocol 2.0 / this id", outcome.culprit)
    return BusError(f"{what}: failed with SDK result {outcome.result}", outcome.culprit)
