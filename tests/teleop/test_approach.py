"""Parking at the end of a session (both rigs, SDK): the next start accepts where it leaves it."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from limbctl.geometry.gimbal import pan_tilt_to_direction, quat_to_pan_tilt
from limbctl.geometry.quat import swing_from_direction
from limbctl.teleop.approach import park, where
from limbctl.teleop.loop import LoopConfig, run
from limbctl.teleop.margin import START_MARGIN_DEG, margins_for
from limbctl.teleop.start import StartOptions, start_session
from tests.safety.support import PacedSource, wait_for
from tests.teleop.chains import RATE, RIGS, chain_gate, live_chain


def edge_line(rig_name, gate, margins):
    """A command line ending a session on the edge: on ``sim`` one whose edge pose rounds to
    ticks outside the cone; on ``sim3`` a twist far past the band's stop."""
    if rig_name == "sim3":
        return json.dumps({"pan": 10.0, "tilt": 5.0, "roll": 80.0})
    for pan_deg in np.arange(50.0, 70.0, 0.173):
        command = (math.radians(pan_deg), math.radians(0.37 * pan_deg))
        edge_q = gate.envelope.correct(swing_from_direction(pan_tilt_to_direction(*command)))
        edge = tuple(float(a) for a in quat_to_pan_tilt(edge_q))
        if not gate.is_safe(*margins.held_pose(*edge)):
            return json.dumps({"pan": pan_deg, "tilt": 0.37 * pan_deg})
    raise AssertionError("no command found whose edge pose rounds outside")


@pytest.mark.parametrize("rig_name", RIGS)
def test_a_session_ending_on_the_edge_parks_where_the_next_start_accepts(rig_name):
    """Parked inside by the margin, where the next start accepts it; park needs a started gate
    and writes nothing for a limb already inside by the margin."""
    with live_chain(rig_name) as session:
        rig = session.rig
        spare = chain_gate(session.profile)
        spare_margins = margins_for(spare, rig)
        assert park(rig, spare_margins, RATE).note == "the gate never started"
        spare.start(*rig.read_pose())
        kept = park(rig, spare_margins, RATE)
        assert not kept.moved and kept.pose == spare.safe_pose and not kept.note
        gate = chain_gate(session.profile)
        m = margins_for(gate, rig)
        source = PacedSource([edge_line(rig_name, gate, m)] * 200)
        source.twist = rig_name == "sim3"  # a rig with roll: the lines keep their twist
        # patient with the bus: this test is about where the session ends, not about faults
        summary = run(rig, gate, source, LoopConfig(rate_hz=RATE, max_failed_cycles=200))
        assert summary.ended_by == "end of input", summary.fault
        edge = gate.safe_pose
        assert not m.held_inside(m.held_pose(*edge))  # where the servos would hold it
        parked = park(rig, m, RATE)
        assert parked.moved and 0 < parked.distance_deg <= 3 * START_MARGIN_DEG, parked
        held = m.held_pose(*parked.pose)
        wait_for(lambda: rig.read_pose() == held, 5.0, "the limb to settle")
        # the next session starts at once from where the last one left the limb
        again = chain_gate(session.profile)
        rig.set_torque(False)
        result = start_session(rig, again, StartOptions(wait_s=1.0))
    assert result.started and result.how == "inside", result.message
    assert again.safe_pose == held
    m.margin = math.radians(0.9 * START_MARGIN_DEG)
    assert m.held_inside(again.safe_pose)


def test_where_names_each_joint_of_the_chain():
    assert where((0.0, math.radians(-5.0))) == "pan +0.0, tilt -5.0 deg"
    assert where((0.1, 0.0, math.radians(30.0))).endswith("roll +30.0 deg")
