"""What a felt leader's pty tests assert when the loop could not keep the wall's pace.

The wall is passive only at its rate (docs/haptic.md). A loop whose median period passes 1.25
periods of the rate the source was opened for switches the push off for good
(:meth:`limbctl.teleop.sources.leader.LeaderSource._check_pace`): in the cycle that saw it the
leader gets Goal Current 0 and its torque goes off, the operator is told why, and the mirroring
goes on without feel. A test whose run lost the pace asserts that outcome, not its own property
(which is asserted at exactly 200 Hz on a stepped clock in tests/teleop/test_haptic*.py).
"""

from __future__ import annotations

import re

from limbctl.servo.health import HealthLimits

#: The notice of a lost pace (``LeaderSource._check_pace`` and ``_lose_feel``).
PACE_LOST = re.compile(
    r"the loop runs at (\d+) Hz, under the ([\d.]+) Hz the leader's wall needs to stay passive: "
    r"the push is off, mirroring goes on without feel"
)


#: The loop's health limits for these tests: a follower is lost after 5 s of silence, not 0.5 s.
#: On the shared 2-core machine at load 4-12 the simulator's own process fell silent for
#: 0.51-0.59 s now and then (with main's tests too), and the loop's fault then ended a test of
#: the leader within its first cycles, before it judged anything. The leader's rules for a
#: silent follower (its wall off after FOLLOWER_GRACE_S) are unchanged; the loop's own rule is
#: tested in tests/servo/test_health.py and tests/safety/.
SIM_STARVED_HEALTH = HealthLimits(lost_after_s=5.0)


def paced_out(source) -> bool:
    """Whether the felt leader switched its push off because the loop lost its pace."""
    return any(PACE_LOST.fullmatch(event) for event in source.feel_stats.events)


class FeelOff:
    """Which cycle switched the feel off, and the simulator's ground truth at that cycle's end
    (taken in the loop's thread, before the next cycle's bus traffic).

    Parameters
    ----------
    simulator
        The session's simulator (``truth()``).
    """

    def __init__(self, simulator) -> None:
        self.simulator = simulator
        self.at: int | None = None
        self.truth: dict | None = None

    def observe(self, index: int, was_felt: bool, felt: bool) -> None:
        """Count cycle ``index`` (felt before it: ``was_felt``; after it: ``felt``)."""
        if self.at is None and was_felt and not felt:
            self.at, self.truth = index, self.simulator.truth()


def assert_the_feel_went_off_for_the_pace(pushes, off: FeelOff, source, ids) -> None:
    """The documented outcome of a lost pace, from the loop's cycles ``pushes`` ((cycle, push,
    felt) each), the :class:`FeelOff` that watched them, and the source."""
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
