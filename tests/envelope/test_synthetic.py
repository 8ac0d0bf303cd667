import numpy as np

from limbctl.envelope.synthetic import (
    NOTCH,
    ConeRegion,
    PolygonRegion,
    inset_track,
    to_quaternions,
    traced_teaching,
    trajectory_samples,
)
from limbctl.geometry.gimbal import pan_tilt_to_direction
from limbctl.geometry.quat import direction_angle, limb_direction


def test_cone_samples_inside_ideal_is_lee_and_quaternions_point_the_limb():
    rng = np.random.default_rng(0)
    cone = ConeRegion(np.radians(30.0))
    assert cone.contains(cone.sample(500, rng)).all()
    test = cone.test_directions(2000, rng)
    assert np.degrees(direction_angle(test, cone.axis)).max() <= 60.0 + 1e-9
    ideal = cone.ideal(test)
    outside = ~cone.contains(test)
    np.testing.assert_allclose(
        direction_angle(ideal[outside], cone.axis), np.radians(30), atol=1e-12
    )
    np.testing.assert_array_equal(ideal[~outside], test[~outside])
    d = ConeRegion(1.0).sample(10, np.random.default_rng(2))
    np.testing.assert_allclose(limb_direction(to_quaternions(d)), d, atol=1e-12)


def test_polygon_ideal_is_nearest_boundary_point_and_strokes_stay_inside():
    rng = np.random.default_rng(1)
    bean = PolygonRegion()
    s = bean.sample(1000, rng)
    assert bean.contains(s).all()
    test = bean.test_directions(300, rng)
    ideal = bean.ideal(test)
    outside = ~bean.contains(test)
    # the ideal is no farther than any dense boundary sample
    dist = direction_angle(test[outside], ideal[outside])
    brute = np.min(np.arccos(np.clip(test[outside] @ bean.boundary.T, -1, 1)), axis=1)
    assert (dist <= brute + 1e-12).all()
    # the sampling is dense in the middle, sparse at the edge
    depth = bean.depth(s)
    assert (depth < np.radians(3)).mean() < 0.2
    # trajectory samples are continuous strokes inside
    d = trajectory_samples(bean, 3000, np.random.default_rng(3))
    assert d.shape == (3000, 3)
    assert bean.contains(d).all()
    steps = np.degrees(direction_angle(d[1:], d[:-1]))
    # consecutive samples are close (a 100 Hz recording), except where a stroke ends
    assert np.quantile(steps, 0.98) <= 0.31
    assert (bean.depth(d) < np.radians(1.0)).mean() > 0.05, "some strokes creep along the edge"


def test_the_inset_track_rounds_reflex_corners_and_the_teaching_traces_it_then_wanders():
    track = inset_track(NOTCH, 1.0, 0.12)
    notch = PolygonRegion(NOTCH)
    depth = np.degrees(notch.depth(pan_tilt_to_direction(*np.radians(track).T)))
    # 1 deg in (pan, tilt); a degree of pan is cos(tilt) >= cos(15 deg) = 0.966 deg of angle
    assert depth.min() >= 0.96 and depth.max() <= 1.0 + 1e-5
    steps = np.linalg.norm(np.diff(track, axis=0), axis=1)
    assert steps.max() <= 0.121 and steps.min() >= 0.11
    # the reflex corner (6, 3) is rounded: track points 1 deg from it, none nearer
    near = np.linalg.norm(track - [6.0, 3.0], axis=1)
    assert near.min() >= 1.0 - 1e-9 and (near < 1.0 + 1e-6).sum() >= 10
    # either winding gives the same curve
    np.testing.assert_allclose(
        np.sort(inset_track(NOTCH[::-1], 1.0, 0.12)[:, 0])[::50],
        np.sort(track[:, 0])[::50],
        atol=0.2,
    )
    # the traced teaching traces the edge, then wanders inside
    d, traced = traced_teaching(notch, 20.0, np.random.default_rng(4))
    assert d.shape == (2500, 3) and 1000 < traced < 2500
    assert notch.contains(d).all()
    depth = np.degrees(notch.depth(d))
    assert np.all(np.abs(depth[:traced] - 1.0) < 0.05)
    assert np.median(depth[traced:]) > 3.0
    steps = np.degrees(direction_angle(d[1:traced], d[: traced - 1]))
    np.testing.assert_allclose(np.median(steps), 0.12, atol=0.005, err_msg="15 deg/s at 125 Hz")
