"""The gate's outcome in words: what it did with the command and which way is blocked.

:func:`explain` compares the pose the command asked for with the pose the gate let through and
says, e.g., "at the edge: up is blocked, sliding along it". A joint direction is *blocked* when
the command lies beyond the written pose that way by more than :data:`BLOCKED_MIN_DEG`. Names of
directions depend on who reads them: the terminal names pan as seen from behind the limb
(:data:`KEYBOARD_NAMES`, left is +pan), the page as drawn on its plane (:data:`PLANE_NAMES`, +pan
to the right).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from limbctl.teleop.gate import GateResult, Outcome

#: Directions as the terminal's arrow keys name them (left is +pan, toward +y).
KEYBOARD_NAMES = {"+pan": "left", "-pan": "right", "+tilt": "up", "-tilt": "down"}
#: Directions as the page's pan/tilt plane draws them (pan to the right, tilt up).
PLANE_NAMES = {"+pan": "right", "-pan": "left", "+tilt": "up", "-tilt": "down"}
#: How far (deg) the command must lie beyond the written pose along a joint for that way to be
#: called blocked: well above the 0.01 deg the gate's correction may leave, well below one step.
BLOCKED_MIN_DEG = 0.2
#: Smallest move (deg) of the written pose between two cycles that counts as sliding: above the
#: ~1e-12 rad round trip through joint angles, below one tick (0.088 deg).
MOVING_MIN_DEG = 1e-3


@dataclass(frozen=True)
class Explanation:
    """The gate's outcome for a reader.

    Attributes
    ----------
    words : str
        e.g. "at the edge: up is blocked, sliding along it".
    blocked : tuple of str
        The blocked joint directions ("+pan", "-pan", "+tilt", "-tilt"), pan first.
    """

    words: str
    blocked: tuple[str, ...] = ()


def blocked_directions(
    commanded_deg: tuple[float, float],
    written_deg: tuple[float, float],
    previous_deg: tuple[float, float] | None = None,
) -> tuple[str, ...]:
    """Joint directions the command asks for but the limb does not go (pan first).

    The gap ``c = commanded - written`` asks for a joint direction when it exceeds
    :data:`BLOCKED_MIN_DEG` there. The last move ``m = written - previous`` (none without
    ``previous``) goes that way in its share ``m_j sign(c_j) / |m|``. The direction is blocked
    when that share is under half the command's share ``|c_j| / |c|``: a limb travelling toward
    the command has equal shares, one sliding along an edge has none toward it.
    """
    gap = [wanted - got for wanted, got in zip(commanded_deg, written_deg, strict=True)]
    move = [0.0, 0.0]
    if previous_deg is not None:
        move = [got - before for got, before in zip(written_deg, previous_deg, strict=True)]
    gap_norm = math.hypot(*gap)
    move_norm = math.hypot(*move)
    out = []
    for joint, c, m in zip(("pan", "tilt"), gap, move, strict=True):
        if abs(c) <= BLOCKED_MIN_DEG:
            continue
        moving_share = m * math.copysign(1.0, c) / move_norm if move_norm > MOVING_MIN_DEG else 0.0
        if moving_share < 0.5 * abs(c) / gap_norm:
            out.append(f"{'+' if c > 0 else '-'}{joint}")
    return tuple(out)


def explain(
    result: GateResult | None,
    commanded_deg: tuple[float, float] | None,
    previous_deg: tuple[float, float] | None = None,
    names: dict[str, str] = KEYBOARD_NAMES,
) -> Explanation:
    """Say what the gate did this cycle.

    Parameters
    ----------
    result : GateResult or None
        The gate's answer (None: the cycle ended before the gate ran).
    commanded_deg : (pan, tilt) deg or None
        The command being followed.
    previous_deg : (pan, tilt) deg or None
        The pose the gate gave one cycle earlier, to tell sliding from standing.
    names : dict
        Words for "+pan", "-pan", "+tilt", "-tilt".
    """
    if result is None:
        return Explanation("not running")
    if result.outcome is Outcome.HELD:
        return Explanation(f"holding the last safe pose: {result.reason}")
    if commanded_deg is None:
        return Explanation(result.outcome.value)
    written = (math.degrees(result.pan), math.degrees(result.tilt))
    if result.outcome is Outcome.PASSED:
        return Explanation("inside: following the command")
    if not (result.corrected or result.clamped):
        return Explanation("on the way: the speed limit paces it")
    where = "at a hard limit" if result.clamped else "at the edge"
    blocked = blocked_directions(commanded_deg, written, previous_deg)
    moving = previous_deg is not None and (
        math.hypot(written[0] - previous_deg[0], written[1] - previous_deg[1]) > MOVING_MIN_DEG
    )
    if not blocked:
        if moving:  # toward the nearest pose inside, which the command lies beyond
            return Explanation(
                f"on the way to {where.removeprefix('at ')}: the command lies beyond"
            )
        return Explanation(f"{where}: corrected onto it")
    ways = " and ".join(names[d] for d in blocked)
    verb = "is" if len(blocked) == 1 else "are"
    how = "sliding along it" if moving else "holding there"
    return Explanation(f"{where}: {ways} {verb} blocked, {how}", blocked)
