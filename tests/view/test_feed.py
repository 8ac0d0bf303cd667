"""The scene feeder's schedule: when the next fit may start."""

from __future__ import annotations

import time

import numpy as np

from limbctl.view import Board
from limbctl.view.feed import REFIT_PERIOD_S, SCENE_PERIOD_S, SceneFeeder
from limbctl.view.region import MIN_FIT_SAMPLES


def _samples() -> np.ndarray:
    """Joint angles (N, 2) rad filling a 20 deg disc: enough for a fit."""
    rng = np.random.default_rng(0)
    r = np.radians(20.0) * np.sqrt(rng.uniform(0.0, 1.0, MIN_FIT_SAMPLES + 100))
    a = rng.uniform(-np.pi, np.pi, r.size)
    return np.column_stack([r * np.cos(a), r * np.sin(a)])


def test_a_fast_fit_is_followed_by_the_next_when_the_refit_period_is_over():
    samples = _samples()
    feeder = SceneFeeder(Board(), lambda: samples)
    try:
        before = time.monotonic()
        feeder.publish_once()  # starts the fit process and the first fit
        after = time.monotonic()
        scene_due = after + SCENE_PERIOD_S
        # idle right after the start: wake when REFIT_PERIOD_S is over, not a scene later
        wake = feeder.wake_time(after, scene_due)
        assert before + REFIT_PERIOD_S <= wake <= after + REFIT_PERIOD_S < scene_due
        # once the period is over nothing is gained by waking early: the next scene
        assert feeder.wake_time(after + REFIT_PERIOD_S, scene_due) == scene_due
    finally:
        feeder.__exit__(None, None, None)


def test_without_fits_the_feeder_wakes_for_the_next_scene_only():
    samples = _samples()
    feeder = SceneFeeder(Board(), lambda: samples, fit=False)
    feeder.publish_once()
    now = time.monotonic()
    assert feeder.wake_time(now, now + SCENE_PERIOD_S) == now + SCENE_PERIOD_S
    feeder.__exit__(None, None, None)
