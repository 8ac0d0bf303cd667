"""Starting from outside the region and parking at the end, on the simulator through the SDK."""

from __future__ import annotations

import io
import math
import threading
import time

import numpy as np

from limbctl.envelope import Cone
from limbctl.geometry.gimbal import pan_tilt_to_direction, quat_to_pan_tilt
from limbctl.geometry.quat import direction_angle, swing_from_direction
from limbctl.teleop.approach import (
    MAX_APPROACH_SPEED_DEG_S,
    SETTLE_DEG,
    StartOptions,
    park,
    start_session,
)
from limbctl.teleop.gate import Gate
from limbctl.teleop.loop import LoopConfig, run
from limbctl.teleop.margin import START_MARGIN_DEG, inside_by_margin, outside_by
from tests.safety.support import (
    PacedSource,
    gate_limits,
    goal_log_poses,
    live_rig,
    settle_at,
    wait_for,
)

HALF_ANGLE_DEG = 40.0
RATE = 200.0
TICK_DEG = 360.0 / 4096


def cone_gate() -> Gate:
    return Gate(Cone(math.radians(HALF_ANGLE_DEG)), gate_limits(RATE))


def off_axis_deg(pan: float, tilt: float) -> float:
    d = pan_tilt_to_direction(pan, tilt)
    return math.degrees(float(direction_angle(d, np.array([1.0, 0.0, 0.0]))))


def torque(sim) -> list[bool]:
    servos = sim.truth()["servos"]
    return [servos[1]["torque_on"], servos[2]["torque_on"]]


def test_outside_waits_with_torque_off_then_starts_once_moved_inside_by_hand():
    gate = cone_gate()
    statuses = []
    lines = io.StringIO()
    with live_rig() as (sim, rig):
        settle_at(rig, math.radians(55.0), math.radians(5.0))  # torque on, outside the cone
        outcome = {}

        def starting():
            outcome["start"] = start_session(
                rig, gate, StartOptions(wait_s=30.0), stream=lines, publish=statuses.append
            )

        thread = threading.Thread(target=starting)
        thread.start()
        wait_for(lambda: len(statuses) >= 3, 10.0, "three waiting statuses")
        assert torque(sim) == [False, False]  # switched off so the hand can move it
        first = statuses[0]
        assert not first.ready and not first.inside_region and first.inside_limits
        assert 14.0 < first.outside_deg < 16.0
        assert first.move_pan_deg < -14.0  # turn it right (toward pan 0)
        sim.push(1, -15.0)  # the hand turns the pan joint right, ~15 deg/s
        thread.join(timeout=20.0)
        assert not thread.is_alive()
        sim.push(1, 0.0)
        truth_torque = torque(sim)
        present = rig.read_pose()
    result = outcome["start"]
    assert result.started and result.how == "moved by hand" and result.exit_code == 0
    assert truth_torque == [True, True]
    assert "torque switched off" in lines.getvalue()
    assert "turn it right" in lines.getvalue()
    # it started once inside by the margin, not before, and the gate started where it is
    pan, tilt = gate.safe_pose
    assert off_axis_deg(pan, tilt) <= HALF_ANGLE_DEG - 0.9 * START_MARGIN_DEG
    assert off_axis_deg(*present) <= HALF_ANGLE_DEG
    assert statuses[-1].ready and not any(s.ready for s in statuses[:-1])


def test_a_limb_left_outside_times_out_with_torque_off_and_exit_2():
    gate = cone_gate()
    lines = io.StringIO()
    with live_rig() as (sim, rig):
        settle_at(rig, math.radians(-50.0), math.radians(-10.0))
        result = start_session(rig, gate, StartOptions(wait_s=1.0), stream=lines)
        assert torque(sim) == [False, False]
    assert not result.started and result.how == "timed out" and result.exit_code == 2
    assert "--approach" in result.message and "torque is off" in result.message
    assert result.status is not None and result.status.move_pan_deg > 9.0  # turn it left
    assert gate.safe_pose is None


class WriteRecorder:
    """The real rig; it also remembers every pose written and when (an observer)."""

    def __init__(self, rig):
        self.rig = rig
        self.writes: list[tuple[float, float, float]] = []  # (monotonic s, pan, tilt)

    def __getattr__(self, name):
        return getattr(self.rig, name)

    def write_pose(self, pan, tilt):
        goal = self.rig.write_pose(pan, tilt)
        self.writes.append((time.monotonic(), pan, tilt))
        return goal


