"""How far beyond the outermost taught samples the true edge lies: the three gap estimators.

Near an edge, taught samples thin out at random: the outermost one lies short of the edge by
about one sample spacing. Each edge of the region measures the samples' *depths* beyond a
reference curve (rad, larger is farther out) and adds one of these gaps to the outermost
depth. With samples of locally even density, ``lambda`` per radian of depth, the outermost
depths of a window behave like a Poisson process below the edge: the edge lies one mean
spacing ``1 / lambda`` beyond the first, and each estimator below is unbiased for that gap.

- :func:`line_gap` (the supported edge's margins, :func:`limbctl.region.shape.edge_margins`):
  the least-squares line through the order statistics, extrapolated to rank 0.
- :func:`spacing_gap` (the smooth edge's offsets, and the traced edge where a window has too
  few readings): the mean spacing of the order statistics.
- :func:`majorant_gap` (the traced edge): the gap between the upper concave majorant of the
  readings and the edge, from the residuals below the majorant.

All angles in radians.
"""

from __future__ import annotations

import numpy as np

#: Outermost depths an estimate reads: the spacing of 12 averages 11 gaps (relative noise about
#: 1 / sqrt(11), 30 %), few enough that they come from the band next to the edge.
ORDER_STATISTICS = 12
#: The majorant's expected gap to the edge in units of the ORDER_STATISTICS-th smallest residual
#: over ORDER_STATISTICS: below a straight edge, E[gap] = 1.85 / (rho 2h) and
#: E[r_(12) / 12] = 0.85 / (rho 2h) (simulated, 3000 draws each at 30 and 100 points per unit
#: depth; the tests check the estimate is unbiased).
MAJORANT_GAP = 2.19


def line_gap(depths: np.ndarray) -> float:
    """Gap (rad) beyond the outermost of ``depths`` (K,), sorted outermost first: the line fit.

    ``E[o_(i)] = edge - i g`` for ``i = 1 .. K``; the least-squares line ``o = c + s i``
    through ``(i, o_(i))`` gives the edge at ``i = 0``, ``c``, and the gap is
    ``max(c - o_(1), 0)``. 0 for fewer than 3 depths. Unbiased before the clip at 0; with 12
    depths the clip raises the mean by 13 % and the spread is three times the spacing's
    (4000 Poisson draws, ``tests/region/test_gaps.py``).
    """
    k = depths.size
    if k < 3:
        return 0.0
    i = np.arange(1, k + 1, dtype=np.float64)
    # slope and intercept of the least-squares line o = c + s i
    slope = np.sum((i - i.mean()) * (depths - depths.mean())) / np.sum((i - i.mean()) ** 2)
    intercept = depths.mean() - slope * i.mean()
    return max(float(intercept - depths[0]), 0.0)


def spacing_gap(depths: np.ndarray) -> float:
    """Gap (rad) beyond the outermost of ``depths`` (K,), sorted outermost first: the spacing.

    The outermost depths are evenly spaced on average, and the edge lies one spacing beyond
    the first: ``(o_(1) - o_(K)) / (K - 1)``. 0 for fewer than 3 depths.
    """
    k = depths.size
    return float((depths[0] - depths[-1]) / (k - 1)) if k >= 3 else 0.0


def majorant_gap(residuals: np.ndarray) -> float:
    """Gap (rad) between the upper concave majorant of readings and the edge.

    ``residuals`` (at least K) are the readings' distances below the majorant, smallest first
    (the two readings it passes through give 0); the gap is ``MAJORANT_GAP r_(K) / K`` with
    ``K = ORDER_STATISTICS``.
    """
    return float(MAJORANT_GAP * residuals[ORDER_STATISTICS - 1] / ORDER_STATISTICS)
