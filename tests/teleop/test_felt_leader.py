"""A passive or felt leader over the real SDK and the simulator's pty, on two servos and three:
the edge at pan 30 deg (on three also roll 30, twist_square.py), judged on the 1 ms ground truth."""

from __future__ import annotations

import functools
import json
import math
import statistics
import time
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass, replace

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from limbctl.envelope import Cone
from limbctl.errors import BusTimeout, ConfigError, CorruptReply
from limbctl.geometry.gimbal import pose_quat, pose_quat_scalar
from limbctl.geometry.twist import decompose_one
from limbctl.live import leader_status
from limbctl.servo.control_table import Register
from limbctl.servo.leader import encode_feel, present_current, present_velocity
from limbctl.servo.leader_guard import GIVE_UP_S
from limbctl.servo.setup import configure_servos
from limbctl.session import open_rig
from limbctl.teleop.gate import Gate, GateLimits
from limbctl.teleop.haptic import VELOCITY_UNIT_DEG_S
from limbctl.teleop.haptic_push import corrected_pose
from limbctl.teleop.pacing import PaceWatch
from limbctl.teleop.sources import LeaderSource, SourceContext, parse_source
from limbctl.teleop.sources.leader_snap import cycle_velocity, read_motion
from limbctl.view.leader import SWING_SHARE_DRAWN
from tests.servo.test_leader_guard import START_S, end_pipe, torque_when_free
from tests.teleop.chains import off_axis_deg
from tests.teleop.felt_running import Running, pressing, pushed_only_when_fit
from tests.teleop.stepped_leader import beyond_of, limits_of, way_of
from tests.teleop.twist_square import square_region

EDGE = 30.0
HAND = {"stiffness_nm_deg": 0.05, "damping_nm_s_rad": 0.02, "max_torque_nm": 0.3}
#: Two servos: the hand means the leader 20 deg beyond the edge in pan.
PRESS = {"script": [[0.0, 0.0, 0.0], [1.5, EDGE + 20.0, 0.0]], **HAND}
#: Three servos: 20 deg beyond the edge in twist (roll 50).
TWIST_PRESS = {"script": [[0.0, 0.0, 0.0, 0.0], [1.5, 0.0, 0.0, EDGE + 20.0]], **HAND}
#: Three servos: in swing (pan 50) to 3.5 s, back to the middle, in twist (roll 50) from 5.5 s.
SWING_THEN_TWIST = {
    "script": [[0.0, 0, 0, 0], [1.5, 50, 0, 0], [3.5, 50, 0, 0], [4.5, 0, 0, 0], [5.5, 0, 0, 50]],
    **HAND,
}
#: A hand pushing with this much (N m, toward the outside) presses: its spring stretched by 1 deg.
PRESSING_NM = HAND["stiffness_nm_deg"] * 1.0
#: A hold is judged strictly only with no release for this long (s) before: 20 deg walked back.
WALKED_BACK_S = 1.5


@dataclass(frozen=True)
class FeltRig:
    """A follower rig, its leader's ``ids``, ``region``, ``press`` 20 deg beyond along ``joint``."""

    profile: str
    ids: tuple[int, ...]
    region: Callable[[], object]
    press: dict
    joint: int

    @property
    def pusher(self) -> int:
        return self.ids[self.joint]


SIM = FeltRig("sim", (3, 4), lambda: Cone(half_angle_deg=EDGE), PRESS, 0)
SIM3 = FeltRig("sim3", (4, 5, 6), square_region, TWIST_PRESS, 2)
#: The two-servo leader's ids (benchmarks).
IDS = SIM.ids


@pytest.fixture(params=[SIM, SIM3], ids=["sim", "sim3"])
def rig(request) -> FeltRig:
    return request.param


@contextmanager
def felt_session(tmp_path, rig: FeltRig = SIM, model="xm430-w350", rate_hz=25.0):
    """An open ``rig`` with its leader, configured and gated; yields (session, source, log path).
    At 25 Hz a busy machine neither refuses the start nor loses the pace (200 Hz: test_haptic)."""
    log = tmp_path / "leader.jsonl"
    leader = {"ids": list(rig.ids), "model": model, "log": str(log)}
    with open_rig(rig_path=rig.profile, extra_ids=rig.ids, sim_options={"leader": leader}) as s:
        bus = s.rig.bus
        configure_servos(bus, {**s.rig.tick_limits(), **dict.fromkeys(rig.ids, (0, 4095))})
        spec = "leader:" + ",".join(map(str, rig.ids))
        source = parse_source(spec).open(SourceContext(rig=s.rig, rate_hz=rate_hz))
        assert isinstance(source, LeaderSource)
        step = math.radians(120.0) / 200.0  # 120 deg/s at 200 Hz
        region = rig.region()
        s.gate = Gate(region, GateLimits.for_profile(s.profile, step, 3.0 * step))
        # the region's kernels compiled before the hand moves, as `limbctl teleop` does
        for pose in ((0.0,) * len(rig.ids), (60.0,) + (0.0,) * (len(rig.ids) - 1)):
            q = pose_quat(*pose)
            region.contains(q), region.correct(q)
            region.contains(q[None]), region.correct(q[None])
        yield s, source, log


