import numpy as np
import pytest

from limbctl.envelope import layouts
from limbctl.envelope.layouts import make_layout
from limbctl.errors import ConfigError


def nearest_neighbour_angles(points: np.ndarray) -> np.ndarray:
    """Angle (rad, (n,)) on S^3 between each unit 4-vector and its nearest other point."""
    points = np.asarray(points, dtype=np.float64)
    gram = points @ points.T
    np.fill_diagonal(gram, -np.inf)
    return np.arccos(np.clip(gram.max(axis=1), -1.0, 1.0))


def covering_angle(points, probes, sign_aware=False, chunk=4096):
    """Covering radius estimate (rad): the largest angle from a probe (m, 4) to its nearest point
    (n, 4), q and -q one point when ``sign_aware``; a lower bound of the true radius."""
    points = np.asarray(points, dtype=np.float64)
    best_dots = []
    for start in range(0, len(probes), chunk):
        dots = probes[start : start + chunk] @ points.T
        if sign_aware:
            dots = np.abs(dots)
        best_dots.append(dots.max(axis=1))
    worst = float(np.min(np.concatenate(best_dots)))
    return float(np.arccos(np.clip(worst, -1.0, 1.0)))


#: (name, full-sphere count, nearest-neighbour angle between unit 4-vectors in degrees)
POLYTOPES = [
    ("24-cell", 24, 60.0),
    ("600-cell", 120, 36.0),
    # 120-cell edge over circumradius = 1 / (phi^2 sqrt 2); angle = 2 asin(edge / 2)
    ("120-cell", 600, np.degrees(2 * np.arcsin(1 / (2 * layouts.PHI**2 * np.sqrt(2))))),
]


