"""The gate on two servos (a cone) and three (a cone with a twist band): commands anywhere never
give a pose outside the region or the hard limits, slew-limited; bad targets are held."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from limbctl.envelope import Cone
from limbctl.errors import ConfigError, SafetyError
from limbctl.geometry.gimbal import (
    chain_twist,
    pan_tilt_to_direction,
    pan_tilt_to_quat,
    pose_quat_scalar,
)
from limbctl.geometry.twist import compose, decompose_one
from limbctl.teleop.gate import Gate, GateLimits, Outcome, written_tolerance_deg

R = math.radians(40)
STEP = math.radians(2.0)
RIGS = (2, 3)


class ConeBand:
    """The limb within ``half_angle`` of +x, its twist within ``half_width`` of ``centre``;
    ``correct`` clamps the direction, then the twist (not always the nearest)."""

    def __init__(self, half_angle: float, centre: float, half_width: float) -> None:
        self.half_angle, self.centre, self.half_width = half_angle, centre, half_width

    def _split(self, q):
        d, tau = decompose_one(np.asarray(q, dtype=float))
        angle = math.acos(max(-1.0, min(1.0, d[0])))
        offset = math.remainder(tau - self.centre, 2 * math.pi)
        return d, angle, offset

    def contains(self, q) -> bool:
        _, angle, offset = self._split(q)
        return angle <= self.half_angle and abs(offset) <= self.half_width

    def correct(self, q) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        if self.contains(q):
            return q
        d, angle, offset = self._split(q)
        if angle > self.half_angle:
            side = math.hypot(d[1], d[2])
            if side < 1e-12:
                d = (math.cos(self.half_angle), math.sin(self.half_angle), 0.0)
            else:
                s = math.sin(self.half_angle) / side
                d = (math.cos(self.half_angle), d[1] * s, d[2] * s)
        offset = max(-self.half_width, min(self.half_width, offset))
        return compose(np.array(d), self.centre + offset)


def quat(pose) -> np.ndarray:
    """The orientation (4,) of a pose (rad) of either chain."""
    return pan_tilt_to_quat(*pose) if len(pose) == 2 else pose_quat_scalar(*pose)


def make_gate(rig, half_angle=R, max_step=STEP, max_joint_step=10.0, tilt_max=None, start=True):
    """A gate over a cone (two servos) or a cone with a +-30 deg twist band (three), at rest."""
    tilt_max = math.radians(80 if rig == 2 else 70) if tilt_max is None else tilt_max
    limits = GateLimits(
        joint_min=tuple(map(math.radians, (-100, -30) if rig == 2 else (-115, -55, -100))),
        joint_max=(math.radians(100 if rig == 2 else 115), tilt_max, math.radians(100))[:rig],
        max_step=max_step,
        max_joint_step=math.radians(max_joint_step),
    )
    region = Cone(half_angle) if rig == 2 else ConeBand(half_angle, 0.0, math.radians(30))
    gate = Gate(region, limits)
    if start:
        gate.start(*(0.0,) * rig)
    return gate


def moved(gate, before, after) -> float:
    """How far (rad) the limb moved between two poses, in the gate's chain's distance."""
    chain = gate.chain
    return chain.distance(chain.point_at(before), chain.point_at(after))


@pytest.mark.parametrize("rig", RIGS)
def test_an_inside_command_is_reached_exactly_and_an_outside_one_slides_onto_the_edge(rig):
    """Inside: reached exactly at the slew rate. Outside (two servos: pan 90 deg, past the
    cone; three: roll 90 deg, past the twist band): slid onto the edge in bounded steps."""
    gate = make_gate(rig)
    target = tuple(map(math.radians, (20.0, 15.0, 10.0)))[:rig]
    assert gate.envelope.contains(quat(target))
    steps = []
    for _ in range(40):
        before = gate.safe_pose
        result = gate.step(quat(target))
        steps.append(moved(gate, before, result.pose))
        if result.outcome is Outcome.PASSED:
            break
    assert result.outcome is Outcome.PASSED
    assert result.pose == pytest.approx(target, abs=1e-9)
    # every slewed cycle moves the limb by exactly max_step
    assert len(steps) > 5 and np.allclose(steps[:-1], STEP, atol=1e-9)
    gate = make_gate(rig)
    target, edge = {
        2: ((math.radians(90), 0.0), (R, 0.0)),
        3: ((0.0, 0.0, math.radians(90)), (0.0, 0.0, math.radians(30))),
    }[rig]
    results = [gate.step(quat(target)) for _ in range(40)]
    assert results[-1].outcome is Outcome.CORRECTED and not results[-1].slewed
    assert results[-1].pose == pytest.approx(edge, abs=1e-9)
    for a, b in zip(results, results[1:]):
        assert moved(gate, a.pose, b.pose) <= STEP + 1e-9


@pytest.mark.parametrize("rig", RIGS)
def test_bad_targets_are_held_and_start_outside_is_refused(rig):
    gate = make_gate(rig, start=False)
    gate.start(*(0.1,) * rig)
    for bad in (np.array([np.nan, 0, 0, 1.0]), np.array([np.inf, 1, 0, 0]), np.zeros(4)):
        held = gate.step(bad)
        assert held.outcome is Outcome.HELD and held.pose == (0.1,) * rig
    assert gate.step(np.array([2.0, 0, 0, 0])).outcome is Outcome.HELD
    assert gate.step(np.ones(3)).reason == "malformed target"
    outside, said = (
        ((math.radians(80), 0.0), "tilt 0.0 deg, outside the taught region or the rig's")
        if rig == 2
        else ((0.0, 0.0, math.radians(60)), "roll 60.0 deg, outside the taught region (swing and")
    )
    with pytest.raises(SafetyError, match=re.escape(said)):
        make_gate(rig, start=False).start(*outside)
    with pytest.raises(SafetyError):
        make_gate(rig, start=False).start(float("nan"), *(0.0,) * (rig - 1))
    with pytest.raises(RuntimeError, match="start"):
        make_gate(rig, start=False).step(quat((0.0,) * rig))


def test_limits_are_validated():
    with pytest.raises(ConfigError):
        GateLimits((0.0, 0.0), (-1.0, 1.0), 0.1, 0.1)
    with pytest.raises(ConfigError):
        GateLimits((0, 0, 1), (1, 1, 0), 0.1, 0.1)
    with pytest.raises(ConfigError):
        GateLimits((-1.0, -1.0), (1.0, 1.0), float("nan"), 0.1)
    with pytest.raises(ConfigError, match="2 or 3 joints"):
        GateLimits((-1.0,) * 4, (1.0,) * 4, 0.1, 0.1)
    with pytest.raises(ConfigError):
        GateLimits((-1.0, -1.0), (1.0, 1.0, 1.0), 0.1, 0.1)
    assert GateLimits((-1, -1), (1, 1), 0.1, 0.1).inside(1.0, -1.0)
    assert not GateLimits((-1, -1), (1, 1), 0.1, 0.1).inside(0.0, float("nan"))


def unit(v):
    v = np.asarray(v, dtype=float)
    q = v / np.linalg.norm(v)
    return -q if q[0] < 0 else q


odd = st.sampled_from(
    [np.array([np.nan, 0, 0, 0]), np.array([np.inf, 1, 0, 0]), np.zeros(4), np.ones(3)]
)
directions = st.tuples(st.floats(-math.pi, math.pi), st.floats(-math.pi / 2, math.pi / 2)).map(
    lambda pt: pan_tilt_to_quat(*pt)
)
quats = st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(
    lambda v: 1e-3 < sum(x * x for x in v)
)
# the families: twist near +-180 deg; tilt near +-90 deg (pan and roll share an axis)
twist_edge = st.tuples(
    st.floats(-math.pi, math.pi),
    st.floats(-1.4, 1.4),
    st.sampled_from([-1.0, 1.0]),
    st.floats(0.0, 0.05),
).map(lambda a: compose(pan_tilt_to_direction(a[0], a[1]), a[2] * (math.pi - a[3])))
tilt_edge = st.tuples(
    st.floats(-math.pi, math.pi),
    st.sampled_from([-1.0, 1.0]),
    st.floats(0.0, 0.05),
    st.floats(-math.pi, math.pi),
).map(lambda a: pose_quat_scalar(a[0], a[1] * (math.pi / 2 - a[2]), a[3]))
TARGETS = {2: st.one_of(directions, odd), 3: st.one_of(quats.map(unit), twist_edge, tilt_edge, odd)}


@pytest.mark.parametrize("rig", RIGS)
@settings(max_examples=60, deadline=None)
@given(data=st.data(), half_angle_deg=st.floats(5, 120))
def test_every_output_is_safe_and_slew_limited(rig, data, half_angle_deg):
    gate = make_gate(rig, half_angle=math.radians(half_angle_deg))
    lim, region, chain = gate.limits, gate.envelope, gate.chain
    # the step moves max_step, then its correction: on a cone that keeps it within max_step, on
    # the cone with a band the twist clamp may add up to another max_step
    bound = lim.max_step * (1 if rig == 2 else 2) + 1e-9
    for target in data.draw(st.lists(TARGETS[rig], min_size=1, max_size=8)):
        for _ in range(15):
            before = gate.safe_pose
            result = gate.step(target)
            assert lim.inside(*result.pose)
            q = quat(result.pose)
            nearest = chain.point(region.correct(q))
            assert chain.distance(chain.point(q), nearest) <= lim.region_tolerance
            joint_step = max(abs(a - b) for a, b in zip(result.pose, before))
            assert joint_step <= lim.max_joint_step + 1e-12
            assert moved(gate, before, result.pose) <= bound


def test_a_step_clamped_at_a_joint_limit_stays_within_the_slew_limit():
    # hypothesis's example: along tilt's -30 deg limit on a 75 deg cone, a clamped step overshot
    gate = make_gate(2, half_angle=math.radians(75.0))
    clamped = []
    for target in ((1.0, 0.0), (0.0, -1.5), (-2.0, 0.0)):
        for _ in range(15):
            before = gate.safe_pose
            result = gate.step(pan_tilt_to_quat(*target))
            if result.clamped:  # it ran along the limit
                clamped.append(moved(gate, before, result.pose))
                assert result.pose[1] == pytest.approx(math.radians(-30.0))
    assert clamped and 0.9 * gate.limits.max_step < max(clamped)
    assert max(clamped) <= gate.limits.max_step + 1e-12


@pytest.mark.parametrize("rig", RIGS)
@settings(max_examples=60, deadline=None)
@given(pose=st.tuples(st.floats(-0.5, 0.5), st.floats(-0.4, 0.4), st.floats(-0.45, 0.45)))
def test_valid_commands_within_one_step_pass_exactly(rig, pose):
    gate = make_gate(rig, max_step=math.radians(90), max_joint_step=90.0)
    q = quat(pose[:rig])
    if not np.array_equal(gate.envelope.correct(q), q):  # outside, or on the edge
        return
    result = gate.step(q)
    assert result.outcome is Outcome.PASSED
    assert gate.chain.distance(gate.chain.point_at(result.pose), gate.chain.point(q)) <= 1e-12


@pytest.mark.parametrize("rig", RIGS)
def test_a_hard_limit_clamps_inside_the_region_and_the_joint_step_limit_holds_at_the_pole(rig):
    """Clamped at a hard limit inside the region; near the pole the joint step bounds the pan."""
    gate = make_gate(rig, tilt_max=math.radians(10))
    for _ in range(30):
        result = gate.step(quat((0.0, math.radians(30), 0.0)[:rig]))
    assert result.outcome is Outcome.CLAMPED
    assert result.pose[1] == pytest.approx(math.radians(10))
    # limb almost straight up: a short step across the pole swings the pan far
    # (three servos: the roll keeps the twist 0, inside the band)
    gate = make_gate(rig, math.radians(179), math.radians(5), 3.0, math.radians(85), start=False)
    start = (0.0, math.radians(79), 0.0)[:rig]
    gate.start(*start)
    pan, tilt = math.radians(90), math.radians(79)
    result = gate.step(quat((pan, tilt, -float(chain_twist(pan, tilt)))[:rig]))
    assert result.slewed and result.pose[0] > math.radians(1)
    assert max(abs(v - v0) for v, v0 in zip(result.pose, start)) <= math.radians(3) + 1e-12


@pytest.mark.parametrize(("rig", "stated"), [(2, 0.072), (3, 0.108)])
def test_the_written_tolerance_bounds_the_rounding_to_ticks(rig, stated):
    assert written_tolerance_deg(joints=rig) == pytest.approx(stated, abs=5e-4)
    # rounding each joint by half a tick moves the limb by at most the bound less the gate's own
    chain = make_gate(rig).chain
    rng = np.random.default_rng(0)
    half_tick = math.pi / 4096
    worst = 0.0
    for pose in rng.uniform([-2, -1.5, -1.7][:rig], [2, 1.5, 1.7][:rig], size=(2000, rig)):
        shifted = pose + rng.choice([-1.0, 1.0], size=rig) * half_tick
        worst = max(worst, chain.distance(chain.point_at(pose), chain.point_at(shifted)))
    assert math.degrees(worst) <= written_tolerance_deg(joints=rig) - 0.01 + 1e-9
    assert math.degrees(worst) > written_tolerance_deg(joints=rig) - 0.03  # the bound is tight
