import math

from limbctl.teach.coverage import CoverageMap


def test_counts_cells_spread_and_picture():
    cov = CoverageMap(cols=10, rows=4)
    for pan_deg in (-170, -10, 10, 170):
        cov.add(math.radians(pan_deg), 0.0)
    cov.add(math.radians(10), math.radians(80))
    assert cov.samples == 5
    assert cov.cells_visited() == 5
    lines = cov.render()
    assert len(lines) == 4 + 2
    grid = lines[1:-1]
    assert all(len(row) == 12 for row in grid)
    # +170 pan is drawn at the left (seen from behind the limb, +y is left)
    assert grid[2][1] != " " and grid[2][10] != " "
    # every sample within 180 deg of the mean direction; four of them level around the circle
    assert 0.0 < cov.spread_deg() <= 180.0


def test_spread_of_one_direction_is_zero():
    cov = CoverageMap()
    for _ in range(3):
        cov.add(0.2, 0.1)
    assert cov.spread_deg() < 1e-6
