"""The one place every commanded pose passes before it may become a goal position.

Per command (the safety model in docs/architecture.md):

1. ``correct``: the envelope returns the target itself inside the taught region, else the
   nearest orientation on its boundary;
2. slew limit: the limb direction moves at most ``max_step`` (rad) per cycle from the last safe
   pose along the great circle toward the corrected target; the intermediate pose is corrected
   again, so a non-convex region is followed, never cut across. When that corrected step makes
   no way (a concave wall between the two holds it), the step aims instead at a point of a
   route along the region (:class:`~limbctl.teleop.route.Router`), so the wall is gone round;
3. inverse kinematics to (pan, tilt), keeping the current pan at the singularity;
4. hard joint limits clamp (pan, tilt); a joint step larger than ``max_joint_step`` is scaled
   down, both joints by one factor, so the largest step is ``max_joint_step`` (``SLEWED``);
5. final check: the pose that would be written is inside the region (``contains``) and inside
   the hard limits; if not, the last safe pose is held.

The outcome of a cycle is a value (:class:`Outcome`), not an exception (after ruckig).
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from limbctl.errors import ConfigError
from limbctl.geometry import scalar
from limbctl.geometry.scalar import Vec3
from limbctl.teleop.route import Router


class RegionModel(Protocol):
    """What the gate needs of an envelope (any :class:`limbctl.envelope.Envelope`)."""

    def contains(self, q: np.ndarray) -> bool | np.ndarray: ...

    def correct(self, q: np.ndarray) -> np.ndarray: ...


class Outcome(enum.Enum):
    """What the gate did with one command."""

    PASSED = "passed"  # inside the region, within one step: written as commanded
    CORRECTED = "corrected"  # moved onto the region's boundary
    CLAMPED = "clamped"  # a hard joint limit trimmed it
    SLEWED = "slewed"  # on its way: the step limit shortened it
    HELD = "held"  # nothing safe to do with it: the last safe pose is kept

    @classmethod
    def strongest(cls, corrected: bool, clamped: bool, slewed: bool) -> Outcome:
        """The outcome a cycle reports for what its stages did: CLAMPED > CORRECTED > SLEWED >
        PASSED (HELD is decided before, by the final check)."""
        if clamped:
            return cls.CLAMPED
        if corrected:
            return cls.CORRECTED
        return cls.SLEWED if slewed else cls.PASSED


#: Default gate tolerance (deg): how far outside the region a written pose may be; a seventh of
#: the 0.072 deg a pose moves when rounded to 4096-tick servos, so rounding dominates the error.
REGION_TOLERANCE_DEG = 0.01
#: Largest | |q| - 1 | of a target the gate follows: the parser's quaternions are normalised to
#: ~1e-16, so anything further off was damaged on the way and is held.
UNIT_NORM_TOLERANCE = 1e-6


@dataclass(frozen=True)
class GateLimits:
    """Hard limits and rates the gate enforces; angles in radians.

    Attributes
    ----------
    pan_min, pan_max, tilt_min, tilt_max : float
        Hard joint limits (rad) from the rig profile.
    max_step : float
        Largest change of limb direction per cycle (rad).
    max_joint_step : float
        Largest change of either joint per cycle (rad); guards the singularity where a small
        direction change asks for a large pan swing.
    region_tolerance : float
        How far (rad, limb direction) outside the learned region a written pose may be: the
        round trip through joint angles moves a boundary point by ~1e-12 rad, never more.
    """

    pan_min: float
    pan_max: float
    tilt_min: float
    tilt_max: float
    max_step: float
    max_joint_step: float
    region_tolerance: float = math.radians(REGION_TOLERANCE_DEG)

    def __post_init__(self) -> None:
        values = [getattr(self, f) for f in self.__dataclass_fields__]
        if not all(math.isfinite(v) for v in values):
            raise ConfigError(f"gate limits must be finite: {self}")
        if not (self.pan_min < self.pan_max and self.tilt_min < self.tilt_max):
            raise ConfigError(f"gate limits: each min must be below its max: {self}")
        if not (self.max_step > 0 and self.max_joint_step > 0 and self.region_tolerance >= 0):
            raise ConfigError(
                "gate limits: max_step and max_joint_step must be positive, "
                "region_tolerance non-negative"
            )


def written_tolerance_deg(ticks_per_turn: int = 4096) -> float:
    """How far (deg) a goal that reached a servo may lie outside the model's region.

    The gate's tolerance (``REGION_TOLERANCE_DEG``) plus the rounding of both joints to whole
    ticks: half a tick each moves the limb direction by at most ``sqrt(2) * half tick``
    (``|dd|^2 = (cos(tilt) dpan)^2 + dtilt^2``). 0.072 deg for 4096-tick servos.
    """
    half_tick = 360.0 / ticks_per_turn / 2.0
    return REGION_TOLERANCE_DEG + math.sqrt(2.0) * half_tick


@dataclass(frozen=True)
class GateResult:
    """One cycle's answer.

    Attributes
    ----------
    pan, tilt : float
        The pose to write (rad); the last safe pose when ``outcome`` is HELD.
    outcome : Outcome
        The strongest thing that happened (HELD > CLAMPED > CORRECTED > SLEWED > PASSED).
    corrected, clamped, slewed : bool
        Each stage that changed the command.
    reason : str
        Why the command was held, empty otherwise.
    """

    pan: float
    tilt: float
    outcome: Outcome
    corrected: bool = False
    clamped: bool = False
    slewed: bool = False
    reason: str = ""

    @property
    def pose(self) -> tuple[float, float]:
        """``(pan, tilt)`` (rad), what the rig writes."""
        return (self.pan, self.tilt)


class Gate:
    """Turns commanded orientations into safe joint goals, one cycle at a time.

    Parameters
    ----------
    envelope : RegionModel
        The trained region (``contains``/``correct`` on single quaternions).
    limits : GateLimits
        Hard limits and per-cycle step limits.
    """

    def __init__(self, envelope: RegionModel, limits: GateLimits) -> None:
        self.envelope = envelope
        self.limits = limits
        self.router = Router(envelope, twist=False)
        self._pan: float | None = None
        self._tilt: float | None = None
        self._direction: Vec3 | None = None

    @property
    def safe_pose(self) -> tuple[float, float] | None:
        """The last pose the gate let through (rad), or None before :meth:`start`."""
        if self._pan is None or self._tilt is None:
            return None
        return self._pan, self._tilt

    def is_safe(self, pan: float, tilt: float) -> bool:
        """True when the pose is finite, inside the hard limits and inside the region."""
        lim = self.limits
        if not (lim.pan_min <= pan <= lim.pan_max and lim.tilt_min <= tilt <= lim.tilt_max):
            return False  # NaN fails every comparison above and lands here
        direction = scalar.direction(pan, tilt)
        q = scalar.swing(direction)
        if bool(self.envelope.contains(q)):
            return True
        # inside up to the stated tolerance: the nearest region point is within region_tolerance
        nearest = scalar.limb(self.envelope.correct(q))
        return scalar.angle(direction, nearest) <= lim.region_tolerance

    def start(self, current_pan: float, current_tilt: float) -> None:
        """Begin from the limb's present pose, which must already be safe.

        Raises
        ------
        SafetyError
            When the present pose is outside the region or the hard limits: the gate will not
            drive the limb from there (move it inside by hand with torque off, then start again).
        """
        from limbctl.errors import SafetyError

        if not self.is_safe(current_pan, current_tilt):
            raise SafetyError(
                f"the limb is at pan {math.degrees(current_pan):.1f} deg, tilt "
                f"{math.degrees(current_tilt):.1f} deg, outside the taught region or the rig's "
                "hard limits; move it inside by hand (torque off) before starting"
            )
        self._pan, self._tilt = float(current_pan), float(current_tilt)
        self._direction = scalar.direction(self._pan, self._tilt)
        if self.router.batched:  # a fitted region: its roadmap now, before the loop's clock
            self.router.prepare(scalar.swing(self._direction))

    def hold(self, reason: str) -> GateResult:
        """Keep the last safe pose."""
        if self._pan is None or self._tilt is None:
            raise RuntimeError("Gate.start() must be called before the first cycle")
        return GateResult(self._pan, self._tilt, Outcome.HELD, reason=reason)

    def step(self, target_q: np.ndarray) -> GateResult:
        """Gate one commanded orientation (4,) and return the pose to write this cycle."""
        if self._direction is None or self._pan is None or self._tilt is None:
            raise RuntimeError("Gate.start() must be called before the first cycle")
        target_q = np.asarray(target_q, dtype=np.float64)
        if target_q.shape != (4,):
            return self.hold("malformed target")
        w, x, y, z = target_q.tolist()
        # | |q| - 1 | <= UNIT_NORM_TOLERANCE; NaN and inf fail the comparison and are held
        if not abs(math.sqrt(w * w + x * x + y * y + z * z) - 1.0) <= UNIT_NORM_TOLERANCE:
            return self.hold("non-finite or non-unit target")
        lim = self.limits

        corrected_q = self.envelope.correct(target_q)
        target_dir = scalar.limb(corrected_q)
        corrected = not np.array_equal(corrected_q, target_q)

        # slew: at most max_step along the great circle from the last safe direction
        slewed = False
        if scalar.angle(self._direction, target_dir) > lim.max_step:
            slewed = True
            step_dir = scalar.toward(self._direction, target_dir, lim.max_step)
            plain = scalar.limb(self.envelope.correct(scalar.swing(step_dir)))
            progress = scalar.angle(self._direction, target_dir) - scalar.angle(plain, target_dir)
            moved = scalar.angle(self._direction, plain)
            if self.router.wanted(scalar.swing(target_dir), progress, moved, lim.max_step):
                # a wall holds the plain step: aim at a point of a route along the region
                aim = scalar.limb(
                    self.router.subgoal(scalar.swing(self._direction), scalar.swing(target_dir))
                )
                step_dir = (
                    scalar.toward(self._direction, aim, lim.max_step)
                    if scalar.angle(self._direction, aim) > lim.max_step
                    else aim
                )
                plain = scalar.limb(self.envelope.correct(scalar.swing(step_dir)))
            target_dir = plain

        pan, tilt = scalar.pan_tilt(target_dir, self._pan)
        clamped_pan = min(max(pan, lim.pan_min), lim.pan_max)
        clamped_tilt = min(max(tilt, lim.tilt_min), lim.tilt_max)
        clamped = clamped_pan != pan or clamped_tilt != tilt
        pan, tilt = clamped_pan, clamped_tilt

        # near the singularity a short direction step can ask for a long pan swing: shorten it
        # in joint space, pan' = pan0 + f (pan - pan0) with f = max_joint_step / largest step
        largest = max(abs(pan - self._pan), abs(tilt - self._tilt))
        if largest > lim.max_joint_step:
            f = lim.max_joint_step / largest
            pan = self._pan + f * (pan - self._pan)
            tilt = self._tilt + f * (tilt - self._tilt)
            slewed = True
        if not self.is_safe(pan, tilt):
            return self.hold("corrected pose failed the final region/limit check")

        self._pan, self._tilt = pan, tilt
        self._direction = scalar.direction(pan, tilt)
        outcome = Outcome.strongest(corrected, clamped, slewed)
        return GateResult(pan, tilt, outcome, corrected=corrected, clamped=clamped, slewed=slewed)
