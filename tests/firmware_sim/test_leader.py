"""The leader gimbal's world: the operator's hand, friction, let go, the ground-truth log."""

from __future__ import annotations

import json
import math

import pytest

from firmware_sim.leader import LEADER_COULOMB_NM, LeaderWorld, Operator, leader_joints
from firmware_sim.simulator import Simulator
from firmware_sim.world import DEFAULT_JOINTS


class Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def sim_with(operator=None, log=None):
    clock = Clock()
    spec = {"ids": [3, 4], "model": "xm430-w350", "operator": operator, "log": log}
    return Simulator(ids=(1, 2), leader=spec, clock=clock), clock


def test_operator_interpolates_its_script_and_is_bounded():
    hand = Operator([[0.0, 0.0, 0.0], [2.0, 20.0, -10.0]], max_torque_nm=0.1)
    assert hand.target_deg(1.0) == pytest.approx((10.0, -5.0))
    assert hand.target_deg(5.0) == (20.0, -10.0)
    assert hand.torque(1.0, 0, 0.0, 0.0) == pytest.approx(0.1)  # 10 deg x 0.05 N m/deg, bounded
    assert hand.torque(1.0, 1, 0.0, 0.0) == pytest.approx(-0.1)


def test_operator_refuses_bad_scripts_and_keys():
    with pytest.raises(ValueError, match="must not decrease"):
        Operator([[1.0, 0.0, 0.0], [0.5, 1.0, 0.0]])
    with pytest.raises(ValueError, match="finite"):
        Operator([[0.0, math.nan, 0.0]])
    with pytest.raises(ValueError, match="unknown operator keys"):
        Operator.from_mapping({"script": [[0, 0, 0]], "grip": 1})
    with pytest.raises(ValueError, match="unknown leader keys"):
        LeaderWorld.from_spec({"ids": [3, 4], "colour": "red"})


def test_leader_is_built_like_the_follower_at_its_own_ids():
    pan, tilt = leader_joints((3, 4))
    assert (pan.servo_id, tilt.servo_id) == (3, 4)
    assert (pan.zero_tick, tilt.direction) == (DEFAULT_JOINTS[0].zero_tick, -1)
    with pytest.raises(ValueError, match="distinct"):
        leader_joints((3, 3))
    with pytest.raises(ValueError, match="must not be the follower's"):
        Simulator(ids=(1, 2), leader={"ids": [2, 3]})


def test_the_hand_moves_a_free_leader_and_let_go_leaves_it_to_friction(tmp_path):
    log = tmp_path / "leader.jsonl"
    sim, clock = sim_with(
        {"script": [[0.0, 0.0, 0.0], [1.0, 20.0, 10.0]], "let_go_s": 1.5}, str(log)
    )
    clock.t = 1.4
    sim.advance()
    held = sim.truth()["leader"]
    assert held["pose_deg"] == pytest.approx([20.0, 10.0], abs=0.5)
    clock.t = 3.0
    sim.advance()
    truth = sim.truth()["leader"]
    assert truth["hand_nm"] == [0.0, 0.0] and truth["velocity_deg_s"] == [0.0, 0.0]
    assert truth["pose_deg"] == pytest.approx(held["pose_deg"], abs=0.5)  # friction stopped it
    rows = [json.loads(line) for line in log.read_text().splitlines()]
    assert len(rows) == 3000  # one line per 1 ms physics step
    assert {"t", "pose_deg", "hand_nm", "motor_nm", "motor_work_j"} <= set(rows[-1])


def test_stiction_holds_under_a_touch_below_coulomb_friction():
    touch = LEADER_COULOMB_NM * 0.9
    sim, clock = sim_with({"script": [[0.0, 90.0, 0.0]], "max_torque_nm": touch})
    clock.t = 1.0
    sim.advance()
    assert sim.truth()["leader"]["pose_deg"][0] == 0.0


def test_the_leader_servo_reads_where_the_hand_took_it():
    sim, clock = sim_with({"script": [[0.0, 15.0, 0.0]]})
    clock.t = 1.0
    sim.advance()
    servo = sim.servo(3)
    servo.refresh(sim.time_s)
    joint = sim.leader.joints[0]
    assert servo.raw_tick == pytest.approx(joint.raw_tick(math.radians(15.0)), abs=5.0)
    sim.set_operator(None)
    assert sim.leader.operator is None


def test_a_slow_let_go_lowers_the_hands_bound_linearly_to_zero():
    hand = Operator([[0.0, 90.0, 0.0]], let_go_s=1.0, release_s=0.1, max_torque_nm=0.3)
    # far from its target the hand pushes with its whole bound, which falls over 100 ms
    assert hand.torque(0.99, 0, 0.0, 0.0) == pytest.approx(0.3)
    assert hand.torque(1.025, 0, 0.0, 0.0) == pytest.approx(0.225)
    assert hand.torque(1.05, 0, 0.0, 0.0) == pytest.approx(0.15)
    assert hand.torque(1.1, 0, 0.0, 0.0) == 0.0
    assert Operator([[0.0, 90.0, 0.0]], let_go_s=1.0).torque(1.0, 0, 0.0, 0.0) == 0.0
    with pytest.raises(ValueError, match="release_s"):
        Operator([[0.0, 0.0, 0.0]], release_s=-1.0)
