"""The snap watch: a held wall lets go the moment its leader starts snapping toward the region.

Let go, a leader pressed against the wall snaps onto the servo's setpoint, which leads it, and
the servo's loop brakes it there (an outward pull 2-10 ms later, too soon for a 200 Hz read).
So while a wall holds a still leader its speed is read about every millisecond between the
cycles: the watch *arms* on a still leader held with at least HOLD, *cuts* (Goal Current 0) when
the speed toward the region passes SNAP having risen as a let go makes it, and a free wall
*re-arms* only on a leader read as not moving in. While any wall is on, the brake rules
(:mod:`limbctl.teleop.brake`) also apply. The watch only ever takes torque away; docs/haptic.md
("The snap watch") states the rules and figures.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from limbctl.teleop.brake import BrakeLaw, brakes_soon, outruns


@dataclass(frozen=True)
class SnapLaw:
    """The snap watch's constants.

    Attributes
    ----------
    snap_speed_deg_s : float
        4 deg/s (3 velocity units): over a held leader's reading (0, a unit of noise) and
        under what a let go reaches within a millisecond (about 17 deg/s from a 0.3 N m hold
        on the simulated 1e-3 kg m^2 leader: it accelerates at tau / J).
    still_speed_deg_s : float
        1.5 deg/s: one velocity unit (1.37 deg/s) read as still: the watch arms on a held
        leader read so, and the brake rules watch only a leader moving in faster.
    rearm_speed_deg_s : float
        0.5 deg/s, under one velocity unit: a free wall comes on only on a leader read as not
        moving in at all, since the wall starts with its setpoint at the leader and the loop
        brakes any leader still moving in (outward).
    rearm_span_s : float
        12 ms: with the watch's ``rearm_twice``, the cycle read before must be this recent to
        count (two cycles at 200 Hz, one of them up to 2 ms late); an older one says nothing of
        the leader now.
    hold_nm : float
        0.06 N m: the watch arms only while the motor pushes a hand at least this hard (the
        0.02 N m/deg hand pressing 5 deg beyond is held with 0.09 N m); the loop walking a
        released leader back needs 0.02-0.03 N m.
    released : float
        0.5: a let go frees the whole hold at once (the leader speeds up at about tau_hold /
        J); a grip fading over 50 ms gives about a seventh of that, and a cut then leaves the
        leader to a hand still pushing out. Half: between the two.
    rise_s : float
        1 ms: the rise is judged over at most a millisecond whatever the gap between two reads
        (2-3 ms over the pty): a snap keeps speeding up for 2-3 ms, so a read too soon leaves
        it to the next, while a fading grip gains about 5 deg/s over 2.5 ms, under the
        8.6 deg/s of a 0.3 N m hold.
    inertia_kg_m2 : float
        1e-3 kg m^2, the simulated leader's inertia at each joint (``firmware_sim/leader.py``);
        a real leader's is to be measured (the coast-down that gives its damping gives it too).
        Too high, a relaxing hand reads as a let go; too low, let goes are missed.
    """

    snap_speed_deg_s: float = 4.0
    still_speed_deg_s: float = 1.5
    rearm_speed_deg_s: float = 0.5
    rearm_span_s: float = 0.012
    hold_nm: float = 0.06
    released: float = 0.5
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
    """One leader's watch state.

    Attributes
    ----------
    law : SnapLaw
    brake : BrakeLaw or None
        The brake rules (:mod:`limbctl.teleop.brake`); None: the snap rule alone.
    walk_deg_s : float
        How fast the wall's setpoint walks toward the region (deg/s): its Profile Velocity.
    armed : tuple of float or None
        The unit step toward the correction (joint space) while armed.
    walking : tuple of float or None
        The unit step toward the correction while a wall is on (the brake rules watch it).
    cuts : int
        How many times the watch (or a cycle's read) let a held wall go at a snap.
    brakes : int
        How many times the brake rules let a wall go.
    reads : int
        How many reads the watch was handed between the cycles.
    at_read : bool
        Whether the source judges each cycle's read as soon as it is read (:meth:`judge`) and
        writes a cut at once, before the cycle's gate work (1-2 ms over the pty, by which the
        loop had begun braking). False: judged when its push is decided (:meth:`allows`).
    rearm_twice : bool
        Whether a free wall comes back only when the cycle's read *and* the one before (within
        ``rearm_span_s``) show the leader not moving in, or at once on a leader pushed outward
        faster than STILL: a hand reversing from pushing out to pulling in leaves the leader
        still for a millisecond or two, and a wall back then met its pull at once. False: one
        still read.
    """

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
        """Whether the loop should read the leader between the cycles: a wall is on and some
        rule watches it."""
        return self.armed is not None or (self.brake is not None and self.walking is not None)

    def disarm(self) -> None:
        """No watch until a cycle arms it again (the wall went off)."""
        self.armed, self._seen = None, None
        self.walking, self._torque_seen = None, None

    def _snapping(self, velocity_deg_s: Sequence[float], now_s: float) -> bool:
        """Whether the armed leader, read at ``now_s``, snaps: past SNAP, risen since the last
        read by what RELEASED of the hold would give it; a cut disarms the watch."""
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
        """Whether a wall that is on must go by the brake rules at this read (``torque_nm``:
        the motors' read torque, joint frame, N m; None: not read); a cut disarms the watch."""
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
        """Whether a wall the law would push with (goal ``goal``, rad) may push at this read
        (at ``now_s``, s): not if it is free and the leader still moves in (re-arm), nor if it
        is armed and the leader snaps (cut), nor if the brake rules free it."""
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
        """Whether a leader at ``present`` (rad) moving at ``velocity_deg_s`` (joint frame,
        deg/s) is read as not moving in toward ``goal`` (the re-arm speed); a read that leaves
        the watch's state as it is (the source's read just before a wall comes on)."""
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
        """After a cycle's write: arm when the wall (goal ``goal``, None if free) holds a still
        leader against a hand (read at ``now_s``, s), else disarm; the brake rules watch any
        wall that is on."""
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
            # armed on a still hold; it stays while the wall holds, the leader creeping or not,
            # judged against the hold as read now
            self.armed, self._seen = unit, (toward, now_s)
            self._hold_nm = along(torque_nm, unit)
        self._was_still = still

    def judge(
        self,
        velocity_deg_s: Sequence[float],
        now_s: float,
        torque_nm: Sequence[float] | None = None,
    ) -> bool:
        """At a cycle's read (``at_read``): whether a wall that is on must go at once, by the
        rules :meth:`snaps` applies between the cycles. A wall kept here is not judged again on
        the same read (:meth:`allows` with ``judged``)."""
        snapped = self._snapping(velocity_deg_s, now_s)
        return snapped or self._braking(velocity_deg_s, torque_nm, now_s)

    def snaps(
        self,
        velocity_deg_s: Sequence[float],
        now_s: float,
        torque_nm: Sequence[float] | None = None,
    ) -> bool:
        """Between cycles: whether a wall that is on must go at this read of the leader's speed
        (``velocity_deg_s``, joint frame, deg/s) and torque (``torque_nm``, N m; None: not
        read) at ``now_s`` (s): an armed leader snaps, or the brake rules free it (then the
        caller writes Goal Current 0)."""
        self.reads += 1
        return self.judge(velocity_deg_s, now_s, torque_nm)
