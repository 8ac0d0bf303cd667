"""Where a limb may start from: "inside by a margin", and the nearest such pose, for any chain.

A start pose must survive the rounding of the last goal to ticks and a holding servo's tick or
two of compliance, so a waiting or parked limb aims at a pose *inside by*
:data:`START_MARGIN_DEG`. The chain decides what that means (:func:`margins_for`): on two joints
(:class:`SphereMargins`) the direction and a ring of :data:`RING_PROBES` directions around it
lie inside; on three (:class:`RotationMargins`) the held pose stays safe with any one joint
moved by the margin either way. Angles in radians unless a name ends in ``_deg``;
orientations as unit quaternions (4,), scalar first.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from limbctl.geometry import scalar
from limbctl.geometry.chains import geodesic, toward, turn_by
from limbctl.geometry.gimbal import pan_tilt_roll_scalar, pose_quat_scalar
from limbctl.geometry.quat import limb_direction, multiply, swing_from_direction, tangent_frame
from limbctl.teleop.gate import Gate

#: How far (deg) inside the region and the hard limits a start or park pose must be. It covers
#: the rounding of a goal to ticks (0.072 deg, written_tolerance_deg) plus a holding servo's
#: compliance of up to 2 ticks per joint (sqrt(2) * 2 * 0.088 = 0.25 deg), with room to spare.
START_MARGIN_DEG = 0.35
#: Directions probed on the ring around a pose: with 12, a straight edge that passes between two
#: probes is still at least cos(15 deg) = 97 % of the margin away.
RING_PROBES = 12
#: Ring radii (multiples of the margin) searched for the nearest start pose: fine near the
#: edge, up to 24 margins (8.4 deg) for narrow necks and corners.
SEARCH_RADII = (1.0, 1.25, 1.5, 2.0, 3.0, 4.0, 6.0, 9.0, 13.0, 18.0, 24.0)
#: Directions tried on each search ring (22.5 deg apart).
SEARCH_DIRECTIONS = 16

#: A pose's rounding to what the servos hold: (pan, tilt) rad -> (pan, tilt) rad.
RoundToTicks = Callable[[float, float], tuple[float, float]]


def _exact(pan: float, tilt: float) -> tuple[float, float]:
    return pan, tilt


def ring(directions: np.ndarray, radius: float, count: int) -> np.ndarray:
    """``count`` unit directions at angle ``radius`` (rad) around each of ``directions`` (N, 3).

    Returns
    -------
    ndarray, shape (N, count, 3)
    """
    out = np.empty((len(directions), count, 3))
    theta = 2.0 * math.pi * np.arange(count) / count
    for i, d in enumerate(directions):
        u, v = tangent_frame(d)
        # p_k = cos(r) d + sin(r) (cos th_k u + sin th_k v)
        tangent = np.cos(theta)[:, None] * u + np.sin(theta)[:, None] * v
        out[i] = math.cos(radius) * d + math.sin(radius) * tangent
    return out


def within_limits(gate: Gate, pan: float, tilt: float, margin: float = 0.0) -> bool:
    """Both joints at least ``margin`` (rad) inside the gate's hard limits (NaN is not)."""
    (pan_min, tilt_min), (pan_max, tilt_max) = gate.limits.joint_min, gate.limits.joint_max
    return (
        pan_min + margin <= pan <= pan_max - margin
        and tilt_min + margin <= tilt <= tilt_max - margin
    )


def inside_by_margin(gate: Gate, poses: np.ndarray, margin: float) -> np.ndarray:
    """Which poses (N, 2) (pan, tilt, rad) are inside the region and the limits by ``margin``.

    Inside the region by ``margin`` means the pose's direction and :data:`RING_PROBES`
    directions at angle ``margin`` around it are all inside (one batched ``contains``).

    Returns
    -------
    ndarray of bool, shape (N,)
    """
    poses = np.asarray(poses, dtype=np.float64).reshape(-1, 2)
    (pan_min, tilt_min), (pan_max, tilt_max) = gate.limits.joint_min, gate.limits.joint_max
    ok = (
        (poses[:, 0] >= pan_min + margin)
        & (poses[:, 0] <= pan_max - margin)
        & (poses[:, 1] >= tilt_min + margin)
        & (poses[:, 1] <= tilt_max - margin)
    )
    if not ok.any():
        return ok
    pan, tilt = poses[ok, 0], poses[ok, 1]
    # d = (cos t cos p, cos t sin p, sin t)
    d = np.stack([np.cos(tilt) * np.cos(pan), np.cos(tilt) * np.sin(pan), np.sin(tilt)], axis=1)
    probes = np.concatenate([d[:, None, :], ring(d, margin, RING_PROBES)], axis=1)
    inside = np.asarray(gate.envelope.contains(swing_from_direction(probes.reshape(-1, 3))))
    ok[np.flatnonzero(ok)] = inside.reshape(len(d), RING_PROBES + 1).all(axis=1)
    return ok


