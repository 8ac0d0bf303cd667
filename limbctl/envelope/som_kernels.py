"""Numba training kernel of the SOM (Jenkins & Dacey 2011); its plain numpy twin is in the tests.

The rule (Mehrotra, Mohan & Ranka's Kohonen SOM, as the paper uses it), for time step
``t = 0, 1, ...`` (one time step = one presentation of every training pattern, in order):

- for each pattern ``x``: the winner ``c`` minimises the squared Euclidean distance
  ``D_i = sum_k (x_k - w_ik)^2`` (first index on ties);
- every node ``i`` within the neighbourhood, grid distance ``g_ci <= radius(t)``, moves toward
  the pattern: ``w_i += lr(t) (x - w_i)``;
- training stops when no pattern's winner changed during a whole time step (convergence), or
  after the last scheduled time step.

The schedules ``lr(t)`` and ``radius(t)`` are given as arrays (one entry per time step, their
length is the step cap); :func:`limbctl.envelope.som.table_i_schedule` builds the paper's.
No fastmath: comparisons stay NaN-safe. Compiled once and cached on disk (``cache=True``).
"""

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
    """Train ``weights`` in place by the SOM rule (module docstring).

    Parameters
    ----------
    weights : ndarray, shape (M, 4)
        Initial weights; trained in place.
    patterns : ndarray, shape (N, 4)
        Training patterns, presented in this order every time step.
    grid_distance : ndarray, shape (M, M)
        Distance between nodes on the output grid.
    learning_rates, radii : ndarray, shape (T,)
        ``lr(t)`` and neighbourhood ``radius(t)`` per time step; T caps the training.
    winners : ndarray, shape (N,) int64
        Filled with each pattern's winner in the last time step run. Entries that are not a
        node index (e.g. -1) count as changed in the first step.

    Returns
    -------
    steps : int
        Time steps run.
    converged : bool
        True when the last step changed no winner.
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
