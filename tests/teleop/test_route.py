"""Routing (limbctl/teleop/route.py) through both gates on random outlines with a bay and a notch:
a command inside is reached within the stated bound; a straight way inside is followed exactly."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from limbctl.geometry import scalar
from limbctl.geometry.chains import chain_geometry
from limbctl.geometry.gimbal import pan_tilt_roll_scalar
from limbctl.geometry.twist import compose, decompose, wrap
from limbctl.teleop.gate import Gate, GateLimits
from limbctl.teleop.route import (
    REACH_EXTRA_CYCLES,
    REACH_FACTOR,
    TWIST_SPLITS,
    Router,
    fibonacci_sphere,
)
from tests.compile_probe import COUNTER
from tests.teleop.bays import (
    InsidePaths,
    OutlineBandRegion,
    OutlineRegion,
    bay_outline,
    inside_points,
    teaching,
)

STEP = math.radians(0.6)  # limbctl teleop's default: 120 deg/s at 200 Hz
ROLL = math.radians(179.0)
RIGS = (2, 3)


def region_for(rig: int, seed: int):
    rng = np.random.default_rng(seed)
    region = OutlineRegion(bay_outline(rng)) if rig == 2 else OutlineBandRegion.random(rng)
    return region, rng


def gate_at(region, rig: int, q: np.ndarray):
    lo = (math.radians(-170), math.radians(-85), -ROLL)[:rig]
    hi = (math.radians(170), math.radians(85), ROLL)[:rig]
    gate = Gate(region, GateLimits(lo, hi, STEP, max(3.0 * STEP, math.radians(1.0))))
    if rig == 2:
        gate.start(*scalar.pan_tilt(scalar.limb(q), 0.0))
    else:
        gate.start(*pan_tilt_roll_scalar(q, 0.0, 0.0, -ROLL, ROLL))
    return gate


def pose_q(gate, rig: int) -> np.ndarray:
    return gate.chain.quat(gate.chain.point_at(gate.safe_pose))


def apart(a: np.ndarray, b: np.ndarray, rig: int) -> float:
    chain = chain_geometry(rig)
    return chain.distance(chain.point(a), chain.point(b))


def needed(paths: InsidePaths, a: np.ndarray, b: np.ndarray, rig: int) -> float:
    """The distance a reach needs (rad): the shortest path inside, plus any twist to turn."""
    (da, ta), (db, tb) = decompose(a), decompose(b)
    length = paths.length(da, db)
    return length if rig == 2 else length + abs(float(wrap(tb - ta)))


def drive(gate, region, rig: int, target: np.ndarray, limit: int) -> int | None:
    """Step ``gate`` to within 1e-3 rad of ``target``: the cycles taken (None past ``limit``),
    every written pose checked inside and within two steps (a step, its correction) of the last."""
    before = pose_q(gate, rig)
    for n in range(1, limit + 1):
        gate.step(target)
        now = pose_q(gate, rig)
        # a step of max_step, then corrected onto the region: never a jump across it
        assert apart(before, now, rig) <= 2.0 * STEP, f"cycle {n} jumped: not one step"
        off = 0.0 if region.contains(now) else apart(now, region.correct(now), rig)
        assert off <= math.radians(0.01), f"cycle {n} wrote a pose outside the region"
        before = now
        if apart(now, target, rig) < 1e-3:
            return n
    return None


def bound(length: float) -> float:
    """The stated bound (cycles) for a reach of ``length`` rad (docs/safety.md)."""
    return REACH_FACTOR * length / STEP + REACH_EXTRA_CYCLES


#: (seed, pair) where the gate before routing sat SLEWED at a concave wall, per chain.
STUCK_BEFORE = {2: (3, 0), 3: (7, 0)}


class OneAtATime:
    """A region (or any model) whose ``contains`` takes one quaternion only."""

    def __init__(self, region) -> None:
        self.region = region

    def contains(self, q):
        q = np.asarray(q)
        if q.shape != (4,):
            raise ValueError("one quaternion at a time")
        return self.region.contains(q)

    def correct(self, q):
        return self.region.correct(np.asarray(q))


@pytest.mark.parametrize("rig", RIGS, ids=["two", "three"])
def test_a_target_past_a_concave_wall_is_reached_within_the_bound(rig, monkeypatch):
    """Reached within the bound: by a batched region, one asked a pose at a time, and a target
    held behind the wall with a tremor, routed once."""
    from limbctl.geometry.quat import from_axis_angle, multiply
    from limbctl.teleop import route

    seed, pair = STUCK_BEFORE[rig]
    region, rng = region_for(rig, seed)
    pts = inside_points(region, 20, rng)
    a, b = pts[2 * pair], pts[2 * pair + 1]
    length = needed(InsidePaths(region), a, b, rig)
    assert length > apart(a, b, rig) + math.radians(0.5)  # the straight way leaves the region
    cycles = drive(gate_at(region, rig, a), region, rig, b, int(3 * length / STEP) + 400)
    assert cycles is not None, "the target was never reached: stuck at a wall"
    assert cycles <= bound(length)
    # one pose at a time: the router asks it row by row, its roadmap built when first needed
    gate = gate_at(OneAtATime(region), rig, a)
    assert not gate.router.batched and gate.router._nodes is None
    assert drive(gate, region, rig, b, int(bound(length)) + 1) is not None
    assert isinstance(gate.router, Router) and gate.router._nodes is not None
    # a tremor of 0.2 deg either side, turning every cycle
    gate = gate_at(region, rig, a)
    runs = []
    real = route.dijkstra
    monkeypatch.setattr(route, "dijkstra", lambda *args, **kw: runs.append(1) or real(*args, **kw))
    axis = np.array([0.0, 0.0, 1.0])
    for n in range(int(bound(length)) + 5):
        tremor = from_axis_angle(axis, math.radians(0.2) * (-1) ** n)
        target = multiply(tremor, b)
        target = -target if target[0] < 0 else target
        gate.step(target)
    assert apart(pose_q(gate, rig), target, rig) < 1e-3
    assert len(runs) == 1


@pytest.mark.parametrize("rig", RIGS, ids=["two", "three"])
def test_random_outlines_every_inside_target_is_reached_within_the_bound(rig):
    bent = 0
    for seed in (11, 12, 13):
        region, rng = region_for(rig, seed)
        paths = InsidePaths(region)
        pts = inside_points(region, 12, rng)
        for a, b in zip(pts[0::2], pts[1::2], strict=True):
            length = needed(paths, a, b, rig)
            bent += length > apart(a, b, rig) + math.radians(0.5)
            cycles = drive(gate_at(region, rig, a), region, rig, b, int(bound(length)) + 1)
            assert cycles is not None, (
                f"seed {seed}: a target {math.degrees(length):.1f} deg away along the region "
                f"was not reached within {bound(length):.0f} cycles"
            )
    assert bent >= 1  # the family is not all convex: some pairs need a bent path


@pytest.mark.parametrize("rig", RIGS, ids=["two", "three"])
def test_a_straight_way_inside_is_followed_exactly_as_without_routing(rig):
    region, rng = region_for(rig, 21)
    pts = inside_points(region, 40, rng)
    checked = 0
    for a, b in zip(pts[0::2], pts[1::2], strict=True):
        routed = gate_at(region, rig, a)
        if not routed.router.clear(pose_q(routed, rig), b):
            continue
        plain = gate_at(region, rig, a)
        plain.router.subgoal = lambda current, target: target  # the gate before routing
        for _ in range(int(apart(a, b, rig) / STEP) + 3):
            assert routed.step(b) == plain.step(b)
        assert apart(pose_q(routed, rig), b, rig) < 1e-6  # reached, passed unchanged
        checked += 1
    assert checked >= 5


def test_the_lattice_spacing_is_as_stated():
    d = fibonacci_sphere(math.radians(1.5))
    from scipy.spatial import cKDTree

    nearest = np.degrees(cKDTree(d).query(d, k=2)[0][:, 1] / 1.0)
    assert np.all(np.abs(np.linalg.norm(d, axis=1) - 1.0) < 1e-12)
    assert 1.2 < np.median(nearest) < 1.6  # about one spacing to the nearest neighbour


@pytest.mark.parametrize("rig", RIGS, ids=["two", "three"])
def test_a_fitted_region_routes_round_its_bay(rig):
    """A fitted model's region (batched: the roadmap built at start) is routed round a wall."""
    from limbctl.region.taught import TaughtRegion
    from limbctl.region.twist_region import TwistRegion

    truth, rng = region_for(rig, 31)
    region = (TaughtRegion() if rig == 2 else TwistRegion()).fit(teaching(truth, 60.0, rng))
    paths = InsidePaths(truth)
    pts = inside_points(truth, 400, rng)
    pts = pts[np.asarray(region.contains(pts), dtype=bool)]
    # the first pair whose way inside bends by 3 deg or more
    for a, b in zip(pts[0::2], pts[1::2], strict=True):
        length = needed(paths, a, b, rig)
        da, db = decompose(a)[0], decompose(b)[0]
        if paths.length(da, db) > math.acos(min(1.0, float(da @ db))) + math.radians(3.0):
            break
    else:
        pytest.fail("no pair with a bent way: the family lost its bays")
    gate = gate_at(region, rig, a)
    assert gate.router._nodes is not None  # built at start
    assert drive(gate, region, rig, b, int(bound(length)) + 1) is not None


