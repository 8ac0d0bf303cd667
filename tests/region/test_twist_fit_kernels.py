"""The band's fitting kernels against their numpy twins and on planes they must read exactly."""

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from limbctl.geometry.quat import normalize
from limbctl.geometry.twist import wrap
from limbctl.region import twist_fit_kernels as fk


def upper_hull_reference(px: np.ndarray, py: np.ndarray, t: np.ndarray, top: int) -> float:
    """Numpy twin of :func:`limbctl.region.twist_fit_kernels.upper_hull` (all triangles at once)."""
    order = np.argsort(-t, kind="stable")[:top]
    a, b, c = np.array(list(itertools.combinations(range(len(order)), 3))).T
    ia, ib, ic = order[a], order[b], order[c]
    cab = px[ia] * py[ib] - py[ia] * px[ib]
    cbc = px[ib] * py[ic] - py[ib] * px[ic]
    cca = px[ic] * py[ia] - py[ic] * px[ia]
    area = cab + cbc + cca
    ok = area != 0
    la, lb, lc = (np.where(ok, x / np.where(ok, area, 1.0), -1.0) for x in (cbc, cca, cab))
    held = ok & (la >= 0) & (lb >= 0) & (lc >= 0)
    if not held.any():
        return float("nan")
    return float(np.max((la * t[ia] + lb * t[ib] + lc * t[ic])[held]))


def evidence_caps_reference(nodes, start, members, d, limit, ref, slope, near, band):
    """Numpy twin of :func:`limbctl.region.twist_fit_kernels.evidence_caps`."""
    m = nodes.shape[0]
    up, lo = np.full(m, np.nan), np.full(m, np.nan)
    n_up, n_lo = np.zeros(m, dtype=np.int64), np.zeros(m, dtype=np.int64)
    for i in range(m):
        j = members[start[i] : start[i + 1]]
        if j.size == 0:
            continue
        # angle = 2 asin(|n - d_j| / 2)
        angle = 2.0 * np.arcsin(np.minimum(1.0, 0.5 * np.linalg.norm(d[j] - nodes[i], axis=1)))
        t = limit[j] - ref[i]
        up[i] = np.max(t - slope * angle)
        lo[i] = np.min(t + slope * angle)
        n_up[i] = np.sum((angle <= near) & (t >= up[i] - band))
        n_lo[i] = np.sum((angle <= near) & (t <= lo[i] + band))
    return up, lo, n_up, n_lo


@settings(max_examples=100, deadline=None)
@given(seed=st.integers(0, 10**6), n=st.integers(3, 30), top=st.integers(3, 24))
def test_upper_hull_matches_its_numpy_twin(seed, n, top):
    rng = np.random.default_rng(seed)
    px, py = rng.normal(size=(2, n))
    t = rng.normal(size=n)
    got = fk.upper_hull(px, py, t, top)
    expected = upper_hull_reference(px, py, t, top)
    assert (np.isnan(got) and np.isnan(expected)) or math.isclose(got, expected, abs_tol=1e-12)


def _disk_samples(rng, n, radius):
    """Unit directions within ``radius`` of +z, and the node +z itself."""
    r = radius * np.sqrt(rng.uniform(0, 1, n))
    a = rng.uniform(-math.pi, math.pi, n)
    d = np.stack([np.sin(r) * np.cos(a), np.sin(r) * np.sin(a), np.cos(r)], axis=-1)
    return d, np.array([[0.0, 0.0, 1.0]])


def _one_node(d):
    """``start``, ``members`` of one node holding every row of ``d``."""
    return np.array([0, d.shape[0]], dtype=np.int64), np.arange(d.shape[0], dtype=np.int64)


