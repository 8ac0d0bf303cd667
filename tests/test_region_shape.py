import numpy as np

from limbctl.envelope import region_shape as rs
from limbctl.envelope.synthetic import ConeRegion, PolygonRegion, trajectory_samples
from limbctl.quat import direction_angle


def test_thin_keeps_spacing_and_covers_every_point():
    d = ConeRegion(np.radians(30.0)).sample(3000, np.random.default_rng(0))
    spacing = np.radians(2.0)
    keep = rs.thin(d, spacing)
    kept = d[keep]
    dots = kept @ kept.T
    np.fill_diagonal(dots, -1.0)
    assert np.arccos(np.clip(dots.max(axis=1), -1, 1)).min() >= spacing - 1e-12
    cover = np.arccos(np.clip((d @ kept.T).max(axis=1), -1, 1))
    assert cover.max() <= spacing + 1e-12
    assert keep.size < d.shape[0] / 2


def _ring(inner_deg, outer_deg, n, rng):
    d = ConeRegion(np.radians(outer_deg)).sample(n, rng)
    return d[direction_angle(d, np.array([1.0, 0, 0])) >= np.radians(inner_deg)]


def test_holes_below_the_limit_are_filled_larger_ones_kept():
    d = _ring(8.0, 25.0, 3000, np.random.default_rng(1))
    alpha = np.radians(3.0)
    probe = np.array([[1.0, 0.0, 0.0]])
    filled = rs.alpha_loops(d, alpha, max_hole=0.1)
    kept = rs.alpha_loops(d, alpha, max_hole=1e-4)
    assert rs.enclosed(probe, filled)[0]
    assert not rs.enclosed(probe, kept)[0]
    assert len(kept) == len(filled) + 1


def test_learned_alpha_follows_the_data_scale():
    rng = np.random.default_rng(2)
    cone = ConeRegion(np.radians(30.0))
    dense = rs.learn_alpha(cone.sample(2000, rng), 2.0)
    sparse = rs.learn_alpha(cone.sample(200, rng), 2.0)
    assert sparse > 2.0 * dense
    # hand strokes leave gaps far wider than their sample spacing: alpha follows the gaps
    strokes = trajectory_samples(cone, 3000, rng)
    thin = strokes[rs.thin(strokes, np.radians(1.0))]
    assert rs.learn_alpha(thin, 2.0) > np.radians(3.0)


def test_smoothing_keeps_a_circle_and_offsets_find_its_edge():
    rng = np.random.default_rng(3)
    cone = ConeRegion(np.radians(25.0))
    data = cone.sample(4000, rng)
    loops = rs.alpha_loops(data, np.radians(4.0), max_hole=0.1)
    assert len(loops) == 1
    step = np.radians(0.4)
    smooth = rs.smooth_loop(loops[0], step, np.radians(3.0))
    radius = direction_angle(smooth, cone.axis)
    assert np.abs(radius - np.radians(25.0)).max() < np.radians(1.5)
    offsets = rs.edge_offsets([smooth], data, np.radians(6.0), 12, np.radians(2.0), step)[0]
    final = rs.offset_loop(smooth, offsets)
    err = np.degrees(direction_angle(final, cone.axis)) - 25.0
    assert np.abs(err).mean() < 0.5
    # every sample inside the moved loop
    assert rs.enclosed(data, [final]).mean() >= 0.999


def test_loop_area_and_gap_estimate():
    bean = PolygonRegion()
    loop = bean.boundary[::-1] if rs.loop_area(bean.boundary) < 0 else bean.boundary
    assert rs.loop_area(loop) > 0 and rs.loop_area(loop[::-1]) < 0
    assert abs(rs._gap_beyond(np.array([1.0, 0.9, 0.8, 0.7, 0.6])) - 0.1) < 1e-12
    assert rs._gap_beyond(np.array([1.0, 1.0, 1.0, 1.0])) == 0.0
