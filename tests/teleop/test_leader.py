"""A leader gimbal on the same bus is mirrored through the gate.

The simulator models only one gimbal; ids 3 and 4 are free shafts. The test plays the person
who moved the leader by driving its pan shaft to 60 degrees first (torque on, a goal, wait until
it is there); the leader source then switches the leader's torque off and mirrors it.
"""

import math
import threading
import time

import pytest

from calib.profile import default_sim_profile
from limbctl.envelope import Cone
from limbctl.errors import ConfigError
from limbctl.jobs import gate_for
from limbctl.servo.control_table import Register
from limbctl.servo.setup import configure_servos
from limbctl.session import open_rig
from limbctl.teleop.loop import LoopConfig, run
from limbctl.teleop.sources import LeaderSource


def test_follower_mirrors_a_pushed_leader_within_the_region(tmp_path):
    model = tmp_path / "cone.npz"
    sim = default_sim_profile()
    Cone(half_angle_deg=30.0).save(
        model, metadata={"rig": sim.name, "calibration": sim.calibration.to_dict()}
    )
    gate = gate_for(model, default_sim_profile(), 200.0, 120.0)
    with open_rig(extra_ids=(3, 4)) as session:
        rig = session.rig
        limits = rig.tick_limits()
        limits.update({3: (0, 4095), 4: (0, 4095)})
        configure_servos(rig.bus, limits)
        pan_joint = rig.profile.pan
        target = pan_joint.zero_tick + pan_joint.direction * round(60 * 4096 / 360)
        tilt_target = rig.profile.tilt.zero_tick
        rig.bus.set_torque(True, (3, 4))
        rig.bus.sync_write(Register.GOAL_POSITION, {3: target, 4: tilt_target})
        deadline = time.monotonic() + 20
        while abs(rig.bus.sync_read(Register.PRESENT_POSITION, (3,))[3] - target) > 2:
            assert time.monotonic() < deadline, "the leader shaft did not reach its goal"
        source = LeaderSource(rig, (3, 4))
        stop = threading.Event()
        out = {}
        with source:
            assert rig.bus.torque_enabled()[3] is False
            rig.set_torque(True)
            thread = threading.Thread(
                target=lambda: out.update(s=run(rig, gate, source, LoopConfig(), stop=stop))
            )
            thread.start()
            thread.join(timeout=3.0)  # the loop runs; the join times out by design
            stop.set()
            thread.join(timeout=10)
        pan, tilt = rig.read_pose()
    summary = out["s"]
    assert summary.exit_code == 0 and summary.commands > 100
    assert summary.goals_written > 100
    # the follower turned toward the leader (pan 60) and stopped at the cone's edge
    angle = math.degrees(math.acos(math.cos(pan) * math.cos(tilt)))
    assert pan > 0 and 29.0 < angle <= 30.2


def test_leader_ids_must_be_on_the_bus_and_distinct():
    with open_rig() as session:
        with pytest.raises(ConfigError, match="not on the bus"):
            LeaderSource(session.rig, (3, 4))
        with pytest.raises(ConfigError):
            LeaderSource(session.rig, (1, 2))
