"""The wall on a diagonal, two- and three-servo leaders alike, at exactly 200 Hz on the stepped
clock: what the hand feels (the norm of the joints' torques) never passes the cap, and a let go
returns under 30 deg/s on every 1 ms sample."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from limbctl.teleop.haptic import FeelLaw
from tests.teleop.stepped_leader import CONE, felt_at_200_hz, motor_of
from tests.teleop.twist_square import square_region

LAW = FeelLaw()
MOTOR = motor_of("xm430-w350")
#: The most the wall may push the hand with, in any direction (N m): the cap the current allows.
CAP = MOTOR.torque_of(MOTOR.units_for(LAW.cap_nm))
LET_GO_S = 4.5
#: Pressing on a diagonal, both joints beyond the edge: toward pan = tilt = 30 deg on the 30 deg
#: cone (11 deg beyond it), toward the corner pan 38, tilt 33 of the square region (its edges at
#: pan 30 and tilt 25).
DIAGONALS = {
    "two-servo": [[0.0, 0.0, 0.0], [2.0, 30.0, 30.0]],
    "three-servo": [[0.0, 0.0, 0.0, 0.0], [2.0, 38.0, 33.0, 0.0]],
}


@functools.cache
def pressed(rig: str, stiffness: float, max_torque_nm: float) -> tuple:
    """The 1 ms truth rows of a diagonal press by a hand of ``stiffness`` (N m/deg) pushing with
    at most ``max_torque_nm`` (N m), let go at once at LET_GO_S."""
    region = square_region() if rig == "three-servo" else CONE
    rows = felt_at_200_hz(
        DIAGONALS[rig], 6.0, stiffness, LET_GO_S, max_torque_nm=max_torque_nm, region=region
    )
    return tuple(rows)


@pytest.mark.parametrize("rig", sorted(DIAGONALS))
@pytest.mark.parametrize("max_torque_nm", [0.3, 0.6])
def test_on_a_diagonal_the_hand_feels_at_most_the_cap(rig, max_torque_nm):
    # a relaxed hand (0.3 N m) and one that overpowers the wall (0.6 N m): each motor sat at its
    # own cap and the hand felt sqrt(2) of it (0.56 N m of a 0.40 cap)
    rows = pressed(rig, 0.2, max_torque_nm)
    felt = [float(np.linalg.norm(r["motor_nm"])) for r in rows if r["t"] < LET_GO_S]
    assert max(felt) <= CAP + 1e-12, max(felt)
    assert max(felt) > 0.25  # it pushed


@pytest.mark.parametrize("rig", sorted(DIAGONALS))
@pytest.mark.parametrize("stiffness", [0.05, 0.2])
def test_on_a_diagonal_a_let_go_returns_under_30_deg_s_on_every_sample(rig, stiffness):
    rows = pressed(rig, stiffness, 0.3)
    speeds = [float(np.linalg.norm(r["velocity_deg_s"])) for r in rows if r["t"] >= LET_GO_S]
    assert max(speeds) <= 30.0, max(speeds)
    assert max(speeds) > 1.0  # it returned
