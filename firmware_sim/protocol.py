"""Dynamixel Protocol 2.0 framing, written from the e-Manual (not from the SDK's code). A packet:
``FF FF FD 00 | ID | LEN_L LEN_H | INST | PARAM ... | CRC_L CRC_H``, byte-stuffed, ``LEN`` counting
everything after itself. :class:`PacketParser` resynchronises after junk."""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from enum import IntEnum

HEADER = b"\xff\xff\xfd\x00"
BROADCAST_ID = 0xFE
MAX_SERVO_ID = 0xFC
STATUS_INSTRUCTION = 0x55
ALERT_BIT = 0x80
# LEN must at least cover instruction + CRC.
MIN_LENGTH_FIELD = 3
# Longest packet the simulated firmware buffers; longer declared lengths are treated as junk.
MAX_LENGTH_FIELD = 1024

CRC_POLYNOMIAL = 0x8005


class Instruction(IntEnum):
    """Protocol 2.0 instruction codes."""

    PING = 0x01
    READ = 0x02
    WRITE = 0x03
    REG_WRITE = 0x04
    ACTION = 0x05
    FACTORY_RESET = 0x06
    REBOOT = 0x08
    CLEAR = 0x10
    STATUS = 0x55
    SYNC_READ = 0x82
    SYNC_WRITE = 0x83
    FAST_SYNC_READ = 0x8A
    BULK_READ = 0x92
    BULK_WRITE = 0x93
    FAST_BULK_READ = 0x9A


class ErrorNumber(IntEnum):
    """Error numbers of a status packet (bits 0-6 of its error byte)."""

    NONE = 0
    RESULT_FAIL = 1  # the instruction could not be carried out
    INSTRUCTION = 2  # undefined instruction, or ACTION without REG_WRITE
    CRC = 3  # the instruction packet's CRC does not match
    DATA_RANGE = 4  # value outside the item's minimum..maximum
    DATA_LENGTH = 5  # data shorter than the item it writes
    DATA_LIMIT = 6  # value outside a limit set by another item (position/velocity/PWM limit)
    ACCESS = 7  # read-only/undefined address, or EEPROM write while torque is on


def _make_crc_table() -> tuple[int, ...]:
    """The 256-entry table of the MSB-first CRC-16 with polynomial 0x8005."""
    table = []
    for byte in range(256):
        crc = byte << 8
        for _ in range(8):
            # shift left; when the top bit falls out, xor the polynomial in
            crc = ((crc << 1) ^ CRC_POLYNOMIAL) if crc & 0x8000 else (crc << 1)
        table.append(crc & 0xFFFF)
    return tuple(table)


_CRC_TABLE = _make_crc_table()


def crc16(data: bytes | bytearray | memoryview, crc: int = 0) -> int:
    """The 16-bit CRC (poly 0x8005, init 0, MSB first) of ``data``, continuing from ``crc``."""
    table = _CRC_TABLE
    for byte in data:
        # crc' = (crc << 8) ^ T[(crc >> 8) ^ byte]
        crc = ((crc << 8) ^ table[((crc >> 8) ^ byte) & 0xFF]) & 0xFFFF
    return crc


def stuff(body: bytes | bytearray) -> bytes:
    """Insert an ``FD`` after every ``FF FF FD`` in an instruction+parameter field."""
    # occurrences of FF FF FD cannot overlap, so one replace stuffs them all
    return bytes(body).replace(b"\xff\xff\xfd", b"\xff\xff\xfd\xfd")


def unstuff(body: bytes | bytearray) -> bytes:
    """Remove the stuffing ``FD`` after every ``FF FF FD`` (inverse of :func:`stuff`)."""
    if b"\xff\xff\xfd\xfd" not in body:
        return bytes(body)
    out = bytearray()
    index = 0
    while index < len(body):
        byte = body[index]
        out.append(byte)
        if byte == 0xFD and index >= 2 and body[index - 1] == 0xFF and body[index - 2] == 0xFF:
            index += 1  # the next byte is the stuffing FD
        index += 1
    return bytes(out)