def outside_by(gate: Gate, pan: float, tilt: float) -> float:
    """Angle (rad) by which the pose's direction lies outside the region; 0 inside."""
    d = scalar.direction(pan, tilt)
    q = scalar.swing(d)
    if bool(gate.envelope.contains(q)):
        return 0.0
    return scalar.angle(d, scalar.limb(gate.envelope.correct(q)))


def nearest_start_pose(
    gate: Gate,
    pan: float,
    tilt: float,
    margin: float = math.radians(START_MARGIN_DEG),
    round_to_ticks: RoundToTicks = _exact,
) -> tuple[float, float] | None:
    """The pose nearest ``(pan, tilt)`` (rad) that is inside by ``margin`` once rounded to ticks.

    Candidates: past the region's nearest boundary point along the line from the pose (the
    inward way across a smooth edge), then rings of :data:`SEARCH_RADII` around that point
    (corners, necks). Among those whose rounded pose is inside by ``margin``, the one nearest
    the present direction wins. None when no candidate qualifies (a region thinner than twice
    the margin near the pose).

    Returns
    -------
    (pan, tilt) in rad, already rounded to ticks, or None
    """
    d = np.asarray(scalar.direction(pan, tilt))
    nearest = limb_direction(gate.envelope.correct(swing_from_direction(d)))
    # the nearest point of the region, pulled into the hard limits with twice the margin
    base_pan, base_tilt = scalar.pan_tilt(tuple(nearest), pan)
    (pan_min, tilt_min), (pan_max, tilt_max) = gate.limits.joint_min, gate.limits.joint_max
    base_pan = min(max(base_pan, pan_min + 2 * margin), pan_max - 2 * margin)
    base_tilt = min(max(base_tilt, tilt_min + 2 * margin), tilt_max - 2 * margin)
    base = np.asarray(scalar.direction(base_pan, base_tilt))

    candidates = [base[None, :]]
    gap = scalar.angle(tuple(d), tuple(base))
    if gap > margin * 1e-3:
        # across the edge: from d through base and on by s, d' = toward(d, base, gap + s)
        steps = [gap + s * margin for s in SEARCH_RADII]
        candidates.append(np.array([scalar.toward(tuple(d), tuple(base), s) for s in steps]))
    for radius in SEARCH_RADII:
        candidates.append(ring(base[None, :], radius * margin, SEARCH_DIRECTIONS)[0])
    directions = np.concatenate(candidates)
    rounded = np.array(
        [round_to_ticks(*scalar.pan_tilt(tuple(c), base_pan)) for c in directions], dtype=float
    )
    ok = inside_by_margin(gate, rounded, margin)
    if not ok.any():
        return None
    rounded_dirs = np.stack(
        [
            np.cos(rounded[:, 1]) * np.cos(rounded[:, 0]),
            np.cos(rounded[:, 1]) * np.sin(rounded[:, 0]),
            np.sin(rounded[:, 1]),
        ],
        axis=1,
    )
    # angle to the present direction, acos(clip(d . c)): only the order matters here
    closeness = np.where(ok, rounded_dirs @ d, -np.inf)
    best = rounded[int(np.argmax(closeness))]
    return float(best[0]), float(best[1])


# ---- on SO(3): a three-servo chain (pan, tilt, roll) ------------------------------------------
#: Axes (world frame) the search rings turn the nearest orientation about: the six faces and
#: eight corners of a cube, so every rotation axis lies within 35 deg of one of them; +x is
#: among them, which is the limb's own axis at rest and near it in a region about +x.
RING_AXES = np.array(
    [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]]
    + [[sx, sy, sz] for sx in (1, -1) for sy in (1, -1) for sz in (1, -1)],
    dtype=np.float64,
)
RING_AXES /= np.linalg.norm(RING_AXES, axis=1, keepdims=True)

