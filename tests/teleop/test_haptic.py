"""The haptic law: zero inside, toward the region outside, never above the cap."""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from limbctl.envelope import Cone
from limbctl.errors import ConfigError
from limbctl.geometry.gimbal import pan_tilt_to_quat, quat_to_pan_tilt
from limbctl.servo.control_table import ModelNumber
from limbctl.servo.leader import FELT_MODELS
from limbctl.teleop.haptic import TICK_DEG, FeelLaw, FeelStats, beyond_deg, push_for
from limbctl.teleop.sources.leader import PaceWatch
from tests.teleop.stepped_leader import felt_at_200_hz

LAW = FeelLaw()
MOTOR = FELT_MODELS[ModelNumber.XM430_W350]
CONE = Cone(half_angle_deg=30.0)


def q_of(pan_deg: float, tilt_deg: float) -> np.ndarray:
    return np.asarray(pan_tilt_to_quat(math.radians(pan_deg), math.radians(tilt_deg)))


def test_torque_is_zero_inside_and_within_the_deadband_then_grows_to_the_cap():
    assert LAW.torque_nm(0.0) == 0.0
    assert LAW.torque_nm(LAW.deadband_deg) == 0.0
    assert LAW.torque_nm(1.4) == pytest.approx(0.2)  # K (1.4 - 0.4)
    assert LAW.torque_nm(50.0) == LAW.cap_nm


def test_the_law_is_passive_at_200_hz_with_the_simulated_leader():
    # b / (K T / 2): 0.05 / (11.46 x 0.005 / 2) = 1.75
    assert LAW.passivity_margin(0.05, 200.0) == pytest.approx(1.745, abs=1e-3)
    assert LAW.passivity_margin(0.05, 100.0) < 1.0  # at 100 Hz the same wall is not


def test_profile_velocity_stays_under_30_deg_s():
    assert LAW.profile_velocity_units() * 0.229 * 6.0 <= 30.0
    with pytest.raises(ConfigError, match="return_speed_deg_s"):
        FeelLaw(return_speed_deg_s=45.0)
    with pytest.raises(ConfigError, match="cap_nm"):
        FeelLaw(cap_nm=-1.0)


def test_distance_is_between_the_command_and_its_correction():
    q = q_of(40.0, 0.0)
    assert beyond_deg(q, CONE.correct(q)) == pytest.approx(10.0, abs=1e-6)
    assert beyond_deg(q_of(10.0, 5.0), CONE.correct(q_of(10.0, 5.0))) == 0.0


def test_a_push_leads_the_leader_toward_the_corrected_pose_by_at_most_the_lead():
    q = q_of(40.0, 0.0)
    push = push_for(LAW, MOTOR, (math.radians(40.0), 0.0), q, CONE.correct(q))
    assert push.goal_current == MOTOR.units_for(LAW.cap_nm)
    # 10 deg beyond, deeper than a hand within the cap holds it: three ticks, not two
    assert math.degrees(push.goal_pan) == pytest.approx(40.0 - 3 * TICK_DEG)
    near = push_for(
        LAW, MOTOR, (math.radians(31.5), 0.0), q_of(31.5, 0.0), CONE.correct(q_of(31.5, 0.0))
    )
    assert math.degrees(near.goal_pan) == pytest.approx(31.5 - 2 * TICK_DEG)
    assert push.profile_velocity == LAW.profile_velocity_units()
    inside = push_for(LAW, MOTOR, (0.1, 0.0), q_of(5.7, 0.0), q_of(5.7, 0.0))
    assert (inside.goal_current, inside.profile_velocity, inside.torque_nm) == (0, 0, 0.0)
    assert inside.goal_pan == 0.1  # free: the goal rides with the leader


