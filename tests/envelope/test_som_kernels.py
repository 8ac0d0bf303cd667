import numpy as np
import pytest

from limbctl.envelope.som import SOM, table_i_schedule
from limbctl.envelope.som_kernels import train_som
from tests.envelope.test_som import cone_patterns


def train_som_reference(weights, patterns, grid_distance, learning_rates, radii, winners):
    """Plain numpy version of :func:`train_som` (same arguments, same result)."""
    steps = 0
    for t in range(len(learning_rates)):
        lr = learning_rates[t]
        changed = 0
        for j, x in enumerate(patterns):
            # D_i = |x - w_i|^2 ; winner = first argmin
            diff = x - weights
            d = diff[:, 0] ** 2 + diff[:, 1] ** 2 + diff[:, 2] ** 2 + diff[:, 3] ** 2
            win = int(np.argmin(d))
            if winners[j] != win:
                changed += 1
                winners[j] = win
            near = grid_distance[win] <= radii[t]
            # w_i += lr (x - w_i) for the winner's grid neighbourhood
            weights[near] += lr * (x - weights[near])
        steps = t + 1
        if changed == 0:
            return steps, True
    return steps, False


@pytest.mark.parametrize(
    ("rows", "cols", "seed", "max_steps", "n", "half_angle_deg", "min_steps"),
    [(5, 6, 3, 60, 80, 70, 10), (4, 4, 5, 500, 40, 45, 0)],
    ids=["several periods", "to convergence"],
)
def test_kernel_matches_reference(rows, cols, seed, max_steps, n, half_angle_deg, min_steps):
    som = SOM(rows=rows, cols=cols, seed=seed, max_steps=max_steps)
    patterns = cone_patterns(n, np.radians(half_angle_deg), seed=seed + 1)
    lr, radii = som.schedule()
    wk, wr = som.initial_weights(), som.initial_weights()
    win_k, win_r = np.full(n, -1, dtype=np.int64), np.full(n, -1, dtype=np.int64)
    out_k = train_som(wk, patterns, som.grid_distance(), lr, radii, win_k)
    out_r = train_som_reference(wr, patterns, som.grid_distance(), lr, radii, win_r)
    np.testing.assert_allclose(wk, wr, atol=1e-10, rtol=0)
    np.testing.assert_array_equal(win_k, win_r)
    assert out_k == out_r
    steps, converged = out_k
    assert converged and min_steps < steps < max_steps  # it really trained, and converged


def test_one_update_moves_the_winners_grid_neighbourhood_by_the_learning_rate():
    weights = np.array([[0.0, 0.0, 0.0, 0.0], [1.0, 1.0, 1.0, 1.0]])
    pattern = np.array([[1.0, 0.0, 0.0, 0.0]])
    winners = np.full(1, -1, dtype=np.int64)
    pair = np.array([[0.0, 1.0], [1.0, 0.0]])  # the grid distances of two nodes
    steps, converged = train_som(weights, pattern, pair, np.array([0.25]), np.zeros(1), winners)
    # node 0 wins (D = 1 < 3); w += 0.25 (x - w); radius 0: node 1 untouched
    np.testing.assert_array_equal(weights, [[0.25, 0.0, 0.0, 0.0], [1.0, 1.0, 1.0, 1.0]])
    assert winners[0] == 0 and steps == 1 and not converged
    weights = np.zeros((9, 4))
    weights[4] = [1.0, 0.0, 0.0, 0.0]  # the centre node of a 3 x 3 grid wins
    grid_distance = SOM(rows=3, cols=3, seed=0).grid_distance()
    train_som(weights, pattern, grid_distance, np.array([0.5]), np.array([1.0]), winners)
    # radius 1 on the grid: the centre and its 4 edge neighbours, not the diagonals
    assert list(np.flatnonzero(weights[:, 0] > 0)) == [1, 3, 4, 5, 7]
    np.testing.assert_allclose(weights[[1, 3, 5, 7], 0], 0.5)


def test_training_stops_when_no_winner_changes_or_at_the_cap():
    patterns = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])
    lr, radii = table_i_schedule(100)
    winners = np.full(2, -1, dtype=np.int64)
    grid_distance = np.array([[0.0, 1.0], [1.0, 0.0]])
    steps, converged = train_som(patterns.copy(), patterns, grid_distance, lr, 0 * radii, winners)
    # step 1 sets the winners (changed from -1), step 2 changes none
    assert (steps, converged) == (2, True)
    np.testing.assert_array_equal(winners, [0, 1])
    som = SOM(rows=8, cols=8, seed=1, max_steps=3)
    patterns = cone_patterns(200, np.radians(60), seed=2)
    lr, radii = som.schedule()
    winners = np.full(len(patterns), -1, dtype=np.int64)
    steps, converged = train_som(
        som.initial_weights(), patterns, som.grid_distance(), lr, radii, winners
    )
    assert steps == 3 and not converged, "the cap is honoured without convergence"
