"""What a felt leader's snap watch reads (:mod:`limbctl.teleop.snap`): the leader's speed and
its motors' torque, between the cycles."""

from __future__ import annotations

import time
from collections.abc import Sequence

from limbctl.errors import BusError
from limbctl.servo.control_table import Block, Register
from limbctl.servo.cycle import CycleRead
from limbctl.servo.leader import LeaderMotor, present_velocity
from limbctl.teleop.brake import BrakeLaw
from limbctl.teleop.haptic import VELOCITY_UNIT_DEG_S, FeelLaw
from limbctl.teleop.snap import SnapLaw, SnapWatch

#: Present Current (2 bytes) and Present Velocity (4) are neighbours on every X-series model
#: (126-131): one sync read of this block gives the watch both.
MOTION_BLOCK = Block(Register.PRESENT_CURRENT, Register.PRESENT_CURRENT.size + 4)


def snap_watch(law: FeelLaw) -> SnapWatch:
    """A felt leader's watch: the snap rule and the brake rules, the wall's setpoint walking at
    ``law``'s Profile Velocity."""
    walk = law.profile_velocity_units() * VELOCITY_UNIT_DEG_S
    return SnapWatch(SnapLaw(), brake=BrakeLaw(), walk_deg_s=walk, at_read=True, rearm_twice=True)


def cycle_velocity(read: CycleRead, ids: Sequence[int], joints: Sequence) -> tuple[float, ...]:
    """The leader's joint speeds (deg/s, joint frame) in a good cycle read of a felt leader
    (Present Velocity rides in its Goal Position slot: :data:`~limbctl.servo.leader.
    VELOCITY_MAP`), each turned into its joint's frame by its direction."""
    return tuple(
        joint.direction * present_velocity(read.reports[servo_id]) * VELOCITY_UNIT_DEG_S
        for servo_id, joint in zip(ids, joints, strict=True)
    )


def read_motion(
    bus, ids: Sequence[int], joints: Sequence, motor: LeaderMotor
) -> tuple[tuple[float, ...], tuple[float, ...]] | None:
    """The leader's joint speeds (deg/s) and motor torques (N m), joint frame, in one sync read
    of Present Current and Present Velocity (:data:`MOTION_BLOCK`); None if the read failed
    (the next cycle's read decides what to do about the leader)."""
    try:
        blocks = bus.sync_read(MOTION_BLOCK, ids, check_alert=False)
    except BusError:
        return None
    speeds, torques = [], []
    for servo_id, joint in zip(ids, joints, strict=True):
        data = blocks[servo_id]
        current = int.from_bytes(data[:2], "little", signed=True)
        velocity = int.from_bytes(data[2:6], "little", signed=True)
        speeds.append(joint.direction * velocity * VELOCITY_UNIT_DEG_S)
        torques.append(joint.direction * motor.torque_of(current))
    return tuple(speeds), tuple(torques)


class SnapWatching:
    """The loop's idle work for a felt leader source (mixed into ``LeaderSource``, which has
    ``felt``, ``snap``, ``rig``, ``leader_ids``, ``motor`` and ``release``)."""

    @property
    def idle_work(self):
        """What the loop runs while it waits for the next cycle: the snap watch while a wall is
        on (:meth:`watch_snap`), else None (the loop just waits, as for any source)."""
        return self.watch_snap if self.felt and self.snap.watching else None

    def still_to_engage(self, pose: Sequence[float], goal: Sequence[float]) -> bool:
        """Whether a wall about to come on (from ``pose`` toward ``goal``, rad) finds its leader
        still, read again just before the write: the wall starts with its setpoint at the
        leader, and the servo's loop would brake one a hand has started to take in since the
        cycle's read (2-3 ms earlier over the bus), outward. A failed read: not now."""
        motion = read_motion(self.rig.bus, self.leader_ids, self.rig.joints, self.motor)
        if motion is None:
            return False
        return self.snap.still(pose, goal, motion[0])

    def judge_read(self, speed: Sequence[float], torque: Sequence[float], now: float) -> bool:
        """At the cycle's own read of a wall that is on (the watch's ``at_read``): let it go at
        once if the snap or brake rules say so, before the cycle's gate work and the
        follower's write. True if the rules ran on this read (and kept or freed the wall)."""
        if not (self.snap.at_read and self.snap.watching):
            return False
        if self.snap.judge(speed, now, torque):
            self.release()
        return True

    def watch_snap(self) -> None:
        """Between cycles: read the leader's speed and torque; a held leader that snaps toward
        the region, or one its loop is about to brake outward, is let go at once
        (:mod:`limbctl.teleop.snap`, :mod:`limbctl.teleop.brake`)."""
        motion = read_motion(self.rig.bus, self.leader_ids, self.rig.joints, self.motor)
        now = time.perf_counter()
        if self.snap.watching and motion is not None and self.snap.snaps(motion[0], now, motion[1]):
            self.release()
