import numpy as np
import pytest

from limbctl.geometry import gimbal, quat


def test_forward_kinematics_hand_cases():
    np.testing.assert_allclose(gimbal.pan_tilt_to_direction(0.0, 0.0), [1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(gimbal.pan_tilt_to_direction(np.pi / 2, 0.0), [0, 1, 0], atol=1e-15)
    np.testing.assert_allclose(gimbal.pan_tilt_to_direction(0.3, np.pi / 2), [0, 0, 1], atol=1e-15)


def test_round_trip_through_quaternion():
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


def test_singularity_keeps_current_pan():
    pan, tilt = gimbal.direction_to_pan_tilt(np.array([0.0, 0.0, 1.0]), current_pan=0.7)
    assert pan == pytest.approx(0.7)
    assert tilt == pytest.approx(np.pi / 2)
