"""Refused lines by reason, with the first examples, from the real parser's messages."""

import threading

import pytest

from limbctl.errors import InvalidInputError
from limbctl.teleop.commands import parse_command
from limbctl.teleop.refusals import EXAMPLES_PER_REASON, MAX_RECENT, Refusals, reason_of

LINES = [
    b'{"pan": 500, "tilt": 0}',
    b"garbage",
    b'{"pan": 720.5, "tilt": 0}',
    b'{"pan": NaN, "tilt": 0}',
    b"not json at all",
    b'{"pan": -999, "tilt": 0}',
    b'{"pan": 1e3, "tilt": 0}',
    b'{"gate": false}',
]


def refusal_message(line):
    with pytest.raises(InvalidInputError) as caught:
        parse_command(line)
    return str(caught.value)


def refuse_all(lines):
    refusals = Refusals()
    for number, line in enumerate(lines, start=1):
        refusals.add(refusal_message(line), line, number)
    return refusals


def test_reasons_group_what_varies_from_line_to_line():
    refusals = refuse_all(LINES)
    assert refusals.total == len(LINES)
    assert refusals.counts == {
        "pan N deg is outside [N, N]": 4,
        "malformed JSON": 2,
        "NaN is not a valid number": 1,
        reason_of(refusal_message(b'{"gate": false}')): 1,
    }
    lines = refusals.lines()
    assert lines[0].startswith("refused      4 x pan N deg is outside [N, N] (e.g. line 1: ")
    # the first examples only, in order, with their line numbers
    kept = refusals.examples["pan N deg is outside [N, N]"]
    assert [e.line_no for e in kept] == [1, 3, 6][:EXAMPLES_PER_REASON]
    assert "line 2: 'garbage'" in lines[1] and "line 5: 'not json at all'" in lines[1]


def test_recent_reasons_are_taken_once_and_bounded_and_long_lines_cut_to_an_excerpt():
    refusals = refuse_all(LINES[:2])
    assert refusals.take_recent() == ["pan N deg is outside [N, N]", "malformed JSON"]
    assert refusals.take_recent() == []
    for _ in range(MAX_RECENT + 50):
        refusals.add("malformed JSON: x", b"x")
    assert len(refusals.take_recent()) == MAX_RECENT
    assert refusals.counts["malformed JSON"] == MAX_RECENT + 51
    refusals = Refusals()
    refusals.add("line is not UTF-8", b"\xff" * 500, 7)
    example = refusals.examples["line is not UTF-8"][0]
    assert len(example.text) <= 60 and example.text.endswith("...")
    assert example.line_no == 7


def test_counts_survive_a_concurrent_writer():
    refusals = Refusals()
    taken = []

    def writer():
        for i in range(5000):
            refusals.add(f"pan {i} deg is outside [-180, 180]", b"x", i)

    thread = threading.Thread(target=writer)
    thread.start()
    while thread.is_alive():
        taken.extend(refusals.take_recent())
    taken.extend(refusals.take_recent())
    assert refusals.total == 5000 == refusals.counts["pan N deg is outside [N, N]"]
    assert 0 < len(taken) <= 5000
