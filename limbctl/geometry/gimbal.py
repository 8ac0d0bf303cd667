"""Joint angles <-> limb direction <-> quaternion for a chain of 2 or 3 joints, exactly.
The limb rests along +x; pan turns about +z, tilt raises it toward +z. Two joints stand for the
twist-free swing from +x to the limb direction, three for ``q = Rz(pan) Ry(-tilt) Rx(roll)``,
whose twist about +x is ``roll + chain_twist(pan, tilt)``. Angles are radians; ``*_scalar``
functions take one pose."""

from __future__ import annotations

import math

import numpy as np

from limbctl.geometry.quat import limb_direction, swing_from_direction
from limbctl.geometry.scalar import SINGULAR_COS
from limbctl.geometry.scalar import limb as limb_scalar
from limbctl.geometry.scalar import pan_tilt as pan_tilt_scalar


def pan_tilt_to_direction(pan: np.ndarray, tilt: np.ndarray) -> np.ndarray:
    """Limb direction (..., 3) for joint angles ``pan``, ``tilt`` (rad)."""
    pan = np.asarray(pan, dtype=np.float64)
    tilt = np.asarray(tilt, dtype=np.float64)
    # d = (cos(tilt) cos(pan), cos(tilt) sin(pan), sin(tilt))
    ct = np.cos(tilt)
    return np.stack([ct * np.cos(pan), ct * np.sin(pan), np.sin(tilt)], axis=-1)


