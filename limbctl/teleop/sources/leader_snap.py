"""What a felt leader's snap watch reads (:mod:`limbctl.teleop.snap`): the leader's speed."""

from __future__ import annotations

import time
from collections.abc import Sequence

from limbctl.errors import BusError
from limbctl.servo.control_table import Register
from limbctl.servo.cycle import CycleRead
from limbctl.servo.leader import present_velocity
from limbctl.teleop.haptic import VELOCITY_UNIT_DEG_S


def cycle_velocity(read: CycleRead, ids: Sequence[int], joints: Sequence) -> tuple[float, ...]:
    """The leader's joint speeds (deg/s, joint frame) in a good cycle read of a felt leader
    (Present Velocity rides in its Goal Position slot: :data:`~limbctl.servo.leader.
    VELOCITY_MAP`), each turned into its joint's frame by its direction."""
    return tuple(
        joint.direction * present_velocity(read.reports[servo_id]) * VELOCITY_UNIT_DEG_S
        for servo_id, joint in zip(ids, joints, strict=True)
    )


def read_velocity(bus, ids: Sequence[int], joints: Sequence) -> tuple[float, ...] | None:
    """The leader's joint speeds (deg/s, joint frame) in one sync read of Present Velocity;
    None if the read failed (the next cycle's read decides what to do about the leader)."""
    try:
        units = bus.sync_read(Register.PRESENT_VELOCITY, ids, check_alert=False)
    except BusError:
        return None
    return tuple(
        joint.direction * units[servo_id] * VELOCITY_UNIT_DEG_S
        for servo_id, joint in zip(ids, joints, strict=True)
    )


class SnapWatching:
    """The loop's idle work for a felt leader source (mixed into ``LeaderSource``, which has
    ``felt``, ``snap``, ``rig``, ``leader_ids`` and ``release``)."""

    @property
    def idle_work(self):
        """What the loop runs while it waits for the next cycle: the snap watch while it is
        armed (:meth:`watch_snap`), else None (the loop just waits, as for any source)."""
        return self.watch_snap if self.felt and self.snap.armed is not None else None

    def watch_snap(self) -> None:
        """Between cycles: read the leader's speed; a held leader that snaps toward the region
        is let go at once (:mod:`limbctl.teleop.snap`)."""
        speed = read_velocity(self.rig.bus, self.leader_ids, self.rig.joints)
        now = time.perf_counter()
        if self.snap.armed is not None and speed is not None and self.snap.snaps(speed, now):
            self.release()
