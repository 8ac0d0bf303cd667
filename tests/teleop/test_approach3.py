"""Starting a three-servo limb from outside the region by driving in, and parking it after: on
the simulator (pan, tilt, roll) through the SDK, judged by the simulator's own goal log."""

from __future__ import annotations

import json
import math
import threading

import numpy as np

from limbctl.geometry.gimbal import pose_quat_scalar
from limbctl.servo.setup import configure_servos
from limbctl.session import open_rig
from limbctl.teleop.approach import MAX_APPROACH_SPEED_DEG_S, SETTLE_DEG, StartOptions
from limbctl.teleop.approach3 import (
    assess3,
    nearest_start_pose3,
    outside_by3,
    park3,
    safe_with_margin,
)
from limbctl.teleop.gate3 import Gate3, GateLimits3, geodesic
from limbctl.teleop.loop import LoopConfig, run
from limbctl.teleop.margin import START_MARGIN_DEG
from limbctl.teleop.start3 import start_three
from tests.safety.support import PacedSource, wait_for
from tests.teleop.test_gate3 import ConeBand

RATE = 200.0
MARGIN = math.radians(START_MARGIN_DEG)
#: The true region of these tests: the limb within 40 deg of +x, its twist within 30 deg of 0.
REGION = ConeBand(math.radians(40), 0.0, math.radians(30))


def gate_for(profile) -> Gate3:
    limits = GateLimits3(
        profile.pan.min_rad, profile.pan.max_rad, profile.tilt.min_rad,
        profile.tilt.max_rad, profile.roll.min_rad, profile.roll.max_rad,
        max_step=math.radians(120) / RATE, max_joint_step=math.radians(1.8),
    )  # fmt: skip
    return Gate3(REGION, limits)


def settle_at3(rig, pose, timeout_s=20.0):
    """Drive the limb (no gate: test set-up only) to ``pose`` (rad) and wait until it is there."""
    rig.write_pose(*pose)
    tol = math.radians(0.5)
    wait_for(
        lambda: all(abs(a - b) < tol for a, b in zip(rig.read_pose(), pose, strict=True)),
        timeout_s,
        f"the limb to reach {pose}",
    )


def goal_orientations(log, start_offset=0):
    """The full orientations (N, 4) the simulator's goal log says were commanded, in order."""
    by_time = {}
    with open(log, "rb") as fh:
        fh.seek(start_offset)
        for raw in fh:
            row = json.loads(raw)
            by_time[row["t"]] = row["limb_q"]
    return np.array(list(by_time.values()))


def test_nearest_start_pose_is_inside_by_the_margin_and_near():
    gate = Gate3(REGION, GateLimits3(-2, 2, -1, 1, -2.5, 2.5, 0.01, 0.03))
    exact = lambda pose: pose  # noqa: E731 - no tick rounding: the search's own geometry
    # outside in twist only (roll 45 deg at rest: twist 45 against the band's 30)
    twisted = (0.0, 0.0, math.radians(45))
    found = nearest_start_pose3(gate, twisted, exact)
    assert found is not None and safe_with_margin(gate, found, MARGIN)
    q, f = pose_quat_scalar(*twisted), pose_quat_scalar(*found)
    # the nearest region orientation is 15 deg away; the start pose a margin or two further
    assert 15.0 < math.degrees(geodesic(q, f)) <= 15.0 + 3 * START_MARGIN_DEG
    # outside in swing and twist: pan 55 deg, roll -50 deg
    both = (math.radians(55), 0.0, math.radians(-50))
    found = nearest_start_pose3(gate, both, exact)
    assert found is not None and safe_with_margin(gate, found, MARGIN)
    gap = geodesic(pose_quat_scalar(*both), REGION.correct(pose_quat_scalar(*both)))
    assert geodesic(pose_quat_scalar(*both), pose_quat_scalar(*found)) <= gap + 6 * MARGIN
    # already inside by the margin: the pose itself
    inside = (0.1, 0.05, 0.1)
    assert nearest_start_pose3(gate, inside, exact) == inside


def test_approach_drives_a_three_servo_limb_inside_along_a_slow_checked_path(tmp_path):
    log = tmp_path / "goals.jsonl"
    speed = MAX_APPROACH_SPEED_DEG_S
    outside = (math.radians(50), math.radians(10), math.radians(-45))  # swing and twist out
    with open_rig(rig_path="sim3", goal_log=log) as session:
        rig, profile = session.rig, session.profile
        configure_servos(rig.bus, rig.tick_limits())
        rig.set_torque(True)
        settle_at3(rig, outside)
        rig.set_torque(False)
        gate = gate_for(profile)
        start_offset = log.stat().st_size
        result = start_three(
            rig, gate, StartOptions(wait_s=20.0, approach_deg_s=speed, rate_hz=RATE)
        )
        present = rig.read_pose()
        torque = rig.torque_enabled()
    assert result.started and result.how == "approached", result.message
    assert torque == (True, True, True)
    goals = goal_orientations(log, start_offset)
    assert len(goals) >= 10
    steps = [math.degrees(geodesic(a, b)) for a, b in zip(goals[:-1], goals[1:], strict=True)]
    # slow: one cycle's share of the speed per goal, give or take both goals' rounding to ticks
    # (sqrt(5) half ticks each: gate3.written_tolerance_deg3 without the gate's own tolerance)
    rounding = math.sqrt(5) * 360.0 / 4096 / 2
    assert max(steps) <= speed / RATE + 2 * rounding
    assert np.mean(steps) <= speed / RATE + 0.01
    # never further outside than where it started, and it ends inside by the margin
    start_out = outside_by3(gate, rig.held_pose(*outside))
    assert max(geodesic(q, REGION.correct(q)) for q in goals) <= start_out + math.radians(0.11)
    settled = math.radians(0.9 * (START_MARGIN_DEG - SETTLE_DEG))
    assert safe_with_margin(gate, present, settled)


