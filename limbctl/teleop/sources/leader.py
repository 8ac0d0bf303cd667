"""A leader as a command source: a second chain of servos moved by hand, perhaps felt."""

from __future__ import annotations

import math
import time

from limbctl.errors import BusError, ConfigError, InvalidInputError
from limbctl.servo.control_table import Register
from limbctl.servo.leader import feel_data
from limbctl.servo.leader_guard import LeaderGuard
from limbctl.servo.rig import Rig
from limbctl.teleop.commands import Command, command_from_pan_tilt, command_from_pose
from limbctl.teleop.gate import Outcome
from limbctl.teleop.haptic import FeelLaw, FeelStats
from limbctl.teleop.haptic_push import Push, held, push_for
from limbctl.teleop.pacing import PaceWatch
from limbctl.teleop.sources.base import CommandSource
from limbctl.teleop.sources.leader_bus import WATCHDOG_UNIT_S, WATCHDOG_UNITS, LeaderBus
from limbctl.teleop.sources.leader_ids import check_leader_fits
from limbctl.teleop.sources.leader_silence import LeaderSilence
from limbctl.teleop.sources.leader_snap import SnapWatching, cycle_velocity, snap_watch

#: How the loop's gate says it held because the follower's read failed this cycle.
FOLLOWER_UNREAD = "the bus failed this cycle"
#: How long (s) the wall stays on while only the follower's reads fail: one silent-servo probe
#: interval (50 ms) and a cycle (docs/decisions/haptic.md).
FOLLOWER_GRACE_S = 0.055


def pose_command(pose: tuple[float, ...]) -> Command:
    """The command of a leader's pose (rad, one angle per joint); InvalidInputError outside the
    range every source's commands are checked against."""
    if len(pose) == 3:
        return command_from_pose(*(math.degrees(a) for a in pose))
    return command_from_pan_tilt(math.degrees(pose[0]), math.degrees(pose[1]))


