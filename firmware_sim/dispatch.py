"""What the servos on one bus answer to each instruction packet (e-Manual, Protocol 2.0)."""

from __future__ import annotations

import contextlib
from collections.abc import Sequence
from dataclasses import dataclass

from firmware_sim.control_table import Register
from firmware_sim.protocol import (
    BROADCAST_ID,
    CorruptPacket,
    ErrorNumber,
    Instruction,
    InstructionPacket,
    build_fast_status,
    build_status,
)
from firmware_sim.servo import FACTORY_RESET_ALL, Servo, ServoError

# Return Delay Time unit: 2 microseconds
RETURN_DELAY_UNIT_S = 2e-6
READ_INSTRUCTIONS = frozenset(
    Instruction[name]
    for name in ("READ", "SYNC_READ", "FAST_SYNC_READ", "BULK_READ", "FAST_BULK_READ")
)


@dataclass(frozen=True)
class Reply:
    """One status packet to send after waiting ``delay_s`` (the servo's Return Delay Time)."""

    servo_id: int
    packet: bytes
    delay_s: float


def _answers(servo: Servo, instruction: int) -> bool:
    """Whether ``servo``'s Status Return Level lets it answer ``instruction``."""
    level = servo.value(Register.STATUS_RETURN_LEVEL)
    if instruction == Instruction.PING:
        return True
    if level == 0:
        return False
    return level == 2 or instruction in READ_INSTRUCTIONS


def _delay(servo: Servo) -> float:
    # delay = Return Delay Time * 2 us
    return servo.value(Register.RETURN_DELAY_TIME) * RETURN_DELAY_UNIT_S


def _reply(servo: Servo, number: ErrorNumber, data: bytes = b"", servo_id: int | None = None):
    sid = servo.servo_id if servo_id is None else servo_id
    return Reply(sid, build_status(sid, servo.status_error(number), data), _delay(servo))


def _word(params: bytes, offset: int) -> int:
    return params[offset] | (params[offset + 1] << 8)


def dispatch(packet: InstructionPacket | CorruptPacket, servos: Sequence[Servo]) -> list[Reply]:
    """Execute ``packet`` on the responsive ``servos``; the status packets they send back."""
    if isinstance(packet, CorruptPacket):
        return [
            _reply(s, ErrorNumber.CRC)
            for s in servos
            if s.servo_id == packet.servo_id and _answers(s, packet.instruction)
        ]
    if packet.servo_id == BROADCAST_ID:
        return _broadcast(packet, servos)
    replies = []
    for servo in [s for s in servos if s.servo_id == packet.servo_id]:
        servo.heard_from_bus()
        reply = _unicast(packet, servo)
        if reply is not None and _answers(servo, packet.instruction):
            replies.append(reply)
    return replies


def _unicast(packet: InstructionPacket, servo: Servo) -> Reply | None:
    """Run a unicast instruction on one servo; its status packet (before SRL filtering)."""
    instruction, params = packet.instruction, packet.params
    servo_id = servo.servo_id  # answer with the ID the packet reached (factory reset may move it)
    try:
        data = _execute(instruction, params, servo, unicast=True)
    except ServoError as error:
        return _reply(servo, error.number, servo_id=servo_id)
    if instruction in (Instruction.REBOOT, Instruction.FACTORY_RESET):
        # the servo answers before it restarts: data carries the pre-restart alert bit
        return Reply(servo_id, build_status(servo_id, data[0]), _delay(servo))
    return _reply(servo, ErrorNumber.NONE, data, servo_id=servo_id)


def _execute(instruction: int, params: bytes, servo: Servo, unicast: bool) -> bytes:
    """Carry out a single-servo instruction; the status data (raises ServoError)."""
    if instruction == Instruction.PING:
        model = servo.value(Register.MODEL_NUMBER)
        return bytes([model & 0xFF, model >> 8, servo.value(Register.FIRMWARE_VERSION)])
    if instruction == Instruction.READ:
        if len(params) != 4:
            raise ServoError(ErrorNumber.INSTRUCTION, "READ takes address(2) + length(2)")
        return servo.read(_word(params, 0), _word(params, 2))
    if instruction in (Instruction.WRITE, Instruction.REG_WRITE):
        if len(params) < 3:
            raise ServoError(ErrorNumber.DATA_LENGTH, "WRITE takes address(2) + data")
        if instruction == Instruction.WRITE:
            servo.write(_word(params, 0), params[2:])
        else:
            servo.register_write(_word(params, 0), params[2:])
        return b""
    if instruction == Instruction.ACTION:
        servo.action()
        return b""
    if instruction in (Instruction.REBOOT, Instruction.FACTORY_RESET):
        pre_restart_error = bytes([servo.status_error()])
        if instruction == Instruction.REBOOT:
            servo.reboot()
        else:
            if len(params) != 1:
                raise ServoError(ErrorNumber.DATA_LENGTH, "FACTORY_RESET takes one option byte")
            if not unicast and params[0] == FACTORY_RESET_ALL:
                return pre_restart_error  # reset-all is refused on broadcast (keeps IDs apart)
            servo.factory_reset(params[0])
        return pre_restart_error
    if instruction == Instruction.CLEAR:
        servo.clear(params)
        return b""
    raise ServoError(ErrorNumber.INSTRUCTION, f"instruction {instruction:#04x} is not valid here")


