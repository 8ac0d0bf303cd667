"""One simulated X-series servo: control-table memory, instruction semantics, errors, motion.
A hardware error in Shutdown latches, turns torque off and alerts until REBOOT; an input voltage
error latches and alerts even outside Shutdown (torque stays on)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from firmware_sim.control_table import (
    DRIVE_MODE_REVERSE,
    DRIVE_MODE_TIME_BASED,
    EEPROM_END,
    HW_INPUT_VOLTAGE,
    HW_OVERHEATING,
    HW_OVERLOAD,
    Access,
    Item,
    Model,
    OperatingMode,
    Register,
)
from firmware_sim.motion import (
    TICKS_PER_TURN,
    VELOCITY_UNIT_TICKS_S,
    Trajectory,
    time_based_limits,
    velocity_based_limits,
)
from firmware_sim.protocol import ALERT_BIT, ErrorNumber

# Overload trips when |load| stays above this many percent of stall torque ...
OVERLOAD_PERCENT = 100.0
# ... for longer than this many seconds (torque on).
OVERLOAD_SECONDS = 0.5
# Bus Watchdog unit: 20 ms
WATCHDOG_UNIT_S = 0.020
WATCHDOG_TRIPPED = 0xFF  # the register reads -1 after a trip
# CLEAR instruction parameters: option 0x01 (multi-turn) and its magic "DXL""
CLEAR_MULTI_TURN = bytes([0x01, 0x44, 0x58, 0x4C, 0x22])
FACTORY_RESET_ALL, FACTORY_RESET_KEEP_ID, FACTORY_RESET_KEEP_ID_BAUD = 0xFF, 0x01, 0x02
POSITION_MODES = (
    OperatingMode.POSITION,
    OperatingMode.EXTENDED_POSITION,
    OperatingMode.CURRENT_BASED_POSITION,
)


class ServoError(Exception):
    """An instruction was refused; carries the Protocol 2.0 error number to answer with."""

    def __init__(self, number: ErrorNumber, reason: str) -> None:
        self.number = number
        super().__init__(reason)


@dataclass(frozen=True)
class Environment:
    """Conditions the servo measures: supply voltage (V) and motor temperature (deg C)."""

    voltage: float = 11.1
    temperature: float = 30.0


class Servo:
    """A servo's memory and firmware logic: it starts with ID ``servo_id`` (it answers whatever
    its ID item holds) and its shaft at ``raw_tick`` (raw ticks); ``on_goal(servo, goal)`` is
    called whenever a Goal Position write takes effect."""

    def __init__(
        self,
        servo_id: int,
        model: Model,
        raw_tick: float,
        on_goal: Callable[[Servo, int], None] | None = None,
    ) -> None:
        self.model = model
        self.memory = bytearray(model.memory_size)
        self._by_address: list[Item | None] = [None] * model.memory_size
        for item in model.items:
            for offset in range(item.size):
                self._by_address[item.address + offset] = item
        self._on_goal = on_goal
        self.environment = Environment(voltage=model.supply_v)
        self.raw_tick = float(raw_tick)
        self.raw_velocity = 0.0
        self.load_percent = 0.0
        self.current_units: int | None = None  # Present Current set by a torque model
        self.trajectory = Trajectory(self.raw_tick)
        self.turn_offset = 0  # whole turns removed by CLEAR (multi-turn reset)
        self._overload_seconds = 0.0
        self._silent_seconds = 0.0
        self._registered: tuple[int, bytes] | None = None
        self._load_defaults(keep=())
        self._set(Register.ID, servo_id)
        self._after_restart()

    def value(self, register: Register) -> int:
        """Current value of ``register`` (signed items decoded)."""
        item = self.model.item(register)
        return self._decode(item, self.memory[item.address : item.address + item.size])

    def preset(self, register: Register, value: int) -> None:
        """Set ``register`` as a previous session left it (before power-up; no checks)."""
        self._set(register, value)

    def _set(self, register: Register, value: int) -> None:
        item = self.model.item(register)
        self.memory[item.address : item.address + item.size] = self._encode(item, value)

    @staticmethod
    def _decode(item: Item, raw: bytes | bytearray) -> int:
        return int.from_bytes(raw, "little", signed=item.signed)

    @staticmethod
    def _encode(item: Item, value: int) -> bytes:
        # two's complement in item.size bytes
        return (value % (1 << (8 * item.size))).to_bytes(item.size, "little")

    def _load_defaults(self, keep: tuple[Register, ...]) -> None:
        kept = {register: self.value(register) for register in keep}
        for item in self.model.items:
            self.memory[item.address : item.address + item.size] = self._encode(item, item.default)
        for register, value in kept.items():
            self._set(register, value)

    @property
    def servo_id(self) -> int:
        return self.memory[self.model.item(Register.ID).address]

    @property
    def torque_on(self) -> bool:
        return self.memory[self.model.item(Register.TORQUE_ENABLE).address] == 1

    @property
    def alert(self) -> bool:
        return self.value(Register.HARDWARE_ERROR_STATUS) != 0

    def status_error(self, number: ErrorNumber = ErrorNumber.NONE) -> int:
        """The error byte of a status packet: error number plus the alert bit."""
        return int(number) | (ALERT_BIT if self.alert else 0)

    def present_from_raw(self, raw: float) -> float:
        """Present Position units for a raw shaft tick (reverse: 4096 - raw; + Homing Offset)."""
        turned = raw - self.turn_offset * TICKS_PER_TURN
        oriented = TICKS_PER_TURN - turned if self._reverse else turned
        return oriented + self.value(Register.HOMING_OFFSET)

    def raw_from_present(self, present: float) -> float:
        """Inverse of :meth:`present_from_raw`."""
        oriented = present - self.value(Register.HOMING_OFFSET)
        turned = TICKS_PER_TURN - oriented if self._reverse else oriented
        return turned + self.turn_offset * TICKS_PER_TURN

    @property
    def _reverse(self) -> bool:
        return bool(self.value(Register.DRIVE_MODE) & DRIVE_MODE_REVERSE)

    def goal_raw_tick(self) -> float:
        """Raw tick the current Goal Position corresponds to."""
        return self.raw_from_present(self.value(Register.GOAL_POSITION))

    def _resolve(self, address: int) -> int:
        """Address actually touched by ``address`` (indirect data redirects)."""
        for first_address, first_data, count in self.model.indirect_blocks:
            if first_data <= address < first_data + count:
                k = address - first_data
                slot = first_address + 2 * k
                return self.memory[slot] | (self.memory[slot + 1] << 8)
        return address

    def read(self, address: int, length: int) -> bytes:
        """Bytes ``address .. address+length`` (indirect data resolved). Raises ServoError."""
        if length <= 0:
            raise ServoError(ErrorNumber.DATA_LENGTH, "READ of zero bytes")
        if address + length > len(self.memory):
            raise ServoError(ErrorNumber.ACCESS, f"READ beyond address {len(self.memory) - 1}")
        targets = [self._resolve(address + offset) for offset in range(length)]
        if all(self._by_address[t] is None for t in targets):
            raise ServoError(ErrorNumber.ACCESS, f"no item at address {address}")
        return bytes(self.memory[t] if self._by_address[t] is not None else 0 for t in targets)

    def check_write(self, address: int, data: bytes) -> dict[Item, int]:
        """Validate a WRITE of ``data`` at ``address``; the items and values it would set
        (ServoError: Access, Data Length, Data Range or Data Limit, as the e-Manual's firmware)."""
        if not data:
            raise ServoError(ErrorNumber.DATA_LENGTH, "WRITE without data")
        if address + len(data) > len(self.memory):
            raise ServoError(ErrorNumber.ACCESS, f"WRITE beyond address {len(self.memory) - 1}")
        staged: dict[int, int] = {}
        for offset, byte in enumerate(data):
            staged[self._resolve(address + offset)] = byte
        items: dict[Item, int] = {}
        for target in staged:
            item = self._by_address[target]
            if item is None:
                raise ServoError(ErrorNumber.ACCESS, f"no item at address {target}")
            if item in items:
                continue
            covered = range(item.address, item.address + item.size)
            if any(a not in staged for a in covered):
                raise ServoError(ErrorNumber.DATA_LENGTH, f"{item.name} needs {item.size} bytes")
            items[item] = self._decode(item, bytes(staged[a] for a in covered))
        for item, value in items.items():
            self._check_item(item, value, items)
        return items

    def _check_item(self, item: Item, value: int, staged: dict[Item, int]) -> None:
        if item.access is Access.R:
            raise ServoError(ErrorNumber.ACCESS, f"{item.name} is read-only")
        if item.address < EEPROM_END and self.torque_on:
            raise ServoError(ErrorNumber.ACCESS, f"{item.name} is EEPROM: turn torque off first")
        if not item.minimum <= value <= item.maximum:
            raise ServoError(
                ErrorNumber.DATA_RANGE,
                f"{item.name}={value} outside {item.minimum}..{item.maximum}",
            )
        register = item.register
        if register is Register.OPERATING_MODE and value not in self.model.operating_modes:
            raise ServoError(ErrorNumber.DATA_RANGE, f"{self.model.title} has no mode {value}")
        if register is Register.TORQUE_ENABLE and value == 1 and self.alert:
            raise ServoError(ErrorNumber.RESULT_FAIL, "hardware error latched: REBOOT first")
        if register in (Register.GOAL_VELOCITY, Register.GOAL_PWM, Register.GOAL_CURRENT) or (
            register is Register.GOAL_POSITION and self._mode() not in POSITION_MODES[:2]
        ):
            if self.memory[self.model.item(Register.BUS_WATCHDOG).address] == WATCHDOG_TRIPPED:
                raise ServoError(ErrorNumber.DATA_RANGE, "bus watchdog tripped: write 0 to it")
        if item.bound is None:
            return
        if register is Register.GOAL_POSITION and self._mode() is not OperatingMode.POSITION:
            return  # multi-turn modes use the item's own range only
        low_register, high_register = item.bound
        high = self._staged_value(high_register, staged)
        low = -high if low_register is None else self._staged_value(low_register, staged)
        if not low <= value <= high:
            raise ServoError(ErrorNumber.DATA_LIMIT, f"{item.name}={value} outside {low}..{high}")

    def _staged_value(self, register: Register, staged: dict[Item, int]) -> int:
        item = self.model.item(register)
        return staged[item] if item in staged else self.value(register)

    def write(self, address: int, data: bytes) -> None:
        """WRITE: validate everything first, then apply atomically. Raises ServoError."""
        self.apply(self.check_write(address, data))

    def apply(self, items: dict[Item, int]) -> None:
        """Store validated values and run their side effects."""
        before_torque = self.torque_on
        for item, value in items.items():
            self.memory[item.address : item.address + item.size] = self._encode(item, value)
        written = {item.register for item in items}
        if Register.OPERATING_MODE in written or Register.DRIVE_MODE in written:
            self.trajectory.hold(self.raw_tick)
        if Register.TORQUE_ENABLE in written and self.torque_on and not before_torque:
            # torque on: hold where the shaft is; Goal Position follows Present Position
            self.trajectory.hold(self.raw_tick)
            self._set(Register.GOAL_POSITION, round(self.present_from_raw(self.raw_tick)))
        if Register.GOAL_POSITION in written:
            self._start_position_move()
            if self._on_goal is not None:
                self._on_goal(self, self.value(Register.GOAL_POSITION))
        if written & {Register.GOAL_VELOCITY, Register.GOAL_PWM, Register.GOAL_CURRENT}:
            self._start_velocity_move()

    def register_write(self, address: int, data: bytes) -> None:
        """REG_WRITE: validate now, apply on ACTION."""
        self.check_write(address, data)
        self._registered = (address, bytes(data))
        self._set(Register.REGISTERED_INSTRUCTION, 1)

    def action(self) -> None:
        """ACTION: apply the registered write (Instruction Error if there is none)."""
        if self._registered is None:
            raise ServoError(ErrorNumber.INSTRUCTION, "ACTION without REG_WRITE")
        address, data = self._registered
        self._registered = None
        self._set(Register.REGISTERED_INSTRUCTION, 0)
        self.write(address, data)

    def factory_reset(self, option: int) -> None:
        """FACTORY_RESET: 0xFF all, 0x01 all but ID, 0x02 all but ID and baud rate."""
        keep = {
            FACTORY_RESET_ALL: (),
            FACTORY_RESET_KEEP_ID: (Register.ID,),
            FACTORY_RESET_KEEP_ID_BAUD: (Register.ID, Register.BAUD_RATE),
        }
        if option not in keep:
            raise ServoError(ErrorNumber.DATA_RANGE, f"factory reset option {option:#04x}")
        self._load_defaults(keep=keep[option])
        self._after_restart()

    def reboot(self) -> None:
        """REBOOT: RAM back to defaults (EEPROM kept), hardware errors cleared, torque off."""
        eeprom = bytes(self.memory[:EEPROM_END])
        self._load_defaults(keep=())
        self.memory[:EEPROM_END] = eeprom
        self._after_restart()

    def _after_restart(self) -> None:
        self._registered = None
        self._overload_seconds = 0.0
        self._silent_seconds = 0.0
        self.trajectory.hold(self.raw_tick)
        self._set(Register.GOAL_POSITION, round(self.present_from_raw(self.raw_tick)))

    def clear(self, params: bytes) -> None:
        """CLEAR option 0x01: drop whole turns so Present Position is back within one turn."""
        if params != CLEAR_MULTI_TURN:
            raise ServoError(ErrorNumber.DATA_RANGE, f"unknown CLEAR parameters {params.hex()}")
        if self.value(Register.MOVING):
            raise ServoError(ErrorNumber.RESULT_FAIL, "CLEAR needs the servo to be stopped")
        unshifted = self.raw_tick - self.turn_offset * TICKS_PER_TURN
        self.turn_offset += int(unshifted // TICKS_PER_TURN)
        self.trajectory.hold(self.raw_tick)

    def _mode(self) -> OperatingMode:
        return OperatingMode(self.value(Register.OPERATING_MODE))

    def _profile_limits(self, distance: float):
        velocity_limit = self.value(Register.VELOCITY_LIMIT)
        velocity = self.value(Register.PROFILE_VELOCITY)
        acceleration = self.value(Register.PROFILE_ACCELERATION)
        if self.value(Register.DRIVE_MODE) & DRIVE_MODE_TIME_BASED:
            return time_based_limits(distance, velocity, acceleration, velocity_limit)
        return velocity_based_limits(velocity, acceleration, velocity_limit)

    def _start_position_move(self) -> None:
        if not self.torque_on or self._mode() not in POSITION_MODES:
            return
        target = self.goal_raw_tick()
        limits = self._profile_limits(target - self.trajectory.position)
        self.trajectory.move_to(target, limits)

    def _start_velocity_move(self) -> None:
        mode = self._mode()
        if not self.torque_on or mode in POSITION_MODES:
            return
        velocity_limit = self.value(Register.VELOCITY_LIMIT)
        if mode is OperatingMode.VELOCITY:
            units = self.value(Register.GOAL_VELOCITY)
        elif mode is OperatingMode.PWM:
            # PWM drives speed in proportion: v = goal_pwm / 885 * velocity_limit
            units = self.value(Register.GOAL_PWM) / 885.0 * velocity_limit
        else:
            # current mode: v = goal_current / current_limit * velocity_limit
            limit = max(self.value(Register.CURRENT_LIMIT), 1)
            units = self.value(Register.GOAL_CURRENT) / limit * velocity_limit
        sign = -1.0 if self._reverse else 1.0
        limits = velocity_based_limits(0, self.value(Register.PROFILE_ACCELERATION), velocity_limit)
        self.trajectory.run_at(sign * units * VELOCITY_UNIT_TICKS_S, limits)

    def drive_setpoint(self, dt: float) -> float | None:
        """Advance the profile by ``dt`` s; the raw-tick setpoint, or None with torque off."""
        if not self.torque_on:
            return None
        self._silent_seconds += dt
        watchdog = self.memory[self.model.item(Register.BUS_WATCHDOG).address]
        watched = self._mode() not in POSITION_MODES[:2]  # a leader's mode 5 too
        late = self._silent_seconds > watchdog * WATCHDOG_UNIT_S
        if 0 < watchdog < WATCHDOG_TRIPPED and watched and late:
            # watchdog trip: stop (mode 5 holds where it is), refuse goals until it is cleared
            self._set(Register.BUS_WATCHDOG, -1 & 0xFF)
            if self._mode() is OperatingMode.CURRENT_BASED_POSITION:
                self.trajectory.hold(self.raw_tick)
            else:
                self.trajectory.run_at(0.0, self.trajectory.limits)
        return self.trajectory.step(dt)

    def heard_from_bus(self) -> None:
        """A packet addressed to this servo arrived (feeds the bus watchdog)."""
        self._silent_seconds = 0.0

    def observe(self, raw_tick: float, raw_velocity: float, load_percent: float, dt: float) -> None:
        """Record where the world moved the shaft; run overload/voltage/temperature checks."""
        self.raw_tick = raw_tick
        self.raw_velocity = raw_velocity
        self.load_percent = load_percent
        if not self.torque_on:
            self.trajectory.hold(raw_tick)
            self._overload_seconds = 0.0
        elif abs(load_percent) > OVERLOAD_PERCENT:
            self._overload_seconds += dt
            if self._overload_seconds > OVERLOAD_SECONDS:
                self._raise_hardware_error(HW_OVERLOAD)
        else:
            self._overload_seconds = 0.0
        self._check_environment()

    def _check_environment(self) -> None:
        volts_tenths = self.environment.voltage * 10.0
        if not (
            self.value(Register.MIN_VOLTAGE_LIMIT)
            <= volts_tenths
            <= self.value(Register.MAX_VOLTAGE_LIMIT)
        ):
            self._raise_hardware_error(HW_INPUT_VOLTAGE)
        if self.environment.temperature > self.value(Register.TEMPERATURE_LIMIT):
            self._raise_hardware_error(HW_OVERHEATING)

    def _raise_hardware_error(self, bit: int) -> None:
        shutdown = self.value(Register.SHUTDOWN)
        if not shutdown & bit and bit != HW_INPUT_VOLTAGE:
            return
        status = self.value(Register.HARDWARE_ERROR_STATUS)
        self._set(Register.HARDWARE_ERROR_STATUS, status | bit)
        if shutdown & bit:
            self._set(Register.TORQUE_ENABLE, 0)
            self.trajectory.hold(self.raw_tick)
            self._overload_seconds = 0.0

    def refresh(self, now_s: float) -> None:
        """Write the measured state into the RAM items a READ returns."""
        present = self.present_from_raw(self.raw_tick)
        sign = -1.0 if self._reverse else 1.0
        velocity_units = sign * self.raw_velocity / VELOCITY_UNIT_TICKS_S
        self._set(Register.PRESENT_POSITION, round(present))
        self._set(Register.PRESENT_VELOCITY, round(velocity_units))
        load = sign * self.load_percent
        if self.model.has(Register.PRESENT_LOAD):
            # unit 0.1 %
            self._set(Register.PRESENT_LOAD, round(max(-1000.0, min(1000.0, load * 10.0))))
        elif self.current_units is not None:  # a leader's motor says it (firmware_sim.torque)
            self._set(Register.PRESENT_CURRENT, round(sign * self.current_units))
        else:
            # the model's unit (2.69 mA on the XM430-W350, stall 2.3 A at 12 V; 1 mA on the 330s)
            current = load / 100.0 * self.model.stall_current_ma / self.model.current_unit_ma
            self._set(Register.PRESENT_CURRENT, round(max(-32768, min(32767, current))))
        pwm_limit = self.value(Register.PWM_LIMIT)
        pwm = load / 100.0 * 885.0 if self.torque_on else 0.0
        self._set(Register.PRESENT_PWM, round(max(-pwm_limit, min(pwm_limit, pwm))))
        self._set(Register.PRESENT_INPUT_VOLTAGE, round(self.environment.voltage * 10.0))
        self._set(Register.PRESENT_TEMPERATURE, round(self.environment.temperature))
        # realtime tick: ms, wraps at 32767
        self._set(Register.REALTIME_TICK, int(now_s * 1000.0) % 32768)
        threshold = self.value(Register.MOVING_THRESHOLD)
        moving = abs(velocity_units) > threshold or (self.torque_on and self.trajectory.active)
        self._set(Register.MOVING, int(moving))
        self._set(Register.MOVING_STATUS, self._moving_status(present, threshold))
        trajectory = self.trajectory
        self._set(
            Register.VELOCITY_TRAJECTORY,
            round(sign * trajectory.velocity / VELOCITY_UNIT_TICKS_S) if self.torque_on else 0,
        )
        self._set(
            Register.POSITION_TRAJECTORY,
            round(self.present_from_raw(trajectory.position)) if self.torque_on else round(present),
        )

    def _moving_status(self, present: float, threshold: int) -> int:
        """Moving Status bits: 0 in position, 1 profile ongoing, 4-5 profile type."""
        status = 0
        if abs(self.value(Register.GOAL_POSITION) - present) <= threshold:
            status |= 0x01
        if self.torque_on and self.trajectory.active:
            status |= 0x02
        velocity = self.value(Register.PROFILE_VELOCITY)
        acceleration = self.value(Register.PROFILE_ACCELERATION)
        # 00 step, 01 rectangle (velocity only), 10 triangle, 11 trapezoid
        if velocity and acceleration:
            status |= 0x30
        elif acceleration:
            status |= 0x20
        elif velocity:
            status |= 0x10
        return status
