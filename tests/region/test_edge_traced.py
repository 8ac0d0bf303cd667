from pathlib import Path

import numpy as np
import pytest

from firmware_sim.hand import Hand
from firmware_sim.regions import grid_inside
from limbctl.demo import true_outline, true_twist_probes
from limbctl.envelope import RigidMap
from limbctl.envelope.synthetic import EGG, SMALL_KIDNEY, PolygonRegion, to_quaternions
from limbctl.geometry.gimbal import pan_tilt_roll_to_quat, pan_tilt_to_direction, pan_tilt_to_quat
from limbctl.geometry.quat import direction_angle, limb_direction
from limbctl.geometry.twist import decompose
from limbctl.region import edge_traced as et
from limbctl.region.loops import resample_loop, station_positions
from tests.region.support import circle

X = np.array([1.0, 0.0, 0.0])
REPO = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("per_depth", [30, 100])
def test_edge_estimate_is_unbiased_below_a_straight_edge_and_local(per_depth):
    # Poisson points under a straight edge at depth 0 over u in [-1, 1], per_depth per unit depth
    rng = np.random.default_rng(0)
    est = []
    for _ in range(1500):
        n = rng.poisson(per_depth * 3)
        est.append(et.edge_estimate(rng.uniform(-1.0, 1.0, n), -rng.uniform(0.0, 3.0, n)))
    est = np.array(est) * per_depth
    # in units of 1 / (rho 2h): mean 0 within 3 standard errors (sd about 1.5)
    assert abs(est.mean()) < 3 * 1.5 / np.sqrt(len(est))
    assert 1.0 < est.std() < 2.0
    # local: readings 1 unit deep and one 1 unit out at the window's end: the majorant's chord
    # from the far left to it passes the station at 0 (plus the small gap estimate)
    u = np.concatenate([np.linspace(-1.0, 1.0, 41), [1.0]])
    o = np.concatenate([np.full(41, -1.0), [1.0]])
    assert et.edge_estimate(u, o) < 0.5


def test_local_quadratic_keeps_a_circle_and_removes_wiggles():
    sigma = np.radians(et.TRACE_SMOOTH_DEG)
    for radius, shrink in ((20.0, 0.03), (10.0, 0.16)):
        loop = circle(radius, int(radius * 24))
        got = np.degrees(direction_angle(et.local_quadratic(loop, sigma), X))
        assert np.all(got <= radius + 1e-9) and np.all(got >= radius - shrink)
    # a 0.2 deg wiggle every 6 stations (1.5 deg along a 20 deg circle's 480 stations)
    n = 480
    phi = np.linspace(-np.pi, np.pi, n, endpoint=False)
    r = np.radians(20.0 + 0.2 * np.cos(np.arange(n) * 2.0 * np.pi / 6.0))
    ring = np.column_stack([np.cos(phi), np.sin(phi)])
    bumpy = np.column_stack([np.cos(r), np.sin(r)[:, None] * ring])
    radius = np.degrees(direction_angle(et.local_quadratic(bumpy, sigma), X))
    assert np.abs(radius - 20.0).max() < 0.04


def test_trace_window_follows_the_density_refuses_a_sparse_edge_and_chords_are_lifted(cone20):
    loop, dense = circle(19.5, 80), cone20[1]
    h = et.trace_window(loop, dense)
    assert et.TRACE_MIN_WINDOW_DEG <= np.degrees(h) <= et.TRACE_MAX_WINDOW_DEG
    # 100 samples over a 20 deg cap: about 0.08 per deg^2 at the edge, a 30 deg window
    assert np.degrees(et.trace_window(loop, dense[:100])) > et.TRACE_MAX_WINDOW_DEG
    assert et.trace_edge(loop, dense[:100], np.radians(3.0)) is None
    assert et.trace_window(loop, -dense) == np.inf
    # chord_need lifts a sample 0.01 deg outside the middle of the chord between stations 0 and
    # 1: inside the circle, outside the polygon of stations (sagitta 0.06 deg)
    loop = circle(20.0, 60)
    mid = loop[0] + loop[1]
    mid /= np.linalg.norm(mid)
    outward = mid - X * np.cos(np.radians(20.0))
    outward -= (outward @ mid) * mid
    outward /= np.linalg.norm(outward)
    sample = np.cos(np.radians(0.01)) * mid + np.sin(np.radians(0.01)) * outward
    need = et.chord_need(loop, sample[None, :])
    assert need[0] > 0.0 and need[1] > 0.0
    assert np.sum(np.isfinite(need)) == 3


