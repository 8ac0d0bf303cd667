"""A leader's servos in current-based position mode (5): which models can, and their set-up."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from limbctl.errors import BusError, ConfigError
from limbctl.servo.control_table import (
    INDIRECT_SLOTS,
    Block,
    ModelNumber,
    OperatingMode,
    Register,
    model_name,
)
from limbctl.servo.cycle import CYCLE_BYTES, CYCLE_REGISTERS, ServoReport, indirect_map

if TYPE_CHECKING:
    from limbctl.servo.bus import ServoBus


@dataclass(frozen=True)
class LeaderMotor:
    """What the controller needs of a current-sensing model's motor: the e-Manual's stall torque
    (N m) at its stall current (mA), one current unit (mA) and the Current Limit's factory
    maximum (units); ``loop_stall_error_deg``: the position error (deg) at which the factory-gain
    loop asks for stall torque (2: the simulator's; measure a real one's); ``let_go_cap_nm``: a cap
    (N m) for a loop so soft a released leader would snap back over 30 deg/s (docs/haptic.md)."""

    stall_torque_nm: float
    stall_current_ma: float
    current_unit_ma: float
    max_current_units: int
    loop_stall_error_deg: float = 2.0
    let_go_cap_nm: float | None = None

    @property
    def loop_nm_per_deg(self) -> float:
        """The position loop's stiffness at the output (N m per deg of error)."""
        return self.stall_torque_nm / self.loop_stall_error_deg

    def units_for(self, torque_nm: float) -> int:
        """Goal Current units for a torque (N m), rounded down: never more than asked."""
        units = abs(torque_nm) * self.stall_current_ma / self.stall_torque_nm / self.current_unit_ma
        return min(int(units), self.max_current_units)

    def torque_of(self, units: int) -> float:
        """The torque (N m) a current of ``units`` gives."""
        return units * self.current_unit_ma * self.stall_torque_nm / self.stall_current_ma

    def cap_nm(self, asked_nm: float) -> float:
        """``asked_nm`` (N m) capped at CAP_STALL_FRACTION of stall and ``let_go_cap_nm``."""
        cap = min(asked_nm, CAP_STALL_FRACTION * self.stall_torque_nm)
        return cap if self.let_go_cap_nm is None else min(cap, self.let_go_cap_nm)


#: A felt leader pushes with at most half its stall torque: cool and out of Overload for seconds.
CAP_STALL_FRACTION = 0.5


#: Models whose leader can push back; XL330-M288's cap: docs/bench_haptic_models.md.
FELT_MODELS: dict[ModelNumber, LeaderMotor] = {
    ModelNumber.XM430_W350: LeaderMotor(4.1, 2300.0, 2.69, 1193),
    ModelNumber.XL330_M077: LeaderMotor(0.215, 1470.0, 1.0, 1750),
    ModelNumber.XL330_M288: LeaderMotor(0.52, 1470.0, 1.0, 1750, let_go_cap_nm=0.12),
}

#: The felt leader's registers, in Indirect Data order after the cycle's read block.
FEEL_REGISTERS = (Register.GOAL_CURRENT, Register.GOAL_POSITION)
FEEL_BYTES = sum(register.size for register in FEEL_REGISTERS)
assert CYCLE_BYTES + FEEL_BYTES <= INDIRECT_SLOTS


def feel_data(indirect_data_1: int = Register.INDIRECT_DATA_1.address) -> Block:
    """Where a felt leader's command goes: after the cycle's block from ``indirect_data_1``."""
    return Block(Register.INDIRECT_DATA_1, FEEL_BYTES, indirect_data_1 + CYCLE_BYTES)


#: :func:`feel_data` where Indirect Data 1 is at 224.
FEEL_DATA = feel_data()
#: The Indirect Addresses that map it (two bytes per data byte; at 168 + 2 n on every family).
FEEL_MAP = Block(
    Register.INDIRECT_ADDRESS_1,
    2 * FEEL_BYTES,
    Register.INDIRECT_ADDRESS_1.address + 2 * CYCLE_BYTES,
)


def feel_map() -> bytes:
    """The bytes of the Indirect Addresses that map :data:`FEEL_REGISTERS`, little-endian."""
    return indirect_map(FEEL_REGISTERS)


