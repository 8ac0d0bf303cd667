"""The one place every commanded pose passes before it may become a goal position."""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from limbctl.errors import ConfigError, SafetyError
from limbctl.geometry.chains import chain_geometry
from limbctl.teleop.route import Router

Pose = tuple[float, ...]


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
        """The strongest of what the stages did: CLAMPED > CORRECTED > SLEWED > PASSED."""
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
#: Rounds of scaling a clamped joint move back within the slew limit: each takes the distance
#: to within a second-order term of ``max_step`` (about 1e-6 of it for a 2 deg step), so the
#: second round ends it; four leave room, and a move still over after them is held.
CLAMP_SHRINK_ROUNDS = 4


@dataclass(frozen=True)
class GateLimits:
    """Hard limits and rates the gate enforces; angles in radians.

    Attributes
    ----------
    joint_min, joint_max : tuple of float, shape (J,)
        Hard joint limits (rad) in chain order; J = 2 or 3 picks the chain.
    max_step, max_joint_step : float
        Largest move of the limb per cycle (rad; direction or SO(3) geodesic); largest change of
        any joint per cycle (rad), for the singularity at tilt +-90 deg.
    region_tolerance : float
        How far (rad) outside the learned region a written pose may be.
    """

    joint_min: Pose
    joint_max: Pose
    max_step: float
    max_joint_step: float
    region_tolerance: float = math.radians(REGION_TOLERANCE_DEG)

    def __post_init__(self) -> None:
        object.__setattr__(self, "joint_min", tuple(float(v) for v in self.joint_min))
        object.__setattr__(self, "joint_max", tuple(float(v) for v in self.joint_max))
        if len(self.joint_min) != len(self.joint_max):
            raise ConfigError(f"gate limits: as many minima as maxima: {self}")
        chain_geometry(len(self.joint_min))  # 2 or 3 joints
        rates = (self.max_step, self.max_joint_step, self.region_tolerance)
        if not all(math.isfinite(v) for v in (*self.joint_min, *self.joint_max, *rates)):
            raise ConfigError(f"gate limits must be finite: {self}")
        if not all(lo < hi for lo, hi in zip(self.joint_min, self.joint_max, strict=True)):
            raise ConfigError(f"gate limits: each min must be below its max: {self}")
        if not (self.max_step > 0 and self.max_joint_step > 0 and self.region_tolerance >= 0):
            raise ConfigError(
                "gate limits: max_step and max_joint_step must be positive, "
                "region_tolerance non-negative"
            )

    @classmethod
    def for_profile(cls, profile: Any, max_step: float, max_joint_step: float) -> GateLimits:
        """The limits of ``profile.joints`` with the given rates (rad per cycle)."""
        joints = [joint for _, joint in profile.joints]
        return cls(
            tuple(j.min_rad for j in joints),
            tuple(j.max_rad for j in joints),
            max_step=max_step,
            max_joint_step=max_joint_step,
        )

    def inside(self, *pose: float) -> bool:
        """True when every joint is within its hard limits (NaN is not)."""
        return all(
            lo <= v <= hi for v, lo, hi in zip(pose, self.joint_min, self.joint_max, strict=True)
        )


def written_tolerance_deg(ticks_per_turn: int = 4096, joints: int = 2) -> float:
    """How far (deg) a written goal may lie outside the region: the gate's tolerance plus
    half a tick on each joint (``sqrt(2)`` or ``sqrt(5)`` half ticks, docs/safety.md)."""
    half_tick = 360.0 / ticks_per_turn / 2.0
    return REGION_TOLERANCE_DEG + chain_geometry(joints).rounding * half_tick


@dataclass(frozen=True)
class GateResult:
    """One cycle's answer: ``pose`` (J,), the joint angles to write (rad; the last safe pose when
    HELD); ``outcome``, the strongest thing that happened; ``reason``, why the command was held
    (empty otherwise); ``corrected``, ``clamped``, ``slewed``: each stage that changed the command.
    """

    pose: Pose
    outcome: Outcome
    corrected: bool = False
    clamped: bool = False
    slewed: bool = False
    reason: str = ""


