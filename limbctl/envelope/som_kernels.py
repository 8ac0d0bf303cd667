"""Numba training kernel of the SOM (Jenkins & Dacey 2011; the rule: :mod:`limbctl.envelope.som`;
ties to the first index). Its numpy twin is in the tests. No fastmath: comparisons stay NaN-safe."""

from __future__ import annotations

import numpy as np

from limbctl.geometry.jit import njit


@njit
def train_som(
    weights: np.ndarray,
    patterns: np.ndarray,
    grid_distance: np.ndarray,
    learning_rates: np.ndarray,
    radii: np.ndarray,
    winners: np.ndarray,
) -> tuple[int, bool]:
    """Train ``weights`` (M, 4) in place by the SOM rule; the time steps run, and whether the
    last changed no winner.

    Parameters
    ----------
    patterns : ndarray, shape (N, 4)
        Training patterns, presented in this order every time step.
    grid_distance : ndarray, shape (M, M)
        Distance between nodes on the output grid.
    learning_rates, radii : ndarray, shape (T,)
        ``lr(t)`` and neighbourhood ``radius(t)`` per time step; T caps the training.
    winners : ndarray, shape (N,) int64
        Filled with each pattern's winner in the last time step run (-1: changed at first).
    """
    n = patterns.shape[0]
    m = weights.shape[0]
    steps = 0
    for t in range(learning_rates.shape[0]):
        lr = learning_rates[t]
        radius = radii[t]
        changed = 0
        for j in range(n):
            best = np.inf
            win = 0
            for i in range(m):
                # D_i = sum_k (x_k - w_ik)^2
                d = 0.0
                for k in range(4):
                    diff = patterns[j, k] - weights[i, k]
                    d += diff * diff
                if d < best:
                    best = d
                    win = i
            if winners[j] != win:
                changed += 1
                winners[j] = win
            for i in range(m):
                if grid_distance[win, i] <= radius:
                    # w_i += lr (x - w_i)
                    for k in range(4):
                        weights[i, k] += lr * (patterns[j, k] - weights[i, k])
        steps = t + 1
        if changed == 0:
            return steps, True
    return steps, False
