"""The demo's excursion measure: a sampled held orientation bounds a goal's distance to the region
where ``correct``'s local search may stop short (limbctl/eval/twist_demo.py)."""

from __future__ import annotations

import math

import numpy as np

from limbctl.eval.twist_demo import nearest_held_nearby_deg, rotation_deg
from limbctl.geometry.quat import from_axis_angle

RADIUS_DEG = 20.0


class BallRegion:
    """Every orientation within RADIUS_DEG of the identity: its distance is known exactly."""

    def contains(self, q: np.ndarray) -> np.ndarray:
        q = np.atleast_2d(q)
        return rotation_deg(q, np.broadcast_to([1.0, 0.0, 0.0, 0.0], q.shape)) <= RADIUS_DEG


def goal_outside_by(deg: float, axis=(0.3, -0.5, 0.8)) -> np.ndarray:
    axis = np.asarray(axis) / np.linalg.norm(axis)
    return from_axis_angle(axis, np.radians(RADIUS_DEG + deg))


def test_the_sampled_bound_is_near_the_true_distance_and_never_under_it():
    for k, outside in enumerate((0.02, 0.07, 0.15)):
        # the bound handed in is what an early-stopping search might say: 0.1 deg too far
        found = nearest_held_nearby_deg(BallRegion(), goal_outside_by(outside), outside + 0.1, k)
        assert outside <= found + 1e-9  # an upper bound: the region holds that orientation
        assert found <= outside + 0.01


def test_with_nothing_held_within_the_radius_the_radius_is_returned():
    found = nearest_held_nearby_deg(BallRegion(), goal_outside_by(1.0), 0.5, seed=0)
    assert math.isclose(found, 0.5)
