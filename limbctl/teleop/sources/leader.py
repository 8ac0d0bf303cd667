"""A leader gimbal as a command source: a second pair of servos moved by hand.

The leader sits on the same bus as the follower (``leader:3,4`` = pan id 3, tilt id 4; a
three-servo leader ``leader:4,5,6`` adds its roll id and needs a three-servo follower) and is
assumed to be built and calibrated like the follower: its ticks are read with the follower's
zero ticks and directions. Each control cycle reads the leader in one sync read and offers its
pose as the newest command; it goes through the gate like any other.

A leader whose model senses current (:data:`limbctl.servo.leader.FELT_MODELS`) *feels the edge*:
its servos run in current-based position mode, free inside the region, pushing back beyond it
(:mod:`limbctl.teleop.haptic`); after each cycle's gate, :meth:`LeaderSource.feel` writes that
push in one sync write. Any doubt switches the push off at once: a leader that is silent, in
alarm or restarted, a failed bus, a held gate, a fault (:meth:`LeaderSource.release`) or the
session's end. Bus Watchdog is the backstop; a guard process switches its torque off if this
one dies (:mod:`limbctl.servo.leader_guard`). Other models stay passive (torque off). While the
wall holds the leader still, the loop's wait between cycles reads its speed and lets the wall go
as soon as it snaps toward the region (:mod:`limbctl.teleop.snap`).
"""

from __future__ import annotations

import math
import time

import numpy as np

from limbctl.errors import BusError, ConfigError, InvalidInputError
from limbctl.servo.control_table import MAX_TICK, Block, Register, model_name
from limbctl.servo.leader import (
    configure_felt_leader,
    encode_feel,
    feel_data,
    felt_motor,
    present_current,
)
from limbctl.servo.leader_guard import LeaderGuard
from limbctl.servo.rig import Rig
from limbctl.teleop.commands import Command, command_from_pan_tilt, command_from_pose
from limbctl.teleop.gate import Outcome
from limbctl.teleop.haptic import FeelLaw, FeelStats
from limbctl.teleop.haptic_push import Push, held, push_for
from limbctl.teleop.pacing import PaceWatch
from limbctl.teleop.sources.base import CommandSource
from limbctl.teleop.sources.leader_ids import check_leader_fits
from limbctl.teleop.sources.leader_silence import LeaderSilence
from limbctl.teleop.sources.leader_snap import SnapWatching, cycle_velocity, snap_watch

#: Bus Watchdog of a felt leader: 5 x 20 ms = 100 ms without a packet stops it (it holds where it
#: is with its last push, at most the cap, until its guard switches it off: docs/haptic.md, a
#: controller that dies). As long as the loop's own 20 failed cycles at 200 Hz, so the loop, not
#: the watchdog, notices a failing bus; the watchdog covers a dead controller.
WATCHDOG_UNITS = 5
WATCHDOG_UNIT_S = 0.020
#: Goal Current alone, written as raw bytes (sent even to a servo in alarm).
GOAL_CURRENT_BLOCK = Block(Register.GOAL_CURRENT, Register.GOAL_CURRENT.size)
#: Cycles timed at start (one follower read, one leader read, one leader write each) to check the
#: rate can be kept: a quarter of a second at 200 Hz, enough for a median; up to three batches,
#: so a moment of load on a shared machine does not refuse a bus that keeps the rate.
RATE_CHECK_CYCLES = 50
RATE_CHECK_TRIES = 3
#: How the loop's gate says it held because the follower's read failed this cycle.
FOLLOWER_UNREAD = "the bus failed this cycle"
#: How long the wall stays on while the follower's reads fail and the leader's do not (s): the
#: wall is computed from the leader's own pose and the region, not from the follower, so a
#: follower that missed a reply (the loop holds it until its silent servo's probe, every 50 ms)
#: need not drop the wall in the operator's hand. One probe interval and a cycle; after that
#: the follower counts as faulted and the wall goes off until it is read again (the loop's own
#: fault, 0.5 s of silence, releases it too). docs/decisions/haptic.md.
FOLLOWER_GRACE_S = 0.055


