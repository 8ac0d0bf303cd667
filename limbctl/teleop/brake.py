"""The brake rules: a wall lets its leader go before the servo's loop would brake it outward.

The servo's position loop pulls toward its profile setpoint, which walks toward the region at
RETURN_SPEED (:mod:`limbctl.teleop.haptic`). A leader that gains on that setpoint (a hand
pulling it back inside, a grip fading while the wall walks the leader back, a setpoint that
stopped at its goal because a cycle came late) is braked by the loop: its torque turns away
from the region while the leader is still outside it. The snap watch (:mod:`limbctl.teleop.
snap`) reads the leader's speed and torque about every millisecond while a wall is on, and
these rules free the wall (Goal Current 0) before the braking starts::

    outrun   the leader moves toward the region faster than the setpoint walks, by more than
             OUTRUN, while the motor's read torque toward the region is under LOOSE (no hand
             held against the wall, which a cut would let throw the leader out)
    braking  the leader moves toward the region (faster than STILL), and the motor's torque
             toward the region, carried on at its rate since the last read (within SPAN),
             falls under zero within HORIZON, or within the gap since the last read plus
             LAND if that is longer (the next read comes about as late)

A freed wall comes back only on a leader read as not moving in (the snap watch's re-arm
rule), from where the leader then is. The rules only ever take torque away.
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
        setpoint's own units (10 units, 13.7 deg/s; the next reads 15.1) is an outrun. A leader
        the wall walks back itself (its speed ripples up to 14.0 deg/s) keeps its wall; a hand
        pulling it in, or a fading grip's last push, takes it past the setpoint's pace a few
        milliseconds before the loop brakes. At 1.5 deg/s a 100 ms fade read at 15.1 deg/s
        kept its wall and was braked (decisions/haptic.md, round 8).
    loose_nm : float
        0.06 N m, the snap watch's HOLD: under it no hand is held against the wall, so freeing
        the wall cannot let a hand throw the leader outward (a fading grip cut while the hand
        still pushed 0.25 N m threw the leader 0.3 deg out: decisions/haptic.md, round 7).
    horizon_s : float
        2 ms: a cut decided at a read lands within a millisecond over the bus, and the stepped
        clock's grain is another; the torque must still point toward the region then.
    land_s : float
        1 ms: a cut's write lands within it of the read that decided it. Over the pty the
        watch's reads come 2-3 ms apart (a sync read and the cycle's own work between them),
        so the torque must stay toward the region until the read after next could act: the gap
        since the last read plus this.
    span_s : float
        4 ms: the torque's rate is taken only from two reads this close (the watch reads about
        every millisecond, the cycle's own work leaves 2-3 ms between two of its reads); an
        older read says nothing of the loop's braking now.
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
