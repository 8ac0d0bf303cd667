import pytest

from limbctl.servo.control_table import (
    ALERT_BIT,
    BAUD_RATE_VALUES,
    MODEL_BY_NAME,
    HardwareError,
    ModelNumber,
    OperatingMode,
    Register,
    StatusError,
    decode_hardware_error,
    describe_status_error,
    model_name,
)

# (address, size, signed) from the XL430-W250 / XM430-W350 e-Manual control tables
E_MANUAL = {
    "MODEL_NUMBER": (0, 2, False),
    "FIRMWARE_VERSION": (6, 1, False),
    "ID": (7, 1, False),
    "BAUD_RATE": (8, 1, False),
    "RETURN_DELAY_TIME": (9, 1, False),
    "DRIVE_MODE": (10, 1, False),
    "OPERATING_MODE": (11, 1, False),
    "HOMING_OFFSET": (20, 4, True),
    "VELOCITY_LIMIT": (44, 4, False),
    "MAX_POSITION_LIMIT": (48, 4, False),
    "MIN_POSITION_LIMIT": (52, 4, False),
    "SHUTDOWN": (63, 1, False),
    "TORQUE_ENABLE": (64, 1, False),
    "LED": (65, 1, False),
    "STATUS_RETURN_LEVEL": (68, 1, False),
    "HARDWARE_ERROR_STATUS": (70, 1, False),
    "BUS_WATCHDOG": (98, 1, True),
    "GOAL_PWM": (100, 2, True),
    "GOAL_CURRENT": (102, 2, True),
    "CURRENT_LIMIT": (38, 2, False),
    "PROFILE_ACCELERATION": (108, 4, False),
    "PROFILE_VELOCITY": (112, 4, False),
    "GOAL_POSITION": (116, 4, True),
    "MOVING": (122, 1, False),
    "PRESENT_LOAD": (126, 2, True),
    "PRESENT_VELOCITY": (128, 4, True),
    "PRESENT_POSITION": (132, 4, True),
    "PRESENT_INPUT_VOLTAGE": (144, 2, False),
    "PRESENT_TEMPERATURE": (146, 1, False),
}


@pytest.mark.parametrize(("name", "spec"), sorted(E_MANUAL.items()))
def test_registers_match_the_e_manual(name, spec):
    register = Register[name]
    assert (register.address, register.size, register.signed) == spec


def test_registers_models_modes_bauds_hardware_errors_and_status_errors():
    spans = sorted((r.address, r.address + r.size, r.name) for r in Register)
    for (_, end, name), (start, _, next_name) in zip(spans[:-1], spans[1:], strict=True):
        assert end <= start, f"{name} overlaps {next_name}"
    with pytest.raises(ValueError, match="TORQUE_ENABLE holds 0..255, got 256"):
        Register.TORQUE_ENABLE.encode(256)
    with pytest.raises(ValueError, match="PROFILE_VELOCITY holds 0"):
        Register.PROFILE_VELOCITY.encode(-1)
    with pytest.raises(ValueError, match="integer"):
        Register.GOAL_POSITION.encode(1.5)
    with pytest.raises(ValueError, match="4 bytes wide"):
        Register.GOAL_POSITION.decode(b"\x00\x00")
    assert (ModelNumber.XL430_W250, ModelNumber.XM430_W350) == (1060, 1020)
    assert MODEL_BY_NAME["xl430-w250"] is ModelNumber.XL430_W250
    assert model_name(1020) == "XM430-W350 (1020)"
    assert model_name(7) == "unknown model (7)"
    assert MODEL_BY_NAME["xl330-m077"] == 1190 and MODEL_BY_NAME["xl330-m288"] == 1200
    assert model_name(1200) == "XL330-M288 (1200)"
    # Present Load and Present Current are one register whose meaning depends on the family
    assert Register.PRESENT_CURRENT is Register.PRESENT_LOAD
    assert (OperatingMode.POSITION, OperatingMode.EXTENDED_POSITION) == (3, 4)
    assert (BAUD_RATE_VALUES[57600], BAUD_RATE_VALUES[1_000_000]) == (1, 3)
    assert int(HardwareError.INPUT_VOLTAGE) == 1 << 0
    assert int(HardwareError.OVERHEATING) == 1 << 2
    assert int(HardwareError.MOTOR_ENCODER) == 1 << 3
    assert int(HardwareError.ELECTRICAL_SHOCK) == 1 << 4
    assert int(HardwareError.OVERLOAD) == 1 << 5
    assert decode_hardware_error(0) == ()
    assert decode_hardware_error(0x24) == ("overheating", "overload")
    assert decode_hardware_error(0x19) == ("input voltage", "motor encoder", "electrical shock")
    assert decode_hardware_error(0x02) == ("unknown bit 1",)
    assert [e.value for e in StatusError] == list(range(1, 8))
    assert StatusError.ACCESS == 7 and StatusError.CRC == 3
    assert describe_status_error(0) == ""
    assert "CRC" in describe_status_error(3)
    assert "torque on" in describe_status_error(7)
    both = describe_status_error(ALERT_BIT | 4)
    assert "out of range" in both and "Hardware Error Status" in both
    assert "unknown error number 9" in describe_status_error(9)


@pytest.mark.parametrize(
    ("register", "value", "raw"),
    [
        (Register.GOAL_POSITION, 2048, [0x00, 0x08, 0x00, 0x00]),
        (Register.GOAL_POSITION, -1, [0xFF, 0xFF, 0xFF, 0xFF]),
        (Register.HOMING_OFFSET, -1044479, [0x01, 0x10, 0xF0, 0xFF]),
        (Register.PRESENT_LOAD, -1000, [0x18, 0xFC]),
        (Register.BUS_WATCHDOG, -1, [0xFF]),
        (Register.MODEL_NUMBER, 1060, [0x24, 0x04]),
        (Register.TORQUE_ENABLE, 1, [0x01]),
    ],
)
def test_encode_decode_little_endian_twos_complement(register, value, raw):
    assert register.encode(value) == raw
    assert register.decode(bytes(raw)) == value