def test_a_wall_walking_its_leader_back_with_no_hand_leads_two_ticks_more():
    pose, q = (math.radians(31.5), 0.0), q_of(31.5, 0.0)
    corrected = CONE.correct(q)

    def lead_ticks(engaged: bool, torque, velocity) -> float:
        push = push_for(LAW, MOTOR, pose, q, corrected, pose, 0.005, engaged, torque, velocity)
        assert push.goal_current > 0
        return round((31.5 - math.degrees(push.goal_pan)) / TICK_DEG, 6)

    walking = (-0.02, 0.0), (-13.7, 0.0)  # 0.02 N m in, at the setpoint's 13.7 deg/s
    assert lead_ticks(True, *walking) == 4
    assert lead_ticks(False, *walking) == 2  # the wall comes on: from the leader, LEAD
    assert lead_ticks(True, (-LAW.walk_hold_nm, 0.0), (-13.7, 0.0)) == 2  # a hand is held
    assert lead_ticks(True, (-0.02, 0.0), (-1.37, 0.0)) == 2  # one velocity unit: still
    assert lead_ticks(True, (-0.02, 0.0), (13.7, 0.0)) == 2  # moving out
    assert lead_ticks(True, (-0.02, 0.0), None) == 2  # speed not read: LEAD alone
    assert lead_ticks(True, None, (-13.7, 0.0)) == 2
    # the lead never passes the corrected pose: 0.6 deg beyond, four ticks would reach 0.25
    edge = q_of(30.6, 0.0)
    near = push_for(
        LAW, MOTOR, (math.radians(30.6), 0.0), edge, CONE.correct(edge), None, 0.0, True, *walking
    )
    assert math.degrees(near.goal_pan) >= 30.0 - 1e-9
    without = FeelLaw(walk_lead_ticks=0)
    push = push_for(without, MOTOR, pose, q, corrected, pose, 0.005, True, *walking)
    assert math.degrees(push.goal_pan) == pytest.approx(31.5 - 2 * TICK_DEG)


angles = st.floats(-100.0, 100.0, allow_nan=False)


@settings(max_examples=300, deadline=None)
@given(angles, st.floats(-50.0, 65.0), st.floats(-1.0, 1.0), st.floats(-1.0, 1.0))
def test_property_never_above_the_cap_zero_inside_toward_the_region(pan, tilt, dp, dt):
    q = q_of(pan, tilt)
    corrected = CONE.correct(q)
    present = (math.radians(pan + dp), math.radians(tilt + dt))  # the read lags a little
    push = push_for(LAW, MOTOR, present, q, corrected)
    assert 0 <= push.goal_current <= MOTOR.units_for(LAW.cap_nm)
    assert push.torque_nm <= LAW.cap_nm
    if bool(CONE.contains(q)):
        assert push.goal_current == 0
    if push.goal_current:
        # the goal lies from the leader toward the corrected pose, no further than the lead
        step = np.subtract((push.goal_pan, push.goal_tilt), present)
        lead = LAW.lead_for_deg(push.distance_deg, MOTOR)
        assert np.max(np.abs(step)) <= math.radians(lead) + 1e-12
        target = np.subtract(np.asarray(quat_to_pan_tilt(corrected), dtype=float), present)
        assert float(step @ target) >= 0.0


