"""The snap watch (limbctl/teleop/snap.py): it arms on a held still leader, cuts at a snap, and
lets a free wall come back only on a still leader; it only ever takes torque away."""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from limbctl.teleop.snap import SnapLaw, SnapWatch, along, unit_step

LAW = SnapLaw()
#: The leader 2 deg beyond a pan edge at 30 deg, the wall's goal two ticks in (rad).
POSE = (math.radians(32.0), 0.0)
GOAL = (math.radians(31.824), 0.0)
HELD_NM = (-0.3, 0.0)  # the motor pushes a hand with 0.3 N m toward the region (-pan)
STILL = (0.0, 0.0)


def held_watch(hold: tuple[float, float] = HELD_NM) -> SnapWatch:
    """A watch after two cycles of a wall holding a still leader against a hand with ``hold``
    (the motor's torque, N m; last read 0 s)."""
    watch = SnapWatch(LAW)
    watch.arm(POSE, GOAL, STILL, hold, False, -0.005)  # the wall came on: not yet
    assert watch.armed is None
    watch.arm(POSE, GOAL, STILL, hold, True, 0.0)
    return watch


def test_only_a_wall_holding_a_still_leader_against_a_hand_arms_the_watch_while_it_holds():
    """Armed along the step to the goal by a held still leader, not a moving or light one."""
    assert unit_step(POSE, GOAL) == (-1.0, 0.0)
    assert unit_step(POSE, POSE) is None
    assert along((3.0, 4.0), (0.6, 0.8)) == 5.0
    assert held_watch().armed == (-1.0, 0.0)
    moving = SnapWatch(LAW)  # a wall pushing a deep leader back at 5 deg/s
    for k, engaged in enumerate((False, True, True)):
        moving.arm(POSE, GOAL, (-5.0, 0.0), HELD_NM, engaged, 0.005 * k)
    assert moving.armed is None
    assert held_watch((-0.03, 0.0)).armed is None  # a light hold: the loop walking it back
    # armed, it stays while the wall holds and goes with it
    creeping = held_watch()
    creeping.arm(POSE, GOAL, (-3.0, 0.0), HELD_NM, True, 0.005)  # a relaxing hand: creeping in
    assert creeping.armed == (-1.0, 0.0)
    creeping.arm(POSE, GOAL, (-3.0, 0.0), (-0.03, 0.0), True, 0.010)  # the hold is gone
    assert creeping.armed is None
    free = held_watch()
    free.arm(POSE, None, STILL, HELD_NM, True, 0.005)  # this cycle's wall is off
    assert free.armed is None


def test_an_armed_watch_cuts_at_a_snap_toward_the_region_once_not_at_a_relaxing_hand():
    """A snap inward cuts once; a grip fading from the hold as read at the last cycle does not."""
    watch = held_watch()
    assert not watch.snaps((-LAW.snap_speed_deg_s, 0.0), 0.001)  # at the threshold: not yet
    assert not watch.snaps((20.0, 0.0), 0.002)  # pushed outward by the hand: the wall holds
    assert not watch.snaps((0.0, 0.0), 0.003)
    assert watch.snaps((-17.0, 0.0), 0.004)  # a let go: 17 deg/s within a millisecond
    assert watch.armed is None and watch.cuts == 1
    assert not watch.snaps((-25.0, 0.0), 0.005)  # disarmed: once
    assert watch.reads == 5
    # a grip fading over 50 ms lets the leader speed up at about 2000 deg/s^2: the watch leaves
    # the wall on (a cut would leave the leader to a hand still pushing outward)
    watch = held_watch()
    speeds = [-0.5, -1.5, -3.0, -5.0, -7.0, -9.0]
    assert not any(watch.snaps((v, 0.0), 0.001 * (k + 1)) for k, v in enumerate(speeds))
    assert watch.armed is not None
    # and a let go while it creeps in is still one
    assert watch.snaps((-25.0, 0.0), 0.007)
    # armed while the hand pressed lightly (0.07 N m), the hold then grew to 0.3 N m: a grip
    # fading from there (2 deg/s more each millisecond) is no let go
    watch = held_watch((-0.07, 0.0))
    watch.arm(POSE, GOAL, (-1.4, 0.0), HELD_NM, True, 0.005)
    assert not any(watch.snaps((-1.4 - 2.0 * k, 0.0), 0.005 + 0.001 * k) for k in range(1, 5))
    assert watch.armed is not None