def test_the_hull_and_both_readings_read_planes_exactly():
    rng = np.random.default_rng(2)
    # few enough that the 24 highest twists are the upper stops all round the node
    d, node = _disk_samples(rng, 60, math.radians(8))
    # the kernels' tangent frame at +z: e1 = (z, 0, -x) = (1, 0, 0), e2 = node x e1 = (0, 1, 0)
    x, y = d[:, 0], d[:, 1]
    upper = 0.5 + 0.4 * x - 0.3 * y
    lower = -0.4 + 0.2 * x + 0.1 * y
    side = rng.choice([-1, 0, 1], d.shape[0])
    tau = np.where(side > 0, upper, np.where(side < 0, lower, rng.uniform(lower, upper)))
    start, members = _one_node(d)
    centre, half = fk.fit_nodes(node, start, members, d, tau, 24, math.radians(10), 1.0)
    # the centre is the middle of the occupied arc, any turn of the circle
    assert math.isclose(wrap(centre[0] + half[0] - 0.5), 0.0, abs_tol=1e-9)
    assert math.isclose(wrap(centre[0] - half[0] + 0.4), 0.0, abs_tol=1e-9)
    ref = np.array([centre[0]])
    for limit, stop in ((upper, side > 0), (lower, side < 0)):
        rel = fk.refine_nodes(node, start, members, d, limit, stop, ref, math.radians(5), 1.0)
        expected = 0.5 if limit is upper else -0.4
        assert math.isclose(wrap(ref[0] + rel[0] - expected), 0.0, abs_tol=1e-9)
    # upper_hull reads a sloping plane exactly and fails outside the points
    rng = np.random.default_rng(1)
    px, py = rng.uniform(-1, 1, (2, 40))
    t = 0.3 + 0.7 * px - 0.4 * py
    assert math.isclose(fk.upper_hull(px, py, t, 24), 0.3, abs_tol=1e-12)
    # points on one side only: no triangle holds the origin
    assert np.isnan(fk.upper_hull(np.abs(px) + 0.1, py, t, 24))


def test_free_twist_too_few_samples_and_too_steep_a_plane():
    rng = np.random.default_rng(3)
    d, node = _disk_samples(rng, 300, math.radians(8))
    tau = rng.uniform(-math.pi, math.pi, d.shape[0])
    start, members = _one_node(d)
    _, half = fk.fit_nodes(node, start, members, d, tau, 24, math.radians(10), 1.0)
    assert half[0] == math.pi
    few = np.array([0, 2], dtype=np.int64)
    centre, _ = fk.fit_nodes(node, few, members, d, tau, 24, math.radians(10), 1.0)
    assert np.isnan(centre[0])
    # refine refuses planes steeper than allowed
    d, node = _disk_samples(np.random.default_rng(4), 300, math.radians(8))
    limit = 3.0 * d[:, 0]  # slope 3 rad/rad
    stop = np.ones(d.shape[0], dtype=bool)
    ref = np.zeros(1)
    assert np.isnan(fk.refine_nodes(node, start, members, d, limit, stop, ref, 0.1, 1.0)[0])
    assert math.isclose(
        fk.refine_nodes(node, start, members, d, limit, stop, ref, 0.1, 4.0)[0], 0.0, abs_tol=1e-9
    )


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10**6), slope=st.floats(0.0, 2.0))
def test_evidence_caps_match_their_numpy_twin(seed, slope):
    rng = np.random.default_rng(seed)
    d, _ = _disk_samples(rng, 50, math.radians(10))
    nodes, _ = _disk_samples(rng, 12, math.radians(6))
    members = rng.integers(0, 50, 80)
    start = np.concatenate([[0], np.sort(rng.integers(0, 81, 11)), [80]]).astype(np.int64)
    limit = rng.normal(size=50)
    ref = rng.normal(size=12)
    args = (nodes, start, members, d, limit, ref, slope, math.radians(4), 0.3)
    got = fk.evidence_caps(*args)
    expected = evidence_caps_reference(*args)
    for a, b in zip(got, expected, strict=True):
        np.testing.assert_allclose(a, b, atol=1e-12)
    for a in got[:2]:
        assert np.array_equal(np.isnan(a), start[1:] == start[:-1])
    # witnesses are among the node's samples
    assert np.all(got[2] <= np.diff(start)) and np.all(got[3] <= np.diff(start))