@contextmanager
def running_felt(tmp_path, rig: FeltRig = SIM, **options):
    """:func:`felt_session`, torque on, the loop in :class:`Running`: yields those and it."""
    with felt_session(tmp_path, rig, **options) as (session, source, log), source:
        session.rig.set_torque(True)
        with Running(session, source) as running:
            yield session, source, log, running


def truth_rows(log):
    return [json.loads(line) for line in log.read_text().splitlines()]


def cap_of(source) -> float:
    motor = source.motor
    return motor.torque_of(motor.units_for(motor.cap_nm(source.law.cap_nm)))


def test_the_leader_stops_near_the_edge_free_inside_never_above_the_cap(tmp_path, rig):
    """Two servos pressed 20 deg beyond in pan, three in swing then in twist (SWING_THEN_TWIST):
    held near the edge, no current for a command inside, never above the cap, and the motors
    never pulling the pressed leader outward while the loop keeps its rate."""
    with running_felt(tmp_path, rig) as (session, source, log, running):
        cap = cap_of(source)
        if rig is SIM:
            if running.pressed_or_paced_out(PRESS):  # the feel went off for good, as it must
                return
            seen, pressed_at = len(running.pushes), time.monotonic()

            def a_paced_second(p) -> bool:
                """300 more pressed cycles whose last second kept the rate unreleased, or 15 s."""
                now = time.monotonic()
                clean = running.kept_pace(now - 1.0, now) and running.unreleased(
                    now - 1.0 - WALKED_BACK_S, now
                )
                return len(p) > seen + 300 and (clean or now > pressed_at + 15.0 or not p[-1][2])

            running.until(a_paced_second)
            now, wall = session.simulator.truth()["leader"]["t"], time.monotonic()
        else:
            session.simulator.set_operator(SWING_THEN_TWIST)
            running.until(lambda p: session.simulator.truth()["leader"]["t"] > 0 and len(p) > 0)
            start, wall = session.simulator.truth()["leader"]["t"], time.monotonic()
            running.until(
                lambda p: session.simulator.truth()["leader"]["t"] > start + 8.0 or not p[-1][2]
            )
        if running.paced_out():  # the feel went off for good, as it must
            return
    lines = source.report_lines()

    kept = functools.partial(running.kept_sim, now if rig is SIM else start, wall)
    said = "feels the edge" if rig is SIM else "three servos"
    assert said in lines[0] and "pressed beyond the edge for" in lines[1]
    rows = truth_rows(log)
    assert max(abs(m) for row in rows for m in row["motor_nm"]) <= cap + 1e-12
    # every cycle whose command was inside wrote no current at all, on any servo
    inside = [push for _, push, _ in running.pushes if push is not None and push.distance_deg == 0]
    assert inside and all(push.goal_current == 0 for push in inside)
    if rig is SIM:
        # held within 10 deg while the loop kept the rate unreleased (a starved loop yields more)
        held = statistics.median(row["pose_deg"][0] for row in rows if now - 1.0 <= row["t"] <= now)
        paced = kept(now - 1.0, now, now - 1.0 - WALKED_BACK_S)
        assert EDGE < held and (held < EDGE + 10.0 or not paced), held
        # pressed outside, the motor never pulls pan outward while the loop keeps its rate
        pressed = [
            row
            for row in rows
            if row["pose_deg"][0] > EDGE + 0.5 and row["hand_nm"][0] >= PRESSING_NM
        ]
        paced = [row for row in pressed if kept(row["t"] - 0.2, row["t"])]
        outward = [row for row in paced if row["motor_nm"][0] > 0.0]
        assert pressed and not outward, (len(pressed), len(paced), outward[:5])
        return
    region = square_region()
    # each press's last second: held beyond the edge, within HELD_WITHIN as the law reads it
    # when the loop kept the rate unreleased since the press crossed it (pan at 0.9 s, roll at
    # 5.1 s); the truth within the encoders' rounding of that, half a tick on each joint
    within = source.law.held_within_deg
    for crossed, window, joint in ((0.9, (2.5, 3.5), 0), (5.1, (7.0, 8.0), 2)):
        held = [r for r in rows if start + window[0] <= r["t"] < start + window[1]]
        distance = statistics.median(beyond_of(region, r) for r in held[::5])
        read = statistics.median(
            push.distance_deg
            for (_, push, _), t in zip(running.pushes, running.clock, strict=True)
            if push is not None and wall + window[0] <= t < wall + window[1]
        )
        paced = kept(start + window[0], start + window[1], start + crossed)
        assert 0.4 < distance and (read < within or not paced), (joint, read)
        assert distance < within + 3 * 180.0 / 4096 or not paced, (joint, distance)
        assert statistics.median(r["pose_deg"][joint] for r in held) > 29.0
    # well inside (every joint 5 deg in) the motors apply nothing at all
    well_inside = [
        r for r in rows if all(abs(a) < b for a, b in zip(r["pose_deg"], (25, 20, 25), strict=True))
    ]
    assert well_inside and all(r["motor_nm"] == [0.0, 0.0, 0.0] for r in well_inside)
    # every push's goals lie from the pose it read toward that pose's correction
    leads = []
    for (_, push, _), pose in zip(running.pushes, running.poses, strict=True):
        if push is not None and push.goal_current:
            corrected = region.correct(pose_quat_scalar(*pose))
            way = np.subtract(corrected_pose(corrected, pose, limits_of(3)), pose)
            leads.append(float(np.dot(np.subtract(push.goal, pose), way)))
    assert len(leads) > 100 and min(leads) > 0.0
    # pressed outward beyond the edge, the torques point toward the correction while paced
    pressed, dots = 0, []
    for r in rows[::5]:
        if beyond_of(region, r) < 0.5 or not any(r["motor_nm"]):
            continue
        way = way_of(region, r)
        if float(np.dot(r["hand_nm"], way / np.linalg.norm(way))) <= -PRESSING_NM:
            pressed += 1
            if kept(r["t"] - 0.2, r["t"]):
                dots.append((float(np.dot(r["motor_nm"], way)), r["t"] - start, r))
    assert pressed > 50
    outward = [(round(t, 3), row) for dot, t, row in dots if dot <= 0.0]
    assert not outward, (len(dots), outward)


