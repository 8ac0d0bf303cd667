"""Inside by a margin, the nearest start pose and the waiting status, on two servos and three."""

import math

import numpy as np
import pytest

from calib import default_sim_profile
from limbctl.geometry.chains import geodesic
from limbctl.geometry.gimbal import pan_tilt_to_direction, pose_quat_scalar
from limbctl.geometry.quat import direction_angle
from limbctl.servo.rig import Rig
from limbctl.teleop.gate import Gate, GateLimits, written_tolerance_deg
from limbctl.teleop.margin import (
    RING_PROBES,
    START_MARGIN_DEG,
    RotationMargins,
    SphereMargins,
    inside_by_margin,
    nearest_start_pose,
    safe_with_margin,
)
from limbctl.teleop.start import assess
from tests.teleop.chains import off_axis_deg
from tests.teleop.test_gate import ConeBand, make_gate

HALF_ANGLE = math.radians(40)
MARGIN = math.radians(START_MARGIN_DEG)
RIG = Rig(default_sim_profile())
#: The three-servo region: the limb within 40 deg of +x, its twist within 30 deg of 0.
BAND = ConeBand(HALF_ANGLE, 0.0, math.radians(30))


def exact(*pose):
    return pose  # no tick rounding: the search's own geometry


def band_gate(roll_limit=2.5):
    return Gate(BAND, GateLimits((-2, -1, -roll_limit), (2, 1, roll_limit), 0.01, 0.03))


def cone_gate():
    """test_gate.py's 40 deg cone, tilt up to 70 deg, at teleop's 0.6 deg a cycle; not started."""
    return make_gate(2, HALF_ANGLE, math.radians(0.6), 1.8, math.radians(70), start=False)


def test_inside_by_margin_on_a_cone():
    """Inside by the margin (more than the rounding to ticks) of the cone and the hard limits."""
    assert START_MARGIN_DEG > written_tolerance_deg()
    gate = cone_gate()
    edge = 40.0 - START_MARGIN_DEG
    cases = [
        ([0.0, 0.0], True),  # the axis
        ([edge - 0.02, 0.0], True),  # just inside by the margin
        ([edge + 0.02, 0.0], False),  # inside, but not by the margin
        ([40.5, 0.0], False),  # outside
        ([0.0, -30.0 + START_MARGIN_DEG / 2], False),  # inside the cone, too near the tilt limit
        ([np.nan, 0.0], False),
    ]
    poses = np.radians([pose for pose, _ in cases])
    assert inside_by_margin(gate, poses, MARGIN).tolist() == [ok for _, ok in cases]


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
    axis_angle = off_axis_deg(*target)
    # probes 360/RING_PROBES deg apart: an edge between two is cos(180/RING_PROBES) margins away
    assert axis_angle <= 40.0 - START_MARGIN_DEG * math.cos(math.pi / RING_PROBES) + 1e-9
    # and near: for a pose outside, about the margin beyond the edge along the way in
    outside = max(0.0, off_axis_deg(pan, tilt) - 40.0)
    moved = math.degrees(
        float(direction_angle(pan_tilt_to_direction(pan, tilt), pan_tilt_to_direction(*target)))
    )
    if outside > 0 or axis_angle > 40.0 - 2 * START_MARGIN_DEG:
        assert moved <= outside + 2.5 * START_MARGIN_DEG


def test_status_says_how_far_and_which_way_on_two_servos_and_three():
    gate = cone_gate()
    margins = SphereMargins(gate, RIG.held_pose)
    status = assess(margins, (math.radians(50.0), math.radians(0.0)), waited_s=3.0)
    assert not status.ready and not status.inside_region and status.inside_limits
    assert status.outside_deg == pytest.approx(10.0, abs=1e-6)
    assert 10.0 + START_MARGIN_DEG <= status.distance_deg <= 10.0 + 2.5 * START_MARGIN_DEG
    assert status.move_deg[0] < -10.0 and abs(status.move_deg[1]) < 1.0
    assert "10.0 deg outside the taught region" in status.line()
    assert "turn it right" in status.advice()
    row = status.as_dict()
    assert row["kind"] == "start" and row["waited_s"] == 3.0 and row["advice"]

    up = assess(margins, (0.0, math.radians(-45.0)))
    assert not up.inside_limits and "beyond the rig's hard limits" in up.line()
    assert "raise it" in up.advice()

    inside = assess(margins, (math.radians(5.0), math.radians(5.0)))
    assert inside.ready and inside.distance_deg == 0.0 and "starting" in inside.line()
    # three servos: the rotation's margins
    margins = RotationMargins(band_gate(), exact)
    twisted = assess(margins, (0.0, 0.0, math.radians(45)), waited_s=2.0)
    assert not twisted.ready and twisted.inside_limits
    assert abs(twisted.outside_deg - 15.0) < 1e-6
    assert 15.0 < twisted.distance_deg <= 15.0 + 3 * START_MARGIN_DEG
    # the way in is a roll back toward the band, about -15 deg
    assert twisted.target_deg is not None and -16.5 < twisted.target_deg[2] - 45.0 < -15.0
    line = twisted.line()
    assert "roll +45.0 deg (15.0 deg outside the taught region)" in line, line
    assert "move the limb 15." in line and "deg about its axis" in line, line
    inside = assess(margins, (0.1, 0.05, 0.1))
    assert inside.ready and inside.distance_deg == 0.0
    assert inside.line().endswith("(ready): inside the taught region: starting")
    beyond = assess(margins, (0.0, 1.2, 0.0))  # tilt past its 1 rad hard limit
    assert not beyond.inside_limits and "beyond the rig's hard limits" in beyond.line()


def test_nearest_rotation_start_pose_is_inside_by_the_margin_on_every_joint_and_near():
    gate = band_gate()
    margins = RotationMargins(gate, exact)
    # outside in twist only (roll 45 deg at rest: twist 45 against the band's 30)
    twisted = (0.0, 0.0, math.radians(45))
    found = margins.nearest(twisted)
    assert found is not None and safe_with_margin(gate, found, MARGIN)
    q, f = pose_quat_scalar(*twisted), pose_quat_scalar(*found)
    # the nearest region orientation is 15 deg away; the start pose a margin or two further
    assert 15.0 < math.degrees(geodesic(q, f)) <= 15.0 + 3 * START_MARGIN_DEG
    # outside in swing and twist: pan 55 deg, roll -50 deg
    both = (math.radians(55), 0.0, math.radians(-50))
    found = margins.nearest(both)
    assert found is not None and safe_with_margin(gate, found, MARGIN)
    gap = geodesic(pose_quat_scalar(*both), BAND.correct(pose_quat_scalar(*both)))
    assert geodesic(pose_quat_scalar(*both), pose_quat_scalar(*found)) <= gap + 6 * MARGIN
    # already inside by the margin: the pose itself
    inside = (0.1, 0.05, 0.1)
    assert margins.nearest(inside) == inside
    # safe with the margin needs room on every joint
    gate = band_gate(roll_limit=1.7)
    assert safe_with_margin(gate, (0.0, 0.0, 0.0), MARGIN)
    edge = (0.0, 0.0, math.radians(29.9))  # twist 29.9: 0.35 deg more roll leaves the band
    assert gate.is_safe(*edge) and not safe_with_margin(gate, edge, MARGIN)
