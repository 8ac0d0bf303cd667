"""The three-dimensional region: containment, and correct() as the nearest orientation on SO(3)."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree

from limbctl.envelope.synthetic import _cap_directions, rounded
from limbctl.envelope.synthetic_twist import SHOULDER, ShoulderRegion
from limbctl.errors import ConfigError, InvalidInputError
from limbctl.geometry import quat
from limbctl.geometry.quat import geodesic_distance
from limbctl.geometry.twist import compose, decompose, wrap
from limbctl.region import twist_kernels as tk
from limbctl.region.twist_region import TwistRegion, boundary_samples
from tests.geometry.test_quat import unit_quats

#: 2 acos|<p, q>| resolves ~1e-8 rad near 0 (acos at 1): comparisons of distances allow this.
ACOS_NOISE = 1e-7


def _fitted(centre_deg: float, seed: int):
    truth = ShoulderRegion(rounded(SHOULDER), centre_deg=centre_deg)
    q = truth.teaching(1500, 1000, 1800, np.random.default_rng(seed))
    return truth, TwistRegion().fit(q), q


@pytest.fixture(scope="module")
def shoulder():
    return _fitted(10.0, 1)


def _commands(truth, n, rng, outside_deg=30.0):
    """Commands inside and out: directions up to ``outside_deg`` beyond the outline, twists up to
    40 deg past the band."""
    d = _cap_directions(n, truth.swing.axis, truth.swing.radius + math.radians(outside_deg), rng)
    c, h = truth.band(d)
    return compose(d, c + (h + math.radians(40.0)) * rng.uniform(-1.0, 1.0, n))


def _clamp(region, q):
    """The engines' two steps on ``region``: the direction projected, then the twist clamped."""
    d, tau = decompose(q)
    d2 = region.mesh.project(d)
    c, h = region.band.at(d2)
    return compose(d2, c + np.clip(wrap(tau - c), -h, h))


def test_correct_is_the_brute_force_nearest_orientation(shoulder):
    """Nearest as a brute force over the region's boundary, inside, nearer than the clamp, and
    near the true region (the further starts find the better of several local optima)."""
    truth, region, _ = shoulder
    q = _commands(truth, 6000, np.random.default_rng(7))
    out, inside = region.correct(q), region.contains(q)
    b = boundary_samples(region, 0.3)
    points = np.vstack([b, -b])
    _, i = cKDTree(points).query(q[~inside])
    reference = geodesic_distance(q[~inside], points[i])
    excess = np.degrees(geodesic_distance(q[~inside], out[~inside]) - reference)
    # the brute force's points are in the region (never nearer than exact), its 0.3 deg lattice
    # up to ~0.2 deg short: an answer 0.3 deg farther is a local optimum, not the nearest
    assert (~inside).sum() > 4000
    assert excess.mean() < 0.0
    assert np.percentile(excess, 99) < 0.1
    assert excess.max() < 0.3, np.sort(excess)[-5:]
    assert region.contains(out).all(), "an answer lies outside the region"
    assert inside.sum() > 300
    np.testing.assert_array_equal(out[inside], q[inside] * np.sign(q[inside, :1] + 0.0))
    assert np.allclose(np.linalg.norm(out, axis=1), 1.0, atol=1e-12)
    # correct() beats the swing-then-twist clamp on the same region
    clamp = _clamp(region, q)
    assert region.contains(clamp).all()
    found = geodesic_distance(q, out)
    two_step = geodesic_distance(q, clamp)
    assert np.all(found <= two_step + ACOS_NOISE), "farther than the clamp"
    # and it is not the same answer: the clamp is several degrees farther on average
    assert np.degrees(np.mean(two_step - found)) > 2.0, "no nearer than the clamp on average"
    # answers inside the true region, or within 1 deg of its boundary (measured to its lattice)
    outside_truth = ~truth.contains(out)
    b = truth.boundary(0.4)
    gap = np.degrees(cKDTree(np.vstack([b, -b])).query(out[outside_truth])[0])
    # chord in R^4 of a geodesic angle g is 2 sin(g/4)
    gap = 4.0 * np.degrees(np.arcsin(np.radians(gap) / 2.0))
    assert np.mean(gap <= 1.0) * outside_truth.sum() >= outside_truth.sum() - 0.005 * len(q), (
        "answers farther than 1 deg outside the true region"
    )


