"""What a felt leader's pty tests assert when the loop could not keep the wall's pace.

A lost pace switches the push off for good in the cycle that saw it, says why, and mirrors on
(``LeaderSource._check_pace``); a run that lost it asserts that outcome instead of its own
property (asserted at exactly 200 Hz in tests/teleop/test_haptic.py).
"""

from __future__ import annotations

import re

from limbctl.servo.health import HealthLimits

#: The notice of a lost pace (``LeaderSource._check_pace`` and ``_lose_feel``).
PACE_LOST = re.compile(
    r"the loop runs at (\d+) Hz, under the ([\d.]+) Hz the leader's wall needs to stay passive: "
    r"the push is off, mirroring goes on without feel"
)


#: The loop's health limits for these tests: a follower is lost after 5 s of silence, not 0.5 s:
#: a loaded machine's simulator fell silent for 0.51-0.59 s now and then (the loop's own rule is
#: tested in tests/servo/test_health.py and tests/safety/).
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
