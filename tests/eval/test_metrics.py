"""Metric functions against hand-computed cases."""

from __future__ import annotations

import math

import numpy as np
import pytest

from limbctl.errors import ConfigError
from limbctl.eval import metrics

IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])
#: 90 degrees about +z: the limb turns from +x to +y.
QUARTER_Z = np.array([math.cos(math.pi / 4), 0.0, 0.0, math.sin(math.pi / 4)])


def test_quaternion_endpoint_angle_and_unchanged_by_hand():
    answer = np.array([IDENTITY, [0.0, 0.0, 0.0, 1.0]])
    ideal = np.array([[0.6, 0.8, 0.0, 0.0], [0.0, 0.0, 0.0, -1.0]])
    # |(1,0,0,0) - (0.6,0.8,0,0)|^2 = 0.16 + 0.64; the second pair is q and -q: no error
    np.testing.assert_allclose(metrics.quaternion_sq_error(answer, ideal), [0.8, 0.0], atol=1e-15)
    answer = np.array([IDENTITY, QUARTER_Z])
    ideal = np.array([QUARTER_Z, QUARTER_Z])
    # limb +x vs +y: the end points are sqrt(2) apart, 90 degrees
    np.testing.assert_allclose(
        metrics.endpoint_error(answer, ideal), [math.sqrt(2.0), 0.0], atol=1e-12
    )
    np.testing.assert_allclose(metrics.direction_error_deg(answer, ideal), [90.0, 0.0], atol=1e-9)

    # unchanged uses the rotation angle's tolerance
    def about_x(angle):
        return [math.cos(angle / 2), math.sin(angle / 2), 0.0, 0.0]

    q = np.array([IDENTITY, IDENTITY, IDENTITY])
    answer = np.array([IDENTITY, about_x(1e-7), about_x(1e-3)])
    assert metrics.unchanged(answer, q).tolist() == [True, True, False]


def test_score_splits_valid_and_invalid_by_hand():
    q = np.array([IDENTITY, IDENTITY, IDENTITY, QUARTER_Z])
    ideal = q.copy()
    answer = np.array([IDENTITY, IDENTITY, QUARTER_Z, QUARTER_Z])
    valid = np.array([True, True, False, False])
    inside = np.array([True, True, False, True])
    outside = np.array([0.0, 0.0, 2.0, 0.0])
    s = metrics.score(q, answer, ideal, valid, inside, outside)
    quarter_sq = 2.0 - math.sqrt(2.0)  # |identity - quarter|^2 = 2 - 2 cos(45 deg)
    assert s["all"]["n"] == 4
    assert s["all"]["mse"] == pytest.approx(quarter_sq / 4)
    assert s["all"]["err3d_rms"] == pytest.approx(math.sqrt(2.0 / 4))
    assert s["all"]["angle_mean_deg"] == pytest.approx(22.5)
    # 95th percentile of [0, 0, 0, 90] by linear interpolation: position 2.85 -> 0.85 * 90
    assert s["all"]["angle_p95_deg"] == pytest.approx(76.5)
    assert s["all"]["unchanged_share"] == pytest.approx(0.75)
    assert s["all"]["inside_share"] == pytest.approx(0.75)
    assert s["all"]["outside_p95_deg"] == pytest.approx(0.85 * 2.0)
    errors = ("mse", "err3d_rms", "angle_mean_deg", "angle_p95_deg", "outside_p95_deg")
    shares = {"n": 2.0, "unchanged_share": 1.0, "inside_share": 1.0}
    assert s["valid"] == shares | dict.fromkeys(errors, 0.0)
    assert s["invalid"]["mse"] == pytest.approx(quarter_sq / 2)
    assert s["invalid"]["angle_p95_deg"] == pytest.approx(85.5)
    assert s["invalid"]["unchanged_share"] == pytest.approx(0.5)
    assert s["invalid"]["inside_share"] == pytest.approx(0.5)
    assert s["invalid"]["outside_p95_deg"] == pytest.approx(0.95 * 2.0)


def test_an_empty_subset_is_nan_mismatched_shapes_are_refused_and_mean_and_spread():
    q = np.array([IDENTITY])
    s = metrics.score(q, q, q, np.array([True]), np.array([True]))
    assert s["invalid"]["n"] == 0
    assert all(math.isnan(s["invalid"][m]) for m in metrics.METRIC_NAMES[1:])
    # a shape mismatch is refused with the shapes
    with pytest.raises(ConfigError, match=r"\(2, 4\) and \(1, 4\)"):
        metrics.quaternion_sq_error(np.zeros((2, 4)), np.zeros((1, 4)))
    q = np.array([IDENTITY])
    with pytest.raises(ConfigError, match="one entry per row"):
        metrics.score(q, q, q, np.array([True, False]), np.array([True]))
    with pytest.raises(ConfigError, match="outside_deg"):
        metrics.score(q, q, q, np.array([True]), np.array([True]), np.zeros(3))
    # mean and spread, nan skipped
    assert metrics.mean_and_spread([1.0, 2.0, 3.0]) == pytest.approx((2.0, 1.0))
    assert metrics.mean_and_spread([5.0]) == (5.0, 0.0)
    assert metrics.mean_and_spread([math.nan, 1.0, 3.0]) == pytest.approx((2.0, math.sqrt(2.0)))
    assert all(math.isnan(v) for v in metrics.mean_and_spread([math.nan]))
