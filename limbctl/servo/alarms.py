"""Servo alarms: what a hardware error means for torque as each servo reports it, and reboots."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Protocol

from limbctl.errors import ServoAlarm
from limbctl.servo.control_table import HARDWARE_ERROR_ADVICE, HardwareError


class RebootableBus(Protocol):
    """What :func:`reboot_servos_in_alarm` needs of a bus (:class:`limbctl.servo.bus.ServoBus`)."""

    def read_hardware_errors(self) -> dict[int, tuple[str, ...]]: ...

    def reboot(self, servo_id: int, timeout_s: float = 3.0) -> None: ...


def _advice(bits: tuple[str, ...]) -> str:
    return "; ".join(
        HARDWARE_ERROR_ADVICE[flag]
        for flag in HardwareError
        if flag.name.lower().replace("_", " ") in bits
    )


def _torque_clause(servo_id: int, torque_on: bool | None) -> str:
    if torque_on is None:
        return f"servo {servo_id}'s torque state could not be read"
    if torque_on:
        return (
            f"servo {servo_id} keeps torque on (this error is not in its Shutdown mask) and "
            f"the alert stays until it is rebooted"
        )
    return f"servo {servo_id} has torque off, and it cannot be switched on until it is rebooted"


def alarm_message(
    found: Mapping[int, tuple[str, ...]], torque_on: Mapping[int, bool | None] | None = None
) -> str:
    """The message of a :class:`limbctl.errors.ServoAlarm` for ``found`` (id -> decoded bits) and
    ``torque_on`` (id -> Torque Enable as reported; missing: unread; None: the alarm alone)."""
    detail = "; ".join(f"servo {i}: {', '.join(bits)}" for i, bits in found.items())
    advice = "; ".join(_advice(bits) for bits in found.values())
    if torque_on is None:
        return f"hardware error reported ({detail}). {advice}: fix the cause, then `limbctl reboot`"
    torque = "; ".join(_torque_clause(i, torque_on.get(i)) for i in found)
    return (
        f"hardware error reported ({detail}). {advice}. {torque}: fix the cause, then "
        f"`limbctl reboot`"
    )


def alarm_alone(alarm: ServoAlarm) -> ServoAlarm:
    """The bus's alarm told without its torque, for a caller that then says the torque."""
    if alarm.servo_id is None or not alarm.bits:
        return alarm
    return ServoAlarm(alarm_message({alarm.servo_id: alarm.bits}), alarm.servo_id, alarm.bits)


def _joined(names: list[str]) -> str:
    return " and ".join(names)


def held_torque(torque: Mapping[str, bool], after_alarm: bool = False) -> str:
    """What the HOLD safe state left, from ``torque`` (joint -> Torque Enable, read after)."""
    on = [name for name, enabled in torque.items() if enabled]
    off = [name for name, enabled in torque.items() if not enabled]
    if not off:
        return "holding the last safe pose (torque on)"
    held = f"; {_joined(on)} holding the last safe pose (torque on)" if on else ""
    advice = "" if after_alarm else " (after an alarm: fix the cause, then `limbctl reboot`)"
    return f"{_joined(off)} torque off as the servo reports it{advice}{held}"


def switched_off(reported: Mapping[str, bool | None]) -> str:
    """What TORQUE_OFF says, from ``reported`` (joint -> last Torque Enable read; None: unknown)."""
    already = [name for name, enabled in reported.items() if enabled is False]
    switched = [name for name in reported if name not in already]
    if not already:
        return "torque switched off"
    servos = "servos" if len(already) > 1 else "servo"
    was = f"{_joined(already)} torque was already off (as the {servos} reported it)"
    if not switched:
        return f"{was}; it stays off"
    return f"torque switched off on {_joined(switched)}; {was}"


@dataclass(frozen=True)
class Rebooted:
    """A servo that was in alarm and was rebooted: its id and the alarm it had."""

    servo_id: int
    alarm: tuple[str, ...]

    def describe(self) -> str:
        return f"servo {self.servo_id} was in alarm ({', '.join(self.alarm)}): rebooted, torque off"


def reboot_servos_in_alarm(bus: RebootableBus) -> list[Rebooted]:
    """Reboot every servo in alarm (torque off, RAM reset: configure again before driving)."""
    rebooted = []
    for servo_id, bits in bus.read_hardware_errors().items():
        if bits:
            bus.reboot(servo_id)
            rebooted.append(Rebooted(servo_id, bits))
    return rebooted
