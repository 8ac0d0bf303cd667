"""The region the view draws: traced stretches and the fitted outline (a record watched on the
page: tests/test_live.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from limbctl.envelope import RigidMap
from limbctl.geometry.gimbal import pan_tilt_to_direction
from limbctl.geometry.quat import limb_direction, swing_from_direction
from limbctl.teach.dataset import load_dataset
from limbctl.view.region import TRACED_WITHIN_DEG, fit_outline, model_loops, region_loops


def ring(radius_deg: float, angles: np.ndarray) -> np.ndarray:
    """Directions (N, 3) on a circle of ``radius_deg`` around the rest direction +x."""
    radius = np.radians(radius_deg)
    return pan_tilt_to_direction(radius * np.cos(angles), radius * np.sin(angles))


def test_stretches_without_a_sample_nearby_are_untraced():
    """A circular edge traced all round but for a 90 deg gap on the right."""
    loop = ring(20.0, np.linspace(0.0, 2.0 * np.pi, 72, endpoint=False))
    edges = np.column_stack([np.arange(72), np.roll(np.arange(72), -1)])
    taught = np.random.default_rng(0).uniform(np.pi / 4, 7 * np.pi / 4, 3000)
    (outline,) = region_loops(loop, edges, ring(20.0, taught))
    angle = np.arctan2(outline.pan_tilt_deg[:, 1], outline.pan_tilt_deg[:, 0])
    following = np.roll(angle, -1)
    middle = np.angle(np.exp(1j * angle) + np.exp(1j * following))
    # a sample within TRACED_WITHIN_DEG reaches this far (rad of the circle's angle) into the gap
    reach = 1.1 * TRACED_WITHIN_DEG / 20.0
    in_gap = np.abs(middle) < np.pi / 4 - reach
    beyond = np.abs(middle) > np.pi / 4 + np.radians(1.0)
    assert not outline.traced[in_gap].any()
    assert outline.traced[beyond].all()
    # traced: all but the gap less what the samples at its ends reach
    expected = 1.0 - (np.pi / 2 - 2.0 * TRACED_WITHIN_DEG / 20.0) / (2.0 * np.pi)
    assert abs(outline.traced.mean() - expected) < 0.03
    # a loaded model (no samples): every stretch counts as traced
    (plain,) = region_loops(loop, edges, None)
    assert plain.traced.all()


def test_fit_outline_outlines_a_taught_disc_and_the_default_rigid_maps_region():
    rng = np.random.default_rng(0)
    radius = np.radians(20.0) * np.sqrt(rng.uniform(0.0, 1.0, 3000))
    angle = rng.uniform(0.0, 2.0 * np.pi, 3000)
    fit = fit_outline(np.column_stack([radius * np.cos(angle), radius * np.sin(angle)]))
    assert len(fit.loops) == 1 and not fit.problem, fit.note
    (outline,) = fit.loops
    distance = np.hypot(outline.pan_tilt_deg[:, 0], outline.pan_tilt_deg[:, 1])
    assert np.all((distance > 17.0) & (distance < 23.0))
    assert outline.traced.mean() > 0.95
    assert fit.note.startswith("fitted on 3000 samples")
    too_few = fit_outline(np.zeros((10, 2)))
    assert not too_few.loops and "need 200 samples" in too_few.note
    # the view fits the region alone: it is the one a default RigidMap's gate enforces
    data = load_dataset(Path(__file__).parents[1] / "data" / "hand_irregular_seed0_20s.limb")
    pan_tilt = np.radians(np.column_stack([data.pan_deg, data.tilt_deg]))
    fit = fit_outline(pan_tilt)
    directions = pan_tilt_to_direction(pan_tilt[:, 0], pan_tilt[:, 1])
    model = RigidMap().fit(swing_from_direction(directions))
    expected = model_loops(model, limb_direction(swing_from_direction(directions)))
    assert fit.edge == model.edge and len(fit.loops) == len(expected) > 0
    for drawn, learned in zip(fit.loops, expected, strict=True):
        np.testing.assert_array_equal(drawn.pan_tilt_deg, learned.pan_tilt_deg)
        np.testing.assert_array_equal(drawn.traced, learned.traced)
