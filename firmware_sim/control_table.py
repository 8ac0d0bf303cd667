"""X-series control tables (XL430-W250, XM430-W350, XL330-M077/M288) from the e-Manual."""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

from firmware_sim.registers import Register
from firmware_sim.x_models import register_into


class Access(Enum):
    """Who may touch an item."""

    R = "R"
    RW = "RW"


class OperatingMode(int, Enum):
    """Values of Operating Mode (11)."""

    CURRENT = 0
    VELOCITY = 1
    POSITION = 3
    EXTENDED_POSITION = 4
    CURRENT_BASED_POSITION = 5
    PWM = 16


# Drive Mode (10) bits
DRIVE_MODE_REVERSE = 0x01
DRIVE_MODE_TIME_BASED = 0x04
# Hardware Error Status (70) bits, also the bits of Shutdown (63)
HW_INPUT_VOLTAGE = 0x01
HW_OVERHEATING = 0x04
HW_OVERLOAD = 0x20

EEPROM_END = 64  # addresses below this are EEPROM: locked while Torque Enable is 1
INDIRECT_BLOCKS = ((168, 224, 28), (578, 634, 28))  # (first address item, first data item, count)
MEMORY_SIZE = 662
INDIRECT_ADDRESS_RANGE = (64, 661)
#: The 330s' one block of 20 slots; Indirect Data 1 moved from 208 (firmware <= 52) to 224.
X330_INDIRECT_SLOTS = 20
X330_LAST_FIRMWARE_WITH_DATA_AT_208 = 52
#: Firmware the simulated 330s report unless told otherwise (the e-Manual's layout, data at 208).
X330_FIRMWARE = 52


@dataclass(frozen=True)
class Item:
    """One control-table item: ``register`` (None: indirect), address, size, factory default,
    own range (Data Range Error outside), the items that ``bound`` it (Data Limit Error outside;
    ``(None, R)``: ``-R .. R``) and the e-Manual's ``name``."""

    register: Register | None
    address: int
    size: int
    access: Access
    default: int
    minimum: int
    maximum: int
    signed: bool = False
    bound: tuple[Register | None, Register | None] | None = None
    name: str = ""


@dataclass(frozen=True)
class Model:
    """A servo model: number, firmware version, supported modes and its items."""

    key: str
    title: str
    model_number: int
    firmware_version: int
    operating_modes: frozenset[int]
    items: tuple[Item, ...]
    indirect_blocks: tuple[tuple[int, int, int], ...] = INDIRECT_BLOCKS
    memory_size: int = MEMORY_SIZE
    #: Present Current's unit (mA) and the stall current (mA) the load (% of stall) scales by
    current_unit_ma: float = 2.69
    stall_current_ma: float = 2300.0
    #: The supply the simulated servo sits on (V): the 330s are 5 V servos (3.7..6.0 V)
    supply_v: float = 11.1

    def __post_init__(self) -> None:
        lookup = {item.register: item for item in self.items if item.register is not None}
        object.__setattr__(self, "_lookup", lookup)

    def item(self, register: Register) -> Item:
        """The item named ``register``; KeyError naming the model if it has none."""
        try:
            return self._lookup[register]
        except KeyError:
            raise KeyError(f"{self.title} has no control-table item {register.name}") from None

    def has(self, register: Register) -> bool:
        return register in self._lookup


R, RW = Access.R, Access.RW
I32_MIN, I32_MAX = -(2**31), 2**31 - 1


def _item(register, address, size, access, default, minimum, maximum, bound=None) -> Item:
    """An item named after its register, signed when its range goes below 0."""
    name = register.name.replace("_", " ").title()
    return Item(
        register, address, size, access, default, minimum, maximum, minimum < 0, bound, name
    )


