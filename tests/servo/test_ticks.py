import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from limbctl.servo.ticks import TICKS_PER_RAD, angle_to_ticks, tick_limits, ticks_to_angle

ZERO, DIRECTION = st.integers(0, 4095), st.sampled_from([1, -1])


def test_hand_cases_shapes_and_integral_limits():
    assert TICKS_PER_RAD == pytest.approx(4096 / (2 * math.pi))
    assert int(angle_to_ticks(math.pi / 2, 2048, 1)) == 3072
    assert int(angle_to_ticks(math.pi / 2, 2048, -1)) == 1024
    assert float(ticks_to_angle(1024, 2048, -1)) == pytest.approx(math.pi / 2)
    assert float(ticks_to_angle(2048, 2048, 1)) == 0.0
    angles = np.linspace(-1.0, 1.0, 12).reshape(3, 4)
    ticks = angle_to_ticks(angles, 2000, -1)
    assert ticks.shape == (3, 4) and ticks.dtype == np.int64
    np.testing.assert_allclose(ticks_to_angle(ticks, 2000, -1), angles, atol=0.5 / TICKS_PER_RAD)
    assert tick_limits(-90.0, 90.0, 2048, 1) == (1024, 3072)
    assert tick_limits(-90.0, 90.0, 2048, -1) == (1024, 3072)


@given(tick=st.integers(0, 4095), zero=ZERO, direction=DIRECTION)
def test_every_tick_round_trips_exactly(tick, zero, direction):
    assert int(angle_to_ticks(ticks_to_angle(tick, zero, direction), zero, direction)) == tick


@given(angle=st.floats(-3.0, 3.0), zero=ZERO, direction=DIRECTION)
def test_rounding_error_is_at_most_half_a_tick(angle, zero, direction):
    tick = int(angle_to_ticks(angle, zero, direction))
    back = float(ticks_to_angle(tick, zero, direction))
    assert abs(back - angle) <= 0.5 / TICKS_PER_RAD + 1e-12


@given(
    low=st.floats(-170.0, 0.0),
    span=st.floats(1.0, 160.0),
    zero=st.integers(1500, 2600),
    direction=DIRECTION,
)
def test_tick_limits_round_inward(low, span, zero, direction):
    high = low + span
    lo, hi = tick_limits(low, high, zero, direction)
    assert lo <= hi
    angles = np.degrees(ticks_to_angle(np.array([lo, hi]), zero, direction))
    assert (angles.min() >= low - 1e-9) and (angles.max() <= high + 1e-9)
    beyond = np.degrees(ticks_to_angle(np.array([lo - 1, hi + 1]), zero, direction))
    assert not (low <= beyond[0] <= high) and not (low <= beyond[1] <= high)
