"""A calibrated gimbal on a servo bus: joint angles (rad) <-> ticks, hard limits, present pose.

:class:`Rig` is deliberately dumb and exact. It converts with the rig profile's ``zero_tick``
and ``direction`` (``ticks = zero_tick + direction * angle * 4096 / (2 pi)``, rounded), clamps
to the profile's hard limits and says whether it did, and reads the present pose. It never
moves the limb on its own: the only way a goal leaves it is :meth:`Rig.write_goal_ticks`
(and :meth:`Rig.write_pose`, which clamps, converts and calls it), used by the gate's caller.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from calib.profile import JointProfile, RigProfile
from limbctl.errors import InvalidInputError, SafetyError
from limbctl.geometry.gimbal import pan_tilt_to_direction, pan_tilt_to_quat
from limbctl.servo.bus import ServoBus
from limbctl.servo.control_table import Register
from limbctl.servo.cycle import CycleRead
from limbctl.servo.profiles import joint_tick_limits
from limbctl.servo.setup import configure_servos
from limbctl.servo.ticks import angle_to_ticks, ticks_to_angle


@dataclass(frozen=True)
class GoalTicks:
    """A pose ready for the bus.

    Attributes
    ----------
    pan, tilt : int
        Goal ticks of the pan and tilt servos (inside the hard limits).
    pan_rad, tilt_rad : float
        The joint angles after clamping (rad).
    clamped : bool
        True if either angle had to be moved onto a hard limit.
    """

    pan: int
    tilt: int
    pan_rad: float
    tilt_rad: float
    clamped: bool


class Rig:
    """The gimbal described by ``profile``, driven through ``bus``.

    Parameters
    ----------
    profile : RigProfile
        Ids, zero ticks, directions and hard limits.
    bus : ServoBus or None
        An open bus; None gives a rig that can only convert (for planning and tests).
    """

    def __init__(self, profile: RigProfile, bus: ServoBus | None = None) -> None:
        self.profile = profile
        self.bus = bus
        self.joints: tuple[JointProfile, JointProfile] = (profile.pan, profile.tilt)

    # ---- conversion ------------------------------------------------------------------------------
    def angles_to_ticks(self, pan: float, tilt: float) -> tuple[int, int]:
        """Nearest ticks ``(pan, tilt)`` for joint angles in rad (no clamping)."""
        return tuple(  # type: ignore[return-value]
            int(angle_to_ticks(angle, joint.zero_tick, joint.direction))
            for angle, joint in zip((pan, tilt), self.joints, strict=True)
        )

    def ticks_to_angles(self, pan_tick: int, tilt_tick: int) -> tuple[float, float]:
        """Joint angles ``(pan, tilt)`` in rad at encoder positions ``(pan_tick, tilt_tick)``."""
        return tuple(  # type: ignore[return-value]
            float(ticks_to_angle(tick, joint.zero_tick, joint.direction))
            for tick, joint in zip((pan_tick, tilt_tick), self.joints, strict=True)
        )

    def tick_limits(self) -> dict[int, tuple[int, int]]:
        """Per servo id, the tick range strictly inside the hard limits (for EEPROM limits)."""
        return {joint.id: joint_tick_limits(joint) for joint in self.joints}

    def clamp(self, pan: float, tilt: float) -> tuple[float, float, bool]:
        """Joint angles (rad) moved onto the hard limits where beyond them.

        Returns
        -------
        pan, tilt : float
            Clamped angles (rad).
        clamped : bool
            True if either angle changed.

        Raises
        ------
        InvalidInputError
            If an angle is NaN or infinite (never clamped into range silently).
        """
        out = []
        for name, angle, joint in zip(("pan", "tilt"), (pan, tilt), self.joints, strict=True):
            angle = float(angle)
            if not math.isfinite(angle):
                raise InvalidInputError(f"{name} angle must be finite, got {angle!r}")
            # clamp: min_rad <= angle <= max_rad
            out.append(min(max(angle, joint.min_rad), joint.max_rad))
        return out[0], out[1], (out[0], out[1]) != (float(pan), float(tilt))

    def goal_for(self, pan: float, tilt: float) -> GoalTicks:
        """Clamp a pose to the hard limits and convert it to goal ticks inside them."""
        pan_c, tilt_c, clamped = self.clamp(pan, tilt)
        ticks = []
        for angle, joint in zip((pan_c, tilt_c), self.joints, strict=True):
            lo, hi = joint_tick_limits(joint)
            tick = int(angle_to_ticks(angle, joint.zero_tick, joint.direction))
            # a clamped angle may round half a tick past its limit: keep the tick inside
            ticks.append(min(max(tick, lo), hi))
        return GoalTicks(ticks[0], ticks[1], pan_c, tilt_c, clamped)

    def held_pose(self, pan: float, tilt: float) -> tuple[float, float]:
        """The joint angles (rad) the servos hold once ``(pan, tilt)`` is written: clamped to
        the hard limits and rounded to whole ticks."""
        goal = self.goal_for(pan, tilt)
        return self.ticks_to_angles(goal.pan, goal.tilt)

    # ---- the bus ---------------------------------------------------------------------------------
    def _bus(self) -> ServoBus:
        if self.bus is None:
            raise RuntimeError("this Rig has no bus; give Rig(profile, bus) an open ServoBus")
        return self.bus

    def configure(self, profile_velocity: int = 200, profile_acceleration: int = 50) -> None:
        """Configure the servos for position control with the hard limits in EEPROM.

        Turns torque OFF (see :func:`limbctl.servo.setup.configure_servos`).
        """
        configure_servos(self._bus(), self.tick_limits(), profile_velocity, profile_acceleration)

    def read_ticks(self) -> tuple[int, int]:
        """Present ticks ``(pan, tilt)``, both from one sync read."""
        positions = self._bus().read_positions()
        return positions[self.profile.pan.id], positions[self.profile.tilt.id]

    @property
    def ids(self) -> tuple[int, int]:
        """The servo ids ``(pan, tilt)``."""
        return self.profile.ids

    def read_cycle(self, attempts: int = 1, ids: Sequence[int] | None = None) -> CycleRead:
        """The servos' (``ids``, default both) position, goal, torque, alarm and PWM in ONE sync
        read (``attempts`` tries)."""
        return self._bus().read_cycle(self.profile.ids if ids is None else ids, attempts)

    def pose_of(self, read: CycleRead) -> tuple[float, float]:
        """Present joint angles ``(pan, tilt)`` in rad from a successful cycle read."""
        reports = read.reports
        return self.ticks_to_angles(
            reports[self.profile.pan.id].present, reports[self.profile.tilt.id].present
        )

    def read_pose(self) -> tuple[float, float]:
        """Present joint angles ``(pan, tilt)`` in rad."""
        return self.ticks_to_angles(*self.read_ticks())

    def read_direction(self) -> np.ndarray:
        """Present limb direction, shape (3,), unit."""
        return pan_tilt_to_direction(*self.read_pose())

    def read_quaternion(self) -> np.ndarray:
        """Present orientation as a twist-free unit quaternion (w, x, y, z), shape (4,)."""
        return pan_tilt_to_quat(*self.read_pose())

    def write_goal_ticks(self, pan_tick: int, tilt_tick: int) -> None:
        """Send goal ticks to both servos in one sync write.

        Raises
        ------
        SafetyError
            If a tick lies outside the hard limits' tick range (nothing is written).
        """
        for name, tick, joint in zip(
            ("pan", "tilt"), (pan_tick, tilt_tick), self.joints, strict=True
        ):
            lo, hi = joint_tick_limits(joint)
            if isinstance(tick, bool) or int(tick) != tick or not lo <= tick <= hi:
                raise SafetyError(
                    f"{name} goal tick {tick!r} is outside the hard limits {lo}..{hi} "
                    f"({joint.min_deg}..{joint.max_deg} deg): nothing was written"
                )
        self._bus().write_goals(
            {self.profile.pan.id: int(pan_tick), self.profile.tilt.id: int(tilt_tick)}
        )

    def write_pose(self, pan: float, tilt: float) -> GoalTicks:
        """Clamp, convert and write a pose (rad); returns what was written."""
        goal = self.goal_for(pan, tilt)
        self.write_goal_ticks(goal.pan, goal.tilt)
        return goal

    def set_torque(self, enabled: bool) -> None:
        """Torque on or off on both servos."""
        self._bus().set_torque(enabled, self.profile.ids)

    def torque_enabled(self) -> tuple[bool, bool]:
        """Torque Enable of (pan, tilt), in one sync read; a servo in alarm does not raise."""
        state = self._bus().sync_read(Register.TORQUE_ENABLE, self.profile.ids, check_alert=False)
        return bool(state[self.profile.pan.id]), bool(state[self.profile.tilt.id])
