"""The teleop loop end to end: real loop, real SDK, the simulator's own goal log as the judge."""

from __future__ import annotations

import json
import math
import os
import threading

import numpy as np

from calib.profile import default_sim_profile
from limbctl.demo import goal_log_excursions
from limbctl.envelope import load_model
from limbctl.geometry.gimbal import pan_tilt_to_direction
from limbctl.geometry.quat import direction_angle
from limbctl.jobs import gate_for
from limbctl.teleop.cycle import CycleState
from limbctl.teleop.gate import Outcome
from limbctl.teleop.loop import ControlLoop, LoopConfig, Telemetry, run
from limbctl.teleop.sources import ReplaySource, StreamSource
from tests.safety.support import packet_directions
from tests.teleop.chains import live_chain

RATE = 200.0
MAX_SPEED = 120.0
STEP_DEG = MAX_SPEED / RATE
HALF_TICK_DEG = 360.0 / 4096 / 2


def write_lines(path, rows):
    path.write_text("".join((r if isinstance(r, str) else json.dumps(r)) + "\n" for r in rows))
    return path


def test_stream_leaving_the_region_is_gated_and_bad_lines_refused(tmp_path, cone_model):
    """Every packet inside the cone, slew-limited; bad lines refused; the observer and the
    telemetry see each cycle alike."""
    rows = [{"pan": 5.0, "tilt": 3.0}] * 60  # well inside: must pass unchanged
    rows += ['{"pan": NaN, "tilt": 0}', "garbage", '{"pan": 10}', '{"dir": [0, 0, 0]}']
    # a sweep far outside the 40-degree cone, on both sides
    rows += [{"pan": p, "tilt": 0.5 * p} for p in np.linspace(0, 110, 80)]
    rows += [{"pan": p, "tilt": -0.3 * p} for p in np.linspace(110, -110, 120)]
    rows += [{"pan": 12.0, "tilt": -4.0}] * 150  # back inside
    goal_log, telemetry_path = tmp_path / "goals.jsonl", tmp_path / "telemetry.jsonl"
    seen = []
    config = LoopConfig(rate_hz=RATE, on_cycle=seen.append)
    gate = gate_for(cone_model, default_sim_profile(), RATE, MAX_SPEED)
    with (
        live_chain("sim", goal_log) as session,
        open(telemetry_path, "w") as fh,
        ReplaySource(write_lines(tmp_path / "cmds.jsonl", rows)) as source,
    ):
        summary = run(session.rig, gate, source, config, telemetry=Telemetry(fh))

    assert summary.exit_code == 0 and summary.ended_by == "end of input"
    assert summary.rejected == 4
    assert summary.commands == len(rows) - 4
    # the simulator's log: every pose a packet commanded is inside the cone (up to half a tick)
    model = load_model(cone_model)
    excursion = goal_log_excursions(goal_log, model)
    assert len(excursion) > 100
    assert excursion.max() <= 2 * HALF_TICK_DEG
    poses = packet_directions(goal_log)
    angles = np.degrees(direction_angle(poses, np.array([1.0, 0.0, 0.0])))
    assert angles.max() <= 40.0 + 2 * HALF_TICK_DEG
    assert angles.max() >= 39.0  # it did slide along the edge, not stop short
    # slew limit between consecutive packets (plus rounding of both to ticks)
    steps = np.degrees(direction_angle(poses[1:], poses[:-1]))
    assert steps.max() <= STEP_DEG + 4 * HALF_TICK_DEG
    # the last command is well inside: written unchanged (to the tick)
    final = pan_tilt_to_direction(math.radians(12.0), math.radians(-4.0))
    assert np.degrees(direction_angle(poses[-1], final)) <= 2 * HALF_TICK_DEG
    logged = [json.loads(x) for x in telemetry_path.read_text().splitlines()]
    assert any(r["outcome"] == "corrected" for r in logged)
    assert any(r["outcome"] == "passed" for r in logged)
    start, cycles = seen[0], seen[1:]
    # the start value: the pose read before the first cycle, nothing gated yet
    assert start.state is CycleState.RUNNING and not start.complete and start.present
    assert all(c.complete for c in cycles) and len(cycles) == summary.cycles
    assert [c.index for c in cycles] == list(range(summary.cycles))
    assert all(c.state is CycleState.RUNNING for c in cycles[:-1])
    assert cycles[-1].state is CycleState.FINISHED and cycles[-1].ended_by == "end of input"
    assert sum(c.written for c in cycles) == summary.goals_written
    assert all(c.result.outcome is not Outcome.HELD for c in cycles if c.written)
    assert any(c.result.outcome is Outcome.CORRECTED for c in cycles)
    assert all(0.0 <= c.timings.gate_s <= c.timings.cycle_s for c in cycles)
    # telemetry is written from the same values, one line per complete cycle
    assert len(logged) == len(cycles)
    assert [r["written"] for r in logged] == [c.written for c in cycles]
    assert [r["t"] for r in logged] == [round(c.t, 6) for c in cycles]


def test_a_set_stop_ends_the_next_cycle_before_any_bus_transfer(cone_model):
    gate = gate_for(cone_model, default_sim_profile(), RATE, MAX_SPEED)
    stop = threading.Event()
    read_end, write_end = os.pipe()  # a source that stays open and silent
    with (
        live_chain("sim") as session,  # a held limb: torque off would be a fault
        os.fdopen(read_end, "rb", buffering=0) as reader,
        StreamSource(reader) as source,
    ):
        loop = ControlLoop(session.rig, gate, source, LoopConfig(), stop=stop)
        assert loop.start().state is CycleState.RUNNING
        running = loop.step()
        stop.set()
        stopped = loop.step()
    assert running.state is CycleState.RUNNING and running.complete
    assert running.result.outcome is Outcome.HELD  # no command yet: nothing written
    assert not running.written
    assert stopped.state is CycleState.FINISHED and stopped.ended_by == "stopped"
    assert not stopped.complete and stopped.result is None
    os.close(write_end)
    assert loop.finish().cycles == 1
