"""The scene feeder's schedule: when the next fit may start."""

from __future__ import annotations

import time
from contextlib import contextmanager

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


@contextmanager
def fit_left_waiting(monkeypatch):
    """A feeder whose first fit is done and collected, the next left waiting for a refit
    period that outlasts the first fit (its process start included) by 0.2 s; yields the
    feeder and the monotonic times just before and after the first fit was started, and the
    period."""
    feeder = SceneFeeder(Board(), GrowingSamples())
    try:
        before = time.monotonic()
        feeder.publish_once()  # starts the fit process and the first fit
        after = time.monotonic()
        assert feeder._fits is not None and feeder._fits.wait(120.0), "the first fit never ended"
        period = time.monotonic() - before + 0.2
        monkeypatch.setattr(feed, "REFIT_PERIOD_S", period)
        feeder.publish_once()  # collects the fit; the next waits for the period
        assert feeder.fits_done == 1 and not feeder._fits.busy
        yield feeder, before, after, period
    finally:
        feeder.__exit__(None, None, None)


def test_a_fit_done_before_the_refit_period_is_over_is_followed_when_it_is(monkeypatch):
    with fit_left_waiting(monkeypatch) as (feeder, before, after, period):
        # wakes when the period since the fit's start is over, before the next scene
        scene_due = after + period + 1.0
        assert before + period <= feeder.wake_time(scene_due) <= after + period


def test_a_refit_due_already_starts_at_once_not_a_scene_later(monkeypatch):
    # the race that left redraws 0.5 s apart: the period ended between the collect and the
    # wait; the wake time is then in the past, so the feeder does not wait
    with fit_left_waiting(monkeypatch) as (feeder, _, _, _):
        monkeypatch.setattr(feed, "REFIT_PERIOD_S", 0.0)  # the period is over
        now = time.monotonic()
        assert feeder.wake_time(now + SCENE_PERIOD_S) < now
        feeder.publish_once()  # and the next fit starts
        assert feeder._fits.busy


def test_without_fits_the_feeder_wakes_for_the_next_scene_only():
    feeder = SceneFeeder(Board(), GrowingSamples(), fit=False)
    feeder.publish_once()
    due = time.monotonic() + SCENE_PERIOD_S
    assert feeder.wake_time(due) == due
    feeder.__exit__(None, None, None)
