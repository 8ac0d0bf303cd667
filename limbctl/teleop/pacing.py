"""The control loop's clock: when each cycle starts, which cycles were late, and whether the
loop keeps the pace a felt leader's wall needs (:class:`PaceWatch`).

Cycle ``k`` is due at ``t0 + k T`` (T = 1 / rate). After a cycle the loop waits for the next
slot; a cycle that ran late is followed at once by the next (no wait), so the loop catches up
and keeps its rate on average instead of losing the slot::

    delay = due_k - now
    delay > 0:                    wait delay
    -BACKLOG T <= delay <= 0:     no wait (catch up); a spell late by more than T is an overrun
    delay < -BACKLOG T:           an overrun; the schedule starts afresh from now (slots lost)

Late cycles are run back to back, each still one slot of the schedule: the gate's slew limit
per cycle and a felt leader's wall (updated more often, never less) are unchanged over the
backlog's span. docs/decisions/haptic.md has the measurement that made the loop catch up.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable

import numpy as np

#: Most periods a late loop catches up on (20 ms at 200 Hz) before it gives up those slots and
#: starts afresh: a stall of a few periods (a moment of load, a garbage collection) is made up
#: by back-to-back cycles; a longer one would only send a burst of goals that are already old.
BACKLOG_PERIODS = 4
#: While felt, the loop's pace is watched over the last PACE_WINDOW cycles (0.2 s at 200 Hz):
#: a median period over PACE_SLACK periods (160 Hz at 200 Hz) switches the push off for good.
#: The wall's passivity margin at 200 Hz is 1.75 (haptic.FeelLaw); at 160 Hz it is 1.4.
PACE_WINDOW = 40
PACE_SLACK = 1.25


class Pacer:
    """The schedule of a loop of period ``period_s``.

    Parameters
    ----------
    period_s : float
        T (s).
    clock : callable
        Seconds, monotonic (``time.perf_counter``).

    Attributes
    ----------
    overruns : int
        Spells of cycles that started more than one period after their slots (one for each
        stall, however many cycles it took to catch up).
    """

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
        """Wait for the next slot (returns at once when late, or when ``stop`` is set); with
        ``idle``, call it every ``idle_period_s`` while waiting, the last call starting at least
        ``idle_period_s`` before the slot. 1 ms: a felt leader's snap watch
        (:mod:`limbctl.teleop.snap`) must see a let go within about 2 ms of it, its read and
        write included (docs/bench_let_go.md's oracle)."""
        self._due += self.period_s
        now = self.clock()
        delay = self._due - now
        if idle is not None:
            # a call every idle_period_s from now, each starting only while more than a period,
            # and more than the last call took, is left before the slot (on a slow bus the
            # work waits for the next wait rather than delay the cycle); a call that ran long
            # is followed by the next at once, not by more
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
    """Whether the loop keeps the rate the wall needs: the median of the last PACE_WINDOW
    periods between calls of :meth:`lost`, against PACE_SLACK periods.

    Parameters
    ----------
    rate_hz : float
        The rate the wall was made passive for (Hz).
    clock : callable
        Seconds, monotonic (``time.perf_counter``).
    """

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