def _slot(register: Register) -> int:
    """Where the cycle's read block holds ``register`` (bytes from Indirect Data 1)."""
    return sum(r.size for r in CYCLE_REGISTERS[: CYCLE_REGISTERS.index(register)])


def _slot_map(mapped: Register, slot_register: Register) -> Block:
    """The Indirect Addresses of ``slot_register``'s slot, to hold ``mapped`` (same size)."""
    assert mapped.size == slot_register.size
    return Block(
        Register.INDIRECT_ADDRESS_1,
        2 * mapped.size,
        Register.INDIRECT_ADDRESS_1.address + 2 * _slot(slot_register),
    )


#: A felt leader's cycle read carries Present Current in Present PWM's slot.
CURRENT_MAP = _slot_map(Register.PRESENT_CURRENT, Register.PRESENT_PWM)
#: And Present Velocity in Goal Position's (a leader's goal is the law's, not read back).
VELOCITY_MAP = _slot_map(Register.PRESENT_VELOCITY, Register.GOAL_POSITION)


def present_current(report: ServoReport) -> int:
    """A felt leader's Present Current (the model's units, signed) from its cycle read."""
    return report.pwm


def present_velocity(report: ServoReport) -> int:
    """A felt leader's Present Velocity (0.229 rev/min units, signed) from its cycle read."""
    return report.goal


def encode_feel(goal_current: int, goal_position: int) -> bytes:
    """One servo's :data:`FEEL_DATA` bytes."""
    values = (goal_current, goal_position)
    return b"".join(bytes(r.encode(v)) for r, v in zip(FEEL_REGISTERS, values, strict=True))


def felt_motor(bus: ServoBus, ids: Sequence[int]) -> LeaderMotor | None:
    """The motor of a leader whose servos can push back; None when their model cannot
    (ConfigError if the leader's servos are of different models)."""
    models = {bus.models[i] for i in ids}
    if len(models) != 1:
        names = ", ".join(f"servo {i}: {model_name(bus.models[i])}" for i in ids)
        raise ConfigError(f"the leader's servos must be one model, got {names}")
    return FELT_MODELS.get(models.pop())


def configure_felt_leader(
    bus: ServoBus, ids: Sequence[int], cap_units: int, watchdog_units: int
) -> None:
    """Set the leader's servos up for feel (mode 5, Current Limit ``cap_units``, Bus Watchdog
    ``watchdog_units`` x 20 ms, the maps); torque ends ON with Goal Current 0. ConfigError if a
    servo refuses mode 5 (its model has none), BusError if one does not keep what was written."""
    with bus.exclusive():
        bus.set_torque(False, ids)
        for servo_id in ids:
            eeprom: Mapping[Register, int] = {
                Register.OPERATING_MODE: int(OperatingMode.CURRENT_BASED_POSITION),
                Register.CURRENT_LIMIT: cap_units,
            }
            for register, value in eeprom.items():
                if bus.read(register, servo_id, patient=True) != value:
                    try:
                        bus.write(register, servo_id, value)
                    except BusError as exc:
                        raise ConfigError(
                            f"leader servo {servo_id} refused {register.name}={value} ({exc}): "
                            f"a felt leader needs current-based position mode (mode 5)"
                        ) from None
                if bus.read(register, servo_id, patient=True) != value:
                    raise BusError(f"servo {servo_id} did not keep {register.name}", servo_id)
            maps = (
                (FEEL_MAP, feel_map()),
                (CURRENT_MAP, indirect_map((Register.PRESENT_CURRENT,))),
                (VELOCITY_MAP, indirect_map((Register.PRESENT_VELOCITY,))),
            )
            for block, data in maps:
                bus.write_block(block, servo_id, data)
                if bus.read_block(block, servo_id) != data:
                    raise BusError(f"servo {servo_id} did not keep the feel map", servo_id)
            bus.write(Register.GOAL_CURRENT, servo_id, 0)
            bus.write(Register.PROFILE_ACCELERATION, servo_id, 0)
            bus.write(Register.PROFILE_VELOCITY, servo_id, 0)  # free: the setpoint rides along
            bus.write(Register.BUS_WATCHDOG, servo_id, 0)  # clears a trip from before
            bus.write(Register.BUS_WATCHDOG, servo_id, watchdog_units)
        bus.set_torque(True, ids)
