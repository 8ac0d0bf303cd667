"""The status line of a source a person steers (keyboard, page): poses and the gate in words."""

from __future__ import annotations

import math
import os
from typing import IO, Any

from limbctl.teleop.cycle import Cycle, TeleopSummary
from limbctl.teleop.explain import DIRECTION_NAMES, explain
from limbctl.teleop.report import STATUS_EVERY_LOG_S, STATUS_EVERY_TTY_S, StatusLine

#: ANSI "erase to the end of the line": a shorter line leaves no tail of the longer one before.
ERASE_TO_END = "\x1b[K"


def _pose(label: str, pose: tuple[float, float] | None) -> str:
    return f"{label} " + ("-" if pose is None else f"pan {pose[0]:6.1f} tilt {pose[1]:6.1f}")


class ExplainedStatus:
    """Status line saying where the limb is asked to be, where it was written and why."""

    def __init__(self, stream: IO[str], source: Any) -> None:
        self._stream = stream
        self._source = source
        self._tty = stream.isatty()
        self._every = STATUS_EVERY_TTY_S if self._tty else STATUS_EVERY_LOG_S
        self._last_shown = 0.0
        self._window: tuple[int, float] | None = None  # (cycles, t) at the last line
        self._rate_hz = 0.0
        self._cycle: Cycle | None = None
        self._written: tuple[float, float] | None = None
        self._previous: tuple[float, float] | None = None

    def update(self, cycle: Cycle, summary: TeleopSummary) -> None:
        """Keep this cycle's poses; print the line if the last one is old enough."""
        self._cycle = cycle
        if cycle.result is not None:
            self._previous = self._written
            pan, tilt = cycle.result.pose[:2]
            self._written = (math.degrees(pan), math.degrees(tilt))
        if self._window is None:
            self._window = (summary.cycles, cycle.t)
        if cycle.t - self._last_shown >= self._every:
            # rate = cycles since the last line / time since it
            cycles, t = self._window
            if cycle.t > t:
                self._rate_hz = (summary.cycles - cycles) / (cycle.t - t)
            self._window = (summary.cycles, cycle.t)
            self._last_shown = cycle.t
            self.show(cycle.t)

    def close(self, summary: TeleopSummary) -> None:
        """Print the last line (and end it on a terminal)."""
        self.show(summary.elapsed_s)
        if self._tty:
            self._stream.write("\n")
        self._stream.flush()

    def line(self, elapsed: float) -> str:
        """The status as one line of text."""
        cycle = self._cycle
        command = cycle.command_deg if cycle is not None else None
        result = cycle.result if cycle is not None else None
        pushing = getattr(self._source, "pushing", None)  # a keyboard: the way its key pushes
        pushed = pushing() if pushing is not None else None
        words = explain(result, command, self._previous, DIRECTION_NAMES, pushed).words
        detail = self._source.describe()
        parts = [f"{elapsed:7.1f} s", f"{self._rate_hz:6.1f} Hz"]
        parts += [detail] if detail else []
        parts += [words, _pose("commanded", command), _pose("written", self._written)]
        return "  ".join(parts)

    def show(self, elapsed: float) -> None:
        if self._tty:
            line = self.line(elapsed)
            try:  # a line longer than the terminal wraps, and "\r" would refresh its last row only
                columns = os.get_terminal_size(self._stream.fileno()).columns
            except (OSError, ValueError, AttributeError):
                columns = 0  # not a terminal whose size can be asked
            if columns > 1:  # a terminal of unknown size says 0: the whole line then
                line = line[: columns - 1]
            self._stream.write("\r" + line + ERASE_TO_END)
        else:
            self._stream.write(self.line(elapsed) + "\n")
        self._stream.flush()


def status_line_for(stream: IO[str], source: Any) -> StatusLine | ExplainedStatus:
    """The status line for ``source``: explained when a person steers it, counts otherwise."""
    if getattr(source, "explains", False):
        return ExplainedStatus(stream, source)
    return StatusLine(stream)
