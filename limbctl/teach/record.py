"""Teach by hand: torque off, sample both joints at a fixed rate, append every sample to disk.

The recorder never buffers: each sample is handed to :class:`limbctl.teach.dataset.DatasetWriter`
as it is read (one ``write`` per record, fsync at least every 0.25 s), so Ctrl-C or SIGTERM
lose nothing and a kill -9 loses at most the last half second.
"""

from __future__ import annotations

import math
import sys
import threading
import time
from dataclasses import dataclass
from typing import IO, Protocol

from limbctl.errors import BusError, ConfigError
from limbctl.teach.coverage import CoverageMap
from limbctl.teach.dataset import DatasetWriter

#: Slowest accepted sampling rate (Hz): a person's hand moves fast.
MIN_RATE_HZ = 100.0
#: Consecutive failed reads after which the recording stops (what was recorded is kept).
MAX_FAILED_READS = 50


class Backdrivable(Protocol):
    """What the recorder needs of a rig."""

    def read_pose(self) -> tuple[float, float]: ...

    def set_torque(self, enabled: bool) -> None: ...


@dataclass
class RecordSummary:
    """What a recording produced."""

    samples: int = 0
    elapsed_s: float = 0.0
    failed_reads: int = 0
    spread_deg: float = 0.0
    cells_visited: int = 0
    ended_by: str = ""
    fault: str = ""

    @property
    def exit_code(self) -> int:
        """0 for a recording that ended as asked (Enter, signal, duration), 3 for a bus failure."""
        return 3 if self.fault else 0

    @property
    def rate_hz(self) -> float:
        return self.samples / self.elapsed_s if self.elapsed_s > 0 else 0.0

    def lines(self) -> list[str]:
        return [
            f"ended by           {self.ended_by}" + (f": {self.fault}" if self.fault else ""),
            f"samples            {self.samples} in {self.elapsed_s:.1f} s ({self.rate_hz:.1f} Hz)",
            f"angular spread     {self.spread_deg:.1f} deg from the mean direction",
            f"failed reads       {self.failed_reads}",
        ]


def stop_on_enter(stop: threading.Event, stream: IO[str] | None = None) -> threading.Thread | None:
    """Set ``stop`` when the user presses Enter (only when standard input is a terminal)."""
    stream = stream if stream is not None else sys.stdin
    if stream is None or not stream.isatty():
        return None

    def wait_for_enter() -> None:
        stream.readline()
        stop.set()

    thread = threading.Thread(target=wait_for_enter, name="stop-on-enter", daemon=True)
    thread.start()
    return thread


def record(
    limb: Backdrivable,
    writer: DatasetWriter,
    rate_hz: float = MIN_RATE_HZ,
    duration_s: float | None = None,
    stop: threading.Event | None = None,
    progress: IO[str] | None = None,
) -> RecordSummary:
    """Switch torque off and record until ``stop`` is set or ``duration_s`` passes.

    Parameters
    ----------
    limb : Backdrivable
        The connected rig.
    writer : DatasetWriter
        An open dataset writer; every sample is appended as it is read.
    rate_hz : float
        Sampling rate (Hz), at least :data:`MIN_RATE_HZ`.
    duration_s : float, optional
        Stop after this many seconds.
    stop : threading.Event, optional
        Set by Ctrl-C/SIGTERM handlers or the Enter key to end the recording.
    progress : text stream, optional
        Where live progress (count, spread, coverage picture) is drawn.
    """
    if not (math.isfinite(rate_hz) and rate_hz >= MIN_RATE_HZ):
        raise ConfigError(f"record at {MIN_RATE_HZ:.0f} Hz or faster, got {rate_hz}")
    stop = stop or threading.Event()
    period = 1.0 / rate_hz
    coverage = CoverageMap()
    summary = RecordSummary()
    limb.set_torque(False)

    redraw_every = 0.5 if progress is not None and progress.isatty() else 5.0
    drawn_lines = 0
    start = time.perf_counter()
    next_tick = start
    last_draw = start
    failed_in_a_row = 0
    while True:
        now = time.perf_counter()
        elapsed = now - start
        if stop.is_set():
            summary.ended_by = "stopped"
            break
        if duration_s is not None and elapsed >= duration_s:
            summary.ended_by = "duration"
            break
        try:
            pan, tilt = limb.read_pose()
        except BusError as exc:
            summary.failed_reads += 1
            failed_in_a_row += 1
            if failed_in_a_row >= MAX_FAILED_READS:
                summary.ended_by = "bus failure"
                summary.fault = f"{MAX_FAILED_READS} reads in a row failed, the last: {exc}"
                break
        else:
            failed_in_a_row = 0
            writer.append(elapsed, pan, tilt)
            coverage.add(pan, tilt)
            summary.samples += 1
        if progress is not None and now - last_draw >= redraw_every:
            last_draw = now
            drawn_lines = _draw(progress, coverage, summary, elapsed, duration_s, drawn_lines)
        # pace: a late sample is followed at once by the next, so the average rate holds;
        # only after a long stall (a second behind) does the schedule restart from now
        next_tick += period
        delay = next_tick - time.perf_counter()
        if delay > 0:
            stop.wait(delay)
        elif delay < -1.0:
            next_tick = time.perf_counter()

    summary.elapsed_s = time.perf_counter() - start
    summary.spread_deg = coverage.spread_deg()
    summary.cells_visited = coverage.cells_visited()
    if progress is not None:
        _draw(progress, coverage, summary, summary.elapsed_s, duration_s, drawn_lines)
    return summary


def _draw(
    stream: IO[str],
    coverage: CoverageMap,
    summary: RecordSummary,
    elapsed: float,
    duration_s: float | None,
    previous_lines: int,
) -> int:
    total = f" / {duration_s:.0f} s" if duration_s else ""
    head = (
        f"recording {elapsed:6.1f} s{total}  samples {summary.samples}  "
        f"spread {coverage.spread_deg():5.1f} deg  cells {coverage.cells_visited()}  "
        f"failed reads {summary.failed_reads}   (Enter or Ctrl-C stops)"
    )
    if not stream.isatty():
        stream.write(head + "\n")
        stream.flush()
        return 0
    lines = [head, *coverage.render()]
    # move the cursor up over the previous picture and draw over it
    if previous_lines:
        stream.write(f"\x1b[{previous_lines}F")
    stream.write("\n".join(line + "\x1b[K" for line in lines) + "\n")
    stream.flush()
    return len(lines)
