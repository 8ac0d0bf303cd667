"""The simulated gimbal's own orientation geometry (the simulator imports nothing of limbctl):
the chain ``q = Rz(pan) Ry(-tilt) Rx(roll)`` and its twist about the rest axis +x, from the
swing-twist split ``q = swing(d) * twist(tau)``. Angles in radians unless named ``_deg``."""

from __future__ import annotations

import math


def chain_twist(pan: float, tilt: float) -> float:
    """Twist (rad) of ``Rz(pan) Ry(-tilt)`` about +x."""
    # tau = 2 atan2(sin(p/2) sin(t/2), cos(p/2) cos(t/2))
    return 2.0 * math.atan2(
        math.sin(pan / 2) * math.sin(tilt / 2), math.cos(pan / 2) * math.cos(tilt / 2)
    )


def wrap_deg(angle_deg: float) -> float:
    """An angle (deg) wrapped into (-180, 180]."""
    # a - 360 ceil((a - 180) / 360)
    return angle_deg - 360.0 * math.ceil((angle_deg - 180.0) / 360.0)


def roll_for_twist_deg(pan_deg: float, tilt_deg: float, twist_deg: float) -> float:
    """The roll (deg, in (-180, 180]) giving the limb the twist ``twist_deg`` at a swing pose."""
    tau = math.degrees(chain_twist(math.radians(pan_deg), math.radians(tilt_deg)))
    return wrap_deg(twist_deg - tau)


def chain_quat(pan: float, tilt: float, roll: float) -> tuple[float, float, float, float]:
    """``Rz(pan) Ry(-tilt) Rx(roll)`` as ``(w, x, y, z)`` with w >= 0."""
    cp, sp = math.cos(pan / 2), math.sin(pan / 2)
    ct, st = math.cos(tilt / 2), math.sin(tilt / 2)
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    # A = Rz(pan) Ry(-tilt) = (cp ct, sp st, -cp st, sp ct); q = A Rx(roll)
    aw, ax, ay, az = cp * ct, sp * st, -cp * st, sp * ct
    w, x, y, z = aw * cr - ax * sr, aw * sr + ax * cr, ay * cr + az * sr, az * cr - ay * sr
    if w < 0.0:
        w, x, y, z = -w, -x, -y, -z
    return (w, x, y, z)
