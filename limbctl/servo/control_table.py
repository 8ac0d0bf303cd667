"""The X-series (Protocol 2.0) registers, model numbers and error codes limbctl uses."""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum, IntEnum, IntFlag

#: Encoder ticks per output-shaft revolution (12-bit absolute encoder).
TICKS_PER_REV = 4096
#: Largest Goal/Present Position tick in single-turn Position Control Mode.
MAX_TICK = TICKS_PER_REV - 1
#: Firmware version from which X-series servos answer Fast Sync Read (instruction 0x8A).
FAST_SYNC_READ_MIN_FIRMWARE = 45
#: The alert bit of a status packet's error byte.
ALERT_BIT = 0x80


class Register(Enum):
    """A control-table entry: ``(address, size in bytes, signed)``."""

    # ---- EEPROM ------------------------------------------------------------------------------
    MODEL_NUMBER = (0, 2, False)
    MODEL_INFORMATION = (2, 4, False)
    FIRMWARE_VERSION = (6, 1, False)
    ID = (7, 1, False)
    BAUD_RATE = (8, 1, False)
    RETURN_DELAY_TIME = (9, 1, False)  # unit 2 us
    DRIVE_MODE = (10, 1, False)
    OPERATING_MODE = (11, 1, False)
    SECONDARY_ID = (12, 1, False)
    PROTOCOL_TYPE = (13, 1, False)
    HOMING_OFFSET = (20, 4, True)
    MOVING_THRESHOLD = (24, 4, False)
    TEMPERATURE_LIMIT = (31, 1, False)
    MAX_VOLTAGE_LIMIT = (32, 2, False)
    MIN_VOLTAGE_LIMIT = (34, 2, False)
    PWM_LIMIT = (36, 2, False)
    CURRENT_LIMIT = (38, 2, False)  # not on XL430/XC430; unit: the family's current unit
    VELOCITY_LIMIT = (44, 4, False)
    MAX_POSITION_LIMIT = (48, 4, False)
    MIN_POSITION_LIMIT = (52, 4, False)
    SHUTDOWN = (63, 1, False)
    # ---- RAM ---------------------------------------------------------------------------------
    TORQUE_ENABLE = (64, 1, False)
    LED = (65, 1, False)
    STATUS_RETURN_LEVEL = (68, 1, False)
    REGISTERED_INSTRUCTION = (69, 1, False)
    HARDWARE_ERROR_STATUS = (70, 1, False)
    BUS_WATCHDOG = (98, 1, True)  # unit 20 ms; -1 = watchdog tripped
    GOAL_PWM = (100, 2, True)
    GOAL_CURRENT = (102, 2, True)  # not on XL430/XC430; unit: the family's current unit
    GOAL_VELOCITY = (104, 4, True)
    PROFILE_ACCELERATION = (108, 4, False)
    PROFILE_VELOCITY = (112, 4, False)
    GOAL_POSITION = (116, 4, True)
    REALTIME_TICK = (120, 2, False)
    MOVING = (122, 1, False)
    MOVING_STATUS = (123, 1, False)
    PRESENT_PWM = (124, 2, True)
    PRESENT_LOAD = (126, 2, True)  # XL430/XC430: load in 0.1 %; the others: Present Current
    PRESENT_CURRENT = (126, 2, True)  # the same register (an alias): mA units by family
    PRESENT_VELOCITY = (128, 4, True)
    PRESENT_POSITION = (132, 4, True)
    VELOCITY_TRAJECTORY = (136, 4, True)
    POSITION_TRAJECTORY = (140, 4, True)
    PRESENT_INPUT_VOLTAGE = (144, 2, False)  # unit 0.1 V
    PRESENT_TEMPERATURE = (146, 1, False)  # unit 1 degC
    # Indirect Address n at 168 + 2 (n - 1) names the RAM address that Indirect Data n at
    # 224 + (n - 1) (208 on older 330 firmware: probed) reads and writes; both RAM
    INDIRECT_ADDRESS_1 = (168, 2, False)
    INDIRECT_DATA_1 = (224, 1, False)

    def __init__(self, address: int, size: int, signed: bool) -> None:
        self.address = address
        self.size = size
        self.signed = signed

    @property
    def min_value(self) -> int:
        """Smallest value the register's width and signedness can hold."""
        return -(1 << (8 * self.size - 1)) if self.signed else 0

    @property
    def max_value(self) -> int:
        """Largest value the register's width and signedness can hold."""
        return (1 << (8 * self.size - (1 if self.signed else 0))) - 1

    def encode(self, value: int) -> list[int]:
        """Little-endian bytes of ``value`` for this register (two's complement if signed);
        ValueError if ``value`` is not an integer or does not fit the register."""
        if isinstance(value, bool) or int(value) != value:
            raise ValueError(f"{self.name} takes an integer, got {value!r}")
        value = int(value)
        if not self.min_value <= value <= self.max_value:
            raise ValueError(f"{self.name} holds {self.min_value}..{self.max_value}, got {value}")
        return list(value.to_bytes(self.size, "little", signed=self.signed))

    def decode(self, data: bytes | bytearray | list[int]) -> int:
        """The integer held by ``size`` little-endian bytes ``data``."""
        if len(data) != self.size:
            raise ValueError(f"{self.name} is {self.size} bytes wide, got {len(data)} bytes")
        return int.from_bytes(bytes(data), "little", signed=self.signed)