def build_packet(servo_id: int, instruction: int, params: bytes | bytearray = b"") -> bytes:
    """A complete, stuffed packet with its CRC from unstuffed ``params`` (status: error first)."""
    body = stuff(bytes([instruction]) + bytes(params))
    # LEN = stuffed body + 2 CRC bytes
    length = len(body) + 2
    frame = bytearray(HEADER)
    frame += bytes([servo_id, length & 0xFF, length >> 8])
    frame += body
    crc = crc16(frame)
    frame += bytes([crc & 0xFF, crc >> 8])
    return bytes(frame)


def build_status(servo_id: int, error: int, data: bytes | bytearray = b"") -> bytes:
    """A status packet (instruction 0x55) from ``servo_id`` with error byte and data."""
    return build_packet(servo_id, STATUS_INSTRUCTION, bytes([error]) + bytes(data))


def build_fast_status(segments: Iterable[tuple[int, int, bytes]]) -> bytes:
    """The one status packet of a FAST read from ``(servo_id, error, data)`` in reply order,
    each adding ``error, id, data, crc`` with ``crc`` over the packet so far."""
    segments = list(segments)
    if not segments:
        raise ValueError("a fast read reply needs at least one servo segment")
    # LEN = instruction + per servo (error + id + data + crc)
    length = 1 + sum(4 + len(data) for _, _, data in segments)
    frame = bytearray(HEADER)
    frame += bytes([BROADCAST_ID, length & 0xFF, length >> 8, STATUS_INSTRUCTION])
    crc = crc16(frame)
    for servo_id, error, data in segments:
        part = bytes([error, servo_id]) + bytes(data)
        crc = crc16(part, crc)
        frame += part
        frame += bytes([crc & 0xFF, crc >> 8])
        crc = crc16(frame[-2:], crc)
    return bytes(frame)


@dataclass(frozen=True)
class InstructionPacket:
    """A well-formed packet received from the controller (parameters unstuffed)."""

    servo_id: int
    instruction: int
    params: bytes


@dataclass(frozen=True)
class CorruptPacket:
    """A framed packet whose CRC did not match (the addressed servo answers CRC error)."""

    servo_id: int
    instruction: int


class PacketParser:
    """Incremental parser: yields every complete packet of the bytes fed to it; a bad length or
    CRC costs one byte, a partial packet older than ``stale_after_s`` is dropped."""

    def __init__(self, stale_after_s: float = 0.05) -> None:
        self._buffer = bytearray()
        self._stale_after_s = stale_after_s
        self._partial_since: float | None = None
        self.junk_bytes = 0

    def feed(self, data: bytes, now: float) -> Iterator[InstructionPacket | CorruptPacket]:
        """Add ``data`` received at time ``now`` (s) and yield every packet now complete."""
        if self._partial_since is not None and now - self._partial_since > self._stale_after_s:
            self.junk_bytes += len(self._buffer)
            self._buffer.clear()
        self._buffer += data
        yield from self._drain()
        self._partial_since = now if self._buffer else None

    def _drain(self) -> Iterator[InstructionPacket | CorruptPacket]:
        buffer = self._buffer
        while True:
            start = buffer.find(HEADER)
            if start < 0:
                # keep a possible header prefix at the end, drop the rest
                keep = _header_prefix_length(buffer)
                self.junk_bytes += len(buffer) - keep
                del buffer[: len(buffer) - keep]
                return
            if start:
                self.junk_bytes += start
                del buffer[:start]
            if len(buffer) < 7:
                return
            length = buffer[5] | (buffer[6] << 8)
            if not MIN_LENGTH_FIELD <= length <= MAX_LENGTH_FIELD:
                self.junk_bytes += 1
                del buffer[:1]
                continue
            total = 7 + length
            if len(buffer) < total:
                return
            frame = bytes(buffer[:total])
            received_crc = frame[-2] | (frame[-1] << 8)
            if crc16(memoryview(frame)[:-2]) != received_crc:
                self.junk_bytes += 1
                del buffer[:1]
                yield CorruptPacket(servo_id=frame[4], instruction=frame[7])
                continue
            del buffer[:total]
            body = unstuff(frame[7:-2])
            yield InstructionPacket(servo_id=frame[4], instruction=body[0], params=body[1:])


def _header_prefix_length(buffer: bytearray) -> int:
    """Length of the longest suffix of ``buffer`` that is a proper prefix of the header."""
    for size in range(min(len(HEADER) - 1, len(buffer)), 0, -1):
        if buffer[-size:] == HEADER[:size]:
            return size
    return 0
