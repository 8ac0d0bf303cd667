"""Region shapes the scripted hand moves in: containment, depth, boundary parametrisation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from firmware_sim.regions import (
    DEEPEN_TOLERANCE_DEG,
    ConeRegion,
    PolygonRegion,
    deepen,
    grid_inside,
    region_from_mapping,
)

SQUARE = [[-10.0, -10.0], [10.0, -10.0], [10.0, 10.0], [-10.0, 10.0]]


@pytest.mark.parametrize("vertices", [SQUARE, SQUARE[::-1], [*SQUARE, SQUARE[0]]])
def test_square_depth_contains_and_centre(vertices):
    square = PolygonRegion(vertices)
    pan = np.array([0.0, 5.0, 9.0, 10.0, 12.0, 0.0, 13.0])
    tilt = np.array([0.0, 0.0, 2.0, 3.0, 0.0, -14.0, 14.0])
    expected = [10.0, 5.0, 1.0, 0.0, -2.0, -4.0, -5.0]
    assert square.edge_distance_deg(pan, tilt) == pytest.approx(expected)
    assert [square.contains(p, t) for p, t in zip(pan, tilt, strict=True)] == [
        True, True, True, True, False, False, False
    ]  # fmt: skip
    assert square.center_deg == pytest.approx((0.0, 0.0))
    assert square.depth_max_deg == pytest.approx(10.0)
    assert square.perimeter_deg == pytest.approx(80.0)
    assert square.area_deg2 == pytest.approx(400.0)


@pytest.mark.parametrize(
    "region", [PolygonRegion(SQUARE), ConeRegion(30.0), PolygonRegion([[0, 0], [50, 10], [5, 40]])]
)
def test_boundary_point_and_fraction_are_inverse(region):
    for u in np.linspace(0.0, 1.0, 37)[:-1] + 0.004:
        pan, tilt = region.boundary_point(u, 0.0)
        assert region.edge_distance_deg(pan, tilt) == pytest.approx(0.0, abs=1e-9)
        assert float(region.boundary_fraction(pan, tilt)) == pytest.approx(u, abs=1e-9)
        inset = region.boundary_point(u, 1.5)
        depth = float(region.edge_distance_deg(*inset))
        # 1.5 deg inward; nearer a corner the next edge is closer (at a sharp one, even outside)
        corners = getattr(region, "vertices_deg", np.empty((0, 2)))
        if np.all(np.hypot(*(corners - [pan, tilt]).T) > 5.0):
            assert depth == pytest.approx(1.5, abs=1e-6)
        else:
            assert depth <= 1.5 + 1e-9


def test_shapes_a_cone_by_angle_a_notch_a_grid_and_deepening_round_a_reflex_corner():
    assert region_from_mapping({"cone": {"half_angle_deg": 45}}).half_angle_deg == 45.0
    assert region_from_mapping({"polygon": SQUARE}).kind == "polygon"
    with pytest.raises(ValueError, match="source.yaml: unknown key"):
        region_from_mapping({"circle": 3}, "source.yaml")
    with pytest.raises(ValueError, match="repeats the next vertex"):
        PolygonRegion([[0, 0], [0, 0], [1, 0], [0, 1]])
    notched = PolygonRegion([[-10, -10], [10, -10], [10, 10], [0, 0], [-10, 10]])
    assert notched.contains(0.0, -5.0)
    assert not notched.contains(0.0, 5.0)  # inside the notch
    assert notched.contains(8.0, 5.0) and notched.contains(-8.0, 5.0)
    square = PolygonRegion([[0, 0], [10, 0], [10, 10], [0, 10]])
    poses = grid_inside(square, step_deg=1.0, min_depth_deg=2.0)
    assert len(poses) == 7 * 7  # 2..8 on both axes
    assert poses.min(axis=0) == pytest.approx([2.0, 2.0])
    assert poses.max(axis=0) == pytest.approx([8.0, 8.0])
    cone = grid_inside(ConeRegion(30.0), step_deg=2.0, min_depth_deg=5.0)
    assert np.all(ConeRegion(30.0).edge_distance_deg(cone[:, 0], cone[:, 1]) >= 5.0)
    assert len(cone) > 100
    ell = PolygonRegion([[0, 0], [20, 0], [20, 10], [10, 10], [10, 20], [0, 20]])
    points = np.array([[5.0, 0.0], [15.0, 9.5], [5.0, 5.0], [9.6, 9.6]])
    deep = deepen(ell, points, np.array([1.0, 1.0, 1.0, 1.0]))
    depth = ell.edge_distance_deg(deep[:, 0], deep[:, 1])
    assert depth == pytest.approx([1.0, 1.0, 5.0, 1.0], abs=DEEPEN_TOLERANCE_DEG)
    assert deep[0] == pytest.approx([5.0, 1.0])  # straight in from a side
    assert deep[2] == pytest.approx([5.0, 5.0])  # deep enough already: untouched
    # by the reflex corner (10, 10): moved away from the corner itself, onto the 1 deg arc
    assert np.hypot(*(deep[3] - [10.0, 10.0])) == pytest.approx(1.0, abs=DEEPEN_TOLERANCE_DEG)
    assert np.all(points[1] == [15.0, 9.5])  # the input is not changed
    cone = ConeRegion(30.0)
    rng = np.random.default_rng(0)
    pan, tilt = rng.uniform(-60, 60, 500), rng.uniform(-60, 60, 500)
    d = np.stack([np.cos(np.radians(tilt)) * np.cos(np.radians(pan)),
                  np.cos(np.radians(tilt)) * np.sin(np.radians(pan)),
                  np.sin(np.radians(tilt))], axis=1)  # fmt: skip
    angle = np.degrees(np.arccos(np.clip(d[:, 0], -1, 1)))
    assert cone.contains_many(pan, tilt).tolist() == (angle <= 30.0).tolist()
    assert cone.edge_distance_deg(pan, tilt) == pytest.approx(30.0 - angle)
    assert cone.perimeter_deg == pytest.approx(360.0 * math.sin(math.radians(30.0)))
