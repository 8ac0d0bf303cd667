"""Simulated operators (limbctl/operators.py) and ``limbctl teleop --operator``: the packaged
ones, files, refusals before anything opens, and a felt leader on the embedded simulator."""

from __future__ import annotations

import json
import re
from dataclasses import replace
from pathlib import Path

import pytest

import calib
from limbctl.cli import main
from limbctl.errors import ConfigError
from limbctl.jobs import Connection, TeleopOptions, run_teleop
from limbctl.live import ViewOptions
from limbctl.operators import OPERATORS, load_operator

EDGE = 30.0


def test_the_packaged_operators_and_an_operator_file_load_with_their_grips(tmp_path):
    push, push3 = load_operator("push", 2), load_operator("push3", 3)
    assert (push.joints, push3.joints) == (2, 3)
    assert push.model == push3.model == "xm430-w350"
    assert push.grip["let_go_s"] == 6.0 and push3.grip["let_go_s"] == 9.0
    assert push.leader_spec((3, 4)) == {"ids": [3, 4], "model": "xm430-w350", "start_deg": [0, 10]}
    assert "(100, 10) deg by 3.5 s and lets go at 6.0 s" in push.describe()
    assert set(OPERATORS) == {"push", "push3"}
    # an operator file is read with its grip
    path = tmp_path / "hand.yaml"
    path.write_text(
        "model: xl330-m288\nstart_deg: [5, 0]\nscript: [[0, 5, 0], [2, 60, 0]]\n"
        "max_torque_nm: 0.1\n"
    )
    operator = load_operator(str(path), 2)
    assert operator.model == "xl330-m288" and operator.start_deg == (5.0, 0.0)
    assert operator.grip == {"script": [[0, 5, 0], [2, 60, 0]], "max_torque_nm": 0.1}
    assert "never lets go" in operator.describe()
    # unknown names and missing files are refused with the known names
    with pytest.raises(ConfigError, match=r"unknown operator 'shove'; known: push, push3"):
        load_operator("shove", 2)
    with pytest.raises(ConfigError, match="no such file"):
        load_operator(str(tmp_path / "gone.yaml"), 2)
    with pytest.raises(ConfigError, match="'push3': it holds a 3-servo leader; this leader has 2"):
        load_operator("push3", 2)


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("script: [[0, 1, 2]]\nhand: 3\n", "unknown keys ['hand']; known: model"),
        ("model: xl999\nscript: [[0, 1, 2]]\n", "no simulated leader of model 'xl999'; known: xm"),
        # a real model, but none the simulator has a motor for
        ("model: xh430-w350\nscript: [[0, 1, 2]]\n", "no simulated leader of model 'xh430-w350'"),
        ("script: [[0, 1, 2]]\nlet_go_s: soon\n", "let_go_s must be a time >= 0 in s"),
        ("script: [[0, 1, 2]]\nlet_go_s: -1\n", "let_go_s must be a time >= 0 in s"),
        ("script: [[0, 1]]\n", "script must be a list of [t_s, pan, tilt] rows"),
        ("script: [[0, 1, .nan]]\n", "script must be a list of [t_s, pan, tilt] rows"),
        ("script: [[1, 1, 2], [0, 1, 2]]\n", "times must not decrease"),
        ("script: [[0, 1, 2]]\nmax_torque_nm: -1\n", "max_torque_nm must be finite and >= 0"),
        ("start_deg: [0, 0, 0]\nscript: [[0, 1, 2, 3]]\n", "it holds a 3-servo leader; this"),
        ("start_deg: [0, true]\nscript: [[0, 1, 2]]\n", "start_deg must be [pan, tilt]"),
        ("- 1\n", "expected a mapping of model, start_deg, script"),
        ("script: [[0, 1, 2]\n", "not valid YAML"),
    ],
)
def test_a_bad_operator_file_is_refused_naming_the_file_and_the_fault(tmp_path, text, says):
    path = tmp_path / "hand.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError) as caught:
        load_operator(str(path), 2)
    assert str(caught.value).startswith(f"operator file {path}: ")
    assert says in str(caught.value)


