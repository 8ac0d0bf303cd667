"""Servo motion and protection of firmware_sim, through the real SDK over the pty."""

from __future__ import annotations

import math
import time

from dynamixel_sdk import COMM_SUCCESS

from firmware_sim.motion import (
    VELOCITY_UNIT_TICKS_S,
    Trajectory,
    time_based_limits,
    velocity_based_limits,
)
from tests.safety.support import wait_for

DRIVE_MODE, HOMING_OFFSET, TORQUE_ENABLE, HARDWARE_ERROR = 10, 20, 64, 70
PROFILE_ACCELERATION, PROFILE_VELOCITY, GOAL_POSITION = 108, 112, 116
MOVING, PRESENT_LOAD, PRESENT_POSITION, VELOCITY_TRAJECTORY = 122, 126, 132, 136
OVERLOAD_BIT, ALERT = 0x20, 0x80


def write(sdk, servo_id, address, size, value):
    p = sdk.packet
    writer = {1: p.write1ByteTxRx, 2: p.write2ByteTxRx, 4: p.write4ByteTxRx}[size]
    comm, error = writer(sdk.port, servo_id, address, value & ((1 << (8 * size)) - 1))
    assert (comm, error) == (COMM_SUCCESS, 0), f"write {address}={value}: {comm}, {error}"


def read(sdk, servo_id, address, size, signed=True):
    """The item's value; 2- and 4-byte items as two's complement unless ``signed`` is False."""
    p = sdk.packet
    reader = {1: p.read1ByteTxRx, 2: p.read2ByteTxRx, 4: p.read4ByteTxRx}[size]
    value, comm, error = reader(sdk.port, servo_id, address)
    assert comm == COMM_SUCCESS
    bits = 8 * size
    return value - (1 << bits) if signed and size > 1 and value >> (bits - 1) else value


def test_trajectories_respect_their_caps_and_a_time_based_profile_its_time():
    limits = velocity_based_limits(50, 10, 265)
    trajectory = Trajectory(0.0)
    trajectory.move_to(2000.0, limits)
    dt, previous_velocity, peak = 0.001, 0.0, 0.0
    for _ in range(20000):
        trajectory.step(dt)
        if not trajectory.active:
            break  # the last step lands on the target and stops
        assert abs(trajectory.velocity) <= limits.max_velocity + 1e-9
        assert abs(trajectory.velocity - previous_velocity) <= limits.max_acceleration * dt + 1e-6
        previous_velocity = trajectory.velocity
        peak = max(peak, trajectory.velocity)
    assert trajectory.position == 2000.0 and not trajectory.active
    assert math.isclose(peak, 50 * VELOCITY_UNIT_TICKS_S, rel_tol=1e-6)
    limits = time_based_limits(1000.0, 800, 200, 265)
    trajectory = Trajectory(0.0)
    trajectory.move_to(1000.0, limits)
    steps = 0
    while trajectory.active:
        trajectory.step(0.001)
        steps += 1
    assert abs(steps - 800) <= 20  # 0.8 s (the profile's own duration) within 2.5 %


