"""limbctl.teleop.report: every rig's telemetry carries its full commanded and written
orientation in one form (joint angles, quaternion, and twist where the rig has one)."""

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

#: A commanded pose (deg) and the pose the gate wrote (rad) per rig: the three-servo command
#: carries a twist the gate turned down (corrected).
RIGS = {
    "two servos": (
        pan_tilt_to_quat(np.radians(30.0), np.radians(-10.0)),
        GateResult((math.radians(25.0), math.radians(-8.0)), Outcome.CORRECTED, corrected=True),
    ),
    "three servos": (
        compose(np.array([math.cos(math.radians(20.0)), math.sin(math.radians(20.0)), 0.0]), 0.9),
        GateResult(
            (math.radians(18.0), math.radians(4.0), math.radians(30.0)),
            Outcome.CORRECTED,
            corrected=True,
        ),
    ),
}


def logged(command_q: np.ndarray, result) -> dict:
    stream = io.StringIO()
    cycle = Cycle(
        index=0,
        t=0.01,
        state=CycleState.RUNNING,
        complete=True,
        command_deg=(0.0, 0.0),  # the loop's (pan, tilt) of the command, as it has always been
        command_q=command_q,
        result=result,
        written=True,
    )
    Telemetry(stream).write(cycle)
    return json.loads(stream.getvalue())


@pytest.mark.parametrize("rig", list(RIGS))
def test_the_telemetry_and_the_summary_carry_the_full_commanded_and_written_orientation(rig):
    """Joint angles, quaternion and, where the rig has one, twist: in telemetry and summary."""
    command_q, result = RIGS[rig]
    row = logged(command_q, result)
    joints = len(result.pose)
    assert len(row["cmd"]) == len(row["out"]) == joints
    assert np.allclose(row["cmd_q"], command_q, atol=1e-6)
    # the commanded joint angles give back the commanded orientation, roll included
    angles = np.radians(row["cmd"])
    back = pose_quat_scalar(*angles) if joints == 3 else pan_tilt_to_quat(*angles)
    assert abs(abs(float(np.dot(back, command_q))) - 1.0) < 1e-8
    # the written orientation is the written pose's
    written = pose_quat_scalar(*result.pose) if joints == 3 else pan_tilt_to_quat(*result.pose)
    assert np.allclose(row["out_q"], written, atol=1e-6)
    assert row["out"] == pytest.approx(np.degrees(result.pose), abs=1e-4)
    if joints == 3:
        assert row["cmd_twist"] == pytest.approx(math.degrees(0.9), abs=1e-4)
        assert row["out_twist"] == pytest.approx(
            math.degrees(float(decompose(written[None])[1][0])), abs=1e-4
        )
    else:
        assert "cmd_twist" not in row and "out_twist" not in row
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
    if rig == "three servos":
        assert "roll" in command and f"twist {row['cmd_twist']:+.1f} deg" in command
        assert f"twist {row['out_twist']:+.1f} deg" in written
    else:
        assert "roll" not in command + written and "twist" not in command + written