@pytest.mark.parametrize("rig", RIGS, ids=["two", "three"])
def test_paths_judged_in_one_batch_are_judged_as_one_by_one(rig):
    """clear_rows answers as clear does path by path: from inside and outside, short paths too."""
    region, rng = region_for(rig, 41)
    router = gate_at(region, rig, inside_points(region, 1, rng)[0]).router
    inside = inside_points(region, 30, rng)
    starts = np.vstack([inside[:3], inside[3:6] * [1.0, 1.0, 0.0, 0.0] + [0.0, 0.0, 0.5, 0.5]])
    starts /= np.linalg.norm(starts, axis=1, keepdims=True)
    judged = 0
    for a in starts:
        # ends anywhere, and a few within one sample step of the start (judged at the start)
        near = a + rng.normal(scale=0.002, size=(4, 4))
        ends = np.vstack([inside[6:], near / np.linalg.norm(near, axis=1, keepdims=True)])
        one_by_one = [router.clear(a, b) for b in ends]
        assert router.clear_rows(a, ends).tolist() == one_by_one
        judged += sum(one_by_one)
    assert 0 < judged < len(starts) * 28  # both answers were met
    assert router.clear_rows(starts[0], np.empty((0, 4))).shape == (0,)


def test_a_three_servo_node_is_judged_at_the_twist_inside_nearest_the_pose():
    """Nodes near a pose are judged at its twist where inside, else at the twist inside nearest
    it (not the flood's): a path to one turns the limb only as far as the band makes it."""
    region, rng = region_for(3, 43)
    router = gate_at(region, 3, inside_points(region, 1, rng)[0]).router
    from_twist = moved = 0
    for q in inside_points(region, 20, rng):
        d, tau = decompose(q)
        near = router._near(d)
        seen = router._poses_at(near, float(tau))
        assert np.asarray(region.contains(seen), dtype=bool).all()
        turned = np.abs(wrap(decompose(seen)[1] - tau))
        flood = np.abs(wrap(router._node_twist[near] - tau))
        fits = np.asarray(region.contains(compose(router._nodes[near], tau)), dtype=bool)
        assert (turned[fits] < 1e-9).all()
        # elsewhere no farther than the flood's twist, and nearest within the halvings' step:
        # that step further toward the pose's twist is outside
        assert (turned[~fits] <= flood[~fits] + 1e-9).all()
        seen_tau = decompose(seen[~fits])[1]
        toward = np.sign(wrap(tau - seen_tau)) * (flood[~fits] / TWIST_SPLITS**2 + 1e-6)
        nearer = compose(router._nodes[near[~fits]], seen_tau + toward)
        assert not np.asarray(region.contains(nearer), dtype=bool).any()
        from_twist += int(fits.sum())
        moved += int((~fits).sum())
    assert from_twist > 0 and moved > 0  # both cases were met