#: Indirect Address / Data pairs every family has (the 330s 20, the others 28).
INDIRECT_SLOTS = 20
#: Where Indirect Data 1 may be: 224 on the 430s and 540s; 208 (330 firmware <= 52) or 224.
INDIRECT_DATA_1_CANDIDATES = (224, 208)


@dataclass(frozen=True)
class Block:
    """``size`` raw bytes from ``start``'s address (or ``at``), a :class:`Register` to transfers."""

    start: Register
    size: int
    at: int | None = None

    @property
    def name(self) -> str:
        moved = "" if self.at is None or self.at == self.start.address else f"@{self.at}"
        return f"{self.start.name}{moved}[{self.size} bytes]"

    @property
    def address(self) -> int:
        return self.start.address if self.at is None else self.at

    def decode(self, data: bytes | bytearray | list[int]) -> bytes:
        """The block's bytes, checked for length."""
        if len(data) != self.size:
            raise ValueError(f"{self.name} is {self.size} bytes wide, got {len(data)} bytes")
        return bytes(data)


class OperatingMode(IntEnum):
    """Values of :attr:`Register.OPERATING_MODE`."""

    CURRENT = 0  # not on XL430/XC430 (see limbctl.servo.families)
    VELOCITY = 1
    POSITION = 3
    EXTENDED_POSITION = 4
    CURRENT_BASED_POSITION = 5  # not on XL430/XC430
    PWM = 16


class DriveModeBit(IntFlag):
    """Bits of :attr:`Register.DRIVE_MODE`."""

    REVERSE = 0x01
    TIME_BASED_PROFILE = 0x04


class ModelNumber(IntEnum):
    """What :attr:`Register.MODEL_NUMBER` (and a ping) reports for the supported servos."""

    XH430_W350 = 1000
    XH430_W210 = 1010
    XM430_W350 = 1020
    XM430_W210 = 1030
    XH430_V350 = 1040
    XH430_V210 = 1050
    XL430_W250 = 1060
    XC430_W150 = 1070
    XC430_W240 = 1080
    XL430_W250_2X = 1090  # the 2XL430-W250: two axes, one ID each
    XH540_W270 = 1100
    XH540_W150 = 1110
    XM540_W270 = 1120
    XM540_W150 = 1130
    XH540_V270 = 1140
    XH540_V150 = 1150
    XL330_M077 = 1190
    XL330_M288 = 1200
    XC330_T181 = 1210
    XC330_T288 = 1220
    XC330_M181 = 1230
    XC330_M288 = 1240

    @property
    def title(self) -> str:
        """The e-Manual's name, e.g. ``'XL330-M288'`` or ``'2XL430-W250'``."""
        if self is ModelNumber.XL430_W250_2X:
            return "2XL430-W250"
        return self.name.replace("_", "-")