def _broadcast(packet: InstructionPacket, servos: Sequence[Servo]) -> list[Reply]:
    instruction, params = packet.instruction, packet.params
    for servo in servos:
        servo.heard_from_bus()
    if instruction == Instruction.PING:
        return [
            _reply(s, ErrorNumber.NONE, _execute(instruction, params, s, unicast=False))
            for s in sorted(servos, key=lambda s: s.servo_id)
        ]
    # a malformed broadcast is ignored: nobody can tell which servo should complain
    with contextlib.suppress(_Malformed):
        if instruction in (Instruction.SYNC_READ, Instruction.FAST_SYNC_READ):
            return _sync_read(params, servos, fast=instruction == Instruction.FAST_SYNC_READ)
        if instruction in (Instruction.BULK_READ, Instruction.FAST_BULK_READ):
            return _bulk_read(params, servos, fast=instruction == Instruction.FAST_BULK_READ)
        if instruction == Instruction.SYNC_WRITE:
            _sync_write(params, servos)
        elif instruction == Instruction.BULK_WRITE:
            _bulk_write(params, servos)
        else:
            for servo in servos:
                with contextlib.suppress(ServoError):  # broadcast errors are not reported
                    _execute(instruction, params, servo, unicast=False)
    return []


class _Malformed(Exception):
    """A sync/bulk parameter block does not add up."""


def _sync_read(params: bytes, servos: Sequence[Servo], fast: bool) -> list[Reply]:
    if len(params) < 5:
        raise _Malformed
    address, length = _word(params, 0), _word(params, 2)
    requests = [(servo_id, address, length) for servo_id in params[4:]]
    return _reads(requests, servos, fast, Instruction.SYNC_READ)


def _bulk_read(params: bytes, servos: Sequence[Servo], fast: bool) -> list[Reply]:
    if not params or len(params) % 5:
        raise _Malformed
    requests = [
        (params[k], _word(params, k + 1), _word(params, k + 3)) for k in range(0, len(params), 5)
    ]
    return _reads(requests, servos, fast, Instruction.BULK_READ)


def _reads(requests, servos: Sequence[Servo], fast: bool, instruction: int) -> list[Reply]:
    """Each listed servo reads its range; separate status packets or one combined packet."""
    by_id = {s.servo_id: s for s in servos}
    parts: list[tuple[Servo | None, int, int, bytes]] = []
    for servo_id, address, length in requests:
        servo = by_id.get(servo_id)
        if servo is None or not _answers(servo, instruction):
            parts.append((None, servo_id, 0, bytes(length)))
            continue
        try:
            parts.append((servo, servo_id, servo.status_error(), servo.read(address, length)))
        except ServoError as error:
            parts.append((servo, servo_id, servo.status_error(error.number), b""))
    if not fast:
        return [
            Reply(servo_id, build_status(servo_id, error, data), _delay(servo))
            for servo, servo_id, error, data in parts
            if servo is not None
        ]
    if parts[0][0] is None:
        return []  # the servo that starts the combined packet is silent: nothing is sent
    # an erroring servo still fills its slot so the others stay where the controller looks
    segments = [
        (servo_id, error, data if data else bytes(length))
        for (_, servo_id, error, data), (_, _, length) in zip(parts, requests, strict=True)
    ]
    packet = build_fast_status(segments)
    silent = next((k for k, part in enumerate(parts) if part[0] is None), None)
    if silent is not None:
        # header(7) + instruction(1) + the segments before the silent servo
        cut = 8 + sum(4 + len(segments[k][2]) for k in range(silent))
        packet = packet[:cut]
    first = parts[0][0]
    return [Reply(BROADCAST_ID, packet, _delay(first))]


def _sync_write(params: bytes, servos: Sequence[Servo]) -> None:
    if len(params) < 4:
        raise _Malformed
    address, length = _word(params, 0), _word(params, 2)
    block = 1 + length
    body = params[4:]
    if length == 0 or len(body) % block:
        raise _Malformed
    for k in range(0, len(body), block):
        _write_quietly(servos, body[k], address, body[k + 1 : k + block])


def _bulk_write(params: bytes, servos: Sequence[Servo]) -> None:
    k = 0
    while k < len(params):
        if k + 5 > len(params):
            raise _Malformed
        servo_id, address, length = params[k], _word(params, k + 1), _word(params, k + 3)
        data = params[k + 5 : k + 5 + length]
        if len(data) != length:
            raise _Malformed
        _write_quietly(servos, servo_id, address, data)
        k += 5 + length


def _write_quietly(servos: Sequence[Servo], servo_id: int, address: int, data: bytes) -> None:
    """Write to the servos answering as ``servo_id``; no status packet carries an error."""
    for servo in servos:
        if servo.servo_id == servo_id:
            with contextlib.suppress(ServoError):
                servo.write(address, data)
