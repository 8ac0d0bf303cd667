"""What every command source shares: a reader thread's queue, and counts of refused input."""

from __future__ import annotations

import queue
import threading
from dataclasses import dataclass, field

from limbctl.errors import InvalidInputError
from limbctl.teleop.commands import Command, parse_command
from limbctl.teleop.refusals import Refusals

#: How often (s) a waiting reader checks for close: a prompt close, 10 wake-ups a second.
WAKE_INTERVAL_S = 0.1
#: Longest wait (s) for a reader to end on close: many wake intervals (a daemon thread).
CLOSE_WAIT_S = 2.0


@dataclass
class SourceStats:
    """Counts kept by every source; ``refusals`` keeps why lines were refused."""

    accepted: int = 0
    rejected: int = 0
    refusals: Refusals = field(default_factory=Refusals)

    def reject(self, reason: str, line: bytes | str = b"", line_no: int = 0) -> None:
        """Count one refused input: the parser's ``reason``, the ``line`` and its number."""
        self.rejected += 1
        self.refusals.add(reason, line, line_no)


class CommandSource:
    """Base: a queue filled by a reader thread; ``latest_only``: follow the newest command only."""

    name = "source"
    latest_only = False
    #: A person steers it: the status line then shows poses and the gate's outcome in words.
    explains = False
    #: True on a three-servo rig: lines keep their twist (``parse_command(..., twist=True)``).
    twist = False

    def __init__(self) -> None:
        self.stats = SourceStats()
        self._lines_fed = 0  # lines handed to feed, for the line numbers of refused ones
        self._queue: queue.SimpleQueue[Command | None] = queue.SimpleQueue()
        self._stop = threading.Event()
        self._ended = threading.Event()
        self._thread: threading.Thread | None = None

    def __enter__(self) -> CommandSource:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def start(self) -> None:
        if self._thread is None:
            self._thread = threading.Thread(target=self._run_guarded, name=self.name, daemon=True)
            self._thread.start()

    def close(self) -> None:
        """Stop the reader; safe to call twice."""
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=CLOSE_WAIT_S)

    def _run_guarded(self) -> None:
        try:
            self._run()
        finally:
            self._ended.set()
            self._queue.put(None)

    def _run(self) -> None:  # pragma: no cover - every subclass overrides it
        raise RuntimeError("subclasses implement _run")

    def feed(self, line: bytes | str) -> None:
        """Parse one line and queue it, or count the rejection."""
        self._lines_fed += 1
        text = line.strip()
        if not text:
            return
        try:
            command = parse_command(text, twist=self.twist)
        except InvalidInputError as exc:
            self.stats.reject(str(exc), text, self._lines_fed)
            return
        self.offer(command)

    def offer(self, command: Command) -> None:
        """Queue a command built from numbers (already validated) and count it."""
        self.stats.accepted += 1
        self._queue.put(command)

    def feel(self, gate: object, result: object, bus_ok: bool) -> tuple[str, ...]:
        """Called by the loop after each cycle's gate and write; notices for the operator."""
        return ()

    def release(self) -> None:
        """Called by the loop on a fault: stop pushing on the operator at once."""

    def report_lines(self) -> tuple[str, ...]:
        """Lines for the session's report (none for most sources)."""
        return ()

    def describe(self) -> str:
        """What the status line should say about the source itself ("" for nothing)."""
        return ""

    @property
    def finished(self) -> bool:
        """True once the input ended and every queued command was polled."""
        return self._ended.is_set() and self._queue.empty()

    def wait_finished(self, timeout: float) -> bool:
        """Block until the input ends (for tests and batch use); True if it did."""
        return self._ended.wait(timeout)

    def poll(self, timeout: float = 0.0) -> list[Command]:
        """Every command parsed since the last call, oldest first, waiting up to ``timeout`` s."""
        out: list[Command] = []
        if timeout > 0:
            try:
                item = self._queue.get(timeout=timeout)
            except queue.Empty:
                return out
            if item is not None:
                out.append(item)
            else:
                self._queue.put(None)  # keep the end marker for later polls
        while True:
            try:
                item = self._queue.get_nowait()
            except queue.Empty:
                return out
            if item is not None:
                out.append(item)
