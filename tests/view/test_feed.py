"""The scene feeder's schedule: when the next fit may start."""

from __future__ import annotations

import time

import numpy as np

from limbctl.view import Board, feed
from limbctl.view.feed import SCENE_PERIOD_S, SceneFeeder
from limbctl.view.region import MIN_FIT_SAMPLES


class GrowingSamples:
    """Joint angles (N, 2) rad filling a 20 deg disc, ten more each time they are read."""

    def __init__(self) -> None:
        rng = np.random.default_rng(0)
        r = np.radians(20.0) * np.sqrt(rng.uniform(0.0, 1.0, 10 * MIN_FIT_SAMPLES))
        a = rng.uniform(-np.pi, np.pi, r.size)
        self._all = np.column_stack([r * np.cos(a), r * np.sin(a)])
        self._count = MIN_FIT_SAMPLES

    def __call__(self) -> np.ndarray:
        self._count += 10
        return self._all[: self._count]


def test_a_refit_waits_out_its_period_and_starts_at_once_and_without_fits_only_scenes_wake(
    monkeypatch,
):
    """The feeder wakes when the refit period is over; a refit already due starts at once (the
    race that left redraws 0.5 s apart: the period ended between the collect and the wait)."""
    feeder = SceneFeeder(Board(), GrowingSamples())
    try:
        before = time.monotonic()
        feeder.publish_once()  # starts the fit process and the first fit
        after = time.monotonic()
        assert feeder._fits is not None and feeder._fits.wait(120.0), "the first fit never ended"
        # a period that outlasts the first fit (its process start included) by 0.2 s
        period = time.monotonic() - before + 0.2
        monkeypatch.setattr(feed, "REFIT_PERIOD_S", period)
        feeder.publish_once()  # collects the fit; the next waits for the period
        assert feeder.fits_done == 1 and not feeder._fits.busy
        scene_due = after + period + 1.0
        assert before + period <= feeder.wake_time(scene_due) <= after + period, "not woken then"
        monkeypatch.setattr(feed, "REFIT_PERIOD_S", 0.0)  # the period is over
        now = time.monotonic()
        assert feeder.wake_time(now + SCENE_PERIOD_S) < now, "a due refit waits for a scene"
        feeder.publish_once()
        assert feeder._fits.busy, "the due refit did not start"
    finally:
        feeder.__exit__(None, None, None)
    # without fits the feeder wakes for the next scene only
    feeder = SceneFeeder(Board(), GrowingSamples(), fit=False)
    feeder.publish_once()
    due = time.monotonic() + SCENE_PERIOD_S
    assert feeder.wake_time(due) == due
    feeder.__exit__(None, None, None)