#: A pose (rad, one angle a joint) -> the pose the servos hold once it is written.
HeldPose = Callable[..., tuple[float, ...]]


def safe_with_margin(gate: Gate, pose: tuple[float, ...], margin: float) -> bool:
    """True when ``pose`` and the poses with one joint moved by +-``margin`` (rad) are safe."""
    if not gate.is_safe(*pose):
        return False
    for k in range(len(pose)):
        for sign in (-1.0, 1.0):
            moved = list(pose)
            moved[k] += sign * margin
            if not gate.is_safe(*moved):
                return False
    return True


def rotation_outside_by(gate: Gate, pose: tuple[float, ...]) -> float:
    """Rotation (rad) from ``pose`` (pan, tilt, roll) to the region's nearest orientation; 0
    inside."""
    q = pose_quat_scalar(*pose)
    if bool(gate.envelope.contains(q)):
        return 0.0
    return geodesic(q, gate.envelope.correct(q))


def _axis_rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Quaternion (4,) of a turn by ``angle`` (rad) about unit ``axis`` (3,)."""
    half = angle / 2.0
    return np.concatenate([[math.cos(half)], math.sin(half) * axis])


def rotation_candidates(gate: Gate, q: np.ndarray, margin: float) -> list[np.ndarray]:
    """Orientations (4,) near ``q`` that may be inside by ``margin``, all built on the region's
    nearest orientation ``c = correct(q)``: on along the shortest rotation from ``q`` through
    ``c``, :data:`SEARCH_RADII` margins past it (across a smooth edge of swing or twist), and
    rings ``r(a, s m) * c`` about each of :data:`RING_AXES` (corners, necks, twist stops)."""
    nearest = gate.envelope.correct(q)
    out = [nearest]
    gap = geodesic(q, nearest)
    if gap > margin * 1e-3:
        for s in SEARCH_RADII:
            out.append(turn_by(q, nearest, gap + s * margin))
    for s in SEARCH_RADII:
        for axis in RING_AXES:
            turned = multiply(_axis_rotation(axis, s * margin), nearest)
            out.append(-turned if turned[0] < 0.0 else turned)
    return out


def nearest_rotation_start_pose(
    gate: Gate, pose: tuple[float, ...], held_pose: HeldPose, margin: float
) -> tuple[float, ...] | None:
    """The pose nearest ``pose`` (pan, tilt, roll; rad) that is inside by ``margin``
    (:func:`safe_with_margin`) once the servos hold it (``held_pose``); the candidates of
    :func:`rotation_candidates`, nearest ``pose`` by geodesic angle first. None when none
    qualifies (a region thinner than twice the margin near the pose)."""
    lim = gate.limits
    here = held_pose(*pose)
    if safe_with_margin(gate, here, margin):
        return here
    q = pose_quat_scalar(*pose)
    for c in sorted(rotation_candidates(gate, q, margin), key=lambda c: geodesic(q, c)):
        held = held_pose(
            *pan_tilt_roll_scalar(c, pose[0], pose[2], lim.joint_min[2], lim.joint_max[2])
        )
        if safe_with_margin(gate, held, margin):
            return held
    return None


# ---- the chain's margins: one object a gate, the only place the chain is told apart ---------
class SphereMargins:
    """Start geometry of a two-servo chain: poses (pan, tilt) point the limb along a direction
    (3,) on the sphere; inside by the margin is :func:`inside_by_margin` of the pose itself."""

    def __init__(self, gate: Gate, held_pose: HeldPose) -> None:
        self.gate, self.held_pose = gate, held_pose
        self.margin = math.radians(START_MARGIN_DEG)

    def point(self, pose: tuple[float, ...]) -> tuple[float, float, float]:
        """The limb's direction (3,) at ``pose``."""
        return scalar.direction(*pose)

    def angle(self, a: tuple[float, ...], b: tuple[float, ...]) -> float:
        """Angle (rad) between two points."""
        return scalar.angle(a, b)

    def toward(self, a: tuple[float, ...], b: tuple[float, ...], step: float) -> object:
        """The point ``step`` rad from ``a`` toward ``b``."""
        return scalar.toward(a, b, step)

    def pose_of(self, point: tuple[float, ...], near: tuple[float, ...]) -> tuple[float, ...]:
        """Joint angles (rad) of ``point``, the branch nearest the pose ``near``."""
        return scalar.pan_tilt(point, near[0])

    def orientation(self, pose: tuple[float, ...]) -> np.ndarray:
        """The orientation (4,) the gate is asked for to reach ``pose``."""
        return scalar.swing(scalar.direction(*pose))

    def within_limits(self, pose: tuple[float, ...]) -> bool:
        """Every joint within its hard limits."""
        return within_limits(self.gate, *pose)

    def outside_by(self, pose: tuple[float, ...]) -> float:
        """Angle (rad) by which ``pose`` lies outside the region; 0 inside."""
        return outside_by(self.gate, *pose)

    def held_inside(self, held: tuple[float, ...]) -> bool:
        """A pose the servos hold (rounded to ticks) is inside by the margin."""
        return bool(inside_by_margin(self.gate, np.array([held]), self.margin)[0])

    def ready(self, pose: tuple[float, ...]) -> bool:
        """A limb read at ``pose`` may start: inside by the margin as read."""
        return bool(inside_by_margin(self.gate, np.array([pose]), self.margin)[0])

    def nearest(self, pose: tuple[float, ...]) -> tuple[float, ...] | None:
        """:func:`nearest_start_pose` of ``pose``, rounded to ticks."""
        return nearest_start_pose(self.gate, *pose, self.margin, self.held_pose)

    def warm(self) -> None:
        """Nothing to compile ahead: the sphere's kernels run on the first read."""


