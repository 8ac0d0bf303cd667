"""Operator files (firmware_sim/operator_file.py): the leader and its hand as one mapping, for
``firmware-sim --leader --operator`` and ``limbctl teleop --operator``."""

from __future__ import annotations

import pytest

from firmware_sim.leader import LeaderWorld
from firmware_sim.operator_file import leader_spec, read_operator_file


def test_a_two_servo_file_becomes_the_simulators_leader_option(tmp_path):
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


def test_a_three_servo_file_takes_roll_too_and_defaults_the_rest():
    spec = leader_spec({"script": [[0, 0, 0, 0], [1, 0, 0, 50]]}, (4, 5, 6))
    assert spec["model"] == "xm430-w350" and spec["start_deg"] == [0.0, 0.0, 0.0]
    assert "log" not in spec
    world = LeaderWorld.from_spec(spec)
    assert world.operator.target_deg(1.0) == (0.0, 0.0, 50.0)
    world.close()


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


def test_an_unreadable_file_is_named(tmp_path):
    with pytest.raises(ValueError, match="cannot read the operator file"):
        read_operator_file(tmp_path / "missing.yaml")
    broken = tmp_path / "broken.yaml"
    broken.write_text("script: [[0, 1, 2]\n")
    with pytest.raises(ValueError, match=f"{broken}: not valid YAML"):
        read_operator_file(broken)