def test_a_fitted_three_servo_route_point_outside_takes_the_nearest_twist_inside():
    """A route point outside at its twist is taken at the twist inside nearest it, not corrected
    back onto the present pose at a wall (benchmark seed 2002's fitted region)."""
    from limbctl.region.twist_region import TwistRegion

    truth, rng = region_for(3, 2002)
    region = TwistRegion().fit(teaching(truth, 60.0, rng))
    pts = inside_points(truth, 200, rng)
    a, b = pts[np.asarray(region.contains(pts), dtype=bool)][6:8]
    gate = gate_at(region, 3, a)
    length = needed(InsidePaths(truth), a, b, 3)
    assert drive(gate, region, 3, b, int(bound(length)) + 1) is not None


def test_a_fitted_three_servo_route_point_is_kept_when_a_step_is_corrected_off_the_way():
    """A step toward a route point that the gate corrects a hair off the straight way keeps that
    aim: recomputed there, the route turned back and the gate swung between two poses 15 deg
    from the target (benchmark seed 2077's fitted region, its first pair)."""
    from limbctl.region.twist_region import TwistRegion

    truth, rng = region_for(3, 2077)
    region = TwistRegion().fit(teaching(truth, 60.0, rng))
    pts = inside_points(truth, 100, np.random.default_rng(2078))
    a, b = pts[np.asarray(region.contains(pts), dtype=bool)][:2]
    gate = gate_at(region, 3, a)
    length = needed(InsidePaths(truth), a, b, 3)
    assert drive(gate, region, 3, b, int(bound(length)) + 1) is not None


