"""The leader gimbal's world of two or three joints: the operator's hand, friction, let go, the
joints built like the follower's, the ground-truth log and the operator files."""

from __future__ import annotations

import json
import math
import re

import pytest

from firmware_sim.control_table import Register
from firmware_sim.leader import LEADER_COULOMB_NM, LeaderWorld, Operator, leader_joints
from firmware_sim.operator_file import leader_spec, read_operator_file
from firmware_sim.simulator import Simulator
from firmware_sim.world import DEFAULT_JOINTS, ROLL_JOINT

#: The leader's ids by joint count, and the follower's (the three-servo one with its roll joint).
LEADER_IDS = {2: [3, 4], 3: [4, 5, 6]}
FOLLOWER = {2: {"ids": (1, 2)}, 3: {"ids": (1, 2, 3), "roll_id": 3}}
JOINTS = pytest.mark.parametrize("joints", [2, 3])
#: What an operator's script of the wrong width is told its points should be.
POINTS = {2: "[[t_s, pan_deg, tilt_deg], ...]", 3: "[[t_s, pan_deg, tilt_deg, roll_deg], ...]"}


def sim_with(stepped, joints, operator=None, log=None):
    spec = {"ids": LEADER_IDS[joints], "model": "xm430-w350", "operator": operator, "log": log}
    return stepped(**FOLLOWER[joints], leader=spec)


def row(t, *angles, joints):
    """A script point: the time and the first ``joints`` of (pan, tilt, roll)."""
    return [t, *angles[:joints]]


@JOINTS
def test_operator_interpolates_its_script_is_bounded_and_refuses_bad_scripts_and_keys(joints):
    script = [row(0.0, 0.0, 0.0, 0.0, joints=joints), row(2.0, 20.0, -10.0, 40.0, joints=joints)]
    hand = Operator(script, max_torque_nm=0.1, joints=joints)
    assert hand.target_deg(1.0) == pytest.approx((10.0, -5.0, 20.0)[:joints])
    assert hand.target_deg(5.0) == (20.0, -10.0, 40.0)[:joints]
    assert hand.torque(1.0, 0, 0.0, 0.0) == pytest.approx(0.1)  # 10 deg x 0.05 N m/deg, bounded
    assert hand.torque(1.0, 1, 0.0, 0.0) == pytest.approx(-0.1)
    # the vector of all of them is bounded: 0.1 N m along (10, -5[, 20]) deg
    torques = hand.torques(1.0, [0.0] * joints, [0.0] * joints)
    assert math.hypot(*torques) == pytest.approx(0.1)
    assert torques[0] / torques[1] == pytest.approx(-2.0)
    rest = [0.0] * joints
    with pytest.raises(ValueError, match="must not decrease"):
        Operator([[1.0, *rest], [0.5, *rest]], joints=joints)
    with pytest.raises(ValueError, match="finite"):
        Operator([[0.0, math.nan, *rest[1:]]], joints=joints)
    with pytest.raises(ValueError, match=re.escape(POINTS[joints])):  # the other chain's width
        Operator([[0.0, *[0.0] * (5 - joints)]], joints=joints)
    with pytest.raises(ValueError, match="unknown operator keys"):
        Operator.from_mapping({"script": [[0, *rest]], "grip": 1}, joints)
    with pytest.raises(ValueError, match="unknown operator keys"):
        Operator.from_mapping({"script": [[0, *rest]], "joints": joints})
    with pytest.raises(ValueError, match="unknown leader keys"):
        LeaderWorld.from_spec({"ids": LEADER_IDS[joints], "colour": "red"})
    with pytest.raises(ValueError, match=f"a {joints}-servo leader starts at"):
        LeaderWorld(LEADER_IDS[joints], "xm430-w350", start_deg=[0.0] * (5 - joints))
    with pytest.raises(ValueError, match="two or three joints"):
        Operator([[0.0, 0.0]], joints=1)


