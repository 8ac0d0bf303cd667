"""The felt-leader pty tests' loop runner (:class:`Running`), for two and three servos: waits on
what the loop did (no sleeps) and judges the wall only where it kept its pace."""

from __future__ import annotations

import threading
import time

import numpy as np

from limbctl.teleop.gate import Outcome
from limbctl.teleop.loop import LoopConfig, run
from limbctl.teleop.pacing import PaceWatch
from limbctl.teleop.sources.leader import FOLLOWER_GRACE_S, FOLLOWER_UNREAD
from tests.teleop.pace_loss import (
    SIM_STARVED_HEALTH,
    FeelOff,
    assert_the_feel_went_off_for_the_pace,
    paced_out,
)


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
        #: The leader's servo ids, which a lost pace must switch off.
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
        """:meth:`kept_pace` and :meth:`unreleased` in simulator time (``sim_at`` is monotonic
        ``wall_at``)."""
        since, until = wall_at + sim_from - sim_at, wall_at + sim_to - sim_at
        first = since if unreleased_from is None else wall_at + unreleased_from - sim_at
        return self.kept_pace(since, until) and self.unreleased(first, until)

    def kept_pace(self, since: float, until: float) -> bool:
        """Whether the median period between two monotonic times was within 1.25 at 200 Hz."""
        times = [t for t in self.clock if since <= t <= until]
        return len(times) > 2 and float(np.median(np.diff(times))) <= 1.25 / 200.0

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

    def held_then(self, press: dict, then: dict) -> float | None:
        """Press until the watch is armed, then hand over to ``then`` for 100 cycles: the leader's
        time at the switch, or None for a lost pace."""
        if self.pressed_or_paced_out(press):
            return None
        held_at = time.monotonic()
        armed = self.source.snap
        self.until(lambda p: armed.armed is not None or time.monotonic() > held_at + 20)
        if self.paced_out():
            return None
        assert armed.armed is not None, "the wall never held the leader still"
        switched_at = self.simulator.truth()["leader"]["t"]
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


def check_a_forced_pace_loss(session, source, press: dict) -> None:
    """The pace-loss outcome, forced: the source believes its wall needs 1 kHz."""
    source.rate_hz, source.pace = 1000.0, PaceWatch(1000.0)
    session.rig.set_torque(True)
    with Running(session, source) as running:
        session.simulator.set_operator(press)
        running.until(lambda p: running.off.at is not None and len(p) > running.off.at + 20)
        accepted = source.stats.accepted
        running.until(lambda p: len(p) > running.off.at + 40)
        assert running.paced_out()
    assert source.stats.accepted > accepted  # still mirrored, without feel
    assert not source.felt
