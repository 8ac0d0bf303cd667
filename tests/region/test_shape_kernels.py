import numpy as np

from limbctl.envelope.synthetic import ConeRegion
from limbctl.geometry.quat import tangent_frame
from limbctl.region import shape_kernels


def test_widest_bearing_gaps_match_numpy_in_the_tangent_frame():
    rng = np.random.default_rng(3)
    data = ConeRegion(np.radians(30.0)).sample(400, rng)
    # points near z take the other helper axis
    p = np.vstack([ConeRegion(np.radians(40.0)).sample(50, rng), [[0.1, 0.0, 0.995]]])
    p /= np.linalg.norm(p, axis=1, keepdims=True)
    near = [np.flatnonzero(data @ x > np.cos(np.radians(8.0))) for x in p]
    start = np.concatenate([[0], np.cumsum([len(rows) for rows in near])])
    flat = np.concatenate(near).astype(np.int64)
    got = shape_kernels.widest_bearing_gaps(p, data, start, flat)
    for i, rows in enumerate(near):
        if len(rows) == 0:
            assert got[i] == 2.0 * np.pi
            continue
        u, v = tangent_frame(p[i])
        bearing = np.sort(np.arctan2(data[rows] @ v, data[rows] @ u))
        want = np.diff(np.concatenate([bearing, bearing[:1] + 2.0 * np.pi])).max()
        np.testing.assert_allclose(got[i], want, atol=1e-12)
    # inside the cone the samples surround, beyond its edge they lie on one side
    inside = np.degrees(np.arccos(p[:, 0])) < 20.0
    outside = np.degrees(np.arccos(np.clip(p[:, 0], -1, 1))) > 31.0
    assert (got[inside] < np.radians(120.0)).all()
    assert (got[outside] > np.radians(150.0)).all()
