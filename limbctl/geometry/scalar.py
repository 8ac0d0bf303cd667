"""Scalar kinematics for the gate's hot path: :mod:`~limbctl.geometry.gimbal`'s and
:mod:`~limbctl.geometry.quat`'s formulas for one pose in plain floats (radians), without numpy's
per-call overhead."""

from __future__ import annotations

import math

import numpy as np

Vec3 = tuple[float, float, float]

#: |d_z| above which the pan is undefined and the current pan is kept.
SINGULAR_COS = 1e-9

#: Norm below which a tangent or swing axis is zero: far above rounding (~1e-16) of unit vectors.
DEGENERATE_NORM = 1e-12


def direction(pan: float, tilt: float) -> Vec3:
    """Limb direction at joint angles ``(pan, tilt)`` (as ``gimbal.pan_tilt_to_direction``)."""
    # d = (cos t cos p, cos t sin p, sin t)
    ct = math.cos(tilt)
    return (ct * math.cos(pan), ct * math.sin(pan), math.sin(tilt))


def swing(d: Vec3) -> np.ndarray:
    """Twist-free quaternion (4,) turning +x onto unit ``d`` (as ``quat.swing_from_direction``)."""
    # q = normalize(1 + d_x, 0, -d_z, d_y)
    w, y, z = 1.0 + d[0], -d[2], d[1]
    norm = math.sqrt(w * w + y * y + z * z)
    if norm < DEGENERATE_NORM:  # d = -x: the half-turn about +z
        return np.array([0.0, 0.0, 0.0, 1.0])
    return np.array([w / norm, 0.0, y / norm, z / norm])


def limb(q: np.ndarray) -> Vec3:
    """Limb direction of unit quaternion ``q`` (4,) (as ``quat.limb_direction``)."""
    # d = (w^2 + x^2 - y^2 - z^2, 2(xy + wz), 2(xz - wy)): +x rotated by q
    w, x, y, z = q.tolist()
    return (w * w + x * x - y * y - z * z, 2.0 * (x * y + w * z), 2.0 * (x * z - w * y))


def angle(a: Vec3, b: Vec3) -> float:
    """Angle (rad) between unit directions (as ``quat.direction_angle``)."""
    # atan2(|a x b|, a . b): accurate for tiny angles
    cx = a[1] * b[2] - a[2] * b[1]
    cy = a[2] * b[0] - a[0] * b[2]
    cz = a[0] * b[1] - a[1] * b[0]
    return math.atan2(
        math.sqrt(cx * cx + cy * cy + cz * cz), a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    )


def toward(a: Vec3, b: Vec3, step: float) -> Vec3:
    """Unit direction ``step`` rad from ``a`` along the great circle toward ``b``."""
    # d = cos(step) a + sin(step) u, with u the unit tangent at a toward b
    dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    t = (b[0] - dot * a[0], b[1] - dot * a[1], b[2] - dot * a[2])
    norm = math.sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2])
    if norm < DEGENERATE_NORM:
        return a
    c, s = math.cos(step), math.sin(step) / norm
    return (c * a[0] + s * t[0], c * a[1] + s * t[1], c * a[2] + s * t[2])


def pan_tilt(d: Vec3, current_pan: float) -> tuple[float, float]:
    """Joint angles of direction ``d``, the pan kept at the singularity (as ``gimbal``'s)."""
    # pan = atan2(d_y, d_x), tilt = atan2(d_z, |d_xy|)
    horizontal = math.hypot(d[0], d[1])
    pan = math.atan2(d[1], d[0]) if horizontal > SINGULAR_COS else current_pan
    return pan, math.atan2(d[2], horizontal)
