"""Twist: how a full orientation splits into direction and twist, ``q = swing(d) * twist(tau)``.
``swing(d)`` is the shortest rotation from the rest axis +x onto the limb direction ``d``;
``twist(tau) = (cos(tau/2), sin(tau/2), 0, 0)`` turns the limb by ``tau`` (rad, in ``(-pi, pi]``)
about +x, applied first. At ``d = -x`` the swing is the half-turn about +z and twist loses
precision like ``1e-16 / s_w`` near it, so regions stay :data:`SINGULAR_MARGIN` away from -x."""

from __future__ import annotations

import math

import numpy as np

from limbctl.geometry.quat import canonical, limb_direction, swing_from_direction

Vec3 = tuple[float, float, float]

#: Swing scalar ``s_w`` below which the direction is -x, twist read from (y, z): above rounding.
SINGULAR_SW = 1e-12
#: Closest angle (rad) a region comes to -x: s_w >= sin(10 deg) keeps twist precise to ~1e-15.
SINGULAR_MARGIN = math.radians(20.0)


def wrap(angle: np.ndarray | float) -> np.ndarray:
    """Angles (rad) wrapped into ``(-pi, pi]`` (the twist's range). Shape as given."""
    a = np.asarray(angle, dtype=np.float64)
    # a - 2 pi ceil((a - pi) / 2 pi) lies in (-pi, pi]
    wrapped = a - 2.0 * np.pi * np.ceil((a - np.pi) / (2.0 * np.pi))
    # the quotient rounds near the ends (-pi + 4e-16 wrapped to pi + 4e-16): in range is kept
    wrapped = np.where(wrapped > np.pi, wrapped - 2.0 * np.pi, wrapped)
    wrapped = np.where(wrapped <= -np.pi, wrapped + 2.0 * np.pi, wrapped)
    return np.where((a > -np.pi) & (a <= np.pi), a, wrapped)


def decompose(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Split unit quaternions (..., 4), either hemisphere, into unit limb directions ``d`` (...,
    3) and twists ``tau`` (...,) rad in ``(-pi, pi]``: ``q = swing(d) * twist(tau)``."""
    q = canonical(np.asarray(q, dtype=np.float64))
    w, x, y, z = np.moveaxis(q, -1, 0)
    singular = np.hypot(w, x) < SINGULAR_SW
    # tau = 2 atan2(x, w); at d = -x, q = (0, 0, sin(tau/2), cos(tau/2)) so tau = 2 atan2(y, z)
    tau = 2.0 * np.where(singular, np.arctan2(y, z), np.arctan2(x, w))
    d = limb_direction(q)
    d = np.where(singular[..., None], np.array([-1.0, 0.0, 0.0]), d)
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    return d, wrap(tau)


def compose(d: np.ndarray, tau: np.ndarray | float) -> np.ndarray:
    """Unit orientations ``swing(d) * twist(tau)`` (..., 4), w >= 0, of directions ``d`` (..., 3)
    (normalised here) and twists ``tau`` (...,) rad (any value)."""
    return twisted(swing_from_direction(d), tau)


def twisted(sw: np.ndarray, tau: np.ndarray | float) -> np.ndarray:
    """Unit orientations ``sw * twist(tau)`` (..., 4), w >= 0, of swings ``sw`` (..., 4) (as
    :func:`~limbctl.geometry.quat.swing_from_direction` gives, x = 0) and twists ``tau`` (...,)
    rad, broadcast together: :func:`compose` with the swing computed once for many twists."""
    half = 0.5 * wrap(tau)
    c, s = np.cos(half), np.sin(half)
    s_w, s_y, s_z = sw[..., 0], sw[..., 2], sw[..., 3]
    # q = swing(d) * twist(tau) = (s_w c, s_w s, s_y c + s_z s, s_z c - s_y s)
    q = np.stack([s_w * c, s_w * s, s_y * c + s_z * s, s_z * c - s_y * s], axis=-1)
    return canonical(q)


def decompose_one(q: np.ndarray) -> tuple[Vec3, float]:
    """Scalar twin of :func:`decompose` for one quaternion (4,)."""
    w, x, y, z = q.tolist()
    if w < 0.0:
        w, x, y, z = -w, -x, -y, -z
    if math.hypot(w, x) < SINGULAR_SW:
        # d = -x, q = (0, 0, sin(tau/2), cos(tau/2))
        return (-1.0, 0.0, 0.0), _wrap_one(2.0 * math.atan2(y, z))
    # d = (w^2 + x^2 - y^2 - z^2, 2(xy + wz), 2(xz - wy)), tau = 2 atan2(x, w)
    d0, d1, d2 = w * w + x * x - y * y - z * z, 2.0 * (x * y + w * z), 2.0 * (x * z - w * y)
    n = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    return (d0 / n, d1 / n, d2 / n), _wrap_one(2.0 * math.atan2(x, w))


def _wrap_one(a: float) -> float:
    """Scalar :func:`wrap` (the same fold at the ends)."""
    if -math.pi < a <= math.pi:
        return a
    wrapped = a - 2.0 * math.pi * math.ceil((a - math.pi) / (2.0 * math.pi))
    if wrapped > math.pi:
        return wrapped - 2.0 * math.pi
    return wrapped + 2.0 * math.pi if wrapped <= -math.pi else wrapped
