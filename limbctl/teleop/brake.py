"""The brake rules: a wall lets its leader go before the servo's loop would brake it outward.

The loop pulls toward its profile setpoint, which walks toward the region at RETURN_SPEED; a
leader that gains on it is braked (torque away from the region while still outside). The snap
watch (:mod:`limbctl.teleop.snap`) reads speed and torque about every millisecond while a wall
is on and frees it (Goal Current 0) when the leader *outruns* the setpoint with no hand held
(:func:`outruns`) or its torque toward the region is about to fall under zero
(:func:`brakes_soon`). The rules only ever take torque away; docs/haptic.md ("The brake
rules") gives the figures.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class BrakeLaw:
    """The brake rules' constants.

    Attributes
    ----------
    outrun_deg_s : float
        1.0 deg/s, under one Present Velocity unit (1.37 deg/s): the first reading above the
        setpoint's own units (10 units, 13.7 deg/s; the next reads 15.1) is an outrun, while a
        leader the wall walks back itself (rippling up to 14.0 deg/s) keeps its wall.
    loose_nm : float
        0.06 N m, the snap watch's HOLD: under it no hand is held against the wall, so freeing
        the wall cannot let a hand throw the leader outward.
    horizon_s : float
        2 ms: a cut decided at a read lands within a millisecond over the bus, and the stepped
        clock's grain is another; the torque must still point toward the region then.
    land_s : float
        1 ms: a cut's write lands within it of its read; reads come 2-3 ms apart over the pty,
        so the torque must stay toward the region for the gap since the last read plus this.
    span_s : float
        4 ms: the torque's rate is taken only from two reads this close (the watch's 1 ms, or
        2-3 ms across a cycle's own work); an older read says nothing of the braking now.
    """

    outrun_deg_s: float = 1.0
    loose_nm: float = 0.06
    horizon_s: float = 0.002
    land_s: float = 0.001
    span_s: float = 0.004


def outruns(toward_deg_s: float, walk_deg_s: float, torque_nm: float, law: BrakeLaw) -> bool:
    """Whether a leader moving toward the region at ``toward_deg_s`` outruns a setpoint walking
    at ``walk_deg_s`` (deg/s) with no hand held against the wall (``torque_nm``: the motor's
    read torque toward the region, N m)."""
    return toward_deg_s > walk_deg_s + law.outrun_deg_s and torque_nm < law.loose_nm


def brakes_soon(
    toward_deg_s: float,
    still_deg_s: float,
    torque_nm: float,
    now_s: float,
    seen: tuple[float, float] | None,
    law: BrakeLaw,
) -> bool:
    """Whether the loop is about to brake a leader moving toward the region at
    ``toward_deg_s`` (deg/s; over ``still_deg_s``): its torque toward the region ``torque_nm``
    (N m, read at ``now_s``, s), carried on at its rate since ``seen`` (the torque and time of
    the last read, None if none), falls under zero within HORIZON (or the gap since that read
    plus LAND)."""
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
