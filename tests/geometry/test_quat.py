import numpy as np
import pytest
from hypothesis import strategies as st

from limbctl.errors import InvalidInputError
from limbctl.geometry import quat

#: Quaternions drawn as four coordinates in [-1, 1], not yet normalised (norm above 0.1).
unit_quats = st.lists(st.floats(-1, 1, allow_nan=False), min_size=4, max_size=4).filter(
    lambda v: np.linalg.norm(v) > 0.1
)


def random_unit(n, seed=0):
    rng = np.random.default_rng(seed)
    return quat.canonical(quat.normalize(rng.normal(size=(n, 4))))


def test_limb_direction_swing_and_swing_angle_agree():
    q = random_unit(50)
    np.testing.assert_allclose(quat.limb_direction(q), quat.rotate(q, [1.0, 0.0, 0.0]), atol=1e-12)
    q = random_unit(200, seed=2)
    angle = quat.direction_angle(quat.limb_direction(q), [1.0, 0.0, 0.0])
    np.testing.assert_allclose(quat.swing_angle(q), angle, atol=1e-7)
    # the swing of a direction points the limb there, twist-free
    rng = np.random.default_rng(1)
    d = quat.normalize(rng.normal(size=(100, 3)))
    q = quat.swing_from_direction(d)
    np.testing.assert_allclose(quat.limb_direction(q), d, atol=1e-12)
    np.testing.assert_allclose(q[:, 1], 0.0, atol=1e-15)
    assert (q[:, 0] >= 0).all()


def test_hand_derived_rotation_about_z():
    # 90 deg about +z sends +x to +y; q = (cos 45, 0, 0, sin 45)
    q = quat.from_axis_angle(np.array([0.0, 0.0, 1.0]), np.pi / 2)
    np.testing.assert_allclose(q, [np.sqrt(0.5), 0, 0, np.sqrt(0.5)], atol=1e-15)
    np.testing.assert_allclose(quat.limb_direction(q), [0, 1, 0], atol=1e-15)
    assert quat.geodesic_distance(q, [1, 0, 0, 0]) == pytest.approx(np.pi / 2)
    assert quat.geodesic_distance(q, -q) == pytest.approx(0.0, abs=1e-7)


def test_as_quaternions_names_the_bad_row():
    good = random_unit(3)
    bad = good.copy()
    bad[2, 1] = np.nan
    with pytest.raises(InvalidInputError, match="row 2"):
        quat.as_quaternions(bad)
    with pytest.raises(ValueError, match="row 1"):
        quat.as_quaternions(np.array([[1, 0, 0, 0], [2, 0, 0, 0]]))
    with pytest.raises(ValueError, match="shape"):
        quat.as_quaternions(np.zeros((3, 3)))
    q, single = quat.as_quaternions(-good[0])
    assert single and q.shape == (1, 4) and q[0, 0] >= 0


@pytest.mark.parametrize("axis", [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.6, 0.0, -0.8]])
def test_tangent_frame_is_right_handed_and_orthonormal(axis):
    a = np.asarray(axis)
    u, v = quat.tangent_frame(a)
    np.testing.assert_allclose([u @ u, v @ v, u @ v, u @ a, v @ a], [1, 1, 0, 0, 0], atol=1e-12)
    np.testing.assert_allclose(np.cross(u, v), a, atol=1e-12)
