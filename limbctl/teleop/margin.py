"""Where a limb may start from: "inside by a margin", and the nearest such pose, any chain."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from limbctl.geometry import scalar
from limbctl.geometry.chains import geodesic, toward, turn_by
from limbctl.geometry.gimbal import pan_tilt_roll_scalar, pose_quat_scalar
from limbctl.geometry.quat import limb_direction, multiply, swing_from_direction, tangent_frame
from limbctl.teleop.gate import Gate

#: How far (deg) inside the region and limits a start or park pose must be: rounding to ticks
#: (0.072 deg) plus a holding servo's 2 ticks of compliance (0.25 deg), with room to spare.
START_MARGIN_DEG = 0.35
#: Ring probes around a pose: an edge passing between two is still 97 % of the margin away.
RING_PROBES = 12
#: Search ring radii (margins) for the nearest start pose: fine near the edge, wide for necks.
SEARCH_RADII = (1.0, 1.25, 1.5, 2.0, 3.0, 4.0, 6.0, 9.0, 13.0, 18.0, 24.0)
#: Directions tried on each search ring (22.5 deg apart).
SEARCH_DIRECTIONS = 16


def ring(directions: np.ndarray, radius: float, count: int) -> np.ndarray:
    """(N, count, 3): ``count`` unit directions ``radius`` (rad) around each of ``directions``
    (N, 3)."""
    out = np.empty((len(directions), count, 3))
    theta = 2.0 * math.pi * np.arange(count) / count
    for i, d in enumerate(directions):
        u, v = tangent_frame(d)
        # p_k = cos(r) d + sin(r) (cos th_k u + sin th_k v)
        tangent = np.cos(theta)[:, None] * u + np.sin(theta)[:, None] * v
        out[i] = math.cos(radius) * d + math.sin(radius) * tangent
    return out


def _directions(poses: np.ndarray) -> np.ndarray:
    """Limb directions (N, 3) of poses (N, 2) (pan, tilt; rad)."""
    pan, tilt = poses[:, 0], poses[:, 1]
    return np.stack([np.cos(tilt) * np.cos(pan), np.cos(tilt) * np.sin(pan), np.sin(tilt)], axis=1)


def inside_by_margin(gate: Gate, poses: np.ndarray, margin: float) -> np.ndarray:
    """(N,) bool: which poses (N, 2) (pan, tilt, rad) are inside region and limits by ``margin``."""
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
    d = _directions(poses[ok])
    probes = np.concatenate([d[:, None, :], ring(d, margin, RING_PROBES)], axis=1)
    inside = np.asarray(gate.envelope.contains(swing_from_direction(probes.reshape(-1, 3))))
    ok[np.flatnonzero(ok)] = inside.reshape(len(d), RING_PROBES + 1).all(axis=1)
    return ok


def nearest_start_pose(
    gate: Gate,
    pan: float,
    tilt: float,
    margin: float,
    round_to_ticks: Callable[[float, float], tuple[float, float]],
) -> tuple[float, float] | None:
    """The pose (pan, tilt) (rad, rounded to ticks) nearest ``(pan, tilt)`` inside by
    ``margin``: past the nearest boundary point, or on rings around it; None if none."""
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
    # the cosine of the angle to the present direction: only the order matters
    closeness = np.where(ok, _directions(rounded) @ d, -np.inf)
    best = rounded[int(np.argmax(closeness))]
    return float(best[0]), float(best[1])


# ---- on SO(3): a three-servo chain (pan, tilt, roll) ------------------------------------------
#: Axes the search rings turn about: a cube's faces and corners (every axis within 35 deg of one).
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


def _axis_rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Quaternion (4,) of a turn by ``angle`` (rad) about unit ``axis`` (3,)."""
    half = angle / 2.0
    return np.concatenate([[math.cos(half)], math.sin(half) * axis])


def rotation_candidates(gate: Gate, q: np.ndarray, margin: float) -> list[np.ndarray]:
    """Orientations (4,) near ``q`` that may be inside by ``margin``: past ``correct(q)`` on the
    way there, and rings about :data:`RING_AXES` around it."""
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
    """The pose nearest ``pose`` (pan, tilt, roll; rad) inside by ``margin`` once the servos hold
    it (``held_pose``), or None."""
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
    """Start geometry of a two-servo chain: points are limb directions (3,)."""

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
        return self.gate.limits.inside(*pose)

    def outside_by(self, pose: tuple[float, ...]) -> float:
        """Angle (rad) by which ``pose`` lies outside the region; 0 inside."""
        d = scalar.direction(*pose)
        q = scalar.swing(d)
        if bool(self.gate.envelope.contains(q)):
            return 0.0
        return scalar.angle(d, scalar.limb(self.gate.envelope.correct(q)))

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
    """Start geometry of a three-servo chain: points are orientations (4,)."""

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

    def outside_by(self, pose: tuple[float, ...]) -> float:
        q = pose_quat_scalar(*pose)
        if bool(self.gate.envelope.contains(q)):
            return 0.0
        return geodesic(q, self.gate.envelope.correct(q))

    def held_inside(self, held: tuple[float, ...]) -> bool:
        return safe_with_margin(self.gate, held, self.margin)

    def ready(self, pose: tuple[float, ...]) -> bool:
        """The pose the servos would hold at ``pose`` is inside by the margin."""
        return safe_with_margin(self.gate, self.held_pose(*pose), self.margin)

    def nearest(self, pose: tuple[float, ...]) -> tuple[float, ...] | None:
        return nearest_rotation_start_pose(self.gate, pose, self.held_pose, self.margin)

    def warm(self) -> None:
        """Compile the region's kernels here, not in the loop's first cycles."""
        self.gate.envelope.correct(pose_quat_scalar(math.pi / 2, 0.0, math.pi / 2))


def margins_for(gate: Gate, limb: object) -> SphereMargins:
    """The start geometry of ``limb``'s chain (its ``joints`` and ``held_pose``)."""
    chain = SphereMargins if len(limb.joints) == 2 else RotationMargins  # type: ignore[attr-defined]
    return chain(gate, limb.held_pose)  # type: ignore[attr-defined]
