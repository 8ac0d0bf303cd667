"""Writers of the loop's cycle values: the telemetry file and the status line."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import IO

import numpy as np

from limbctl.geometry.gimbal import pan_tilt_to_quat
from limbctl.teleop.cycle import Cycle, TeleopSummary, orientation_fields
from limbctl.teleop.gate import Outcome


class Telemetry:
    """One JSON line per complete cycle, in :func:`orientation_fields`' form for every rig."""

    def __init__(self, stream: IO[str]) -> None:
        self._stream = stream

    def write(self, cycle: Cycle) -> None:
        """Log one complete cycle (see :class:`~limbctl.teleop.cycle.Cycle`)."""
        result = cycle.result
        command_q = cycle.command_q
        if command_q is None and cycle.command_deg is not None:  # a cycle built by hand
            command_q = pan_tilt_to_quat(*np.radians(cycle.command_deg))
        row = {
            "t": round(cycle.t, 6),
            **orientation_fields(command_q, None if result is None else result.pose),
            "outcome": None if result is None else result.outcome.value,
            "written": cycle.written,
            "present": None
            if cycle.present is None
            else [round(math.degrees(v), 4) for v in cycle.present],
            "cycle_ms": round(1e3 * cycle.timings.cycle_s, 3) if cycle.timings else None,
            "refused": list(cycle.refused_reasons),
        }
        self._stream.write(json.dumps(row) + "\n")


def open_telemetry(path: str | Path | None) -> IO[str] | None:
    """Open a telemetry file for line-buffered writing (None: no telemetry)."""
    if path is None:
        return None
    return open(path, "w", buffering=1, encoding="utf-8")


#: Seconds between status lines on a terminal (refreshed in place) and in a log (one per line).
STATUS_EVERY_TTY_S = 0.5
STATUS_EVERY_LOG_S = 5.0


class StatusLine:
    """A one-line status refreshed in place on a terminal, or appended now and then to a log."""

    def __init__(self, stream: IO[str]) -> None:
        self._stream = stream
        self._tty = stream.isatty()
        self._every = STATUS_EVERY_TTY_S if self._tty else STATUS_EVERY_LOG_S
        self._last = 0.0

    def update(self, cycle: Cycle, summary: TeleopSummary) -> None:
        """Print the status if the last one is old enough (``cycle.t`` is the clock)."""
        if cycle.t - self._last >= self._every:
            self._last = cycle.t
            self.show(summary, cycle.t)

    def close(self, summary: TeleopSummary) -> None:
        """Print the final status (and end the refreshed line on a terminal)."""
        self.show(summary, summary.elapsed_s)
        if self._tty:
            self._stream.write("\n")

    def show(self, summary: TeleopSummary, elapsed: float) -> None:
        n = max(1, sum(summary.outcomes.values()))
        share = {o: 100.0 * summary.outcomes[o] / n for o in Outcome}
        rate = summary.cycles / elapsed if elapsed > 0 else 0.0
        self._stream.write(
            ("\r" if self._tty else "")
            + f"{elapsed:7.1f} s  {rate:6.1f} Hz  pass {share[Outcome.PASSED]:5.1f}%  "
            f"corr {share[Outcome.CORRECTED]:5.1f}%  clamp {share[Outcome.CLAMPED]:4.1f}%  "
            f"held {share[Outcome.HELD]:5.1f}%  refused {summary.rejected}  "
            f"bus errors {summary.bus_errors}   " + ("" if self._tty else "\n")
        )
        self._stream.flush()
