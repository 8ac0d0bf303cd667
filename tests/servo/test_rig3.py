"""The three-servo rig through the real dynamixel-sdk on the simulator: poses (pan, tilt, roll) in
and out, hard limits on every joint, and the simulator's own full orientation of each goal."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from calib import default_sim_profile
from limbctl.errors import InvalidInputError, SafetyError
from limbctl.geometry.gimbal3 import pose_quat_scalar
from limbctl.servo.rig import Rig
from limbctl.servo.rig3 import RollRig, rig_for
from limbctl.session import open_rig


def test_rig_for_picks_the_class_by_the_profile():
    assert type(rig_for(default_sim_profile())) is Rig
    assert type(rig_for(default_sim_profile("sim3"))) is RollRig
    with pytest.raises(InvalidInputError, match="has no roll joint"):
        RollRig(default_sim_profile())


def test_clamp_and_ticks_on_all_three_joints():
    rig = RollRig(default_sim_profile("sim3"))
    goal = rig.goal_for3((0.0, 0.0, math.radians(150.0)))
    assert goal.clamped
    assert goal.angles[2] == pytest.approx(math.radians(100.0))
    lo, hi = rig.tick_limits()[3]
    assert lo <= goal.ticks[2] <= hi
    held = rig.held_pose3((0.1, 0.2, 0.3))
    # rounding to whole ticks moves each joint by at most half a tick
    assert np.allclose(held, (0.1, 0.2, 0.3), atol=math.pi / 4096 + 1e-12)
    with pytest.raises(InvalidInputError, match="roll angle must be finite"):
        rig.goal_for3((0.0, 0.0, math.nan))


def test_write_read_and_the_simulators_goal_log(tmp_path):
    log = tmp_path / "goals.jsonl"
    with open_rig(rig_path="sim3", goal_log=log) as session:
        rig = session.rig
        assert isinstance(rig, RollRig)
        assert session.profile.ids == (1, 2, 3)
        rig.configure()
        pose = (math.radians(30.0), math.radians(20.0), math.radians(-40.0))
        goal = rig.write_pose(*pose)
        with pytest.raises(SafetyError, match="roll goal tick"):
            rig.write_goal_ticks(goal.ticks[0], goal.ticks[1], 5000)
        rig.set_torque(True)
        assert rig.torque_enabled() == (True, True, True)
        rig.write_pose(*pose)
        # the servos track toward the goal; the read pose has three joints
        present = rig.read_pose()
        assert len(present) == 3
        q = rig.read_quaternion()
        assert q.shape == (4,) and q[0] >= 0
    rows = [json.loads(line) for line in log.read_text().splitlines()]
    last = rows[-1]
    expected = pose_quat_scalar(*rig.angles_of(goal.ticks))
    assert np.allclose(last["limb_q"], expected, atol=1e-12)
