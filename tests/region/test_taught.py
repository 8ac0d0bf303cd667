import numpy as np
import pytest

from limbctl.envelope.synthetic import EGG, ConeRegion, PolygonRegion, to_quaternions
from limbctl.envelope.synthetic_twist import BandRegion
from limbctl.errors import ConfigError, InvalidInputError
from limbctl.geometry.gimbal import pan_tilt_to_direction
from limbctl.geometry.quat import limb_direction
from limbctl.region import RegionParams, TaughtRegion
from tests.region.support import benchmark


@pytest.fixture(scope="module")
def cone():
    rng = np.random.default_rng(0)
    region = ConeRegion(np.radians(20.0))
    return region, region.sample(800, rng), region.test_directions(4000, rng)


@pytest.fixture(scope="module")
def fitted(cone):
    return TaughtRegion().fit(cone[1])


def test_directions_quaternions_and_the_arrays_build_the_same_region_answering_alike(cone, fitted):
    region, train, test = cone
    from_q = TaughtRegion().fit(to_quaternions(train))
    assert from_q.edge == fitted.edge == "smooth"
    # the quaternions' limb directions differ from the directions by rounding only: the same region
    assert from_q.mesh.vertices.shape == fitted.mesh.vertices.shape
    q = to_quaternions(test)
    np.testing.assert_allclose(from_q.correct(q), fitted.correct(q), atol=1e-9)
    # the shape was built on thinned samples, all of them among the taught ones
    assert 0 < fitted.support_index.size < train.shape[0]
    back = TaughtRegion.from_arrays(fitted.arrays(), fitted.params, fitted.edge)
    np.testing.assert_array_equal(back.correct(q), fitted.correct(q), "rebuilt from the arrays")
    assert back.edge == "smooth" and back.verdicts == ()
    # contains and correct answer one command and many alike
    assert fitted.contains(to_quaternions(train)).mean() > 0.999
    inside = fitted.contains(q)
    out = fitted.correct(q)
    np.testing.assert_array_equal(out[inside], q[inside])
    # corrected commands land in the region, within 1 deg of the true cone
    assert fitted.contains(out).all()
    assert region.depth(limb_direction(out)).min() > -np.radians(1.0)
    for i in range(0, 4000, 400):
        assert fitted.contains(q[i]) == inside[i]
        np.testing.assert_array_equal(fitted.correct(q[i]), out[i])


@pytest.mark.parametrize("shape", ["cone", "egg"])
def test_containment_from_the_arcs_is_the_gates(cone, fitted, shape):
    # train's summary asks the arcs (the fit's kernel); the gate asks its grid: the same answers
    rng = np.random.default_rng(4)
    _, train, test = cone
    if shape == "egg":
        region = PolygonRegion(EGG)
        train, test = region.sample(800, rng), region.test_directions(4000, rng)
        fitted = TaughtRegion().fit(train)
    near = fitted.mesh.vertices[fitted.mesh.edges[:, 0]]
    far = rng.normal(size=(2000, 3))
    for d in (train, test, near, far / np.linalg.norm(far, axis=1, keepdims=True)):
        q = to_quaternions(d)
        inside = fitted.contains(q)
        np.testing.assert_array_equal(fitted.contains_from_arcs(q), inside)
    assert 0 < fitted.contains_from_arcs(to_quaternions(test)).sum() < len(test)


def test_the_edge_is_chosen_by_name_every_verdict_kept_and_the_support_capped(cone):
    # each strategy by name: tests/region/test_edge_choice.py; here the settings reach it
    traced = TaughtRegion(RegionParams(edge="traced", support_nodes=60)).fit(cone[1])
    assert traced.edge == "traced"
    assert [v.strategy for v in traced.verdicts] == ["traced", "supported"]
    assert traced.support_index.size <= 60, "the support is capped"


def test_bad_samples_and_an_unbuilt_region_are_refused():
    with pytest.raises(InvalidInputError, match="directions \\(N, 3\\) or quaternions"):
        TaughtRegion().fit(np.zeros((10, 2)))
    with pytest.raises(InvalidInputError, match="at least 3"):
        TaughtRegion().fit(np.array([[1.0, 0.0, 0.0]]))
    with pytest.raises(InvalidInputError, match="finite unit vectors"):
        TaughtRegion().fit(np.full((10, 3), 2.0))
    with pytest.raises(ConfigError, match="not built"):
        TaughtRegion().contains(np.array([1.0, 0.0, 0.0, 0.0]))


def edge_offsets(region: TaughtRegion, truth: BandRegion, every: int = 20) -> np.ndarray:
    """How far (deg) the region's edge stands past the truth's (negative: inside) along its
    outward normal at its boundary points ``every`` apart (0.05 deg each)."""
    b = truth.swing.boundary
    at = np.arange(0, b.shape[0], every)
    normal = np.cross(b[(at + 1) % b.shape[0]] - b[at - 1], b[at])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    normal[truth.swing.depth(b[at] + 1e-3 * normal) > 0.0] *= -1.0
    s = np.radians(np.arange(-2.5, 2.5, 0.01))
    ray = np.cos(s)[None, :, None] * b[at][:, None] + np.sin(s)[None, :, None] * normal[:, None]
    inside = region.mesh.contains(ray.reshape(-1, 3)).reshape(at.size, s.size)
    # the last step inside along each ray
    return np.degrees(s[s.size - 1 - np.argmax(inside[:, ::-1], axis=1)])


def test_a_dense_teaching_puts_the_edge_where_its_samples_reach():
    # a star-shaped outline of 3.5 deg straight pieces turning both ways, as the region families'
    rng = np.random.default_rng(7)
    phi = np.radians(np.arange(0.0, 360.0, 5.0))
    r = 40.0 * (1.0 + 0.06 * rng.uniform(-1.0, 1.0, phi.size))
    poly = r[:, None] * np.stack([np.cos(phi), np.sin(phi)], axis=1)
    truth = BandRegion(poly, lambda pan, tilt: (0.0 * pan, 40.0 + 0.0 * pan))
    # dense i.i.d.: the edge band's samples come within a few hundredths of a degree of it
    q = truth.teaching(2500, 1900, 3100, rng)
    region = TaughtRegion().fit(q)
    assert region.contains(q).mean() > 0.998
    off = edge_offsets(region, truth)
    # the edge at the samples' reach, neither past nor inside
    assert abs(float(np.median(off))) < 0.15
    assert np.percentile(off, 25) > -0.15


def test_an_edge_from_the_samples_own_depths_is_held_to_the_tight_reach():
    # the families' outline of seed 26, taught densely: no chord across the notch stands past it
    poly = benchmark("bench_region_families").outline(np.random.default_rng([26, 0]))
    truth = BandRegion(poly, lambda pan, tilt: (np.zeros_like(pan), np.full_like(pan, 40.0)))
    d = limb_direction(truth.teaching(2500, 1900, 3100, np.random.default_rng([26, 99])))
    region = TaughtRegion().fit(d)
    lo, hi = poly.min(axis=0) - 5.0, poly.max(axis=0) + 5.0
    pan, tilt = np.meshgrid(np.arange(lo[0], hi[0], 0.5), np.arange(lo[1], hi[1], 0.5))
    lattice = pan_tilt_to_direction(np.radians(pan.ravel()), np.radians(tilt.ravel()))
    past = -np.degrees(truth.swing.depth(lattice[region.mesh.contains(lattice)]).min())
    assert past <= 1.0, f"the learned edge stands {past:.2f} deg past the truth"
