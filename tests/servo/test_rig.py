"""The rig of either chain: conversion, hard limits, and poses through the SDK on the simulator."""

from __future__ import annotations

import json
import math
import time

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from calib import default_sim_profile
from limbctl.errors import InvalidInputError, SafetyError
from limbctl.geometry import gimbal
from limbctl.servo.profiles import joint_tick_limits
from limbctl.servo.rig import Rig
from limbctl.session import open_rig

RIGS = ("sim", "sim3")
PROFILES = {name: default_sim_profile(name) for name in RIGS}
TICK_RAD = 2 * math.pi / 4096
#: Poses (rad) of up to three joints; a rig takes the first of them, one per joint.
poses = st.lists(st.floats(-4.0, 4.0), min_size=3, max_size=3)


@pytest.fixture(params=RIGS)
def rig(request):
    return Rig(PROFILES[request.param])


def test_the_chain_is_the_profiles_joints_in_order_and_a_rig_converts_clamps_and_limits(rig):
    two, three = Rig(PROFILES["sim"]), Rig(PROFILES["sim3"])
    assert (two.names, three.names) == (("pan", "tilt"), ("pan", "tilt", "roll"))
    assert (len(two), len(three)) == (2, 3)
    assert three.joints == (PROFILES["sim3"].pan, PROFILES["sim3"].tilt, PROFILES["sim3"].roll)
    assert (two.ids, three.ids) == ((1, 2), (1, 2, 3))
    joints = rig.joints
    assert rig.angles_to_ticks(*[0.0] * len(rig)) == tuple(j.zero_tick for j in joints)
    # ticks = zero_tick + direction * angle * 4096 / (2 pi)
    assert rig.angles_to_ticks(*[math.pi / 4] * len(rig)) == tuple(
        j.zero_tick + j.direction * 512 for j in joints
    )
    assert rig.ticks_to_angles(*(j.zero_tick + 1024 for j in joints)) == pytest.approx(
        tuple(j.direction * math.pi / 2 for j in joints)
    )
    inside = (0.1, -0.2, 0.3)[: len(rig)]
    assert rig.clamp(*inside) == (inside, False)
    angles, clamped = rig.clamp(*[4.0 if i % 2 == 0 else -4.0 for i in range(len(rig))])
    assert clamped
    assert angles == tuple(j.max_rad if i % 2 == 0 else j.min_rad for i, j in enumerate(rig.joints))
    for i, name in enumerate(rig.names):
        for bad in (float("nan"), float("inf")):
            with pytest.raises(InvalidInputError, match=f"{name} angle must be finite"):
                rig.clamp(*(bad if k == i else 0.0 for k in range(len(rig))))
    with pytest.raises(SafetyError, match=f"takes {len(rig)} angles"):
        rig.goal_for(*[0.0] * (5 - len(rig)))
    zeros = [j.zero_tick for j in rig.joints]
    for i, (name, joint) in enumerate(zip(rig.names, rig.joints, strict=True)):
        lo, hi = joint_tick_limits(joint)
        for bad in (hi + 1, lo - 1, lo + 0.5):
            ticks = [*zeros[:i], bad, *zeros[i + 1 :]]
            with pytest.raises(SafetyError, match=rf"{name} goal tick .* outside the hard limits"):
                rig.write_goal_ticks(*ticks)
    with pytest.raises(SafetyError, match=f"takes {len(rig)} goal ticks"):
        rig.write_goal_ticks(*zeros[:-1])
    with pytest.raises(RuntimeError, match="no bus"):
        rig.read_pose()
    assert rig.tick_limits() == {j.id: joint_tick_limits(j) for j in rig.joints}


@pytest.mark.parametrize("name", RIGS)
@given(pose=poses)
def test_goal_ticks_are_inside_the_hard_limits_and_held_as_written(name, pose):
    rig = Rig(PROFILES[name])
    pose = tuple(pose[: len(rig)])
    goal = rig.goal_for(*pose)
    for tick, joint in zip(goal.ticks, rig.joints, strict=True):
        lo, hi = joint_tick_limits(joint)
        assert lo <= tick <= hi
    inside = all(j.min_rad <= a <= j.max_rad for a, j in zip(pose, rig.joints, strict=True))
    assert goal.clamped == (not inside)
    if inside:
        # exact inside the limits: nearest tick, within half a tick of the command
        back = rig.ticks_to_angles(*goal.ticks)
        assert np.all(np.abs(np.subtract(back, pose)) <= TICK_RAD / 2 + 1e-12)
    # the held pose is the written goal back in radians
    held = rig.held_pose(*pose)
    assert rig.angles_to_ticks(*held) == goal.ticks
    # half a tick of rounding; a clamped joint is kept on a tick strictly inside, up to a tick
    rounding = TICK_RAD if goal.clamped else TICK_RAD / 2
    assert np.all(np.abs(np.subtract(held, goal.angles)) <= rounding + 1e-12)


@pytest.mark.parametrize("name", RIGS)
def test_present_pose_matches_the_world_and_write_pose_reaches_it_clamped_and_logged(
    name, tmp_path
):
    log = tmp_path / "goals.jsonl"
    with open_rig(rig_path=name, goal_log=log) as session:
        rig, sim = session.rig, session.simulator
        pose = rig.read_pose()
        truth = sim.truth()["joints_deg"]
        # the sim profile is the world's true geometry: within a tick of the truth
        assert len(pose) == len(rig)
        want = [truth[joint_name] for joint_name in rig.names]
        assert np.degrees(pose) == pytest.approx(want, abs=math.degrees(TICK_RAD))
        rig.configure(profile_velocity=0, profile_acceleration=0)
        # tilt beyond its limit; the roll inside its own
        target = (math.radians(30.0), math.radians(90.0), math.radians(-40.0))[: len(rig)]
        goal = rig.write_pose(*target)
        assert goal.clamped and goal.angles[1] == pytest.approx(rig.joints[1].max_rad)
        rig.set_torque(True)
        assert rig.torque_enabled() == (True,) * len(rig)
        rig.write_pose(*target)
        expected = np.degrees(rig.ticks_to_angles(*goal.ticks))

        def arrived():
            truth = sim.truth()["joints_deg"]
            return all(abs(truth[n] - e) < 0.5 for n, e in zip(rig.names, expected, strict=True))

        deadline = time.monotonic() + 10.0
        while not arrived():
            assert time.monotonic() < deadline, sim.truth()["joints_deg"]
            rig.read_pose()  # one bus round trip per wait step
        assert math.degrees(rig.read_pose()[1]) <= rig.joints[1].max_deg
    last = json.loads(log.read_text().splitlines()[-1])
    held = rig.ticks_to_angles(*goal.ticks)
    assert np.allclose(last["limb_dir"], gimbal.pan_tilt_to_direction(*held[:2]), atol=1e-12)
    if len(rig) == 3:  # the simulator's own full orientation of the goal
        assert np.allclose(last["limb_q"], gimbal.pose_quat(*held), atol=1e-12)
