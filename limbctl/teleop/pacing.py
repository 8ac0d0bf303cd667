"""The control loop's clock, and whether it keeps a felt leader's pace (:class:`PaceWatch`)."""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable

import numpy as np

#: Most periods a late loop catches up on (20 ms at 200 Hz): longer would burst old goals.
BACKLOG_PERIODS = 4
#: While felt, a median period over the last PACE_WINDOW cycles (0.2 s) above PACE_SLACK periods
#: (160 Hz at 200 Hz, passivity margin still 1.4) switches the push off for good.
PACE_WINDOW = 40
PACE_SLACK = 1.25


class Pacer:
    """The schedule of a loop of period ``period_s`` (s); ``overruns`` counts late spells."""

    def __init__(self, period_s: float, clock: Callable[[], float] = time.perf_counter) -> None:
        self.period_s = float(period_s)
        self.clock = clock
        self.overruns = 0
        self._due = 0.0
        self._late = False

    def start(self, now: float) -> None:
        """Slot 0 is ``now`` (the loop's start)."""
        self._due = now

    def wait(
        self,
        stop: threading.Event,
        idle: Callable[[], None] | None = None,
        idle_period_s: float = 0.001,
    ) -> None:
        """Wait for the next slot (at once when late or ``stop`` is set), calling ``idle`` every
        ``idle_period_s`` meanwhile (1 ms: the snap watch must see a let go within ~2 ms)."""
        self._due += self.period_s
        now = self.clock()
        delay = self._due - now
        if idle is not None:
            # a call starts only while more than a period and the last call's time are left
            call_at, took = now, 0.0
            while self._due - call_at > max(idle_period_s, took) and not stop.is_set():
                if call_at > now and stop.wait(call_at - now):
                    break
                started = self.clock()
                idle()
                now = self.clock()
                took = now - started
                call_at = max(call_at + idle_period_s, now)
            delay = self._due - self.clock()
        if delay > 0.0:
            stop.wait(delay)
        elif delay < -BACKLOG_PERIODS * self.period_s:
            self.overruns += 1
            self._due = now
        elif delay < -self.period_s and not self._late:
            self.overruns += 1  # once per late spell, not for each cycle that catches up
        self._late = delay < -self.period_s


class PaceWatch:
    """Whether the loop keeps the rate ``rate_hz`` (Hz) the wall was made passive for."""

    def __init__(self, rate_hz: float, clock: Callable[[], float] = time.perf_counter) -> None:
        self.limit_s = PACE_SLACK / rate_hz
        self.clock = clock
        self._last: float | None = None
        self._periods: deque[float] = deque(maxlen=PACE_WINDOW)

    def lost(self) -> float | None:
        """Count a cycle now; the median period (s) once it is over the limit, else None."""
        now = self.clock()
        if self._last is not None:
            self._periods.append(now - self._last)
        self._last = now
        if len(self._periods) < PACE_WINDOW:
            return None
        median = float(np.median(self._periods))
        return median if median > self.limit_s else None
