"""Kinematics of both chains: the two-joint swing and the three-joint Rz Ry Rx, array and scalar."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from limbctl.geometry import gimbal, quat
from limbctl.geometry.quat import limb_direction
from limbctl.geometry.quat import multiply as quat_multiply
from limbctl.geometry.twist import decompose


def test_hand_cases_round_trip_through_quaternion_and_the_singularity_keeps_the_pan():
    pan, tilt = np.array([0.0, np.pi / 2, 0.3]), np.array([0.0, 0.0, np.pi / 2])
    np.testing.assert_allclose(gimbal.pan_tilt_to_direction(pan, tilt), np.eye(3), atol=1e-15)
    rng = np.random.default_rng(0)
    pan = rng.uniform(-np.pi + 0.01, np.pi - 0.01, 500)
    tilt = rng.uniform(-1.5, 1.5, 500)
    q = gimbal.pan_tilt_to_quat(pan, tilt)
    assert (q[:, 0] >= 0).all()
    p2, t2 = gimbal.quat_to_pan_tilt(q)
    np.testing.assert_allclose(p2, pan, atol=1e-9)
    np.testing.assert_allclose(t2, tilt, atol=1e-9)
    # the pose's quaternion points the limb along the pose's direction
    np.testing.assert_allclose(
        quat.limb_direction(q), gimbal.pan_tilt_to_direction(pan, tilt), atol=1e-12
    )
    # at the singularity the current pan is kept
    pan, tilt = gimbal.direction_to_pan_tilt(np.array([0.0, 0.0, 1.0]), current_pan=0.7)
    assert pan == pytest.approx(0.7)
    assert tilt == pytest.approx(np.pi / 2)


angle = st.floats(-math.pi + 1e-6, math.pi - 1e-6)
tilt_open = st.floats(-math.pi / 2 + 1e-3, math.pi / 2 - 1e-3)


def chain_by_products(pan, tilt, roll):
    """Rz(pan) Ry(-tilt) Rx(roll) by quaternion products, the reference."""
    z, y, x = (quat.from_axis_angle(np.eye(3)[i], a) for i, a in ((2, pan), (1, -tilt), (0, roll)))
    q = quat_multiply(quat_multiply(z, y), x)
    return q if q[0] >= 0 else -q


def twist_about_x(q):
    """Swing-twist twist angle about +x, in (-pi, pi], from the module that owns twist."""
    return float(decompose(q)[1])


@pytest.mark.parametrize(
    ("pan", "tilt", "expected"), [(30, 30, 8.2), (60, 45, 26.9), (90, 60, 60.0), (0, 50, 0.0)]
)
def test_chain_twist_figures(pan, tilt, expected):
    tau = math.degrees(float(gimbal.chain_twist(math.radians(pan), math.radians(tilt))))
    assert tau == pytest.approx(expected, abs=0.05)
    # tau = 2 atan(tan(pan/2) tan(tilt/2)), the formula as written
    closed = 2 * math.atan(math.tan(math.radians(pan) / 2) * math.tan(math.radians(tilt) / 2))
    assert math.radians(tau) == pytest.approx(closed, abs=1e-12)
    # and it is the twist of the two-joint chain itself
    q = chain_by_products(math.radians(pan), math.radians(tilt), 0.0)
    assert math.degrees(twist_about_x(q)) == pytest.approx(tau, abs=1e-9)
    # the two-servo swing differs from the zero-roll chain by that twist
    q2 = gimbal.pan_tilt_to_quat(math.radians(pan), math.radians(tilt))
    gap = 2 * math.degrees(math.acos(min(1.0, abs(float(np.dot(q, q2))))))
    assert gap == pytest.approx(expected, abs=0.05)


@settings(max_examples=300, deadline=None)
@given(angle, tilt_open, angle)
def test_forward_is_the_products_twist_roll_plus_chain_twist_and_inverse_back(pan, tilt, roll):
    q = gimbal.pan_tilt_roll_to_quat(pan, tilt, roll)
    assert np.allclose(q, chain_by_products(pan, tilt, roll), atol=1e-12)
    assert q[0] >= 0
    assert np.allclose(limb_direction(q), gimbal.pan_tilt_to_direction(pan, tilt), atol=1e-12)
    assert np.allclose(gimbal.pose_quat_scalar(pan, tilt, roll), q, atol=1e-15)
    expected = math.remainder(roll + float(gimbal.chain_twist(pan, tilt)), 2 * math.pi)
    got = twist_about_x(q)
    assert abs(math.remainder(got - expected, 2 * math.pi)) < 1e-9
    if abs(roll) <= math.radians(170):  # the inverse round trips within +-175 deg roll limits
        lim = (-math.radians(175), math.radians(175))
        assert gimbal.pan_tilt_roll_scalar(q, 0.0, 0.0, *lim) == pytest.approx(
            (pan, tilt, roll), abs=1e-9
        )


@pytest.mark.parametrize("tilt_deg", [90.0, -90.0])
def test_gimbal_lock_keeps_the_present_pan_and_roll_takes_the_turn(tilt_deg):
    tilt = math.radians(tilt_deg)
    q = gimbal.pan_tilt_roll_to_quat(math.radians(40), tilt, math.radians(10))
    for present_pan in (0.0, math.radians(25), math.radians(-60)):
        pan, t2, roll = gimbal.pan_tilt_roll_scalar(q, present_pan, 0.0, -math.pi, math.pi)
        assert pan == present_pan
        assert t2 == pytest.approx(tilt, abs=1e-7)
        # the same orientation, whichever pan was kept
        again = gimbal.pose_quat_scalar(pan, t2, roll)
        assert abs(float(np.dot(again, q))) == pytest.approx(1.0, abs=1e-12)
        # only pan + roll (tilt +90) or roll - pan (tilt -90) is fixed
        sign = 1.0 if tilt_deg > 0 else -1.0
        both, fixed = math.degrees(roll + sign * pan), 10 + sign * 40
        assert math.remainder(both - fixed, 360) == pytest.approx(0.0, abs=1e-5)


def test_unwrap_roll_prefers_limits_then_the_present_roll_and_a_pose_uses_its_chain():
    lo, hi = math.radians(-100), math.radians(100)
    # only one representative within +-100: chosen whatever the present roll
    r = math.radians(-170)
    assert gimbal.unwrap_roll_scalar(r, math.radians(90), lo, hi) == pytest.approx(r)
    # wide limits (a multi-turn roll): the representative nearest the present roll
    wide = (math.radians(-350), math.radians(350))
    got = gimbal.unwrap_roll_scalar(math.radians(-170), math.radians(150), *wide)
    assert math.degrees(got) == pytest.approx(190.0)
    # beyond every limit: the nearest to the limits (the clamp then decides)
    got = gimbal.unwrap_roll_scalar(math.radians(150), 0.0, lo, hi)
    assert math.degrees(got) == pytest.approx(150.0)
    # one pose of either chain uses its count's functions
    pan, tilt, roll = 0.4, -0.3, 1.1
    assert np.array_equal(gimbal.pose_quat(pan, tilt), gimbal.pan_tilt_to_quat(pan, tilt))
    assert np.array_equal(
        gimbal.pose_quat(pan, tilt, roll), gimbal.pose_quat_scalar(pan, tilt, roll)
    )