#: Rig-profile model names -> model numbers (the title in lower case, e.g. ``"xl330-m288"``).
MODEL_BY_NAME: dict[str, ModelNumber] = {model.title.lower(): model for model in ModelNumber}


def model_name(model_number: int) -> str:
    """Readable name of a model number, e.g. ``'XL430-W250 (1060)'`` or ``'unknown (77)'``."""
    try:
        return f"{ModelNumber(model_number).title} ({model_number})"
    except ValueError:
        return f"unknown model ({model_number})"


#: Baud rate in bit/s -> value of :attr:`Register.BAUD_RATE`.
BAUD_RATE_VALUES: dict[int, int] = {
    9600: 0,
    57600: 1,
    115200: 2,
    1_000_000: 3,
    2_000_000: 4,
    3_000_000: 5,
    4_000_000: 6,
    4_500_000: 7,
}
#: The rates the dynamixel-sdk's PortHandler opens (it refuses others, 4.5 Mbps among them).
SDK_BAUDS = frozenset(
    {9600, 19200, 38400, 57600, 115200, 230400, 460800, 500000, 576000, 921600, 1_000_000}
    | {1_152_000, 2_000_000, 2_500_000, 3_000_000, 3_500_000, 4_000_000}
)


class HardwareError(IntFlag):
    """Bits of :attr:`Register.HARDWARE_ERROR_STATUS` (and of :attr:`Register.SHUTDOWN`)."""

    INPUT_VOLTAGE = 0x01
    OVERHEATING = 0x04
    MOTOR_ENCODER = 0x08
    ELECTRICAL_SHOCK = 0x10
    OVERLOAD = 0x20


#: What each hardware error means and what to do about it.
HARDWARE_ERROR_ADVICE: dict[HardwareError, str] = {
    HardwareError.INPUT_VOLTAGE: "input voltage outside the voltage limits: check the supply",
    HardwareError.OVERHEATING: "over the temperature limit: let it cool, reduce the load",
    HardwareError.MOTOR_ENCODER: "motor encoder malfunction: check the servo, it may be damaged",
    HardwareError.ELECTRICAL_SHOCK: "electrical shock or too little power: check the supply",
    HardwareError.OVERLOAD: "persistent overload: free the limb, reduce the load",
}


def decode_hardware_error(status: int) -> tuple[str, ...]:
    """Names of the bits set in a Hardware Error Status byte, lowest first (``'unknown bit N'``)."""
    known = {int(flag): flag for flag in HardwareError}
    names: list[str] = []
    for bit in range(8):
        mask = 1 << bit
        if not status & mask:
            continue
        flag = known.get(mask)
        names.append(flag.name.lower().replace("_", " ") if flag else f"unknown bit {bit}")
    return tuple(names)


class StatusError(IntEnum):
    """Error numbers in bits 0-6 of a status packet's error byte."""

    RESULT_FAIL = 1
    INSTRUCTION = 2
    CRC = 3
    DATA_RANGE = 4
    DATA_LENGTH = 5
    DATA_LIMIT = 6
    ACCESS = 7


#: What each status error number means.
STATUS_ERROR_MEANING: dict[StatusError, str] = {
    StatusError.RESULT_FAIL: "the servo failed to process the instruction",
    StatusError.INSTRUCTION: "undefined instruction, or Action without Reg Write",
    StatusError.CRC: "the instruction packet's CRC did not match (noise on the bus)",
    StatusError.DATA_RANGE: "the data is out of range for that address",
    StatusError.DATA_LENGTH: "the data is shorter than the register",
    StatusError.DATA_LIMIT: "the data is beyond the register's limit",
    StatusError.ACCESS: "read-only/undefined address, or EEPROM written with torque on",
}


def describe_status_error(error_byte: int) -> str:
    """Human description of a status packet's error byte ('' when it reports nothing)."""
    parts: list[str] = []
    number = error_byte & ~ALERT_BIT
    if number:
        try:
            parts.append(f"error {number}: {STATUS_ERROR_MEANING[StatusError(number)]}")
        except ValueError:
            parts.append(f"unknown error number {number}")
    if error_byte & ALERT_BIT:
        parts.append("alert: a hardware error is set (read Hardware Error Status)")
    return "; ".join(parts)
