"""The demo's helpers: the sampled excursion bound, and the learned twist band's picture."""

from __future__ import annotations

import math

import numpy as np

from limbctl.envelope import RigidMap
from limbctl.envelope.synthetic_twist import ShoulderRegion
from limbctl.eval import twist_demo
from limbctl.geometry.gimbal import pan_tilt_to_direction
from limbctl.geometry.quat import from_axis_angle

RADIUS_DEG = 20.0


class BallRegion:
    """Every orientation within RADIUS_DEG of the identity: its distance is known exactly."""

    def contains(self, q: np.ndarray) -> np.ndarray:
        q = np.atleast_2d(q)
        identity = np.broadcast_to([1.0, 0.0, 0.0, 0.0], q.shape)
        return twist_demo.rotation_deg(q, identity) <= RADIUS_DEG


def goal_outside_by(deg: float, axis=(0.3, -0.5, 0.8)) -> np.ndarray:
    axis = np.asarray(axis) / np.linalg.norm(axis)
    return from_axis_angle(axis, np.radians(RADIUS_DEG + deg))


def test_the_sampled_bound_is_near_the_true_distance_never_under_it_nor_over_the_radius():
    for k, outside in enumerate((0.02, 0.07, 0.15)):
        # the bound handed in is what an early-stopping search might say: 0.1 deg too far
        found = twist_demo.nearest_held_nearby_deg(
            BallRegion(), goal_outside_by(outside), outside + 0.1, k
        )
        assert outside <= found + 1e-9  # an upper bound: the region holds that orientation
        assert found <= outside + 0.01
    # with nothing held within the radius the radius is returned
    found = twist_demo.nearest_held_nearby_deg(BallRegion(), goal_outside_by(1.0), 0.5, seed=0)
    assert math.isclose(found, 0.5)


def test_the_learned_band_line_is_the_band_where_the_swing_region_reaches(tmp_path):
    region = ShoulderRegion()
    taught = region.teaching(2500, 1200, 1200, np.random.default_rng(0))
    model = RigidMap(twist=True).fit(taught)
    tilt = np.linspace(-60.0, 85.0, 30)
    low, high = twist_demo.learned_band_line(model.region, 30.0, tilt)
    d = pan_tilt_to_direction(np.full(30, math.radians(30.0)), np.radians(tilt))
    inside = np.asarray(model.region.mesh.contains(d), dtype=bool)
    assert inside.any() and not inside.all()
    assert np.isnan(low[~inside]).all() and np.isnan(high[~inside]).all()
    c, h = model.region.band.at(d[inside])
    assert np.allclose(high[inside] - low[inside], np.degrees(2.0 * h))
    # the centre, on the turn nearest 0 (the shoulder's is 10 + 0.25 pan - 0.2 tilt deg)
    centre = np.degrees((c + math.pi) % (2.0 * math.pi) - math.pi)
    assert np.allclose((low[inside] + high[inside]) / 2.0, centre)
    # the true band's centre there, learned to within a few degrees
    true_centre = 10.0 + 0.25 * 30.0 - 0.2 * tilt[inside]
    assert np.median(np.abs(centre - true_centre)) < 5.0
    # the picture: three panels with a model learned with twist, two without
    import matplotlib.image

    samples = taught[:2000]
    lines = (tilt, (true_centre.mean() - 40.0 + 0 * tilt, true_centre.mean() + 40.0 + 0 * tilt))
    twist_demo.twist_picture(tmp_path / "three.png", samples, samples[:50], *lines, model=model)
    twist_demo.twist_picture(tmp_path / "two.png", samples, samples[:50], *lines)
    assert matplotlib.image.imread(tmp_path / "three.png").shape[:2] == (500, 1800)
    assert matplotlib.image.imread(tmp_path / "two.png").shape[:2] == (500, 1200)