def test_a_failed_bus_or_a_held_gate_switches_the_push_off_in_that_cycle_an_alarm_on_every_servo(
    tmp_path, rig
):
    """Every reply lost: no current in that cycle. Pushing again once the bus answers, an alarm
    (overheating) faults the session: the push off on every servo, as if passive."""
    with running_felt(tmp_path, rig) as (session, source, log, running):
        if running.pressed_or_paced_out(rig.press):
            return
        session.simulator.set_faults(drop=1.0)  # every reply lost: reads fail, writes land
        running.until(lambda p: sum(1 for c, _, _ in p[-5:] if c.present is None) == 5)
        during = session.simulator.truth()["leader"]["motor_nm"]
        session.simulator.set_faults(drop=0.0)
        # pushing again, or the loop ended (20 failed cycles) or lost its pace
        running.until(
            lambda p: (
                (p[-1][1] is not None and p[-1][1].goal_current > 0)
                or running.ended
                or not p[-1][2]
            )
        )
        alarmed = not running.ended and source.felt  # else no push is left for an alarm to end
        if alarmed:
            session.simulator.set_temperature(rig.pusher, 95.0)  # overheating shuts it down
            running.thread.join(timeout=20.0)
            truth = session.simulator.truth()
    assert during == [0.0] * len(rig.ids)
    # each cycle whose reads failed wrote no current (but within FOLLOWER_GRACE_S, leader read)
    failed = [push for cycle, push, _ in running.pushes if cycle.complete and cycle.present is None]
    assert failed and sum(1 for push in failed if push is None or push.goal_current == 0) >= 5
    pushed_only_when_fit(running.pushes)
    if not alarmed:  # the loop ended, or the feel went off for a lost pace (its outcome asserted)
        assert running.ended or running.paced_out()
        return
    # the cycle that saw the alarm switched the push off; the other servos' torque is off too
    assert all(truth["servos"][i]["torque_on"] is False for i in rig.ids if i != rig.pusher)
    assert truth["leader"]["motor_nm"] == [0.0] * len(rig.ids)
    summary = running.out["s"]
    assert summary.exit_code == 3 and f"servo {rig.pusher}" in summary.fault
    assert not source.felt and any("alarm" in event for event in source.feel_stats.events)


