"""A three-servo leader gimbal as a command source that feels the edge of a twist region.

``leader:ID,ID,ID`` (pan, tilt, roll ids) beside a three-servo follower: each cycle the leader's
full orientation is the command, gated by :class:`limbctl.teleop.gate3.Gate3`. A leader whose
model senses current (:data:`limbctl.servo.leader.FELT_MODELS`) runs all three servos in
current-based position mode and pushes back beyond the region by the law of
:mod:`limbctl.teleop.haptic3`. Everything else is the two-servo leader's
(:class:`~limbctl.teleop.sources.leader.LeaderSource`): the set-up, the rate check at start, the
pace watch, Goal Current 0 on all three at once on any doubt (a leader that is silent, in alarm
or restarted, a failed bus, a held gate, a fault, the session's end), Torque Enable off and on
when the wall comes on, the Bus Watchdog as the backstop. Other models stay passive.
"""

from __future__ import annotations

import math
import time

from limbctl.errors import BusError, ConfigError, InvalidInputError
from limbctl.servo.control_table import MAX_TICK, Register, model_name
from limbctl.servo.leader import configure_felt_leader, encode_feel, feel_data, felt_motor
from limbctl.servo.ticks import angle_to_ticks
from limbctl.teleop.commands import Command, command_from_pose
from limbctl.teleop.gate import Outcome
from limbctl.teleop.haptic import Push
from limbctl.teleop.haptic3 import Pose3, Push3, held3, push3_for
from limbctl.teleop.sources.leader import WATCHDOG_UNIT_S, WATCHDOG_UNITS, LeaderSource


