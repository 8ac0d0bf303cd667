"""The keyboard's keys (:data:`KEYS`), their guide, and steady motion while one is held."""

from __future__ import annotations

import enum
from dataclasses import dataclass


class Action(enum.Enum):
    """What a key does."""

    UP = "up"
    DOWN = "down"
    LEFT = "left"
    RIGHT = "right"
    FINER = "finer"
    COARSER = "coarser"
    HOLD = "hold"
    CENTRE = "centre"
    ROLL_LEFT = "roll left"
    ROLL_RIGHT = "roll right"
    HELP = "help"
    QUIT = "quit"


@dataclass(frozen=True)
class KeyBinding:
    """One action's keys: the terminal's ``sequences``, the guide's ``label``, what it ``does``, its
    (pan, tilt) ``move`` signs in steps (left is +pan) and its ``roll`` sign (three-servo rigs)."""

    action: Action
    sequences: tuple[bytes, ...]
    label: str
    does: str
    move: tuple[int, int] = (0, 0)
    roll: int = 0


#: Every key, in the guide's order (arrows as ESC [ X, or ESC O X in application-cursor mode).
KEYS: dict[Action, KeyBinding] = {
    binding.action: binding
    for binding in (
        KeyBinding(Action.UP, (b"\x1b[A", b"\x1bOA", b"w", b"W"), "up / w", "tilt up", (0, 1)),
        KeyBinding(
            Action.DOWN, (b"\x1b[B", b"\x1bOB", b"s", b"S"), "down / s", "tilt down", (0, -1)
        ),
        KeyBinding(Action.LEFT, (b"\x1b[D", b"\x1bOD", b"a", b"A"), "left / a", "pan left", (1, 0)),
        KeyBinding(
            Action.RIGHT, (b"\x1b[C", b"\x1bOC", b"d", b"D"), "right / d", "pan right", (-1, 0)
        ),
        KeyBinding(Action.COARSER, (b"+", b"="), "+", "a larger step"),
        KeyBinding(Action.FINER, (b"-", b"_"), "-", "a smaller step"),
        KeyBinding(Action.HOLD, (b" ",), "space", "hold here / release (the gate holds the pose)"),
        KeyBinding(Action.CENTRE, (b"c", b"C"), "c", "back to the region's centre"),
        KeyBinding(Action.ROLL_LEFT, (b"[",), "[", "roll -1 step (three-servo rigs)", roll=-1),
        KeyBinding(Action.ROLL_RIGHT, (b"]",), "]", "roll +1 step (three-servo rigs)", roll=1),
        KeyBinding(Action.HELP, (b"?", b"h"), "?", "this guide again"),
        KeyBinding(Action.QUIT, (b"q", b"Q", b"\x04"), "q", "quit (the limb is parked inside)"),
    )
}
#: Bytes -> action, from :data:`KEYS`.
SEQUENCES: dict[bytes, Action] = {seq: b.action for b in KEYS.values() for seq in b.sequences}

#: The steps (deg) that +/- walk through: from creeping along an edge to crossing the region.
STEPS_DEG = (0.5, 1.0, 2.0, 5.0, 10.0)
#: The first step (deg): creeps up to an edge, crosses 90 deg in 45 presses.
DEFAULT_STEP_DEG = 2.0
#: Steps per second while a key is held: 20 deg/s at the default step, under the 120 deg/s slew.
KEY_RATE_HZ = 10.0
#: Longest gap (s) between events of a key held down: above the slowest common auto-repeat (83 ms).
REPEAT_GAP_S = 0.15
#: Longest gap (s) still continuing a hold: above the X server's 660 ms auto-repeat delay.
HOLD_GAP_S = 0.75


def split_keys(pending: bytes) -> tuple[list[bytes], bytes]:
    """Split terminal bytes into keys and the bytes of an escape sequence not yet complete."""
    keys: list[bytes] = []
    while pending:
        size = 3 if pending[:1] == b"\x1b" and pending[1:2] in (b"[", b"O", b"") else 1
        if len(pending) < size:
            break
        keys.append(pending[:size])
        pending = pending[size:]
    return keys, pending


def next_step(step_deg: float, coarser: bool) -> float:
    """The step after ``step_deg`` in :data:`STEPS_DEG`, one up or down (kept at the ends)."""
    if coarser:
        return next((s for s in STEPS_DEG if s > step_deg), STEPS_DEG[-1])
    return next((s for s in reversed(STEPS_DEG) if s < step_deg), STEPS_DEG[0])


def key_guide(step_deg: float) -> list[str]:
    """The guide's lines: each action's keys and what it does, and how far the limb moves."""
    speed = step_deg * KEY_RATE_HZ
    lines = [
        f"keys: one press moves {step_deg:g} deg; a key held moves {speed:g} deg/s "
        f"(step {', '.join(f'{s:g}' for s in STEPS_DEG)} deg with +/-); every move goes "
        "through the gate"
    ]
    lines += [f"  {b.label:<10} {b.does}" for b in KEYS.values()]
    return lines


class HeldKey:
    """How far each key event moves: a step per press (a gap over :data:`REPEAT_GAP_S`); held, in
    all ``step * KEY_RATE_HZ * (t - run start)`` over events within ``HOLD_GAP_S``."""

    def __init__(self) -> None:
        self._action: Action | None = None
        self._last_t = self._run_start = 0.0
        self._moved = 0.0

    def reset(self) -> None:
        """Forget the run (after a step change, a hold or the centre key)."""
        self._action = None

    def distance(self, action: Action, t: float, step_deg: float) -> float:
        """Degrees the event of ``action`` at time ``t`` (s) moves, in the action's direction."""
        gap = t - self._last_t
        self._last_t = t
        if action is not self._action or gap > HOLD_GAP_S:
            self._action, self._run_start, self._moved = action, t, step_deg
            return step_deg
        if gap > REPEAT_GAP_S:
            owed = self._moved + step_deg  # a second press, or the repeat after the delay
        else:
            # held: speed * time since the run began, never less than what was already given
            owed = max(self._moved, step_deg * KEY_RATE_HZ * (t - self._run_start))
        move, self._moved = owed - self._moved, owed
        return move
