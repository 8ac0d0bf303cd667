"""Single SDK transfers over the simulator's pty, and the error each failure becomes."""

import pytest
from dynamixel_sdk import (
    COMM_NOT_AVAILABLE,
    COMM_PORT_BUSY,
    COMM_RX_CORRUPT,
    COMM_RX_TIMEOUT,
    COMM_SUCCESS,
    COMM_TX_FAIL,
    PacketHandler,
)

from firmware_sim.bus import SimulatedBus
from firmware_sim.wire import RIG_BAUD
from limbctl.errors import BusError, BusTimeout, CorruptReply, PortError
from limbctl.servo import transfers
from limbctl.servo.control_table import ModelNumber, Register


def test_transfers_ping_read_write_keep_error_numbers_and_sync_reads_name_the_absent(sdk):
    outcome = transfers.ping(sdk.packet, sdk.port, 1)
    assert outcome.result == COMM_SUCCESS and outcome.value == ModelNumber.XL430_W250
    outcome = transfers.write(sdk.packet, sdk.port, Register.LED, 2, Register.LED.encode(1))
    assert outcome.result == COMM_SUCCESS and outcome.errors == {2: 0}
    outcome = transfers.read(sdk.packet, sdk.port, Register.LED, 2)
    assert (outcome.result, outcome.value) == (COMM_SUCCESS, 1)
    transfers.write(sdk.packet, sdk.port, Register.TORQUE_ENABLE, 1, [1])
    outcome = transfers.write(sdk.packet, sdk.port, Register.OPERATING_MODE, 1, [3])
    assert outcome.result == COMM_SUCCESS and outcome.errors[1] & 0x7F == 7  # access error
    for read in (transfers.sync_read, transfers.fast_sync_read):
        outcome = read(sdk.packet, sdk.port, Register.MODEL_NUMBER, (1, 2))
        assert outcome.result == COMM_SUCCESS, read.__name__
        assert outcome.value == {1: 1060, 2: 1060}
        assert outcome.errors == {1: 0, 2: 0}
        absent = read(sdk.packet, sdk.port, Register.PRESENT_POSITION, (5, 1))
        assert absent.result != COMM_SUCCESS and absent.culprit == 5, read.__name__


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


def test_a_late_reply_is_never_read_as_the_next_registers_value():
    """A reply delayed past the timeout is refused by its size, never taken for the next one's."""
    wrong, late = [], 0
    reads = ((Register.MODEL_NUMBER, ModelNumber.XL430_W250), (Register.ID, 1))
    with SimulatedBus(ids=(1,), baud=RIG_BAUD, latency_ms=6.0, latency_p=0.3, seed=3) as sim:
        port = transfers.TunedPortHandler(sim.port, latency_timer_ms=1.0)
        assert port.setBaudRate(RIG_BAUD)
        packets = PacketHandler(2.0)
        try:
            for k in range(150):
                # a 2-byte register (model number 1060) between 1-byte ones (ID 1, LED k % 2)
                for register, expected in reads:
                    outcome = transfers.read(packets, port, register, 1)
                    late += outcome.result != COMM_SUCCESS
                    if outcome.result == COMM_SUCCESS and outcome.value != expected:
                        wrong.append((register.name, outcome.value))
                outcome = transfers.write(packets, port, Register.LED, 1, [k % 2])
                late += outcome.result != COMM_SUCCESS
        finally:
            port.closePort()
        delayed = sim.truth()["faults"]["delayed"]
    assert delayed > 30 and late > 0  # the fault happened and some replies came late
    assert wrong == []
