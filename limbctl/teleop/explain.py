"""The gate's outcome in words, e.g. "at the edge: up is blocked, sliding left along it"."""

from __future__ import annotations

import math
from dataclasses import dataclass

from limbctl.teleop.gate import GateResult, Outcome

#: Directions seen from behind the limb (at rest along +x): +pan turns it left (+y).
DIRECTION_NAMES = {"+pan": "left", "-pan": "right", "+tilt": "up", "-tilt": "down"}
#: The names the page uses (the same: its plane is seen from behind the limb).
PLANE_NAMES = DIRECTION_NAMES
#: How far (deg) beyond the written pose a joint's command is blocked: > 0.01 deg tolerance.
BLOCKED_MIN_DEG = 0.2
#: Smallest move (deg) between two cycles that counts as sliding: above rounding, below a tick.
MOVING_MIN_DEG = 1e-3


@dataclass(frozen=True)
class Explanation:
    """The gate's outcome for a reader: ``words``, and the ``blocked`` joint directions."""

    words: str
    blocked: tuple[str, ...] = ()


def blocked_directions(
    commanded_deg: tuple[float, float],
    written_deg: tuple[float, float],
    previous_deg: tuple[float, float] | None = None,
) -> tuple[str, ...]:
    """Joint directions the command asks for that the last move goes under half as much."""
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


def pushed_short(
    commanded_deg: tuple[float, float], written_deg: tuple[float, float], pushing: tuple[str, ...]
) -> tuple[str, ...]:
    """The ``pushing`` directions the command lies beyond by over :data:`BLOCKED_MIN_DEG`."""
    out = []
    for index, joint in enumerate(("pan", "tilt")):
        for sign in ("+", "-"):
            if f"{sign}{joint}" not in pushing:
                continue
            short = (commanded_deg[index] - written_deg[index]) * (1.0 if sign == "+" else -1.0)
            if short > BLOCKED_MIN_DEG:
                out.append(f"{sign}{joint}")
    return tuple(out)


def slide_direction(move_deg: tuple[float, float]) -> str:
    """The joint direction of a move's larger component ("+pan", "-tilt", ...)."""
    joint = 0 if abs(move_deg[0]) >= abs(move_deg[1]) else 1
    return f"{'+' if move_deg[joint] > 0 else '-'}{('pan', 'tilt')[joint]}"


def explain(
    result: GateResult | None,
    commanded_deg: tuple[float, float] | None,
    previous_deg: tuple[float, float] | None = None,
    names: dict[str, str] = DIRECTION_NAMES,
    pushing: tuple[str, ...] | None = None,
) -> Explanation:
    """Say what the gate did this cycle (``result`` None: the cycle ended before the gate ran).
    ``commanded_deg``/``previous_deg`` are the command followed and the pose the gate gave a cycle
    earlier, (pan, tilt) deg; ``names`` words for "+pan" ... "-tilt"; ``pushing`` the directions a
    person pushes (e.g. ``("+tilt",)``): only those may be blocked."""
    if result is None:
        return Explanation("not running")
    if result.outcome is Outcome.HELD:
        return Explanation(f"holding the last safe pose: {result.reason}")
    if commanded_deg is None:
        return Explanation(result.outcome.value)
    written = (math.degrees(result.pose[0]), math.degrees(result.pose[1]))
    if result.outcome is Outcome.PASSED:
        return Explanation("inside: following the command")
    if not (result.corrected or result.clamped):
        return Explanation("on the way: the speed limit paces it")
    where = "at a hard limit" if result.clamped else "at the edge"
    move = (0.0, 0.0)
    if previous_deg is not None:
        move = (written[0] - previous_deg[0], written[1] - previous_deg[1])
    moving = math.hypot(*move) > MOVING_MIN_DEG
    if pushing is None:
        blocked = blocked_directions(commanded_deg, written, previous_deg)
    else:
        blocked = pushed_short(commanded_deg, written, pushing)
    if not blocked:
        if moving:  # toward the nearest pose inside, which the command lies beyond
            return Explanation(
                f"on the way to {where.removeprefix('at ')}: the command lies beyond"
            )
        return Explanation(f"{where}: corrected onto it")
    ways = " and ".join(names[d] for d in blocked)
    verb = "is" if len(blocked) == 1 else "are"
    how = f"sliding {names[slide_direction(move)]} along it" if moving else "holding there"
    return Explanation(f"{where}: {ways} {verb} blocked, {how}", blocked)
