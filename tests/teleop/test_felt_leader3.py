"""A felt three-servo leader over the real SDK and the simulator's pty: the wall in swing and in
twist, its faults, a passive model.

The follower is the simulated three-servo gimbal (calib/rigs/sim3.yaml) gated by a twist region
whose edge lies near pan 30 deg and near roll 30 deg (tests/teleop/twist_square.py). The
simulator's three-servo leader (ids 4, 5, 6; firmware_sim/leader.py) is held by its operator,
whose ground truth (motor torque every 0.5-1 ms) is what the assertions read, beside what the
controller wrote.
"""

from __future__ import annotations

import json
import math
import statistics
import time
from contextlib import contextmanager

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calib.profile import default_sim_profile
from limbctl.errors import ConfigError
from limbctl.geometry.gimbal import pose_quat_scalar
from limbctl.geometry.twist import decompose_one
from limbctl.live import leader_status
from limbctl.servo.rig import Rig
from limbctl.servo.setup import configure_servos
from limbctl.session import open_rig
from limbctl.teleop.gate import Gate, GateLimits
from limbctl.teleop.haptic_push import beyond_deg, corrected_pose
from limbctl.teleop.sources import LeaderSource, SourceContext, parse_source
from limbctl.view.leader import SWING_SHARE_DRAWN
from tests.teleop.felt_running import Running as FeltRunning
from tests.teleop.felt_running import check_a_forced_pace_loss, pressing, pushed_only_when_fit
from tests.teleop.twist_square import square_region

IDS = (4, 5, 6)
#: The joints' hard limits in calib/rigs/sim3.yaml (rad): the roll joint's within +-100 deg.
LIMITS = tuple((j.min_rad, j.max_rad) for j in Rig(default_sim_profile("sim3")).joints)
HAND = {"stiffness_nm_deg": 0.05, "damping_nm_s_rad": 0.02, "max_torque_nm": 0.3}
#: In swing (pan 50: 20 deg beyond) from 0 to 3.5 s, back to the middle, then in twist (roll 50)
#: from 5.5 s on.
PRESS = {
    "script": [
        [0.0, 0.0, 0.0, 0.0],
        [1.5, 50.0, 0.0, 0.0],
        [3.5, 50.0, 0.0, 0.0],
        [4.5, 0.0, 0.0, 0.0],
        [5.5, 0.0, 0.0, 50.0],
    ],
    **HAND,
}
TWIST_PRESS = {"script": [[0.0, 0.0, 0.0, 0.0], [1.5, 0.0, 0.0, 50.0]], **HAND}
#: A hand pushing with this much (N m, toward the outside) presses: its spring stretched by 1 deg.
PRESSING_NM = HAND["stiffness_nm_deg"] * 1.0


@contextmanager
def felt3_session(tmp_path, model="xm430-w350", rate_hz=25.0):
    """An open three-servo rig with a three-servo leader; yields (session, source, log path).

    ``rate_hz`` is what the source checks its start and pace against: 25 Hz, as the two-servo
    leader's tests (tests/teleop/test_felt_leader.py) for a busy shared machine; the loop
    itself runs at 200 Hz."""
    region = square_region()
    log = tmp_path / "leader.jsonl"
    leader = {"ids": list(IDS), "model": model, "log": str(log)}
    with open_rig(rig_path="sim3", extra_ids=IDS, sim_options={"leader": leader}) as session:
        rig, profile = session.rig, session.profile
        configure_servos(rig.bus, {**rig.tick_limits(), **dict.fromkeys(IDS, (0, 4095))})
        source = parse_source("leader:4,5,6").open(SourceContext(rig=rig, rate_hz=rate_hz))
        assert isinstance(source, LeaderSource)
        limits = GateLimits.for_profile(profile, math.radians(120) / 200, math.radians(1.8))
        session.gate = Gate(region, limits)
        yield session, source, log


