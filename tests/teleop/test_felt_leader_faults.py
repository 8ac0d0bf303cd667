"""A felt leader whose parts fail, two- and three-servo leaders alike, over the real SDK and the
simulator's pty: a leader servo dropping off the bus mid-push switches every leader servo's
push off within one period and one failed read, and the summary names the dropout."""

from __future__ import annotations

import time

import pytest

from limbctl.servo.leader_guard import GIVE_UP_S
from tests.servo.test_leader_guard import START_S, end_pipe, torque_when_free
from tests.teleop.felt_running import Running
from tests.teleop.test_felt_leader import (
    PRESS,
    SIM,
    SIM3,
    SWING_THEN_TWIST,
    felt_session,
    truth_rows,
)

#: Each rig and the hand's press (along pan first, the edge at pan 30 deg for both regions).
RIGS = {"two-servo": (SIM, PRESS), "three-servo": (SIM3, SWING_THEN_TWIST)}
#: The simulator's leader log has one row a millisecond: a push's end is seen within it.
LOG_GRAIN_S = 0.001
PERIOD_S = 1.0 / 200.0


@pytest.mark.parametrize("rig", sorted(RIGS))
def test_a_leader_servo_dropping_off_mid_push_switches_every_push_off_and_is_reported(
    tmp_path, rig
):
    spec, press = RIGS[rig]
    ids = spec.ids
    gone, pusher = ids[-1], ids.index(ids[0])  # the last servo drops; the pan motor pushes
    with felt_session(tmp_path, spec) as (session, source, log), source:
        session.rig.set_torque(True)
        with Running(session, source) as running:
            if running.pressed_or_paced_out(press):
                return  # the feel went off for a lost pace (its outcome asserted)
            held_at = time.monotonic()
            running.until(
                lambda p: source.snap.armed is not None or time.monotonic() > held_at + 20.0
            )
            if running.paced_out():
                return
            assert source.snap.armed is not None, "the wall never held the leader still"
            at = session.simulator.truth()["leader"]["t"]
            session.simulator.vanish(gone, 0.3)
            # the vanish lands between the two reads of the simulator's clock (each a call to
            # its process: up to 12 ms apart on a loaded machine)
            landed = session.simulator.truth()["leader"]["t"]
            running.until(lambda p: session.simulator.truth()["leader"]["t"] > at + 0.5)
            felt = source.felt
        lines = source.report_lines()
        # one failed read, timed on this bus with the loop stopped (the servo gone again)
        session.simulator.vanish(gone, 0.1)
        failed = session.rig.bus.read_cycle(ids=ids, attempts=1)
        assert not failed.ok
    rows = [row for row in truth_rows(log) if row["t"] >= at]
    assert rows[0]["motor_nm"][pusher] != 0.0  # it pushed when the servo dropped off
    off = next(row["t"] for row in rows if row["motor_nm"][pusher] == 0.0)
    # one period (the cycle's work between its read and the watch's next) plus one failed read
    seen = getattr(getattr(source, "silence", None), "longest_failed_read_s", 0.0)
    bound = PERIOD_S + max(failed.duration_s, seen) + LOG_GRAIN_S
    assert off - landed <= bound, (off - landed, off - at, bound)
    # nothing pushed the hand while the servo was gone (the silent one's own push ends at its
    # Bus Watchdog, 100 ms: it hears nothing)
    during = [row for row in rows if off <= row["t"] <= at + 0.3]
    assert during and all(row["motor_nm"][pusher] == 0.0 for row in during)
    line = next(line for line in lines if line.startswith("leader dropouts"))
    assert f"servo {gone} " in line, lines
    length = float(line.split(f"servo {gone} ")[1].split(" s")[0])
    assert 0.25 <= length <= 0.45, line  # 0.3 s, known within a probe interval and a read
    assert felt or running.paced_out()


#: A dead controller's last goal lies at most LEAD plus the walking lead ahead of the leader:
#: three and two ticks on an XM430 (limbctl/teleop/haptic.py), 0.44 deg.
LAST_GOAL_AHEAD_DEG = 5 * 360.0 / 4096


def held_still(running, source, press) -> bool:
    """Press past the edge and wait (20 s at most) for the wall to hold the leader still; False
    when the loop lost its pace first (the feel then goes off for good, as it must)."""
    if running.pressed_or_paced_out(press):
        return False
    held_at = time.monotonic()
    running.until(lambda p: source.snap.armed is not None or time.monotonic() > held_at + 20.0)
    return not running.paced_out()