GATE_FIRST_CALLS = (
    COUNTER
    + r"""
import math
import numpy as np
from limbctl.envelope import load_model
from limbctl.teleop.gate import Gate, GateLimits
model = load_model(sys.argv[2])
q = np.asarray(json.loads(sys.argv[3]))
lim = GateLimits((-3.0, -1.5, -3.1), (3.0, 1.5, 3.1), 0.0105, 0.0314)
gate = Gate(model, lim)
gate.start(*json.loads(sys.argv[4]))
ev.register("numba:compile", Count())
for rows in (q, q[0]):  # what a routing cycle asks: batches and single rows
    model.contains(rows)
    model.correct(rows)
with open(sys.argv[1], "w") as out:
    json.dump(compiled, out)
"""
)


def test_a_three_servo_gate_has_its_kernels_ready_before_the_first_cycle(tmp_path):
    """Empty kernel cache: the gate's start leaves no kernel for a routing cycle to compile."""
    from limbctl.envelope import RigidMap

    truth, rng = region_for(3, 31)
    model_path = tmp_path / "model.npz"
    RigidMap(twist=True, seed=0).fit(teaching(truth, 30.0, rng)).save(model_path)
    start = inside_points(truth, 1, rng)[0]
    pose = pan_tilt_roll_scalar(start, 0.0, 0.0, -ROLL, ROLL)
    commands = np.vstack([start, inside_points(truth, 4, rng)]).tolist()
    log = tmp_path / "compiled.json"
    root = Path(__file__).resolve().parents[2]
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache"), "PYTHONPATH": str(root)}
    args = [str(log), str(model_path), json.dumps(commands), json.dumps(list(pose))]
    done = subprocess.run(
        [sys.executable, "-c", GATE_FIRST_CALLS, *args], env=env, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    assert json.loads(log.read_text()) == []
