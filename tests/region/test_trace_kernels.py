import numpy as np
import pytest

from limbctl.envelope.synthetic import ConeRegion
from limbctl.region.edge_traced import edge_estimate, readings, station_estimates
from limbctl.region.loops import StationBuckets, resample_loop, signed_offset, station_positions
from tests.region.support import circle


def station_estimates_reference(s, total, owner, depth, reach):
    """:func:`station_estimates` in numpy, station by station."""
    buckets = StationBuckets(owner, s.shape[0])
    move = np.zeros(s.shape[0])
    for i in range(s.shape[0]):
        rows = buckets.around(i, reach)
        if rows.size:
            u = signed_offset(s[owner[rows]], s[i], total)
            move[i] = edge_estimate(u, depth[rows])
    return move


@pytest.mark.parametrize(
    ("seed", "radius_deg", "reach", "quarter"),
    [(4, 18.5, 1, False), (4, 18.5, 3, False), (4, 18.5, 8, False), (4, 18.5, 40, False)]
    + [(5, 19.0, 2, True)],
)
def test_the_kernel_gives_the_numpy_loops_estimates_to_the_bit(seed, radius_deg, reach, quarter):
    # windows from a few readings to wider than half the loop (reach 40); with readings on a
    # quarter of the stations, empty windows give 0 and one-sided ones the spacing estimate
    data = ConeRegion(np.radians(20.0)).sample(3000, np.random.default_rng(seed))
    if quarter:
        data = data[(data[:, 1] > 0.0) & (data[:, 2] > 0.0)]
    curve, _, _ = resample_loop(circle(radius_deg, 90), np.radians(1.5))
    s, total = station_positions(curve)
    owner, depth = readings(curve, data)
    fast = station_estimates(s, total, owner, depth, reach)
    assert np.array_equal(fast, station_estimates_reference(s, total, owner, depth, reach))
    assert np.all(np.isfinite(fast)) and np.any(fast != 0.0)
    assert not quarter or np.any(fast == 0.0)
