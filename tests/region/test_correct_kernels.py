import numpy as np

from limbctl.geometry.quat import from_axis_angle, limb_direction, multiply, normalize
from limbctl.region import correct_kernels as ck
from limbctl.region.mesh import DirectionMesh
from tests.region.support import circle


def cap_args():
    """The kernels' arguments of the region within 20 deg of +x."""
    return DirectionMesh.from_loops([circle(20.0, 120)], 0.0).kernel_args()


def about(axis, angle_deg):
    """The rotation by ``angle_deg`` about unit ``axis`` as a quaternion (w, x, y, z)."""
    return from_axis_angle(axis, np.radians(angle_deg))


def test_inside_comes_back_canonical_outside_moves_to_the_edge_keeping_twist_bad_refused():
    args = cap_args()
    twist = about([1, 0, 0], 30.0)
    inside = -multiply(about([0, 0, 1], 10.0), twist)  # w < 0: comes back with w >= 0
    outside = multiply(about([0, 0, 1], 40.0), twist)
    out, status = ck.correct_batch(np.vstack([inside, outside]), *args)
    np.testing.assert_array_equal(status, [1, 0])
    np.testing.assert_array_equal(out[0], -inside)
    moved = limb_direction(out[1])
    # the nearest region direction: 20 deg (less the 120-gon's chord) along the same meridian
    assert 19.9 < np.degrees(np.arccos(moved[0])) <= 20.0 and abs(moved[2]) < 1e-12
    # the twist about the limb is kept: out = swing(d') * twist
    swing = about([0, 0, 1], np.degrees(np.arctan2(moved[1], moved[0])))
    np.testing.assert_allclose(out[1], multiply(swing, twist), atol=1e-12)
    # bad input is refused, one command and many
    bad = np.array([[np.nan, 0.0, 0.0, 0.0], [2.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]])
    _, status = ck.correct_batch(bad, *args)
    np.testing.assert_array_equal(status, [-1, -1, 1])
    _, one = ck.correct_single(bad[0], *args)
    assert one == -1
    out, one = ck.correct_single(bad[2], *args)
    assert one == 1 and np.array_equal(out, bad[2])


def test_every_batch_path_answers_as_the_parallel_kernel_row_for_row():
    """correct_rows: one by one (small), one thread (medium) and the pool give the same arrays."""
    args = cap_args()
    rng = np.random.default_rng(7)
    q = normalize(rng.normal(size=(300, 4)))
    q[5] = np.nan  # refused alike: status -1
    q = np.ascontiguousarray(q)
    out, status = ck.correct_batch(q, *args)
    assert {-1, 0, 1} <= set(status.tolist())
    serial = ck.correct_serial(q, *args)
    np.testing.assert_array_equal(serial[1], status)
    np.testing.assert_array_equal(serial[0][status >= 0], out[status >= 0])
    small = ck.correct_rows(np.ascontiguousarray(q[: ck.SINGLE_ROWS]), *args)
    np.testing.assert_array_equal(small[1], status[: ck.SINGLE_ROWS])
    keep = status[: ck.SINGLE_ROWS] >= 0
    np.testing.assert_array_equal(small[0][keep], out[: ck.SINGLE_ROWS][keep])
