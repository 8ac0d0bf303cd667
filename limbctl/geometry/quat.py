"""Quaternion algebra for limb orientations: float64 (4,) or (N, 4), scalar first ``(w, x, y,
z)``, unit, canonical ``w >= 0`` (docs/architecture.md); the limb rests along +x."""

from __future__ import annotations

import numpy as np

from limbctl.errors import InvalidInputError

#: Tolerance on | |q| - 1 | for input quaternions.
UNIT_TOLERANCE = 1e-6


def as_quaternions(
    q: object, name: str = "q", tol: float = UNIT_TOLERANCE
) -> tuple[np.ndarray, bool]:
    """Validate unit quaternions ``q`` (4,) or (N, 4) (w, x, y, z) (``name`` in messages, ``tol``
    on the norm): a float64 copy (N, 4) canonicalised to w >= 0, and True when the input was a
    single (4,) quaternion. InvalidInputError names the first row that is non-finite or not unit
    length, or the wrong shape."""
    try:
        arr = np.array(q, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"{name}: cannot read as float quaternions ({exc})") from exc
    single = arr.ndim == 1
    if single:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != 4:
        raise InvalidInputError(f"{name}: expected shape (4,) or (N, 4), got {np.shape(q)}")
    finite = np.isfinite(arr).all(axis=1)
    if not finite.all():
        row = int(np.flatnonzero(~finite)[0])
        raise InvalidInputError(f"{name}: row {row} is not finite: {arr[row].tolist()}")
    norms = np.linalg.norm(arr, axis=1)
    bad = ~(np.abs(norms - 1.0) <= tol)
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise InvalidInputError(
            f"{name}: row {row} has norm {norms[row]:.9g}, expected a unit quaternion "
            f"(normalise it first)"
        )
    return canonical(arr), single


def canonical(q: np.ndarray) -> np.ndarray:
    """Flip quaternions (..., 4) into the w >= 0 hemisphere (q and -q are one rotation)."""
    q = np.asarray(q, dtype=np.float64)
    sign = np.where(q[..., :1] < 0.0, -1.0, 1.0)
    return q * sign


def normalize(q: np.ndarray) -> np.ndarray:
    """Scale quaternions to unit length (no hemisphere change). Shape (..., 4)."""
    q = np.asarray(q, dtype=np.float64)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a * b`` (apply b, then a). Shapes broadcast over (..., 4)."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    # (aw, av)(bw, bv) = (aw bw - av.bv, aw bv + bw av + av x bv)
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def from_axis_angle(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Quaternion of a rotation by ``angle`` (rad) about unit ``axis`` (..., 3)."""
    axis = np.asarray(axis, dtype=np.float64)
    half = 0.5 * np.asarray(angle, dtype=np.float64)
    # q = (cos(angle/2), sin(angle/2) * axis)
    return np.concatenate([np.cos(half)[..., None], np.sin(half)[..., None] * axis], axis=-1)


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors ``v`` (..., 3) by unit quaternions ``q`` (..., 4)."""
    q = np.asarray(q, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    w = q[..., :1]
    u = q[..., 1:]
    # v' = v + 2 w (u x v) + 2 u x (u x v)
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def limb_direction(q: np.ndarray) -> np.ndarray:
    """Unit direction (..., 3) of a limb resting along +x after rotation by ``q`` (..., 4)."""
    q = np.asarray(q, dtype=np.float64)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    d = np.empty(q.shape[:-1] + (3,))
    # d = (w^2 + x^2 - y^2 - z^2, 2(xy + wz), 2(xz - wy))
    d[..., 0] = w * w + x * x - y * y - z * z
    d[..., 1] = 2 * (x * y + w * z)
    d[..., 2] = 2 * (x * z - w * y)
    return d


def swing_from_direction(d: np.ndarray) -> np.ndarray:
    """The twist-free quaternion (..., 4) turning +x onto ``d`` (..., 3); at -x the turn about z."""
    d = np.asarray(d, dtype=np.float64)
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    # q = normalize(1 + d_x, 0, -d_z, d_y)
    q = np.zeros(d.shape[:-1] + (4,))
    q[..., 0] = 1.0 + d[..., 0]
    q[..., 2] = -d[..., 2]
    q[..., 3] = d[..., 1]
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    antipodal = n[..., 0] < 1e-12
    q = np.where(antipodal[..., None], np.array([0.0, 0.0, 0.0, 1.0]), q / np.where(n > 0, n, 1.0))
    return q


def swing_angle(q: np.ndarray) -> np.ndarray:
    """Swing angle (...,) rad of ``q``, limb to rest direction: ``2 acos(sqrt(w^2 + x^2))``."""
    q = np.asarray(q, dtype=np.float64)
    c = np.sqrt(np.clip(q[..., 0] ** 2 + q[..., 1] ** 2, 0.0, 1.0))
    return 2.0 * np.arccos(c)


def geodesic_distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotation angle (rad) between orientations: ``2 acos(|<a, b>|)``. Shapes broadcast."""
    dot = np.abs(np.sum(np.asarray(a, dtype=np.float64) * np.asarray(b, dtype=np.float64), axis=-1))
    return 2.0 * np.arccos(np.clip(dot, 0.0, 1.0))


def euclidean_distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Euclidean distance in R^4 between quaternions, sign-aware: ``min(|a - b|, |a + b|)``."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    return np.minimum(np.linalg.norm(a - b, axis=-1), np.linalg.norm(a + b, axis=-1))


def direction_angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle (rad) between unit direction vectors ``a`` and ``b`` (..., 3), robust near 0."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    # atan2(|a x b|, a . b) is accurate for tiny and near-pi angles alike
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))


def tangent_frame(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit u, v (3,) completing ``axis`` (3,) to a right-handed frame (u from +z, or +y near z)."""
    helper = np.array([0.0, 0.0, 1.0]) if abs(axis[2]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(helper, axis)
    u /= np.linalg.norm(u)
    return u, np.cross(axis, u)
