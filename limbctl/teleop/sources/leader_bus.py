"""A leader source's bus side (mixed into ``LeaderSource``): set-up, reads and writes."""

from __future__ import annotations

import math
import time

import numpy as np

from limbctl.errors import BusError, ConfigError
from limbctl.servo.control_table import MAX_TICK, Block, Register, model_name
from limbctl.servo.leader import (
    configure_felt_leader,
    encode_feel,
    feel_data,
    felt_motor,
    present_current,
)
from limbctl.servo.leader_guard import LeaderGuard
from limbctl.teleop.haptic_push import Push, held

#: Bus Watchdog of a felt leader: 5 x 20 ms = 100 ms, as long as the loop's own 20 failed cycles
#: at 200 Hz, so the loop notices a failing bus and the watchdog a dead controller.
WATCHDOG_UNITS = 5
WATCHDOG_UNIT_S = 0.020
#: Goal Current alone, written as raw bytes (sent even to a servo in alarm).
GOAL_CURRENT_BLOCK = Block(Register.GOAL_CURRENT, Register.GOAL_CURRENT.size)
#: Cycles timed at start to check the rate (a median of a quarter second at 200 Hz), in batches.
RATE_CHECK_CYCLES = 50
RATE_CHECK_TRIES = 3
#: What the operator is told when the leader feels the edge, by its number of joints.
FEEL_NOTICES = {
    2: "leader {model} feels the edge: free inside, pushed back beyond {deadband:g} deg, at most "
    "{cap_nm:.2f} N m (Current Limit {cap})",
    3: "leader {model} (three servos) feels the edge in swing and twist: free inside, pushed back "
    "beyond {deadband:g} deg of rotation, at most {cap_nm:.2f} N m (Current Limit {cap})",
}


class LeaderBus:
    """Set-up, reads, writes and torque of a leader's servos."""

    def start(self) -> None:
        """Switch the leader's torque off for the hand, or set a current-sensing one up to feel
        the edge (torque on, no current yet). ConfigError if a felt leader's servo refuses mode 5,
        or its cycle cannot keep the rate."""
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
        self._guard = LeaderGuard.start(bus, self.leader_ids)
        self.cap_nm = motor.torque_of(cap)
        feels = FEEL_NOTICES[len(self.leader_ids)]
        self.notice = feels.format(
            model=model, deadband=self.law.deadband_deg, cap_nm=self.cap_nm, cap=cap
        )

    def _check_rate(self) -> None:
        """Refuse when no batch of timed felt cycles has its median within the period."""
        medians = []
        for _ in range(RATE_CHECK_TRIES):
            times = []
            for _ in range(RATE_CHECK_CYCLES):
                start = time.perf_counter()
                self.rig.read_cycle(attempts=1)
                read = self.rig.bus.read_cycle(ids=self.leader_ids, attempts=1)
                if read.ok:
                    self._write(held(self._pose(read)))
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
        """Goal Current 0 on every leader servo in one sync write, alarm or not."""
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

    def _arm_watchdog(self) -> None:
        """Clear a Bus Watchdog that may have tripped (it refuses every goal) and arm it again."""
        try:
            for servo_id in self.leader_ids:
                self.rig.bus.write(Register.BUS_WATCHDOG, servo_id, 0, check_alert=False)
                self.rig.bus.write(Register.BUS_WATCHDOG, servo_id, WATCHDOG_UNITS, False)
        except BusError:
            self._heard_at = -math.inf  # tried again on the next good read

    def _pose(self, read) -> tuple[float, ...]:
        """The pose (rad, one angle per joint) of a good read, with the follower's calibration."""
        return self.rig.ticks_to_angles(*(read.reports[i].present for i in self.leader_ids))

    def _torque(self, read) -> tuple[float, ...]:
        """The felt leader's motor torques (joint frame, N m) from a good read's Present Current."""
        return tuple(
            joint.direction * self.motor.torque_of(present_current(read.reports[servo_id]))
            for servo_id, joint in zip(self.leader_ids, self.rig.joints, strict=True)
        )

    def release(self) -> None:
        """No current on the leader from now until the next push (one sync write)."""
        self.snap.disarm()
        self.last_push = None
        if self.felt:
            self._zero_current()

    def _write(self, push: Push) -> None:
        """One sync write of Goal Current and Goal Position (torque cycled as the wall comes on)."""
        ticks = self.rig.angles_to_ticks(*push.goal)  # the goal's ticks, kept to one turn below
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
                # torque on puts the profile's setpoint at the present position: the wall starts
                # from the leader, not from where it last left the setpoint
                off = dict.fromkeys(self.leader_ids, 0)
                self.rig.bus.sync_write(Register.TORQUE_ENABLE, off)
                self.rig.bus.sync_write(Register.TORQUE_ENABLE, dict.fromkeys(self.leader_ids, 1))
            # the wall's speed, written once it first comes on
            if push.goal_current and push.profile_velocity != self._profile_velocity:
                self._profile_velocity = None
                velocity = dict.fromkeys(self.leader_ids, push.profile_velocity)
                self.rig.bus.sync_write(Register.PROFILE_VELOCITY, velocity)
                self._profile_velocity = push.profile_velocity
            self.rig.bus.sync_write_block(self._feel_block, data)
            self.last_push = push
        except BusError:
            self.last_push = None  # the next cycle tries again; the watchdog is the backstop
