"""The brake rules (limbctl/teleop/brake.py) and the watch that applies them
(limbctl/teleop/snap.py): a wall lets its leader go before the servo's loop brakes it outward,
and only then; on the stepped 200 Hz clock a hand pulling the leader back inside is never
pulled outward (a fading grip: test_haptic.py's let go tests), where the snap rule alone
(round 7) was."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from limbctl.teleop.brake import BrakeLaw, brakes_soon, outruns
from limbctl.teleop.snap import SnapLaw, SnapWatch
from tests.teleop.stepped_leader import felt_at_200_hz
from tests.teleop.test_snap import GOAL, POSE  # 2 deg beyond a pan edge at 30 deg

BRAKE = BrakeLaw()
WALK = 13.74  # the wall's setpoint speed (deg/s): Profile Velocity 10 units
STILL = SnapLaw().still_speed_deg_s


def walking_watch(brake: BrakeLaw | None = BRAKE) -> SnapWatch:
    """A watch after a cycle whose wall walks the leader back: in at the setpoint's pace, the
    motor pushing with 0.014 N m (what the simulated walk needs), read at 0 s."""
    watch = SnapWatch(SnapLaw(), brake=brake, walk_deg_s=WALK)
    watch.arm(POSE, GOAL, (-13.7, 0.0), (-0.014, 0.0), True, 0.0)
    return watch


def test_outrunning_the_walk_or_a_torque_falling_through_zero_soon_brakes_a_moving_leader():
    """The two brake rules, and neither for a still leader nor on an old read's rate."""
    assert outruns(WALK + 1.37, WALK, 0.01, BRAKE)  # one velocity unit over the setpoint
    assert not outruns(WALK + 0.3, WALK, 0.01, BRAKE)  # the walk's own ripple
    # a hand still pressed against the wall: freeing it would let the hand throw the leader
    assert not outruns(WALK + 5.0, WALK, BRAKE.loose_nm, BRAKE)
    # 0.02 N m now, 0.03 a millisecond ago: 0 in 2 ms
    assert brakes_soon(14.0, STILL, 0.019, 0.001, (0.03, 0.0), BRAKE)
    assert not brakes_soon(14.0, STILL, 0.021, 0.001, (0.03, 0.0), BRAKE)
    assert brakes_soon(14.0, STILL, -0.001, 0.001, None, BRAKE)  # already outward
    assert not brakes_soon(14.0, STILL, 0.014, 0.001, (0.014, 0.0), BRAKE)  # a steady walk
    assert not brakes_soon(STILL, STILL, -0.2, 0.001, (0.3, 0.0), BRAKE)  # a hand holds it
    # the last read 5 ms ago: its rate says nothing of now, only the sign counts
    assert not brakes_soon(14.0, STILL, 0.005, 0.005, (0.3, 0.0), BRAKE)


def test_a_walking_wall_is_watched_and_freed_when_its_leader_outruns_it():
    """Watched only with the brake rules; freed at a watch's read or a cycle's."""
    watch = walking_watch()
    assert watch.watching and watch.armed is None  # not held: the snap rule does not arm
    assert not watch.snaps((-13.7, 0.0), 0.001, (-0.014, 0.0))
    assert watch.snaps((-15.1, 0.0), 0.002, (-0.012, 0.0))  # a hand pulls it in
    assert watch.brakes == 1 and not watch.watching
    assert not watch.snaps((-16.0, 0.0), 0.003, (0.01, 0.0))  # freed: nothing more to cut
    alone = walking_watch(brake=None)  # without the brake rules only a held wall is watched
    assert not alone.watching
    assert not alone.snaps((-20.0, 0.0), 0.001, (0.05, 0.0))
    watch = walking_watch()
    assert watch.allows(POSE, GOAL, (-13.7, 0.0), True, 0.005, (-0.014, 0.0))
    assert not watch.allows(POSE, GOAL, (-13.7, 0.0), True, 0.006, (0.004, 0.0))  # outward
    assert watch.brakes == 1


#: Reads of the leader's speed along pan (deg/s) and its motor's torque along pan (N m).
READS = st.lists(st.tuples(st.floats(-40.0, 40.0), st.floats(-0.4, 0.4)), min_size=1, max_size=12)


@settings(max_examples=300, deadline=None)
@given(READS)
def test_property_the_brake_rules_cut_only_a_leader_moving_toward_the_region(reads):
    watch = walking_watch()
    for k, (speed, torque) in enumerate(reads):
        before = watch.watching
        cut = watch.snaps((speed, 0.0), 0.001 * (k + 1), (torque, 0.0))
        # toward the region is -pan: a cut needs a wall on and the leader moving in
        assert not cut or (before and -speed > STILL)
        assert not cut or watch.brakes == 1


#: A press 5 deg beyond the edge (pan 35) by the 0.2 N m/deg hand, let go at 5 s.
PRESS = [[0.0, 0.0, 0.0], [2.0, 35.0, 0.0]]


def outward(rows, after_s: float) -> list[float]:
    """Times (s) of the 1 ms samples after ``after_s`` outside the edge (pan 30) with the motor
    pulling outward (+pan)."""
    outside = [r for r in rows if r["t"] > after_s and r["pose_deg"][0] > 30.0]
    return [r["t"] for r in outside if r["motor_nm"][0] > 0.0]


def test_at_200_hz_the_snap_rule_alone_pulls_a_fading_grip_outward():
    # the peer: round 7's watch without the brake rules, on the fades that test_haptic.py's let
    # go test (its FADING_CASES at phase 0) never sees pulled outward with them
    counts = [
        len(outward(felt_at_200_hz(PRESS, 5.4, 0.2, let_go_s=5.0, release_s=r, brake=None), 5.0))
        for r in (0.01, 0.05, 0.1)
    ]
    assert sum(counts) >= 3


@pytest.mark.parametrize(("stiffness", "snap_alone"), [(0.05, 5), (0.2, 0)])
def test_at_200_hz_a_hand_pulling_the_leader_back_inside_is_never_pulled_outward(
    stiffness, snap_alone
):
    # pressed 20 deg beyond, the hand pulls it inside (pan 50 -> 0 in 0.2 s) faster than the
    # setpoint walks: the watch frees the wall before the loop brakes it. The snap rule alone
    # leaves the 0.05 N m/deg hand 5 samples pulled outward; the 0.2 hand's it cuts by itself
    script = [[0.0, 0.0, 0.0], [2.0, 50.0, 0.0], [4.0, 50.0, 0.0], [4.2, 0.0, 0.0]]
    rows = felt_at_200_hz(script, 4.6, stiffness)
    assert outward(rows, 4.0) == []
    alone = felt_at_200_hz(script, 4.6, stiffness, brake=None)
    assert len(outward(alone, 4.0)) == snap_alone
    inside = [r for r in rows if r["pose_deg"][0] < 30.0]
    assert inside and all(r["motor_nm"] == [0.0, 0.0] for r in inside)
