"""Twist: the split q = swing(d) * twist(tau) about +x, its round trips, wrap-around and -x."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from limbctl.geometry import quat
from limbctl.geometry import twist as tw
from tests.geometry.test_quat import unit_quats


def twist_quat(tau: np.ndarray | float) -> np.ndarray:
    """Quaternions (..., 4) of turns by ``tau`` (rad) about +x, wrapped first: w >= 0."""
    half = 0.5 * tw.wrap(tau)
    zero = np.zeros_like(half)
    return np.stack([np.cos(half), np.sin(half), zero, zero], axis=-1)


twists = st.floats(-3 * math.pi, 3 * math.pi, allow_nan=False)


def _unit(v):
    q = np.asarray(v, dtype=np.float64)
    return q / np.linalg.norm(q)


def _same_rotation(a, b, atol):
    assert min(np.abs(a - b).max(), np.abs(a + b).max()) <= atol


def test_wrap_range_half_turn_and_an_angle_a_ulp_inside_the_range():
    a = np.array([-math.pi, math.pi, 3 * math.pi, -3 * math.pi, 0.0, 2 * math.pi, 7.0])
    w = tw.wrap(a)
    assert np.all(w > -math.pi) and np.all(w <= math.pi)
    np.testing.assert_allclose(w[:4], math.pi)
    np.testing.assert_allclose(np.cos(w), np.cos(a), atol=1e-12)
    np.testing.assert_allclose(np.sin(w), np.sin(a), atol=1e-12)
    # (-pi + 4e-16 - pi) / 2 pi rounds to exactly -1: the plain formula gave pi + 4e-16
    inside = math.nextafter(-math.pi, 0.0) + 2e-16
    for angle in (math.nextafter(-math.pi, 0.0), inside, math.pi, 2.0 * math.atan2(1.0, -2.2e-16)):
        for wrapped in (float(tw.wrap(angle)), tw._wrap_one(angle)):
            assert -math.pi < wrapped <= math.pi
    assert float(tw.wrap(math.nextafter(-math.pi, 0.0))) == math.nextafter(-math.pi, 0.0)
    v = [2.220446049250313e-16, -1.0, 0.0, 0.0]  # hypothesis found it: a half turn about -x
    assert -math.pi < float(tw.decompose(_unit(v))[1]) <= math.pi
    assert -math.pi < tw.decompose_one(_unit(v))[1] <= math.pi


@settings(max_examples=300, deadline=None)
@given(v=unit_quats)
def test_decompose_then_compose_is_the_same_rotation_and_the_scalar_twin_agrees(v):
    """Away from -x (s_w > 1e-3, 0.11 deg): near it precision falls like 1e-16 / s_w^2."""
    q = _unit(v)
    if 0 < math.hypot(q[0], q[1]) < 1e-3:
        return
    d, tau = tw.decompose(q)
    d1, tau1 = tw.decompose_one(q)
    np.testing.assert_allclose(d1, d, atol=1e-12, err_msg="the scalar twin")
    assert abs(tw.wrap(tau1 - tau)) < 1e-12
    if math.hypot(q[0], q[1]) == 0:  # -x itself: checked by the half-turn test
        return
    assert -math.pi < tau <= math.pi
    _same_rotation(tw.compose(d, tau), q, 1e-9)
    # the direction is +x rotated by q, the twist part the one of the product form
    np.testing.assert_allclose(
        d, quat.limb_direction(q) / np.linalg.norm(quat.limb_direction(q)), atol=1e-12
    )
    _same_rotation(quat.multiply(quat.swing_from_direction(d), twist_quat(tau)), q, 1e-9)


@settings(max_examples=300, deadline=None)
@given(pan=st.floats(-math.pi, math.pi), tilt=st.floats(-1.5, 1.5), tau=twists)
def test_compose_then_decompose_gives_back_direction_and_wrapped_twist(pan, tilt, tau):
    d = np.array([math.cos(tilt) * math.cos(pan), math.cos(tilt) * math.sin(pan), math.sin(tilt)])
    if quat.direction_angle(d, np.array([-1.0, 0, 0])) < 1e-3:
        return
    q = tw.compose(d, tau)
    assert q[0] >= 0.0
    d2, tau2 = tw.decompose(q)
    np.testing.assert_allclose(d2, d, atol=1e-12)
    assert abs(tw.wrap(tau2 - tau)) < 1e-9
    assert -math.pi < tau2 <= math.pi


def test_half_turn_twist_is_plus_pi_both_ways_and_minus_x_round_trips():
    d = np.array([0.0, 0.6, 0.8])
    for tau in (math.pi, -math.pi, 3 * math.pi):
        _, back = tw.decompose(tw.compose(d, tau))
        assert back == pytest.approx(math.pi)
    # at the singular -x: round trips with the half turn about z
    for tau in np.linspace(-math.pi, math.pi, 13):
        q = tw.compose(np.array([-1.0, 0.0, 0.0]), tau)
        assert abs(q[0]) < 1e-15 and abs(q[1]) < 1e-15
        d, back = tw.decompose(q)
        np.testing.assert_array_equal(d, [-1.0, 0.0, 0.0])
        assert abs(tw.wrap(back - tau)) < 1e-12
        dd, bb = tw.decompose_one(q)
        assert dd == (-1.0, 0.0, 0.0) and abs(tw.wrap(bb - tau)) < 1e-12
    # the swing is the half-turn about +z: twist 0 at -x is exactly it
    np.testing.assert_allclose(tw.compose(np.array([-1.0, 0, 0]), 0.0), [0, 0, 0, 1], atol=1e-15)