@pytest.mark.parametrize("rig", sorted(RIGS))
def test_a_leader_cut_off_from_its_controller_holds_within_the_cap_and_pushes_no_further(
    tmp_path, rig
):
    # the bus is cut mid-push (a pulled cable: nothing the controller, or its guard, sends
    # reaches the leader any more). Each servo's Bus Watchdog (100 ms) stops it: it holds where
    # it is (the e-Manual's "stop"; Goal Current and Goal Position read-only), with at most the
    # last push's share of the cap. The hand presses 0.3 s more, then lets go: the leader is
    # pushed no further in than its last goal and, once still, by nothing
    spec, press = RIGS[rig]
    ids = spec.ids
    with felt_session(tmp_path, spec) as (session, source, log), source:
        session.rig.set_torque(True)
        with Running(session, source) as running:
            if not held_still(running, source, press):
                return
            assert source.snap.armed is not None, "the wall never held the leader still"
            at = session.simulator.truth()["leader"]["t"]
            for servo_id in ids:
                session.simulator.vanish(servo_id, 2.0)
            target = [list(press["script"][-1][1:])]
            session.simulator.set_operator(
                {**press, "script": [[0.0, *target[0]]], "let_go_s": 0.3}
            )
            running.until(lambda p: session.simulator.truth()["leader"]["t"] > at + 1.0)
            cap = source.cap_nm
    rows = [row for row in truth_rows(log) if at <= row["t"] <= at + 1.0]
    assert max(sum(m * m for m in row["motor_nm"]) ** 0.5 for row in rows) <= cap + 1e-12
    start = rows[0]["pose_deg"]
    moved_in = max(start[0] - row["pose_deg"][0] for row in rows)  # pan toward the edge
    assert moved_in <= LAST_GOAL_AHEAD_DEG + 0.1, moved_in
    still = [row for row in rows if row["t"] >= at + 0.8]
    assert still and all(sum(abs(m) for m in row["motor_nm"]) < 0.02 for row in still), still[-1]


@pytest.mark.parametrize("rig", sorted(RIGS))
def test_a_dead_controllers_leader_goes_limp_within_its_guards_bound(tmp_path, rig, capfd):
    # the controller dies mid-push: the loop is frozen between two transfers (it holds nothing
    # more to send), and what the kernel does to a dead process is done here: its end of the
    # guard's pipe closes without "done" and its port closes (the port's lock with it). The
    # guard then switches every leader servo's torque off, and no follower servo's. The kill -9
    # of a real `limbctl teleop` is tests/servo/test_leader_guard.py's
    spec, press = RIGS[rig]
    ids = spec.ids
    with felt_session(tmp_path, spec) as (session, source, log), source:
        session.rig.set_torque(True)
        bus, follower = session.rig.bus, session.profile.ids
        with Running(session, source) as running:
            if not held_still(running, source, press):
                return
            with bus.exclusive():  # the loop stops at its next transfer
                assert source.last_push is not None and source.last_push.goal_current > 0
                died_at, guard = time.monotonic(), source._guard
                end_pipe(guard)
                bus.close()
                guard.process.wait(START_S + GIVE_UP_S)
                limp_s = time.monotonic() - died_at  # the guard's exit: it did what it could
                torque = torque_when_free(
                    bus.port_name, (*follower, *ids), time.monotonic() + START_S, bus.baud
                )
                bus.open()  # the loop goes on, to its end, on a leader whose torque is off
    assert guard.process.returncode == 0
    assert not any(torque[i] for i in ids), torque
    assert all(torque[i] for i in follower), torque  # the follower left as it was
    assert limp_s <= GIVE_UP_S, limp_s
    said = f"the controller died; Torque Enable 0 on leader servos {', '.join(map(str, ids))} "
    err = capfd.readouterr().err
    assert said in err
    line = next(line for line in err.splitlines() if said in line)
    print(f"{rig}: the controller's end to the guard's exit: {limp_s * 1e3:.1f} ms; {line}")


def test_a_passive_leader_has_no_guard(tmp_path):
    # an XL430 senses no current: torque off from the start, nothing for a guard to do
    with felt_session(tmp_path, model="xl430-w250") as (session, source, log), source:
        source.start()
        assert not source.felt and source._guard is None