class Running3(FeltRunning):
    """:class:`tests.teleop.felt_running.Running` that also keeps the leader's pose each push was
    made from (``poses``)."""

    ids = IDS

    def __init__(self, session, source) -> None:
        self.poses = []
        super().__init__(session, source)

    def kept(self, cycle) -> None:
        self.poses.append(self.source.last_pose)


def truth_rows(log):
    return [json.loads(line) for line in log.read_text().splitlines()]


def cap_of(source) -> float:
    motor = source.motor
    return motor.torque_of(motor.units_for(motor.cap_nm(source.law.cap_nm)))


def beyond(row) -> float:
    q = pose_quat_scalar(*np.radians(row["pose_deg"]))
    return beyond_deg(q, square_region().correct(q), 3)


def test_the_three_servo_leader_is_held_at_the_edge_in_swing_and_in_twist(tmp_path):
    with felt3_session(tmp_path) as (session, source, log), source:
        cap = cap_of(source)
        session.rig.set_torque(True)
        with Running3(session, source) as running:
            session.simulator.set_operator(PRESS)
            running.until(lambda p: session.simulator.truth()["leader"]["t"] > 0 and len(p) > 0)
            start, wall = session.simulator.truth()["leader"]["t"], time.monotonic()
            running.until(
                lambda p: session.simulator.truth()["leader"]["t"] > start + 8.0 or not p[-1][2]
            )
            if running.paced_out():  # the feel went off for good, as it must
                return
        lines = source.report_lines()

    def kept(sim_from: float, sim_to: float) -> bool:  # the simulator runs on the wall clock
        since, until = wall + sim_from - start, wall + sim_to - start
        return running.kept_pace(since, until) and running.unreleased(since, until)

    assert "three servos" in lines[0] and "pressed beyond the edge for" in lines[1]
    rows = truth_rows(log)
    region = square_region()
    # each press's last second: held beyond the edge. Under 2 deg of rotation when the loop kept
    # the rate the wall is passive at (a median period within the pace watch's 1.25 periods
    # at 200 Hz; the law at exactly 200 Hz: tests/teleop/test_haptic.py); a starved loop (a
    # sampled wall under its passivity bound, and failed reads that release the leader) lets
    # the hand take it further, as with two servos (docs/haptic.md)
    for window, joint in (((2.5, 3.5), 0), ((7.0, 8.0), 2)):
        held = [r for r in rows if start + window[0] <= r["t"] < start + window[1]]
        distance = statistics.median(beyond(r) for r in held[::5])
        paced = kept(start + window[0], start + window[1])
        assert 0.4 < distance and (distance < 2.0 or not paced), (joint, distance)
        assert statistics.median(r["pose_deg"][joint] for r in held) > 29.0
    assert max(abs(m) for r in rows for m in r["motor_nm"]) <= cap + 1e-12
    # every cycle whose command was inside wrote no current on any of the three servos
    inside = [push for _, push, _ in running.pushes if push is not None and push.distance_deg == 0]
    assert inside and all(push.goal_current == 0 for push in inside)
    # in the ground truth, well inside (every joint 5 deg inside the taught square and band,
    # further than a hand moves the leader in a cycle) the motors apply nothing at all
    well_inside = [
        r for r in rows if all(abs(a) < b for a, b in zip(r["pose_deg"], (25, 20, 25), strict=True))
    ]
    assert well_inside and all(r["motor_nm"] == [0.0, 0.0, 0.0] for r in well_inside)
    # every push's goals lie from the pose it read toward that pose's correction
    leads = []
    for (_, push, _), pose in zip(running.pushes, running.poses, strict=True):
        if push is not None and push.goal_current:
            corrected = region.correct(pose_quat_scalar(*pose))
            way = np.subtract(corrected_pose(corrected, pose, LIMITS), pose)
            leads.append(float(np.dot(np.subtract(push.goal, pose), way)))
    assert len(leads) > 100 and min(leads) > 0.0
    # pressed outward beyond the edge, the joint torques point toward the corrected pose: the
    # wall's physics, which holds while the loop keeps the rate the wall is passive at (a
    # slower sampled wall rings; the source's pace watch at the real rate turns it off). Judged
    # on every such 5 ms row the run gave, however few a busy machine left; the presses
    # themselves (the motors pushing beyond the edge against the hand) must be there. Pressed:
    # the hand pushes outward with PRESSING_NM or more (a hand resting near where it means the
    # leader, the wall walking it back, is the let go: docs/haptic.md, not done).
    pressed, dots = 0, []
    for r in rows[::5]:
        present = tuple(np.radians(r["pose_deg"]))
        q = pose_quat_scalar(*present)
        if beyond_deg(q, region.correct(q), 3) < 0.5 or not any(r["motor_nm"]):
            continue
        way = np.subtract(corrected_pose(region.correct(q), present, LIMITS), present)
        if float(np.dot(r["hand_nm"], way / np.linalg.norm(way))) <= -PRESSING_NM:
            pressed += 1
            if kept(r["t"] - 0.2, r["t"]):
                dots.append((float(np.dot(r["motor_nm"], way)), r["t"] - start, r))
    assert pressed > 50
    outward = [(round(t, 3), row) for dot, t, row in dots if dot <= 0.0]
    assert not outward, (len(dots), outward)


