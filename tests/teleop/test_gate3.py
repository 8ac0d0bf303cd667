"""The three-servo gate: commands anywhere on SO(3) (twist near +-180 deg, tilt near +-90 deg)
never give a pose outside the region or the hard limits, the slew limit is a rotation speed,
and an inside command is reached exactly."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from limbctl.errors import ConfigError, SafetyError
from limbctl.geometry.gimbal import pose_quat_scalar
from limbctl.geometry.twist import compose_one, decompose_one
from limbctl.teleop.gate import Outcome
from limbctl.teleop.gate3 import Gate3, GateLimits3, geodesic, toward, written_tolerance_deg3

STEP = math.radians(2.0)


class ConeBand:
    """A true region over full orientations: the limb within ``half_angle`` of +x and its twist
    within ``half_width`` of ``centre``. ``correct`` is the engines' two-step clamp (direction
    onto the cone keeping the twist, then the twist into the band): always inside the region,
    not always the nearest orientation, which the gate does not need for its safety."""

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
        return compose_one(d, self.centre + offset)


def limits(max_step=STEP, max_joint_step=math.radians(10.0)):
    return GateLimits3(
        pan_min=math.radians(-115),
        pan_max=math.radians(115),
        tilt_min=math.radians(-55),
        tilt_max=math.radians(70),
        roll_min=math.radians(-100),
        roll_max=math.radians(100),
        max_step=max_step,
        max_joint_step=max_joint_step,
    )


def make_gate(**kw):
    gate = Gate3(ConeBand(math.radians(40), 0.0, math.radians(30)), limits(**kw))
    gate.start(0.0, 0.0, 0.0)
    return gate


def unit(v):
    v = np.asarray(v, dtype=float)
    q = v / np.linalg.norm(v)
    return -q if q[0] < 0 else q


def check_result(gate, before, result):
    lim = gate.limits
    pose = result.pose
    assert lim.inside(*pose)
    q = pose_quat_scalar(*pose)
    region = gate.envelope
    assert region.contains(q) or geodesic(q, region.correct(q)) <= lim.region_tolerance
    assert max(abs(a - b) for a, b in zip(pose, before)) <= lim.max_joint_step + 1e-12


quats = st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(
    lambda v: 1e-3 < sum(x * x for x in v)
)
# families the issue names: twist near +-180 deg; tilt near +-90 deg (pan and roll share an axis)
twist_edge = st.tuples(
    st.floats(-math.pi, math.pi),
    st.floats(-1.4, 1.4),
    st.sampled_from([-1.0, 1.0]),
    st.floats(0.0, 0.05),
).map(
    lambda a: compose_one(
        (math.cos(a[1]) * math.cos(a[0]), math.cos(a[1]) * math.sin(a[0]), math.sin(a[1])),
        a[2] * (math.pi - a[3]),
    )
)
tilt_edge = st.tuples(
    st.floats(-math.pi, math.pi),
    st.sampled_from([-1.0, 1.0]),
    st.floats(0.0, 0.05),
    st.floats(-math.pi, math.pi),
).map(lambda a: pose_quat_scalar(a[0], a[1] * (math.pi / 2 - a[2]), a[3]))


@settings(max_examples=60, deadline=None)
@given(st.lists(st.one_of(quats.map(unit), twist_edge, tilt_edge), min_size=1, max_size=6))
def test_commands_anywhere_on_so3_never_leave_the_region_or_the_limits(targets):
    gate = make_gate()
    for target in targets:
        for _ in range(25):
            before = gate.safe_pose
            result = gate.step(target)
            check_result(gate, before, result)
            # the rotation per cycle: at most max_step toward the target, then corrected
            assert (
                geodesic(pose_quat_scalar(*before), pose_quat_scalar(*result.pose))
                <= (2 * gate.limits.max_step + 1e-9)
                or result.outcome is Outcome.HELD
            )


def test_an_inside_command_is_reached_exactly_at_the_slew_rate():
    gate = make_gate()
    target = pose_quat_scalar(math.radians(20), math.radians(15), math.radians(10))
    assert gate.envelope.contains(target)
    angles = []
    for _ in range(40):
        before = pose_quat_scalar(*gate.safe_pose)
        result = gate.step(target)
        angles.append(geodesic(before, pose_quat_scalar(*result.pose)))
        if result.outcome is Outcome.PASSED:
            break
    assert result.outcome is Outcome.PASSED
    assert result.pose == pytest.approx(
        (math.radians(20), math.radians(15), math.radians(10)), abs=1e-9
    )
    # every slewed cycle turns the limb by exactly max_step of rotation
    assert np.allclose(angles[:-1], STEP, atol=1e-9)


def test_a_twist_outside_the_band_is_corrected_onto_it():
    gate = make_gate(max_step=math.radians(180), max_joint_step=math.radians(180))
    target = compose_one((1.0, 0.0, 0.0), math.radians(170))
    result = gate.step(target)
    assert result.corrected
    d, tau = decompose_one(pose_quat_scalar(*result.pose))
    assert math.degrees(tau) == pytest.approx(30.0, abs=1e-6)


def test_bad_targets_are_held_and_start_outside_is_refused():
    gate = make_gate()
    for bad in (np.array([np.nan, 0, 0, 1.0]), np.array([2.0, 0, 0, 0]), np.zeros(3)):
        assert gate.step(bad).outcome is Outcome.HELD
    with pytest.raises(SafetyError, match="roll 60.0 deg, outside"):
        Gate3(gate.envelope, limits()).start(0.0, 0.0, math.radians(60))
    with pytest.raises(ConfigError):
        GateLimits3(0, 1, 0, 1, 1, 0, 0.1, 0.1)


def test_toward_turns_by_the_step_along_the_shortest_rotation():
    a = pose_quat_scalar(0.0, 0.0, 0.0)
    b = pose_quat_scalar(0.0, 0.0, math.radians(90))
    half = toward(a, b, math.radians(30))
    assert geodesic(a, half) == pytest.approx(math.radians(30), abs=1e-12)
    assert geodesic(half, b) == pytest.approx(math.radians(60), abs=1e-12)
    assert np.array_equal(toward(a, b, math.radians(100)), b)


def test_written_tolerance_grows_with_the_third_joint():
    assert written_tolerance_deg3() == pytest.approx(0.108, abs=5e-4)
    # the bound holds: rounding each joint by half a tick turns the limb by at most that
    rng = np.random.default_rng(0)
    half_tick = math.pi / 4096
    worst = 0.0
    for pan, tilt, roll in rng.uniform([-2, -1.5, -1.7], [2, 1.5, 1.7], size=(2000, 3)):
        signs = rng.choice([-1.0, 1.0], size=3)
        moved = pose_quat_scalar(*(np.array([pan, tilt, roll]) + signs * half_tick))
        worst = max(worst, geodesic(pose_quat_scalar(pan, tilt, roll), moved))
    assert math.degrees(worst) <= written_tolerance_deg3() - 0.01 + 1e-9
