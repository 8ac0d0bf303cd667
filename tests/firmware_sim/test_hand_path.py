"""The swing path: in its region, the edge traced then wandered, corners rounded, retraced."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from firmware_sim.hand import DEFAULT_TREMOR_DEG, Hand
from firmware_sim.hand_path import EDGE_INSET_DEG, PATH_DEPTH_FLOOR_DEG, TRACE_SPEED_DEG_S
from firmware_sim.world import World

REGIONS = Path(__file__).resolve().parents[2] / "examples" / "regions"
OFF = {1: None, 2: None}
U_SHAPE = [[-60, -30], [60, -30], [60, 40], [40, 40], [40, -10], [-40, -10], [-40, 40], [-60, 40]]


def record(hand: Hand, seconds: float = 60.0, rate_hz: int = 100, seed: int = 0) -> np.ndarray:
    """Joint angles (M, 2) deg sampled at ``rate_hz`` while the hand backdrives the world."""
    world = World(hand=hand, seed=seed)
    per_sample = 1000 // rate_hz
    samples = []
    for _ in range(int(seconds * rate_hz)):
        for _ in range(per_sample):
            world.step(0.001, OFF)
        angles = world.joint_angles_deg()
        samples.append((angles["pan"], angles["tilt"]))
    return np.array(samples)


def perimeter_gap(region, poses: np.ndarray) -> float:
    """Largest fraction of the perimeter that no pose of ``poses`` (M, 2) deg lies along."""
    u = np.sort(region.boundary_fraction(poses[:, 0], poses[:, 1]))
    return float(np.max(np.diff(np.concatenate([u, u[:1] + 1.0]))))


def density_by_depth(region, samples: np.ndarray, lo: float, hi: float) -> float:
    """Share of samples over share of area in a band of depth fractions [lo, hi)."""
    p_lo, p_hi, t_lo, t_hi = region.bbox_deg
    grid = np.stack(np.meshgrid(np.linspace(p_lo, p_hi, 150), np.linspace(t_lo, t_hi, 150)), -1)
    grid_depth = region.edge_distance_deg(grid[..., 0], grid[..., 1]).ravel()
    grid_fraction = grid_depth[grid_depth >= 0] / region.depth_max_deg
    fraction = region.edge_distance_deg(samples[:, 0], samples[:, 1]) / region.depth_max_deg
    share_samples = np.mean((fraction >= lo) & (fraction < hi))
    share_area = np.mean((grid_fraction >= lo) & (grid_fraction < hi))
    return float(share_samples / share_area)


@pytest.fixture(scope="module", params=["irregular.yaml", "cone30.yaml"])
def minute(request):
    """A 60 s, 100 Hz recording backdriven by a hand that only wanders (``style: wander``)."""
    hand = Hand.from_mapping({**yaml.safe_load((REGIONS / request.param).read_text()),
                              "style": "wander"}, seed=11)  # fmt: skip
    return hand, record(hand)


@pytest.fixture(scope="module", params=["irregular.yaml", "cone30.yaml"])
def taught(request):
    """A 60 s, 100 Hz recording by the default hand (trace, then wander), and its times (s)."""
    hand = Hand.from_yaml(REGIONS / request.param, seed=11)
    samples = record(hand)
    return hand, samples, np.arange(1, len(samples) + 1) / 100.0


def test_a_wandering_minute_stays_in_covers_edge_and_interior_dense_in_the_middle(minute):
    hand, samples = minute
    region = hand.region
    assert hand.style == "wander" and hand.path.trace_span_s is None
    depth = region.edge_distance_deg(samples[:, 0], samples[:, 1])
    # in the region: the planned path keeps PATH_DEPTH_FLOOR_DEG inside, the tremor may eat part
    assert depth.min() > -DEFAULT_TREMOR_DEG
    assert np.mean(depth < 0.0) < 0.001
    # it reaches the deep middle within seconds instead of tracing the edge first
    assert depth[:300].max() > 0.8 * region.depth_max_deg
    # the boundary all around: every eighth visited, no stretch over 12 % left out
    near = samples[depth < 3.0]
    arcs = np.floor(region.boundary_fraction(near[:, 0], near[:, 1]) * 8).astype(int)
    assert set(arcs.tolist()) == set(range(8))
    assert perimeter_gap(region, near) < 0.12
    # the interior
    p_lo, p_hi, t_lo, t_hi = region.bbox_deg
    cells = np.stack(np.meshgrid(np.arange(p_lo, p_hi, 5.0), np.arange(t_lo, t_hi, 5.0)), -1)
    cells = cells.reshape(-1, 2)
    cells = cells[region.edge_distance_deg(cells[:, 0], cells[:, 1]) >= 5.0]
    gap = np.min(np.hypot(*(cells[:, None, :] - samples[None, ::5, :]).transpose(2, 0, 1)), axis=1)
    assert np.mean(gap < 8.0) > 0.9
    # dense in the middle, sparse and slow near the edge
    assert density_by_depth(region, samples, 0.5, 1.01) > 1.1 * density_by_depth(
        region, samples, 0.05, 0.35
    )
    speed = np.hypot(*np.diff(samples, axis=0).T) * 100.0  # deg/s at 100 Hz
    near_edge, middle_speed = speed[depth[1:] < 3.0], speed[depth[1:] > 0.5 * region.depth_max_deg]
    assert np.median(near_edge) < 0.75 * np.median(middle_speed)


def test_the_default_hand_takes_hold_traces_the_whole_edge_at_a_persons_pace_then_wanders(taught):
    hand, samples, t = taught
    region = hand.region
    start, end = hand.path.trace_span_s
    assert hand.style == "trace"
    rest = World(hand=hand, seed=11).joint_angles_deg()
    assert hand.pose_deg(0.0) == pytest.approx((rest["pan"], rest["tilt"]), abs=DEFAULT_TREMOR_DEG)
    # no yank: a minimum-jerk move peaks at 1.875 x its mean speed; the tremor adds a little
    speed = np.hypot(*np.diff(samples[:300], axis=0).T) * 100.0
    assert speed.max() < 2.0 * hand.speed_deg_s + 15.0, "the hand yanked the limb"
    assert np.hypot(*(samples[299] - samples[0])) > 10.0  # it did take the limb somewhere
    # it reaches the edge within a couple of seconds of taking hold ...
    assert start < 3.0
    tracing = (t >= start) & (t < end)
    depth = region.edge_distance_deg(samples[:, 0], samples[:, 1])
    assert np.all(depth[tracing] < 2.5)
    # ... goes all the way round (no stretch of more than 2 % of the perimeter left out) ...
    assert perimeter_gap(region, samples[tracing]) < 0.02
    # ... in one lap: its duration is the perimeter at a person's pace
    assert region.perimeter_deg / 20.0 < end - start < region.perimeter_deg / 10.0
    # then wanders through the middle: deep poses, none of them on the edge band any more
    after = t >= end + 1.0
    assert np.max(depth[after]) > 0.6 * region.depth_max_deg
    assert np.mean(depth[after] > 5.0) > 0.8
    # the pace over half-second windows (the tremor's 7-12 Hz averages out)
    traced = samples[tracing]
    speed = np.hypot(*(traced[50:] - traced[:-50]).T) / 0.5
    assert 10.0 < np.median(speed) < 20.0
    assert np.median(speed) == pytest.approx(TRACE_SPEED_DEG_S, rel=0.1)
    assert np.percentile(speed, 95) < 22.0 and np.percentile(speed, 5) > 8.0
    # about a degree inside, its depth wandering by a few tenths of a degree
    depth = depth[tracing]
    assert np.median(depth) == pytest.approx(EDGE_INSET_DEG, abs=0.1)
    assert depth.min() > PATH_DEPTH_FLOOR_DEG - DEFAULT_TREMOR_DEG
    assert 0.3 < np.percentile(depth, 95) - np.percentile(depth, 5) < 1.0


def test_a_u_is_traced_and_walked_round_its_reflex_corners_boxed_in_retraced_a_notch_reached():
    # the U's inner corners are reflex: a trace set in from one side would cut the corner
    hand = Hand.from_mapping({"region": {"polygon": U_SHAPE}, "tremor_deg": 0}, seed=20)
    start, end = hand.path.trace_span_s
    poses = np.array([hand.pose_deg(float(s)) for s in np.arange(start, end, 0.01)])
    depth = hand.region.edge_distance_deg(poses[:, 0], poses[:, 1])
    assert depth.min() >= PATH_DEPTH_FLOOR_DEG - 1e-9
    assert np.median(depth) == pytest.approx(EDGE_INSET_DEG, abs=0.1)
    # both arms' tips and the floor between them are traced, not skipped
    for corner in ([-60, 40], [60, 40], [-40, 40], [40, 40], [0, -10]):
        assert np.min(np.hypot(*(poses - corner).T)) < 2.0
    hand = Hand.from_mapping({"region": {"polygon": U_SHAPE}, "tremor_deg": 0}, seed=18)
    poses = np.array([hand.pose_deg(float(t)) for t in np.arange(0.0, 120.0, 0.001)])
    depth = hand.region.edge_distance_deg(poses[:, 0], poses[:, 1])
    assert depth.min() >= PATH_DEPTH_FLOOR_DEG - 1e-9  # never across the gap between the arms
    # continuous: a minimum-jerk move peaks at 1.875 x its mean speed
    assert np.hypot(*np.diff(poses, axis=0).T).max() / 0.001 < 2.0 * hand.speed_deg_s
    for arm in (poses[:, 0] < -40.0, poses[:, 0] > 40.0):
        assert np.any(arm & (poses[:, 1] > 30.0))  # both arms' tips are reached
    # boxed in, it retraces its last move: its end to its start, bowed the same way
    hand = Hand.from_mapping({"region": {"polygon": U_SHAPE}, "tremor_deg": 0}, seed=19)
    hand.pose_deg(20.0)
    path = hand.path
    *_, last_move = (s for s in path.track.segments if s[2:4] != s[4:6])  # moves, not pauses
    before = len(path.track.segments)
    path._reach = lambda target: False  # nothing reachable from here: boxed in
    path._plan_next()
    (retrace,) = (s for s in path.track.segments[before:] if s[6])
    assert retrace[2:6] == (*last_move[4:6], *last_move[2:4])
    assert retrace[7:9] == last_move[7:9]
    # a notched region: the planned path keeps its margin yet goes to the edge
    notch = [[-40, -30], [40, -30], [40, 30], [0, 0], [-40, 30]]
    hand = Hand.from_mapping({"region": {"polygon": notch}, "tremor_deg": 0}, seed=12)
    poses = np.array([hand.pose_deg(float(s)) for s in np.arange(0.0, 120.0, 0.01)])
    depth = hand.region.edge_distance_deg(poses[:, 0], poses[:, 1])
    assert depth.min() >= PATH_DEPTH_FLOOR_DEG - 1e-9
    assert np.mean(depth < EDGE_INSET_DEG + 0.5) > 0.01
