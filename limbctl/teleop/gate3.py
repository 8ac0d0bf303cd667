"""The gate of a three-servo rig: every commanded full orientation passes here before a goal.

The same safety model as the two-servo :class:`limbctl.teleop.gate.Gate`, on SO(3) instead of
the sphere of directions, per command:

1. ``correct``: the envelope returns the target itself inside the taught region (swing and
   twist), else the nearest orientation of the region by geodesic angle;
2. slew limit as an angular speed on SO(3): the orientation turns at most ``max_step`` (rad of
   geodesic angle ``2 acos |<a, b>|``, the rotation between the two) per cycle from
   the last safe orientation along the shortest rotation (slerp) toward the corrected target,
   that intermediate orientation is corrected again, so a concave region is followed, not cut;
   when the corrected step makes no way (a concave wall holds it), it aims at a point of a
   route along the region instead (the two-servo gate's :class:`~limbctl.teleop.route.Router`,
   on SO(3)), so the wall is gone round;
3. inverse kinematics to (pan, tilt, roll) (:func:`limbctl.geometry.gimbal.pan_tilt_roll_scalar`):
   the present pan kept at tilt +-90 deg, the roll unwrapped within its hard limits nearest the
   present roll;
4. hard limits clamp all three joints; a joint step above ``max_joint_step`` scales all three
   steps down by one factor (``SLEWED``);
5. final check: the pose that would be written is inside the hard limits and inside the region
   (``contains``, or within ``region_tolerance`` of ``correct``); if not, the last safe pose is
   held.

**The long way round.** The profile keeps the roll's hard limits inside (-180, 180) deg, so a
short rotation on SO(3) that crosses roll +-180 deg cannot be followed by the joint: IK returns
the roll within its limits, i.e. the other way round, and the per-joint step limit walks the
joints there. The poses in between then leave the slerp path; each is checked (step 5), and the
gate holds the last safe pose rather than write one outside the region. With a twist band that
does not cross +-180 deg (every region the region layer fits, which refuses d = -x), the path
the joints take between two poses of the band stays in it.

The outcome of a cycle is a value (:class:`GateResult3`, with the two-servo gate's
:class:`~limbctl.teleop.gate.Outcome`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from limbctl.errors import ConfigError, SafetyError
from limbctl.geometry.gimbal import pan_tilt_roll_scalar, pose_quat_scalar
from limbctl.teleop.gate import (
    REGION_TOLERANCE_DEG,
    UNIT_NORM_TOLERANCE,
    Outcome,
    RegionModel,
)
from limbctl.teleop.route import Router

Pose3 = tuple[float, float, float]


def geodesic(a: np.ndarray, b: np.ndarray) -> float:
    """Rotation angle (rad) between unit quaternions (4,): ``4 atan2(|a - s b|, |a + s b|)``
    with ``s = sign(a . b)``. The quaternions lie ``phi = acos |a . b|`` apart on S^3, and
    ``|a - s b| = 2 sin(phi/2)``, ``|a + s b| = 2 cos(phi/2)``, so this is
    ``2 phi = 2 acos |a . b|``, accurate near 0 where acos is not."""
    aw, ax, ay, az = a.tolist()
    bw, bx, by, bz = b.tolist()
    if aw * bw + ax * bx + ay * by + az * bz < 0.0:
        bw, bx, by, bz = -bw, -bx, -by, -bz
    dw, dx, dy, dz = aw - bw, ax - bx, ay - by, az - bz
    sw, sx, sy, sz = aw + bw, ax + bx, ay + by, az + bz
    return 4.0 * math.atan2(
        math.sqrt(dw * dw + dx * dx + dy * dy + dz * dz),
        math.sqrt(sw * sw + sx * sx + sy * sy + sz * sz),
    )


def toward(a: np.ndarray, b: np.ndarray, step: float) -> np.ndarray:
    """Unit quaternion ``step`` rad of rotation from ``a`` along the shortest rotation to ``b``,
    or ``b`` itself when it is nearer than that; w >= 0."""
    angle = geodesic(a, b)
    if angle <= step:
        return b
    return _slerp(a, b, angle, step)


def turn_by(a: np.ndarray, b: np.ndarray, step: float) -> np.ndarray:
    """Unit quaternion ``step`` rad of rotation from ``a`` along the shortest rotation to ``b``,
    which may lie past ``b``; ``b`` itself when the two are the same orientation."""
    angle = geodesic(a, b)
    if angle == 0.0:
        return b
    return _slerp(a, b, angle, step)


def _slerp(a: np.ndarray, b: np.ndarray, angle: float, step: float) -> np.ndarray:
    """Slerp ``step`` rad of rotation from ``a`` toward ``b``, ``angle`` (> 0) rad apart:
    ``q = sin((1 - t) h) / sin h * a + sin(t h) / sin h * s b`` with ``h = angle / 2``,
    ``t = step / angle`` and ``s = sign(a . b)``; w >= 0."""
    sign = 1.0 if float(np.dot(a, b)) >= 0.0 else -1.0
    half, t = angle / 2.0, step / angle
    s = math.sin(half)
    q = (math.sin((1.0 - t) * half) / s) * a + (sign * math.sin(t * half) / s) * b
    q = q / math.sqrt(float(np.dot(q, q)))
    return -q if q[0] < 0.0 else q


def written_tolerance_deg3(ticks_per_turn: int = 4096) -> float:
    """How far (deg of rotation) a goal that reached three servos may lie outside the region.

    The gate's tolerance plus the rounding of all three joints to whole ticks. Half a tick ``h``
    on each joint turns the limb by the rotation vector ``e_p z + e_t y' + e_r d`` (pan axis +z,
    tilt axis y' horizontal and perpendicular to the limb d, roll axis d): y' is perpendicular
    to both others and ``z . d = sin(tilt)``, so its length squared is at most
    ``h^2 (3 + 2 |sin tilt|) <= 5 h^2``. 0.108 deg for 4096-tick servos (0.072 with two).
    """
    half_tick = 360.0 / ticks_per_turn / 2.0
    return REGION_TOLERANCE_DEG + math.sqrt(5.0) * half_tick


@dataclass(frozen=True)
class GateLimits3:
    """Hard limits and rates of a three-servo gate; angles in radians.

    Attributes
    ----------
    pan_min, pan_max, tilt_min, tilt_max, roll_min, roll_max : float
        Hard joint limits (rad) from the rig profile.
    max_step : float
        Largest rotation of the limb per cycle (rad of geodesic angle on SO(3)).
    max_joint_step : float
        Largest change of any joint per cycle (rad).
    region_tolerance : float
        How far (rad of rotation) outside the learned region a written pose may be.
    """

    pan_min: float
    pan_max: float
    tilt_min: float
    tilt_max: float
    roll_min: float
    roll_max: float
    max_step: float
    max_joint_step: float
    region_tolerance: float = math.radians(REGION_TOLERANCE_DEG)

    def __post_init__(self) -> None:
        values = [getattr(self, f) for f in self.__dataclass_fields__]
        if not all(math.isfinite(v) for v in values):
            raise ConfigError(f"gate limits must be finite: {self}")
        pairs = ((self.pan_min, self.pan_max), (self.tilt_min, self.tilt_max))
        if not all(lo < hi for lo, hi in (*pairs, (self.roll_min, self.roll_max))):
            raise ConfigError(f"gate limits: each min must be below its max: {self}")
        if not (self.max_step > 0 and self.max_joint_step > 0 and self.region_tolerance >= 0):
            raise ConfigError(
                "gate limits: max_step and max_joint_step must be positive, "
                "region_tolerance non-negative"
            )

    def inside(self, pan: float, tilt: float, roll: float) -> bool:
        """True when every joint is within its hard limits (NaN is not)."""
        return (
            self.pan_min <= pan <= self.pan_max
            and self.tilt_min <= tilt <= self.tilt_max
            and self.roll_min <= roll <= self.roll_max
        )


@dataclass(frozen=True)
class GateResult3:
    """One cycle's answer of the three-servo gate: as :class:`~limbctl.teleop.gate.GateResult`,
    with the pose to write ``(pan, tilt, roll)`` (rad)."""

    pan: float
    tilt: float
    roll: float
    outcome: Outcome
    corrected: bool = False
    clamped: bool = False
    slewed: bool = False
    reason: str = ""

    @property
    def pose(self) -> Pose3:
        """``(pan, tilt, roll)`` (rad), what the rig writes."""
        return (self.pan, self.tilt, self.roll)


class Gate3:
    """Turns commanded full orientations into safe goals of a three-servo rig, cycle by cycle.

    Parameters
    ----------
    envelope : RegionModel
        The trained region over full orientations (``contains``/``correct`` on one (4,) q).
    limits : GateLimits3
    """

    def __init__(self, envelope: RegionModel, limits: GateLimits3) -> None:
        self.envelope = envelope
        self.limits = limits
        self.router = Router(envelope, twist=True)
        self._pose: Pose3 | None = None
        self._q: np.ndarray | None = None

    @property
    def safe_pose(self) -> Pose3 | None:
        """The last pose the gate let through (rad), or None before :meth:`start`."""
        return self._pose

    def is_safe(self, pan: float, tilt: float, roll: float) -> bool:
        """True when the pose is finite, inside the hard limits and inside the region."""
        if not self.limits.inside(pan, tilt, roll):
            return False  # NaN fails every comparison and lands here
        q = pose_quat_scalar(pan, tilt, roll)
        if bool(self.envelope.contains(q)):
            return True
        return geodesic(q, self.envelope.correct(q)) <= self.limits.region_tolerance

    def start(self, pan: float, tilt: float, roll: float) -> None:
        """Begin from the limb's present pose, which must already be safe.

        Raises
        ------
        SafetyError
            When the present pose is outside the region or the hard limits.
        """
        if not self.is_safe(pan, tilt, roll):
            raise SafetyError(
                f"the limb is at pan {math.degrees(pan):.1f} deg, tilt {math.degrees(tilt):.1f} "
                f"deg, roll {math.degrees(roll):.1f} deg, outside the taught region (swing and "
                "twist) or the rig's hard limits; move it inside by hand (torque off) before "
                "starting"
            )
        self._pose = (float(pan), float(tilt), float(roll))
        self._q = pose_quat_scalar(*self._pose)
        if self.router.batched:  # a fitted region: its roadmap now, before the loop's clock
            self.router.prepare(self._q)

    def hold(self, reason: str) -> GateResult3:
        """Keep the last safe pose."""
        if self._pose is None:
            raise RuntimeError("Gate3.start() must be called before the first cycle")
        return GateResult3(*self._pose, Outcome.HELD, reason=reason)

    def step(self, target_q: np.ndarray) -> GateResult3:
        """Gate one commanded orientation (4,) and return the pose to write this cycle."""
        if self._pose is None or self._q is None:
            raise RuntimeError("Gate3.start() must be called before the first cycle")
        target_q = np.asarray(target_q, dtype=np.float64)
        if target_q.shape != (4,):
            return self.hold("malformed target")
        w, x, y, z = target_q.tolist()
        # | |q| - 1 | <= UNIT_NORM_TOLERANCE; NaN and inf fail the comparison and are held
        if not abs(math.sqrt(w * w + x * x + y * y + z * z) - 1.0) <= UNIT_NORM_TOLERANCE:
            return self.hold("non-finite or non-unit target")
        lim = self.limits
        pan0, tilt0, roll0 = self._pose

        corrected_q = self.envelope.correct(target_q)
        corrected = not np.array_equal(corrected_q, target_q)
        goal_q = corrected_q
        # slew: at most max_step of rotation along the shortest rotation from the last safe pose
        slewed = False
        if geodesic(self._q, goal_q) > lim.max_step:
            slewed = True
            plain = self.envelope.correct(toward(self._q, goal_q, lim.max_step))
            progress = geodesic(self._q, goal_q) - geodesic(plain, goal_q)
            moved = geodesic(self._q, plain)
            if self.router.wanted(goal_q, progress, moved, lim.max_step):
                # a wall holds the plain step: aim at a point of a route along the region
                aim = self.router.subgoal(self._q, goal_q)
                plain = self.envelope.correct(toward(self._q, aim, lim.max_step))
            goal_q = plain

        pan, tilt, roll = pan_tilt_roll_scalar(goal_q, pan0, roll0, lim.roll_min, lim.roll_max)
        clamped_pose = (
            min(max(pan, lim.pan_min), lim.pan_max),
            min(max(tilt, lim.tilt_min), lim.tilt_max),
            min(max(roll, lim.roll_min), lim.roll_max),
        )
        clamped = clamped_pose != (pan, tilt, roll)
        pan, tilt, roll = clamped_pose

        # a short rotation can ask for a long joint move (tilt near +-90, roll the long way):
        # joint' = joint0 + f (joint - joint0), f = max_joint_step / largest step
        largest = max(abs(pan - pan0), abs(tilt - tilt0), abs(roll - roll0))
        if largest > lim.max_joint_step:
            f = lim.max_joint_step / largest
            pan, tilt, roll = (
                pan0 + f * (pan - pan0),
                tilt0 + f * (tilt - tilt0),
                roll0 + f * (roll - roll0),
            )
            slewed = True
        if not self.is_safe(pan, tilt, roll):
            return self.hold("corrected pose failed the final region/limit check")

        self._pose = (pan, tilt, roll)
        self._q = pose_quat_scalar(pan, tilt, roll)
        outcome = Outcome.strongest(corrected, clamped, slewed)
        return GateResult3(
            pan, tilt, roll, outcome, corrected=corrected, clamped=clamped, slewed=slewed
        )