class LeaderSource(SnapWatching, LeaderBus, CommandSource):
    """Mirror a hand-moved leader (``leader_ids``, one per joint of ``rig``, on its bus), read in
    :meth:`poll`; a current-sensing one feels the edge and must keep the loop's ``rate_hz`` (Hz)."""

    name = "leader"
    latest_only = True

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
        #: Cycles whose push the safety rules released, whether or not it pressed.
        self.released_cycles = 0
        self.rate_hz = float(rate_hz)
        self.law = law or FeelLaw()
        self.motor = None  # a LeaderMotor while the leader feels the edge
        self._guard: LeaderGuard | None = None  # while felt: limps it if this process dies
        self.notice = ""
        self.feel_stats = FeelStats()
        self.last_push: Push | None = None
        #: The leader's pose as last read (rad), None before the first read.
        self.last_pose: tuple[float, ...] | None = None
        #: The most a felt leader may push (N m); None while passive.
        self.cap_nm: float | None = None
        self._cycle: tuple | None = None  # pose, command, last read, read time, torque, speed
        self._cycle_judged = False  # the snap and brake rules ran on the cycle's read
        self.snap = snap_watch(self.law)
        #: A felt leader's motor torques as last read (N m); None before or while passive.
        self.last_torque_nm: tuple[float, ...] | None = None
        #: The leader's pose at its last good read and when (perf_counter s).
        self._last_read: tuple[tuple[float, ...], float] | None = None
        self._notes: list[str] = []
        self.silence = LeaderSilence()
        #: A wall on when one read missed goes on as engaged if the next read answers.
        self.resume = False
        #: Last answer (perf_counter s): never, so a first read re-arms the watchdog.
        self._heard_at = -math.inf
        self._follower_read_at = -math.inf  # the follower's last good read (perf_counter s)
        self._polled_at: float | None = None  # this cycle's poll, right after the follower's read
        self._profile_velocity: int | None = 0  # what the leader's servos hold (set-up: 0)
        self._feel_block = feel_data()  # where its command goes (set at start)
        self.pace = PaceWatch(self.rate_hz)

    @property
    def felt(self) -> bool:
        """True while the leader pushes back at the edge."""
        return self.motor is not None

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
            return []
        command = self._command(self.rig.ticks_to_angles(*(ticks[i] for i in self.leader_ids)))
        return [] if command is None else [command]

    def _command(self, pose: tuple[float, ...]) -> Command | None:
        """The leader's pose read now as a counted command; None (refused) out of range."""
        self.last_pose = pose
        try:  # the same range checks as every other source's commands
            command = pose_command(pose)
        except InvalidInputError as exc:
            self.stats.reject(f"leader pose refused: {exc}")
            return None
        self.stats.accepted += 1
        return command

    def _poll_felt(self) -> list[Command]:
        """The felt leader's read: its pose, and whether it is still fit to push."""
        self._cycle = None
        read = self.read_leader()  # a miss switches the push off at once (leader_snap.py)
        now = time.perf_counter()
        if read is None or not read.ok:
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
        command = self._command(pose)
        if command is None:
            return []
        if self.felt:
            self.last_torque_nm = self._torque(read)
            speed = cycle_velocity(read, self.leader_ids, self.rig.joints)
            judged = self.judge_read(speed, self.last_torque_nm, now)
            self._cycle = (pose, command.q, self._last_read, now, self.last_torque_nm, speed)
            self._cycle_judged = judged
            self._last_read = (pose, now)
        return [command]

    def _lose_feel(self, cause: str) -> None:
        """Switch the push off for good; the mirroring goes on and the operator is told."""
        self.motor = None
        self.last_push = None
        self._switch_off()
        note = f"{cause}: the push is off, mirroring goes on without feel"
        self.feel_stats.events.append(note)
        self._notes.append(note)

    def feel(self, gate, result, bus_ok: bool) -> tuple[str, ...]:
        """Write this cycle's push: none unless the leader was read and fit and the gate ran (or
        held only on a follower read failed within FOLLOWER_GRACE_S); a lost pace ends it."""
        if self.felt:
            self._check_pace()
        notes, self._notes = tuple(self._notes), []
        resume, self.resume = self.resume, False  # a wall freed by one lost reply (missed)
        cycle, self._cycle = self._cycle, None
        if not self.felt:
            return notes
        # the follower's read is timed at the poll right after it (a failed leader read is slow)
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
            # the gate's joint limits: a three-joint correction's roll is unwrapped within them
            limits = tuple(zip(gate.limits.joint_min, gate.limits.joint_max))
            corrected = gate.envelope.correct(q)
            push = push_for(
                self.law, self.motor, pose, q, corrected, previous, period, engaged, torque,
                speed, limits,
            )  # fmt: skip
            # a wall kept by the rules at this very read (judge_read) is not judged twice
            judged = engaged and self._cycle_judged
            if (
                push.goal_current
                and not judged
                and not self.snap.allows(pose, push.goal, speed, engaged, read_at, torque)
            ):
                push = held(pose)  # still moving in, snapping or outrunning: no wall
            if push.goal_current and not engaged and not self.still_to_engage(pose, push.goal):
                push = held(pose)  # a hand took it in since the read: not yet
        else:
            push = held(cycle[0])
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

    def _follower_missed(self, result, bus_ok: bool, now: float) -> bool:
        """Whether the gate held only on a follower read failed within FOLLOWER_GRACE_S."""
        return (
            not bus_ok
            and result is not None
            and result.outcome is Outcome.HELD
            and result.reason == FOLLOWER_UNREAD
            and now - self._follower_read_at <= FOLLOWER_GRACE_S
        )

    def _check_pace(self) -> None:
        """The wall is passive only at its rate: a lost pace switches the push off for good."""
        median = self.pace.lost()
        if median is not None:
            self._lose_feel(
                f"the loop runs at {1.0 / median:.0f} Hz, under the {self.rate_hz:g} Hz "
                f"the leader's wall needs to stay passive"
            )

    def report_lines(self) -> tuple[str, ...]:
        """The start notice, how long and how hard the operator pressed, what switched it off."""
        if not self.notice:
            return ()
        lines = [self.notice]
        if "feels the edge" in self.notice:
            lines.append(self.feel_stats.describe())
            lines.extend(self.silence.lines(time.perf_counter()))
        return (*lines, *self.feel_stats.events)