def test_a_restart_of_the_roll_servo_ends_the_feel_on_all_three_and_mirroring_goes_on(tmp_path):
    with felt3_session(tmp_path) as (session, source, log), source:
        session.rig.set_torque(True)
        with Running3(session, source) as running:
            if running.pressed_or_paced_out(TWIST_PRESS):
                return
            session.simulator.restart(IDS[2])
            running.until(lambda p: not p[-1][2])
            lost = len(running.pushes)
            running.until(lambda p: len(p) > lost + 50)
            accepted = source.stats.accepted
            running.until(lambda p: len(p) > lost + 100)
            truth = session.simulator.truth()
    assert truth["servos"][IDS[0]]["torque_on"] is False
    assert truth["servos"][IDS[1]]["torque_on"] is False
    assert truth["leader"]["motor_nm"] == [0.0, 0.0, 0.0]
    assert source.stats.accepted > accepted  # still mirrored, without feel
    notes = [n for c, _, _ in running.pushes for n in c.notices]
    assert any("servo 6 restarted" in n and "without feel" in n for n in notes)


def test_an_alarm_switches_the_push_off_and_the_session_faults(tmp_path):
    with felt3_session(tmp_path) as (session, source, log), source:
        session.rig.set_torque(True)
        with Running3(session, source) as running:
            if running.pressed_or_paced_out(TWIST_PRESS):
                return
            session.simulator.set_temperature(IDS[2], 95.0)  # overheating shuts it down
            running.thread.join(timeout=20.0)
            truth = session.simulator.truth()
    summary = running.out["s"]
    assert summary.exit_code == 3 and "servo 6" in summary.fault
    assert not source.felt and any("alarm" in event for event in source.feel_stats.events)
    assert truth["leader"]["motor_nm"] == [0.0, 0.0, 0.0]


def test_a_failed_bus_switches_the_push_off_in_that_cycle_and_it_comes_back(tmp_path):
    with felt3_session(tmp_path) as (session, source, log), source:
        session.rig.set_torque(True)
        with Running3(session, source) as running:
            if running.pressed_or_paced_out(TWIST_PRESS):
                return
            session.simulator.set_faults(drop=1.0)  # every reply lost: reads fail, writes land
            running.until(lambda p: sum(1 for c, _, _ in p[-5:] if c.present is None) == 5)
            during = session.simulator.truth()["leader"]["motor_nm"]
            session.simulator.set_faults(drop=0.0)
            # pushing again; or, on a busy machine, the loop ended by 20 failed cycles in a row
            # (its own bus rule) or its lost pace switched the feel off
            running.until(
                lambda p: (
                    (p[-1][1] is not None and p[-1][1].goal_current > 0)
                    or running.ended
                    or not p[-1][2]
                )
            )
    assert during == [0.0, 0.0, 0.0]
    # each cycle whose reads failed wrote no current (released, or a push of 0), from the first
    # on; a cycle whose follower read failed and whose leader read did not (the fault lifting
    # between the two) may keep the wall within FOLLOWER_GRACE_S, and no other
    failed = [push for cycle, push, _ in running.pushes if cycle.complete and cycle.present is None]
    assert failed and sum(1 for push in failed if push is None or push.goal_current == 0) >= 5
    pushed_only_when_fit(running.pushes)


