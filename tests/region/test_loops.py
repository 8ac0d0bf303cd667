import numpy as np
import pytest

from limbctl.envelope.synthetic import PolygonRegion
from limbctl.geometry.quat import direction_angle
from limbctl.region import loops
from limbctl.region.mesh import DirectionMesh
from tests.region.support import circle


def test_resample_puts_stations_evenly_on_the_loop_and_loops_to_edges_closes_it():
    loop = circle(20.0, 17)
    stations, s, at_vertex = loops.resample_loop(loop, np.radians(0.5))
    total = loops.loop_length(loop)
    assert at_vertex[0] == 0.0 and np.all(np.diff(at_vertex) > 0)
    np.testing.assert_allclose(np.diff(s), total / s.size, rtol=1e-12)
    assert total / s.size <= np.radians(0.5)
    vertices, edges = loops.loops_to_edges([circle(10.0, 4), circle(20.0, 3)])
    assert vertices.shape == (7, 3)
    np.testing.assert_array_equal(edges, [[0, 1], [1, 2], [2, 3], [3, 0], [4, 5], [5, 6], [6, 4]])
    np.testing.assert_allclose(np.linalg.norm(stations, axis=1), 1.0, atol=1e-12)
    # every station lies on an arc of the loop: within the arc's great circle
    mesh = DirectionMesh.from_loops([loop], 0.0)
    foot = mesh.project(stations)
    assert np.all(mesh.contains(stations) | (direction_angle(foot, stations) < 1e-9))


def test_loop_area_is_signed_by_orientation():
    bean = PolygonRegion()
    loop = bean.boundary[::-1] if loops.loop_area(bean.boundary) < 0 else bean.boundary
    assert loops.loop_area(loop) > 0 and loops.loop_area(loop[::-1]) < 0
    # a cap of angular radius r has area 2 pi (1 - cos r); the 720-gon lies a hair inside
    r = np.radians(20.0)
    assert loops.loop_area(circle(20.0, 720)) == pytest.approx(
        2 * np.pi * (1 - np.cos(r)), rel=1e-4
    )


def test_signed_offset_gaps_and_station_buckets_wrap_around_the_loop():
    total = 10.0
    np.testing.assert_allclose(loops.signed_offset(np.array([9.0, 1.0]), 0.0, total), [-1.0, 1.0])
    np.testing.assert_allclose(
        loops.loop_gaps(np.array([9.5]), np.array([0.5, 5.0]), total), [[1.0, 4.5]]
    )
    owner = np.array([2, 0, 2, 4, 1, -1, 0, 5])
    buckets = loops.StationBuckets(owner, 5)
    # station by station in the order asked, each station's items in their original order
    np.testing.assert_array_equal(buckets.rows(np.array([2, 0])), [0, 2, 1, 6])
    # items owned by no station (-1, 5) are never read
    np.testing.assert_array_equal(buckets.around(0, 1), [3, 1, 6, 4])
    assert buckets.rows(np.array([3])).size == 0


def test_nearest_station_smoothing_and_lift_along_the_loop():
    stations = circle(20.0, 36)
    data = circle(19.0, 36)
    np.testing.assert_array_equal(loops.nearest_station(data, stations), np.arange(36))
    s, total = loops.station_positions(stations)
    values = np.zeros(36)
    values[0] = 1.0
    smooth = loops.smooth_along(values, s, total, np.radians(2.0))
    # symmetric about station 0 across the wrap, and a constant stays constant
    assert smooth[1] == pytest.approx(smooth[-1]) and smooth[0] > smooth[1]
    np.testing.assert_allclose(loops.smooth_along(np.ones(36), s, total, 0.1), 1.0)
    # lift makes up each deficit and nothing more
    s = np.radians(np.arange(0.0, 360.0, 2.0))
    total = np.radians(360.0)
    none = loops.lift(np.full(s.size, -1.0), s, total, np.radians(5.0))
    np.testing.assert_array_equal(none, 0.0)
    deficit = np.full(s.size, -0.01)
    deficit[[10, 100]] = [0.02, 0.005]
    up = loops.lift(deficit, s, total, np.radians(5.0))
    assert up[10] == pytest.approx(0.02) and up[100] >= 0.005
    assert np.all(up <= 0.02) and np.all(up >= 0.0)
    assert up[25] < 1e-6, "bumps fade: 30 deg (6 widths) away nothing is left"


def test_vertex_turns_are_left_positive_and_close_the_loop():
    loop = circle(20.0, 36)
    turns = loops.vertex_turns(loop)
    assert (turns > 0.0).all()
    # Gauss-Bonnet: the turns of a simple loop add up to 2 pi minus the area it encloses
    assert turns.sum() == pytest.approx(2.0 * np.pi - loops.loop_area(loop), abs=1e-9)
    # walked the other way round every corner is concave
    np.testing.assert_allclose(loops.vertex_turns(loop[::-1]), -turns[::-1], atol=1e-12)
