"""The geometry a joint chain's gate (:mod:`limbctl.teleop.gate`) steps in: limb directions and
great circles for two joints (:class:`Directions`), unit quaternions and slerp for three
(:class:`Rotations`). One pose per cycle, plain floats; angles are radians."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from limbctl.errors import ConfigError
from limbctl.geometry import scalar
from limbctl.geometry.gimbal import pan_tilt_roll_scalar, pose_quat_scalar

Pose = tuple[float, ...]


def geodesic(a: np.ndarray, b: np.ndarray) -> float:
    """Rotation angle (rad) ``2 acos |a . b|`` between unit quaternions (4,), accurate near 0."""
    # 4 atan2(|a - s b|, |a + s b|), s = sign(a . b)
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
    """Unit quaternion ``step`` rad from ``a`` toward ``b``, or ``b`` when nearer; w >= 0."""
    angle = geodesic(a, b)
    if angle <= step:
        return b
    return _slerp(a, b, angle, step)


def turn_by(a: np.ndarray, b: np.ndarray, step: float) -> np.ndarray:
    """Unit quaternion ``step`` rad from ``a`` toward ``b``, maybe past it; ``b`` when equal."""
    angle = geodesic(a, b)
    if angle == 0.0:
        return b
    return _slerp(a, b, angle, step)


def _slerp(a: np.ndarray, b: np.ndarray, angle: float, step: float) -> np.ndarray:
    """Slerp ``step`` rad of rotation from ``a`` toward ``b`` (4,), ``angle`` (> 0) rad apart."""
    sign = 1.0 if float(np.dot(a, b)) >= 0.0 else -1.0
    half, t = angle / 2.0, step / angle
    s = math.sin(half)
    # q = sin((1 - t) h) / sin h * a + sin(t h) / sin h * s b,  h = angle / 2, s = sign(a . b)
    q = (math.sin((1.0 - t) * half) / s) * a + (sign * math.sin(t * half) / s) * b
    q = q / math.sqrt(float(np.dot(q, q)))
    return -q if q[0] < 0.0 else q


class Directions:
    """Two joints (pan, tilt): points are limb directions (unit 3-tuples) on the sphere."""

    names = ("pan", "tilt")
    twist = False  # the region is over directions: its twist is never asked
    #: sqrt(|dd|^2) for half a tick ``h`` on each joint: ``(cos(tilt) h)^2 + h^2 <= 2 h^2``
    rounding = math.sqrt(2.0)

    @staticmethod
    def point(q: np.ndarray) -> scalar.Vec3:
        """The limb direction of unit quaternion ``q`` (4,)."""
        return scalar.limb(q)

    @staticmethod
    def quat(point: scalar.Vec3) -> np.ndarray:
        """The twist-free quaternion (4,) of a direction."""
        return scalar.swing(point)

    @staticmethod
    def distance(a: scalar.Vec3, b: scalar.Vec3) -> float:
        """Angle (rad) between two directions."""
        return scalar.angle(a, b)

    @staticmethod
    def toward(a: scalar.Vec3, b: scalar.Vec3, step: float) -> scalar.Vec3:
        """``step`` rad from ``a`` along the great circle to ``b``; ``b`` when nearer."""
        return scalar.toward(a, b, step) if scalar.angle(a, b) > step else b

    @staticmethod
    def point_at(pose: Pose) -> scalar.Vec3:
        """The direction at joint angles ``(pan, tilt)``."""
        return scalar.direction(*pose)

    @staticmethod
    def joints(point: scalar.Vec3, present: Pose, lo: Pose, hi: Pose) -> Pose:
        """``(pan, tilt)`` of a direction, the present pan kept at the singularity."""
        return scalar.pan_tilt(point, present[0])


class Rotations:
    """Three joints (pan, tilt, roll): points are full orientations (unit quaternions (4,))."""

    names = ("pan", "tilt", "roll")
    twist = True
    #: Half a tick h on each joint: |e_p z + e_t y' + e_r d|^2 <= h^2 (3 + 2 |sin tilt|) <= 5 h^2
    rounding = math.sqrt(5.0)

    @staticmethod
    def point(q: np.ndarray) -> np.ndarray:
        return q

    @staticmethod
    def quat(point: np.ndarray) -> np.ndarray:
        return point

    distance = staticmethod(geodesic)
    toward = staticmethod(toward)

    @staticmethod
    def point_at(pose: Pose) -> np.ndarray:
        """``Rz(pan) Ry(-tilt) Rx(roll)`` (4,), w >= 0."""
        return pose_quat_scalar(*pose)

    @staticmethod
    def joints(point: np.ndarray, present: Pose, lo: Pose, hi: Pose) -> Pose:
        """``(pan, tilt, roll)`` of ``point``: the present pan kept at tilt +-90 deg, the roll
        within its limits ``[lo[2], hi[2]]`` nearest the present roll."""
        return pan_tilt_roll_scalar(point, present[0], present[2], lo[2], hi[2])


#: The geometry of each chain, by its number of joints.
CHAINS: dict[int, Any] = {2: Directions, 3: Rotations}


def chain_geometry(joints: int) -> Any:
    """:class:`Directions` for 2 joints, :class:`Rotations` for 3 (ConfigError for any other)."""
    try:
        return CHAINS[joints]
    except KeyError:
        raise ConfigError(f"a limb has 2 or 3 joints, not {joints}") from None
