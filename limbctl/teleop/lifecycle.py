"""One teleop session from start to park, for any chain (:func:`run_session`)."""

from __future__ import annotations

import threading
from collections.abc import Callable
from contextlib import AbstractContextManager
from dataclasses import dataclass
from pathlib import Path
from typing import IO

from limbctl.errors import SafetyError
from limbctl.teleop.approach import ParkOutcome, StartLimb, park
from limbctl.teleop.cycle import TeleopSummary
from limbctl.teleop.gate import Gate
from limbctl.teleop.loop import LoopConfig, run
from limbctl.teleop.margin import margins_for
from limbctl.teleop.report import Telemetry, open_telemetry
from limbctl.teleop.sources import CommandSource
from limbctl.teleop.start import StartOptions, StartOutcome, StartStatus, start_session


@dataclass(frozen=True)
class SessionResult:
    """How a session went: its start, the loop's summary and the park (None where not reached)."""

    start: StartOutcome
    summary: TeleopSummary | None = None
    parked: ParkOutcome | None = None

    @property
    def exit_code(self) -> int:
        """The start's code when it did not start, else the loop's (0, 2 all refused, 3)."""
        return self.start.exit_code if self.summary is None else self.summary.exit_code

    def lines(self) -> list[str]:
        """What the person reads after the session, in order."""
        start, summary, parked = self.start, self.summary, self.parked
        if summary is None:
            return [f"not started: {start.message}"]
        out = (
            [] if start.how == "inside" else [f"started after {start.waited_s:.1f} s ({start.how})"]
        )
        if parked is not None and parked.moved:
            out.append(
                f"parked the limb {parked.distance_deg:.2f} deg in from the region's edge, "
                "where the next start accepts it"
            )
        elif parked is not None and parked.note:
            out.append(f"not parked: {parked.note}")
        out += summary.lines()
        if summary.fault:
            out.append(f"FAULT: {summary.fault}")
        elif summary.all_refused:
            out.append(f"ERROR: every one of the {summary.rejected} command lines was refused")
        return out


def run_session(
    limb: StartLimb,
    gate: Gate,
    open_source: Callable[[], AbstractContextManager[CommandSource]],
    config: LoopConfig,
    starting: StartOptions,
    telemetry_path: str | Path | None = None,
    stream: IO[str] | None = None,
    status: IO[str] | None = None,
    stop: threading.Event | None = None,
    torque_was_on: bool = False,
    publish: Callable[[StartStatus], None] | None = None,
) -> SessionResult:
    """Start, open the source (``open_source()``, once the limb is held inside), run and park one
    session (arguments as for :func:`~limbctl.teleop.start.start_session` and loop's ``run``)."""
    stop = stop or threading.Event()
    # opened first: a path that cannot be written is refused before torque may come on
    telemetry_file = open_telemetry(telemetry_path)
    try:
        start = start_session(limb, gate, starting, stream, publish, stop, torque_was_on)
        if not start.started:
            return SessionResult(start)
        telemetry = Telemetry(telemetry_file) if telemetry_file is not None else None
        try:
            opened = open_source()
        except Exception:
            limb.set_torque(False)  # no source after all: leave the limb free, as before the start
            raise
        try:
            with opened as source:
                summary = run(limb, gate, source, config, telemetry, status, stop)  # type: ignore[arg-type]
        except SafetyError:
            limb.set_torque(False)  # the limb moved out as the loop began: leave it free
            raise
    finally:
        if telemetry_file is not None:
            telemetry_file.close()
    margins = margins_for(gate, limb)
    parked = park(limb, margins, config.rate_hz) if summary.ended_by != "fault" else None
    return SessionResult(start, summary, parked)
