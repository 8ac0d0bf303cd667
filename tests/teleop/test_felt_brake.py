"""The snap watch's brake rules over the real SDK and the simulator's pty: the watch's one read
carries the leader's torque and speed, and a hand pulling a held leader back inside is let go
by the watch before the servo's loop brakes it (limbctl/teleop/brake.py)."""

from __future__ import annotations

import time

import pytest

from limbctl.servo.control_table import Register
from limbctl.teleop.haptic import VELOCITY_UNIT_DEG_S
from limbctl.teleop.sources.leader_snap import read_motion
from tests.teleop.test_felt_leader import (
    EDGE,
    HAND,
    IDS,
    PRESS,
    Running,
    felt_session,
    press_against_pan_zero,
    truth_rows,
)


def test_the_watchs_one_read_carries_the_leaders_torque_and_speed(tmp_path):
    # Present Current (126) and Present Velocity (128) side by side: one sync read of both. A
    # hand presses the leader outward against a motor of 40 units whose goal is pan 0
    with felt_session(tmp_path) as (session, source, log), source:
        bus, units = session.rig.bus, press_against_pan_zero(session, source)
        deadline, motion = time.monotonic() + 5.0, None
        while time.monotonic() < deadline:
            motion = read_motion(bus, IDS, session.rig.joints, source.motor)
            if motion is not None and abs(motion[1][0]) == source.motor.torque_of(units):
                break
        assert motion is not None
        speeds, torques = motion
        # toward pan 0 (pan decreasing) in the joint's frame, at the Goal Current's clip
        assert torques[0] == pytest.approx(-source.motor.torque_of(units))
        assert torques[1] == 0.0  # the tilt servo has no current
        plain = bus.read(Register.PRESENT_VELOCITY, IDS[0])
        unit = VELOCITY_UNIT_DEG_S  # the reads a millisecond apart: within a few units
        assert abs(speeds[0] * session.rig.joints[0].direction - plain * unit) <= 3 * unit


def test_a_hand_pulling_a_held_leader_back_inside_is_let_go_before_it_is_braked(tmp_path):
    # pressed and held 20 deg beyond, then the hand heads back inside (pan 50 -> 0 in 0.2 s),
    # faster than the wall's setpoint walks: the watch frees the wall as the leader gains on
    # it (or the snap rule as the hand's push fades). Never any torque inside
    with felt_session(tmp_path) as (session, source, log), source:
        session.rig.set_torque(True)
        with Running(session, source) as running:
            pull = [[0.0, EDGE + 20.0, 0.0], [0.2, 0.0, 0.0]]  # from the switch on
            now = running.held_then(PRESS, {"script": pull, **HAND})
    if now is None:
        return  # the feel went off for a lost pace (its outcome asserted)
    after = [r for r in truth_rows(log) if r["t"] >= now]
    assert after and min(r["pose_deg"][0] for r in after) < EDGE  # the hand took it inside
    assert all(r["motor_nm"] == [0.0, 0.0] for r in after if r["pose_deg"][0] < EDGE)
    assert source.snap.brakes + source.snap.cuts >= 1  # the watch let the wall go
    # outside, pulling outward: about a cycle and its write (the cycle's own read of the
    # motor's torque is the backstop when the watch's reads, 1-3 ms apart over the pty, miss
    # it), and small beside the 0.28 N m the loop pulls a dragged leader with
    outward = [r for r in after if r["pose_deg"][0] > EDGE and r["motor_nm"][0] > 0.0]
    assert not outward or outward[-1]["t"] - outward[0]["t"] <= 0.012  # two cycles at most
    assert max((r["motor_nm"][0] for r in outward), default=0.0) < 0.25 * source.law.cap_nm
