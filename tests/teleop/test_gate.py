import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from limbctl.envelope import Cone
from limbctl.errors import ConfigError, SafetyError
from limbctl.geometry.gimbal import pan_tilt_to_direction, pan_tilt_to_quat
from limbctl.geometry.quat import direction_angle, limb_direction
from limbctl.teleop.gate import Gate, GateLimits, Outcome

R = math.radians(40)
STEP = math.radians(2)


def make_gate(half_angle=R, max_step=STEP, tilt_max=math.radians(80), max_joint_step=10.0):
    limits = GateLimits(
        pan_min=math.radians(-100),
        pan_max=math.radians(100),
        tilt_min=math.radians(-30),
        tilt_max=tilt_max,
        max_step=max_step,
        max_joint_step=math.radians(max_joint_step),
    )
    return Gate(Cone(half_angle), limits)


def angle_from_x(pan, tilt):
    return float(direction_angle(pan_tilt_to_direction(pan, tilt), np.array([1.0, 0, 0])))


def test_inside_command_passes_unchanged():
    gate = make_gate()
    gate.start(0.0, 0.0)
    pan, tilt = math.radians(1.0), math.radians(-0.5)
    result = gate.step(pan_tilt_to_quat(pan, tilt))
    assert result.outcome is Outcome.PASSED
    assert result.pan == pytest.approx(pan, abs=1e-12)
    assert result.tilt == pytest.approx(tilt, abs=1e-12)


def test_outside_command_slides_to_the_cone_edge_in_bounded_steps():
    gate = make_gate()
    gate.start(0.0, 0.0)
    target = pan_tilt_to_quat(math.radians(90), 0.0)
    poses = [gate.step(target) for _ in range(40)]
    final = poses[-1]
    assert final.outcome is Outcome.CORRECTED and not final.slewed
    assert final.pan == pytest.approx(R, abs=1e-9)
    assert final.tilt == pytest.approx(0.0, abs=1e-9)
    for a, b in zip(poses, poses[1:]):
        da = pan_tilt_to_direction(a.pan, a.tilt)
        db = pan_tilt_to_direction(b.pan, b.tilt)
        assert direction_angle(da, db) <= STEP + 1e-9


def test_hard_limit_clamps_inside_the_region():
    gate = make_gate(tilt_max=math.radians(10))
    gate.start(0.0, 0.0)
    for _ in range(30):
        result = gate.step(pan_tilt_to_quat(0.0, math.radians(30)))
    assert result.outcome is Outcome.CLAMPED
    assert result.tilt == pytest.approx(math.radians(10))


def test_nan_target_is_held_and_start_outside_refused():
    gate = make_gate()
    gate.start(0.1, 0.1)
    held = gate.step(np.array([np.nan, 0, 0, 0]))
    assert held.outcome is Outcome.HELD and (held.pan, held.tilt) == (0.1, 0.1)
    assert gate.step(np.zeros(4)).outcome is Outcome.HELD
    assert gate.step(np.array([2.0, 0, 0, 0])).outcome is Outcome.HELD
    with pytest.raises(SafetyError, match="outside the taught region"):
        make_gate().start(math.radians(80), 0.0)
    with pytest.raises(SafetyError):
        make_gate().start(float("nan"), 0.0)


def test_limits_are_validated():
    with pytest.raises(ConfigError):
        GateLimits(0.0, -1.0, 0.0, 1.0, 0.1, 0.1)
    with pytest.raises(ConfigError):
        GateLimits(-1.0, 1.0, -1.0, 1.0, float("nan"), 0.1)


directions = st.tuples(st.floats(-math.pi, math.pi), st.floats(-math.pi / 2, math.pi / 2)).map(
    lambda pt: pan_tilt_to_quat(*pt)
)
odd = st.sampled_from(
    [np.array([np.nan, 0, 0, 0]), np.array([np.inf, 1, 0, 0]), np.zeros(4), np.ones(3)]
)


@settings(max_examples=60, deadline=None)
@given(
    stream=st.lists(st.one_of(directions, odd), min_size=1, max_size=60),
    half_angle_deg=st.floats(5, 120),
)
def test_every_output_is_safe_and_slew_limited(stream, half_angle_deg):
    gate = make_gate(half_angle=math.radians(half_angle_deg))
    gate.start(0.0, 0.0)
    lim = gate.limits
    prev = pan_tilt_to_direction(0.0, 0.0)
    for target in stream:
        result = gate.step(target)
        assert lim.pan_min <= result.pan <= lim.pan_max
        assert lim.tilt_min <= result.tilt <= lim.tilt_max
        assert angle_from_x(result.pan, result.tilt) <= math.radians(half_angle_deg) + 1e-9
        d = pan_tilt_to_direction(result.pan, result.tilt)
        assert direction_angle(prev, d) <= lim.max_step + 1e-9
        prev = d


@settings(max_examples=60, deadline=None)
@given(pan=st.floats(-0.5, 0.5), tilt=st.floats(-0.4, 0.4))
def test_valid_commands_within_one_step_pass_exactly(pan, tilt):
    gate = make_gate(max_step=math.radians(90), max_joint_step=90.0)
    gate.start(0.0, 0.0)
    q = pan_tilt_to_quat(pan, tilt)
    if angle_from_x(pan, tilt) > R - 1e-6:
        return
    result = gate.step(q)
    assert result.outcome is Outcome.PASSED
    np.testing.assert_allclose(
        limb_direction(pan_tilt_to_quat(result.pan, result.tilt)), limb_direction(q), atol=1e-12
    )


def test_joint_step_limit_near_the_singularity():
    # limb almost straight up: a short direction step across the pole swings the pan far
    gate = make_gate(half_angle=math.radians(179), max_step=math.radians(5), max_joint_step=3.0)
    gate.start(0.0, math.radians(79))
    result = gate.step(pan_tilt_to_quat(math.radians(90), math.radians(79)))
    assert result.slewed
    assert abs(result.pan) <= math.radians(3) + 1e-12
