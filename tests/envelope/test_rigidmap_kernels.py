import numpy as np
import pytest

from limbctl.envelope import rigidmap_kernels as rk
from limbctl.envelope.layouts import make_layout
from limbctl.envelope.synthetic import ConeRegion, to_quaternions
from tests.geometry.test_quat import random_unit


def _patterns(n, seed, half_angle_deg=30.0):
    rng = np.random.default_rng(seed)
    cone = ConeRegion(np.radians(half_angle_deg))
    return np.ascontiguousarray(to_quaternions(cone.sample(n, rng)))


def _nodes_at_the_data():
    """The support refinement's case: every node a winner, two clusters far apart, so that in
    the middle epochs a node sees only a few patterns (gathered) and early on all (scanned)."""
    rng = np.random.default_rng(7)
    near = _patterns(70, 8, half_angle_deg=10.0)
    far = to_quaternions(-ConeRegion(np.radians(10.0)).sample(12, rng))
    patterns = np.ascontiguousarray(np.vstack([near, far])[rng.permutation(82)])
    return np.ascontiguousarray(patterns[::2]), patterns


@pytest.mark.parametrize(
    ("case", "metric"),
    [("layout", rk.EUCLIDEAN), ("layout", rk.COSINE), ("nodes at the data", rk.EUCLIDEAN)],
)
def test_training_kernel_matches_numpy_reference(case, metric):
    if case == "layout":
        positions, patterns = random_unit(150, 1), _patterns(60, 2)
    else:
        positions, patterns = _nodes_at_the_data()
    w_kernel = positions.copy()
    w_ref = positions.copy()
    args = (1.0, 0.15, 2 * np.pi, 1.0, 0.04, 1000, 1e-9)
    e_kernel = rk.train_rigid_map(positions, w_kernel, patterns, *args)
    e_ref = rk.train_rigid_map_reference(positions, w_ref, patterns, *args, metric=metric)
    assert e_kernel == e_ref < 1000
    np.testing.assert_allclose(w_kernel, w_ref, atol=1e-12)
    # training moved the weights onto the data: every winner's weight is near its patterns
    assert case != "layout" or not np.allclose(w_kernel, positions)


def test_patterns_near_gathers_few_in_pattern_order_and_scans_many():
    pattern_slot = np.array([2, 0, 1, 2, 0, 0, 1, 2, 0, 0, 0, 0], dtype=np.int64)
    start, grouped = rk._slot_patterns(pattern_slot, 3)
    np.testing.assert_array_equal(start, [0, 7, 9, 12])
    np.testing.assert_array_equal(grouped, [1, 4, 5, 8, 9, 10, 11, 2, 6, 0, 3, 7])
    buffer = np.empty(12, dtype=np.int64)
    mark = np.zeros(12, dtype=np.bool_)
    # slots 1 and 2: 5 of 12 patterns, more than a quarter: scan them all
    assert rk._patterns_near(np.array([0.0, 0.5, 0.2]), start, grouped, buffer, mark) == -1
    # slot 1 alone: 2 patterns, gathered in order
    count = rk._patterns_near(np.array([0.0, 0.5, 0.0]), start, grouped, buffer, mark)
    np.testing.assert_array_equal(buffer[:count], [2, 6])
    assert not mark.any()
    # many slots: merged in pattern order
    rng = np.random.default_rng(5)
    pattern_slot = rng.integers(0, 12, 400)
    start, grouped = rk._slot_patterns(pattern_slot, 12)
    h = np.zeros(12)
    h[[3, 7, 8]] = [0.1, 1.0, 0.4]
    buffer = np.empty(400, dtype=np.int64)
    mark = np.zeros(400, dtype=np.bool_)
    count = rk._patterns_near(h, start, grouped, buffer, mark)
    np.testing.assert_array_equal(buffer[:count], np.flatnonzero(h[pattern_slot] > 0.0))
    assert not mark.any()


def test_position_winners_and_topology_are_the_nearest_positions_ties_in_index_order():
    positions = random_unit(200, 3)
    patterns = _patterns(50, 4)
    got = rk.position_winners(positions, patterns)
    want = np.argmin(((patterns[:, None, :] - positions[None]) ** 2).sum(-1), axis=1)
    np.testing.assert_array_equal(got, want)
    p = random_unit(40, 11)
    topo = rk.position_topology(p, 3)
    for i in range(40):
        assert i not in topo[i]
        dots = p @ p[i]
        dots[i] = -np.inf
        np.testing.assert_array_equal(np.sort(topo[i]), np.sort(np.argsort(-dots)[:3]))
    # polytope layouts hold many equal dots: the order is a stable sort's, nearest first
    for layout in ("600-cell", "24-cell"):
        p = make_layout(layout, None, seed=0)
        dots = p @ p.T
        np.fill_diagonal(dots, -np.inf)
        for k in (1, 5, 12):
            want = np.argsort(-dots, axis=1, kind="stable")[:, : min(k, len(p) - 1)]
            np.testing.assert_array_equal(rk.position_topology(p, k), want, f"{layout}, k={k}")
