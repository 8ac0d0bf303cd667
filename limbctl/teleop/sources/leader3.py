"""A three-servo leader gimbal as a command source that feels the edge of a twist region.

``leader:ID,ID,ID`` (pan, tilt, roll ids) beside a three-servo follower: each cycle the leader's
full orientation is the command, gated by :class:`limbctl.teleop.gate.Gate`. A leader whose
model senses current (:data:`limbctl.servo.leader.FELT_MODELS`) runs all three servos in
current-based position mode and pushes back beyond the region by the law of
:mod:`limbctl.teleop.haptic_push`. Everything else is the two-servo leader's
(:class:`~limbctl.teleop.sources.leader.LeaderSource`, whose cycle this class runs): the set-up,
the rate check at start, the pace watch, Goal Current 0 on all three at once on any doubt (a
leader that is silent, in alarm or restarted, a failed bus, a held gate, a fault, the session's
end), the wall kept while only the follower's read failed within FOLLOWER_GRACE_S, Torque Enable
off and on when the wall comes on, Profile Velocity once with it, the Bus Watchdog as the
backstop. What is its own: three joints' poses and goals, the law on SO(3) and its notice.
Other models stay passive.
"""

from __future__ import annotations

from limbctl.errors import ConfigError
from limbctl.servo.ticks import angle_to_ticks
from limbctl.teleop.haptic_push import Push, held, push_for
from limbctl.teleop.sources.leader import LeaderSource


class LeaderSource3(LeaderSource):
    """Mirror a hand-moved three-servo leader; a current-sensing one feels the twist region.

    Parameters
    ----------
    rig : Rig
        The three-servo follower rig; its bus also holds the leader's ids.
    leader_ids : (int, int, int)
        The leader's (pan, tilt, roll) ids.
    rate_hz, law
        As :class:`~limbctl.teleop.sources.leader.LeaderSource`.
    """

    felt_joints = 3

    def __init__(self, rig, leader_ids: tuple[int, ...], rate_hz: float = 200.0, law=None) -> None:
        if len(leader_ids) != 3:
            raise ConfigError(f"a three-servo leader needs three ids, got {leader_ids}")
        super().__init__(rig, leader_ids, rate_hz, law)
        #: The leader's (pan, tilt, roll) as last read (rad); None before the first read.
        self.last_pose3: tuple[float, float, float] | None = None

    def _feel_notice(self, model: str, cap: int) -> str:
        return (
            f"leader {model} (three servos) feels the edge in swing and twist: free inside, "
            f"pushed back beyond {self.law.deadband_deg:g} deg of rotation, at most "
            f"{self.motor.torque_of(cap):.2f} N m (Current Limit {cap})"
        )

    def _seen(self, pose: tuple[float, float, float]) -> None:
        self.last_pose3, self.last_pose = pose, (pose[0], pose[1])

    def _law(self, gate, pose, q, previous, period: float, engaged: bool, torque, speed) -> Push:
        """This cycle's push by the three-servo law (:func:`~limbctl.teleop.haptic_push.push_for`),
        the correction's roll unwrapped within the gate's roll limits."""
        limits = tuple(zip(gate.limits.joint_min, gate.limits.joint_max))
        corrected = gate.envelope.correct(q)
        return push_for(
            self.law,
            self.motor,
            pose,
            q,
            corrected,
            previous,
            period,
            engaged,
            torque,
            speed,
            limits,
        )

    @staticmethod
    def _free(pose: tuple[float, float, float]) -> Push:
        return held(pose)

    def _goal_ticks(self, push: Push) -> tuple[int, ...]:
        return tuple(
            int(angle_to_ticks(angle, joint.zero_tick, joint.direction))
            for angle, joint in zip(push.goal, self.rig.joints, strict=True)
        )