# the small kidney's seeds whose trace is taken; the egg's tight end, which no smooth edge follows
@pytest.mark.parametrize(
    ("shape", "seed"),
    [("small kidney", 1), ("small kidney", 5)] + [("egg", s) for s in (0, 1, 2, 4)],
)
def test_a_dent_or_a_tight_end_keeps_every_output_near_the_true_region(shape, seed):
    region = PolygonRegion(SMALL_KIDNEY if shape == "small kidney" else EGG)
    rng = np.random.default_rng(seed)
    train = region.sample(1000, rng)
    m = RigidMap(nodes=2000, layout="uniform", seed=seed).fit(to_quaternions(train))
    test = region.test_directions(5000, rng)
    q = to_quaternions(test)
    out = m.correct(q)
    d_out = limb_direction(out)
    depth = region.depth(d_out)
    assert (depth >= -np.radians(1.0)).mean() >= 0.995
    if shape == "egg":
        assert depth.min() > -np.radians(2.0)
        if seed == 4:  # the smooth edge passes every data check but reaches 2 deg past the traced
            smooth, traced, supported = m.region.verdicts
            assert m.edge == "traced" and traced.accepted and supported.accepted
            assert not smooth.accepted and smooth.figures["reach_beyond_deg"] > 1.5
            assert "beyond the traced edge" in smooth.reasons[0]
        return
    # a dent on top: no smooth edge, but the samples trace the edge densely enough
    assert m.edge == "traced"
    err = np.degrees(direction_angle(d_out, region.ideal(test)))
    assert err.mean() < 0.6, "the supported loops give about 1.0 deg here"
    valid = region.depth(test) >= np.radians(2.0)
    assert np.all(out[valid] == q[valid], axis=1).mean() >= 0.99
    # taught samples stay inside (up to the acceptance's tolerance)
    assert m.contains(to_quaternions(train)).mean() >= 0.999


def test_a_hole_is_bridged_and_without_one_the_estimates_stay_to_the_bit():
    # a 20 deg circle's stations read on the curve but at 30..35 (a hole), and 15 deg inside there
    curve, _, _ = resample_loop(circle(20.0, 400), np.radians(et.TRACE_STEP_DEG))
    s, total = station_positions(curve)
    edge = np.setdiff1d(np.arange(curve.shape[0]), np.arange(30, 36))
    owner = np.concatenate([np.repeat(edge, 3), np.arange(31, 35)])
    depth = np.concatenate([np.zeros(3 * edge.size), np.full(4, -np.radians(15.0))])
    h = np.radians(3.0)
    edge = depth == 0.0
    plain = et.station_estimates(s, total, owner[edge], depth[edge], 2)
    assert np.array_equal(et.bridged_estimates(s, total, owner[edge], depth[edge], 2, h), plain)
    assert not et.over_hole(owner[edge], depth[edge], s.size, h).any()
    hole = et.over_hole(owner, depth, s.size, h)
    assert np.array_equal(np.flatnonzero(hole), np.arange(31, 35))
    # without the bridge the interior readings pull the stations over the hole 15 deg in
    plain = et.station_estimates(s, total, owner, depth, 2)
    assert np.degrees(plain[31:35]).min() < -10.0
    bridged = np.degrees(et.bridged_estimates(s, total, owner, depth, 2, h))
    # with it the hole takes the estimates of its ends: the edge's readings at depth 0
    assert np.abs(bridged).max() < 0.5


#: The recorder's stalls of issue 19 (start s, length s), cut out of the demo's 60 s teaching at
#: 125 Hz (docs/bench_edge_hole.md); the first cuts nothing (``limbctl demo``'s own teaching).
CUTS = ((0.0, 0.0), (6.0, 0.4), (18.0, 0.4), (9.0, 0.5))


def _inner_probes(path, hand):
    """Two-servo orientations (M, 4) on a 1 deg grid at least 2 deg inside the true outline."""
    grid = np.radians(grid_inside(hand.region, 1.0, 0.0))
    outline = np.radians(true_outline(path))
    edge = pan_tilt_to_direction(outline[:, 0], outline[:, 1])
    d = pan_tilt_to_direction(grid[:, 0], grid[:, 1])
    inner = direction_angle(d[:, None, :], edge[None, :, :]).min(axis=1) >= np.radians(2.0)
    return pan_tilt_to_quat(grid[inner, 0], grid[inner, 1])


@pytest.mark.parametrize("twist", [False, True], ids=["two servos", "three servos"])
def test_an_edge_trace_with_a_recorder_hole_keeps_the_true_region(twist):
    path = REPO / "limbctl" / "data" / ("demo_region3.yaml" if twist else "demo_region.yaml")
    hand = Hand.from_yaml(path, seed=0)
    hand.start_from(0.0, 0.0)
    t = np.arange(int(60.0 * 125.0)) / 125.0
    pose = np.radians([(tuple(hand.pose_deg(float(x))) + (0.0,))[:3] for x in t])
    probes = true_twist_probes(path) if twist else _inner_probes(path, hand)
    for start, length in CUTS[1:3] if twist else CUTS:
        keep = ~((t >= start) & (t < start + length))
        q = pan_tilt_roll_to_quat(*pose[keep].T) if twist else pan_tilt_to_quat(*pose[keep, :2].T)
        m = RigidMap(twist=twist).fit(q)
        held = np.mean(np.asarray(m.contains(probes), dtype=bool))
        if not twist:
            assert held >= 0.99, f"cut at {start} s: {100 * held:.2f} % held"
            continue
        # where the twist stops are too sparse the band is held short and the places listed; the
        # swing edge still holds the probes' directions
        swing = np.mean(m.region.swing.mesh.contains(decompose(probes)[0]))
        assert swing >= 0.99, f"cut at {start} s: {100 * swing:.2f} % of the directions held"
        assert held >= 0.99 or m.region.unsupported, f"cut at {start} s: {100 * held:.2f} % held"
