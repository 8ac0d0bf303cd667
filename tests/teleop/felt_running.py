"""The felt-leader pty tests' loop runner, for two and three servos.

:class:`Running` runs :func:`limbctl.teleop.loop.run` in a thread on an open simulated rig and
keeps every cycle's push, so a test can wait on what the loop did (no sleeps) and judge the
wall only on stretches that kept its pace.
"""

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
    """The loop in a thread with every cycle's push kept (``pushes``: (cycle, push, felt)), the
    leader's pose each push was made from (``poses``, rad), when each cycle ended (``clock``,
    monotonic s), and the cycle that switched the feel off with the ground truth at its end
    (``off``); ``until(predicate)`` waits on the pushes."""

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
        """:meth:`kept_pace` from simulator time ``sim_from`` to ``sim_to`` (s) and
        :meth:`unreleased` from ``unreleased_from`` (default ``sim_from``) on: the simulator runs
        on the wall clock, its time ``sim_at`` being monotonic ``wall_at``."""
        since, until = wall_at + sim_from - sim_at, wall_at + sim_to - sim_at
        first = since if unreleased_from is None else wall_at + unreleased_from - sim_at
        return self.kept_pace(since, until) and self.unreleased(first, until)

    def kept_pace(self, since: float, until: float) -> bool:
        """Whether the loop kept the wall's rate between two monotonic times: the median period
        of its cycles within 1.25 periods at 200 Hz (the pace watch's rule, PaceWatch)."""
        times = [t for t in self.clock if since <= t <= until]
        return len(times) > 2 and float(np.median(np.diff(times))) <= 1.25 / 200.0

    def unreleased(self, since: float, until: float) -> bool:
        """Whether every cycle between two monotonic times read both gimbals, ran the gate and
        wrote the law's push: none released the leader for a failed read or a held gate, after
        which the hand may carry it past (docs/decisions/haptic.md)."""
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
        """Start the operator's ``press`` and wait until the wall pushes (:func:`pressing`);
        True when the feel went off for a lost pace instead (its outcome asserted)."""
        self.simulator.set_operator(press)
        self.until(pressing)
        return self.paced_out()

    def held_then(self, press: dict, then: dict) -> float | None:
        """Press with ``press`` until the snap watch holds the leader still (armed), then hand
        the leader to the operator ``then`` (its script's clock starting there) and run 100
        cycles more. Returns the simulator's leader time at the switch; None when the feel went
        off for a lost pace instead (its outcome asserted)."""
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
    """A cycle pushes only when the leader was read and fit to push, and the gate ran on a good
    read, or held only because the follower's read failed within FOLLOWER_GRACE_S (one cycle of
    slack: the grace is timed when the push is written) of the follower's last good read."""
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
    """The pace-loss outcome the other tests assert when a busy machine loses the pace, forced:
    the source believes its wall needs 1 kHz, so the loop's 200 Hz is five periods late. The
    feel goes off for good in its cycle (asserted cycle by cycle) and mirroring goes on."""
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
