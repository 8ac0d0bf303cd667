"""Teach by hand: torque off, sample every joint at a fixed rate, append every sample to disk,
and show the guides' assessment on one updating line."""

from __future__ import annotations

import math
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import IO, Protocol

from limbctl.errors import BusError, ConfigError
from limbctl.geometry.gimbal import pose_quat_scalar
from limbctl.teach.dataset import DatasetWriter
from limbctl.teach.edge_support import EdgeSupport
from limbctl.teach.guide import Guidance, Guide
from limbctl.teach.twist_guide import TwistGuidance, TwistGuide

#: Slowest accepted sampling rate (Hz): a person's hand moves fast.
MIN_RATE_HZ = 100.0
#: Consecutive failed reads after which the recording stops (what was recorded is kept).
MAX_FAILED_READS = 50
#: Seconds between the guide's assessments: a teacher reads the line about once a second.
GUIDE_EVERY_S = 1.0
#: Seconds between progress lines when the progress stream is not a terminal (a log file).
LOG_EVERY_S = 5.0
#: Failed reads this long (s) are a reported dropout: ten samples at 100 Hz; shorter only counted.
DROPOUT_REPORT_S = 0.1
#: Latency timer (ms) on the simulator: a reply awaited ~52 ms rides out a loaded machine's bursts.
SIM_LATENCY_TIMER_MS = 25.0


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
    ended_by: str = ""
    fault: str = ""
    guidance: Guidance | None = None
    dropouts: list[str] = field(default_factory=list)
    twist: TwistGuidance | None = None  # a three-servo rig: where the twist is untaught
    edge_checked: bool = False  # whether the learned edge's support was checked at the end

    @property
    def exit_code(self) -> int:
        """0 for a recording that ended as asked (Enter, signal, duration), 3 for a bus failure."""
        return 3 if self.fault else 0

    @property
    def rate_hz(self) -> float:
        return self.samples / self.elapsed_s if self.elapsed_s > 0 else 0.0

    def lines(self) -> list[str]:
        out = [
            f"ended by           {self.ended_by}" + (f": {self.fault}" if self.fault else ""),
            f"samples            {self.samples} in {self.elapsed_s:.1f} s ({self.rate_hz:.1f} Hz)",
            f"angular spread     {self.spread_deg:.1f} deg from the mean direction",
            f"failed reads       {self.failed_reads}",
        ]
        out.extend(f"dropout            {dropout}" for dropout in self.dropouts)
        if self.guidance:
            out.extend(f"hole               {hole.line()}" for hole in self.guidance.holes)
            out.append(f"guide              {guide_words(self.guidance, self.twist)}")
            out.extend(
                f"edge unsupported   {stretch.request()} ({stretch.length_deg:.1f} deg of edge "
                f"up to {stretch.distance_deg:.1f} deg from every sample)"
                for stretch in self.guidance.unsupported
            )
            out.extend(f"edge held          {stretch.line()}" for stretch in self.guidance.settled)
            if self.guidance.ready and not self.edge_checked:
                out.append(
                    "edge support       not checked (the training's kernels are still compiling "
                    "on this first run); limbctl train lists any stretch the samples leave open"
                )
        if self.twist:
            out.append(f"guide              {self.twist.line()}")
        if self.fault:
            out.append(f"FAULT: the recording ended early: {self.fault} (the samples are kept)")
        return out


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


def check_rate(rate_hz: float) -> None:
    """Refuse a sampling rate (Hz) below :data:`MIN_RATE_HZ` (or not a number) with a ConfigError
    naming the least rate; callers check before any file or port is opened."""
    if not (math.isfinite(rate_hz) and rate_hz >= MIN_RATE_HZ):
        raise ConfigError(f"--rate: record at {MIN_RATE_HZ:.0f} Hz or faster, got {rate_hz:g}")


