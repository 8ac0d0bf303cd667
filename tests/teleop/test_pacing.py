"""The loop's clock (limbctl/teleop/pacing.py) on a stepped clock: a late loop catches up; the
felt leader's pace watch switches its feel off once the median period is too long."""

from __future__ import annotations

import threading

import pytest

from limbctl.teleop.pacing import BACKLOG_PERIODS, Pacer, PaceWatch
from tests.conftest import SteppedClock

PERIOD = 0.005


class SteppedStop(threading.Event):
    """``wait`` moves the stepped clock instead of sleeping, and keeps each ``timeout``."""

    def __init__(self, clock: SteppedClock) -> None:
        super().__init__()
        self.clock, self.waits = clock, []

    def wait(self, timeout: float | None = None) -> bool:
        self.waits.append(timeout)
        self.clock.t += timeout or 0.0
        return False


def run(cycle_s: list[float], idle_s: float | None = None):
    """Cycles that take ``cycle_s`` (s) each, waiting for their slot with idle work of ``idle_s``
    (s) asked for every millisecond (None: no idle work): the pacer, each cycle's start, the
    idle work's calls (clock s) and the stop's waits (s)."""
    clock = SteppedClock()
    pacer, stop = Pacer(PERIOD, clock), SteppedStop(clock)
    pacer.start(clock.t)
    starts: list[float] = []
    calls: list[float] = []

    def idle() -> None:
        calls.append(clock.t)
        clock.t += idle_s

    for work in cycle_s:
        starts.append(clock.t)
        clock.t += work
        if idle_s is None:
            pacer.wait(stop)
        else:
            pacer.wait(stop, idle, 0.001)
    return pacer, starts, calls, stop.waits


def test_cycles_start_on_their_slots_a_short_stall_is_caught_up_a_long_one_starts_afresh():
    """On time: every cycle on its slot; a few periods late: caught up; longer: a new schedule."""
    pacer, starts, _, _ = run([0.001] * 100)
    assert all(abs(start - k * PERIOD) < 1e-9 for k, start in enumerate(starts))
    assert pacer.overruns == 0
    work = [0.001] * 200
    work[50] = 3.5 * PERIOD  # one cycle stalls 17.5 ms
    pacer, starts, _, _ = run(work)
    # after the stall the cycles run back to back until they are on their slots again
    assert abs(starts[-1] - 199 * PERIOD) < 1e-9
    assert pacer.overruns >= 1
    work[50] = (BACKLOG_PERIODS + 2) * PERIOD
    pacer, starts, _, _ = run(work)
    # the schedule restarted after the stall: the last cycle starts later than slot 199
    assert starts[-1] > 199 * PERIOD + PERIOD
    assert pacer.overruns == 1


def test_idle_work_runs_about_every_period_while_waiting_and_the_slot_is_kept():
    """Idle work runs a millisecond apart between the cycles; slower work never delays one."""
    pacer, starts, calls, _ = run([0.0015] * 20, 0.0003)  # a read of the leader's speed
    # each cycle's start stays on its slot; in the 3.5 ms left after the work, the watch runs
    # from right after the cycle, a millisecond apart, and ends a millisecond before the slot
    assert all(abs(start - k * PERIOD) < 1e-9 for k, start in enumerate(starts))
    per_cycle = [[c for c in calls if k * PERIOD < c < (k + 1) * PERIOD] for k in range(20)]
    assert all(len(cycle) == 3 for cycle in per_cycle)
    gaps = [b - a for cycle in per_cycle for a, b in zip(cycle, cycle[1:], strict=False)]
    assert all(abs(gap - 0.001) < 1e-9 for gap in gaps)
    assert all(
        slot_end - cycle[-1] >= 0.001
        for slot_end, cycle in zip([(k + 1) * PERIOD for k in range(20)], per_cycle, strict=True)
    )
    assert pacer.overruns == 0
    # a slow bus: each call takes 2.5 ms. After the 1.5 ms cycle it runs once (3.5 ms left), not
    # again with 1 ms left: the cycle starts on its slot
    pacer, starts, calls, _ = run([0.0015] * 10, 0.0025)
    assert all(abs(start - k * PERIOD) < 1e-9 for k, start in enumerate(starts))
    assert len(calls) == 10 and pacer.overruns == 0
    # without idle work the wait is one wait
    assert run([0.0015])[3] == [PERIOD - 0.0015]


def test_the_pace_watch_switches_the_feel_off_when_the_median_period_is_over_1_25_periods():
    ticks = iter([0.005 * k for k in range(41)] + [0.2 + 0.0066 * k for k in range(1, 100)])
    watch = PaceWatch(200.0, clock=lambda: next(ticks))
    # 200 Hz for 40 periods: kept; then 151 Hz (6.6 ms > 6.25 ms): lost once the median passes
    assert [watch.lost() for _ in range(41)] == [None] * 41
    verdicts = [watch.lost() for _ in range(99)]
    first = next(k for k, v in enumerate(verdicts) if v is not None)
    assert 15 <= first <= 25 and verdicts[first] == pytest.approx(0.0066)
    assert all(v is None for v in verdicts[:first])
    # a late cycle or a few do not: the median ignores them
    ticks = iter([0.005 * k + (0.03 if k >= 20 else 0.0) for k in range(60)])
    watch = PaceWatch(200.0, clock=lambda: next(ticks))
    assert all(watch.lost() is None for _ in range(60))
