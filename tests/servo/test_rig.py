import math
import time

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from calib import default_sim_profile
from limbctl.errors import InvalidInputError, SafetyError
from limbctl.geometry import gimbal
from limbctl.servo.bus import ServoBus
from limbctl.servo.profiles import joint_tick_limits
from limbctl.servo.rig import Rig

PROFILE = default_sim_profile()
TICK_RAD = 2 * math.pi / 4096


@pytest.fixture
def rig():
    return Rig(PROFILE)


def test_conversion_follows_the_profile(rig):
    pan, tilt = PROFILE.pan, PROFILE.tilt
    assert rig.angles_to_ticks(0.0, 0.0) == (pan.zero_tick, tilt.zero_tick)
    # ticks = zero_tick + direction * angle * 4096 / (2 pi)
    assert rig.angles_to_ticks(math.pi / 4, math.pi / 4) == (
        pan.zero_tick + pan.direction * 512,
        tilt.zero_tick + tilt.direction * 512,
    )
    assert rig.ticks_to_angles(pan.zero_tick + 1024, tilt.zero_tick - 1024) == pytest.approx(
        (pan.direction * math.pi / 2, -tilt.direction * math.pi / 2)
    )


def test_clamp(rig):
    assert rig.clamp(0.1, -0.2) == (0.1, -0.2, False)
    pan, tilt, clamped = rig.clamp(math.radians(170), math.radians(-80))
    assert clamped
    assert pan == pytest.approx(math.radians(PROFILE.pan.max_deg))
    assert tilt == pytest.approx(math.radians(PROFILE.tilt.min_deg))
    for bad in (float("nan"), float("inf")):
        with pytest.raises(InvalidInputError, match="finite"):
            rig.clamp(bad, 0.0)


@given(pan=st.floats(-4.0, 4.0), tilt=st.floats(-4.0, 4.0))
def test_goal_ticks_are_always_inside_the_hard_limits(pan, tilt):
    rig = Rig(PROFILE)
    goal = rig.goal_for(pan, tilt)
    for tick, joint in ((goal.pan, PROFILE.pan), (goal.tilt, PROFILE.tilt)):
        lo, hi = joint_tick_limits(joint)
        assert lo <= tick <= hi
    inside = (
        PROFILE.pan.min_rad <= pan <= PROFILE.pan.max_rad
        and PROFILE.tilt.min_rad <= tilt <= PROFILE.tilt.max_rad
    )
    assert goal.clamped == (not inside)
    if inside:
        # exact inside the limits: nearest tick, within half a tick of the command
        back = rig.ticks_to_angles(goal.pan, goal.tilt)
        assert abs(back[0] - pan) <= TICK_RAD / 2 + 1e-12
        assert abs(back[1] - tilt) <= TICK_RAD / 2 + 1e-12


def test_write_goal_ticks_refuses_ticks_beyond_limits(rig):
    lo, hi = joint_tick_limits(PROFILE.pan)
    with pytest.raises(SafetyError, match=r"pan goal tick .* outside the hard limits"):
        rig.write_goal_ticks(hi + 1, PROFILE.tilt.zero_tick)
    with pytest.raises(SafetyError, match="tilt goal tick"):
        rig.write_goal_ticks(lo, 1.5)


def test_a_rig_without_bus_only_converts(rig):
    with pytest.raises(RuntimeError, match="no bus"):
        rig.read_pose()


def test_tick_limits_per_servo(rig):
    assert rig.tick_limits() == {
        PROFILE.pan.id: joint_tick_limits(PROFILE.pan),
        PROFILE.tilt.id: joint_tick_limits(PROFILE.tilt),
    }


def test_present_pose_matches_the_simulated_world(sim):
    with ServoBus.from_profile(PROFILE, port=sim.port) as bus:
        rig = Rig(PROFILE, bus)
        pan, tilt = rig.read_pose()
        truth = sim.truth()["joints_deg"]
        # the sim profile is the world's true geometry: within a tick of the truth
        assert math.degrees(pan) == pytest.approx(truth["pan"], abs=math.degrees(TICK_RAD))
        assert math.degrees(tilt) == pytest.approx(truth["tilt"], abs=math.degrees(TICK_RAD))
        np.testing.assert_allclose(
            rig.read_direction(), gimbal.pan_tilt_to_direction(pan, tilt), atol=2 * TICK_RAD
        )
        q = rig.read_quaternion()
        assert q.shape == (4,) and q[0] >= 0 and np.linalg.norm(q) == pytest.approx(1.0)


def test_write_pose_reaches_the_pose_and_clamps(sim):
    with ServoBus.from_profile(PROFILE, port=sim.port) as bus:
        rig = Rig(PROFILE, bus)
        rig.configure(profile_velocity=0, profile_acceleration=0)
        rig.set_torque(True)
        target = (math.radians(30.0), math.radians(90.0))  # tilt beyond its 70 deg limit
        goal = rig.write_pose(*target)
        assert goal.clamped and goal.tilt_rad == pytest.approx(PROFILE.tilt.max_rad)
        expected_deg = (30.0, math.degrees(rig.ticks_to_angles(goal.pan, goal.tilt)[1]))

        def arrived():
            truth = sim.truth()["joints_deg"]
            return (
                abs(truth["pan"] - expected_deg[0]) < 0.5
                and abs(truth["tilt"] - expected_deg[1]) < 0.5
            )

        deadline = time.monotonic() + 10.0
        while not arrived():
            assert time.monotonic() < deadline, sim.truth()["joints_deg"]
            rig.read_pose()  # one bus round trip per wait step
        assert math.degrees(rig.read_pose()[1]) <= PROFILE.tilt.max_deg


@given(pan=st.floats(-4.0, 4.0), tilt=st.floats(-4.0, 4.0))
def test_held_pose_is_the_written_goal_back_in_radians(pan, tilt):
    rig = Rig(PROFILE)
    held = rig.held_pose(pan, tilt)
    goal = rig.goal_for(pan, tilt)
    assert rig.angles_to_ticks(*held) == (goal.pan, goal.tilt)
    # half a tick of rounding per joint after the clamp; a clamped joint is kept on a tick
    # strictly inside its limit, up to a whole tick from it
    rounding = TICK_RAD if goal.clamped else TICK_RAD / 2
    assert abs(held[0] - goal.pan_rad) <= rounding + 1e-12
    assert abs(held[1] - goal.tilt_rad) <= rounding + 1e-12
