"""A calibrated three-servo gimbal: pan, tilt and roll (rad) <-> ticks, limits, present pose.

:class:`RollRig` is a :class:`limbctl.servo.rig.Rig` whose poses are ``(pan, tilt, roll)``: the
same exact conversion per joint (``ticks = zero_tick + direction * angle * 4096 / (2 pi)``,
rounded), the same clamp to each joint's hard limits, the same refusal of a tick outside them,
and one sync read / one sync write for all three servos. Its orientation is the full
``q = Rz(pan) Ry(-tilt) Rx(roll)`` (:mod:`limbctl.geometry.gimbal3`), twist included.
:func:`rig_for` picks the class a profile needs, so a two-servo rig stays a plain :class:`Rig`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from calib.profile import RigProfile
from limbctl.errors import InvalidInputError, SafetyError
from limbctl.geometry.gimbal import pan_tilt_to_direction
from limbctl.geometry.gimbal3 import pose_quat_scalar
from limbctl.servo.bus import ServoBus
from limbctl.servo.control_table import Register
from limbctl.servo.cycle import CycleRead
from limbctl.servo.profiles import joint_tick_limits
from limbctl.servo.rig import Rig
from limbctl.servo.ticks import angle_to_ticks, ticks_to_angle

Pose3 = tuple[float, float, float]
JOINT_NAMES = ("pan", "tilt", "roll")


@dataclass(frozen=True)
class GoalTicks3:
    """A three-joint pose ready for the bus.

    Attributes
    ----------
    ticks : tuple of 3 int
        Goal ticks of pan, tilt and roll (inside the hard limits).
    angles : tuple of 3 float
        The joint angles after clamping (rad).
    clamped : bool
        True if any angle had to be moved onto a hard limit.
    """

    ticks: tuple[int, int, int]
    angles: Pose3
    clamped: bool


class RollRig(Rig):
    """The three-servo gimbal of ``profile`` (which must have a roll joint), driven through
    ``bus``; poses are ``(pan, tilt, roll)`` in rad."""

    def __init__(self, profile: RigProfile, bus: ServoBus | None = None) -> None:
        if profile.roll is None:
            raise InvalidInputError(
                f"rig {profile.name!r} has no roll joint; a two-servo rig is a plain Rig"
            )
        super().__init__(profile, bus)
        self.joints = (profile.pan, profile.tilt, profile.roll)  # type: ignore[assignment]

    @property
    def roll_limits(self) -> tuple[float, float]:
        """The roll joint's hard limits (rad)."""
        return self.joints[2].min_rad, self.joints[2].max_rad

    def clamp3(self, pose: Pose3) -> tuple[Pose3, bool]:
        """Angles moved onto the hard limits where beyond them, and whether any moved.

        Raises
        ------
        InvalidInputError
            If an angle is NaN or infinite (never clamped into range silently).
        """
        out = []
        for name, angle, joint in zip(JOINT_NAMES, pose, self.joints, strict=True):
            angle = float(angle)
            if not math.isfinite(angle):
                raise InvalidInputError(f"{name} angle must be finite, got {angle!r}")
            # clamp: min_rad <= angle <= max_rad
            out.append(min(max(angle, joint.min_rad), joint.max_rad))
        clamped_pose = (out[0], out[1], out[2])
        return clamped_pose, clamped_pose != tuple(float(a) for a in pose)

    def goal_for3(self, pose: Pose3) -> GoalTicks3:
        """Clamp a pose to the hard limits and convert it to goal ticks inside them."""
        angles, clamped = self.clamp3(pose)
        ticks = []
        for angle, joint in zip(angles, self.joints, strict=True):
            lo, hi = joint_tick_limits(joint)
            tick = int(angle_to_ticks(angle, joint.zero_tick, joint.direction))
            # a clamped angle may round half a tick past its limit: keep the tick inside
            ticks.append(min(max(tick, lo), hi))
        return GoalTicks3((ticks[0], ticks[1], ticks[2]), angles, clamped)

    def angles_of(self, ticks: tuple[int, ...]) -> Pose3:
        """Joint angles (rad) at encoder positions (pan, tilt, roll)."""
        pan, tilt, roll = (
            float(ticks_to_angle(tick, joint.zero_tick, joint.direction))
            for tick, joint in zip(ticks, self.joints, strict=True)
        )
        return pan, tilt, roll

    def held_pose3(self, pose: Pose3) -> Pose3:
        """The joint angles (rad) the servos hold once ``pose`` is written (clamped, rounded)."""
        return self.angles_of(self.goal_for3(pose).ticks)

    def read_ticks(self) -> tuple[int, int, int]:  # type: ignore[override]
        """Present ticks (pan, tilt, roll), from one sync read."""
        positions = self._bus().read_positions()
        return tuple(positions[joint.id] for joint in self.joints)  # type: ignore[return-value]

    def pose_of(self, read: CycleRead) -> Pose3:  # type: ignore[override]
        """Present joint angles (pan, tilt, roll) in rad from a successful cycle read."""
        return self.angles_of(tuple(read.reports[joint.id].present for joint in self.joints))

    def read_pose(self) -> Pose3:  # type: ignore[override]
        """Present joint angles (pan, tilt, roll) in rad."""
        return self.angles_of(self.read_ticks())

    def read_direction(self) -> np.ndarray:
        """Present limb direction, shape (3,), unit (roll does not move it)."""
        pan, tilt, _ = self.read_pose()
        return pan_tilt_to_direction(pan, tilt)

    def read_quaternion(self) -> np.ndarray:
        """Present full orientation ``Rz(pan) Ry(-tilt) Rx(roll)``, shape (4,), w >= 0."""
        return pose_quat_scalar(*self.read_pose())

    def write_goal_ticks(self, *ticks: int) -> None:  # type: ignore[override]
        """Send goal ticks (pan, tilt, roll) to the three servos in one sync write.

        Raises
        ------
        SafetyError
            If a tick lies outside its joint's hard limits' tick range (nothing is written).
        """
        if len(ticks) != 3:
            raise SafetyError(f"a three-servo rig takes 3 goal ticks, got {len(ticks)}")
        for name, tick, joint in zip(JOINT_NAMES, ticks, self.joints, strict=True):
            lo, hi = joint_tick_limits(joint)
            if isinstance(tick, bool) or int(tick) != tick or not lo <= tick <= hi:
                raise SafetyError(
                    f"{name} goal tick {tick!r} is outside the hard limits {lo}..{hi} "
                    f"({joint.min_deg}..{joint.max_deg} deg): nothing was written"
                )
        self._bus().write_goals(
            {joint.id: int(tick) for joint, tick in zip(self.joints, ticks, strict=True)}
        )

    def write_pose(self, *pose: float) -> GoalTicks3:  # type: ignore[override]
        """Clamp, convert and write a pose (pan, tilt, roll) in rad; returns what was written."""
        if len(pose) != 3:
            raise SafetyError(f"a three-servo rig takes (pan, tilt, roll), got {len(pose)} angles")
        goal = self.goal_for3((pose[0], pose[1], pose[2]))
        self.write_goal_ticks(*goal.ticks)
        return goal

    def torque_enabled(self) -> tuple[bool, bool, bool]:  # type: ignore[override]
        """Torque Enable of (pan, tilt, roll), in one sync read; a servo in alarm does not raise."""
        state = self._bus().sync_read(Register.TORQUE_ENABLE, self.profile.ids, check_alert=False)
        return tuple(bool(state[joint.id]) for joint in self.joints)  # type: ignore[return-value]


def rig_for(profile: RigProfile, bus: ServoBus | None = None) -> Rig:
    """A :class:`RollRig` for a profile with a roll joint, else a plain :class:`Rig`."""
    return Rig(profile, bus) if profile.roll is None else RollRig(profile, bus)
