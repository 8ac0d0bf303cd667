"""What a felt leader's snap watch reads (:mod:`limbctl.teleop.snap`): the leader's speed and
its motors' torque, between the cycles."""

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


def motion_of(
    read: CycleRead, ids: Sequence[int], joints: Sequence, motor: LeaderMotor
) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """The leader's joint speeds (deg/s) and motor torques (N m), joint frame, in a good cycle
    read of a felt leader (Present Velocity and Present Current ride in its cycle read:
    :data:`~limbctl.servo.leader.VELOCITY_MAP`)."""
    speeds = cycle_velocity(read, ids, joints)
    torques = tuple(
        joint.direction * motor.torque_of(present_current(read.reports[servo_id]))
        for servo_id, joint in zip(ids, joints, strict=True)
    )
    return speeds, torques


def read_motion(
    bus, ids: Sequence[int], joints: Sequence, motor: LeaderMotor
) -> tuple[tuple[float, ...], tuple[float, ...]] | None:
    """The leader's joint speeds (deg/s) and motor torques (N m), joint frame, in one try of
    the cycle read (:func:`motion_of`); None if it failed."""
    read = bus.read_cycle(ids=ids, attempts=1)
    return motion_of(read, ids, joints, motor) if read.ok else None


class SnapWatching:
    """The loop's idle work for a felt leader source (mixed into ``LeaderSource``, which has
    ``felt``, ``snap``, ``rig``, ``leader_ids``, ``motor``, ``release``, ``last_push``,
    ``silence`` and ``resume``)."""

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
        motion = self.read_motion()
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
        motion = self.read_motion()
        now = time.perf_counter()
        if self.snap.watching and motion is not None and self.snap.snaps(motion[0], now, motion[1]):
            self.release()

    def read_leader(self) -> CycleRead | None:
        """The cycle's read of the felt leader, one try and, after a miss, one more (a lost
        reply need not drop the mirroring); every miss switches the push off at once
        (:meth:`missed`). While a leader servo is silent, the leader is read only once per
        probe interval (:class:`~limbctl.teleop.sources.leader_silence.LeaderSilence`): None
        on the cycles between."""
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
        """A failed read of the leader (``read``): every leader servo's push goes off at once
        (one that does not answer may be gone, and the others must not push the hand alone),
        and the miss is counted toward a dropout (:class:`LeaderSilence`). A wall that was on
        comes back in the next cycle whose read answers, as the wall it was (``resume``: one
        lost reply costs the hand the milliseconds of the retry, not the re-arm's two still
        reads); a second miss in a row finds it off and leaves it to the re-arm."""
        self.silence.missed(read, time.perf_counter())
        self.resume = self.last_push is not None and self.last_push.goal_current > 0
        if self.felt:
            self.release()

    def read_motion(self) -> tuple[tuple[float, ...], tuple[float, ...]] | None:
        """The leader's joint speeds (deg/s) and torques (N m) in one try of the cycle read
        (:func:`motion_of`); a failed read switches every leader servo's push off at once
        (``missed``) and gives None. One try, no diagnostic pings: a silent servo costs one
        reply timeout (6.3 ms on the simulator's pty), not a stalled loop (a plain sync read's
        three tries and pings took 31 ms and more, the push left on meanwhile). A failing port
        (:class:`~limbctl.errors.PortError`) is a failed read here; the cycle's read raises it."""
        try:
            read = self.rig.bus.read_cycle(ids=self.leader_ids, attempts=1)
        except BusError as exc:
            read = CycleRead({}, (), str(exc))
        if not read.ok:
            self.missed(read)
            return None
        return motion_of(read, self.leader_ids, self.rig.joints, self.motor)
