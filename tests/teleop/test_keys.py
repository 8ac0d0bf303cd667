"""The key table, its guide, and the steady speed of a held key."""

from __future__ import annotations

import pytest

from limbctl.teleop.keys import (
    KEY_RATE_HZ,
    KEYS,
    SEQUENCES,
    STEPS_DEG,
    Action,
    HeldKey,
    key_guide,
    next_step,
    split_keys,
)


def test_every_action_has_keys_and_no_key_does_two_things():
    assert set(KEYS) == set(Action)
    every = [seq for binding in KEYS.values() for seq in binding.sequences]
    assert len(every) == len(set(every)) == len(SEQUENCES)
    # the four moves cover both joints both ways; nothing else moves
    moves = {binding.move for binding in KEYS.values() if binding.move != (0, 0)}
    assert moves == {(0, 1), (0, -1), (1, 0), (-1, 0)}
    assert SEQUENCES[b"\x1b[A"] is Action.UP and SEQUENCES[b"\x1bOA"] is Action.UP
    assert SEQUENCES[b"w"] is Action.UP and SEQUENCES[b"q"] is Action.QUIT
    # the guide names every key and the speeds the step sets
    lines = key_guide(2.0)
    assert "one press moves 2 deg; a key held moves 20 deg/s" in lines[0]
    for binding in KEYS.values():
        assert any(binding.label in line and binding.does in line for line in lines[1:])
    assert "moves 0.5 deg; a key held moves 5 deg/s" in key_guide(0.5)[0]


def test_split_keys_keeps_escape_sequences_whole_and_steps_stop_at_the_tables_ends():
    keys, rest = split_keys(b"\x1b[Aw\x1bOD+\x1b[")
    assert keys == [b"\x1b[A", b"w", b"\x1bOD", b"+"] and rest == b"\x1b["
    keys, rest = split_keys(rest + b"B")
    assert keys == [b"\x1b[B"] and rest == b""
    # a lone escape followed by another key is a key of its own (ignored by the source)
    assert split_keys(b"\x1bq") == ([b"\x1b", b"q"], b"")
    # steps walk the table and stop at its ends
    assert next_step(2.0, coarser=True) == 5.0 and next_step(2.0, coarser=False) == 1.0
    assert next_step(STEPS_DEG[-1], coarser=True) == STEPS_DEG[-1]
    assert next_step(STEPS_DEG[0], coarser=False) == STEPS_DEG[0]


def events(delay_s: float, repeat_hz: float, hold_s: float) -> list[float]:
    """When a terminal sends a key held ``hold_s``: the press, repeats from ``delay_s``."""
    times = [0.0]
    t = delay_s
    while t <= hold_s + 1e-9:
        times.append(t)
        t += 1.0 / repeat_hz
    return times


@pytest.mark.parametrize(
    "delay_s, repeat_hz", [(0.25, 40.0), (0.5, 30.0), (0.66, 25.0), (0.6, 12.0)]
)
def test_a_held_key_moves_at_the_speed_the_step_sets_whatever_the_terminal(delay_s, repeat_hz):
    held, step = HeldKey(), 2.0
    times = events(delay_s, repeat_hz, 2.0)
    moved = sum(held.distance(Action.UP, t, step) for t in times)
    assert moved == pytest.approx(step * KEY_RATE_HZ * times[-1], rel=1e-9)
    assert moved == pytest.approx(40.0, rel=0.05)


def test_presses_move_one_step_each_and_a_new_key_starts_afresh():
    held = HeldKey()
    assert held.distance(Action.UP, 0.0, 2.0) == 2.0
    assert held.distance(Action.UP, 1.0, 2.0) == 2.0  # a new press, not a hold
    assert held.distance(Action.UP, 1.4, 2.0) == 2.0  # within the repeat delay: one more step
    assert held.distance(Action.LEFT, 1.45, 2.0) == 2.0  # another key: its own press
    assert held.distance(Action.LEFT, 1.45, 2.0) == 0.0  # the same instant: nothing owed yet
    held.reset()
    assert held.distance(Action.LEFT, 1.46, 2.0) == 2.0
