"""The brake rules: a wall lets its leader go before the servo's loop brakes it outward."""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class BrakeLaw:
    """The brake rules' constants (units in their names); docs/haptic.md's table gives each
    value and its reasoning."""

    outrun_deg_s: float = 1.0
    loose_nm: float = 0.06
    horizon_s: float = 0.002
    land_s: float = 0.001
    span_s: float = 0.004


def outruns(toward_deg_s: float, walk_deg_s: float, torque_nm: float, law: BrakeLaw) -> bool:
    """Whether a leader moving in (deg/s) outruns its setpoint with no hand held (torque, N m)."""
    return toward_deg_s > walk_deg_s + law.outrun_deg_s and torque_nm < law.loose_nm


def brakes_soon(
    toward_deg_s: float,
    still_deg_s: float,
    torque_nm: float,
    now_s: float,
    seen: tuple[float, float] | None,
    law: BrakeLaw,
) -> bool:
    """Whether a leader moving in faster than ``still_deg_s`` (deg/s) has its torque toward the
    region (N m at ``now_s``, extrapolated from the last read's ``seen``) under zero within
    HORIZON."""
    if toward_deg_s <= still_deg_s:
        return False
    if torque_nm < 0.0:
        return True
    gap = math.inf if seen is None else now_s - seen[1]
    if not 0.0 < gap <= law.span_s:
        return False
    # tau(now + h) = tau(now) + h (tau(now) - tau(seen)) / gap,  h = max(HORIZON, gap + LAND)
    rate = (torque_nm - seen[0]) / gap
    return torque_nm + max(law.horizon_s, gap + law.land_s) * rate < 0.0
