"""limbctl.teleop.report: telemetry and summary carry the full commanded and written orientation."""

from __future__ import annotations

import io
import json
import math

import numpy as np
import pytest

from limbctl.geometry.gimbal import pan_tilt_to_quat, pose_quat_scalar
from limbctl.geometry.twist import compose, decompose
from limbctl.teleop.cycle import Cycle, CycleState, TeleopSummary
from limbctl.teleop.gate import GateResult, Outcome
from limbctl.teleop.report import Telemetry


def corrected(*pose_deg: float) -> GateResult:
    return GateResult(tuple(map(math.radians, pose_deg)), Outcome.CORRECTED, corrected=True)


#: Per rig, a commanded orientation and the gate's corrected answer; the three-servo command
#: carries a twist (0.9 rad) the gate turned down.
PAN_20 = math.radians(20.0)
RIGS = {
    "two servos": (pan_tilt_to_quat(np.radians(30.0), np.radians(-10.0)), corrected(25.0, -8.0)),
    "three servos": (
        compose(np.array([math.cos(PAN_20), math.sin(PAN_20), 0.0]), 0.9),
        corrected(18.0, 4.0, 30.0),
    ),
}


def written_cycle(index, t, command_deg, result, command_q=None) -> Cycle:
    """A complete running cycle that wrote the gate's ``result``."""
    return Cycle(index, t, CycleState.RUNNING, True, command_deg, command_q, result, written=True)


def logged(command_q: np.ndarray, result) -> dict:
    stream = io.StringIO()
    Telemetry(stream).write(written_cycle(0, 0.01, (0.0, 0.0), result, command_q))
    return json.loads(stream.getvalue())


@pytest.mark.parametrize("rig", list(RIGS))
def test_the_telemetry_and_the_summary_carry_the_full_commanded_and_written_orientation(rig):
    """Joint angles, quaternion and, where the rig has one, twist: in telemetry and summary."""
    command_q, result = RIGS[rig]
    row = logged(command_q, result)
    joints = len(result.pose)
    quat = pose_quat_scalar if joints == 3 else pan_tilt_to_quat
    assert len(row["cmd"]) == len(row["out"]) == joints
    assert np.allclose(row["cmd_q"], command_q, atol=1e-6)
    # the commanded joint angles give back the commanded orientation, roll included
    assert abs(abs(float(np.dot(quat(*np.radians(row["cmd"])), command_q))) - 1.0) < 1e-8
    out_q = quat(*result.pose)  # the written orientation is the written pose's
    assert np.allclose(row["out_q"], out_q, atol=1e-6)
    assert row["out"] == pytest.approx(np.degrees(result.pose), abs=1e-4)
    summary = TeleopSummary(last_command_q=command_q, last_written=result.pose)
    command, written = summary.lines()[-2:]
    assert command.startswith("last command") and written.startswith("last written")
    for text, angles, q in (
        (command, row["cmd"], row["cmd_q"]),
        (written, row["out"], row["out_q"]),
    ):
        assert [f"{v:+.1f}" for v in angles] == [
            word for word in text.replace(",", " ").split() if word[0] in "+-"
        ][: len(angles)]
        assert f"{q[0]:.4f}" in text
    if joints == 3:
        assert row["cmd_twist"] == pytest.approx(math.degrees(0.9), abs=1e-4)
        out_twist = math.degrees(float(decompose(out_q[None])[1][0]))
        assert row["out_twist"] == pytest.approx(out_twist, abs=1e-4)
        assert "roll" in command and f"twist {row['cmd_twist']:+.1f} deg" in command
        assert f"twist {row['out_twist']:+.1f} deg" in written
    else:
        assert "cmd_twist" not in row and "out_twist" not in row
        assert "roll" not in command + written and "twist" not in command + written
