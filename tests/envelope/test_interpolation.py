import numpy as np
import pytest

from limbctl.envelope import interpolation as ip
from limbctl.errors import ConfigError
from limbctl.geometry import quat
from tests.geometry.test_quat import random_unit


def respond_reference(
    weights: np.ndarray, q: np.ndarray, k: int, metric: int, mode: int, topology: np.ndarray
) -> np.ndarray:
    """The numpy twin of :func:`ip.respond_batch` (same arguments, same answers)."""
    out = np.empty((q.shape[0], 4))
    norms = np.linalg.norm(weights, axis=1)
    count = 1 if mode == ip.NONE else min(k + 1, len(weights))
    for j, x in enumerate(q):
        if metric == ip.EUCLIDEAN:
            dist = np.sum((x - weights) ** 2, axis=1)
        else:
            dist = np.arccos(np.clip((weights @ x) / norms, -1.0, 1.0)) ** 2
        order = np.argsort(dist, kind="stable")
        if mode == ip.TOPOLOGICAL:
            idx = np.concatenate([order[:1], topology[order[0], : count - 1]])
        else:
            idx = order[:count]
        y = weights[idx[0]].copy()
        if mode == ip.IDW and len(idx) > 1 and dist[idx[0]] > 0.0:
            inv = 1.0 / np.sqrt(dist[idx])
            y = inv @ weights[idx] / inv.sum()
        elif mode in (ip.GEOMETRIC, ip.GEOMETRIC_WINNER, ip.TOPOLOGICAL):
            res = x - y
            for other in idx[1:]:
                base = weights[idx[0]] if mode == ip.GEOMETRIC_WINNER else y
                d = weights[other] - base
                dd = d @ d
                if dd > 0.0:
                    a = np.clip((res @ d) / dd, 0.0, 1.0)
                    y = y + a * d
                    res = res - a * d
        y = y / np.linalg.norm(y)
        out[j] = -y if y[0] < 0.0 else y
    return out


@pytest.mark.parametrize("mode", list(ip.INTERPOLATIONS))
@pytest.mark.parametrize("metric", list(ip.METRICS))
def test_kernel_matches_reference(mode, metric):
    rng = np.random.default_rng(1)
    # trained-looking weights: near-unit, not exactly unit
    weights = random_unit(60, seed=2) * rng.uniform(0.9, 1.0, size=(60, 1))
    q = random_unit(200, seed=3)
    topology = ip.neighbours_by_position(random_unit(60, seed=4), 6)
    for k in (1, 3, 8):
        args = (weights, q, k, ip.METRICS[metric], ip.INTERPOLATIONS[mode], topology)
        kernel = ip.respond_batch(*args)
        reference = respond_reference(*args)
        # the one-thread twin and the size-chosen entry point answer row for row alike
        np.testing.assert_array_equal(ip.respond_serial(*args), kernel)
        np.testing.assert_array_equal(ip.respond_rows(*args), kernel)
        np.testing.assert_allclose(kernel, reference, atol=1e-12)
        np.testing.assert_allclose(np.linalg.norm(kernel, axis=1), 1.0, atol=1e-14)
        assert (kernel[:, 0] >= 0).all()


def test_geometric_projects_the_residual_onto_the_runner_up_direction_within_the_segment():
    w0 = np.array([1.0, 0.0, 0.0, 0.0])
    w1 = quat.normalize(np.array([1.0, 1.0, 0.0, 0.0]))
    empty = np.empty((3, 0), np.int64)
    weights = np.stack([w0, w1, [0.0, 0.0, 0.0, 1.0]])
    # on the bisector of two unit nodes the projection is the chord's midpoint: exactly x
    x = quat.normalize(w0 + w1)
    geo = ip.respond_batch(weights, x[None], 1, ip.EUCLIDEAN, ip.GEOMETRIC, empty)
    np.testing.assert_allclose(geo[0], x, atol=1e-15)
    # elsewhere: y = w0 + a (w1 - w0), a = <x - w0, w1 - w0> / |w1 - w0|^2, normalised
    x = quat.normalize(np.array([1.0, 0.3, 0.05, 0.0]))
    d = w1 - w0
    a = (x - w0) @ d / (d @ d)
    expected = quat.normalize(w0 + a * d)
    none = ip.respond_batch(weights, x[None], 1, ip.EUCLIDEAN, ip.NONE, empty)
    geo = ip.respond_batch(weights, x[None], 1, ip.EUCLIDEAN, ip.GEOMETRIC, empty)
    np.testing.assert_allclose(none[0], w0, atol=1e-15)
    np.testing.assert_allclose(geo[0], expected, atol=1e-15)
    assert 0 < a < 1
    assert quat.geodesic_distance(geo[0], x) < quat.geodesic_distance(none[0], x)
    # x beyond the runner-up: a = 1 (stop at w1), never overshoot
    w1 = quat.normalize(np.array([1.0, 0.2, 0.0, 0.0]))
    x = quat.normalize(np.array([1.0, 0.5, 0.0, 0.0]))
    weights = np.stack([w0, w1])
    out = respond_reference(weights, x[None], 1, ip.EUCLIDEAN, ip.GEOMETRIC, np.empty((2, 0)))
    np.testing.assert_allclose(out[0], w1, atol=1e-12)


