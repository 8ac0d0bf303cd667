"""Pan/tilt joint angles <-> limb direction <-> quaternion for the two-servo gimbal.

The limb rests along +x. Pan rotates about +z, tilt raises the limb toward +z:
``d = (cos(tilt) cos(pan), cos(tilt) sin(pan), sin(tilt))``. The orientation a pose stands
for is the twist-free swing from +x to ``d`` (a 2-DOF limb has no twist to constrain).
At the singularity (limb along +-z) inverse kinematics keeps the current pan.
"""

from __future__ import annotations

import numpy as np

from limbctl.geometry.quat import limb_direction, swing_from_direction

#: |d_z| above which the pan is undefined and the current pan is kept.
SINGULAR_COS = 1e-9


def pan_tilt_to_direction(pan: np.ndarray, tilt: np.ndarray) -> np.ndarray:
    """Limb direction (..., 3) for joint angles ``pan``, ``tilt`` (rad)."""
    pan = np.asarray(pan, dtype=np.float64)
    tilt = np.asarray(tilt, dtype=np.float64)
    ct = np.cos(tilt)
    return np.stack([ct * np.cos(pan), ct * np.sin(pan), np.sin(tilt)], axis=-1)


def direction_to_pan_tilt(
    d: np.ndarray, current_pan: np.ndarray | float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Inverse kinematics: joint angles (rad) that point the limb along ``d`` (..., 3).

    ``pan = atan2(d_y, d_x)``, ``tilt = asin(d_z)``. Where the horizontal part of ``d``
    vanishes (limb along +-z), ``current_pan`` is kept.
    """
    d = np.asarray(d, dtype=np.float64)
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
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