@settings(max_examples=300, deadline=None)
@given(st.floats(31.0, 60.0), st.floats(-2.0, 2.0), st.floats(0.001, 0.05), st.booleans())
def test_property_a_leader_outrunning_its_setpoint_or_still_moving_in_is_free_else_led(
    pan, moved, period, engaged
):
    # along pan beyond the edge at 30 deg: moved > 0 is toward the region
    assume(moved == 0.0 or abs(moved) > 1e-9)  # a motion the float subtraction keeps
    q = q_of(pan, 0.0)
    corrected = CONE.correct(q)
    present, previous = (math.radians(pan), 0.0), (math.radians(pan + moved), 0.0)
    push = push_for(LAW, MOTOR, present, q, corrected, previous, period, engaged)
    free = push_for(LAW, MOTOR, present, q, corrected)
    outrun = moved > LAW.return_speed_deg_s * period + LAW.outrun_slack_deg
    near = (pan - 30.0) - moved <= LAW.deadband_deg
    low = (pan - 30.0) - LAW.deadband_deg <= LAW.rearm_band_deg  # comes on only past this
    if outrun or near or (not engaged and (moved > 0.0 or low)):
        assert push.goal_current == 0
    else:  # otherwise the law's current, the goal at most LEAD ahead (it no longer grows with
        # the leader's step: decisions/haptic.md, round 4)
        assert push.goal_current == free.goal_current
        assert push.goal_pan == free.goal_pan
        lead = LAW.lead_for_deg(push.distance_deg, MOTOR)
        assert 0.0 <= present[0] - push.goal_pan <= math.radians(lead) + 1e-12


@settings(max_examples=300, deadline=None)
@given(st.floats(31.0, 60.0), st.floats(-0.4, 0.4), st.floats(-0.4, 0.4), st.booleans())
def test_property_a_wall_whose_read_torque_pulls_outward_lets_go(pan, pan_nm, tilt_nm, engaged):
    # along pan beyond the edge at 30 deg: the correction lies at pan decreasing, so a read
    # torque with pan_nm > NOISE pulls away from the region (round 5)
    q = q_of(pan, 0.0)
    corrected = CONE.correct(q)
    present = (math.radians(pan), 0.0)
    push = push_for(LAW, MOTOR, present, q, corrected, present, 0.005, engaged, (pan_nm, tilt_nm))
    unread = push_for(LAW, MOTOR, present, q, corrected, present, 0.005, engaged)
    if engaged and pan_nm > LAW.outward_noise_nm:
        assert push.goal_current == 0
    else:  # a torque toward the region, or within the reading's noise: the law as unread
        assert push == unread


def test_stats_say_how_long_and_how_hard():
    stats = FeelStats()
    assert "never pressed" in stats.describe()
    for torque in (0.0, 0.2, 0.4):
        stats.add(torque, 0.005)
    assert stats.engaged_s == pytest.approx(0.01) and stats.peak_nm == 0.4
    assert "0.01 s" in stats.describe() and "0.30 N m on average" in stats.describe()


# -- the law against the simulated leader, at exactly 200 Hz --------------------------------------


def test_at_200_hz_the_leader_stops_within_2_deg_and_a_release_walks_back_to_the_edge():
    script = [[0.0, 0.0, 0.0], [2.0, 50.0, 0.0]]  # 20 deg beyond the 30 deg edge
    rows = felt_at_200_hz(script, 7.0, let_go_s=5.0)
    t = np.array([r["t"] for r in rows])
    pan = np.array([r["pose_deg"][0] for r in rows])
    velocity = np.array([r["velocity_deg_s"][0] for r in rows])
    held = pan[(t >= 3.0) & (t < 5.0)]
    assert 30.0 < held.min() and held.max() < 32.0  # a 0.3 N m hand, stiffness 0.05 N m/deg
    assert np.ptp(held) < 0.2  # no ripple
    after = t >= 5.0
    # walked back by the profile: the speed averaged over 20 ms stays under 30 deg/s
    assert np.convolve(-velocity[after], np.ones(20) / 20.0, mode="valid").max() <= 30.0
    assert 30.0 <= pan[after].min() and pan[-1] < 30.5  # rests within 0.5 deg, never inside
    inside = [r for r in rows if r["pose_deg"][0] < 30.0]
    assert inside and all(r["motor_nm"] == [0.0, 0.0] for r in inside)
    # never above the cap; pressed beyond the edge, the motor pulls pan back, never outward
    assert max(abs(m) for r in rows for m in r["motor_nm"]) <= MOTOR.torque_of(
        MOTOR.units_for(LAW.cap_nm)
    )
    pressed = [r for r in rows if r["pose_deg"][0] > 30.5 and r["hand_nm"][0] > 0.0]
    assert pressed and all(r["motor_nm"][0] <= 0.0 for r in pressed)
    assert min(r["motor_nm"][0] for r in pressed) < -0.25  # it did push: 0.3 N m hand held