def test_a_silent_leader_is_bounded_by_its_cap_and_is_re_armed(tmp_path):
    with felt3_session(tmp_path) as (session, source, log), source:
        cap = cap_of(source)
        session.rig.set_torque(True)
        with Running3(session, source) as running:
            if running.pressed_or_paced_out(TWIST_PRESS):
                return
            session.simulator.vanish(IDS[2], 0.3)  # past its 100 ms watchdog
            running.until(lambda p: p[-1][1] is None)
            running.until(
                lambda p: (p[-1][1] is not None and p[-1][1].goal_current > 0) or not p[-1][2]
            )
            # back, its watchdog cleared and armed again, pushing; or the pace went meanwhile
            felt = source.felt or running.paced_out()
    rows = truth_rows(log)
    assert max(abs(m) for r in rows for m in r["motor_nm"]) <= cap + 1e-12
    assert felt


def test_the_session_end_leaves_all_three_limp(tmp_path):
    with felt3_session(tmp_path) as (session, source, log):
        with source:
            session.rig.set_torque(True)
            with Running3(session, source) as running:
                if running.pressed_or_paced_out(TWIST_PRESS):
                    return
            ended = session.simulator.truth()  # the loop's end released it: no current
        closed = session.simulator.truth()  # the source's close: torque off
    assert running.out["s"].exit_code == 0
    assert ended["leader"]["motor_nm"] == [0.0, 0.0, 0.0]
    assert all(closed["servos"][i]["torque_on"] is False for i in IDS)


def test_an_xl430_three_servo_leader_stays_passive_and_says_so(tmp_path):
    with felt3_session(tmp_path, model="xl430-w250") as (session, source, log), source:
        assert not source.felt and "stays passive" in source.notice
        [command] = source.poll()
        assert source.last_pose is not None
        np.testing.assert_allclose(command.q, pose_quat_scalar(*source.last_pose), atol=1e-12)
        shown = leader_status(source)()  # what the live page is handed
    _, twist = decompose_one(command.q)
    assert shown.twist_deg == pytest.approx(math.degrees(twist))
    assert shown.toward_twist_deg is None and shown.cap_nm is None


@pytest.mark.parametrize("model", ["xl330-m288"])
def test_an_xl330_three_servo_leader_feels_the_twist_edge(tmp_path, model):
    with felt3_session(tmp_path, model=model) as (session, source, log), source:
        cap = cap_of(source)
        assert "XL330" in source.notice and "feels the edge" in source.notice
        session.rig.set_torque(True)
        with Running3(session, source) as running:
            session.simulator.set_operator(TWIST_PRESS)
            running.until(pressing)
            seen = []  # what the live page is handed, cycle by cycle, until it shows the push

            def shown_pushing(_) -> bool:
                pushed = (source.last_push, source.last_pose)  # what the status is made of
                seen.append((leader_status(source)(), *pushed))
                return seen[-1][0].state == "pushing back" or not source.felt

            running.until(shown_pushing)
            if running.paced_out():
                return
            shown, push, pose = seen[-1]  # pushed in twist: its twist parts
    assert shown.state == "pushing back"
    # an arrow on the plane only for a push whose swing part is a tenth of it or more: the wall
    # pushes along its normal, so pan and tilt get their share of the current, and a leader the
    # hand let drift a few tenths of a degree in pan is pushed back in swing too
    swing = math.hypot(push.goal[0] - pose[0], push.goal[1] - pose[1])
    drawn = swing >= SWING_SHARE_DRAWN * max(swing, abs(push.goal[2] - pose[2]))
    assert (shown.toward is not None) == drawn
    assert shown.twist_deg > 29.0 and shown.toward_twist_deg < shown.twist_deg
    rows = truth_rows(log)
    pushed = [abs(r["motor_nm"][2]) for r in rows if r["pose_deg"][2] > 31.0]
    assert pushed and max(pushed) > 0.5 * cap
    assert max(abs(m) for r in rows for m in r["motor_nm"]) <= cap + 1e-12


