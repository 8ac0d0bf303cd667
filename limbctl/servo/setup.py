"""One-time servo set-up for position control, with the rig's hard limits in EEPROM."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

from limbctl.errors import BusError, ConfigError
from limbctl.servo.control_table import (
    INDIRECT_DATA_1_CANDIDATES,
    MAX_TICK,
    Block,
    DriveModeBit,
    OperatingMode,
    Register,
)
from limbctl.servo.cycle import CYCLE_BYTES, INDIRECT_MAP_BLOCK, ServoReport, indirect_map
from limbctl.servo.families import family_of

if TYPE_CHECKING:
    from limbctl.servo.bus import ServoBus

#: Status Return Level at which every instruction is answered.
STATUS_RETURN_ALL = 2


def configure_servos(
    bus: ServoBus,
    position_limits: Mapping[int, tuple[int, int]],
    profile_velocity: int = 200,
    profile_acceleration: int = 50,
) -> None:
    """Prepare every servo for position control and the cycle read, torque ending OFF:
    ``position_limits`` (id -> (min_tick, max_tick)) in EEPROM, Profile Velocity (0.229 rev/min
    units) and Acceleration (214.577 rev/min^2 units; 0: no limit)."""
    if set(position_limits) != set(bus.ids):
        raise ConfigError(
            f"position_limits must cover exactly the servos {list(bus.ids)}, "
            f"got {sorted(position_limits)}"
        )
    for servo_id, (lo, hi) in position_limits.items():
        if not 0 <= lo <= hi <= MAX_TICK:
            raise ConfigError(
                f"position limits of servo {servo_id} must satisfy 0 <= min <= max <= "
                f"{MAX_TICK}, got ({lo}, {hi})"
            )
    pwm_limits: dict[int, int] = {}
    indirect_data: dict[int, int] = {}
    with bus.exclusive():
        bus.set_torque(False)
        check_supply(bus)
        for servo_id in bus.ids:
            level = bus.read(Register.STATUS_RETURN_LEVEL, servo_id, patient=True)
            if level != STATUS_RETURN_ALL:
                raise ConfigError(
                    f"servo {servo_id} has Status Return Level {level}; limbctl needs "
                    f"{STATUS_RETURN_ALL} (answer every instruction): run `limbctl motors "
                    f"setup`, or power the servo off and on (the level is RAM)"
                )
            lo, hi = position_limits[servo_id]
            drive = bus.read(Register.DRIVE_MODE, servo_id, patient=True)
            eeprom = {
                Register.OPERATING_MODE: int(OperatingMode.POSITION),
                Register.DRIVE_MODE: drive & ~int(DriveModeBit.TIME_BASED_PROFILE),
                Register.RETURN_DELAY_TIME: 0,
                Register.MIN_POSITION_LIMIT: lo,
                Register.MAX_POSITION_LIMIT: hi,
            }
            for register, value in eeprom.items():
                # EEPROM wears: write only what differs, then read it back
                if bus.read(register, servo_id, patient=True) != value:
                    bus.write(register, servo_id, value)
                    got = bus.read(register, servo_id, patient=True)
                    if got != value:
                        raise BusError(
                            f"servo {servo_id} kept {register.name}={got} after writing {value}",
                            servo_id,
                        )
            bus.write(Register.PROFILE_ACCELERATION, servo_id, profile_acceleration)
            bus.write(Register.PROFILE_VELOCITY, servo_id, profile_velocity)
            bus.write_block(INDIRECT_MAP_BLOCK, servo_id, indirect_map())
            if bus.read_block(INDIRECT_MAP_BLOCK, servo_id) != indirect_map():
                raise BusError(
                    f"servo {servo_id} did not keep the indirect address map limbctl wrote "
                    f"(Indirect Address 1-{len(indirect_map()) // 2}): check its firmware",
                    servo_id,
                )
            indirect_data[servo_id] = probe_indirect_data(bus, servo_id)
            # EEPROM, out of the indirect addresses' reach: read once, it changes only by hand
            pwm_limits[servo_id] = bus.read(Register.PWM_LIMIT, servo_id, patient=True)
        bus.note_pwm_limits(pwm_limits)
        bus.note_indirect_data(indirect_data)


def check_supply(bus: ServoBus) -> None:
    """Refuse, before torque goes on, a servo whose supply is outside its family's limits
    (ConfigError naming the servo, the voltage it measures and what its model expects)."""
    for servo_id in bus.ids:
        model = bus.models[servo_id]
        volts = bus.read(Register.PRESENT_INPUT_VOLTAGE, servo_id, patient=True, check_alert=False)
        problem = family_of(model).voltage_problem(model, volts)
        if problem:
            raise ConfigError(f"servo {servo_id}: {problem}")


def probe_indirect_data(bus: ServoBus, servo_id: int) -> int:
    """Where ``servo_id`` keeps Indirect Data 1: the candidate whose cycle block mirrors its
    registers (the indirect map written). The firmware version is not trusted for it. BusError
    if no candidate mirrors the registers (the servo does not keep the map)."""
    goal = bus.read(Register.GOAL_POSITION, servo_id, patient=True)
    torque = bool(bus.read(Register.TORQUE_ENABLE, servo_id, patient=True))
    status = bus.read(Register.HARDWARE_ERROR_STATUS, servo_id, patient=True, check_alert=False)
    expected = (goal, torque, bool(status))
    for address in INDIRECT_DATA_1_CANDIDATES:
        block = Block(Register.INDIRECT_DATA_1, CYCLE_BYTES, at=address)
        try:
            report = ServoReport.decode(bus.read_block(block, servo_id))
        except BusError as exc:
            if type(exc) is not BusError:
                raise  # silent, garbled, in alarm, port gone: not an answer about the address
            continue  # the servo refused the address (its status packet said so): not there
        if (report.goal, report.torque_on, bool(report.hardware_error)) == expected:
            return address
    raise BusError(
        f"servo {servo_id} mirrors its registers at none of the Indirect Data addresses "
        f"{', '.join(map(str, INDIRECT_DATA_1_CANDIDATES))}: check its model and firmware",
        servo_id,
    )