@functools.cache
def let_go(stiffness: float, beyond_deg: float, let_go_s: float = 5.0, watch: bool = True) -> dict:
    """A hand of ``stiffness`` pressing ``beyond_deg`` past the edge, let go at ``let_go_s``
    (stepped clock; ``watch``: the snap watch on): after the let go, the 1 ms samples outside
    whose motor torque points outward (their times from the let go, s, and torques), the 1 ms
    and 20 ms peak return speeds, the rest."""
    script = [[0.0, 0.0, 0.0], [2.0, 30.0 + beyond_deg, 0.0]]
    rows = felt_at_200_hz(script, 7.0, stiffness, let_go_s=let_go_s, snap_watch=watch)
    after = [r for r in rows if r["t"] >= let_go_s]
    speed = -np.array([r["velocity_deg_s"][0] for r in after])
    outward = [r for r in after if r["pose_deg"][0] > 30.0 and r["motor_nm"][0] > 0.0]
    return {
        "outward_s": [r["t"] - let_go_s for r in outward],
        "outward_nm": [r["motor_nm"][0] for r in outward],
        "peak": float(speed.max()),
        "mean_20ms": float(np.convolve(speed, np.ones(20) / 20.0, mode="valid").max()),
        "pan": np.array([r["pose_deg"][0] for r in after]),
    }


#: Hands and depths, each let go at 5 s (a cycle's read) and 1-4 ms after it.
LET_GO_CASES = [
    (k, beyond, 5.0 + phase / 1000.0)
    for k in (0.02, 0.05, 0.2)
    for beyond in (5.0, 20.0)
    for phase in (0, 2, 4)
]


@pytest.mark.parametrize(("stiffness", "beyond_deg", "let_go_s"), LET_GO_CASES)
def test_at_200_hz_a_let_go_leader_walks_back_under_30_deg_s_and_rests_at_the_edge(
    stiffness, beyond_deg, let_go_s
):
    out = let_go(stiffness, beyond_deg, let_go_s)
    assert out["mean_20ms"] <= 30.0
    # every 1 ms sample: the snap watch lets the wall go within 2 ms of the let go, before
    # the snap onto the setpoint passes 30 deg/s (the law alone: up to 31.1, below)
    assert out["peak"] <= 30.0
    assert 30.0 <= out["pan"].min() and out["pan"][-1] < 30.5  # within 0.5 deg, never inside


@pytest.mark.parametrize(("stiffness", "beyond_deg", "let_go_s"), LET_GO_CASES)
def test_at_200_hz_after_let_go_no_sample_outside_pulls_outward(stiffness, beyond_deg, let_go_s):
    # the held setpoint lies LEAD ahead; let go, the leader snaps onto it and the simulated
    # loop's damping would brake it there (outward) 2-10 ms after the let go. The snap watch
    # reads the leader's speed every millisecond between the cycles and lets the held wall go
    # as the snap starts; the wall comes back only on a still leader (limbctl/teleop/snap.py)
    assert let_go(stiffness, beyond_deg, let_go_s)["outward_s"] == []


def test_at_200_hz_the_law_alone_brakes_a_let_go_leader_outward_and_snaps_over_30_deg_s():
    # the peer: round 6's law without the snap watch (decisions/haptic.md, rounds 4-5)
    alone = [let_go(k, beyond, t, watch=False) for k, beyond, t in LET_GO_CASES]
    assert sum(len(out["outward_s"]) for out in alone) >= 20
    assert max(out["peak"] for out in alone) > 30.0