def direction_to_pan_tilt(
    d: np.ndarray, current_pan: np.ndarray | float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Joint angles (rad) pointing the limb along ``d`` (..., 3); ``current_pan`` kept at +-z."""
    d = np.asarray(d, dtype=np.float64)
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    # pan = atan2(d_y, d_x), tilt = atan2(d_z, |d_xy|)
    horizontal = np.hypot(d[..., 0], d[..., 1])
    pan = np.where(horizontal > SINGULAR_COS, np.arctan2(d[..., 1], d[..., 0]), current_pan)
    tilt = np.arctan2(d[..., 2], horizontal)
    return pan, tilt


def pan_tilt_to_quat(pan: np.ndarray, tilt: np.ndarray) -> np.ndarray:
    """Twist-free quaternion (..., 4), w >= 0, for joint angles (rad)."""
    return swing_from_direction(pan_tilt_to_direction(pan, tilt))


def quat_to_pan_tilt(
    q: np.ndarray, current_pan: np.ndarray | float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Joint angles (rad) that point the limb where ``q`` points it (twist is ignored)."""
    return direction_to_pan_tilt(limb_direction(q), current_pan)


def chain_twist(pan: np.ndarray, tilt: np.ndarray) -> np.ndarray:
    """Twist (rad) of ``Rz(pan) Ry(-tilt)`` about +x, finite at pan = 180 deg."""
    pan = np.asarray(pan, dtype=np.float64)
    tilt = np.asarray(tilt, dtype=np.float64)
    # tau = 2 atan(tan(pan/2) tan(tilt/2)) = 2 atan2(sp st, cp ct)
    return 2.0 * np.arctan2(np.sin(pan / 2) * np.sin(tilt / 2), np.cos(pan / 2) * np.cos(tilt / 2))


def _pan_tilt_half(pan: np.ndarray, tilt: np.ndarray) -> np.ndarray:
    """``A = Rz(pan) Ry(-tilt)`` as quaternions (..., 4)."""
    cp, sp = np.cos(pan / 2), np.sin(pan / 2)
    ct, st = np.cos(tilt / 2), np.sin(tilt / 2)
    # A = (cp ct, sp st, -cp st, sp ct)
    return np.stack([cp * ct, sp * st, -cp * st, sp * ct], axis=-1)


def pan_tilt_roll_to_quat(pan: np.ndarray, tilt: np.ndarray, roll: np.ndarray) -> np.ndarray:
    """Orientation ``Rz(pan) Ry(-tilt) Rx(roll)`` (..., 4), scalar first, w >= 0."""
    pan, tilt, roll = np.broadcast_arrays(
        *(np.asarray(v, dtype=np.float64) for v in (pan, tilt, roll))
    )
    a = _pan_tilt_half(pan, tilt)
    cr, sr = np.cos(roll / 2), np.sin(roll / 2)
    # q = (A_w cr - A_x sr, A_w sr + A_x cr, A_y cr + A_z sr, A_z cr - A_y sr)
    q = np.stack(
        [
            a[..., 0] * cr - a[..., 1] * sr,
            a[..., 0] * sr + a[..., 1] * cr,
            a[..., 2] * cr + a[..., 3] * sr,
            a[..., 3] * cr - a[..., 2] * sr,
        ],
        axis=-1,
    )
    return np.where(q[..., :1] < 0.0, -q, q)


def pose_quat_scalar(pan: float, tilt: float, roll: float) -> np.ndarray:
    """:func:`pan_tilt_roll_to_quat` of one pose, shape (4,)."""
    cp, sp = math.cos(pan / 2), math.sin(pan / 2)
    ct, st = math.cos(tilt / 2), math.sin(tilt / 2)
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    # A = (cp ct, sp st, -cp st, sp ct); q = A Rx(roll)
    aw, ax, ay, az = cp * ct, sp * st, -cp * st, sp * ct
    w, x, y, z = aw * cr - ax * sr, aw * sr + ax * cr, ay * cr + az * sr, az * cr - ay * sr
    if w < 0.0:
        w, x, y, z = -w, -x, -y, -z
    return np.array([w, x, y, z])


def unwrap_roll_scalar(roll: float, present: float, lo: float, hi: float) -> float:
    """The representative ``roll + 2 pi k`` (k in -1, 0, 1) within ``[lo, hi]`` nearest ``present``
    (``roll`` in (-2 pi, 2 pi] rad); else the one nearest the limits."""
    best, best_score = roll, math.inf
    for k in (-1.0, 0.0, 1.0):
        candidate = roll + 2.0 * math.pi * k
        outside = max(lo - candidate, 0.0) + max(candidate - hi, 0.0)
        score = 4.0 * math.pi + outside if outside > 0.0 else abs(candidate - present)
        if score < best_score:
            best, best_score = candidate, score
    return best


def pan_tilt_roll_scalar(
    q: np.ndarray, current_pan: float, current_roll: float, lo: float, hi: float
) -> tuple[float, float, float]:
    """Joint angles (rad) with ``Rz(pan) Ry(-tilt) Rx(roll) = +-q`` for unit ``q`` (4,), the pan
    ``current_pan`` at tilt +-90 deg, the roll unwrapped near ``current_roll`` in ``[lo, hi]``."""
    # roll = 2 atan2(r_x, r_w) of r = conj(A) q, A = Rz(pan) Ry(-tilt)
    pan, tilt = pan_tilt_scalar(limb_scalar(q), current_pan)
    cp, sp = math.cos(pan / 2), math.sin(pan / 2)
    ct, st = math.cos(tilt / 2), math.sin(tilt / 2)
    aw, ax, ay, az = cp * ct, sp * st, -cp * st, sp * ct
    w, x, y, z = q.tolist()
    # r = conj(A) q: r_w = A . q, r_x = A_w q_x - A_x q_w - A_y q_z + A_z q_y
    r_w = aw * w + ax * x + ay * y + az * z
    r_x = aw * x - ax * w - ay * z + az * y
    return pan, tilt, unwrap_roll_scalar(2.0 * math.atan2(r_x, r_w), current_roll, lo, hi)


def pose_quat(*pose: float) -> np.ndarray:
    """Orientation (4,), w >= 0, of one pose ``(pan, tilt)`` or ``(pan, tilt, roll)``."""
    if len(pose) == 2:
        return pan_tilt_to_quat(*pose)
    return pose_quat_scalar(*pose)