def _gradient_caps(node, d, limit, stop, spread_deg=0.75, limited=False, min_stops=4.0):
    """``fk.gradient_caps`` at one node holding every row of ``d``, ref 0: sigma 3 deg, slack 0.25,
    confidence 2, curvature 8.6, near 3 deg, band 0.02, reach 4 deg, steep 1.4."""
    start, members = _one_node(d)
    args = (math.radians(3), math.radians(spread_deg), 0.25, 2.0, 8.6, math.radians(3), 0.02)
    free = (math.radians(4), 1.4, np.full(1, limited), min_stops, np.zeros(len(d), np.int64))
    return fk.gradient_caps(node, start, members, d, limit, stop, np.zeros(1), *args, *free)


def test_the_caps_a_held_stop_witnesses_and_along_the_local_slope_on_a_steep_plane():
    rng = np.random.default_rng(7)
    d, node = _disk_samples(rng, 200, math.radians(8))
    d[0] = node[0]  # one stop at the node itself
    # an upper limit sloping 1.5 rad/rad, steeper than any fixed cone the cap assumes
    limit = 0.4 + 1.5 * d[:, 0]
    stop = np.ones(d.shape[0], dtype=bool)
    # on a plane the slope is read exactly: no sample lifts the cap above the limit at the node
    cap, wit = _gradient_caps(node, d, limit, stop)
    assert math.isclose(cap[0], 0.4, abs_tol=1e-9)
    assert wit[0] >= 1
    start, members = _one_node(d)
    near = math.radians(3)
    cone, *_ = fk.evidence_caps(node, start, members, d, limit, np.zeros(1), 0.5, near, 0.02)
    assert cone[0] > 0.4 + math.radians(3.0)
    # stops all on one line: the slope across it is unknown, no cap
    on_line = stop & (np.abs(d[:, 1]) < math.radians(0.2))
    cap, wit = _gradient_caps(node, d, limit, on_line)
    assert np.isnan(cap[0]) and wit[0] == 0
    # among the taught directions: samples beyond the reach vouch only by the steep cone, which
    # on this plane (steeper than 1.4) lies below the slope's reading: the node's own stop sets it
    cap, _ = _gradient_caps(node, d, limit, stop, limited=True)
    assert math.isclose(cap[0], 0.4, abs_tol=1e-9)
    # evidence_caps: a stop held at the node witnesses the cap and a far one shrinks it
    a = math.radians(6.0)
    # three samples at the node at twists 0.5, 0.49, 0.2; one 6 deg away at 0.6
    d = np.array([[0, 0, 1], [0, 0, 1], [0, 0, 1], [math.sin(a), 0, math.cos(a)]], float)
    limit = np.array([0.5, 0.49, 0.2, 0.6])
    start, members = _one_node(d)
    up, lo, n_up, n_lo = fk.evidence_caps(
        node, start, members, d, limit, np.zeros(1), 1.0, math.radians(3), 0.05
    )
    # the far sample's 0.6 - 1.0 * 6 deg = 0.495 < 0.5: the cap is the held 0.5
    assert up[0] == pytest.approx(0.5) and n_up[0] == 2
    assert lo[0] == pytest.approx(0.2) and n_lo[0] == 1


def test_a_slope_through_three_stops_is_not_read():
    """Three stops fit a plane exactly: under ``min_stops`` the slope stays unknown (NaN)."""
    node = np.array([[0.0, 0.0, 1.0]])
    a = math.radians(2.0)
    d = np.array([[math.sin(a), 0, math.cos(a)], [0, math.sin(a), math.cos(a)], [0, 0, 1.0]])
    d = normalize(np.vstack([d, [-math.sin(a), -math.sin(a), 1.0]]))
    limit = 0.4 + 1.5 * d[:, 0]
    three = np.array([True, True, True, False])
    for min_stops, known in ((0.0, True), (4.0, False)):
        cap, _ = _gradient_caps(node, d, limit, three, spread_deg=0.5, min_stops=min_stops)
        assert np.isfinite(cap[0]) == known
    # a fourth stop, spread as well, lets the slope be read again
    cap, _ = _gradient_caps(node, d, limit, np.ones(4, bool), spread_deg=0.5, min_stops=3.5)
    assert math.isclose(cap[0], 0.4, abs_tol=1e-9)
