"""The simulator's own geometry of the three-joint gimbal, checked against quaternion products."""

from __future__ import annotations

import math

import numpy as np
import pytest

from firmware_sim.orientation import (
    chain_quat,
    chain_twist,
    roll_for_twist_deg,
    wrap_deg,
)
from tests.geometry.test_gimbal import chain_by_products, twist_about_x


@pytest.mark.parametrize(("pan", "tilt", "tau"), [(30, 30, 8.2), (60, 45, 26.9), (90, 60, 60.0)])
def test_chain_twist_figures(pan, tilt, tau):
    assert math.degrees(chain_twist(math.radians(pan), math.radians(tilt))) == pytest.approx(
        tau, abs=0.05
    )


def test_chain_quat_is_the_product_and_its_twist_is_roll_plus_chain_twist():
    rng = np.random.default_rng(3)
    for pan, tilt, roll in rng.uniform([-3, -1.5, -3], [3, 1.5, 3], size=(200, 3)):
        assert np.allclose(
            chain_quat(pan, tilt, roll), chain_by_products(pan, tilt, roll), atol=1e-12
        )
        twist = math.degrees(twist_about_x(np.array(chain_quat(pan, tilt, roll))))
        expected = math.degrees(roll + chain_twist(pan, tilt))
        assert wrap_deg(twist - expected) == pytest.approx(0.0, abs=1e-9)
        # the roll that gives a twist undoes the chain's own twist
        back = roll_for_twist_deg(math.degrees(pan), math.degrees(tilt), twist)
        assert wrap_deg(back - math.degrees(roll)) == pytest.approx(0.0, abs=1e-9)


def test_wrap_deg_range():
    assert wrap_deg(180.0) == 180.0
    assert wrap_deg(-180.0) == 180.0
    assert wrap_deg(190.0) == pytest.approx(-170.0)
    assert wrap_deg(-540.0) == 180.0
