"""The felt-leader pty tests' loop runner (:class:`Running`): waits on what the loop did and
judges the wall only where it kept its pace; a run that lost it asserts that outcome instead."""

from __future__ import annotations

import re
import threading
import time

import numpy as np

from limbctl.servo.health import HealthLimits
from limbctl.teleop.gate import Outcome
from limbctl.teleop.loop import LoopConfig, run
from limbctl.teleop.sources.leader import FOLLOWER_GRACE_S, FOLLOWER_UNREAD

#: The notice of a lost pace (``LeaderSource._check_pace`` and ``_lose_feel``).
PACE_LOST = re.compile(
    r"the loop runs at (\d+) Hz, under the ([\d.]+) Hz the leader's wall needs to stay passive: "
    r"the push is off, mirroring goes on without feel"
)


#: A follower lost after 5 s of silence, not 0.5: a loaded machine's simulator fell silent for
#: 0.51-0.59 s now and then (the rule itself: tests/servo/test_health.py, tests/safety/).
SIM_STARVED_HEALTH = HealthLimits(lost_after_s=5.0)


def paced_out(source) -> bool:
    """Whether the felt leader switched its push off because the loop lost its pace."""
    return any(PACE_LOST.fullmatch(event) for event in source.feel_stats.events)


class FeelOff:
    """Which cycle switched the feel off, and the ground truth at that cycle's end."""

    def __init__(self, simulator) -> None:
        self.simulator = simulator
        self.at: int | None = None
        self.truth: dict | None = None

    def observe(self, index: int, was_felt: bool, felt: bool) -> None:
        """Count cycle ``index`` (felt before it: ``was_felt``; after it: ``felt``)."""
        if self.at is None and was_felt and not felt:
            self.at, self.truth = index, self.simulator.truth()


def assert_the_feel_went_off_for_the_pace(pushes, off: FeelOff, source, ids) -> None:
    """The documented outcome of a lost pace, from the loop's (cycle, push, felt) ``pushes``."""
    assert off.at is not None and off.truth is not None, "the feel never went off"
    [event] = source.feel_stats.events  # the pace, and nothing before it
    match = PACE_LOST.fullmatch(event)
    assert match, event
    assert float(match[2]) == source.rate_hz
    assert int(match[1]) <= round(source.rate_hz / 1.25)  # the watch's median over 1.25 periods
    # the operator is told in the cycle that saw it, and in the session's report
    assert event in pushes[off.at][0].notices
    assert event in source.report_lines()
    # within that cycle: no current, and the torque off on every leader servo
    assert off.truth["leader"]["motor_nm"] == [0.0] * len(ids)
    assert not any(off.truth["servos"][i]["torque_on"] for i in ids)
    # for good: no push from then on, and no feel
    assert all(push is None and not felt for _, push, felt in pushes[off.at :])


def pressing(pushes) -> bool:
    """100 cycles pushed on, or the feel is off (a lost pace, whose outcome the test asserts)."""
    if pushes and not pushes[-1][2]:
        return True
    return sum(1 for _, push, _ in pushes if push is not None and push.goal_current) >= 100