def test_backdrive_hold_overload_position_control_homing_and_watchdog_over_the_pty(sdk, sim):
    """One bus: a hand backdrives a free joint, not a held one; a push trips overload until a
    reboot; moves follow the profile, a blocked goal overloads; homing and drive mode map the
    position; the bus watchdog stops a velocity servo the bus went silent on."""
    before = read(sdk, 1, PRESENT_POSITION, 4)
    # a hand that carries the pan joint to 30 deg within 0.3 s and holds it there
    sim.set_hand({"script": [[0.0, 0.0, 0.0], [0.3, 30.0, 0.0]]})
    wait_for(lambda: abs(sim.truth()["joints_deg"]["pan"] - 30.0) < 0.2, 5.0, "pan at 30 deg")
    assert read(sdk, 1, PRESENT_POSITION, 4) - before > 300  # 30 deg = 341 ticks
    write(sdk, 1, TORQUE_ENABLE, 1, 1)
    held = read(sdk, 1, PRESENT_POSITION, 4)
    sim.set_hand({"script": [[0.0, 30.0, 0.0], [0.3, -30.0, 0.0]]})
    for _ in range(200):
        assert abs(read(sdk, 1, PRESENT_POSITION, 4) - held) <= 5, "the hand moved a held joint"
    assert abs(sim.truth()["joints_deg"]["pan"] - 30.0) < 1.0
    sim.set_hand(None)
    sim.push(1, 150.0)
    wait_for(lambda: abs(read(sdk, 1, PRESENT_LOAD, 2)) > 1000 * 0.99, 5.0, "load to build")
    status = wait_for(lambda: read(sdk, 1, HARDWARE_ERROR, 1, signed=False), 5.0, "overload")
    assert status == OVERLOAD_BIT
    # torque off, and the alert on every reply
    assert sdk.packet.read1ByteTxRx(sdk.port, 1, TORQUE_ENABLE) == (0, COMM_SUCCESS, ALERT)
    assert sdk.packet.ping(sdk.port, 1)[2] == ALERT
    sim.push(1, 0.0)
    assert sdk.packet.reboot(sdk.port, 1)[0] == COMM_SUCCESS
    assert sdk.packet.read1ByteTxRx(sdk.port, 1, HARDWARE_ERROR) == (0, COMM_SUCCESS, 0)
    write(sdk, 1, PROFILE_VELOCITY, 4, 60)
    write(sdk, 1, PROFILE_ACCELERATION, 4, 20)
    write(sdk, 1, TORQUE_ENABLE, 1, 1)
    start = read(sdk, 1, PRESENT_POSITION, 4)
    goal = start + 600
    write(sdk, 1, GOAL_POSITION, 4, goal)
    peak = 0
    deadline = time.monotonic() + 10.0
    while (
        read(sdk, 1, MOVING, 1, signed=False) or abs(read(sdk, 1, PRESENT_POSITION, 4) - goal) > 3
    ):
        peak = max(peak, read(sdk, 1, VELOCITY_TRAJECTORY, 4))
        assert time.monotonic() < deadline, "the move never finished"
    assert 0 < peak <= 60, "the profile velocity does not cap the trajectory"
    assert abs(sim.truth()["servos"][1]["raw_tick"] - goal) <= 3
    # pan's end stop is at +120 deg = 2185 + 1365 ticks; command far beyond it (within limits)
    write(sdk, 1, GOAL_POSITION, 4, 4000)
    wait_for(lambda: read(sdk, 1, HARDWARE_ERROR, 1, signed=False), 10.0, "the stall to trip")
    assert sim.truth()["servos"][1]["torque_on"] is False
    assert sim.truth()["joints_deg"]["pan"] <= 120.0 + 1e-6
    raw = sim.truth()["servos"][2]["raw_tick"]
    assert read(sdk, 2, PRESENT_POSITION, 4) == round(raw)
    write(sdk, 2, HOMING_OFFSET, 4, 1000)
    assert read(sdk, 2, PRESENT_POSITION, 4) == round(raw + 1000)
    write(sdk, 2, DRIVE_MODE, 1, 1)  # reverse
    assert read(sdk, 2, PRESENT_POSITION, 4) == round(4096 - raw + 1000)
    assert sdk.packet.reboot(sdk.port, 1)[0] == COMM_SUCCESS
    operating_mode, bus_watchdog, goal_velocity, present_velocity = 11, 98, 104, 128
    write(sdk, 1, operating_mode, 1, 1)  # velocity control (EEPROM: torque still off)
    write(sdk, 1, bus_watchdog, 1, 5)  # 5 x 20 ms = 100 ms of silence allowed
    write(sdk, 1, TORQUE_ENABLE, 1, 1)
    write(sdk, 1, goal_velocity, 4, -50)  # away from the +120 deg end stop the stall left it at
    # polling keeps the watchdog fed: it must not trip while the bus talks
    wait_for(lambda: read(sdk, 1, present_velocity, 4) <= -45, 5.0, "spin-up")
    assert read(sdk, 1, bus_watchdog, 1, signed=False) == 5
    time.sleep(0.3)  # the behaviour under test is silence itself
    assert read(sdk, 1, bus_watchdog, 1, signed=False) == 0xFF  # tripped: reads -1
    wait_for(lambda: read(sdk, 1, present_velocity, 4) == 0, 5.0, "the stop")
    # velocity goals are refused (Data Range Error) until the watchdog is cleared
    comm, error = sdk.packet.write4ByteTxRx(sdk.port, 1, goal_velocity, 50)
    assert (comm, error & 0x7F) == (COMM_SUCCESS, 4)
    write(sdk, 1, bus_watchdog, 1, 0)
    write(sdk, 1, goal_velocity, 4, -50)
    wait_for(lambda: read(sdk, 1, present_velocity, 4) <= -45, 5.0, "restart")
