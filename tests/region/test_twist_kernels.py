"""The search's score against brute force over twists, and the kernels' compose and wrap."""

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from limbctl.geometry.quat import geodesic_distance, limb_direction, tangent_frame
from limbctl.geometry.twist import compose, wrap
from limbctl.region import twist_kernels as tk
from limbctl.region.twist_band import TwistBand
from tests.geometry.test_quat import unit_quats

X = np.array([1.0, 0.0, 0.0])
directions = st.lists(st.floats(-1, 1, allow_nan=False), min_size=3, max_size=3).filter(
    lambda v: np.linalg.norm(v) > 0.1
)


@settings(max_examples=200, deadline=None)
@given(v=unit_quats, dv=directions, centre=st.floats(-4, 4), half=st.floats(0, 3.2))
def test_score_is_the_best_twist_over_a_direction(v, dv, centre, half):
    q = np.asarray(v) / np.linalg.norm(v)
    q = -q if q[0] < 0 else q
    d = np.asarray(dv) / np.linalg.norm(dv)
    dq = limb_direction(q)
    if d @ dq < -1 + 1e-6 or d[0] < -1 + 1e-6:
        return
    half = min(half, math.pi)
    # a band of constant centre and half width over the plane about +x
    frame = np.stack([X, *tangent_frame(X)])
    full = np.full((3, 3), centre), np.full((3, 3), half)
    band = TwistBand(frame, np.array([-4.0, -4.0, 4.0]), *full)
    f, tau = tk._score(q, dq, d, *band.kernel_args())
    # brute force over twists in the band, 2001 of them
    taus = centre + half * np.linspace(-1.0, 1.0, 2001)
    g = geodesic_distance(q, compose(np.repeat(d[None], taus.size, axis=0), taus))
    assert 2.0 * math.acos(min(f, 1.0)) <= g.min() + 1e-6
    assert abs(2.0 * math.acos(min(f, 1.0)) - g.min()) < half * 2 / 2000 + 1e-6
    # the twist it returns lies in the band and gives that distance
    assert abs(wrap(tau - centre)) <= half + 1e-12
    got = float(geodesic_distance(q, compose(d, tau)))
    assert abs(got - 2.0 * math.acos(min(f, 1.0))) < 1e-6


@settings(max_examples=200, deadline=None)
@given(dv=directions, tau=st.floats(-10, 10), a=st.floats(-100, 100))
def test_kernel_compose_and_wrap_match_geometry(dv, tau, a):
    assert tk.wrap(a) == float(wrap(a))
    d = np.asarray(dv) / np.linalg.norm(dv)
    if d[0] < -1 + 1e-6:  # within 0.1 deg of the singular -x (checked at -x itself elsewhere)
        return
    out = np.empty(4)
    tk._compose_into(d, tau, out)
    # near -x, 1 + d_x cancels: both lose digits there (1e-16 / s_w^2)
    np.testing.assert_allclose(out, compose(d, tau), atol=1e-9)
