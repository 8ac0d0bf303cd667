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
        seen = {"written": 0, "angle": 0.0}
        changed = threading.Condition()

        def observe(cycle) -> None:  # wait on what the assertions need, however slow the loop
            with changed:
                seen["written"] += cycle.written
                if cycle.present is not None:
                    pan, tilt = cycle.present
                    seen["angle"] = math.degrees(math.acos(math.cos(pan) * math.cos(tilt)))
                changed.notify_all()

        def at_the_edge() -> bool:
            return seen["written"] > 100 and seen["angle"] > 29.0

        with source:
            assert rig.bus.torque_enabled()[3] is False
            rig.set_torque(True)
            thread = threading.Thread(
                target=lambda: out.update(
                    s=run(rig, gate, source, LoopConfig(on_cycle=observe), stop=stop)
                )
            )
            thread.start()
            with changed:  # 100 goals written and the follower at the cone's edge
                changed.wait_for(lambda: at_the_edge() or not thread.is_alive(), timeout=60.0)
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


def test_a_three_servo_leader_gives_full_orientations_and_needs_a_three_servo_follower():
    import numpy as np

    from limbctl.geometry.gimbal import pose_quat_scalar

    with open_rig(extra_ids=(3, 4)) as session:
        refused = "needs a 3-servo follower: rig 'sim' has 2 servos; give leader:ID,ID"
        with pytest.raises(ConfigError, match=refused):
            LeaderSource(session.rig, (3, 4, 5))
    with open_rig(rig_path="sim3", extra_ids=(4, 5, 6)) as session:
        rig = session.rig
        configure_servos(rig.bus, {**rig.tick_limits(), 4: (0, 4095), 5: (0, 4095), 6: (0, 4095)})
        # play the person: put the leader's shafts at pan 20, tilt 10, roll -30 deg
        goals = {
            i: joint.zero_tick + joint.direction * round(deg * 4096 / 360)
            for i, joint, deg in zip((4, 5, 6), rig.joints, (20, 10, -30), strict=True)
        }
        rig.bus.set_torque(True, (4, 5, 6))
        rig.bus.sync_write(Register.GOAL_POSITION, goals)
        deadline = time.monotonic() + 20
        while any(
            abs(rig.bus.sync_read(Register.PRESENT_POSITION, (i,))[i] - goals[i]) > 2 for i in goals
        ):
            assert time.monotonic() < deadline, "the leader shafts did not reach their goals"
        with LeaderSource(rig, (4, 5, 6)) as source:
            ticks = rig.bus.sync_read(Register.PRESENT_POSITION, (4, 5, 6))
            [command] = source.poll()
    expected = pose_quat_scalar(*rig.ticks_to_angles(*(ticks[i] for i in (4, 5, 6))))
    np.testing.assert_allclose(command.q, expected, atol=1e-12)
    # the shafts were waited for within 2 ticks of goals rounded from the angles: 2.33 ticks
    assert math.degrees(rig.ticks_to_angles(*(ticks[i] for i in (4, 5, 6)))[2]) == pytest.approx(
        -30.0, abs=2.34 * 360 / 4096
    )