class RotationMargins(SphereMargins):
    """Start geometry of a three-servo chain: poses (pan, tilt, roll) are orientations (4,) on
    SO(3); inside by the margin is :func:`safe_with_margin` of the pose the servos hold."""

    def point(self, pose: tuple[float, ...]) -> np.ndarray:
        return pose_quat_scalar(*pose)

    def angle(self, a: np.ndarray, b: np.ndarray) -> float:  # type: ignore[override]
        return geodesic(a, b)

    def toward(self, a: np.ndarray, b: np.ndarray, step: float) -> np.ndarray:  # type: ignore[override]
        return toward(a, b, step)

    def pose_of(self, point: np.ndarray, near: tuple[float, ...]) -> tuple[float, ...]:  # type: ignore[override]
        lim = self.gate.limits
        return pan_tilt_roll_scalar(point, near[0], near[2], lim.joint_min[2], lim.joint_max[2])

    def orientation(self, pose: tuple[float, ...]) -> np.ndarray:
        return pose_quat_scalar(*pose)

    def within_limits(self, pose: tuple[float, ...]) -> bool:
        return self.gate.limits.inside(*pose)

    def outside_by(self, pose: tuple[float, ...]) -> float:
        return rotation_outside_by(self.gate, pose)

    def held_inside(self, held: tuple[float, ...]) -> bool:
        return safe_with_margin(self.gate, held, self.margin)

    def ready(self, pose: tuple[float, ...]) -> bool:
        """A limb read at ``pose`` may start: the pose the servos would hold there is inside by
        the margin."""
        return safe_with_margin(self.gate, self.held_pose(*pose), self.margin)

    def nearest(self, pose: tuple[float, ...]) -> tuple[float, ...] | None:
        return nearest_rotation_start_pose(self.gate, pose, self.held_pose, self.margin)

    def warm(self) -> None:
        """The region's kernels compile on their first call: here, not in the loop's first
        cycles."""
        self.gate.envelope.correct(pose_quat_scalar(math.pi / 2, 0.0, math.pi / 2))


def margins_for(gate: Gate, limb: object) -> SphereMargins:
    """The start geometry of the chain ``limb`` drives (its ``joints``): two joints point the
    limb (:class:`SphereMargins`), three orient it (:class:`RotationMargins`). ``limb`` gives
    ``held_pose``, the pose its servos hold once a pose is written."""
    chain = SphereMargins if len(limb.joints) == 2 else RotationMargins  # type: ignore[attr-defined]
    return chain(gate, limb.held_pose)  # type: ignore[attr-defined]