def test_a_three_servo_session_ending_on_the_twist_stop_parks_where_the_next_start_accepts(
    tmp_path,
):
    log = tmp_path / "goals.jsonl"
    with open_rig(rig_path="sim3", goal_log=log) as session:
        rig, profile = session.rig, session.profile
        configure_servos(rig.bus, rig.tick_limits())
        rig.set_torque(True)
        gate = gate_for(profile)
        gate.start(*rig.read_pose())
        # a command twisted far past the band's stop: the session ends on the stop
        line = json.dumps({"pan": 10.0, "tilt": 5.0, "roll": 80.0})
        config = LoopConfig(rate_hz=RATE, max_failed_cycles=200)
        source = PacedSource([line] * 200)
        source.twist = True  # a rig with roll: the lines keep their twist
        summary = run(rig, gate, source, config)
        assert summary.ended_by == "end of input", summary.fault
        edge = gate.safe_pose
        assert not safe_with_margin(gate, rig.held_pose(*edge), MARGIN)
        parked = park3(rig, gate, RATE)
        assert parked.moved and 0 < parked.distance_deg <= 3 * START_MARGIN_DEG, parked
        wait_for(lambda: rig.read_pose() == rig.held_pose(*parked.pose), 5.0, "the limb to settle")
        again = gate_for(profile)
        rig.set_torque(False)
        result = start_three(rig, again, StartOptions(wait_s=1.0), stop=threading.Event())
        final = rig.read_pose()
    assert result.started and result.how == "inside", result.message
    assert safe_with_margin(again, final, math.radians(0.9 * START_MARGIN_DEG))


def test_the_status_of_a_waiting_limb_says_how_far_and_which_way():
    gate = Gate3(REGION, GateLimits3(-2, 2, -1, 1, -2.5, 2.5, 0.01, 0.03))
    exact = lambda pose: pose  # noqa: E731
    twisted = assess3(gate, (0.0, 0.0, math.radians(45)), exact, waited_s=2.0)
    assert not twisted.ready and twisted.inside_limits
    assert abs(twisted.outside_deg - 15.0) < 1e-6
    assert 15.0 < twisted.distance_deg <= 15.0 + 3 * START_MARGIN_DEG
    # the way in is a roll back toward the band, about -15 deg
    assert twisted.target is not None and -16.5 < twisted.target[2] - 45.0 < -15.0
    line = twisted.line()
    assert "roll +45.0 deg (15.0 deg outside the taught region)" in line, line
    assert "move the limb 15." in line and "deg about its axis" in line, line
    inside = assess3(gate, (0.1, 0.05, 0.1), exact)
    assert inside.ready and inside.distance_deg == 0.0
    assert inside.line().endswith("(ready): inside the taught region: starting")
    beyond = assess3(gate, (0.0, 1.2, 0.0), exact)  # tilt past its 1 rad hard limit
    assert not beyond.inside_limits and "beyond the rig's hard limits" in beyond.line()


def test_a_waiting_three_servo_start_prints_and_publishes_its_status(tmp_path):
    import io

    outside = (math.radians(50), math.radians(10), math.radians(-45))
    published = []
    stream = io.StringIO()
    with open_rig(rig_path="sim3") as session:
        rig, profile = session.rig, session.profile
        configure_servos(rig.bus, rig.tick_limits())
        rig.set_torque(True)
        settle_at3(rig, outside)
        rig.set_torque(False)
        result = start_three(
            rig, gate_for(profile), StartOptions(wait_s=0.5, poll_hz=20.0), stream=stream,
            publish=published.append,
        )  # fmt: skip
    assert not result.started and result.how == "timed out" and result.exit_code == 2
    assert len(published) >= 5 and all(not s.ready for s in published)
    last = published[-1]
    assert abs(last.pan_deg - 50.0) < 0.5 and abs(last.roll_deg + 45.0) < 0.5  # as settled
    assert last.outside_deg > 10.0 and last.target is not None
    text = stream.getvalue()
    # to a log (not a terminal) one line every LOG_EVERY_S s: the first, here
    status_lines = [ln for ln in text.splitlines() if ln.startswith("waiting ")]
    assert len(status_lines) == 1 and last.advice().split(":")[0] in text, text
