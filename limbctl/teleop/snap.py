"""The snap watch: a held wall lets go the moment its leader starts snapping toward the region."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from limbctl.teleop.brake import BrakeLaw, brakes_soon, outruns


@dataclass(frozen=True)
class SnapLaw:
    """The snap watch's constants (units in their names; ``inertia_kg_m2`` the simulated leader's);
    docs/haptic.md's table gives each value and its reasoning."""

    snap_speed_deg_s: float = 4.0
    still_speed_deg_s: float = 1.5
    rearm_speed_deg_s: float = 0.5
    rearm_span_s: float = 0.012
    hold_nm: float = 0.06
    released: float = 0.35
    rise_s: float = 0.001
    inertia_kg_m2: float = 1.0e-3


def unit_step(present: Sequence[float], goal: Sequence[float]) -> tuple[float, ...] | None:
    """The unit joint-space step from ``present`` toward ``goal`` (rad); None if they are equal."""
    step = [g - p for g, p in zip(goal, present, strict=True)]
    norm = math.sqrt(sum(s * s for s in step))
    return None if norm == 0.0 else tuple(s / norm for s in step)


def along(values: Sequence[float], unit: Sequence[float]) -> float:
    """The component of ``values`` (per joint) along ``unit``."""
    return sum(v * u for v, u in zip(values, unit, strict=True))


@dataclass
class SnapWatch:
    """One leader's watch state: its ``law`` and ``brake`` rules (None: the snap rule alone), the
    wall's setpoint speed ``walk_deg_s`` (deg/s, its Profile Velocity), the unit joint-space step
    toward the correction while ``armed`` and while ``walking``, the walls let go (``cuts`` at a
    snap, ``brakes`` by the brake rules) and ``reads`` between cycles; ``at_read``: judge each
    cycle's read at once (:meth:`judge`); ``rearm_twice``: re-arm only on two still reads within
    ``rearm_span_s`` (or one pushed outward)."""

    law: SnapLaw
    brake: BrakeLaw | None = None
    walk_deg_s: float = 0.0
    armed: tuple[float, ...] | None = None
    walking: tuple[float, ...] | None = None
    cuts: int = 0
    brakes: int = 0
    reads: int = 0
    at_read: bool = False
    rearm_twice: bool = False
    _was_still: bool = False
    _free_still_at: float | None = None  # the last cycle read of a free wall seen still (s)
    _seen: tuple[float, float] | None = None  # speed toward the region (deg/s), read at (s)
    _hold_nm: float = 0.0  # the torque the armed wall held the hand with (N m)
    _torque_seen: tuple[float, float] | None = None  # torque toward the region (N m), at (s)

    @property
    def watching(self) -> bool:
        """Whether the loop should read the leader between the cycles."""
        return self.armed is not None or (self.brake is not None and self.walking is not None)

    def disarm(self) -> None:
        """No watch until a cycle arms it again (the wall went off)."""
        self.armed, self._seen = None, None
        self.walking, self._torque_seen = None, None

    def _snapping(self, velocity_deg_s: Sequence[float], now_s: float) -> bool:
        """Whether the armed leader snaps at ``now_s`` (s); a cut disarms the watch."""
        if self.armed is None:
            return False
        toward = along(velocity_deg_s, self.armed)
        seen, self._seen = self._seen, (toward, now_s)
        if toward <= self.law.snap_speed_deg_s or seen is None:
            return False
        # dv >= RELEASED tau_hold / J min(dt, RISE)   (rad/s^2 -> deg/s^2)
        freed = math.degrees(self.law.released * self._hold_nm / self.law.inertia_kg_m2)
        if toward - seen[0] < freed * min(max(now_s - seen[1], 0.0), self.law.rise_s):
            return False
        self.cuts += 1
        self.disarm()
        return True

    def _braking(
        self, velocity_deg_s: Sequence[float], torque_nm: Sequence[float] | None, now_s: float
    ) -> bool:
        """Whether the brake rules free the wall (``torque_nm``, N m; None: not read)."""
        if self.brake is None or self.walking is None or torque_nm is None:
            return False
        toward = along(velocity_deg_s, self.walking)
        torque = along(torque_nm, self.walking)
        seen, self._torque_seen = self._torque_seen, (torque, now_s)
        still = self.law.still_speed_deg_s
        if not (
            outruns(toward, self.walk_deg_s, torque, self.brake)
            or brakes_soon(toward, still, torque, now_s, seen, self.brake)
        ):
            return False
        self.brakes += 1
        self.disarm()
        return True

    def allows(
        self,
        present: Sequence[float],
        goal: Sequence[float],
        velocity_deg_s: Sequence[float],
        engaged: bool,
        now_s: float,
        torque_nm: Sequence[float] | None = None,
    ) -> bool:
        """Whether a wall toward ``goal`` (rad) may push at ``now_s`` (s) by the rules."""
        unit = unit_step(present, goal)
        if unit is None:
            return True
        if not engaged:
            toward = along(velocity_deg_s, unit)
            still = toward <= self.law.rearm_speed_deg_s
            if not self.rearm_twice:
                return still
            before, self._free_still_at = self._free_still_at, now_s if still else None
            if toward < -self.law.still_speed_deg_s:
                return True  # pushed outward by a hand: nothing for the loop to brake
            return still and before is not None and now_s - before <= self.law.rearm_span_s
        self._free_still_at = None
        snapped = self._snapping(velocity_deg_s, now_s)
        return not (snapped or self._braking(velocity_deg_s, torque_nm, now_s))

    def still(
        self, present: Sequence[float], goal: Sequence[float], velocity_deg_s: Sequence[float]
    ) -> bool:
        """Whether a leader at ``present`` (rad) at ``velocity_deg_s`` (deg/s) is not moving in."""
        unit = unit_step(present, goal)
        return unit is None or along(velocity_deg_s, unit) <= self.law.rearm_speed_deg_s

    def arm(
        self,
        present: Sequence[float],
        goal: Sequence[float] | None,
        velocity_deg_s: Sequence[float],
        torque_nm: Sequence[float],
        engaged: bool,
        now_s: float,
    ) -> None:
        """After a cycle's write: arm on a wall holding a still leader, else disarm."""
        unit = None if goal is None else unit_step(present, goal)
        if unit is None:
            self.disarm()
            self._was_still = False
            return
        self.walking, self._torque_seen = unit, (along(torque_nm, unit), now_s)
        toward = along(velocity_deg_s, unit)
        still = abs(toward) <= self.law.still_speed_deg_s
        holding = engaged and along(torque_nm, unit) >= self.law.hold_nm
        if not holding:
            self.armed, self._seen = None, None
        elif self.armed is not None or (still and self._was_still):
            # armed on a still hold; stays while the wall holds, judged against this hold
            self.armed, self._seen = unit, (toward, now_s)
            self._hold_nm = along(torque_nm, unit)
        self._was_still = still

    def judge(
        self,
        velocity_deg_s: Sequence[float],
        now_s: float,
        torque_nm: Sequence[float] | None = None,
    ) -> bool:
        """At a cycle's read (``at_read``): whether the wall must go, by :meth:`snaps`' rules."""
        snapped = self._snapping(velocity_deg_s, now_s)
        return snapped or self._braking(velocity_deg_s, torque_nm, now_s)

    def snaps(
        self,
        velocity_deg_s: Sequence[float],
        now_s: float,
        torque_nm: Sequence[float] | None = None,
    ) -> bool:
        """Between cycles: whether the wall must go at this read (deg/s; N m)."""
        self.reads += 1
        return self.judge(velocity_deg_s, now_s, torque_nm)
