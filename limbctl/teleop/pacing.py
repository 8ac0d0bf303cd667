"""The control loop's clock: when each cycle starts, and which cycles were late.

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
from collections.abc import Callable

#: Most periods a late loop catches up on (20 ms at 200 Hz) before it gives up those slots and
#: starts afresh: a stall of a few periods (a moment of load, a garbage collection) is made up
#: by back-to-back cycles; a longer one would only send a burst of goals that are already old.
BACKLOG_PERIODS = 4


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

    def wait(self, stop: threading.Event) -> None:
        """Wait for the next slot (returns at once when late, or when ``stop`` is set)."""
        self._due += self.period_s
        now = self.clock()
        delay = self._due - now
        if delay > 0.0:
            stop.wait(delay)
        elif delay < -BACKLOG_PERIODS * self.period_s:
            self.overruns += 1
            self._due = now
        elif delay < -self.period_s and not self._late:
            self.overruns += 1  # once per late spell, not for each cycle that catches up
        self._late = delay < -self.period_s