class LeaderSource3(LeaderSource):
    """Mirror a hand-moved three-servo leader; a current-sensing one feels the twist region.

    Parameters
    ----------
    rig : RollRig
        The three-servo follower rig; its bus also holds the leader's ids.
    leader_ids : (int, int, int)
        The leader's (pan, tilt, roll) ids.
    rate_hz, law
        As :class:`~limbctl.teleop.sources.leader.LeaderSource`.
    """

    def __init__(self, rig, leader_ids: tuple[int, ...], rate_hz: float = 200.0, law=None) -> None:
        if len(leader_ids) != 3:
            raise ConfigError(f"a three-servo leader needs three ids, got {leader_ids}")
        super().__init__(rig, leader_ids, rate_hz, law)
        #: The leader's (pan, tilt, roll) as last read (rad); None before the first read.
        self.last_pose3: Pose3 | None = None
        #: This cycle's pose, command, the last good read (pose, perf_counter s) and read time.
        self._cycle3: tuple | None = None
        self._last_read3: tuple[Pose3, float] | None = None

    def start(self) -> None:
        """Torque off for a passive model; a current-sensing one is set up to feel the edge on
        all three servos (mode 5, Current Limit = cap, watchdog, torque on, no current).

        Raises
        ------
        ConfigError
            If a felt leader's servo refuses mode 5, or its cycle cannot keep the rate.
        """
        bus = self.rig.bus
        model = model_name(bus.models[self.leader_ids[0]])
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
        self.cap_nm = motor.torque_of(cap)
        self.notice = (
            f"leader {model} (three servos) feels the edge in swing and twist: free inside, "
            f"pushed back beyond {self.law.deadband_deg:g} deg of rotation, at most "
            f"{motor.torque_of(cap):.2f} N m per joint (Current Limit {cap})"
        )

    def _pose(self, read) -> tuple[float, float, float]:  # type: ignore[override]
        pose = self.rig.angles_of(tuple(read.reports[i].present for i in self.leader_ids))
        self.last_pose3 = pose
        return pose

    def _poll_passive(self) -> list[Command]:
        try:
            ticks = self.rig.bus.sync_read(Register.PRESENT_POSITION, self.leader_ids)
        except BusError:
            self.read_failures += 1
            return []
        pose = self.rig.angles_of(tuple(ticks[i] for i in self.leader_ids))
        self.last_pose3, self.last_pose = pose, (pose[0], pose[1])
        try:  # the same range checks as every other source's commands
            command = command_from_pose(*(math.degrees(a) for a in pose))
        except InvalidInputError as exc:
            self.stats.reject(f"leader pose refused: {exc}")
            return []
        self.stats.accepted += 1
        return [command]

    def _poll_felt(self) -> list[Command]:
        """The felt leader's read: its full orientation, and whether it is still fit to push."""
        self._cycle3 = None
        # two tries, as the loop's own read: one lost reply should not drop the push
        read = self.rig.bus.read_cycle(ids=self.leader_ids, attempts=2)
        now = time.perf_counter()
        if not read.ok:
            self.read_failures += 1
            return []
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
        self.last_pose = (pose[0], pose[1])
        try:
            command = command_from_pose(*(math.degrees(a) for a in pose))
        except InvalidInputError as exc:
            self.stats.reject(f"leader pose refused: {exc}")
            return []
        self.stats.accepted += 1
        if self.felt:
            self._cycle3 = (pose, command.q, self._last_read3, now)
            self._last_read3 = (pose, now)
        return [command]

    def feel(self, gate, result, bus_ok: bool) -> tuple[str, ...]:
        """Write this cycle's push (none unless the gate ran on a good read of both gimbals);
        a loop that no longer keeps the rate switches the push off for good."""
        if self.felt:
            self._check_pace()
        notes, self._notes = tuple(self._notes), []
        cycle, self._cycle3 = self._cycle3, None
        if not self.felt:
            return notes
        if cycle is None:  # the leader was not read: it may not hear a push either
            push = None
        elif not bus_ok or result is None or result.outcome is Outcome.HELD:
            push = held3(cycle[0])
        else:
            pose, q, last, read_at = cycle
            previous, period = (None, 0.0) if last is None else (last[0], read_at - last[1])
            engaged = self.last_push is not None and self.last_push.goal_current > 0
            limits = (gate.limits.roll_min, gate.limits.roll_max)
            corrected = gate.envelope.correct(q)
            push = push3_for(
                self.law, self.motor, pose, q, corrected, limits, previous, period, engaged
            )
        if push is None:
            self.release()
            return notes
        self._write(push)
        self.feel_stats.add(push.torque_nm, 1.0 / self.rate_hz)
        return notes

    def _write(self, push: Push) -> None:
        """One sync write of Goal Current and Goal Position to the three servos; Torque Enable
        off and on first when the wall comes on, Profile Velocity when it comes on or goes off.
        A two-servo :class:`Push` (the rate check's) keeps the roll where it was last read."""
        roll = push.goal_roll if isinstance(push, Push3) else (self.last_pose3 or (0, 0, 0))[2]
        goal = (push.goal_pan, push.goal_tilt, roll)
        data = {
            servo_id: encode_feel(
                push.goal_current,
                min(max(int(angle_to_ticks(angle, joint.zero_tick, joint.direction)), 0), MAX_TICK),
            )
            for servo_id, angle, joint in zip(self.leader_ids, goal, self.rig.joints, strict=True)
        }
        engaging = push.goal_current > 0 and (
            self.last_push is None or not self.last_push.goal_current
        )
        try:
            if engaging:
                # Torque on puts each servo's profile setpoint at its present position, so the
                # wall starts from where the leader is (docs/haptic.md, LeaderSource._write)
                off = dict.fromkeys(self.leader_ids, 0)
                self.rig.bus.sync_write(Register.TORQUE_ENABLE, off)
                self.rig.bus.sync_write(Register.TORQUE_ENABLE, dict.fromkeys(self.leader_ids, 1))
            if push.profile_velocity != self._profile_velocity:  # the wall comes on or goes off
                self._profile_velocity = None
                velocity = dict.fromkeys(self.leader_ids, push.profile_velocity)
                self.rig.bus.sync_write(Register.PROFILE_VELOCITY, velocity)
                self._profile_velocity = push.profile_velocity
            self.rig.bus.sync_write_block(self._feel_block, data)
            self.last_push = push
        except BusError:
            self.last_push = None  # the next cycle tries again; the watchdog is the backstop