def test_an_operator_or_a_leader_that_cannot_run_is_refused_before_anything_opens(
    cone_file, tmp_path, capsys
):
    cone_model = cone_file(EDGE)
    stdin = TeleopOptions(model=cone_model, source="stdin", operator="push")
    with pytest.raises(ConfigError, match="use it with --source leader:ID,ID"):
        run_teleop(stdin)
    # the port is never opened: the refusal comes first
    real = TeleopOptions(
        model=cone_model,
        source="leader:3,4",
        operator="push",
        connection=Connection(port="/dev/nonexistent-limbctl-port"),
    )
    with pytest.raises(ConfigError, match="with --port, move the leader by hand"):
        run_teleop(real)
    # nor on a rig profile that names a real port (no --port given)
    profile = tmp_path / "real.yaml"
    sim_yaml = Path(calib.__file__).parent / "rigs" / "sim.yaml"
    profile.write_text(sim_yaml.read_text().replace("port: sim", "port: /dev/ttyUSB9", 1))
    on_rig = replace(real, connection=Connection(rig=profile))
    with pytest.raises(ConfigError, match="with --port, move the leader by hand"):
        run_teleop(on_rig)
    # a leader naming the rig's servos: one line before any port opens (it was a traceback)
    argv = ["teleop", "--model", str(cone_model), "--no-view", "--quiet"]
    assert main([*argv, "--source", "leader:2,3", "--operator", "push"]) == 2
    err = capsys.readouterr().err
    assert "names the rig's servo 2 ('sim' is ids 1, 2): a leader is a second gimbal" in err
    # a two-servo leader gives no twist to a three-servo rig (it crashed in the loop)
    three = ["--rig", "sim3", "--source", "leader:4,5"]
    assert main([*argv, *three]) == 2
    err = capsys.readouterr().err
    assert "a 2-servo leader (4, 5) needs a 2-servo follower: rig 'sim3' has 3 servos; give " in err
    assert "leader:ID,ID,ID (pan, tilt, roll)" in err
    assert "Traceback" not in err
    real = Connection(port="/dev/nonexistent-limbctl-port")
    with pytest.raises(ConfigError, match="names the rig's servos 1, 2"):
        run_teleop(TeleopOptions(model=cone_model, source="leader:1,2", connection=real))
    # an unknown operator, in one line
    assert main([*argv, "--source", "leader:3,4", "--operator", "shove"]) == 2
    err = capsys.readouterr().err
    assert "limbctl teleop: error: unknown operator 'shove'; known: push, push3" in err


#: What a felt run says at its end, and when the feel went off for good (a loaded machine).
PRESSED = r"pressed beyond the edge for ([\d.]+) s, .* ([\d.]+) N m at most"
FEEL_OFF = r"the push is off, mirroring goes on without feel"
#: Per rig: the operator file, its leader, and what the run says the leader feels.
PRESSES = {
    # pressed 25 deg past a 30 deg cone
    "sim": (
        "start_deg: [0, 0]\nscript: [[0, 0, 0], [0.5, 0, 0], [1.5, 55, 0]]\nlet_go_s: 4.0\n",
        "leader:3,4",
        "feels the edge",
    ),
    # roll 150 deg at pan 0, tilt 10, far past the band, in a session opening its source late
    "sim3": (
        "start_deg: [0, 10, 0]\nscript: [[0, 0, 10, 0], [0.5, 0, 10, 0], [2, 0, 10, 150]]\n"
        "let_go_s: 4\n",
        "leader:4,5,6",
        "(three servos) feels the edge in swing and twist",
    ),
}


@pytest.mark.parametrize("rig", list(PRESSES))
def test_a_simulated_operator_presses_a_felt_leader_past_the_edge_on_teleop(
    rig, cone_file, shoulder_model_path, tmp_path, capsys
):
    """``limbctl teleop``'s job for 5 s with an operator file: the operator and its press are
    said (unless a loaded machine switched the feel off); on two servos the follower is held."""
    text, source, feels = PRESSES[rig]
    hand, telemetry = tmp_path / "hand.yaml", tmp_path / "run.jsonl"
    hand.write_text(text)
    run = TeleopOptions(
        model=cone_file(EDGE) if rig == "sim" else shoulder_model_path,
        source=source,
        operator=str(hand),
        duration=5.0,
        quiet=True,
        telemetry=telemetry,
        view=ViewOptions(enabled=False),
        connection=Connection(rig=Path(rig)),
    )
    assert run_teleop(run) == 0
    said = capsys.readouterr().err
    assert f"a simulated operator ({hand}) moves the xm430-w350 leader" in said, said[-800:]
    assert feels in said, said[-800:]
    feel_off = re.search(FEEL_OFF, said)
    pressed = None if feel_off else re.search(PRESSED, said)
    assert pressed or feel_off, said
    assert pressed is None or float(pressed[1]) > 1.0, said
    if rig == "sim3":
        return
    assert pressed is None or float(pressed[2]) > 0.1, said
    rows = [json.loads(line) for line in telemetry.read_text().splitlines()]
    # nothing past the edge was written, however far the operator pressed
    assert max(row["out"][0] for row in rows if row["written"]) <= EDGE + 1e-6
    if pressed:  # the wall held the leader within 2 deg of the edge (bench_haptic.md), up to 6
        # where a loaded machine let a cycle release it
        held = [row["cmd"][0] for row in rows if 2.0 <= row["t"] <= 4.0]
        assert held and EDGE < max(held) < EDGE + 6.0, max(held)
