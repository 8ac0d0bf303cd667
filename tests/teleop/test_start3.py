"""A whole three-servo session on the simulator: start (waiting), the loop with Gate3 at 200 Hz on
a stream that sweeps far outside in swing and twist, judged by the simulator's own goal log."""

from __future__ import annotations

import json
import math
import threading

import numpy as np

from limbctl.geometry.gimbal import pose_quat_scalar
from limbctl.servo.setup import configure_servos
from limbctl.session import open_rig
from limbctl.teleop.approach import StartOptions
from limbctl.teleop.gate3 import Gate3, GateLimits3, geodesic, written_tolerance_deg3
from limbctl.teleop.loop import LoopConfig
from limbctl.teleop.sources import SourceContext, parse_source
from limbctl.teleop.start3 import run_session_three, safe_with_margin
from tests.teleop.test_gate3 import ConeBand


def sweep_lines(n=500):
    t = np.arange(n) / n
    pan = 90 * np.sin(2 * math.pi * t)
    tilt = 10 + 50 * np.sin(4 * math.pi * t + 0.5)
    roll = 150 * np.sin(2 * math.pi * t + 1.0)
    return "".join(
        json.dumps({"pan": p, "tilt": q, "roll": r}) + "\n"
        for p, q, r in zip(pan, tilt, roll, strict=True)
    )


def test_session_on_three_servos_keeps_every_goal_in_the_region(tmp_path):
    region = ConeBand(math.radians(40), 0.0, math.radians(30))
    log = tmp_path / "goals.jsonl"
    lines = sweep_lines()
    with open_rig(rig_path="sim3", goal_log=log) as session:
        rig, profile = session.rig, session.profile
        limits = GateLimits3(
            profile.pan.min_rad, profile.pan.max_rad, profile.tilt.min_rad,
            profile.tilt.max_rad, profile.roll.min_rad, profile.roll.max_rad,
            max_step=math.radians(120) / 200, max_joint_step=math.radians(1.8),
        )  # fmt: skip
        gate = Gate3(region, limits)
        configure_servos(rig.bus, rig.tick_limits())
        stream = tmp_path / "commands.jsonl"
        stream.write_text(lines)
        opened = []

        def open_source():
            source = parse_source(f"replay:{stream}").open(SourceContext(rig=rig))
            assert source.twist  # a rig with roll: the lines keep their twist
            opened.append(source)
            return source

        result = run_session_three(
            rig, gate, open_source, LoopConfig(rate_hz=200.0), StartOptions(wait_s=5.0),
            stop=threading.Event(),
        )  # fmt: skip
        assert len(opened) == 1 and opened[0].finished
    assert result.start.started and result.start.how == "inside"
    assert result.summary.exit_code == 0, result.lines()
    assert result.summary.goals_written > 300
    by_time = {}
    for line in log.read_text().splitlines():
        row = json.loads(line)
        by_time[row["t"]] = row["limb_q"]
    tolerance = math.radians(written_tolerance_deg3())
    outside = 0
    for q in by_time.values():
        q = np.asarray(q)
        if not region.contains(q):
            assert geodesic(q, region.correct(q)) <= tolerance
            outside += 1
    twists = [math.degrees(float(np.arctan2(q[1], q[0]) * 2)) for q in by_time.values()]
    # the stream asked for roll +-150: the gate turned the twist out toward the band's +-30 deg
    assert max(twists) > 20 and min(twists) < -20
    assert max(abs(v) for v in twists) <= 30.0 + written_tolerance_deg3()


def test_safe_with_margin_needs_room_on_every_joint():
    region = ConeBand(math.radians(40), 0.0, math.radians(30))
    gate = Gate3(region, GateLimits3(-2, 2, -1, 1, -1.7, 1.7, 0.01, 0.03))
    margin = math.radians(0.35)
    assert safe_with_margin(gate, (0.0, 0.0, 0.0), margin)
    edge = (0.0, 0.0, math.radians(29.9))  # twist 29.9: 0.35 deg more roll leaves the band
    assert gate.is_safe(*edge) and not safe_with_margin(gate, edge, margin)
    assert pose_quat_scalar(*edge)[0] > 0