class LeaderSource(SnapWatching, CommandSource):
    """Mirror a hand-moved leader gimbal (read synchronously in :meth:`poll`).

    Parameters
    ----------
    rig : Rig
        The follower rig; its bus must also hold the leader's ids.
    leader_ids : tuple of int
        (pan id, tilt id) of the leader, or (pan, tilt, roll) ids of a three-servo leader.
    """

    name = "leader"
    latest_only = True
    #: How many servos this class makes feel the edge: a three-servo leader opened as a plain
    #: LeaderSource stays passive (a felt one is a LeaderSource3, sources/leader3.py).
    felt_joints = 2

    def __init__(
        self,
        rig: Rig,
        leader_ids: tuple[int, ...],
        rate_hz: float = 200.0,
        law: FeelLaw | None = None,
    ) -> None:
        super().__init__()
        check_leader_fits(leader_ids, rig.profile)
        if rig.bus is None or not set(leader_ids) <= set(rig.bus.ids):
            raise ConfigError(f"leader servos {leader_ids} are not on the bus")
        self.rig = rig
        self.leader_ids = tuple(leader_ids)
        self.read_failures = 0
        #: Cycles whose push the safety rules released (the leader unread, a held gate, a
        #: failed write, a follower silent past FOLLOWER_GRACE_S), whether or not it pressed.
        self.released_cycles = 0
        self.rate_hz = float(rate_hz)
        self.law = law or FeelLaw()
        self.motor = None  # a LeaderMotor while the leader feels the edge
        self._guard: LeaderGuard | None = None  # while felt: limps it if this process dies
        self.notice = ""
        self.feel_stats = FeelStats()
        self.last_push: Push | None = None
        #: The leader's (pan, tilt) as last read (rad; a three-servo leader's pan and tilt),
        #: None before the first read: what the live page draws beside the follower.
        self.last_pose: tuple[float, float] | None = None
        #: The most a felt leader may push (N m: the law's cap as its Current Limit allows);
        #: None while passive.
        self.cap_nm: float | None = None
        self._cycle: tuple | None = None  # pose, command, last read, read time, torque, speed
        self._cycle_judged = False  # the snap and brake rules ran on the cycle's read
        #: Lets a wall go the moment its leader snaps, or before its loop brakes the leader
        #: outward (limbctl.teleop.snap, limbctl.teleop.brake).
        self.snap = snap_watch(self.law)
        #: A felt leader's motor torques as last read (joint frame, N m; Present Current);
        #: None before its first read or while passive.
        self.last_torque_nm: tuple[float, ...] | None = None
        #: The leader's pose at its last good read and when (perf_counter s): how fast it moves.
        self._last_read: tuple[tuple[float, float], float] | None = None
        self._notes: list[str] = []
        #: The leader's silent servos and dropouts (leader_silence.py).
        self.silence = LeaderSilence()
        #: A wall that was on when one read missed (leader_snap.py, ``missed``): if the next
        #: read answers, this cycle's wall goes on as engaged, without the re-arm's wait.
        self.resume = False
        self._heard_at = math.inf  # when the leader last answered (perf_counter s)
        self._follower_read_at = -math.inf  # the follower's last good read (perf_counter s)
        self._polled_at: float | None = None  # this cycle's poll, right after the follower's read
        self._profile_velocity: int | None = 0  # what the leader's servos hold (set-up: 0)
        self._feel_block = feel_data()  # where its command goes (set at start)
        self.pace = PaceWatch(self.rate_hz)

    @property
    def felt(self) -> bool:
        """True while the leader pushes back at the edge."""
        return self.motor is not None

    def start(self) -> None:
        """Switch the leader's torque off so a hand can move it (no reader thread); a leader
        that senses current is set up to feel the edge instead (torque on, no current yet).

        Raises
        ------
        ConfigError
            If a felt leader's servo refuses mode 5, or its cycle cannot keep the rate.
        """
        bus = self.rig.bus
        model = model_name(bus.models[self.leader_ids[0]])
        if len(self.leader_ids) != self.felt_joints:
            bus.set_torque(False, self.leader_ids)
            self.notice = "a three-servo leader stays passive: nothing is felt"
            return
        motor = felt_motor(bus, self.leader_ids)
        if motor is None:
            bus.set_torque(False, self.leader_ids)
            self.notice = f"leader {model} senses no current: it stays passive, nothing is felt"
            return
        cap = motor.units_for(motor.cap_nm(self.law.cap_nm))
        at = {bus.indirect_at.get(i, Register.INDIRECT_DATA_1.address) for i in self.leader_ids}
        if len(at) != 1:
            raise ConfigError(
                f"the leader's servos keep Indirect Data at different addresses {sorted(at)}: "
                f"give them the same firmware"
            )
        self._feel_block = feel_data(at.pop())
        configure_felt_leader(bus, self.leader_ids, cap, WATCHDOG_UNITS)
        try:
            self._check_rate()
        except ConfigError:
            self._switch_off()
            raise
        self.motor = motor
        self._guard = LeaderGuard.start(bus, self.leader_ids)
        self.cap_nm = motor.torque_of(cap)
        self.notice = self._feel_notice(model, cap)

    def _feel_notice(self, model: str, cap: int) -> str:
        """What the operator is told at start when the leader feels the edge."""
        return (
            f"leader {model} feels the edge: free inside, pushed back beyond "
            f"{self.law.deadband_deg:g} deg, at most {self.motor.torque_of(cap):.2f} N m "
            f"(Current Limit {cap})"
        )

    def _check_rate(self) -> None:
        """Time felt cycles' transfers; refuse when no batch's median fits the period (a batch
        taken while the machine was busy for a moment is tried again)."""
        medians = []
        for _ in range(RATE_CHECK_TRIES):
            times = []
            for _ in range(RATE_CHECK_CYCLES):
                start = time.perf_counter()
                self.rig.read_cycle(attempts=1)
                read = self.rig.bus.read_cycle(ids=self.leader_ids, attempts=1)
                if read.ok:
                    pose = self._pose(read)
                    self._write(self._free(pose))
                times.append(time.perf_counter() - start)
            medians.append(float(np.median(times)))
            if medians[-1] <= 1.0 / self.rate_hz:
                return
        raise ConfigError(
            f"a cycle with the felt leader takes {min(medians) * 1e3:.1f} ms (the best median of "
            f"{RATE_CHECK_TRIES} x {RATE_CHECK_CYCLES}), more than the {1e3 / self.rate_hz:.1f} ms "
            f"period at {self.rate_hz:g} Hz: lower --rate, or raise the baud rate and lower the "
            f"adapter's latency timer (README)"
        )

    def close(self) -> None:
        """A felt leader goes limp (no current, torque off), its guard told so; safe twice."""
        if self.felt:
            self.motor = None
            self._switch_off()
        self._guard = self._guard and self._guard.done()

    def _zero_current(self) -> None:
        """Goal Current 0 on both leader servos in one sync write, alarm or not."""
        zero = dict.fromkeys(self.leader_ids, bytes(Register.GOAL_CURRENT.encode(0)))
        try:
            self.rig.bus.sync_write_block(GOAL_CURRENT_BLOCK, zero, check_alert=False)
        except BusError:
            pass  # the Bus Watchdog stops a leader that hears nothing

    def _switch_off(self) -> None:
        """No current, then torque off (each tried even if the other failed)."""
        self._zero_current()
        try:
            self.rig.bus.set_torque(False, self.leader_ids)
        except BusError:
            pass  # the watchdog stops it; nothing more can be sent on a failed bus

    @property
    def finished(self) -> bool:
        """A leader never ends by itself."""
        return False

    def poll(self, timeout: float = 0.0) -> list[Command]:
        """Read the leader's pose now and offer it as the newest command."""
        self._polled_at = time.perf_counter()
        return self._poll_felt() if self.felt else self._poll_passive()

    def _poll_passive(self) -> list[Command]:
        try:
            ticks = self.rig.bus.sync_read(Register.PRESENT_POSITION, self.leader_ids)
        except BusError:
            self.read_failures += 1
            return []
        pose = self._angles(tuple(ticks[i] for i in self.leader_ids))
        self._seen(pose)
        try:  # the same range checks as every other source's commands
            command = self._command(pose)
        except InvalidInputError as exc:
            self.stats.reject(f"leader pose refused: {exc}")
            return []
        self.stats.accepted += 1
        return [command]

    def _angles(self, ticks: tuple[int, ...]) -> tuple[float, ...]:
        """The leader's joint angles (rad) at its ticks, read like the follower's: (pan, tilt),
        or (pan, tilt, roll) for three servos."""
        return self.rig.ticks_to_angles(*ticks)

    def _seen(self, pose: tuple[float, ...]) -> None:
        """Keep a read pose for the live page (:attr:`last_pose`: its pan and tilt)."""
        self.last_pose = (pose[0], pose[1])

    @staticmethod
    def _command(pose: tuple[float, ...]) -> Command:
        """The command of a pose (rad): a direction for two joints, an orientation for three.

        Raises
        ------
        InvalidInputError
            Outside the range every source's commands are checked against.
        """
        if len(pose) == 3:
            return command_from_pose(*(math.degrees(a) for a in pose))
        return command_from_pan_tilt(math.degrees(pose[0]), math.degrees(pose[1]))

    def _poll_felt(self) -> list[Command]:
        """The felt leader's read: its pose, and whether it is still fit to push."""
        self._cycle = None
        read = self.read_leader()  # a miss switches the push off at once (leader_snap.py)
        now = time.perf_counter()
        if read is None or not read.ok:
            self.read_failures += read is not None
            return []
        self._notes.extend(self.silence.heard(now))
        unheard_s, self._heard_at = now - self._heard_at, now
        if unheard_s > WATCHDOG_UNITS * WATCHDOG_UNIT_S / 2.0:
            self._arm_watchdog()  # long enough unheard that its watchdog may have tripped
        for servo_id, report in read.reports.items():
            if report.hardware_error:
                self._lose_feel(
                    f"leader servo {servo_id} alarm ({', '.join(report.hardware_error)})"
                )
            elif not report.torque_on:
                self._lose_feel(f"leader servo {servo_id} restarted (its torque went off)")
            if not self.felt:  # a restarted servo's indirect map is gone: read it plainly
                return self._poll_passive()
        pose = self._pose(read)
        self._seen(pose)
        try:
            command = self._command(pose)
        except InvalidInputError as exc:
            self.stats.reject(f"leader pose refused: {exc}")
            return []
        self.stats.accepted += 1
        if self.felt:
            self.last_torque_nm = self._torque(read)
            speed = cycle_velocity(read, self.leader_ids, self.rig.joints)
            judged = self.judge_read(speed, self.last_torque_nm, now)
            self._cycle = (pose, command.q, self._last_read, now, self.last_torque_nm, speed)
            self._cycle_judged = judged
            self._last_read = (pose, now)
        return [command]

    def _torque(self, read) -> tuple[float, ...]:
        """The leader's motor torques (joint frame, N m) in a good read of a felt leader: its
        Present Current (:func:`~limbctl.servo.leader.present_current`) turned into torque and
        into the joint's frame by its direction."""
        return tuple(
            joint.direction * self.motor.torque_of(present_current(read.reports[servo_id]))
            for servo_id, joint in zip(self.leader_ids, self.rig.joints, strict=True)
        )

    def _arm_watchdog(self) -> None:
        """Clear a Bus Watchdog that may have tripped while the leader was not heard, and arm
        it again (a tripped servo refuses every goal, Goal Current 0 included)."""
        try:
            for servo_id in self.leader_ids:
                self.rig.bus.write(Register.BUS_WATCHDOG, servo_id, 0, check_alert=False)
                self.rig.bus.write(Register.BUS_WATCHDOG, servo_id, WATCHDOG_UNITS, False)
        except BusError:
            self._heard_at = -math.inf  # tried again on the next good read

    def _pose(self, read) -> tuple[float, ...]:
        """The pose (rad) of a good read of the leader."""
        return self._angles(tuple(read.reports[i].present for i in self.leader_ids))

    def _lose_feel(self, cause: str) -> None:
        """Switch the push off for good; the mirroring goes on and the operator is told."""
        self.motor = None
        self.last_push = None
        self._switch_off()
        note = f"{cause}: the push is off, mirroring goes on without feel"
        self.feel_stats.events.append(note)
        self._notes.append(note)

    def feel(self, gate, result, bus_ok: bool) -> tuple[str, ...]:
        """Write this cycle's push: none unless the leader was read and is fit to push, and the
        gate ran on a good read of the follower, or held only because the follower's read failed
        within FOLLOWER_GRACE_S of its last good one; a loop that no longer keeps the rate
        switches the push off for good."""
        if self.felt:
            self._check_pace()
        notes, self._notes = tuple(self._notes), []
        resume, self.resume = self.resume, False  # a wall freed by one lost reply (missed)
        cycle, self._cycle = self._cycle, None
        if not self.felt:
            return notes
        # the follower's reads are timed at the poll right after them, not here: a cycle whose
        # leader read failed twice reaches this 13 ms later, and the grace would run from there
        now, self._polled_at = self._polled_at or time.perf_counter(), None
        ran = bus_ok and result is not None and result.outcome is not Outcome.HELD
        if ran:
            self._follower_read_at = now
        released = cycle is None or not (ran or self._follower_missed(result, bus_ok, now))
        self.released_cycles += released
        if cycle is None:  # the leader was not read: it may not hear a push either
            push = None
        elif not released:
            pose, q, last, read_at, torque, speed = cycle
            previous, period = (None, 0.0) if last is None else (last[0], read_at - last[1])
            engaged = resume or (self.last_push is not None and self.last_push.goal_current > 0)
            push = self._law(gate, pose, q, previous, period, engaged, torque, speed)
            # a wall kept by the rules at this very read (judge_read) is not judged twice
            judged = engaged and self._cycle_judged
            if (
                push.goal_current
                and not judged
                and not self.snap.allows(pose, push.goal, speed, engaged, read_at, torque)
            ):
                push = self._free(pose)  # still moving in, snapping or outrunning: no wall
            if push.goal_current and not engaged and not self.still_to_engage(pose, push.goal):
                push = self._free(pose)  # a hand took it in since the read: not yet
        else:
            push = self._free(cycle[0])
        if push is None:
            self.release()
            return notes
        self._write(push)
        if released or self.last_push is None or not push.goal_current:
            self.snap.disarm()
        else:  # the law's push, written: pose, torque, speed and read time from this cycle
            self.snap.arm(pose, push.goal, speed, torque, engaged, read_at)
        self.feel_stats.add(push.torque_nm, 1.0 / self.rate_hz)
        return notes

    def _law(self, gate, pose, q, previous, period: float, engaged: bool, torque, speed) -> Push:
        """This cycle's push by the two-servo law (:func:`~limbctl.teleop.haptic_push.push_for`)
        from the leader's pose (rad), its command ``q`` (4,), the pose read a cycle before (None
        at first) and the time since (s), whether the wall pushed then, and the motors' torque
        and speed as read (joint frame, N m and deg/s)."""
        corrected = gate.envelope.correct(q)
        return push_for(
            self.law, self.motor, pose, q, corrected, previous, period, engaged, torque, speed
        )

    #: The push of a cycle that may not push: no current, the goal at the pose (rad).
    _free = staticmethod(held)

    def _goal_ticks(self, push: Push) -> tuple[int, ...]:
        """The push's Goal Position ticks per leader servo (not clamped)."""
        return self.rig.angles_to_ticks(*push.goal)

    def _follower_missed(self, result, bus_ok: bool, now: float) -> bool:
        """Whether the gate held only because the follower's read failed, within
        FOLLOWER_GRACE_S of its last good read: the wall (the leader's pose against the region)
        then stays on. Any other hold, a failed write, a longer silence: off."""
        return (
            not bus_ok
            and result is not None
            and result.outcome is Outcome.HELD
            and result.reason == FOLLOWER_UNREAD
            and now - self._follower_read_at <= FOLLOWER_GRACE_S
        )

    def _check_pace(self) -> None:
        """The wall is passive only at its rate (docs/haptic.md): a lost pace switches the push
        off for good (:class:`PaceWatch`)."""
        median = self.pace.lost()
        if median is not None:
            self._lose_feel(
                f"the loop runs at {1.0 / median:.0f} Hz, under the {self.rate_hz:g} Hz "
                f"the leader's wall needs to stay passive"
            )

    def release(self) -> None:
        """No current on the leader from now until the next push (one sync write)."""
        self.snap.disarm()
        self.last_push = None
        if self.felt:
            self._zero_current()

    def _write(self, push: Push) -> None:
        """One sync write of Goal Current and Goal Position to the leader's servos; Torque
        Enable off and on first when the wall comes on, Profile Velocity once with it."""
        ticks = self._goal_ticks(push)
        currents = push.currents(len(self.leader_ids))
        data = {
            servo_id: encode_feel(current, min(max(int(tick), 0), MAX_TICK))
            for servo_id, tick, current in zip(self.leader_ids, ticks, currents, strict=True)
        }
        engaging = push.goal_current > 0 and (
            self.last_push is None or not self.last_push.goal_current
        )
        try:
            if engaging:
                # The servo's profile setpoint stays where the wall last put it while the leader
                # is free (Goal Current 0) and the hand moves it; the wall would then pull toward
                # that old setpoint at whatever speed the cap gives, not walk back at the profile's.
                # Torque on puts the setpoint (and Goal Position) at the present position, so the
                # wall starts from where the leader is.
                off = dict.fromkeys(self.leader_ids, 0)
                self.rig.bus.sync_write(Register.TORQUE_ENABLE, off)
                self.rig.bus.sync_write(Register.TORQUE_ENABLE, dict.fromkeys(self.leader_ids, 1))
            # the wall's speed, written once it first comes on; a free leader has no current,
            # and the wall always comes on from the present position, so it is left as it is
            if push.goal_current and push.profile_velocity != self._profile_velocity:
                self._profile_velocity = None
                velocity = dict.fromkeys(self.leader_ids, push.profile_velocity)
                self.rig.bus.sync_write(Register.PROFILE_VELOCITY, velocity)
                self._profile_velocity = push.profile_velocity
            self.rig.bus.sync_write_block(self._feel_block, data)
            self.last_push = push
        except BusError:
            self.last_push = None  # the next cycle tries again; the watchdog is the backstop

    def report_lines(self) -> tuple[str, ...]:
        """The start notice, how long and how hard the operator pressed, what switched it off."""
        if not self.notice:
            return ()
        lines = [self.notice]
        if "feels the edge" in self.notice:
            lines.append(self.feel_stats.describe())
            lines.extend(self.silence.lines(time.perf_counter()))
        return (*lines, *self.feel_stats.events)
