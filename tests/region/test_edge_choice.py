import numpy as np

from limbctl.envelope.synthetic import ConeRegion
from limbctl.region import edge_choice as ec
from limbctl.region import edge_smooth as ef
from limbctl.region.mesh import DirectionMesh

X = np.array([1.0, 0.0, 0.0])


def circle(radius_deg: float, n: int, shift_deg: float = 0.0) -> np.ndarray:
    """A counter-clockwise loop (n, 3) at ``radius_deg`` about +x, tilted ``shift_deg`` about z."""
    phi = np.linspace(-np.pi, np.pi, n, endpoint=False)
    r = np.radians(radius_deg)
    ring = np.column_stack([np.cos(phi), np.sin(phi)])
    loop = np.column_stack([np.full(n, np.cos(r)), np.sin(r) * ring])
    a = np.radians(shift_deg)
    turn = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
    return loop @ turn.T


def test_reach_beyond_measures_how_far_stations_leave_a_region():
    region = DirectionMesh.from_loops([circle(20.0, 120)], 0.0)
    assert ec.reach_beyond([circle(19.0, 60)], region) == 0.0
    reach = np.degrees(ec.reach_beyond([circle(21.0, 60)], region))
    # 1 deg out everywhere; the 120-gon's chords lie up to 0.01 deg inside the circle
    assert 1.0 <= reach < 1.02


def test_agreeing_region_refuses_edges_that_cut_the_taught_samples():
    rng = np.random.default_rng(0)
    data = ConeRegion(np.radians(20.0)).sample(1000, rng)
    supported = DirectionMesh.from_loops([circle(19.5, 120)], np.radians(0.5))
    # a circle on the edge holds the samples and adds nothing the sampling cannot explain
    assert ec.agreeing_region([circle(20.0, 240)], data, supported) is not None
    # one 2 deg inside leaves about a fifth of them out
    assert ec.agreeing_region([circle(18.0, 240)], data, supported) is None
    # a missing edge (the traced edge refused) refuses the set
    assert ec.agreeing_region([None], data, supported) is None
    assert ec.agreeing_region(None, data, supported) is None


def test_agreeing_region_refuses_a_stretch_no_sample_ever_reached():
    rng = np.random.default_rng(0)
    data = ConeRegion(np.radians(20.0)).sample(1000, rng)
    supported = DirectionMesh.from_loops([circle(19.5, 120)], np.radians(0.5))
    # an edge 3 deg wider and 3 deg off centre adds a crescent up to 6 deg wide where the dense
    # data put nothing
    wide = circle(23.0, 240, shift_deg=3.0)
    assert ef.unexplained_gap(wide, data, supported) > ef.GAP_EXPECTED
    assert ec.agreeing_region([wide], data, supported) is None


def test_a_cone_keeps_the_smooth_edge_and_a_sparse_bean_neither():
    from limbctl.envelope import RigidMap
    from limbctl.envelope.synthetic import PolygonRegion, to_quaternions

    rng = np.random.default_rng(1)
    cone = RigidMap(nodes=1000, seed=1).fit(
        to_quaternions(ConeRegion(np.radians(20.0)).sample(1000, rng))
    )
    assert cone.edge == "smooth"
    # 1000 samples over 113 x 78 deg: too sparse at the edge for the traced edge, and corners
    bean = RigidMap(nodes=1000, seed=1).fit(to_quaternions(PolygonRegion().sample(1000, rng)))
    assert bean.edge == "supported"