def record(
    limb: Backdrivable,
    writer: DatasetWriter,
    rate_hz: float = MIN_RATE_HZ,
    duration_s: float | None = None,
    stop: threading.Event | None = None,
    progress: IO[str] | None = None,
    on_guidance: Callable[[Guidance], None] | None = None,
    on_twist: Callable[[TwistGuidance], None] | None = None,
) -> RecordSummary:
    """Switch torque off and record ``limb`` into the open ``writer`` until ``stop`` is set (Ctrl-C,
    Enter) or ``duration_s`` passes, drawing a progress line to ``progress``, sampling at
    ``rate_hz`` (Hz, at least :data:`MIN_RATE_HZ`). ``on_guidance``, ``on_twist`` are called in the
    recording thread (keep them quick) with each Guidance and (three servos) TwistGuidance, every
    GUIDE_EVERY_S and at the end."""
    check_rate(rate_hz)
    with EdgeSupport() as support:
        stop = stop or threading.Event()
        period = 1.0 / rate_hz
        guide = Guide(support=support)
        twist_guide = TwistGuide()
        summary = RecordSummary()
        limb.set_torque(False)

        on_terminal = progress is not None and progress.isatty()
        draw_every = GUIDE_EVERY_S if on_terminal else LOG_EVERY_S
        start = time.perf_counter()
        next_tick = start
        last_guide = last_draw = start
        guidance = guide.assess()
        twist: TwistGuidance | None = None
        if progress is not None:
            progress.write("torque off: move the limb by hand (Enter or Ctrl-C stops)\n")
        failed_in_a_row = 0
        silent_since, silent_servo = 0.0, None
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
                pose = limb.read_pose()
            except BusError as exc:
                summary.failed_reads += 1
                failed_in_a_row += 1
                if failed_in_a_row == 1:
                    silent_since, silent_servo = elapsed, exc.servo_id
                if failed_in_a_row >= MAX_FAILED_READS:
                    summary.ended_by = "bus failure"
                    summary.fault = f"{MAX_FAILED_READS} reads in a row failed, the last: {exc}"
                    break
            else:
                if failed_in_a_row and elapsed - silent_since >= DROPOUT_REPORT_S:
                    who = f"servo {silent_servo}" if silent_servo is not None else "the bus"
                    dropout = (
                        f"{who} silent {elapsed - silent_since:.3f} s from {silent_since:.1f} s "
                        f"({failed_in_a_row} reads failed)"
                    )
                    summary.dropouts.append(dropout)
                    if progress is not None:
                        progress.write(f"\n{dropout}; recording on\n")
                failed_in_a_row = 0
                pan, tilt = pose[0], pose[1]
                # a three-servo rig's sample is its full orientation, twist included
                full = None if len(pose) == 2 else pose_quat_scalar(*pose)
                writer.append(elapsed, pan, tilt, full)
                if full is not None:
                    twist_guide.add(full)
                guide.add(elapsed, pan, tilt)
                summary.samples += 1
            if now - last_guide >= GUIDE_EVERY_S and (progress is not None or on_guidance):
                last_guide = now
                guidance = guide.assess()
                if on_guidance is not None:
                    on_guidance(guidance)
                if twist_guide.samples:
                    twist = twist_guide.assess()
                    if on_twist is not None:
                        on_twist(twist)
            if progress is not None and now - last_draw >= draw_every:
                last_draw = now
                _draw(progress, guidance, summary, elapsed, duration_s, on_terminal, twist)
            # a late sample is followed at once, keeping the rate; a second behind restarts it
            next_tick += period
            delay = next_tick - time.perf_counter()
            if delay > 0:
                stop.wait(delay)
            elif delay < -1.0:
                next_tick = time.perf_counter()

        summary.elapsed_s = time.perf_counter() - start
        summary.guidance = guide.assess(final=True)
        summary.edge_checked = support.stretches is not None
        summary.spread_deg = summary.guidance.spread_deg
        if twist_guide.samples:  # the band's support, checked on every sample (twist_guide)
            twist_guide.check_support()
        twist = twist_guide.assess() if twist_guide.samples else None
        if twist is not None and twist.cells:
            summary.twist = twist
        if on_guidance is not None:
            on_guidance(summary.guidance)
        if on_twist is not None and twist is not None:
            on_twist(twist)
        if progress is not None:
            elapsed = summary.elapsed_s
            _draw(progress, summary.guidance, summary, elapsed, duration_s, on_terminal, twist)
            if on_terminal:
                progress.write("\n")
                progress.flush()
        return summary


def guide_words(guidance: Guidance, twist: TwistGuidance | None) -> str:
    """The swing guide's line; on a three-servo rig READY waits for the twist guide too."""
    if twist is None or twist.complete:
        return guidance.line()
    return guidance.line().replace("READY TO TRAIN", "twist still to teach")


def _draw(
    stream: IO[str],
    guidance: Guidance,
    summary: RecordSummary,
    elapsed: float,
    duration_s: float | None,
    on_terminal: bool,
    twist: TwistGuidance | None = None,
) -> None:
    """One progress line (time, samples, failed reads, the guides' lines), in place on a tty."""
    total = f"/{duration_s:.0f}" if duration_s else ""
    failed = f"  failed reads {summary.failed_reads}" if summary.failed_reads else ""
    words = guide_words(guidance, twist)
    line = f"{elapsed:5.1f}{total} s  {summary.samples} samples{failed}  {words}"
    if twist is not None:  # a terminal's line is rewritten in place: the short form there
        line += f"  {twist.short() if on_terminal else twist.line()}"
    if on_terminal:
        stream.write("\r" + line + "\x1b[K")
    else:
        stream.write(line + "\n")
    stream.flush()