def test_a_leader_unheard_past_its_watchdog_still_pushes_and_the_end_leaves_it_limp(tmp_path, rig):
    """Unheard past its watchdog at set-up or silent mid-push, it pushes again within the cap;
    then restarted, the push goes off on every servo and mirroring goes on without feel."""
    with felt_session(tmp_path, rig) as (session, source, log):
        with source:
            cap = cap_of(source)
            session.rig.set_torque(True)
            # past the Bus Watchdog (100 ms) armed at set-up: the loop must clear it
            time.sleep(0.3)
            with Running(session, source) as running:
                if running.pressed_or_paced_out(rig.press):
                    return
                session.simulator.vanish(rig.pusher, 0.3)  # silent past its 100 ms watchdog
                running.until(lambda p: p[-1][1] is None)
                running.until(
                    lambda p: (p[-1][1] is not None and p[-1][1].goal_current > 0) or not p[-1][2]
                )
                back = session.simulator.truth()
                # back, its watchdog cleared and armed again, pushing; or the pace went meanwhile
                felt = source.felt or running.paced_out()
                restarted = source.felt  # else the feel is off for good (its outcome asserted)
                if restarted:
                    session.simulator.restart(rig.pusher)
                    running.until(lambda p: not p[-1][2])
                    lost = len(running.pushes)
                    running.until(lambda p: len(p) > lost + 50)
                    accepted = source.stats.accepted
                    running.until(lambda p: len(p) > lost + 100)
                    truth = session.simulator.truth()
            ended = session.simulator.truth()  # the loop's end released it: no current
        closed = session.simulator.truth()  # the source's close: torque off
    rows = truth_rows(log)
    assert max(abs(r["motor_nm"][rig.joint]) for r in rows) > 0.5 * cap
    assert back["servos"][rig.pusher]["present"] and felt
    assert max(abs(m) for row in rows for m in row["motor_nm"]) <= cap + 1e-12
    assert running.out["s"].exit_code == 0
    assert ended["leader"]["motor_nm"] == [0.0] * len(rig.ids)
    assert all(closed["servos"][i]["torque_on"] is False for i in rig.ids)
    if not restarted:
        return
    # the cycle that saw the restart switched the push off; the other servos' torque is off too
    assert all(truth["servos"][i]["torque_on"] is False for i in rig.ids if i != rig.pusher)
    assert truth["leader"]["motor_nm"] == [0.0] * len(rig.ids)
    assert source.stats.accepted > accepted  # still mirrored, without feel
    notes = [n for c, _, _ in running.pushes for n in c.notices]
    said = f"servo {rig.pusher} restarted"
    assert any(said in n and "mirroring goes on without feel" in n for n in notes), notes
    assert any("without feel" in line for line in source.report_lines())


def plain_read(bus, register: Register, servo_id: int) -> int | None:
    """A register read by the test as a check on the cycle's; None where a loaded machine kept
    the simulator from answering in time (the check then samples again)."""
    try:
        return bus.read(register, servo_id)
    except (BusTimeout, CorruptReply):
        return None


def test_a_felt_leaders_cycle_read_carries_its_present_velocity(tmp_path):
    """The cycle's read carries Present Velocity (in Goal Position's slot); it and the watch's
    read carry Present Current (round 5)."""
    with felt_session(tmp_path) as (session, source, log), source:
        bus = session.rig.bus
        # no loop runs here: the test's reads stand in for it, and a loaded machine may space
        # them past the 100 ms Bus Watchdog, which would then refuse the feel written below
        for servo_id in IDS:
            bus.write(Register.BUS_WATCHDOG, servo_id, 0)
        session.simulator.set_operator(PRESS)  # the hand carries the free leader out
        deadline, triples = time.monotonic() + 5.0, []
        while time.monotonic() < deadline and len(triples) < 5:
            before = plain_read(bus, Register.PRESENT_VELOCITY, IDS[0])
            read = bus.read_cycle(ids=IDS, attempts=2)
            after = plain_read(bus, Register.PRESENT_VELOCITY, IDS[0])
            if None in (before, after) or not read.ok:
                continue
            if min(before, after) > 3:  # moving: a few units or more
                triples.append((before, present_velocity(read.reports[IDS[0]]), after))
        assert len(triples) == 5
        # read between two plain reads of a leader the hand speeds up (or slows): between them,
        # give or take the few units a millisecond's change makes, however far apart a loaded
        # machine spaces the reads
        assert all(min(b, a) - 3 <= cycle <= max(b, a) + 3 for b, cycle, a in triples)
        speed = cycle_velocity(read, IDS, session.rig.joints)[0]
        assert speed * session.rig.joints[0].direction > 0.0
        # the hand presses against a 40 unit motor whose goal is pan 0: it pulls at that current
        units, goal = 40, session.rig.angles_to_ticks(0.0, 0.0)[0]
        session.simulator.set_operator(PRESS)
        bus.write_block(source._feel_block, IDS[0], encode_feel(units, goal))
        deadline, both = time.monotonic() + 5.0, None
        while time.monotonic() < deadline and both is None:
            read = bus.read_cycle(ids=IDS, attempts=2)
            plain = plain_read(bus, Register.PRESENT_CURRENT, IDS[0])
            cycle = present_current(read.reports[IDS[0]]) if read.ok else None
            # the current leaves the clip as the pull wins over the hand: judged where both
            # reads find it at the clip
            if cycle is not None and plain is not None and abs(cycle) == units:
                both = (cycle, plain) if abs(plain) == units else None
        assert both is not None and abs(both[0]) == units == abs(both[1])
        # toward pan 0 (pan decreasing) in the joint's frame
        assert read.ok and source._torque(read)[0] == pytest.approx(-source.motor.torque_of(units))
        deadline, motion = time.monotonic() + 5.0, None
        while time.monotonic() < deadline:
            before = plain_read(bus, Register.PRESENT_VELOCITY, IDS[0])
            motion = read_motion(bus, IDS, session.rig.joints, source.motor)
            after = plain_read(bus, Register.PRESENT_VELOCITY, IDS[0])
            if None in (before, after) or motion is None:
                continue
            if abs(motion[1][0]) == source.motor.torque_of(units):
                break
        assert motion is not None and None not in (before, after)
        speeds, torques = motion
        # toward pan 0 in the joint's frame, at the Goal Current's clip
        assert torques[0] == pytest.approx(-source.motor.torque_of(units))
        assert torques[1] == 0.0  # the tilt servo has no current
        # between the plain reads before and after it, give or take a few units
        units_read = speeds[0] * session.rig.joints[0].direction / VELOCITY_UNIT_DEG_S
        assert min(before, after) - 3 <= units_read <= max(before, after) + 3