def test_none_returns_the_normalised_winner_and_idw_a_hit_or_the_mean():
    weights = np.array([[0.9, 0.0, 0.0, 0.0], [0.0, 0.0, -0.8, 0.0], [0.0, 0.5, 0.5, 0.0]])
    q = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.0]])
    out = ip.respond_batch(weights, q, 8, ip.EUCLIDEAN, ip.NONE, np.empty((3, 0), np.int64))
    # the second winner (0, 0, -1, 0) has w = 0: kept as is (no flip needed)
    np.testing.assert_allclose(out, [[1, 0, 0, 0], [0, 0, -1, 0]], atol=1e-15)
    w = random_unit(4, seed=5)
    hit = ip.respond_batch(w, w[2:3], 3, ip.EUCLIDEAN, ip.IDW, np.empty((4, 0), np.int64))
    np.testing.assert_allclose(hit[0], w[2], atol=1e-15)
    # input equidistant from two nodes (and far from the rest): the normalised mean
    weights = np.eye(4)[:2]
    x = quat.normalize(weights[0] + weights[1])
    out = ip.respond_batch(weights, x[None], 1, ip.EUCLIDEAN, ip.IDW, np.empty((2, 0), np.int64))
    np.testing.assert_allclose(out[0], x, atol=1e-15)


def test_topological_uses_the_topology_not_the_nearest_weights():
    w0 = np.array([1.0, 0.0, 0.0, 0.0])
    near = quat.normalize(np.array([1.0, 0.3, 0.0, 0.0]))
    linked = quat.normalize(np.array([1.0, 0.0, 0.3, 0.0]))
    weights = np.stack([w0, near, linked])
    x = quat.normalize(np.array([1.0, 0.1, 0.1, 0.0]))
    topology = np.array([[2], [0], [0]], dtype=np.int64)
    topo = ip.respond_batch(weights, x[None], 1, ip.EUCLIDEAN, ip.TOPOLOGICAL, topology)
    geo = ip.respond_batch(weights, x[None], 1, ip.EUCLIDEAN, ip.GEOMETRIC, topology)
    # topological moves toward the linked node (+y), geometric toward the nearest (+x)
    assert topo[0, 2] > 0 and abs(topo[0, 1]) < 1e-15
    assert geo[0, 1] > 0 and abs(geo[0, 2]) < 1e-15


def test_nearest_distance_neighbours_and_names_are_checked():
    w = random_unit(50, seed=6) * 0.95
    q = random_unit(300, seed=7)
    reference = np.sqrt(np.sum((q[:, None, :] - w[None, :, :]) ** 2, axis=2).min(axis=1))
    np.testing.assert_allclose(ip.nearest_distance(w, q), reference, atol=1e-14)
    # neighbours by position on a grid
    grid = np.array([(r, c) for r in range(4) for c in range(5)], dtype=np.float64)
    nb = ip.neighbours_by_position(grid, 8)
    # interior node (1, 1) = index 6: 4 edge neighbours first (lower index on ties), then diagonals
    assert list(nb[6, :4]) == [1, 5, 7, 11]
    assert sorted(nb[6, 4:]) == [0, 2, 10, 12]
    assert nb.shape == (20, 8) and nb.dtype == np.int64
    assert ip.interpolation_code("geometric") == ip.GEOMETRIC, "names are checked"
    with pytest.raises(ConfigError, match="unknown interpolation 'linear'.*none, idw"):
        ip.interpolation_code("linear")
    with pytest.raises(ConfigError, match="integer >= 1"):
        ip.check_k(0)
    assert ip.check_k(np.int64(3)) == 3