def test_judging_a_cycles_read_applies_the_rules_without_counting_a_watch_read():
    """A cycle's read (``allows``, ``judge``) applies the snap rule; a free wall needs it still."""
    watch = held_watch()
    assert watch.allows(POSE, GOAL, (-2.0, 0.0), True, 0.001)
    assert not watch.allows(POSE, GOAL, (-17.0, 0.0), True, 0.002)  # the snap at a read
    assert watch.cuts == 1
    # a free wall comes back only on a leader read as not moving in at all
    assert not watch.allows(POSE, GOAL, (-3.0, 0.0), False, 0.003)
    assert not watch.allows(POSE, GOAL, (-1.37, 0.0), False, 0.0035)  # one velocity unit
    assert watch.allows(POSE, GOAL, (0.0, 0.0), False, 0.004)
    assert watch.allows(POSE, GOAL, (10.0, 0.0), False, 0.005)  # moving out: it comes on
    watch = held_watch()
    assert not watch.judge((-2.0, 0.0), 0.001)
    assert watch.judge((-17.0, 0.0), 0.002)  # the snap at the cycle's read
    assert (watch.cuts, watch.reads, watch.armed) == (1, 0, None)


def test_with_rearm_twice_a_free_wall_comes_back_on_two_still_cycle_reads():
    watch = SnapWatch(LAW, rearm_twice=True)
    assert not watch.allows(POSE, GOAL, STILL, False, 0.000)  # one still read: not yet
    assert watch.allows(POSE, GOAL, STILL, False, 0.005)  # the next cycle's: it comes on
    # a hand reversing: still for one read, then pulling in
    reversing = SnapWatch(LAW, rearm_twice=True)
    assert not reversing.allows(POSE, GOAL, (-3.0, 0.0), False, 0.000)
    assert not reversing.allows(POSE, GOAL, STILL, False, 0.005)
    assert not reversing.allows(POSE, GOAL, (-6.0, 0.0), False, 0.010)
    # a still read older than the span says nothing of the leader now
    stale = SnapWatch(LAW, rearm_twice=True)
    assert not stale.allows(POSE, GOAL, STILL, False, 0.000)
    assert not stale.allows(POSE, GOAL, STILL, False, LAW.rearm_span_s + 0.001)
    # an engaged cycle in between forgets the still read before it
    between = SnapWatch(LAW, rearm_twice=True)
    assert not between.allows(POSE, GOAL, STILL, False, 0.000)
    assert between.allows(POSE, GOAL, STILL, True, 0.005)
    assert not between.allows(POSE, GOAL, STILL, False, 0.010)
    # a leader a hand pushes outward (from inside, or after a held gate): at once
    out = SnapWatch(LAW, rearm_twice=True)
    assert out.allows(POSE, GOAL, (10.0, 0.0), False, 0.000)
    # read at one velocity unit outward: still, so two reads
    creeping = SnapWatch(LAW, rearm_twice=True)
    assert not creeping.allows(POSE, GOAL, (1.37, 0.0), False, 0.000)
    assert creeping.allows(POSE, GOAL, (1.37, 0.0), False, 0.005)


def test_the_read_just_before_a_wall_comes_on_leaves_the_watch_as_it_is():
    watch = SnapWatch(LAW, rearm_twice=True)
    assert watch.still(POSE, GOAL, STILL)
    assert not watch.still(POSE, GOAL, (-1.37, 0.0))  # one velocity unit in
    assert watch.still(POSE, POSE, (-20.0, 0.0))  # no step: nothing to move in toward
    assert not watch.allows(POSE, GOAL, STILL, False, 0.000)  # still the first still read


speeds = st.floats(-100.0, 100.0, allow_nan=False)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(speeds, speeds, st.booleans(), st.floats(-0.5, 0.5)), max_size=30))
def test_property_the_watch_cuts_only_toward_the_region_and_only_when_armed(events):
    # it only says when to let go: an unarmed watch never cuts, an armed one only at a speed
    # toward the region above the threshold, and a cut always disarms it
    watch = SnapWatch(LAW)
    for k, (pan_speed, tilt_speed, engaged, torque) in enumerate(events):
        armed = watch.armed
        snapped = watch.snaps((pan_speed, tilt_speed), 0.005 * k + 0.001)
        if snapped:
            assert armed is not None and along((pan_speed, tilt_speed), armed) > 4.0
            assert watch.armed is None
        else:
            assert armed is None or watch.armed == armed
        watch.arm(POSE, GOAL, (pan_speed, tilt_speed), (torque, 0.0), engaged, 0.005 * (k + 1))


def test_a_snap_is_judged_against_the_hold_of_the_last_cycle_not_of_the_first_arming():
    """Armed on a 0.3 N m hold that then eased to 0.07 N m: a let go from the light hold (the
    leader speeding up 4.5 deg/s within a millisecond, over the 2 deg/s a 0.07 N m hold frees)
    cuts; judged against the first arming's 0.3 N m (8.6 deg/s) it would not."""
    watch = held_watch()
    watch.arm(POSE, GOAL, STILL, (-0.07, 0.0), True, 0.005)
    assert watch.armed is not None
    assert watch.snaps((-4.5, 0.0), 0.006)
    # and the other way: armed light, then held at 0.3 N m, the same rise is no let go
    watch = held_watch((-0.07, 0.0))
    watch.arm(POSE, GOAL, STILL, HELD_NM, True, 0.005)
    assert not watch.snaps((-4.5, 0.0), 0.006)
    assert watch.armed is not None
