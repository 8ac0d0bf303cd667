import numpy as np
import pytest

from limbctl.envelope.synthetic import ConeRegion
from limbctl.geometry.quat import normalize, tangent_frame
from limbctl.region import shape_kernels
from limbctl.region.loops import loops_to_edges
from tests.region.support import nearest_on_edges_reference


def test_widest_bearing_gaps_match_numpy_in_the_tangent_frame():
    rng = np.random.default_rng(3)
    data = ConeRegion(np.radians(30.0)).sample(400, rng)
    # points near z take the other helper axis
    p = normalize(np.vstack([ConeRegion(np.radians(40.0)).sample(50, rng), [[0.1, 0.0, 0.995]]]))
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


def _three_lobed(points: int) -> np.ndarray:
    """A loop (points, 3) about +z, its radius 20 +- 4 deg in three lobes."""
    t = np.linspace(0.0, 2.0 * np.pi, points, endpoint=False)
    r = np.radians(20.0 + 4.0 * np.sin(3.0 * t))
    return np.column_stack([np.sin(r) * np.cos(t), np.sin(r) * np.sin(t), np.cos(r)])


@pytest.mark.parametrize("loop_points", [12, 90])
def test_nearest_arcs_agree_with_the_brute_force_reference(loop_points):
    # loops of a few long arcs or many short ones; directions on both sides and on vertices
    rng = np.random.default_rng(loop_points)
    data = ConeRegion(np.radians(30.0)).sample(4000, rng)
    loop = _three_lobed(loop_points)
    data = np.vstack([data, loop])
    vertices, edges = loops_to_edges([loop])
    want_arc, _, want_angle = nearest_on_edges_reference(data, vertices, edges)
    got_arc, got_angle = shape_kernels.nearest_arcs(data, vertices, edges)
    # equally near within TIE (1e-12 rad): the first arc, whose angle may be TIE larger
    np.testing.assert_allclose(got_angle, want_angle, rtol=0.0, atol=2e-12)
    # a direction on a vertex, ~1e-16 rad from both its arcs, goes to the first in order
    on_vertex = np.concatenate([[0], np.arange(loop_points - 1)])
    np.testing.assert_array_equal(got_arc[-loop_points:], on_vertex)
    assert np.all(got_angle[-loop_points:] <= 1e-12)
    # elsewhere where the arcs named differ, both are nearest: the reference's arc is as near
    other = got_arc != want_arc
    assert other.sum() <= loop_points
    for i in np.flatnonzero(other):
        arc = edges[got_arc[i]][None, :]
        _, _, angle_to_got = nearest_on_edges_reference(data[i : i + 1], vertices, arc)
        assert abs(angle_to_got[0] - want_angle[i]) <= 2e-12