@JOINTS
def test_leader_is_built_like_the_follower_at_its_own_ids_and_stiction_holds_a_touch(
    joints, stepped
):
    ids = LEADER_IDS[joints]
    built = leader_joints(ids)
    assert [j.servo_id for j in built] == ids
    follower = (*DEFAULT_JOINTS, ROLL_JOINT)[:joints]
    assert [(j.name, j.zero_tick, j.direction, j.stop_min_deg, j.stop_max_deg) for j in built] == [
        (j.name, j.zero_tick, j.direction, j.stop_min_deg, j.stop_max_deg) for j in follower
    ]
    with pytest.raises(ValueError, match="distinct"):
        leader_joints([*ids[:-1], ids[0]])
    for wrong in ([3], [3, 4, 5, 6]):
        with pytest.raises(ValueError, match="two or three distinct ids"):
            leader_joints(wrong)
    with pytest.raises(ValueError, match="must not be the follower's"):
        Simulator(**FOLLOWER[joints], leader={"ids": [2, *ids[1:]]})
    sim, _ = sim_with(stepped, joints)
    assert sim.leader.ids == tuple(ids)
    for joint in built:  # each rests at its zero
        assert sim.servo(joint.servo_id).raw_tick == pytest.approx(joint.zero_tick)
    with pytest.raises(ValueError, match=re.escape(POINTS[joints])):  # the other chain's hand
        sim.set_operator({"script": [[0.0, *[10.0] * (5 - joints)]]})
    with pytest.raises(ValueError, match=f"cannot hold a {joints}-servo leader"):
        sim.leader.set_operator(Operator([[0.0, *[0.0] * (5 - joints)]], joints=5 - joints))
    touch = LEADER_COULOMB_NM * 0.9
    hand = {"script": [[0.0, 90.0, *[0.0] * (joints - 1)]], "max_torque_nm": touch}
    sim, clock = sim_with(stepped, joints, hand)
    clock.t = 1.0
    sim.advance()
    assert sim.truth()["leader"]["pose_deg"] == [0.0] * joints


@JOINTS
def test_the_hand_moves_a_free_leader_and_let_go_leaves_it_to_friction(joints, tmp_path, stepped):
    log = tmp_path / "leader.jsonl"
    target = [20.0, 10.0, 40.0][:joints]
    script = [row(0.0, 0.0, 0.0, 0.0, joints=joints), [1.0, *target]]
    sim, clock = sim_with(stepped, joints, {"script": script, "let_go_s": 1.5}, str(log))
    clock.t = 1.4
    sim.advance()
    held = sim.truth()["leader"]
    # a free leader (torque off) follows the relaxed hand to within its friction
    assert held["pose_deg"] == pytest.approx(target, abs=0.5)
    assert held["motor_nm"] == [0.0] * joints
    # each servo reads its joint as the follower's joint does
    for joint, angle in zip(sim.leader.joints, held["pose_deg"], strict=True):
        servo = sim.servo(joint.servo_id)
        servo.refresh(sim.time_s)
        expected = joint.zero_tick + joint.direction * angle * 4096 / 360
        assert servo.value(Register.PRESENT_POSITION) == pytest.approx(expected, abs=1.0)
    clock.t = 3.0
    sim.advance()
    truth = sim.truth()["leader"]
    assert truth["hand_nm"] == [0.0] * joints and truth["velocity_deg_s"] == [0.0] * joints
    assert truth["pose_deg"] == pytest.approx(held["pose_deg"], abs=0.5)  # friction stopped it
    rows = [json.loads(line) for line in log.read_text().splitlines()]
    assert len(rows) == 3000  # one line per 1 ms physics step
    assert {"t", "pose_deg", "hand_nm", "motor_nm", "motor_work_j"} <= set(rows[-1])
    assert all(len(value) == joints for key, value in rows[-1].items() if key != "t")
    sim.set_operator(None)
    assert sim.leader.operator is None