def test_approach_drives_the_limb_inside_along_a_slow_checked_path(tmp_path):
    gate = cone_gate()
    goal_log = tmp_path / "goals.jsonl"
    speed = MAX_APPROACH_SPEED_DEG_S
    with live_rig(goal_log=goal_log) as (sim, rig):
        settle_at(rig, math.radians(48.0), math.radians(12.0))
        start_offset = goal_log.stat().st_size
        limb = WriteRecorder(rig)
        result = start_session(
            limb, gate, StartOptions(wait_s=20.0, approach_deg_s=speed, rate_hz=RATE)
        )
        truth_torque = torque(sim)
    assert result.started and result.how == "approached", result.message
    assert truth_torque == [True, True]
    times = np.array([w[0] for w in limb.writes])
    poses = np.array([w[1:] for w in limb.writes])
    assert len(poses) >= 10
    directions = pan_tilt_to_direction(poses[:, 0], poses[:, 1])
    # slow: one cycle's share of the speed per goal, goals at least a cycle apart
    steps = np.degrees(direction_angle(directions[1:], directions[:-1]))
    assert steps.max() <= speed / RATE + 1e-9
    assert np.diff(times).min() >= 0.99 / RATE
    # never further outside than where it started; it ends inside by the margin
    outside = [outside_by(gate, pan, tilt) for pan, tilt in poses]
    assert max(outside) <= outside_by(gate, math.radians(48.0), math.radians(12.0)) + 1e-9
    # the session starts once the limb is within SETTLE_DEG of the target (inside by the margin)
    final = gate.safe_pose
    settled = math.radians(0.9 * (START_MARGIN_DEG - SETTLE_DEG))
    assert inside_by_margin(gate, np.array([final]), settled)[0]
    assert off_axis_deg(*final) >= HALF_ANGLE_DEG - 3 * START_MARGIN_DEG  # the nearest, not far
    # what reached the servos is exactly what was written, rounded to ticks
    written = {rig.angles_to_ticks(*rig.held_pose(pan, tilt)) for pan, tilt in poses}
    logged = goal_log_poses(goal_log, start_offset)
    assert logged and {g.ticks for g in logged} <= written


def edge_command_that_rounds_outside(gate, rig):
    """A command outside the cone whose edge pose, rounded to ticks, lies outside the region."""
    for pan_deg in np.arange(50.0, 70.0, 0.173):
        command = (math.radians(pan_deg), math.radians(0.37 * pan_deg))
        edge_q = gate.envelope.correct(swing_from_direction(pan_tilt_to_direction(*command)))
        edge = tuple(float(a) for a in quat_to_pan_tilt(edge_q))
        if not gate.is_safe(*rig.held_pose(*edge)):
            return command
    raise AssertionError("no command found whose edge pose rounds outside")


def test_a_session_ending_on_the_edge_parks_where_the_next_start_accepts(tmp_path):
    goal_log = tmp_path / "goals.jsonl"
    with live_rig(goal_log=goal_log) as (sim, rig):
        gate = cone_gate()
        command = edge_command_that_rounds_outside(gate, rig)
        line = f'{{"pan": {math.degrees(command[0])}, "tilt": {math.degrees(command[1])}}}'
        # patient with the bus: this test is about where the session ends, not about faults
        config = LoopConfig(rate_hz=RATE, max_failed_cycles=200)
        summary = run(rig, gate, PacedSource([line] * 200), config)
        assert summary.ended_by == "end of input", summary.fault
        edge = gate.safe_pose
        assert not gate.is_safe(*rig.held_pose(*edge))  # where the servos would hold it
        parked = park(rig, gate, RATE)
        assert parked.moved and 0 < parked.distance_deg <= 2.5 * START_MARGIN_DEG
        wait_for(lambda: rig.read_pose() == rig.held_pose(*parked.pose), 5.0, "the limb to settle")
        last = goal_log_poses(goal_log)[-1]
        # the next session starts at once from where the last one left the limb
        again = cone_gate()
        result = start_session(rig, again, StartOptions(wait_s=1.0))
    assert result.started and result.how == "inside"
    assert rig.angles_to_ticks(*again.safe_pose) == last.ticks
    margin = math.radians(0.9 * START_MARGIN_DEG)
    assert inside_by_margin(again, np.array([again.safe_pose]), margin)[0]
