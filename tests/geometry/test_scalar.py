"""The gate's scalar kinematics agree with the array versions they stand in for."""

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from limbctl.geometry import scalar
from limbctl.geometry.gimbal import direction_to_pan_tilt, pan_tilt_to_direction
from limbctl.geometry.quat import direction_angle, limb_direction, swing_from_direction
from tests.geometry.test_quat import unit_quats

angles = st.floats(-math.pi, math.pi, allow_nan=False)
tilts = st.floats(-math.pi / 2, math.pi / 2, allow_nan=False)


@settings(max_examples=200, deadline=None)
@given(pan=angles, tilt=tilts, current=angles, v=unit_quats)
def test_direction_swing_pan_tilt_and_limb_match_gimbal_and_quat(pan, tilt, current, v):
    q = np.asarray(v) / np.linalg.norm(v)
    np.testing.assert_allclose(scalar.limb(q), limb_direction(q), atol=1e-14)
    d = scalar.direction(pan, tilt)
    np.testing.assert_allclose(d, pan_tilt_to_direction(np.array(pan), np.array(tilt)), atol=1e-15)
    np.testing.assert_allclose(scalar.swing(d), swing_from_direction(np.array(d)), atol=1e-12)
    expected = direction_to_pan_tilt(np.array(d), current_pan=np.array(current))
    np.testing.assert_allclose(scalar.pan_tilt(d, current), np.array(expected), atol=1e-12)


def test_the_swing_of_minus_x_and_pan_tilt_at_the_singularity():
    np.testing.assert_array_equal(scalar.swing((-1.0, 0.0, 0.0)), [0.0, 0.0, 0.0, 1.0])
    np.testing.assert_array_equal(swing_from_direction(np.array([-1.0, 0.0, 0.0])), [0, 0, 0, 1])
    assert scalar.pan_tilt((0.0, 0.0, 1.0), 0.7) == (0.7, math.pi / 2)


@settings(max_examples=200, deadline=None)
@given(p1=angles, t1=tilts, p2=angles, t2=tilts, fraction=st.floats(0.0, 1.0))
def test_angle_matches_quat_and_toward_walks_the_great_circle(p1, t1, p2, t2, fraction):
    a, b = scalar.direction(p1, t1), scalar.direction(p2, t2)
    total = scalar.angle(a, b)
    assert math.isclose(total, float(direction_angle(np.array(a), np.array(b))), abs_tol=1e-12)
    if not 1e-6 < total < math.pi - 1e-6:
        return  # no unique great circle
    step = fraction * total
    got = np.array(scalar.toward(a, b, step))
    # unit, in the plane of a and b, step from a and the rest of the way from b
    normal = np.cross(a, b) / np.linalg.norm(np.cross(a, b))
    assert math.isclose(np.linalg.norm(got), 1.0, abs_tol=1e-12)
    assert abs(float(got @ normal)) < 1e-9
    assert math.isclose(float(direction_angle(np.array(a), got)), step, abs_tol=1e-9)
    assert math.isclose(float(direction_angle(got, np.array(b))), total - step, abs_tol=1e-9)
