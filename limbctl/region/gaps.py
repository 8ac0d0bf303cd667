"""How far beyond the outermost taught samples the true edge lies: three gap estimators, each
unbiased when the outermost depths (rad) behave like a Poisson process below the edge."""

from __future__ import annotations

import numpy as np

#: Outermost depths an estimate reads: 11 gaps average to 30 % noise, all next to the edge.
ORDER_STATISTICS = 12
#: The majorant's expected gap in units of ``r_(12) / 12``, simulated (3000 draws, 30 and 100/unit).
MAJORANT_GAP = 2.19


def line_gap(depths: np.ndarray) -> float:
    """Gap (rad) beyond the outermost of ``depths`` (K,), outermost first: the least-squares line
    through ``(i, o_(i))`` at ``i = 0``, less ``o_(1)``, at least 0; 0 for fewer than 3."""
    k = depths.size
    if k < 3:
        return 0.0
    i = np.arange(1, k + 1, dtype=np.float64)
    # slope and intercept of the least-squares line o = c + s i
    slope = np.sum((i - i.mean()) * (depths - depths.mean())) / np.sum((i - i.mean()) ** 2)
    intercept = depths.mean() - slope * i.mean()
    return max(float(intercept - depths[0]), 0.0)


def spacing_gap(depths: np.ndarray) -> float:
    """Gap (rad) beyond the outermost of ``depths`` (K,), sorted outermost first: their mean
    spacing ``(o_(1) - o_(K)) / (K - 1)``; 0 for fewer than 3."""
    k = depths.size
    return float((depths[0] - depths[-1]) / (k - 1)) if k >= 3 else 0.0


def majorant_gap(residuals: np.ndarray) -> float:
    """Gap (rad) between the upper concave majorant of readings and the edge: ``MAJORANT_GAP
    r_(K) / K`` of the ``residuals`` below it (smallest first), ``K = ORDER_STATISTICS``."""
    return float(MAJORANT_GAP * residuals[ORDER_STATISTICS - 1] / ORDER_STATISTICS)