@pytest.mark.parametrize("release_s", [0.05, 0.1])
def test_at_200_hz_a_fading_grip_is_not_cut_like_a_let_go(release_s):
    # a grip fading over 50-100 ms frees the hold gradually: the snap watch leaves the wall on.
    # Cut on speed alone, the hand still pushing 0.25 N m threw the leader 0.3 deg out at
    # 60 deg/s and the wall's return pushed it in at 30 deg/s (decisions/haptic.md, round 7)
    script = [[0.0, 0.0, 0.0], [2.0, 35.0, 0.0]]
    rows = felt_at_200_hz(script, 5.4, 0.2, let_go_s=5.002, release_s=release_s)
    held = max(r["pose_deg"][0] for r in rows if 4.9 <= r["t"] < 5.002)
    after = [r for r in rows if r["t"] >= 5.002]
    assert max(r["pose_deg"][0] for r in after) < held + 0.02  # not thrown outward
    assert max(-r["velocity_deg_s"][0] for r in after) < 20.0


@pytest.mark.parametrize("stiffness", [0.02, 0.2])
def test_at_200_hz_a_closed_excursion_gives_the_hand_back_less_than_it_put_in(stiffness):
    script = [[0.0, 20.0, 0.0], [1.0, 20.0, 0.0], [2.0, 40.0, 0.0], [2.5, 40.0, 0.0]]
    rows = felt_at_200_hz([*script, [3.5, 20.0, 0.0], [4.5, 20.0, 0.0]], 4.5, stiffness)
    beyond = np.array([r["pose_deg"][0] for r in rows])[1:] > 30.0
    hand = np.diff([r["hand_work_j"][0] for r in rows])[beyond].sum()
    motor = np.diff([r["motor_work_j"][0] for r in rows])[beyond].sum()
    # the sampled wall leaks a little (motor > 0), the leader's friction takes more: the hand's
    # net work stays positive, the motor does no net work on the hand
    assert hand > 0.0 and motor < hand


#: Pressing 5 deg beyond the edge (pan 35), from the middle in 1.5 s; steady from 3 s on.
PRESS_5 = [[0.0, 0.0, 0.0], [1.5, 35.0, 0.0]]


def pan_between(rows, start_s, end_s):
    return np.array([r["pose_deg"][0] for r in rows if start_s <= r["t"] < end_s])


@pytest.mark.parametrize("stiffness", [0.02, 0.05, 0.1, 0.2])
def test_at_200_hz_pressing_into_the_wall_ripples_under_0_2_deg(stiffness):
    held = pan_between(felt_at_200_hz(PRESS_5, 4.5, stiffness), 3.0, 4.5)
    assert 30.0 < held.min() and np.ptp(held) < 0.2


@pytest.mark.parametrize("stiffness", [0.05, 0.2])
def test_late_cycles_keep_the_wall_a_stalled_loop_does_not_release_it(stiffness):
    # the loop stalls for 20 ms at 3.2 s and for 40 ms at 3.8 s: the servos keep their last
    # Goal Current and Goal Position, so the pressed leader does not move
    late = {k: "late" for k in (*range(640, 644), *range(760, 768))}
    held = pan_between(felt_at_200_hz(PRESS_5, 4.5, stiffness, cycles=late), 3.0, 4.5)
    assert 30.0 < held.min() and np.ptp(held) < 0.2