def test_a_held_leader_let_go_or_pulled_back_inside_is_freed_before_it_is_braked(tmp_path):
    """Held still, then the hand is gone: the watch cuts the snap at once; held again, then pulled
    inside faster than the setpoint walks: freed (judged where no cycle stalled). Never a push
    inside."""
    with running_felt(tmp_path) as (session, source, log, running):
        gone = {"script": [[0.0, EDGE + 20.0, 0.0]], "let_go_s": 0.0}
        let_go_at = running.held_then(PRESS, gone)
        if let_go_at is None:
            return  # the feel went off for a lost pace (its outcome asserted)
        let_go_wall = running.switched_wall
        cuts, freed = source.snap.cuts, source.snap.brakes + source.snap.cuts
        pressed_again_at = session.simulator.truth()["leader"]["t"]
        gone_steady = running.unstalled(let_go_wall, time.monotonic())
        pull = [[0.0, EDGE + 20.0, 0.0], [0.2, 0.0, 0.0]]  # from the switch on
        now = running.held_then(PRESS, {"script": pull, **HAND})
        pull_steady = now is not None and running.unstalled(running.switched_wall, time.monotonic())
    rows = truth_rows(log)
    assert not gone_steady or cuts >= 1, "let go: the watch never cut"
    after = [r for r in rows if let_go_at <= r["t"] < pressed_again_at]
    assert after and min(r["pose_deg"][0] for r in after) > EDGE, "let go: walked inside"
    assert all(r["motor_nm"] == [0.0, 0.0] for r in after if r["pose_deg"][0] < EDGE)
    if now is None:
        return  # the feel went off for a lost pace (its outcome asserted)
    after = [r for r in rows if r["t"] >= now]
    assert after and min(r["pose_deg"][0] for r in after) < EDGE  # the hand took it inside
    assert all(r["motor_nm"] == [0.0, 0.0] for r in after if r["pose_deg"][0] < EDGE)
    if not pull_steady:
        return  # a cycle stalled: the leader may have crossed inside unread
    assert source.snap.brakes + source.snap.cuts > freed  # the watch let the wall go
    # outside, pulling outward: two cycles at most, small beside a dragged leader's 0.28 N m
    outward = [r for r in after if r["pose_deg"][0] > EDGE and r["motor_nm"][0] > 0.0]
    assert not outward or outward[-1]["t"] - outward[0]["t"] <= 0.012  # two cycles at most
    assert max((r["motor_nm"][0] for r in outward), default=0.0) < 0.25 * source.law.cap_nm


def turn_shafts(rig, ids: tuple[int, ...], degrees: tuple[float, ...]) -> None:
    """Turn the passive leader's shafts ``ids`` to joint angles ``degrees`` (deg), to 2 ticks."""
    goals = {
        i: joint.zero_tick + joint.direction * round(deg * 4096 / 360)
        for i, joint, deg in zip(ids, rig.joints, degrees, strict=True)
    }
    rig.bus.set_torque(True, ids)
    rig.bus.sync_write(Register.GOAL_POSITION, goals)
    deadline = time.monotonic() + 20
    while any(
        abs(rig.bus.sync_read(Register.PRESENT_POSITION, (i,))[i] - goals[i]) > 2 for i in goals
    ):
        assert time.monotonic() < deadline, "the leader shafts did not reach their goals"


#: Where the hand turns each passive leader's shafts (deg): past the 30 deg cone; roll too.
SHAFTS = {"sim": (60, 0), "sim3": (20, 10, -30)}


