"""The three-servo leader's wall: zero inside, toward the correction on SO(3), never above the cap.

The region is a twist region fitted from a synthetic teaching (tests/teleop/twist_square.py):
its edge lies near pan 30 deg in swing and near roll 30 deg in twist. The law runs against the
simulator's three-servo leader on a stepped clock at exactly 200 Hz (the controller's part in
this process, as tests/teleop/test_haptic.py does for two).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calib.profile import default_sim_profile
from firmware_sim.control_table import Register as SimRegister
from firmware_sim.leader3 import Operator3, leader_joints3
from firmware_sim.simulator import Simulator
from limbctl.geometry.chains import geodesic
from limbctl.geometry.gimbal3 import pose_quat_scalar
from limbctl.servo.control_table import ModelNumber
from limbctl.servo.leader import FEEL_DATA, FEEL_MAP, FELT_MODELS, encode_feel, feel_map
from limbctl.servo.rig3 import RollRig
from limbctl.servo.ticks import angle_to_ticks
from limbctl.teleop.haptic import TICK_DEG, FeelLaw
from limbctl.teleop.haptic3 import Push3, beyond3_deg, corrected_pose, held3, push3_for
from tests.teleop.stepped_leader import SteppedWatch, motor_of, read_torque, read_velocity
from tests.teleop.twist_square import square_region

LAW = FeelLaw()
MOTOR = FELT_MODELS[ModelNumber.XM430_W350]
CAP = MOTOR.torque_of(MOTOR.units_for(LAW.cap_nm))
RIG = RollRig(default_sim_profile("sim3"))
IDS = (4, 5, 6)
HAND = {"damping_nm_s_rad": 0.02, "max_torque_nm": 0.3}


@pytest.fixture(scope="module")
def region():
    return square_region()


def q_of(pan_deg, tilt_deg, roll_deg):
    return pose_quat_scalar(*np.radians((pan_deg, tilt_deg, roll_deg)))


def test_the_simulated_three_servo_leader_is_built_like_the_follower():
    pan, tilt, roll = leader_joints3(IDS)
    assert [j.servo_id for j in (pan, tilt, roll)] == list(IDS)
    assert (roll.zero_tick, roll.direction) == (RIG.joints[2].zero_tick, RIG.joints[2].direction)
    hand = Operator3([[0.0, 0.0, 0.0, 0.0], [2.0, 20.0, -10.0, 40.0]])
    assert hand.target_deg(1.0) == pytest.approx((10.0, -5.0, 20.0))
    assert hand.torque(1.0, 2, 0.0, 0.0) == pytest.approx(0.3)  # 20 deg x 0.05, bounded at 0.3
    with pytest.raises(ValueError, match="roll_deg"):
        Operator3([[0.0, 0.0, 0.0]])
    with pytest.raises(ValueError, match="must not decrease"):
        Operator3([[1.0, 0.0, 0.0, 0.0], [0.5, 0.0, 0.0, 0.0]])


def test_distance_is_the_rotation_to_the_correction_and_the_push_leads_toward_it(region):
    q = q_of(0.0, 0.0, 45.0)
    corrected = region.correct(q)
    distance = beyond3_deg(q, corrected)
    assert distance == pytest.approx(math.degrees(geodesic(q, corrected)))
    assert 10.0 < distance < 20.0  # the band's edge near 30 deg of roll
    present = tuple(np.radians((0.0, 0.0, 45.0)))
    push = push3_for(LAW, MOTOR, present, q, corrected, RIG.roll_limits)
    # the cap shared along the step (mostly roll): what the hand feels is at most the cap
    assert push.goal_current == push.joint_currents[2] >= MOTOR.units_for(LAW.cap_nm) - 2
    felt = math.sqrt(sum(MOTOR.torque_of(c) ** 2 for c in push.joint_currents))
    assert push.torque_nm == pytest.approx(felt) and felt <= CAP
    # 10-20 deg beyond, deeper than a hand within the cap holds it: three ticks, not two, from
    # the leader in joint space
    lead = math.degrees(float(np.linalg.norm(np.subtract(push.goal, present))))
    assert lead == pytest.approx(3 * TICK_DEG, abs=1e-9)
    inside = push3_for(LAW, MOTOR, (0.1, 0.0, 0.2), q_of(5.7, 0, 11.5), q_of(5.7, 0, 11.5), (-1, 1))
    assert (inside.goal_current, inside.profile_velocity, inside.torque_nm) == (0, 0, 0.0)
    assert inside.goal == (0.1, 0.0, 0.2)  # free: the goal rides with the leader
    assert held3((0.1, 0.2, 0.3)) == Push3(0, 0, 0.1, 0.2, 0.0, 0.0, goal_roll=0.3)


def test_the_corrected_roll_is_unwrapped_against_the_present_roll_within_the_limits():
    # roll 190 deg is roll -170: within limits of (-200, 200) deg the one nearer the leader's
    q = q_of(0.0, 0.0, 190.0)
    limits = (math.radians(-200.0), math.radians(200.0))
    assert math.degrees(corrected_pose(q, (0.0, 0.0, math.radians(170.0)), limits)[2]) == (
        pytest.approx(190.0)
    )
    assert math.degrees(corrected_pose(q, (0.0, 0.0, math.radians(-150.0)), limits)[2]) == (
        pytest.approx(-170.0)
    )


angles = st.floats(-60.0, 60.0, allow_nan=False)


@settings(max_examples=150, deadline=None)
@given(
    angles, st.floats(-45.0, 45.0), st.floats(-100.0, 100.0), st.tuples(*[st.floats(-1.0, 1.0)] * 3)
)
def test_property_never_above_the_cap_zero_inside_toward_the_correction(
    region, pan, tilt, roll, lag
):
    q = q_of(pan, tilt, roll)
    corrected = region.correct(q)
    present = tuple(math.radians(a + d) for a, d in zip((pan, tilt, roll), lag, strict=True))
    push = push3_for(LAW, MOTOR, present, q, corrected, RIG.roll_limits)
    assert 0 <= push.goal_current <= MOTOR.units_for(LAW.cap_nm)
    assert push.torque_nm <= LAW.cap_nm
    if bool(region.contains(q)):
        assert push.goal_current == 0
    if push.goal_current:
        step = np.subtract(push.goal, present)
        lead = LAW.lead_for_deg(push.distance_deg, MOTOR)
        assert np.max(np.abs(step)) <= math.radians(lead) + 1e-12
        target = np.subtract(corrected_pose(corrected, present, RIG.roll_limits), present)
        assert float(step @ target) >= 0.0


@settings(max_examples=150, deadline=None)
@given(st.floats(35.0, 60.0), st.floats(-2.0, 2.0), st.floats(0.001, 0.05), st.booleans())
def test_property_a_leader_outrunning_its_setpoints_or_still_moving_in_is_free_else_led(
    region, roll, moved, period, engaged
):
    # beyond the twist edge in roll alone: the correction lies at a smaller roll, so a roll
    # that decreased by ``moved`` moved toward it (the joint-space line is roll's own)
    q = q_of(0.0, 0.0, roll)
    corrected = region.correct(q)
    present = tuple(np.radians((0.0, 0.0, roll)))
    previous = tuple(np.radians((0.0, 0.0, roll + moved)))
    push = push3_for(LAW, MOTOR, present, q, corrected, RIG.roll_limits, previous, period, engaged)
    wall = push3_for(LAW, MOTOR, present, q, corrected, RIG.roll_limits)
    way = np.subtract(corrected_pose(corrected, present, RIG.roll_limits), present)
    moved_in = math.degrees(float(np.subtract(present, previous) @ way) / np.linalg.norm(way))
    outrun = moved_in > LAW.return_speed_deg_s * period + LAW.outrun_slack_deg
    near = wall.distance_deg - moved_in <= LAW.deadband_deg
    low = wall.distance_deg - LAW.deadband_deg <= LAW.rearm_band_deg  # comes on only past it
    if outrun or near or (not engaged and (moved_in > 0.0 or low)):
        assert (push.goal_current, push.goal) == (0, present)
    else:  # the wall's current and goal, at most LEAD ahead (decisions/haptic.md, round 4)
        assert push.goal_current == wall.goal_current and push.goal == wall.goal
        lead = math.radians(LAW.lead_for_deg(wall.distance_deg, MOTOR))
        assert np.max(np.abs(np.subtract(push.goal, present))) <= lead + 1e-12


# -- the law against the simulated three-servo leader, at exactly 200 Hz -------------------------


def felt3_at_200_hz(
    region,
    script,
    seconds,
    let_go_s=None,
    cycles=None,
    stiffness=0.05,
    rules=True,
    model="xm430-w350",
    snap_watch=True,
    max_torque_nm=HAND["max_torque_nm"],
):
    """The controller's part on the simulated leader's registers every 5 ms of a stepped clock:
    read Present Position, push3_for, the bytes to Indirect Data 1 ms later (Torque Enable off
    and on when the wall comes on, as LeaderSource3._write). Returns (1 ms truth rows, each
    cycle's (pose, push)). ``cycles`` maps a cycle's index to "held" (a held gate's push:
    Goal Current 0) or "silent" (a failed leader read: Goal Current 0 alone). ``rules``: pass the
    previous read, the period and whether the wall pushed (as LeaderSource3.feel); False is the
    law without its let-go rules (as before round 3 on three servos). ``model``: the leader
    servos' simulator model (a 330 named with firmware 53 or later). ``snap_watch``: with the
    snap watch between the cycles and its speed rules at each read (with ``rules``).
    ``max_torque_nm``: the hand's bound (N m, the magnitude of its push)."""
    motor = motor_of(model)
    clock = [0.0]
    leader = {"ids": list(IDS), "model": model}
    sim = Simulator(ids=(1, 2, 3), roll_id=3, leader=leader, clock=lambda: clock[0])
    servos = [sim.servo(i) for i in IDS]
    for servo in servos:
        servo.write(11, bytes([5]))  # Operating Mode 5 (EEPROM, torque off)
        limit = motor.units_for(motor.cap_nm(LAW.cap_nm))
        servo.write(38, limit.to_bytes(2, "little"))  # Current Limit
        servo.write(FEEL_MAP.address, feel_map())
        servo.write(64, bytes([1]))  # torque on
    hand = {**HAND, "max_torque_nm": max_torque_nm}
    sim.set_operator(
        {"script": script, "let_go_s": let_go_s, "stiffness_nm_deg": stiffness, **hand}
    )
    rows, pushes, engaged, previous = [], [], False, None
    watch = SteppedWatch(servos, RIG.joints, lambda: sim.time_s, rules and snap_watch, motor)
    for k in range(round(seconds * 200.0)):
        if watch.before_step(5 * k):
            engaged = False  # the watch let the wall go: LeaderSource.release
        for servo in servos:
            servo.refresh(sim.time_s)
        pose = RIG.angles_of(tuple(s.value(SimRegister.PRESENT_POSITION) for s in servos))
        q = pose_quat_scalar(*pose)
        torque = read_torque(servos, RIG.joints, motor)
        velocity = read_velocity(servos, RIG.joints)
        read_s = sim.time_s  # when the cycle read the leader
        if rules:
            corrected = region.correct(q)
            past = (previous, 0.005, engaged, torque)
            push = push3_for(LAW, motor, pose, q, corrected, RIG.roll_limits, *past)
            if watch.on and push.goal_current:
                if not watch.snap.allows(pose, push.goal, velocity, engaged, sim.time_s, torque):
                    push = held3(pose)
        else:
            push = push3_for(LAW, motor, pose, q, region.correct(q), RIG.roll_limits)
        previous = pose
        instead = (cycles or {}).get(k)
        if instead == "held":
            push = held3(pose)
        pushes.append((pose, push, instead))
        if instead == "silent":
            engaged = False
            watch.snap.disarm()
            for servo in servos:
                servo.write(102, bytes(2))  # Goal Current 0 alone
        for step in range(5):
            if step and watch.before_step(5 * k + step):
                engaged = False
            if step == 1 and instead != "silent":
                ticks = [
                    int(angle_to_ticks(a, j.zero_tick, j.direction))
                    for a, j in zip(push.goal, RIG.joints, strict=True)
                ]
                if push.goal_current and not engaged:
                    for servo in servos:
                        servo.write(64, bytes([0]))
                        servo.write(64, bytes([1]))
                was_engaged, engaged = engaged, bool(push.goal_current)
                currents = push.currents(len(servos))
                for servo, tick, current in zip(servos, ticks, currents, strict=True):
                    servo.write(112, push.profile_velocity.to_bytes(4, "little"))
                    servo.write(FEEL_DATA.address, encode_feel(current, tick))
                goal = push.goal if push.goal_current and instead != "held" else None
                watch.wrote(pose, goal, velocity, torque, was_engaged, read_s)
            if step >= 1:  # the loop's wait, from right after the cycle's write
                watch.after_write(5 * k + step)
            clock[0] += 0.001
            sim.advance()
            rows.append(sim.leader.sample())
    return rows, pushes


def beyond_of(region, row):
    q = q_of(*row["pose_deg"])
    return beyond3_deg(q, region.correct(q))


def judge(region, rows, pushes, start_s, end_s):
    """The checks every press must pass; the held rows' distances beyond the edge (deg)."""
    # every cycle whose command was inside wrote no current, on all three servos
    inside = [push for _, push, _ in pushes if push.distance_deg == 0.0]
    assert inside and all(push.goal_current == 0 for push in inside)
    # in the ground truth: never above the cap on any joint; no torque while inside
    assert max(abs(m) for r in rows for m in r["motor_nm"]) <= CAP + 1e-12
    truly_inside = [r for r in rows[::5] if region.contains(q_of(*r["pose_deg"]))]
    assert truly_inside and all(r["motor_nm"] == [0.0, 0.0, 0.0] for r in truly_inside)
    # outside, pressed: the joint torques point toward the corrected pose
    toward = []
    for r in rows[::5]:
        if not any(r["motor_nm"]):
            continue
        present = tuple(np.radians(r["pose_deg"]))
        q = pose_quat_scalar(*present)
        way = np.subtract(corrected_pose(region.correct(q), present, RIG.roll_limits), present)
        if float(np.dot(r["hand_nm"], way)) < 0.0:  # the hand pushes outward
            toward.append(float(np.dot(r["motor_nm"], way)))
    assert len(toward) > 50 and min(toward) > 0.0
    return np.array([beyond_of(region, r) for r in rows if start_s <= r["t"] < end_s])


#: Pressing 20 deg beyond the edge from the middle in 2 s: in swing (pan) and in twist (roll).
PRESSES = {
    "swing": [[0.0, 0.0, 0.0, 0.0], [2.0, 50.0, 0.0, 0.0]],
    "twist": [[0.0, 0.0, 0.0, 0.0], [2.0, 0.0, 0.0, 50.0]],
    "both": [[0.0, 0.0, 0.0, 0.0], [2.0, 40.0, 10.0, -45.0]],
}


_LET_GO: dict = {}


def pressed_and_let_go(region, press):
    """:func:`felt3_at_200_hz` of ``PRESSES[press]`` let go at 4.5 s (computed once)."""
    if press not in _LET_GO:
        _LET_GO[press] = felt3_at_200_hz(region, PRESSES[press], 6.0, let_go_s=4.5)
    return _LET_GO[press]


def outward_after(region, rows, start_s):
    """Times (s from ``start_s``) of the 1 ms samples from then on outside the region whose joint
    torques point away from the correction (dot product with ``corrected - present`` < 0)."""
    times = []
    for r in rows:
        if r["t"] < start_s or not any(r["motor_nm"]):
            continue
        present = tuple(np.radians(r["pose_deg"]))
        q = pose_quat_scalar(*present)
        if region.contains(q):
            continue
        way = np.subtract(corrected_pose(region.correct(q), present, RIG.roll_limits), present)
        if float(np.dot(r["motor_nm"], way)) < 0.0:
            times.append(r["t"] - start_s)
    return times


@pytest.mark.parametrize("press", sorted(PRESSES))
def test_at_200_hz_the_leader_stops_within_2_deg_of_the_edge_and_walks_back(region, press):
    rows, pushes = pressed_and_let_go(region, press)
    held = judge(region, rows, pushes, 3.0, 4.5)
    # a 0.3 N m hand of 0.05 N m/deg held beyond the edge, within 2 deg of rotation of it
    assert 0.4 < held.min() and held.max() < 2.0
    assert np.ptp(held) < 0.3  # no ripple
    # let go: walked back by the profiles (under 30 deg/s on every joint), resting beyond
    after = [r for r in rows if r["t"] >= 4.5]
    speeds = np.abs([r["velocity_deg_s"] for r in after])
    smoothed = [np.convolve(speeds[:, j], np.ones(20) / 20, mode="valid").max() for j in range(3)]
    assert max(smoothed) <= 30.0
    assert beyond_of(region, after[-1]) < LAW.deadband_deg + 0.1
    assert all(beyond_of(region, r) > 0.0 for r in after[::5])  # never walked inside
    # the snap watch lets the held wall go as the snap onto the setpoints starts: no sample
    # after the let go pulls outward, none turns faster than 30 deg/s (limbctl/teleop/snap.py)
    assert outward_after(region, rows, 4.5) == []
    assert speeds.max() <= 30.0


def test_at_200_hz_the_law_alone_brakes_a_let_go_three_servo_leader_outward(region):
    # the peer: round 6's law without the snap watch brakes each press's snap 2-6 ms after the
    # let go, and the swing press's snap reaches 32.0 deg/s (decisions/haptic.md, round 5)
    runs = {p: felt3_at_200_hz(region, PRESSES[p], 6.0, 4.5, snap_watch=False) for p in PRESSES}
    assert all(len(outward_after(region, rows, 4.5)) >= 2 for rows, _ in runs.values())
    swing = [r for r in runs["swing"][0] if r["t"] >= 4.5]
    assert max(max(map(abs, r["velocity_deg_s"])) for r in swing) > 30.0


@pytest.mark.parametrize("model", ["xl330-m288@53", "xl330-m077@53"])
@pytest.mark.parametrize("press", sorted(PRESSES))
def test_at_200_hz_an_xl330_leader_pushes_with_its_cap_and_returns_under_30_deg_s(
    region, model, press
):
    # the lead follows the soft loop (ten ticks and more on an XL330, two on the XM430), and
    # the XL330-M288 holds at most 0.12 N m (decisions/haptic.md, round 6)
    # (the law alone, without the snap watch: the figures do not lean on it)
    rows, _ = felt3_at_200_hz(
        region, PRESSES[press], 6.0, let_go_s=4.5, model=model, snap_watch=False
    )
    motor = motor_of(model)
    cap = motor.torque_of(motor.units_for(motor.cap_nm(LAW.cap_nm)))
    held = [r for r in rows if 3.0 <= r["t"] < 4.5]
    # the 0.3 N m hand overpowers an XL330's cap: the wall pushes with about all of it, never
    # more, in magnitude (the norm of the joints' torques: at most the law's cap; a joint the
    # hand pushes less than its share of the cap sits under it)
    felt = max(float(np.linalg.norm(r["motor_nm"])) for r in held)
    assert 0.9 * cap <= felt <= motor.cap_nm(LAW.cap_nm) + 1e-12
    after = [r for r in rows if r["t"] >= 4.5]
    assert max(max(map(abs, r["velocity_deg_s"])) for r in after) <= 30.0  # every 1 ms sample
    assert beyond_of(region, after[-1]) < 0.5
    assert all(beyond_of(region, r) > 0.0 for r in after[::5])  # never walked inside


#: Pressed 20 deg beyond the edge, held, then pulled back inside in 0.2 s: in swing and twist.
PULLS = {
    "swing": [[0.0, 0.0, 0.0, 0.0], [2.0, 50.0, 0.0, 0.0], [4.0, 50.0, 0.0, 0.0], [4.2, 0, 0, 0]],
    "twist": [[0.0, 0.0, 0.0, 0.0], [2.0, 0.0, 0.0, 50.0], [4.0, 0.0, 0.0, 50.0], [4.2, 0, 0, 0]],
}


def pulled_outward(region, rows):
    """The 1 ms truth rows outside the region whose joint torques point away from the
    correction (their dot product with ``corrected pose - pose`` < 0), and the rows inside
    with any torque."""
    outward, inside = [], []
    for r in rows:
        if not any(r["motor_nm"]):
            continue
        present = tuple(np.radians(r["pose_deg"]))
        q = pose_quat_scalar(*present)
        if bool(region.contains(q)):
            inside.append(r)
            continue
        way = np.subtract(corrected_pose(region.correct(q), present, RIG.roll_limits), present)
        if float(np.dot(r["motor_nm"], way)) < 0.0:
            outward.append(r)
    return outward, inside


@pytest.mark.parametrize("stiffness", [0.05, 0.2])
@pytest.mark.parametrize("pull", sorted(PULLS))
def test_a_hand_carrying_the_leader_back_toward_the_region_is_pulled_outward_less(
    region, pull, stiffness
):
    # as the two-servo leader's: the setpoints move at most 30 deg/s, so the loops would pull a
    # faster leader back, away from the region; the law lets go once a read shows it outrunning
    # the setpoints by more than a tick. Without the let-go rules (previous=None) the wall
    # stays on until the leader is within the deadband.
    # The first read whose Present Current pulls outward frees the wall too (round 5): the
    # pull lasts at most a cycle and its write.
    rows, _ = felt3_at_200_hz(region, PULLS[pull], 5.0, stiffness=stiffness)
    before, _ = felt3_at_200_hz(region, PULLS[pull], 5.0, stiffness=stiffness, rules=False)
    outward, inside = pulled_outward(region, rows)
    assert not inside  # never any torque inside
    assert len(outward) < len(pulled_outward(region, before)[0])
    assert not outward or outward[-1]["t"] - outward[0]["t"] <= 0.006
    # along the way to the correction, never more than a quarter of the cap outward
    pulls = [-float(np.dot(r["motor_nm"], unit_way(region, r))) for r in outward]
    assert max(pulls, default=0.0) < 0.25 * CAP


def unit_way(region, row):
    """The unit joint-space direction from a row's pose toward its correction."""
    present = tuple(np.radians(row["pose_deg"]))
    q = pose_quat_scalar(*present)
    way = np.subtract(corrected_pose(region.correct(q), present, RIG.roll_limits), present)
    return way / np.linalg.norm(way)


def test_a_held_gate_switches_every_joint_off_within_the_cycle(region):
    # the gate holds for 10 cycles from 3.2 s (a failed follower read): each writes Goal
    # Current 0, so from that write (1 ms in) the motors apply nothing until the next cycle's
    held = {k: "held" for k in range(640, 650)}
    rows, pushes = felt3_at_200_hz(region, PRESSES["twist"], 4.0, cycles=held)
    released = [r for r in rows if 3.2 + 0.0015 <= r["t"] < 3.25]
    assert released and all(r["motor_nm"] == [0.0, 0.0, 0.0] for r in released)
    assert max(abs(r["motor_nm"][2]) for r in rows if 3.1 <= r["t"] < 3.2) > 0.25  # it pushed
    # back on, the wall pushes the leader the hand took ~15 deg out back toward the edge, against
    # the hand (0.27 N m there): a two-tick lead left its loop 0.27 N m and it stayed 14.9 deg out
    # (decisions/haptic.md, round 4)
    out = [beyond_of(region, r) for r in rows if 3.25 <= r["t"] < 3.35]
    late = [beyond_of(region, r) for r in rows if 3.9 <= r["t"] < 4.0]
    assert max(out) > 10.0 and max(late) < max(out) - 3.0
    silent = {k: "silent" for k in range(700, 710)}
    rows, _ = felt3_at_200_hz(region, PRESSES["swing"], 4.0, cycles=silent)
    released = [r for r in rows if 3.5 + 0.0005 <= r["t"] < 3.55]
    assert released and all(r["motor_nm"] == [0.0, 0.0, 0.0] for r in released)


def test_a_leader_released_by_goal_current_alone_still_walks_back_in_twist(region):
    # the leader's read fails for 100 ms just before the hand lets go at 4.5 s: released by Goal
    # Current alone, the hand turns it further; let go, the wall comes on again with Torque
    # Enable off and on (its setpoints at the present pose) and walks it back at the profile's
    # speed on every joint, resting beyond the edge
    silent = {k: "silent" for k in range(880, 900)}
    rows, _ = felt3_at_200_hz(region, PRESSES["twist"], 6.5, let_go_s=4.5, cycles=silent)
    before = [beyond_of(region, r) for r in rows if 4.45 <= r["t"] < 4.5]
    assert max(before) > 5.0  # the hand took it far out meanwhile
    after = [r for r in rows if r["t"] >= 4.5]
    speeds = np.abs([r["velocity_deg_s"] for r in after])
    smoothed = [np.convolve(speeds[:, j], np.ones(20) / 20, mode="valid").max() for j in range(3)]
    assert max(smoothed) <= 30.0
    assert all(beyond_of(region, r) > 0.0 for r in after[::5])
