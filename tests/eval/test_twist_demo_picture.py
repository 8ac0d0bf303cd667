"""The three-servo demo's picture draws the learned twist band beside the true one."""

from __future__ import annotations

import math

import numpy as np

from limbctl.envelope import RigidMap
from limbctl.envelope.synthetic_twist import ShoulderRegion
from limbctl.eval.twist_demo import learned_band_line, twist_picture
from limbctl.geometry.gimbal import pan_tilt_to_direction


def test_the_learned_band_line_is_the_band_where_the_swing_region_reaches(tmp_path):
    region = ShoulderRegion()
    taught = region.teaching(2500, 1200, 1200, np.random.default_rng(0))
    model = RigidMap(twist=True).fit(taught)
    tilt = np.linspace(-60.0, 85.0, 30)
    low, high = learned_band_line(model.region, 30.0, tilt)
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
    twist_picture(tmp_path / "three.png", samples, samples[:50], *lines, model=model)
    twist_picture(tmp_path / "two.png", samples, samples[:50], *lines)
    assert matplotlib.image.imread(tmp_path / "three.png").shape[:2] == (500, 1800)
    assert matplotlib.image.imread(tmp_path / "two.png").shape[:2] == (500, 1200)
