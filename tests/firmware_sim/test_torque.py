"""A leader servo's torque by Operating Mode, and the Present Current that follows from it."""

from __future__ import annotations

import math

import pytest

from firmware_sim.control_table import Register
from firmware_sim.simulator import Simulator
from firmware_sim.torque import MOTORS, LoopGains, drive_of
from tests.firmware_sim.test_leader import sim_with

XM = MOTORS["xm430-w350"]
CAP_UNITS = 100  # 269 mA


def write(servo, register: Register, value: int) -> None:
    item = servo.model.item(register)
    servo.write(item.address, (value % (1 << (8 * item.size))).to_bytes(item.size, "little"))


def settle(sim: Simulator, clock, seconds: float) -> None:
    clock.t += seconds
    sim.advance()


def hold_at(sim, clock, servo_id, mode, goal_current, pan_goal_deg=0.0):
    servo = sim.servo(servo_id)
    write(servo, Register.OPERATING_MODE, mode)
    write(servo, Register.GOAL_CURRENT, goal_current)
    write(servo, Register.TORQUE_ENABLE, 1)
    joint = sim.leader.joints[sim.leader.ids.index(servo_id)]
    write(servo, Register.GOAL_POSITION, round(joint.raw_tick(math.radians(pan_goal_deg))))
    return servo


def pushing(target_deg: float, torque_nm: float = 0.3) -> dict:
    return {"script": [[0.0, target_deg, 0.0]], "max_torque_nm": torque_nm, "stiffness_nm_deg": 1.0}


def test_mode_5_goal_current_sets_the_torque_cap_and_present_current_follows_it(stepped):
    sim, clock = sim_with(stepped, 2, pushing(30.0))
    hold_at(sim, clock, 3, 5, 0)
    settle(sim, clock, 1.0)
    truth = sim.truth()["leader"]
    assert truth["motor_nm"] == [0.0, 0.0]
    assert truth["pose_deg"][0] > 25.0  # the hand moved it as if the motor were not there
    beyond = {}
    for units in (20, 40, CAP_UNITS):
        sim, clock = sim_with(stepped, 2, pushing(30.0, torque_nm=0.3))
        hold_at(sim, clock, 3, 5, units)
        settle(sim, clock, 2.0)
        truth = sim.truth()["leader"]
        cap = units * XM.current_unit_ma * XM.nm_per_ma
        assert abs(truth["motor_nm"][0]) <= cap + 1e-12
        beyond[units] = truth["pose_deg"][0]
    # 20 and 40 units (0.10, 0.19 N m) give way to a 0.3 N m hand; 100 units (0.48 N m) hold it
    assert beyond[20] > beyond[40] > 20.0
    assert beyond[CAP_UNITS] < 0.5
    sim, clock = sim_with(stepped, 2, pushing(30.0, torque_nm=0.2))
    servo = hold_at(sim, clock, 3, 5, CAP_UNITS)
    settle(sim, clock, 2.0)
    truth = sim.truth()
    torque = truth["leader"]["motor_nm"][0]
    assert torque == pytest.approx(-0.2, abs=0.01)  # holds the hand's 0.2 N m
    servo.refresh(sim.time_s)
    expected = torque / XM.nm_per_ma / XM.current_unit_ma  # pan joint direction is +1
    assert servo.value(Register.PRESENT_CURRENT) == round(expected)


def test_mode_3_clips_mode_0_is_a_current_torque_off_has_no_cap_and_the_watchdog_trips(stepped):
    sim, clock = sim_with(stepped, 2, pushing(30.0, torque_nm=0.3))
    servo = sim.servo(3)
    write(servo, Register.CURRENT_LIMIT, 50)  # 0.24 N m: the hand wins
    hold_at(sim, clock, 3, 3, 0)
    settle(sim, clock, 2.0)
    assert sim.truth()["leader"]["pose_deg"][0] > 20.0
    assert abs(sim.truth()["leader"]["motor_nm"][0]) == pytest.approx(
        50 * XM.current_unit_ma * XM.nm_per_ma
    )
    sim, clock = sim_with(stepped, 2)
    servo = sim.servo(3)
    write(servo, Register.OPERATING_MODE, 0)
    write(servo, Register.TORQUE_ENABLE, 1)
    write(servo, Register.GOAL_CURRENT, 20)
    assert drive_of(servo, +1).current_nm == pytest.approx(20 * XM.current_unit_ma * XM.nm_per_ma)
    settle(sim, clock, 0.5)
    assert sim.truth()["leader"]["pose_deg"][0] > 5.0  # a free current turns the joint
    sim, clock = sim_with(stepped, 2)
    servo = sim.servo(3)
    assert drive_of(servo, +1).cap_nm == 0.0
    hold_at(sim, clock, 3, 5, CAP_UNITS)
    write(servo, Register.BUS_WATCHDOG, 1)
    settle(sim, clock, 0.1)  # 100 ms without a packet: tripped
    assert servo.value(Register.BUS_WATCHDOG) == -1 & 0xFF
    assert not servo.trajectory.active  # stopped where it was
    gains = LoopGains.for_joint(XM, 1e-3)
    assert gains.kp * math.radians(2.0) == pytest.approx(XM.stall_torque_nm)
    assert gains.kd > 0.0
