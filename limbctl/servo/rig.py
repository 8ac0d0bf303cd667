"""A calibrated chain of joints on a servo bus: joint angles (rad) <-> ticks, limits, pose; a goal
leaves only through :meth:`Rig.write_goal_ticks`."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from calib.profile import JointProfile, RigProfile
from limbctl.errors import InvalidInputError, SafetyError
from limbctl.servo.bus import ServoBus
from limbctl.servo.control_table import Register
from limbctl.servo.cycle import CycleRead
from limbctl.servo.profiles import joint_tick_limits
from limbctl.servo.setup import configure_servos
from limbctl.servo.ticks import angle_to_ticks, ticks_to_angle


@dataclass(frozen=True)
class GoalTicks:
    """A pose ready for the bus: ticks inside the hard limits, the clamped angles (rad), clamped."""

    ticks: tuple[int, ...]
    angles: tuple[float, ...]
    clamped: bool


class Rig:
    """The chain of joints of ``profile`` driven through ``bus`` (None: it only converts)."""

    def __init__(self, profile: RigProfile, bus: ServoBus | None = None) -> None:
        self.profile = profile
        self.bus = bus
        self.names: tuple[str, ...] = tuple(name for name, _ in profile.joints)
        self.joints: tuple[JointProfile, ...] = tuple(joint for _, joint in profile.joints)

    def __len__(self) -> int:
        return len(self.joints)

    @property
    def ids(self) -> tuple[int, ...]:
        """The servo ids, in chain order."""
        return tuple(joint.id for joint in self.joints)

    def _counted(self, values: Sequence[float], what: str) -> None:
        if len(values) != len(self.joints):
            raise SafetyError(
                f"a rig of {len(self.joints)} joints ({', '.join(self.names)}) takes "
                f"{len(self.joints)} {what}, got {len(values)}: nothing was written"
            )

    # ---- conversion ------------------------------------------------------------------------------
    def angles_to_ticks(self, *angles: float) -> tuple[int, ...]:
        """Nearest ticks for joint angles in rad, one per joint (no clamping)."""
        return tuple(
            int(angle_to_ticks(angle, joint.zero_tick, joint.direction))
            for angle, joint in zip(angles, self.joints, strict=True)
        )

    def ticks_to_angles(self, *ticks: int) -> tuple[float, ...]:
        """Joint angles in rad at encoder positions ``ticks``, one per joint."""
        return tuple(
            float(ticks_to_angle(tick, joint.zero_tick, joint.direction))
            for tick, joint in zip(ticks, self.joints, strict=True)
        )

    def tick_limits(self) -> dict[int, tuple[int, int]]:
        """Per servo id, the tick range strictly inside the hard limits (for EEPROM limits)."""
        return {joint.id: joint_tick_limits(joint) for joint in self.joints}

    def clamp(self, *angles: float) -> tuple[tuple[float, ...], bool]:
        """Joint angles (rad) moved onto the hard limits where beyond them; InvalidInputError if an
        angle is NaN or infinite, SafetyError if not one angle per joint is given.

        Returns
        -------
        angles : tuple of float, one per joint
            Clamped angles (rad).
        clamped : bool
            True if any angle changed.
        """
        self._counted(angles, "angles")
        out = []
        for name, angle, joint in zip(self.names, angles, self.joints, strict=True):
            angle = float(angle)
            if not math.isfinite(angle):
                raise InvalidInputError(f"{name} angle must be finite, got {angle!r}")
            out.append(min(max(angle, joint.min_rad), joint.max_rad))
        clamped = tuple(out)
        return clamped, clamped != tuple(float(angle) for angle in angles)

    def goal_for(self, *angles: float) -> GoalTicks:
        """Clamp a pose to the hard limits and convert it to goal ticks inside them."""
        clamped_angles, clamped = self.clamp(*angles)
        ticks = []
        for angle, joint in zip(clamped_angles, self.joints, strict=True):
            lo, hi = joint_tick_limits(joint)
            tick = int(angle_to_ticks(angle, joint.zero_tick, joint.direction))
            # a clamped angle may round half a tick past its limit: keep the tick inside
            ticks.append(min(max(tick, lo), hi))
        return GoalTicks(tuple(ticks), clamped_angles, clamped)

    def held_pose(self, *angles: float) -> tuple[float, ...]:
        """The joint angles (rad) the servos hold once ``angles`` is written (clamped, in ticks)."""
        return self.ticks_to_angles(*self.goal_for(*angles).ticks)

    # ---- the bus ---------------------------------------------------------------------------------
    def _bus(self) -> ServoBus:
        if self.bus is None:
            raise RuntimeError("this Rig has no bus; give Rig(profile, bus) an open ServoBus")
        return self.bus

    def configure(self, profile_velocity: int = 200, profile_acceleration: int = 50) -> None:
        """Configure the servos for position control, hard limits in EEPROM; torque ends OFF."""
        configure_servos(self._bus(), self.tick_limits(), profile_velocity, profile_acceleration)

    def read_ticks(self) -> tuple[int, ...]:
        """Present ticks, one per joint, all from one sync read."""
        positions = self._bus().read_positions()
        return tuple(positions[joint.id] for joint in self.joints)

    def read_cycle(self, attempts: int = 1, ids: Sequence[int] | None = None) -> CycleRead:
        """The servos' (``ids``, default all) :class:`CycleRead` in ONE sync read."""
        return self._bus().read_cycle(self.ids if ids is None else ids, attempts)

    def pose_of(self, read: CycleRead) -> tuple[float, ...]:
        """Present joint angles (rad), one per joint, from a successful cycle read."""
        return self.ticks_to_angles(*(read.reports[joint.id].present for joint in self.joints))

    def read_pose(self) -> tuple[float, ...]:
        """Present joint angles (rad), one per joint."""
        return self.ticks_to_angles(*self.read_ticks())

    def write_goal_ticks(self, *ticks: int) -> None:
        """Send goal ticks, one per joint, to the servos in one sync write (SafetyError if not one
        tick per joint is given, or one lies outside its hard limits)."""
        self._counted(ticks, "goal ticks")
        for name, tick, joint in zip(self.names, ticks, self.joints, strict=True):
            lo, hi = joint_tick_limits(joint)
            if isinstance(tick, bool) or int(tick) != tick or not lo <= tick <= hi:
                raise SafetyError(
                    f"{name} goal tick {tick!r} is outside the hard limits {lo}..{hi} "
                    f"({joint.min_deg}..{joint.max_deg} deg): nothing was written"
                )
        self._bus().write_goals(
            {joint.id: int(tick) for joint, tick in zip(self.joints, ticks, strict=True)}
        )

    def write_pose(self, *angles: float) -> GoalTicks:
        """Clamp, convert and write a pose (rad, one angle per joint); returns what was written."""
        goal = self.goal_for(*angles)
        self.write_goal_ticks(*goal.ticks)
        return goal

    def set_torque(self, enabled: bool) -> None:
        """Torque on or off on every joint's servo."""
        self._bus().set_torque(enabled, self.ids)

    def torque_enabled(self) -> tuple[bool, ...]:
        """Torque Enable per joint, in one sync read; a servo in alarm does not raise."""
        state = self._bus().sync_read(Register.TORQUE_ENABLE, self.ids, check_alert=False)
        return tuple(bool(state[joint.id]) for joint in self.joints)
