"""The synthetic shoulder: its teaching lies inside, its boundary on the edge, its clamp inside."""

import math

import numpy as np
import pytest

from limbctl.envelope.synthetic import rounded
from limbctl.envelope.synthetic_twist import SHOULDER, STOP_SCATTER_DEG, BandRegion, ShoulderRegion
from limbctl.geometry.quat import geodesic_distance
from limbctl.geometry.twist import compose, decompose, wrap


@pytest.fixture(scope="module")
def shoulder():
    return ShoulderRegion(rounded(SHOULDER))


def test_teaching_lies_inside_with_stops_at_the_limits_of_a_band_narrowing_upward(shoulder):
    q = shoulder.teaching(300, 200, 400, np.random.default_rng(0))
    assert q.shape == (900, 4) and shoulder.contains(q).all()
    d, tau = decompose(q[-400:])
    c, h = shoulder.band(d)
    short = np.degrees(h - np.abs(wrap(tau - c)))
    assert np.all(short >= -1e-9) and np.median(short) < 2 * STOP_SCATTER_DEG
    # half the stops along the swing edge (within 1 deg), some deep inside
    depth = np.degrees(shoulder.swing.depth(d))
    assert np.mean(depth <= 1.0 + 1e-9) >= 0.45 and depth.max() > 10.0
    # the band narrows as the limb rises, linearly in tilt
    d = np.array([[math.cos(t), 0.0, math.sin(t)] for t in np.radians([-30.0, 0.0, 40.0])])
    _, h = shoulder.band(d)
    assert h[0] > h[1] > h[2]
    (t0, t1), (h0, h1) = shoulder.tilt_range, shoulder.half_deg
    np.testing.assert_allclose(np.degrees(h[1]), h0 + (h1 - h0) * (0.0 - t0) / (t1 - t0))


def test_boundary_lies_on_the_boundary_and_the_engines_clamp_inside(shoulder):
    b = shoulder.boundary(2.0)
    d, tau = decompose(b)
    c, h = shoulder.band(d)
    on_stop = np.isclose(np.abs(wrap(tau - c)), h, atol=1e-9)
    on_edge = np.abs(shoulder.swing.depth(d)) < np.radians(0.01)
    assert np.all(on_stop | on_edge)
    assert on_stop.sum() > 500 and on_edge.sum() > 500
    # the engines' clamp lands inside but is not the nearest
    rng = np.random.default_rng(1)
    d = shoulder._inside_directions(300, rng)
    c, h = shoulder.band(d)
    q = compose(d, c + h + np.radians(20.0))
    out = shoulder.clamp(q)
    assert shoulder.contains(out).all()
    # here the direction is inside, so the clamp only moves the twist: exactly 20 deg
    np.testing.assert_allclose(np.degrees(geodesic_distance(q, out)), 20.0, atol=1e-6)


def test_a_band_region_takes_any_band_and_teaches_inside_it():
    def band_deg(pan, tilt):
        # a band across +-180 deg whose width curves with pan
        return 175.0 + 0.1 * tilt, 30.0 + 0.005 * pan**2

    square = np.array([[-40.0, -30.0], [40.0, -30.0], [40.0, 40.0], [-40.0, 40.0]])
    region = BandRegion(square, band_deg)
    q = region.teaching(300, 200, 300, np.random.default_rng(0))
    assert region.contains(q).all()
    d, tau = decompose(q)
    c, h = region.band(d)
    pan = np.degrees(np.arctan2(d[:, 1], d[:, 0]))
    np.testing.assert_allclose(np.degrees(h), 30.0 + 0.005 * pan**2, atol=1e-9)
    # the stops are reached: some twists within 1 deg of each limit
    off = np.degrees(np.abs(wrap(tau - c)) - h)
    assert np.sum(off > -1.0) > 50
    # its boundary's stops lie on the band's limits
    db, tb = decompose(region.boundary(2.0))
    cb, hb = region.band(db)
    assert np.min(np.abs(np.abs(wrap(tb - cb)) - hb)) < 1e-9
