"""The three-servo leader gimbal's world: three rotors, the operator on each, the roll joint built
like the follower's, its ticks read back as the chain's angles."""

from __future__ import annotations

import pytest

from firmware_sim.control_table import Register
from firmware_sim.leader import LeaderWorld
from firmware_sim.leader3 import LeaderWorld3, Operator3, leader_joints3
from firmware_sim.simulator import Simulator
from firmware_sim.world import ROLL_JOINT


class Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def test_three_ids_give_a_three_servo_leader_and_two_the_two_servo_one():
    clock = Clock()
    sim = Simulator(ids=(1, 2, 3), roll_id=3, leader={"ids": [4, 5, 6]}, clock=clock)
    assert isinstance(sim.leader, LeaderWorld3) and sim.leader.ids == (4, 5, 6)
    assert sim.servo(6).raw_tick == pytest.approx(ROLL_JOINT.zero_tick)  # rests at roll 0
    two = Simulator(ids=(1, 2), leader={"ids": [3, 4]}, clock=clock)
    assert type(two.leader) is LeaderWorld
    with pytest.raises(ValueError, match="three distinct ids"):
        leader_joints3((4, 4, 5))
    with pytest.raises(ValueError, match="unknown leader keys"):
        LeaderWorld3.from_spec({"ids": [4, 5, 6], "colour": "red"})
    with pytest.raises(ValueError, match="roll_deg"):
        sim.set_operator({"script": [[0.0, 10.0, 0.0]]})  # a two-joint script on three joints


def test_the_hand_turns_a_free_leader_about_its_own_axis_and_the_truth_has_three_joints():
    clock = Clock()
    sim = Simulator(ids=(1, 2, 3), roll_id=3, leader={"ids": [4, 5, 6]}, clock=clock)
    sim.set_operator({"script": [[0.0, 0.0, 0.0, 0.0], [1.0, 10.0, -5.0, 40.0]]})
    for _ in range(2000):
        clock.t += 0.001
        sim.advance()
    truth = sim.truth()["leader"]
    pan, tilt, roll = truth["pose_deg"]
    # a free leader (torque off) follows the relaxed hand to within its friction
    assert pan == pytest.approx(10.0, abs=1.0) and tilt == pytest.approx(-5.0, abs=1.0)
    assert roll == pytest.approx(40.0, abs=1.0)
    assert len(truth["motor_nm"]) == 3 and truth["motor_nm"] == [0.0, 0.0, 0.0]
    # the roll servo reads the joint as the follower's roll joint does
    servo = sim.servo(6)
    servo.refresh(sim.time_s)
    tick = servo.value(Register.PRESENT_POSITION)
    expected = ROLL_JOINT.zero_tick + ROLL_JOINT.direction * roll * 4096 / 360
    assert tick == pytest.approx(expected, abs=1.0)


def test_a_three_servo_operator_interpolates_and_lets_go():
    hand = Operator3([[0.0, 0.0, 0.0, 0.0], [2.0, 20.0, -10.0, 40.0]], let_go_s=1.5)
    assert hand.target_deg(3.0) == (20.0, -10.0, 40.0)
    assert hand.torque(1.0, 2, 0.0, 0.0) > 0.0 and hand.torque(1.6, 2, 0.0, 0.0) == 0.0