def test_band_crossing_half_turn_is_held_and_corrected():
    truth, region, taught = _fitted(170.0, 2)  # a band crossing +-180 over much of the outline
    d, tau = decompose(taught)
    assert np.mean(np.abs(tau) > math.radians(170.0)) > 0.1
    rng = np.random.default_rng(9)
    # poses 2 deg or more inside, with twists on both sides of +-180
    dd = truth._inside_directions(3000, rng)
    c, h = truth.band(dd)
    q = compose(dd, c + (h - math.radians(2.0)) * rng.uniform(-1.0, 1.0, dd.shape[0]))
    deep = truth.swing.depth(dd) >= math.radians(2.0)
    assert region.contains(q[deep]).mean() >= 0.99
    far = compose(dd, c + math.pi)  # the opposite twist: as far out as twist goes
    out = region.correct(far)
    assert region.contains(out).all()
    d_out, t_out = decompose(out)
    c_out, h_out = region.band.at(d_out)
    assert np.all(np.abs(wrap(t_out - c_out)) <= h_out + 1e-9)


@settings(max_examples=150, deadline=None)
@given(v=unit_quats)
def test_commands_anywhere_on_so3_come_back_inside_and_no_farther_than_any_seed(shoulder, v):
    _, region, _ = shoulder
    q = np.asarray(v) / np.linalg.norm(v)
    out = region.correct(q)
    assert out.shape == (4,) and out[0] >= 0.0
    assert abs(np.linalg.norm(out) - 1.0) < 1e-12
    assert region.contains(out)
    if region.contains(q):
        np.testing.assert_array_equal(out, q if q[0] >= 0 else -q)
    else:
        g = geodesic_distance(q, out)
        assert g <= geodesic_distance(q, region.seeds).min() + ACOS_NOISE


@settings(max_examples=150, deadline=None)
@given(
    k=st.integers(0, 10**6),
    inward=st.floats(-3.0, 3.0),
    twist=st.floats(-1.0, 1.0),
    beyond=st.floats(-5.0, 5.0),
)
def test_commands_near_the_edge_and_near_the_stops(shoulder, k, inward, twist, beyond):
    """Directions within 3 deg of the swing edge, twists within 5 deg of a stop."""
    _, region, _ = shoulder
    mesh = region.mesh
    e = mesh.edges[k % mesh.edges.shape[0]]
    a, b = mesh.vertices[e[0]], mesh.vertices[e[1]]
    p = (a + b) / np.linalg.norm(a + b)
    towards = mesh.axis - np.dot(mesh.axis, p) * p
    towards /= np.linalg.norm(towards)
    p = p * math.cos(math.radians(inward)) + towards * math.sin(math.radians(inward))
    c, h = region.band.at(p[None])
    tau = c[0] + math.copysign(1.0, twist) * (h[0] + math.radians(beyond))
    q = compose(p, tau)
    out = region.correct(q)
    assert region.contains(out)
    # never farther than the engines' two steps on the same region
    clamp = _clamp(region, q[None])[0]
    assert geodesic_distance(q, out) <= geodesic_distance(q, clamp) + ACOS_NOISE


def test_one_command_is_answered_as_in_a_batch_and_the_arrays_round_trip(shoulder):
    truth, region, _ = shoulder
    q = _commands(truth, 500, np.random.default_rng(12))
    batch = region.correct(q)
    copy = TwistRegion.from_arrays(region.arrays(), region.params, region.edge)
    np.testing.assert_array_equal(copy.correct(q), batch)
    np.testing.assert_array_equal(copy.contains(q), region.contains(q))
    for row, expected in zip(q, batch, strict=True):
        np.testing.assert_array_equal(region.correct(row), expected)
        assert region.contains(row) == region.contains(row[None])[0]
    # the thread pool's kernels (large batches) answer as the one-thread ones, row for row
    mesh, band = region._args()
    seeds = (region.seeds, region._seed_dirs)
    pool, pool_status = tk.correct_batch(q, mesh, band, *seeds)
    np.testing.assert_array_equal(pool, batch)
    np.testing.assert_array_equal(tk.correct_serial(q, mesh, band, *seeds)[1], pool_status)
    np.testing.assert_array_equal(tk.contains_batch(q, mesh, band) == 1, region.contains(q))


def test_bad_input_regions_reaching_backwards_and_an_unbuilt_region_are_refused(shoulder):
    _, region, _ = shoulder
    with pytest.raises(InvalidInputError, match="row 1"):
        region.correct(np.array([[1.0, 0, 0, 0], [np.nan, 0, 0, 0]]))
    with pytest.raises(InvalidInputError, match="norm"):
        region.correct(np.array([2.0, 0, 0, 0]))
    with pytest.raises(InvalidInputError):
        region.contains(np.array([0.5, 0, 0, 0]))
    rng = np.random.default_rng(11)
    d = quat.normalize(rng.normal(size=(300, 3)))
    with pytest.raises(InvalidInputError, match="-x"):
        TwistRegion().fit(compose(d, rng.uniform(-1, 1, 300)))
    with pytest.raises(ConfigError, match="fit"):
        TwistRegion().correct(np.array([1.0, 0, 0, 0]))