class Gate:
    """Turns commanded orientations into safe joint goals, one cycle at a time, for a trained region
    ``envelope`` (``contains``/``correct`` on quaternions (4,)) and its hard and per-cycle
    ``limits``."""

    def __init__(self, envelope: RegionModel, limits: GateLimits) -> None:
        self.envelope = envelope
        self.limits = limits
        self.chain = chain_geometry(len(limits.joint_min))
        self.router = Router(envelope, twist=self.chain.twist)
        self._pose: Pose | None = None
        self._point: Any = None  # the chain's point of the last safe pose

    @property
    def safe_pose(self) -> Pose | None:
        """The last pose the gate let through (rad), or None before :meth:`start`."""
        return self._pose

    def is_safe(self, *pose: float) -> bool:
        """True when the pose is finite, inside the hard limits and inside the region."""
        if not self.limits.inside(*pose):
            return False  # NaN fails every comparison and lands here
        chain = self.chain
        point = chain.point_at(pose)
        q = chain.quat(point)
        if bool(self.envelope.contains(q)):
            return True
        # inside up to the stated tolerance: the nearest region point is within region_tolerance
        nearest = chain.point(self.envelope.correct(q))
        return chain.distance(point, nearest) <= self.limits.region_tolerance

    def start(self, *pose: float) -> None:
        """Begin from the limb's present pose (rad, chain order), which must already be safe
        (SafetyError when it is outside the region or the hard limits)."""
        if not self.is_safe(*pose):
            at = ", ".join(
                f"{name} {math.degrees(v):.1f} deg"
                for name, v in zip(self.chain.names, pose, strict=True)
            )
            region = (
                "the taught region (swing and twist)" if self.chain.twist else "the taught region"
            )
            raise SafetyError(
                f"the limb is at {at}, outside {region} or the rig's hard limits; move it inside "
                "by hand (torque off) before starting"
            )
        self._pose = tuple(float(v) for v in pose)
        self._point = self.chain.point_at(self._pose)
        if self.router.batched:  # a fitted region: its roadmap now, before the loop's clock
            self.router.prepare(self.chain.quat(self._point))

    def hold(self, reason: str) -> GateResult:
        """Keep the last safe pose."""
        if self._pose is None:
            raise RuntimeError("Gate.start() must be called before the first cycle")
        return GateResult(self._pose, Outcome.HELD, reason=reason)

    def step(self, target_q: np.ndarray) -> GateResult:
        """Gate one commanded orientation (4,) and return the pose to write this cycle."""
        if self._pose is None:
            raise RuntimeError("Gate.start() must be called before the first cycle")
        target_q = np.asarray(target_q, dtype=np.float64)
        if target_q.shape != (4,):
            return self.hold("malformed target")
        w, x, y, z = target_q.tolist()
        # | |q| - 1 | <= UNIT_NORM_TOLERANCE; NaN and inf fail the comparison and are held
        if not abs(math.sqrt(w * w + x * x + y * y + z * z) - 1.0) <= UNIT_NORM_TOLERANCE:
            return self.hold("non-finite or non-unit target")
        lim, chain, here, present = self.limits, self.chain, self._point, self._pose

        corrected_q = self.envelope.correct(target_q)
        goal = chain.point(corrected_q)
        corrected = not np.array_equal(corrected_q, target_q)

        # slew: at most max_step from the last safe point, then corrected onto the region
        slewed = False
        if chain.distance(here, goal) > lim.max_step:
            slewed = True
            plain = self._corrected_step(here, goal)
            progress = chain.distance(here, goal) - chain.distance(plain, goal)
            moved = chain.distance(here, plain)
            if self.router.wanted(chain.quat(goal), progress, moved, lim.max_step):
                # a wall holds the plain step: aim at a point of a route along the region
                aim = chain.point(self.router.subgoal(chain.quat(here), chain.quat(goal)))
                plain = self._corrected_step(here, aim)
            goal = plain

        joints = chain.joints(goal, present, lim.joint_min, lim.joint_max)
        clamped_pose = tuple(
            min(max(v, lo), hi) for v, lo, hi in zip(joints, lim.joint_min, lim.joint_max)
        )
        clamped = any(c != v for c, v in zip(clamped_pose, joints))
        if clamped:
            clamped_pose = self._within_step(clamped_pose, present, here)
            if clamped_pose is None:
                return self.hold("a joint limit carried the step past the slew limit")

        # a short move of the limb can ask for a long joint move (near tilt +-90, roll the long
        # way): joint' = joint0 + f (joint - joint0), f = max_joint_step / largest step
        pose = clamped_pose
        largest = max(abs(v - v0) for v, v0 in zip(pose, present))
        if largest > lim.max_joint_step:
            f = lim.max_joint_step / largest
            pose = tuple(v0 + f * (v - v0) for v, v0 in zip(pose, present))
            slewed = True
        if not self.is_safe(*pose):
            return self.hold("corrected pose failed the final region/limit check")

        self._pose = pose
        self._point = chain.point_at(pose)
        outcome = Outcome.strongest(corrected, clamped, slewed)
        return GateResult(pose, outcome, corrected=corrected, clamped=clamped, slewed=slewed)

    def _within_step(
        self, pose: tuple[float, ...], present: tuple[float, ...], here: Any
    ) -> tuple[float, ...] | None:
        """A clamped ``pose`` (J,) (rad) scaled back toward ``present`` until within ``max_step``
        of ``here`` (a clamp slides along a limit), or None."""
        chain, step = self.chain, self.limits.max_step
        for _ in range(CLAMP_SHRINK_ROUNDS):
            d = chain.distance(here, chain.point_at(pose))
            if d <= step:
                return pose
            f = step / d
            pose = tuple(v0 + f * (v - v0) for v, v0 in zip(pose, present))
        return pose if chain.distance(here, chain.point_at(pose)) <= step else None

    def _corrected_step(self, here: Any, aim: Any) -> Any:
        """The point ``max_step`` from ``here`` toward ``aim``, corrected onto the region."""
        chain = self.chain
        return chain.point(
            self.envelope.correct(chain.quat(chain.toward(here, aim, self.limits.max_step)))
        )
