"""Seeded faults of firmware_sim, observed through the real SDK."""

from __future__ import annotations

import time

import pytest
from dynamixel_sdk import COMM_RX_CORRUPT, COMM_RX_TIMEOUT, COMM_SUCCESS

from firmware_sim.faults import FaultInjector, FaultPlan
from tests.safety.support import wait_for

PRESENT_POSITION, HARDWARE_ERROR, TORQUE_ENABLE, SHUTDOWN = 132, 70, 64, 63
VOLTAGE_BIT, OVERHEATING_BIT, ALERT = 0x01, 0x04, 0x80


def outcomes(sdk, count=40):
    return [sdk.packet.read4ByteTxRx(sdk.port, 1, PRESENT_POSITION)[1] for _ in range(count)]


def test_fault_plans_refuse_bad_options_and_the_same_seed_gives_the_same_faults():
    with pytest.raises(ValueError, match="drop"):
        FaultPlan(drop=1.5)
    with pytest.raises(ValueError, match="latency_ms"):
        FaultPlan(latency_ms=-1)

    def pattern(seed):
        injector = FaultInjector(FaultPlan(drop=0.3, corrupt=0.3, seed=seed))
        return [injector.outgoing(bytes(range(12))) for _ in range(50)]

    assert pattern(4) == pattern(4)
    assert pattern(4) != pattern(5)


def test_a_restart_drops_corruption_latency_a_vanished_servo_and_alarms_reach_the_sdk(sdk, sim):
    p, port = sdk.packet, sdk.port
    assert p.write1ByteTxRx(port, 1, TORQUE_ENABLE, 1) == (COMM_SUCCESS, 0)
    sim.restart(1, 0.0)  # a brown-out: the servo restarts with torque off
    assert p.read1ByteTxRx(port, 1, TORQUE_ENABLE) == (0, COMM_SUCCESS, 0)
    sim.set_faults(drop=1.0)
    assert set(outcomes(sdk, 3)) == {COMM_RX_TIMEOUT}
    sim.set_faults(drop=0.5, seed=3)
    first = outcomes(sdk)
    sim.set_faults(drop=0.5, seed=3)
    assert outcomes(sdk) == first  # same seed, same losses
    assert set(first) == {COMM_SUCCESS, COMM_RX_TIMEOUT}
    assert sim.truth()["faults"]["dropped"] >= first.count(COMM_RX_TIMEOUT)
    sim.set_faults(corrupt=1.0, seed=1)
    results = outcomes(sdk, 20)
    assert COMM_SUCCESS not in results
    assert COMM_RX_CORRUPT in results
    sim.set_faults()
    assert outcomes(sdk, 3) == [COMM_SUCCESS] * 3
    sim.set_faults(latency_ms=20.0)
    start = time.perf_counter()
    assert sdk.packet.read4ByteTxRx(sdk.port, 1, PRESENT_POSITION)[1] == COMM_SUCCESS
    assert time.perf_counter() - start >= 0.020
    sim.set_faults()
    sim.vanish(2, 0.3)
    assert sdk.packet.ping(sdk.port, 2)[1] == COMM_RX_TIMEOUT
    assert sdk.packet.ping(sdk.port, 1)[1] == COMM_SUCCESS
    wait_for(lambda: sdk.packet.ping(sdk.port, 2)[1] == COMM_SUCCESS, 5.0, "servo 2 back")
    assert p.write1ByteTxRx(port, 1, TORQUE_ENABLE, 1) == (COMM_SUCCESS, 0)
    sim.set_voltage(1, 5.0)
    wait_for(lambda: p.read1ByteTxRx(port, 1, HARDWARE_ERROR)[0] == VOLTAGE_BIT, 5, "voltage")
    # voltage is not in the default Shutdown mask (52): alert, but torque stays on
    assert p.read1ByteTxRx(port, 1, TORQUE_ENABLE) == (1, COMM_SUCCESS, ALERT)
    sim.set_temperature(2, 95.0)
    wait_for(lambda: p.read1ByteTxRx(port, 2, HARDWARE_ERROR)[0] & OVERHEATING_BIT, 5, "heat")
    assert p.read1ByteTxRx(port, 2, TORQUE_ENABLE) == (0, COMM_SUCCESS, ALERT)
