"""The gate's outcome in words, from a real gate around a cone."""

from __future__ import annotations

import math

from limbctl.geometry.gimbal import pan_tilt_to_quat
from limbctl.teleop.explain import DIRECTION_NAMES, PLANE_NAMES, blocked_directions, explain
from limbctl.teleop.gate import Gate, GateResult, Outcome
from tests.teleop.test_gate import make_gate


def gate(tilt_max_deg: float = 80.0) -> Gate:
    """test_gate.py's two-servo gate (2 deg a cycle) on a 30 deg cone, at rest."""
    return make_gate(2, math.radians(30), tilt_max=math.radians(tilt_max_deg))


def follow(g: Gate, pan_deg: float, tilt_deg: float, cycles: int) -> list[GateResult]:
    target = pan_tilt_to_quat(math.radians(pan_deg), math.radians(tilt_deg))
    return [g.step(target) for _ in range(cycles)]


def deg(result: GateResult) -> tuple[float, float]:
    return math.degrees(result.pose[0]), math.degrees(result.pose[1])


def test_inside_on_the_way_and_holding():
    g = gate()
    assert explain(follow(g, 1.0, 1.0, 1)[-1], (1.0, 1.0)).words == "inside: following the command"
    results = follow(g, 15.0, 1.0, 2)  # 14 deg away at 2 deg per cycle
    assert explain(results[-1], (15.0, 1.0)).words == "on the way: the speed limit paces it"
    held = g.hold("no command yet")
    assert explain(held, None).words == "holding the last safe pose: no command yet"
    assert explain(None, None).words == "not running"
    g = gate(tilt_max_deg=10.0)  # a hard limit is named as one
    results = follow(g, 0.0, 25.0, 30)
    assert results[-1].outcome is Outcome.CLAMPED
    told = explain(results[-1], (0.0, 25.0), deg(results[-2]))
    assert told.words == "at a hard limit: up is blocked, holding there"


def test_at_the_edge_the_blocked_way_is_named_and_sliding_told_from_standing():
    g = gate()
    results = follow(g, 0.0, 60.0, 3)  # straight up, far beyond the 30 deg cone
    assert explain(results[-1], (0.0, 60.0), deg(results[-2])).words == (
        "on the way to the edge: the command lies beyond"
    )
    results = follow(g, 0.0, 60.0, 40)
    told = explain(results[-1], (0.0, 60.0), deg(results[-2]), DIRECTION_NAMES)
    assert told.words == "at the edge: up is blocked, holding there"
    assert told.blocked == ("+tilt",)
    # up and to the left (+pan): the gate slides the limb along the edge toward the command
    results = follow(g, 50.0, 60.0, 3)
    told = explain(results[-1], (50.0, 60.0), deg(results[-2]), DIRECTION_NAMES)
    assert told.blocked == ("+tilt",)
    assert told.words == "at the edge: up is blocked, sliding left along it"
    # pushed into the edge with nothing to slide toward, both ways are blocked; the page
    # names pan as the terminal does (its plane is seen from behind the limb too)
    results = follow(g, 30.0, 60.0, 60)
    told = explain(results[-1], (30.0, 60.0), deg(results[-2]), PLANE_NAMES)
    assert told.words == "at the edge: left and up are blocked, holding there"
    assert told.blocked == ("+pan", "+tilt")


def test_blocked_needs_more_than_the_gates_rounding_and_no_move_that_way():
    assert blocked_directions((10.0, 5.0), (10.0, 5.0)) == ()
    assert blocked_directions((10.1, 5.0), (10.0, 5.0)) == ()
    assert blocked_directions((9.0, 3.0), (10.0, 5.0)) == ("-pan", "-tilt")
    # moving straight toward the command: nothing is blocked
    assert blocked_directions((20.0, 10.0), (10.0, 5.0), (8.0, 4.0)) == ()
    # moving across it: the way it does not go is
    assert blocked_directions((20.0, 10.0), (10.0, 5.0), (8.0, 5.0)) == ("+tilt",)
    # one key, one motion: the terminal and the page name directions alike
    assert PLANE_NAMES == DIRECTION_NAMES
    assert DIRECTION_NAMES["+pan"] == "left" and DIRECTION_NAMES["+tilt"] == "up"


def test_a_key_held_up_against_a_slanted_edge_names_up_alone_and_the_way_it_slides():
    """Up pressed step by step up the cone's slanted edge: the limb slides right (toward pan 0),
    the status names up alone as blocked, not the way nobody pressed."""
    g = gate()
    written = deg(follow(g, 20.0, 15.0, 20)[-1])
    told_at_edge = []
    for _ in range(12):
        command = (written[0], written[1] + 2.0)
        result = follow(g, *command, 1)[-1]
        told = explain(result, command, written, DIRECTION_NAMES, pushing=("+tilt",))
        written = deg(result)
        if result.corrected:
            told_at_edge.append(told)
    sliding = [t for t in told_at_edge if t.blocked]
    assert len(sliding) >= 8, [t.words for t in told_at_edge]
    for told in sliding:
        assert told.blocked == ("+tilt",)
        assert told.words == "at the edge: up is blocked, sliding right along it"
    assert written[0] < 15.0  # it did slide right, toward pan 0