def test_a_lost_pace_switches_the_feel_off_for_good_in_its_cycle_and_mirroring_goes_on(tmp_path):
    with felt3_session(tmp_path) as (session, source, log), source:
        check_a_forced_pace_loss(session, source, Running3, TWIST_PRESS)


FAULTS = {
    "silence": lambda sim: sim.vanish(IDS[2], 0.2),
    "restart": lambda sim: sim.restart(IDS[0]),
    "alarm": lambda sim: sim.set_temperature(IDS[1], 95.0),
    "bus": lambda sim: sim.set_faults(drop=1.0),
}


@settings(
    max_examples=4,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(
    targets=st.lists(
        st.tuples(st.floats(-20.0, 60.0), st.floats(-20.0, 35.0), st.floats(-60.0, 60.0)),
        min_size=2,
        max_size=3,
    ),
    fault=st.sampled_from(sorted(FAULTS)),
    after=st.integers(20, 200),
)
def test_property_random_streams_and_faults_never_above_the_cap_off_at_once(
    tmp_path_factory, targets, fault, after
):
    """Random operator streams over all three joints with one injected fault: never above the
    cap, and a cycle pushes only when the leader was read, fit to push, and the gate ran on a
    good read (so after any fault the push is off in the cycle that saw it)."""
    tmp_path = tmp_path_factory.mktemp("felt3")
    script = [[0.8 * k, *pose] for k, pose in enumerate([(0.0, 0.0, 0.0), *targets])]
    with felt3_session(tmp_path) as (session, source, log), source:
        cap = cap_of(source)
        session.rig.set_torque(True)
        with Running3(session, source) as running:
            session.simulator.set_operator({"script": script, **HAND})
            running.until(lambda p: len(p) >= after)
            FAULTS[fault](session.simulator)
            seen = len(running.pushes)
            running.until(lambda p: len(p) > seen + 100 or running.ended)
            session.simulator.set_faults(drop=0.0)
    rows = truth_rows(log)
    assert max(abs(m) for r in rows for m in r["motor_nm"]) <= cap + 1e-12
    pushed_only_when_fit(running.pushes)


def test_at_the_real_rate_the_wall_holds_or_its_feel_goes_off_for_good(tmp_path):
    """The source watching the loop's pace at 200 Hz, as `limbctl teleop` does: either the loop
    keeps the rate and the pressed leader is held within 2 deg of the twist edge, or the start
    refuses (leaving the leader limp), or the pace watch switches the push off for good and
    from then on the motors apply nothing."""
    with felt3_session(tmp_path, rate_hz=200.0) as (session, source, log):
        try:
            source.start()
        except ConfigError as exc:
            assert "lower --rate" in str(exc)
            assert not any(session.rig.bus.torque_enabled()[i] for i in IDS)
            return
        try:
            session.rig.set_torque(True)
            with Running3(session, source) as running:
                session.simulator.set_operator(TWIST_PRESS)
                start = session.simulator.truth()["leader"]["t"]
                running.until(lambda p: session.simulator.truth()["leader"]["t"] > start + 4.0)
                truth = session.simulator.truth()
                lost = running.paced_out()  # if so, asserts the outcome cycle by cycle
        finally:
            source.close()
    if lost:
        assert truth["leader"]["motor_nm"] == [0.0, 0.0, 0.0]
        assert not any(truth["servos"][i]["torque_on"] for i in IDS)
    else:
        held = [r for r in truth_rows(log) if start + 3.0 <= r["t"] < start + 4.0]
        assert 0.4 < statistics.median(beyond(r) for r in held[::5]) < 2.0
