import numpy as np
import pytest

from limbctl.region import gaps


def test_line_gap_extrapolates_an_exact_line_and_spacing_gap_is_the_mean_spacing():
    assert gaps.line_gap(np.array([1.0, 0.9, 0.8, 0.7, 0.6])) == pytest.approx(0.1, abs=1e-12)
    # equal depths: no spacing, no gap; too few depths: none
    assert gaps.line_gap(np.array([1.0, 1.0, 1.0, 1.0])) == 0.0
    assert gaps.line_gap(np.array([1.0, 0.5])) == 0.0
    # the spacing gap is the mean spacing
    assert gaps.spacing_gap(np.array([1.0, 0.8, 0.6, 0.4])) == pytest.approx(0.2, abs=1e-12)
    assert gaps.spacing_gap(np.array([1.0, 0.5])) == 0.0


def test_order_statistic_gaps_below_an_edge():
    # the outermost point lies 1 / rate short of the edge on average
    rng = np.random.default_rng(0)
    rate = 50.0
    # the outermost Poisson points' depths: exponential gaps, mean 1 / rate
    draws = [-np.cumsum(rng.exponential(1.0 / rate, gaps.ORDER_STATISTICS)) for _ in range(4000)]
    shortfall = np.array([-d[0] for d in draws])
    assert shortfall.mean() * rate == pytest.approx(1.0, abs=0.05)
    # the mean spacing is unbiased: within 3 standard errors of 1 / rate
    spacing = np.array([gaps.spacing_gap(d) for d in draws]) * rate
    assert abs(spacing.mean() - 1.0) < 3.0 * spacing.std() / np.sqrt(len(draws))
    # the line's intercept is unbiased before its clip at 0, which adds 10-15 %
    line = np.array([gaps.line_gap(d) for d in draws]) * rate
    assert 1.10 < line.mean() < 1.15
    assert line.std() > 2.5 * spacing.std()


def majorant_at_zero(u: np.ndarray, o: np.ndarray) -> tuple[float, float]:
    """Brute force: the highest chord over pairs left and right of u = 0, at 0, and its slope."""
    best, slope = -np.inf, 0.0
    for i in np.flatnonzero(u < 0.0):
        for j in np.flatnonzero(u >= 0.0):
            s = (o[j] - o[i]) / (u[j] - u[i])
            at = o[i] - s * u[i]
            if at > best:
                best, slope = at, s
    return best, slope


def test_majorant_gap_puts_the_edge_estimate_on_the_edge():
    # uniform points below a straight edge at depth 0 over u in [-1, 1], 30 per unit depth
    rng = np.random.default_rng(1)
    per_depth = 30
    estimates = []
    for _ in range(600):
        n = rng.poisson(per_depth * 2)
        u, o = rng.uniform(-1.0, 1.0, n), -rng.uniform(0.0, 2.0, n)
        top = np.argsort(-o)[:40]
        at, slope = majorant_at_zero(u[top], o[top])
        residuals = np.sort(at + slope * u[top] - o[top])
        assert residuals[0] == pytest.approx(0.0, abs=1e-12)
        estimates.append(at + gaps.majorant_gap(residuals))
    estimates = np.array(estimates) * per_depth
    # in units of the spacing 1 / (rho 2h): centred on the edge within 3 standard errors
    assert abs(estimates.mean()) < 3.0 * estimates.std() / np.sqrt(len(estimates))
    assert gaps.majorant_gap(np.arange(20) * 0.1) == pytest.approx(gaps.MAJORANT_GAP * 1.1 / 12)