def test_an_xl430_leader_stays_passive_mirrors_and_says_so(tmp_path, rig):
    """Passive, it says so and its command is its shafts' full orientation (roll included); the
    follower mirrors it and stops at the cone's edge; leader ids must be on the bus, not the
    follower's, and three need a three-servo follower."""
    with felt_session(tmp_path, rig, model="xl430-w250") as (session, source, log), source:
        assert not source.felt and "stays passive" in source.notice
        assert source._guard is None  # torque off from the start: nothing for a guard to do
        assert not any(session.rig.bus.torque_enabled()[i] for i in rig.ids)
        [command] = source.poll()
        pose = source.last_pose
        assert pose is not None and len(pose) == len(rig.ids)
        # two servos: the three-servo pose with no roll
        q = pose_quat_scalar(*pose, *[0.0] * (3 - len(pose)))
        np.testing.assert_allclose(command.q, q, atol=1e-12)
        shown = leader_status(source)()  # what the live page is handed
        limb = session.rig
        turn_shafts(limb, rig.ids, SHAFTS[rig.profile])
        if len(rig.ids) == 3:
            # read before and after the poll: a shaft still settling within its 2 ticks lies
            # between the two reads
            ticks = limb.bus.sync_read(Register.PRESENT_POSITION, rig.ids)
            [turned] = source.poll()
            polled = source.last_pose
            later = limb.bus.sync_read(Register.PRESENT_POSITION, rig.ids)
        else:
            with pytest.raises(ConfigError, match="not on the bus"):
                LeaderSource(limb, (5, 6))
            with pytest.raises(ConfigError):
                LeaderSource(limb, (1, 2))
            refused = "needs a 3-servo follower: rig 'sim' has 2 servos; give leader:ID,ID"
            with pytest.raises(ConfigError, match=refused):
                LeaderSource(limb, (3, 4, 5))
            limb.set_torque(True)
            with Running(session, source) as running:  # 100 goals written, at the cone's edge
                running.until(
                    lambda p: (
                        sum(c.written for c, _, _ in p) > 100
                        and off_axis_deg(*next(c.present for c, _, _ in p[::-1] if c.present))
                        > 29.0
                    )
                )
            pan, tilt = limb.read_pose()
    assert shown.toward_twist_deg is None and shown.cap_nm is None
    if len(rig.ids) == 2:
        assert shown.twist_deg is None
        summary = running.out["s"]
        assert summary.exit_code == 0 and summary.commands > 100
        assert summary.goals_written > 100
        # the follower turned toward the leader (pan 60) and stopped at the cone's edge
        assert pan > 0 and 29.0 < off_axis_deg(pan, tilt) <= 30.2
        return
    assert shown.twist_deg == pytest.approx(math.degrees(decompose_one(command.q)[1]))
    angles = limb.ticks_to_angles(*(ticks[i] for i in rig.ids))
    after = limb.ticks_to_angles(*(later[i] for i in rig.ids))
    np.testing.assert_allclose(turned.q, pose_quat_scalar(*polled), atol=1e-12)
    for joint, (at, polled_at, then) in enumerate(zip(angles, polled, after, strict=True)):
        assert min(at, then) - 1e-12 <= polled_at <= max(at, then) + 1e-12, joint
    # the shafts were waited for within 2 ticks of goals rounded from the angles: 2.33 ticks
    assert math.degrees(angles[2]) == pytest.approx(-30.0, abs=2.34 * 360 / 4096)


def test_a_rate_it_cannot_keep_is_refused_and_a_lost_pace_switches_the_feel_off_for_good(
    tmp_path, rig
):
    """Refused at 2 kHz, left limp; started, a lost pace switches the feel off for good in its
    cycle and mirroring goes on."""
    with felt_session(tmp_path, rig, rate_hz=2000.0) as (session, source, log):
        with pytest.raises(ConfigError, match="lower --rate"), source:
            pass
        assert not any(session.rig.bus.torque_enabled()[i] for i in rig.ids), "not left limp"
        # started at a rate the start's check passes on a loaded machine, then forced: the
        # source believes its wall needs 1 kHz, which the loop cannot keep
        source.rate_hz = 200.0
        with source:
            source.rate_hz, source.pace = 1000.0, PaceWatch(1000.0)
            session.rig.set_torque(True)
            with Running(session, source) as running:
                session.simulator.set_operator(rig.press)
                running.until(lambda p: running.off.at is not None and len(p) > running.off.at + 20)
                accepted = source.stats.accepted
                running.until(lambda p: len(p) > running.off.at + 40)
                assert running.paced_out()
            assert source.stats.accepted > accepted  # still mirrored, without feel
            assert not source.felt


#: Faults injected into a running rig (its simulator, the rig).
FAULTS = {
    "silence": lambda sim, rig: sim.vanish(rig.pusher, 0.2),
    "restart": lambda sim, rig: sim.restart(rig.ids[0]),
    "alarm": lambda sim, rig: sim.set_temperature(rig.ids[1], 95.0),
    "bus": lambda sim, rig: sim.set_faults(drop=1.0),
    "follower": lambda sim, rig: sim.vanish(1, 0.2),
}
#: Each rig's operator targets (deg: pan, tilt and, on three servos, roll).
TARGETS = {
    "sim": st.tuples(st.floats(-20.0, 70.0), st.floats(-20.0, 40.0)),
    "sim3": st.tuples(st.floats(-20.0, 60.0), st.floats(-20.0, 35.0), st.floats(-60.0, 60.0)),
}


