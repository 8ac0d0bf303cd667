"""Single SDK transfers over the simulator's pty, and the error each failure becomes."""

import pytest
from dynamixel_sdk import (
    COMM_NOT_AVAILABLE,
    COMM_PORT_BUSY,
    COMM_RX_CORRUPT,
    COMM_RX_TIMEOUT,
    COMM_SUCCESS,
    COMM_TX_FAIL,
)

from limbctl.errors import BusError, BusTimeout, CorruptReply, PortError
from limbctl.servo import transfers
from limbctl.servo.control_table import ModelNumber, Register


def test_ping_read_write(sdk):
    outcome = transfers.ping(sdk.packet, sdk.port, 1)
    assert outcome.result == COMM_SUCCESS and outcome.value == ModelNumber.XL430_W250
    outcome = transfers.write(sdk.packet, sdk.port, Register.LED, 2, Register.LED.encode(1))
    assert outcome.result == COMM_SUCCESS and outcome.errors == {2: 0}
    outcome = transfers.read(sdk.packet, sdk.port, Register.LED, 2)
    assert (outcome.result, outcome.value) == (COMM_SUCCESS, 1)


@pytest.mark.parametrize("read", [transfers.sync_read, transfers.fast_sync_read])
def test_sync_reads_agree_with_single_reads(sdk, read):
    outcome = read(sdk.packet, sdk.port, Register.MODEL_NUMBER, (1, 2))
    assert outcome.result == COMM_SUCCESS
    assert outcome.value == {1: 1060, 2: 1060}
    assert outcome.errors == {1: 0, 2: 0}


@pytest.mark.parametrize("read", [transfers.sync_read, transfers.fast_sync_read])
def test_sync_read_of_an_absent_servo_names_it(sdk, read):
    outcome = read(sdk.packet, sdk.port, Register.PRESENT_POSITION, (5, 1))
    assert outcome.result != COMM_SUCCESS
    assert outcome.culprit == 5


def test_refused_write_keeps_the_error_number(sdk):
    transfers.write(sdk.packet, sdk.port, Register.TORQUE_ENABLE, 1, [1])
    outcome = transfers.write(sdk.packet, sdk.port, Register.OPERATING_MODE, 1, [3])
    assert outcome.result == COMM_SUCCESS and outcome.errors[1] & 0x7F == 7  # access error


@pytest.mark.parametrize(
    ("result", "error_type", "fragment"),
    [
        (COMM_RX_TIMEOUT, BusTimeout, "servo 2 did not answer after 3 attempts"),
        (COMM_RX_CORRUPT, CorruptReply, "kept failing CRC/framing"),
        (COMM_TX_FAIL, PortError, "could not send on /dev/x"),
        (COMM_PORT_BUSY, BusError, "busy"),
        (COMM_NOT_AVAILABLE, BusError, "not available"),
        (-12345, BusError, "SDK result -12345"),
    ],
)
def test_failure_maps_results_to_typed_errors(result, error_type, fragment):
    error = transfers.failure("read X", transfers.Attempt(None, result, {}, 2), 3, 57600, "/dev/x")
    assert type(error) is error_type
    assert fragment in str(error) and str(error).startswith("read X: ")
    assert error.servo_id == (2 if result != COMM_PORT_BUSY else None)