def _common_items(
    temperature_limit,
    voltage,
    velocity_limit,
    gains,
    *,
    baud_max=7,
    protocols=(1, 2),
    vmax=1023,
    shutdown=52,
) -> list[Item]:
    """Items every supported model has (defaults and ranges that differ are arguments)."""
    (v_min, v_max, v_default_max, v_default_min) = voltage
    (vel_i, vel_p, pos_d, pos_i, pos_p) = gains
    reg = Register
    position_limits = (reg.MIN_POSITION_LIMIT, reg.MAX_POSITION_LIMIT)
    return [
        _item(reg.ID, 7, 1, RW, 1, 0, 252),
        _item(reg.BAUD_RATE, 8, 1, RW, 1, 0, baud_max),
        _item(reg.RETURN_DELAY_TIME, 9, 1, RW, 250, 0, 254),
        _item(reg.DRIVE_MODE, 10, 1, RW, 0, 0, 5),
        _item(reg.OPERATING_MODE, 11, 1, RW, 3, 0, 16),
        _item(reg.SECONDARY_ID, 12, 1, RW, 255, 0, 255),
        _item(reg.PROTOCOL_TYPE, 13, 1, RW, 2, *protocols),
        _item(reg.HOMING_OFFSET, 20, 4, RW, 0, -1_044_479, 1_044_479),
        _item(reg.MOVING_THRESHOLD, 24, 4, RW, 10, 0, 1023),
        _item(reg.TEMPERATURE_LIMIT, 31, 1, RW, temperature_limit, 0, 100),
        _item(reg.MAX_VOLTAGE_LIMIT, 32, 2, RW, v_default_max, v_min, v_max),
        _item(reg.MIN_VOLTAGE_LIMIT, 34, 2, RW, v_default_min, v_min, v_max),
        _item(reg.PWM_LIMIT, 36, 2, RW, 885, 0, 885),
        _item(reg.VELOCITY_LIMIT, 44, 4, RW, velocity_limit, 0, vmax),
        _item(reg.MAX_POSITION_LIMIT, 48, 4, RW, 4095, 0, 4095),
        _item(reg.MIN_POSITION_LIMIT, 52, 4, RW, 0, 0, 4095),
        _item(reg.SHUTDOWN, 63, 1, RW, shutdown, 0, 255),
        _item(reg.TORQUE_ENABLE, 64, 1, RW, 0, 0, 1),
        _item(reg.LED, 65, 1, RW, 0, 0, 1),
        _item(reg.STATUS_RETURN_LEVEL, 68, 1, RW, 2, 0, 2),
        _item(reg.REGISTERED_INSTRUCTION, 69, 1, R, 0, 0, 1),
        _item(reg.HARDWARE_ERROR_STATUS, 70, 1, R, 0, 0, 255),
        _item(reg.VELOCITY_I_GAIN, 76, 2, RW, vel_i, 0, 16383),
        _item(reg.VELOCITY_P_GAIN, 78, 2, RW, vel_p, 0, 16383),
        _item(reg.POSITION_D_GAIN, 80, 2, RW, pos_d, 0, 16383),
        _item(reg.POSITION_I_GAIN, 82, 2, RW, pos_i, 0, 16383),
        _item(reg.POSITION_P_GAIN, 84, 2, RW, pos_p, 0, 16383),
        _item(reg.FEEDFORWARD_2ND_GAIN, 88, 2, RW, 0, 0, 16383),
        _item(reg.FEEDFORWARD_1ST_GAIN, 90, 2, RW, 0, 0, 16383),
        # -1 is written by the firmware itself when the watchdog trips (see servo.py)
        _item(reg.BUS_WATCHDOG, 98, 1, RW, 0, 0, 127),
        _item(reg.GOAL_PWM, 100, 2, RW, 0, -885, 885, (None, reg.PWM_LIMIT)),
        _item(reg.GOAL_VELOCITY, 104, 4, RW, 0, -vmax, vmax, (None, reg.VELOCITY_LIMIT)),
        _item(reg.PROFILE_ACCELERATION, 108, 4, RW, 0, 0, 32767),
        _item(reg.PROFILE_VELOCITY, 112, 4, RW, 0, 0, 32767),
        _item(reg.GOAL_POSITION, 116, 4, RW, 0, -(2**20 - 1), 2**20 - 1, position_limits),
        _item(reg.REALTIME_TICK, 120, 2, R, 0, 0, 32767),
        _item(reg.MOVING, 122, 1, R, 0, 0, 1),
        _item(reg.MOVING_STATUS, 123, 1, R, 0, 0, 255),
        _item(reg.PRESENT_PWM, 124, 2, R, 0, -885, 885),
        _item(reg.PRESENT_VELOCITY, 128, 4, R, 0, I32_MIN, I32_MAX),
        _item(reg.PRESENT_POSITION, 132, 4, R, 0, I32_MIN, I32_MAX),
        _item(reg.VELOCITY_TRAJECTORY, 136, 4, R, 0, I32_MIN, I32_MAX),
        _item(reg.POSITION_TRAJECTORY, 140, 4, R, 0, I32_MIN, I32_MAX),
        _item(reg.PRESENT_INPUT_VOLTAGE, 144, 2, R, 0, 0, 65535),
        _item(reg.PRESENT_TEMPERATURE, 146, 1, R, 0, 0, 255),
    ]


def _header_items(model_number: int, firmware_version: int) -> list[Item]:
    reg = Register
    return [
        _item(reg.MODEL_NUMBER, 0, 2, R, model_number, 0, 65535),
        _item(reg.MODEL_INFORMATION, 2, 4, R, 0, 0, 2**32 - 1),
        _item(reg.FIRMWARE_VERSION, 6, 1, R, firmware_version, 0, 255),
    ]


def _current_items(limit: int) -> list[Item]:
    """Current Limit, Goal Current and Present Current of a model that measures current."""
    reg = Register
    return [
        _item(reg.CURRENT_LIMIT, 38, 2, RW, limit, 0, limit),
        _item(reg.GOAL_CURRENT, 102, 2, RW, 0, -limit, limit, (None, reg.CURRENT_LIMIT)),
        _item(reg.PRESENT_CURRENT, 126, 2, R, 0, -32768, 32767),
    ]


