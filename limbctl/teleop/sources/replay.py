"""Command source ``replay:FILE``: JSON lines from a file, paced by their ``"t"`` (seconds)."""

from __future__ import annotations

import math
import time
from pathlib import Path

from limbctl.errors import ConfigError, InvalidInputError
from limbctl.teleop.commands import parse_command
from limbctl.teleop.sources.base import CommandSource

#: Rate (lines/s) at which lines without a ``"t"`` follow each other: half the loop's default
#: 200 Hz, so each line is gated rather than skipped as stale.
UNSTAMPED_RATE_HZ = 100.0


class ReplaySource(CommandSource):
    """JSON lines from a file, paced: a line with ``"t"`` (s) is released at that time after the
    first stamped line; lines without it follow the previous one after ``1 / rate_hz``."""

    name = "replay"

    def __init__(
        self, path: str | Path, speed: float = 1.0, rate_hz: float = UNSTAMPED_RATE_HZ
    ) -> None:
        super().__init__()
        self.path = Path(path)
        if not self.path.is_file():
            raise ConfigError(f"replay file {self.path} does not exist")
        if not (math.isfinite(speed) and speed > 0):
            raise ConfigError(f"replay speed must be positive, got {speed}")
        if not (math.isfinite(rate_hz) and rate_hz > 0):
            raise ConfigError(f"replay rate must be positive, got {rate_hz}")
        self.speed = speed
        self.rate_hz = rate_hz

    def _run(self) -> None:
        start = time.monotonic()
        t0: float | None = None
        due = start
        with open(self.path, "rb") as fh:
            for raw in fh:
                if self._stop.is_set():
                    return
                stamp = _peek_time(raw, self.twist)
                if stamp is not None:
                    t0 = stamp if t0 is None else t0
                    due = start + (stamp - t0) / self.speed
                else:
                    due += 1.0 / (self.rate_hz * self.speed)
                # wait for the line's time, waking at once if the source is closed
                self._stop.wait(max(0.0, due - time.monotonic()))
                self.feed(raw)


def _peek_time(raw: bytes, twist: bool = False) -> float | None:
    try:
        return parse_command(raw, twist=twist).t
    except InvalidInputError:
        return None