@pytest.mark.parametrize("name,count,nn_deg", POLYTOPES)
def test_polytopes_on_s3_and_folded_keep_one_of_each_antipodal_pair(name, count, nn_deg):
    full = make_layout(name, hemisphere=False)
    assert full.shape == (count, 4)
    np.testing.assert_allclose(np.linalg.norm(full, axis=1), 1.0, atol=1e-14)
    nn = np.degrees(nearest_neighbour_angles(full))
    np.testing.assert_allclose(nn, nn_deg, atol=1e-9)
    # centrally symmetric: the antipode of every vertex is a vertex
    assert np.allclose(np.max(full @ (-full).T, axis=1), 1.0)
    half = make_layout(name)
    assert half.shape == (count // 2, 4)
    assert (half[:, 0] >= 0).all()
    # every full-sphere vertex is a folded node or the antipode of one, and nothing is repeated
    best = np.max(np.abs(full @ half.T), axis=1)
    np.testing.assert_allclose(best, 1.0, atol=1e-12)
    assert np.max(np.abs(half @ half.T) - np.eye(len(half))) < 1 - 1e-9
    np.testing.assert_allclose(np.degrees(nearest_neighbour_angles(half)).min(), nn_deg, atol=1e-9)


def test_the_720_unions_counts_alignment_and_covering():
    assert POLYTOPES[2][2] == pytest.approx(15.52, abs=0.01), "the 120-cell's edge angle"
    for name in ("polytope-720", "polytope-720-even"):
        assert make_layout(name, hemisphere=False).shape == (720, 4)
        assert make_layout(name).shape == (360, 4)
    # dual alignment: every 600-cell vertex sits at a 120-cell cell centre, far from its vertices
    c120 = layouts.cell_120()
    assert np.degrees(np.arccos(np.max(layouts.cell_600("odd") @ c120.T, axis=1))).min() > 20.0
    assert np.degrees(np.arccos(np.max(layouts.cell_600("even") @ c120.T, axis=1))).min() < 10.0
    probes = make_layout("uniform", n=60000, seed=11, hemisphere=False)
    dual = np.degrees(covering_angle(make_layout("polytope-720", hemisphere=False), probes))
    even = np.degrees(covering_angle(make_layout("polytope-720-even", hemisphere=False), probes))
    alone = np.degrees(covering_angle(make_layout("120-cell", hemisphere=False), probes))
    assert dual < even - 3.0 and dual < alone - 5.0, "the dual-aligned union covers better"
    # the 120-cell alone covers to ~22.2 deg (its cell centres): a sane estimate stays below
    assert alone < 22.3
    probes = make_layout("uniform", n=30000, seed=12)
    full = covering_angle(make_layout("polytope-720", hemisphere=False), probes)
    half = covering_angle(make_layout("polytope-720"), probes, sign_aware=True)
    assert half == pytest.approx(full, abs=1e-12), "the folded union covers as the full one"


def test_uniform_is_seeded_unit_and_on_the_hemisphere():
    a = make_layout("uniform", n=2000, seed=3)
    np.testing.assert_array_equal(a, make_layout("uniform", n=2000, seed=np.random.default_rng(3)))
    assert not np.array_equal(a, make_layout("uniform", n=2000, seed=4))
    assert a.shape == (2000, 4)
    np.testing.assert_allclose(np.linalg.norm(a, axis=1), 1.0, atol=1e-14)
    assert (a[:, 0] >= 0).all()
    full = make_layout("uniform", n=20000, seed=3, hemisphere=False)
    # uniform on S^3: each coordinate has mean 0 and variance 1/4
    np.testing.assert_allclose(full.mean(axis=0), 0.0, atol=0.02)
    np.testing.assert_allclose(full.var(axis=0), 0.25, atol=0.01)


@pytest.mark.parametrize("hemisphere", [True, False])
def test_super_fibonacci_is_near_uniform_and_starts_on_the_formula(hemisphere):
    n = 2000
    sf = make_layout("super-fibonacci", n=n, hemisphere=hemisphere)
    rnd = make_layout("uniform", n=n, seed=0, hemisphere=hemisphere)
    assert sf.shape == (n, 4)
    np.testing.assert_allclose(np.linalg.norm(sf, axis=1), 1.0, atol=1e-14)
    if hemisphere:
        assert (sf[:, 0] >= 0).all()
    # spirals keep points apart: the closest pair is several times wider than random's
    assert nearest_neighbour_angles(sf).min() > 3.0 * nearest_neighbour_angles(rnd).min()
    probes = make_layout("uniform", n=40000, seed=21, hemisphere=hemisphere)
    assert covering_angle(sf, probes) < covering_angle(rnd, probes)
    # deterministic
    np.testing.assert_array_equal(sf, make_layout("super-fibonacci", n=n, hemisphere=hemisphere))
    # the first point of the full spiral by the formula
    n, s = 10, 0.5
    alpha, beta = 2 * np.pi * s / np.sqrt(2), 2 * np.pi * s / layouts.PSI
    r, big_r = np.sqrt(s / n), np.sqrt(1 - s / n)
    expected = [r * np.sin(alpha), r * np.cos(alpha), big_r * np.sin(beta), big_r * np.cos(beta)]
    first = make_layout("super-fibonacci", n=n, hemisphere=False)[0]
    np.testing.assert_allclose(first, expected, atol=1e-15)
    assert layouts.PSI**4 == pytest.approx(layouts.PSI + 4, abs=1e-12)


def test_unknown_names_and_bad_node_counts_are_refused():
    with pytest.raises(ConfigError, match="unknown layout 'cube'.*600-cell.*super-fibonacci"):
        make_layout("cube")
    with pytest.raises(ConfigError, match="needs a node count"):
        make_layout("uniform")
    with pytest.raises(ConfigError, match="needs a node count"):
        make_layout("super-fibonacci", n=0)
    with pytest.raises(ConfigError, match="has 60 nodes"):
        make_layout("600-cell", n=100)
    assert make_layout("600-cell", n=60).shape == (60, 4)
