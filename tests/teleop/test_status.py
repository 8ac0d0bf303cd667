"""The explained status line: step, both poses, the gate in words, the loop's rate."""

from __future__ import annotations

import fcntl
import io
import os
import pty
import select
import struct
import termios

from limbctl.teleop.cycle import TeleopSummary
from limbctl.teleop.report import StatusLine
from limbctl.teleop.sources import StreamSource
from limbctl.teleop.status import ERASE_TO_END, ExplainedStatus, status_line_for
from tests.teleop.test_explain import follow, gate
from tests.teleop.test_report import written_cycle


class Steered(StreamSource):
    """A stdin source that says something about itself, as the keyboard does."""

    explains = True

    def describe(self) -> str:
        return "step 2 deg"


def cycles_up_against_the_edge(count: int, rate_hz: float = 200.0):
    """Real gate cycles (test_explain.py's gate) of a command straight up beyond a 30 deg cone."""
    summary = TeleopSummary()
    for index, result in enumerate(follow(gate(), 0.0, 60.0, count)):
        summary.cycles += 1
        summary.outcomes[result.outcome] += 1
        yield written_cycle(index, index / rate_hz, (0.0, 60.0), result), summary


def test_a_log_gets_the_step_poses_words_and_rate():
    stream = io.StringIO()
    status = ExplainedStatus(stream, Steered())
    for cycle, summary in cycles_up_against_the_edge(count=1100):  # 5.5 s at 200 Hz
        status.update(cycle, summary)
    lines = stream.getvalue().splitlines()
    assert len(lines) == 1  # every STATUS_EVERY_LOG_S (5 s) in a log
    last = lines[-1]
    assert "200.0 Hz" in last and "step 2 deg" in last
    assert "commanded pan    0.0 tilt   60.0" in last
    assert last.endswith("written pan    0.0 tilt   30.0")
    assert "at the edge: up is blocked, holding there" in last


def test_a_terminal_line_is_refreshed_in_place_and_ended_on_close():
    master, slave = pty.openpty()
    # a terminal 100 columns wide: each refreshed line is cut to 99
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 100, 0, 0))
    try:
        with os.fdopen(slave, "w", closefd=False) as terminal:
            status = ExplainedStatus(terminal, Steered())
            for cycle, summary in cycles_up_against_the_edge(count=120):
                status.update(cycle, summary)
            summary.elapsed_s = 0.6
            status.close(summary)
        shown = ""
        while select.select([master], [], [], 0.5)[0]:  # all that was written is there already
            shown += os.read(master, 65536).decode()
    finally:
        os.close(master)
        os.close(slave)
    assert shown.count("\r") >= 2 and shown.count(ERASE_TO_END) >= 2
    assert "up is blocked" in shown and shown.endswith("\n")
    refreshed = [part.split(ERASE_TO_END)[0] for part in shown.split("\r") if ERASE_TO_END in part]
    assert refreshed and all(len(line) == 99 for line in refreshed)
    # the status line is chosen by the source
    stream = io.StringIO()
    assert isinstance(status_line_for(stream, Steered()), ExplainedStatus)
    assert isinstance(status_line_for(stream, StreamSource()), StatusLine)