def _indirect_items(blocks=INDIRECT_BLOCKS, address_range=INDIRECT_ADDRESS_RANGE) -> list[Item]:
    """Indirect Address n (2 bytes, default = address of Indirect Data n) and Indirect Data n."""
    items = []
    for first_address, first_data, count in blocks:
        base = 1 if first_address == blocks[0][0] else 1 + blocks[0][2]
        for k in range(count):
            low, high = address_range
            address, data = first_address + 2 * k, first_data + k
            items.append(
                Item(None, address, 2, RW, data, low, high, name=f"Indirect Address {base + k}")
            )
            items.append(Item(None, data, 1, RW, 0, 0, 255, name=f"Indirect Data {base + k}"))
    return items


def _model(key: str, title: str, number: int, modes, items: list[Item], **kw) -> Model:
    """A model at firmware 46 (the 330s pass theirs) with its items in address order."""
    firmware = kw.pop("firmware_version", 46)
    ordered = tuple(sorted(items, key=lambda i: i.address))
    return Model(key, title, number, firmware, frozenset(modes), ordered, **kw)


def _xl430_w250() -> Model:
    items = _header_items(1060, 46)
    items += _common_items(72, (60, 140, 140, 60), 265, (1000, 100, 4000, 0, 640))
    items.append(_item(Register.PRESENT_LOAD, 126, 2, R, 0, -1000, 1000))
    return _model("xl430-w250", "XL430-W250", 1060, {1, 3, 4, 16}, items + _indirect_items())


def _xm430_w350() -> Model:
    items = _header_items(1020, 46)
    items += _common_items(80, (95, 160, 160, 95), 200, (1920, 100, 0, 0, 800))
    ports = [Register[f"EXTERNAL_PORT_MODE_{k}"] for k in (1, 2, 3)]
    items += [_item(port, 56 + k, 1, RW, 3, 0, 3) for k, port in enumerate(ports)]
    items += _current_items(1193) + _indirect_items()
    return _model("xm430-w350", "XM430-W350", 1020, {0, 1, 3, 4, 5, 16}, items)


def x330_indirect_blocks(firmware_version: int) -> tuple[tuple[int, int, int], ...]:
    """The 330s' indirect block for a firmware version: Indirect Data 1 at 208, or 224 after 52."""
    first_data = 208 if firmware_version <= X330_LAST_FIRMWARE_WITH_DATA_AT_208 else 224
    return ((168, first_data, X330_INDIRECT_SLOTS),)


def _xl330(key: str, title: str, number: int, velocity_limit: int, gains, stall_ma: float):
    """An XL330 (5 V family): Present Current in 1 mA, Current Limit 1750 mA, six modes."""

    def build(firmware_version: int = X330_FIRMWARE) -> Model:
        reg = Register
        blocks = x330_indirect_blocks(firmware_version)
        end = blocks[0][1] + blocks[0][2]  # one past the last Indirect Data
        items = _header_items(number, firmware_version)
        common = dict(baud_max=6, protocols=(2, 22), vmax=2047, shutdown=53)
        items += _common_items(70, (31, 70, 70, 35), velocity_limit, gains, **common)
        items += [
            _item(reg.STARTUP_CONFIGURATION, 60, 1, RW, 0, 0, 3),
            _item(reg.PWM_SLOPE, 62, 1, RW, 140, 1, 255),
            _item(reg.BACKUP_READY, 147, 1, R, 0, 0, 1),
        ]
        items += _current_items(1750) + _indirect_items(blocks, (64, end - 1))
        memory = dict(indirect_blocks=blocks, memory_size=end, firmware_version=firmware_version)
        power = dict(current_unit_ma=1.0, stall_current_ma=stall_ma, supply_v=5.0)
        return _model(key, title, number, {0, 1, 3, 4, 5, 16}, items, **memory, **power)

    return build


#: Builders of the 330s by firmware version (the indirect data address depends on it).
X330_BUILDERS = {
    # gains (Velocity I, Velocity P, Position D, Position I, Position P); stall 1.47 A at 5 V
    "xl330-m077": _xl330("xl330-m077", "XL330-M077", 1190, 1620, (400, 40, 0, 400, 400), 1470.0),
    "xl330-m288": _xl330("xl330-m288", "XL330-M288", 1200, 445, (1600, 180, 0, 0, 400), 1470.0),
}

MODELS: dict[str, Model] = {
    m.key: m for m in (_xl430_w250(), _xm430_w350(), *(build() for build in X330_BUILDERS.values()))
}
# the rest of the X series shares these tables (firmware_sim.x_models)
register_into(MODELS, X330_BUILDERS)


def get_model(key: str) -> Model:
    """The model called ``key`` (case-insensitive); ValueError listing the choices otherwise.
    A 330 may name its firmware, ``"xl330-m288@53"``: after 52 its Indirect Data moved to 224."""
    name, _, firmware = key.lower().partition("@")
    try:
        if firmware:
            return X330_BUILDERS[name](int(firmware))
        return MODELS[name]
    except (KeyError, ValueError):
        raise ValueError(
            f"unknown servo model {key!r}; choose one of: {', '.join(sorted(MODELS))} (a 330 "
            f"with its firmware version: xl330-m288@53)"
        ) from None
