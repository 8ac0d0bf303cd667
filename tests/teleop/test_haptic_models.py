"""The haptic law by leader model: the goal's lead follows the servo loop's stiffness, and a soft
loop's cap keeps a let go's snap under 30 deg/s (decisions/haptic.md, round 6)."""

from __future__ import annotations

import functools
from dataclasses import replace

import numpy as np
import pytest

from limbctl.servo.control_table import ModelNumber
from limbctl.servo.leader import CAP_STALL_FRACTION, FELT_MODELS
from limbctl.teleop.haptic import TICK_DEG, FeelLaw
from tests.teleop.stepped_leader import felt_at_200_hz

LAW = FeelLaw()
#: Round 5's lead: two ticks (three deeper) on every model, the peer of the law by model.
TWO_TICKS = FeelLaw(lead_deg=2 * TICK_DEG, walk_lead_ticks=0)  # round 5: no walking lead
EDGE = 30.0


@pytest.mark.parametrize(
    ("model", "cap_nm", "normal", "deeper"),
    [
        (ModelNumber.XM430_W350, 0.4, 2, 3),
        (ModelNumber.XL330_M288, 0.12, 5, 6),
        (ModelNumber.XL330_M077, 0.1075, 10, 12),
    ],
)
def test_the_lead_follows_the_loops_error_at_the_cap(model, cap_nm, normal, deeper):
    motor = FELT_MODELS[model]
    assert motor.cap_nm(LAW.cap_nm) == pytest.approx(cap_nm)
    # 0.5 deg beyond: K (d - DEADBAND) = 0.02 N m, within every cap
    assert LAW.lead_for_deg(0.5, motor) == pytest.approx(normal * TICK_DEG)
    assert LAW.lead_for_deg(LAW.held_within_deg + 0.1, motor) == pytest.approx(deeper * TICK_DEG)
    # a fixed lead overrides the loop's (benchmarks sweep it), half as much again deeper
    assert FeelLaw(lead_deg=0.3).lead_for_deg(10.0, motor) == pytest.approx(0.45)


@pytest.mark.parametrize("model", list(FELT_MODELS))
def test_the_deeper_lead_gives_the_cap_wherever_the_leader_sits_within_its_tick(model):
    motor = FELT_MODELS[model]
    cap = motor.cap_nm(LAW.cap_nm)
    assert cap <= CAP_STALL_FRACTION * motor.stall_torque_nm
    least = LAW.lead_for_deg(10.0, motor) - TICK_DEG / 2  # the read rounds the pose to a tick
    assert least * motor.loop_nm_per_deg >= cap
    # and no more than a tick over that: the loop stores no more than it needs to
    assert (least - TICK_DEG) * motor.loop_nm_per_deg < cap


@functools.cache
def let_go(
    model: str, law: FeelLaw, stiffness: float, beyond_deg: float, motor=None, watch=True
) -> dict:
    """A relaxed hand's bound (0.3 N m) of ``stiffness`` pressing ``beyond_deg`` past the edge,
    let go at 5 s, on the stepped clock with a leader of ``model`` (``motor``: the controller's
    idea of it, None: the table's; ``watch``: the snap watch on)."""
    script = [[0.0, 0.0, 0.0], [2.0, EDGE + beyond_deg, 0.0]]
    rows = felt_at_200_hz(
        script, 7.0, stiffness, let_go_s=5.0, model=model, law=law, motor=motor, snap_watch=watch
    )
    t = np.array([r["t"] for r in rows])
    pan = np.array([r["pose_deg"][0] for r in rows])
    motor = np.array([r["motor_nm"][0] for r in rows])
    after = t >= 5.0
    return {
        "held_nm": float(-motor[(t >= 4.0) & (t < 5.0)].mean()),
        "peak": float(-np.array([r["velocity_deg_s"][0] for r in rows])[after].min()),
        "rest": float(pan[-1] - EDGE),
        "deepest": float(EDGE - pan[after].min()),
        "torque_inside": int(np.count_nonzero(motor[pan < EDGE])),
    }


XL330 = ["xl330-m288@53", "xl330-m077@53"]
HANDS = [(0.02, 5.0), (0.05, 20.0), (0.2, 5.0)]


@pytest.mark.parametrize("model", XL330)
def test_an_xl330_wall_pushes_with_its_cap_where_two_ticks_gave_a_fraction(model):
    motor = FELT_MODELS[ModelNumber.XL330_M288 if "m288" in model else ModelNumber.XL330_M077]
    cap_nm = motor.torque_of(motor.units_for(motor.cap_nm(LAW.cap_nm)))
    # a 0.3 N m hand overpowers an XL330's cap: the wall holds it with all of the cap
    held = let_go(model, LAW, 0.05, 20.0)["held_nm"]
    assert held == pytest.approx(cap_nm, rel=0.02)
    # two ticks (three deeper) gave its soft loop 0.03 (M077) and 0.08 (M288) N m
    assert let_go(model, TWO_TICKS, 0.05, 20.0)["held_nm"] < held / 1.4


@pytest.mark.parametrize("model", XL330)
@pytest.mark.parametrize(("stiffness", "beyond_deg"), HANDS)
def test_a_let_go_xl330_leader_returns_under_30_deg_s_to_within_0_5_deg_never_inside(
    model, stiffness, beyond_deg
):
    out = let_go(model, LAW, stiffness, beyond_deg)
    assert out["peak"] <= 30.0  # every 1 ms sample
    assert out["deepest"] <= 0.0 and out["rest"] < 0.5
    assert out["torque_inside"] == 0


def test_two_ticks_left_a_let_go_xl330_m077_leader_resting_far_beyond_the_edge():
    # the peer: its loop gave two ticks 0.02 N m, about its friction, so the walk back stalled
    assert let_go("xl330-m077@53", TWO_TICKS, 0.05, 20.0)["rest"] > 5.0
    assert let_go("xl330-m077@53", LAW, 0.05, 20.0)["rest"] < 0.5


def test_an_xl330_m288_held_at_half_its_stall_torque_snaps_back_over_30_deg_s():
    # why its cap is 0.12 N m: at half its stall torque (0.26 N m) its soft loop stores enough
    # for a faster snap than the return may have
    table = FELT_MODELS[ModelNumber.XL330_M288]
    half = replace(table, let_go_cap_nm=None)
    assert half.cap_nm(LAW.cap_nm) == pytest.approx(0.5 * table.stall_torque_nm)
    # (the law alone: the snap watch shortens any snap, but runs only in the loop's idle time)
    assert let_go("xl330-m288@53", LAW, 0.05, 20.0, half, watch=False)["peak"] > 40.0
    assert let_go("xl330-m288@53", LAW, 0.05, 20.0, watch=False)["peak"] <= 30.0