@settings(
    max_examples=4,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(data=st.data(), fault=st.sampled_from(sorted(FAULTS)), after=st.integers(20, 200))
def test_property_random_streams_and_faults_never_above_the_cap_off_at_once(
    tmp_path_factory, rig, data, fault, after
):
    """Random streams with one injected fault: never above the cap, a push only when fit."""
    targets = data.draw(st.lists(TARGETS[rig.profile], min_size=2, max_size=4), label="targets")
    tmp_path = tmp_path_factory.mktemp("felt")
    rest = (0.0,) * len(rig.ids)
    script = [[0.8 * k, *pose] for k, pose in enumerate([rest, *targets])]
    with running_felt(tmp_path, rig) as (session, source, log, running):
        cap = cap_of(source)
        session.simulator.set_operator({"script": script, **HAND})
        running.until(lambda p: len(p) >= after)
        FAULTS[fault](session.simulator, rig)
        seen = len(running.pushes)
        running.until(lambda p: len(p) > seen + 100 or running.ended)
        session.simulator.set_faults(drop=0.0)
    rows = truth_rows(log)
    assert max(abs(m) for row in rows for m in row["motor_nm"]) <= cap + 1e-12
    pushed_only_when_fit(running.pushes)


@pytest.mark.parametrize(
    ("rig", "model"),
    [(SIM, "xl330-m288"), (SIM, "xl330-m077@52"), (SIM3, "xl330-m288")],
    ids=["sim-m288", "sim-m077@52", "sim3-m288"],
)
def test_an_xl330_leader_feels_the_edge_with_half_its_stall_torque_at_most(tmp_path, rig, model):
    # beside an XL430 follower; the M077 with firmware 52 keeps its Indirect Data at 208
    with running_felt(tmp_path, rig, model=model) as (session, source, log, running):
        cap = cap_of(source)
        assert "XL330" in source.notice and "feels the edge" in source.notice
        assert cap <= 0.5 * source.motor.stall_torque_nm
        session.simulator.set_operator(rig.press)
        running.until(pressing)
        seen = []  # what the live page is handed, cycle by cycle, until it shows the push

        def shown_pushing(_) -> bool:
            pushed = (source.last_push, source.last_pose)  # what the status is made of
            seen.append((leader_status(source)(), *pushed))
            return seen[-1][0].state == "pushing back" or not source.felt

        running.until(shown_pushing)
        if running.paced_out():
            return
        shown, push, pose = seen[-1]
    assert shown.state == "pushing back"
    # an arrow on the plane only for a push whose swing part is SWING_SHARE_DRAWN of it or more
    swing = math.hypot(push.goal[0] - pose[0], push.goal[1] - pose[1])
    twist = abs(push.goal[2] - pose[2]) if len(pose) == 3 else 0.0
    assert (shown.toward is not None) == (swing >= SWING_SHARE_DRAWN * max(swing, twist))
    if len(pose) == 3:  # pushed in twist: its twist parts
        assert shown.twist_deg > 29.0 and shown.toward_twist_deg < shown.twist_deg
    rows = truth_rows(log)
    j = rig.joint
    pushed = [abs(r["motor_nm"][j]) for r in rows if r["pose_deg"][j] > EDGE + 1.0]
    assert pushed and max(pushed) > 0.5 * cap  # the motor pushed, at most by the cap
    assert max(abs(m) for r in rows for m in r["motor_nm"]) <= cap + 1e-12


def test_at_the_real_rate_the_wall_holds_or_its_feel_goes_off_for_good(tmp_path):
    """At 200 Hz as `limbctl teleop`: held within 2 deg of the twist edge, or refused at start
    (limp), or the pace watch switched the push off for good."""
    with felt_session(tmp_path, SIM3, rate_hz=200.0) as (session, source, log):
        try:
            source.start()
        except ConfigError as exc:
            assert "lower --rate" in str(exc)
            assert not any(session.rig.bus.torque_enabled()[i] for i in SIM3.ids)
            return
        try:
            session.rig.set_torque(True)
            with Running(session, source) as running:
                session.simulator.set_operator(TWIST_PRESS)
                start = session.simulator.truth()["leader"]["t"]
                running.until(lambda p: session.simulator.truth()["leader"]["t"] > start + 4.0)
                truth = session.simulator.truth()
                lost = running.paced_out()  # if so, asserts the outcome cycle by cycle
        finally:
            source.close()
    if lost:
        assert truth["leader"]["motor_nm"] == [0.0, 0.0, 0.0]
        assert not any(truth["servos"][i]["torque_on"] for i in SIM3.ids)
    else:
        held = [r for r in truth_rows(log) if start + 3.0 <= r["t"] < start + 4.0]
        assert 0.4 < statistics.median(beyond_of(square_region(), r) for r in held[::5]) < 2.0


# -- a leader servo, the bus or the controller failing mid-push -------------------------------
#: Each rig pressed along pan first (the edge at pan 30 deg for both regions).
SWINGS = pytest.mark.parametrize(
    "rig", [SIM, replace(SIM3, press=SWING_THEN_TWIST, joint=0)], ids=["sim", "sim3"]
)
#: The simulator's leader log has one row a millisecond: a push's end is seen within it.
LOG_GRAIN_S = 0.001
PERIOD_S = 1.0 / 200.0
#: A dead controller's last goal: at most LEAD plus the walking lead (5 ticks on an XM430) ahead.
LAST_GOAL_AHEAD_DEG = 5 * 360.0 / 4096
#: Cycles before the dropout whose pacing bounds how long the cycle in progress then takes.
PACING_CYCLES = 20


def cycle_pace_s(running: Running, wall_s: float) -> float:
    """The longest start-to-start time (s) of the ``PACING_CYCLES`` cycles that ended before
    monotonic ``wall_s``: how late the loop ran just before a fault (the period when it kept
    pace; the fault's own cycles, which hold a failed read, are not counted)."""
    with running.changed:
        i = next(k for k, end in enumerate(running.clock) if end >= wall_s)
        starts = [cycle.t for cycle, _, _ in running.pushes[max(i - PACING_CYCLES, 0) : i]]
    return float(np.max(np.diff(starts)))


@SWINGS
def test_a_leader_servo_dropping_off_mid_push_switches_every_push_off_and_is_reported(
    tmp_path, rig
):
    ids = rig.ids
    gone, pusher = ids[-1], rig.joint  # the last servo drops; the pan motor pushes
    with felt_session(tmp_path, rig) as (session, source, log), source:
        session.rig.set_torque(True)
        with Running(session, source) as running:
            if not running.held_still(rig.press):
                return  # the feel went off for a lost pace (its outcome asserted)
            at = session.simulator.truth()["leader"]["t"]
            session.simulator.vanish(gone, 0.3)
            # the vanish lands between the two reads of the simulator's clock
            landed = session.simulator.truth()["leader"]["t"]
            landed_wall = time.monotonic()
            running.until(lambda p: session.simulator.truth()["leader"]["t"] > at + 0.5)
            felt = source.felt
            cycle_s = cycle_pace_s(running, landed_wall)
        lines = source.report_lines()
        # one failed read, timed on this bus with the loop stopped (the servo gone again)
        session.simulator.vanish(gone, 0.1)
        failed = session.rig.bus.read_cycle(ids=ids, attempts=1)
        assert not failed.ok
    rows = [row for row in truth_rows(log) if row["t"] >= at]
    assert rows[0]["motor_nm"][pusher] != 0.0  # it pushed when the servo dropped off
    off = next(row["t"] for row in rows if row["motor_nm"][pusher] == 0.0)
    # one cycle (the work between its read and the watch's next: a period, or as long as the
    # loop's cycles took just before on a loaded machine) plus one failed read
    seen = getattr(getattr(source, "silence", None), "longest_failed_read_s", 0.0)
    bound = max(PERIOD_S, cycle_s) + max(failed.duration_s, seen) + LOG_GRAIN_S
    assert off - landed <= bound, (off - landed, off - at, bound)
    # nothing pushed the hand while the servo was gone
    during = [row for row in rows if off <= row["t"] <= at + 0.3]
    assert during and all(row["motor_nm"][pusher] == 0.0 for row in during)
    line = next(line for line in lines if line.startswith("leader dropouts"))
    assert f"servo {gone} " in line, lines
    length = float(line.split(f"servo {gone} ")[1].split(" s")[0])
    assert 0.25 <= length <= 0.45, line  # 0.3 s, known within a probe interval and a read
    assert felt or running.paced_out()


@SWINGS
def test_a_leader_cut_off_from_its_controller_holds_within_the_cap_and_pushes_no_further(
    tmp_path, rig
):
    """Cut off mid-push, each Bus Watchdog holds at most the last push; let go after 0.3 s, the
    hand is pushed no further in than the last goal, then by nothing."""
    press = rig.press
    with running_felt(tmp_path, rig) as (session, source, log, running):
        if not running.held_still(press):
            return
        at = session.simulator.truth()["leader"]["t"]
        for servo_id in rig.ids:
            session.simulator.vanish(servo_id, 2.0)
        target = [list(press["script"][-1][1:])]
        session.simulator.set_operator({**press, "script": [[0.0, *target[0]]], "let_go_s": 0.3})
        running.until(lambda p: session.simulator.truth()["leader"]["t"] > at + 1.0)
        cap = source.cap_nm
    rows = [row for row in truth_rows(log) if at <= row["t"] <= at + 1.0]
    assert max(sum(m * m for m in row["motor_nm"]) ** 0.5 for row in rows) <= cap + 1e-12
    start = rows[0]["pose_deg"]
    moved_in = max(start[0] - row["pose_deg"][0] for row in rows)  # pan toward the edge
    assert moved_in <= LAST_GOAL_AHEAD_DEG + 0.1, moved_in
    still = [row for row in rows if row["t"] >= at + 0.8]
    assert still and all(sum(abs(m) for m in row["motor_nm"]) < 0.02 for row in still), still[-1]


@SWINGS
def test_a_dead_controllers_leader_goes_limp_within_its_guards_bound(tmp_path, rig, capfd):
    """The controller dies mid-push (guard pipe and port closed as by the kernel): the guard
    switches every leader servo's torque off, no follower's (kill -9: test_leader_guard)."""
    ids = rig.ids
    with running_felt(tmp_path, rig) as (session, source, log, running):
        bus, follower = session.rig.bus, session.profile.ids
        if not running.held_still(rig.press):
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
    print(f"{rig.profile}: the controller's end to the guard's exit: {limp_s * 1e3:.1f} ms; {line}")