def test_a_slow_let_go_lowers_the_bound_and_two_and_three_servo_files_become_the_leader(tmp_path):
    hand = Operator([[0.0, 90.0, 0.0]], let_go_s=1.0, release_s=0.1, max_torque_nm=0.3)
    # far from its target the hand pushes with its whole bound, which falls over 100 ms
    assert hand.torque(0.99, 0, 0.0, 0.0) == pytest.approx(0.3)
    assert hand.torque(1.025, 0, 0.0, 0.0) == pytest.approx(0.225)
    assert hand.torque(1.05, 0, 0.0, 0.0) == pytest.approx(0.15)
    assert hand.torque(1.1, 0, 0.0, 0.0) == 0.0
    assert Operator([[0.0, 90.0, 0.0]], let_go_s=1.0).torque(1.0, 0, 0.0, 0.0) == 0.0
    with pytest.raises(ValueError, match="release_s"):
        Operator([[0.0, 0.0, 0.0]], release_s=-1.0)
    data = {"model": "xl330-m077", "start_deg": [5, 0], "script": [[0, 5, 0], [1, 30, 0]]}
    spec = leader_spec({**data, "let_go_s": 2}, (3, 4), log=str(tmp_path / "log.jsonl"))
    assert spec == {
        "ids": [3, 4],
        "model": "xl330-m077",
        "start_deg": [5.0, 0.0],
        "operator": {"script": [[0, 5, 0], [1, 30, 0]], "let_go_s": 2},
        "log": str(tmp_path / "log.jsonl"),
    }
    world = LeaderWorld.from_spec(spec)  # the simulator builds it as given
    assert world.ids == (3, 4) and world.operator.let_go_s == 2
    world.close()
    spec = leader_spec({"script": [[0, 0, 0, 0], [1, 0, 0, 50]]}, (4, 5, 6))
    assert spec["model"] == "xm430-w350" and spec["start_deg"] == [0.0, 0.0, 0.0]
    assert "log" not in spec
    world = LeaderWorld.from_spec(spec)
    assert world.operator.target_deg(1.0) == (0.0, 0.0, 50.0)
    world.close()
    with pytest.raises(ValueError, match="cannot read the operator file"):
        read_operator_file(tmp_path / "missing.yaml")
    broken = tmp_path / "broken.yaml"
    broken.write_text("script: [[0, 1, 2]\n")
    with pytest.raises(ValueError, match=f"{broken}: not valid YAML"):
        read_operator_file(broken)


@pytest.mark.parametrize(
    ("data", "says"),
    [
        ([1, 2], "expected a mapping of model, start_deg, script"),
        ({"script": [[0, 0, 0]], "grip": 1}, "unknown keys ['grip']"),
        ({"script": [[0, 0, 0]], "model": "xh540-w270"}, "no simulated leader of model"),
        ({"script": [[0, 0, 0, 0]]}, "it holds a 3-servo leader; this leader has 2 servos"),
        ({"script": [[0, 0, 0]], "start_deg": [0, 0, 0]}, "it holds a 3-servo leader"),
        ({"script": [[0, 0, float("inf")]]}, "rows of finite numbers"),
        ({"script": []}, "script must be a list"),
        ({"script": [[0, 0, 0]], "start_deg": [0, "a"]}, "start_deg must be [pan, tilt]"),
        ({"script": [[1, 0, 0], [0, 0, 0]]}, "times must not decrease"),
        ({"script": [[0, 0, 0]], "let_go_s": True}, "let_go_s must be a time >= 0"),
        ({"script": [[0, 0, 0]], "max_torque_nm": float("nan")}, "max_torque_nm must be finite"),
    ],
)
def test_a_bad_file_is_refused_saying_what_is_wrong(data, says):
    with pytest.raises(ValueError) as refused:
        leader_spec(data, (3, 4))
    assert says in str(refused.value)
