"""What a felt leader's snap watch reads between the cycles: speed and motor torque."""

from __future__ import annotations

import time
from collections.abc import Sequence

from limbctl.errors import BusError
from limbctl.servo.cycle import CycleRead
from limbctl.servo.leader import LeaderMotor, present_current, present_velocity
from limbctl.teleop.brake import BrakeLaw
from limbctl.teleop.haptic import VELOCITY_UNIT_DEG_S, FeelLaw
from limbctl.teleop.snap import SnapLaw, SnapWatch


def snap_watch(law: FeelLaw) -> SnapWatch:
    """A felt leader's watch: the snap and brake rules at ``law``'s Profile Velocity."""
    walk = law.profile_velocity_units() * VELOCITY_UNIT_DEG_S
    return SnapWatch(SnapLaw(), brake=BrakeLaw(), walk_deg_s=walk, at_read=True, rearm_twice=True)


def cycle_velocity(read: CycleRead, ids: Sequence[int], joints: Sequence) -> tuple[float, ...]:
    """A felt leader's joint speeds (deg/s, joint frame) in a good cycle read."""
    return tuple(
        joint.direction * present_velocity(read.reports[servo_id]) * VELOCITY_UNIT_DEG_S
        for servo_id, joint in zip(ids, joints, strict=True)
    )


def motion_of(
    read: CycleRead, ids: Sequence[int], joints: Sequence, motor: LeaderMotor
) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """A felt leader's joint speeds (deg/s) and torques (N m), joint frame, in a good read."""
    speeds = cycle_velocity(read, ids, joints)
    torques = tuple(
        joint.direction * motor.torque_of(present_current(read.reports[servo_id]))
        for servo_id, joint in zip(ids, joints, strict=True)
    )
    return speeds, torques


def read_motion(
    bus, ids: Sequence[int], joints: Sequence, motor: LeaderMotor
) -> tuple[tuple[float, ...], tuple[float, ...]] | None:
    """:func:`motion_of` one try of the cycle read; None if it failed."""
    read = bus.read_cycle(ids=ids, attempts=1)
    return motion_of(read, ids, joints, motor) if read.ok else None


class SnapWatching:
    """The loop's idle work for a felt leader (mixed into ``LeaderSource``)."""

    @property
    def idle_work(self):
        """What the loop runs while it waits: :meth:`watch_snap` while a wall is on, else None."""
        return self.watch_snap if self.felt and self.snap.watching else None

    def still_to_engage(self, pose: Sequence[float], goal: Sequence[float]) -> bool:
        """Whether a wall about to come on (``pose`` toward ``goal``, rad) finds its leader still
        on a fresh read (the loop would brake one moving in outward); a failed read: no."""
        motion = self.read_motion()
        if motion is None:
            return False
        return self.snap.still(pose, goal, motion[0])

    def judge_read(self, speed: Sequence[float], torque: Sequence[float], now: float) -> bool:
        """At the cycle's read: let the wall go if the rules say so; whether they ran."""
        if not (self.snap.at_read and self.snap.watching):
            return False
        if self.snap.judge(speed, now, torque):
            self.release()
        return True

    def watch_snap(self) -> None:
        """Between cycles: let the wall go at once on a snap or a coming brake."""
        motion = self.read_motion()
        now = time.perf_counter()
        if self.snap.watching and motion is not None and self.snap.snaps(motion[0], now, motion[1]):
            self.release()

    def read_leader(self) -> CycleRead | None:
        """The cycle's read of the felt leader, retried once; None between probes while silent."""
        if not self.silence.read_now(time.perf_counter()):
            return None
        read = self.rig.bus.read_cycle(ids=self.leader_ids, attempts=1)
        if not read.ok:
            self.missed(read)
            if not self.silence.silent:
                read = self.rig.bus.read_cycle(ids=self.leader_ids, attempts=1)
                if not read.ok:
                    self.missed(read)
        return read

    def missed(self, read: CycleRead) -> None:
        """A failed read: push off at once, the miss counted, the wall resumed on a good read."""
        self.silence.missed(read, time.perf_counter())
        self.resume = self.last_push is not None and self.last_push.goal_current > 0
        if self.felt:
            self.release()

    def read_motion(self) -> tuple[tuple[float, ...], tuple[float, ...]] | None:
        """Speeds (deg/s) and torques (N m) in one try of the cycle read; None if ``missed``."""
        try:
            read = self.rig.bus.read_cycle(ids=self.leader_ids, attempts=1)
        except BusError as exc:
            read = CycleRead({}, (), str(exc))
        if not read.ok:
            self.missed(read)
            return None
        return motion_of(read, self.leader_ids, self.rig.joints, self.motor)
