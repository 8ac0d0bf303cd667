"""Inside by a margin, the nearest start pose and the waiting limb's status, on a Lee cone."""

import math

import numpy as np
import pytest

from calib import default_sim_profile
from limbctl.envelope import Cone
from limbctl.geometry.gimbal import pan_tilt_to_direction
from limbctl.geometry.quat import direction_angle
from limbctl.servo.rig import Rig
from limbctl.teleop.gate import Gate, GateLimits, written_tolerance_deg
from limbctl.teleop.margin import (
    RING_PROBES,
    START_MARGIN_DEG,
    assess,
    inside_by_margin,
    nearest_start_pose,
)

HALF_ANGLE = math.radians(40)
MARGIN = math.radians(START_MARGIN_DEG)
RIG = Rig(default_sim_profile())


def cone_gate():
    limits = GateLimits(
        joint_min=(math.radians(-100), math.radians(-30)),
        joint_max=(math.radians(100), math.radians(70)),
        max_step=math.radians(0.6),
        max_joint_step=math.radians(1.8),
    )
    return Gate(Cone(HALF_ANGLE), limits)


def off_axis(pan_deg, tilt_deg):
    """Angle (deg) of a pose from the cone's axis (+x)."""
    d = pan_tilt_to_direction(math.radians(pan_deg), math.radians(tilt_deg))
    return math.degrees(float(direction_angle(d, np.array([1.0, 0.0, 0.0]))))


def test_the_margin_exceeds_the_rounding_to_ticks():
    assert START_MARGIN_DEG > written_tolerance_deg()


def test_inside_by_margin_on_a_cone():
    gate = cone_gate()
    edge = 40.0 - START_MARGIN_DEG
    poses = np.radians(
        [
            [0.0, 0.0],  # the axis
            [edge - 0.02, 0.0],  # just inside by the margin
            [edge + 0.02, 0.0],  # inside, but not by the margin
            [40.5, 0.0],  # outside
            [0.0, -30.0 + START_MARGIN_DEG / 2],  # inside the cone, too near the tilt limit
            [np.nan, 0.0],
        ]
    )
    assert inside_by_margin(gate, poses, MARGIN).tolist() == [
        True,
        True,
        False,
        False,
        False,
        False,
    ]


@pytest.mark.parametrize(
    ("pan_deg", "tilt_deg"),
    [(55.0, 0.0), (40.0, 0.0), (39.9, 0.01), (30.0, 30.0), (-60.0, -20.0), (0.0, 0.0)],
)
def test_nearest_start_pose_is_inside_by_the_margin_after_rounding(pan_deg, tilt_deg):
    gate = cone_gate()
    pan, tilt = math.radians(pan_deg), math.radians(tilt_deg)
    target = nearest_start_pose(gate, pan, tilt, MARGIN, RIG.held_pose)
    assert target is not None
    assert RIG.held_pose(*target) == target  # already a whole-tick pose
    assert inside_by_margin(gate, np.array([target]), MARGIN)[0]
    axis_angle = off_axis(*np.degrees(target))
    # the ring's probes are 360/RING_PROBES deg apart: an edge between two of them is at
    # least cos(180/RING_PROBES deg) of the margin away
    assert axis_angle <= 40.0 - START_MARGIN_DEG * math.cos(math.pi / RING_PROBES) + 1e-9
    # and near: for a pose outside, about the margin beyond the edge along the way in
    outside = max(0.0, off_axis(pan_deg, tilt_deg) - 40.0)
    moved = math.degrees(
        float(direction_angle(pan_tilt_to_direction(pan, tilt), pan_tilt_to_direction(*target)))
    )
    if outside > 0 or axis_angle > 40.0 - 2 * START_MARGIN_DEG:
        assert moved <= outside + 2.5 * START_MARGIN_DEG


def test_status_says_how_far_and_which_way():
    gate = cone_gate()
    status = assess(gate, math.radians(50.0), math.radians(0.0), RIG.held_pose, waited_s=3.0)
    assert not status.ready and not status.inside_region and status.inside_limits
    assert status.outside_deg == pytest.approx(10.0, abs=1e-6)
    assert 10.0 + START_MARGIN_DEG <= status.distance_deg <= 10.0 + 2.5 * START_MARGIN_DEG
    assert status.move_pan_deg < -10.0 and abs(status.move_tilt_deg) < 1.0
    assert "10.0 deg outside the taught region" in status.line()
    assert "turn it right" in status.advice()
    row = status.as_dict()
    assert row["kind"] == "start" and row["waited_s"] == 3.0 and row["advice"]

    up = assess(gate, 0.0, math.radians(-45.0), RIG.held_pose)
    assert not up.inside_limits and "beyond the rig's hard limits" in up.line()
    assert "raise it" in up.advice()

    inside = assess(gate, math.radians(5.0), math.radians(5.0), RIG.held_pose)
    assert inside.ready and inside.distance_deg == 0.0 and "starting" in inside.line()