class Running:
    """The loop in a thread keeping each cycle's ``pushes`` ((cycle, push, felt)), ``poses``
    (rad), end times (``clock``, monotonic s) and the feel's switch-off (``off``)."""

    def __init__(self, session, source) -> None:
        self.source, self.pushes, self.out = source, [], {}
        self.poses: list[tuple[float, ...] | None] = []
        self.ids: tuple[int, ...] = source.leader_ids
        self.clock: list[float] = []
        self.simulator = session.simulator
        self.off = FeelOff(session.simulator)
        self.changed = threading.Condition()
        self.stop = threading.Event()
        rig = session.rig
        config = LoopConfig(on_cycle=self._observe, health=SIM_STARVED_HEALTH)

        def body() -> None:
            try:
                self.out.update(s=run(rig, session.gate, source, config, stop=self.stop))
            finally:
                with self.changed:
                    self.ended = True
                    self.changed.notify_all()

        self.ended = False
        self.switched_wall: float | None = None  # when :meth:`held_then` last switched (s)
        self.thread = threading.Thread(target=body)

    def _observe(self, cycle) -> None:
        with self.changed:
            was_felt = self.pushes[-1][2] if self.pushes else True
            self.off.observe(len(self.pushes), was_felt, self.source.felt)
            self.pushes.append((cycle, self.source.last_push, self.source.felt))
            self.poses.append(self.source.last_pose)
            self.clock.append(time.monotonic())
            self.changed.notify_all()

    def until(self, predicate, timeout: float = 60.0) -> None:
        """Wait until ``predicate(pushes)``; fail at once, saying why, if the loop ended first."""
        with self.changed:
            self.changed.wait_for(lambda: predicate(self.pushes) or self.ended, timeout)
            if predicate(self.pushes):
                return
            summary = self.out.get("s")
            raise AssertionError(
                f"never happened in {len(self.pushes)} cycles; loop ended: {self.ended}, "
                f"fault: {getattr(summary, 'fault', None)!r}, feel: {self.source.feel_stats.events}"
            )

    def kept_sim(
        self, sim_at: float, wall_at: float, sim_from: float, sim_to: float, unreleased_from=None
    ) -> bool:
        """:meth:`kept_pace` and :meth:`unreleased` in simulator time (``sim_at``: ``wall_at``)."""
        since, until = wall_at + sim_from - sim_at, wall_at + sim_to - sim_at
        first = since if unreleased_from is None else wall_at + unreleased_from - sim_at
        return self.kept_pace(since, until) and self.unreleased(first, until)

    def kept_pace(self, since: float, until: float) -> bool:
        """Whether the median period between two monotonic times was within 1.25 at 200 Hz."""
        times = [t for t in self.clock if since <= t <= until]
        return len(times) > 2 and float(np.median(np.diff(times))) <= 1.25 / 200.0

    def unstalled(self, since: float, until: float) -> bool:
        """Whether no cycle between two monotonic times came later than two periods at 200 Hz
        after the one before it: what a watch needs to see a snap that lasts a few cycles."""
        times = [t for t in self.clock if since <= t <= until]
        return len(times) > 2 and float(np.max(np.diff(times))) <= 2.0 / 200.0

    def unreleased(self, since: float, until: float) -> bool:
        """Whether every cycle between two monotonic times read, gated and wrote the law's push."""
        cycles = [p for p, t in zip(self.pushes, self.clock, strict=True) if since <= t <= until]
        return bool(cycles) and all(
            push is not None
            and cycle.present is not None
            and cycle.result is not None
            and cycle.result.outcome is not Outcome.HELD
            for cycle, push, _ in cycles
        )

    def paced_out(self) -> bool:
        """Whether the feel went off for a lost pace; if so, asserts its documented outcome."""
        if not paced_out(self.source):
            return False
        with self.changed:
            assert_the_feel_went_off_for_the_pace(self.pushes, self.off, self.source, self.ids)
        return True

    def pressed_or_paced_out(self, press: dict) -> bool:
        """Press until the wall pushes; True when the feel went off for a lost pace instead."""
        self.simulator.set_operator(press)
        self.until(pressing)
        return self.paced_out()

    def held_still(self, press: dict) -> bool:
        """Press past the edge and wait (20 s at most) for the wall to hold the leader still;
        False when the loop lost its pace first (the feel then goes off for good, as it must)."""
        if self.pressed_or_paced_out(press):
            return False
        held_at, watch = time.monotonic(), self.source.snap
        self.until(lambda p: watch.armed is not None or time.monotonic() > held_at + 20.0)
        if self.paced_out():
            return False
        assert watch.armed is not None, "the wall never held the leader still"
        return True

    def held_then(self, press: dict, then: dict) -> float | None:
        """:meth:`held_still`, then ``then`` for 100 cycles: the switch's time, or None."""
        if not self.held_still(press):
            return None
        switched_at = self.simulator.truth()["leader"]["t"]
        self.switched_wall = time.monotonic()
        self.simulator.set_operator(then)
        seen = len(self.pushes)
        self.until(lambda p: len(p) > seen + 100 or self.ended)
        return None if self.paced_out() else switched_at

    def __enter__(self) -> Running:
        self.thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop.set()
        self.thread.join(timeout=10.0)


def pushed_only_when_fit(pushes) -> None:
    """A cycle pushes only when fit and the gate ran on a good read, or held on a follower read
    failed within FOLLOWER_GRACE_S (plus a cycle) of its last good one."""
    period = 1.0 / LoopConfig().rate_hz
    last_read = None
    for cycle, push, felt in pushes:
        if not cycle.complete:
            continue
        ran = cycle.present is not None and cycle.result.outcome is not Outcome.HELD
        if ran:
            last_read = cycle.t
        if push is not None and push.goal_current:
            assert felt
            if not ran:
                assert cycle.result.outcome is Outcome.HELD
                assert cycle.result.reason == FOLLOWER_UNREAD
                assert last_read is not None
                assert cycle.t - last_read <= FOLLOWER_GRACE_S + period