@pytest.mark.parametrize("stiffness", [0.05, 0.2])
def test_a_hand_carrying_the_leader_back_toward_the_region_is_not_pulled_outward(stiffness):
    # pressed 20 deg beyond, then the hand heads back inside: the servo's setpoint moves at
    # most RETURN_SPEED, so its loop brakes a faster leader, pulling it away from the region.
    # The first read whose Present Current shows that frees the wall (round 5): the pull lasts
    # at most a cycle and its write (6 ms); round 4, which waited for the leader to outrun the
    # setpoint by a tick, let a hand at about the setpoint's pace (0.05 N m/deg) be pulled
    # 25 ms, up to 0.19 N m (docs/bench_haptic.md). Never any torque inside.
    script = [[0.0, 0.0, 0.0], [2.0, 50.0, 0.0], [4.0, 50.0, 0.0], [4.2, 0.0, 0.0]]
    rows = felt_at_200_hz(script, 5.0, stiffness)
    outward = [r for r in rows if r["pose_deg"][0] > 30.0 and r["motor_nm"][0] > 0.0]
    assert not outward or outward[-1]["t"] - outward[0]["t"] <= 0.006
    assert max((r["motor_nm"][0] for r in outward), default=0.0) < 0.25 * LAW.cap_nm
    inside = [r for r in rows if r["pose_deg"][0] < 30.0 and r["t"] > 4.0]
    assert inside and all(r["motor_nm"] == [0.0, 0.0] for r in inside)


def test_a_held_gate_releases_the_leader_at_once_and_the_hand_pushes_through():
    # a gate that held (or a follower silent past FOLLOWER_GRACE_S): each held cycle releases
    # the leader (the safety rule): the hand pushes it toward where it means to go, and the
    # wall takes it back afterwards (docs/decisions/haptic.md).
    rows = felt_at_200_hz(PRESS_5, 4.5, 0.05, cycles={k: "held" for k in range(640, 650)})
    # from the held cycle's write (1 ms in) to the next cycle's, the motor applies nothing
    released = [r for r in rows if 3.2 + 0.0015 <= r["t"] < 3.25]
    assert released and all(r["motor_nm"] == [0.0, 0.0] for r in released)
    before, during = pan_between(rows, 3.0, 3.2), pan_between(rows, 3.2, 3.6)
    assert np.ptp(before) < 0.2 and during.max() - before.mean() > 1.0
    assert pan_between(rows, 4.3, 4.5).max() < before.max() + 0.2  # the wall took it back


def test_the_pace_watch_switches_the_feel_off_when_the_median_period_is_over_1_25_periods():
    ticks = iter([0.005 * k for k in range(41)] + [0.2 + 0.0066 * k for k in range(1, 100)])
    watch = PaceWatch(200.0, clock=lambda: next(ticks))
    # 200 Hz for 40 periods: kept; then 151 Hz (6.6 ms > 6.25 ms): lost once the median passes
    assert [watch.lost() for _ in range(41)] == [None] * 41
    verdicts = [watch.lost() for _ in range(99)]
    first = next(k for k, v in enumerate(verdicts) if v is not None)
    assert 15 <= first <= 25 and verdicts[first] == pytest.approx(0.0066)
    assert all(v is None for v in verdicts[:first])
    # a late cycle or a few do not: the median ignores them
    ticks = iter([0.005 * k + (0.03 if k >= 20 else 0.0) for k in range(60)])
    watch = PaceWatch(200.0, clock=lambda: next(ticks))
    assert all(watch.lost() is None for _ in range(60))


def test_a_leader_released_by_goal_current_alone_still_walks_back_after_let_go():
    # the leader's read fails for 100 ms just before the hand lets go at 5 s: released by Goal
    # Current alone, the hand takes it ~19 deg further; let go, it must still walk back at the
    # profile's speed
    script = [[0.0, 0.0, 0.0], [2.0, 50.0, 0.0]]
    silent = {k: "silent" for k in range(980, 1000)}
    rows = felt_at_200_hz(script, 7.0, let_go_s=5.0, cycles=silent)
    t = np.array([r["t"] for r in rows])
    pan = np.array([r["pose_deg"][0] for r in rows])
    velocity = np.array([r["velocity_deg_s"][0] for r in rows])
    assert pan[(t >= 4.9) & (t < 5.0)].max() > 45.0  # the hand took it far out meanwhile
    after = t >= 5.0
    assert np.convolve(-velocity[after], np.ones(20) / 20.0, mode="valid").max() <= 30.0
    assert 30.0 <= pan[after].min()
