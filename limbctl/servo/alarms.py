"""Servo alarms: what a hardware error means for torque, and the way out (a reboot).

An X-series servo latches a hardware error into Hardware Error Status (70) and raises the alert
bit of every status packet until it is rebooted. Whether it also switched torque off depends on
its Shutdown (63) mask: the factory mask leaves an input-voltage error out, so after a voltage
alarm torque is still on. Messages therefore state the torque each servo REPORTS, never both.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Protocol

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
    return f"servo {servo_id} switched torque off and keeps it off until it is rebooted"


def alarm_message(
    found: Mapping[int, tuple[str, ...]], torque_on: Mapping[int, bool | None]
) -> str:
    """The message of a :class:`limbctl.errors.ServoAlarm`.

    Parameters
    ----------
    found : mapping id -> decoded hardware error bits
        Only servos with bits set.
    torque_on : mapping id -> bool
        Torque Enable as each servo reports it (a missing id: could not be read).
    """
    detail = "; ".join(f"servo {i}: {', '.join(bits)}" for i, bits in found.items())
    advice = "; ".join(_advice(bits) for bits in found.values())
    torque = "; ".join(_torque_clause(i, torque_on.get(i)) for i in found)
    return (
        f"hardware error reported ({detail}). {advice}. {torque}: fix the cause, then "
        f"`limbctl reboot` (ServoBus.reboot)"
    )


@dataclass(frozen=True)
class Rebooted:
    """A servo that was in alarm and was rebooted: its id and the alarm it had."""

    servo_id: int
    alarm: tuple[str, ...]

    def describe(self) -> str:
        return f"servo {self.servo_id} was in alarm ({', '.join(self.alarm)}): rebooted, torque off"


def reboot_servos_in_alarm(bus: RebootableBus) -> list[Rebooted]:
    """Reboot every servo whose Hardware Error Status is set; the ones rebooted, with the alarm.

    A reboot clears the error, switches torque off and resets RAM (profile velocity, the cycle's
    indirect map): configure the servos again before driving them. Healthy servos are left alone.
    """
    rebooted = []
    for servo_id, bits in bus.read_hardware_errors().items():
        if bits:
            bus.reboot(servo_id)
            rebooted.append(Rebooted(servo_id, bits))
    return rebooted
