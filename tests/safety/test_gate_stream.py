"""Promise 1: no goal reaches a servo unless the gate made it, inside the region and the limits;
property tests in process and end to end, judged by the simulator's goal log."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from limbctl.envelope import Cone
from limbctl.errors import InvalidInputError
from limbctl.geometry.gimbal import pan_tilt_to_direction
from limbctl.servo.profiles import joint_tick_limits
from limbctl.servo.rig import Rig
from limbctl.teleop.commands import parse_command
from limbctl.teleop.gate import Outcome
from limbctl.teleop.loop import LoopConfig, SafeState, run
from tests.safety.support import (
    PROFILE,
    PacedSource,
    RecordingGate,
    assert_goals_safe,
    bean_model,
    excursion_deg,
    gate_limits,
    goal_log_poses,
    live_rig,
    settle,
    written_tolerance_deg,
)

# ---- command streams ---------------------------------------------------------------------------
ODD_NUMBERS = [
    *"NaN Infinity -Infinity 1e400 -1e400 5e-324 2.2250738585072014e-308".split(),
    "1" + "0" * 400,  # an integer too large for a float
    *'1e6 -0.0 true null "10" [1] {}'.split(),
]
any_float = st.floats(allow_nan=True, allow_infinity=True, width=64)
finite = st.floats(-1e3, 1e3, allow_nan=False)
tiny = st.floats(-1e-300, 1e-300, allow_nan=False)

pan_tilt_lines = st.builds(
    lambda p, t: json.dumps({"pan": p, "tilt": t}), st.floats(-180, 180), st.floats(-90, 90)
)
dir_lines = st.builds(
    lambda v: json.dumps({"dir": v}), st.lists(st.one_of(finite, tiny), min_size=3, max_size=3)
)
q_lines = st.builds(
    lambda v, scale: json.dumps({"q": [c * scale for c in v]}),
    st.lists(st.floats(-1, 1), min_size=4, max_size=4)
    .filter(lambda v: np.linalg.norm(v) > 1e-3)
    .map(lambda v: list(np.asarray(v) / np.linalg.norm(v))),
    st.sampled_from([1.0, 1.0005, 0.9995, 1.01, 0.0, -1.0]),
)
odd_lines = st.builds(
    lambda key, odd: {
        "pan": f'{{"pan": {odd}, "tilt": 0}}',
        "tilt": f'{{"pan": 0, "tilt": {odd}}}',
        "dir": f'{{"dir": [1, {odd}, 0]}}',
        "q": f'{{"q": [{odd}, 0, 0, 0]}}',
        "t": f'{{"t": {odd}, "pan": 1, "tilt": 1}}',
    }[key],
    st.sampled_from(["pan", "tilt", "dir", "q", "t"]),
    st.sampled_from(ODD_NUMBERS),
)
wild_json = st.recursive(
    st.none() | st.booleans() | any_float | st.text(max_size=8),
    lambda inner: (
        st.lists(inner, max_size=4)
        | st.dictionaries(st.sampled_from(["pan", "tilt", "dir", "q", "t", "x"]), inner, max_size=3)
    ),
    max_leaves=8,
).map(json.dumps)
garbage = st.one_of(st.binary(max_size=80), st.text(max_size=80))

command_lines = st.one_of(
    pan_tilt_lines, pan_tilt_lines, dir_lines, q_lines, odd_lines, wild_json, garbage
)
streams = st.lists(command_lines, min_size=1, max_size=60)
models = st.one_of(st.floats(8.0, 80.0).map(lambda a: Cone(math.radians(a))), st.just("bean"))


def _model(choice):
    return bean_model() if choice == "bean" else choice


def expected_refusals(lines) -> int:
    refused = 0
    for line in lines:
        text = line.strip() if isinstance(line, (str, bytes)) else line
        if not text:
            continue
        try:
            parse_command(text)
        except InvalidInputError:
            refused += 1
    return refused


# ---- in process: gate + tick conversion, many examples ----------------------------------------
@settings(max_examples=120, deadline=None)
@given(
    model=models,
    lines=streams,
    rate_hz=st.floats(50.0, 1000.0),
    speed=st.floats(10.0, 720.0),
    start=st.tuples(st.floats(-3.0, 3.0), st.floats(-3.0, 3.0)),
)
def test_every_gated_goal_is_inside_region_and_limits(model, lines, rate_hz, speed, start):
    model = _model(model)
    limits = gate_limits(rate_hz, speed)
    gate = RecordingGate(model, limits)
    rig = Rig(PROFILE)
    gate.start(math.radians(start[0]), math.radians(start[1]))
    lo_pan, hi_pan = joint_tick_limits(PROFILE.pan)
    lo_tilt, hi_tilt = joint_tick_limits(PROFILE.tilt)
    previous = gate.safe_pose
    for line in lines:
        try:
            command = parse_command(line)
        except InvalidInputError:
            continue
        # the parser only lets finite unit orientations through
        assert np.isfinite(command.q).all() and abs(np.linalg.norm(command.q) - 1) < 1e-9
        for _ in range(3):
            result = gate.step(command.q)
            goal = rig.goal_for(*result.pose)
            assert lo_pan <= goal.ticks[0] <= hi_pan and lo_tilt <= goal.ticks[1] <= hi_tilt
            assert not goal.clamped, "the gate left a pose beyond the hard limits to the rig"
            pan, tilt = rig.ticks_to_angles(*goal.ticks)
            worst = excursion_deg(model, pan_tilt_to_direction(pan, tilt))[0]
            assert worst <= written_tolerance_deg(limits)
            # a step never exceeds the joint-step limit (the singularity guard)
            assert max(abs(a - b) for a, b in zip(result.pose, previous, strict=True)) <= (
                limits.max_joint_step + 1e-12
            )
            previous = result.pose


# ---- end to end: the real loop, judged by the simulator's goal log ---------------------------
@pytest.fixture(scope="module")
def live(tmp_path_factory):
    log = tmp_path_factory.mktemp("gate_stream") / "goals.jsonl"
    with live_rig(goal_log=log) as (sim, rig):
        yield sim, rig, log


@settings(
    max_examples=10,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(
    model=models,
    lines=streams,
    rate_hz=st.sampled_from([100.0, 200.0, 500.0]),
    speed=st.floats(90.0, 360.0),
    drop=st.sampled_from([0.0, 0.01, 0.05, 0.2]),
    corrupt=st.sampled_from([0.0, 0.02]),
    seed=st.integers(0, 2**16),
)
def test_loop_writes_only_gated_goals_inside_the_region(
    live, model, lines, rate_hz, speed, drop, corrupt, seed
):
    sim, rig, log = live
    model = _model(model)
    sim.set_faults()
    settle(rig, (0.0, 0.0))
    offset = log.stat().st_size
    limits = gate_limits(rate_hz, speed)
    gate = RecordingGate(model, limits)
    sim.set_faults(drop=drop, corrupt=corrupt, seed=seed)
    config = LoopConfig(rate_hz=rate_hz, duration_s=3.0, safe_state=SafeState.HOLD)
    try:
        summary = run(rig, gate, PacedSource(lines), config)
    finally:
        sim.set_faults()
    rig.read_pose()  # one round trip: the simulator has handled every goal before it answers
    logged = goal_log_poses(log, offset)

    assert summary.rejected == expected_refusals(lines)
    assert len(logged) <= summary.goals_written
    gated = sum(1 for r in gate.results if r.outcome is not Outcome.HELD)
    assert summary.goals_written <= gated
    assert bool(logged) == bool(summary.goals_written)
    assert_goals_safe(logged, model, limits, gate.produced_ticks(rig))
    if summary.ended_by == "fault":
        assert summary.fault and summary.exit_code == 3
