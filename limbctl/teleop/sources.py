"""Command sources for teleoperation: stdin, UDP, replay, keyboard (the leader gimbal is in
:mod:`limbctl.teleop.leader`, since it needs a bus).

Each source is a context manager. A reader thread parses lines as they arrive (see
:mod:`limbctl.teleop.commands`) and the control loop calls :meth:`CommandSource.poll` once per
cycle, which never blocks. Malformed input is counted and its reason kept, never forwarded.

Choose a source by name with :func:`open_source`::

    stdin                  JSON lines on standard input
    udp://127.0.0.1:PORT   the same lines as UDP datagrams (loopback unless told otherwise)
    replay:FILE            JSON lines from a file, paced by their "t" (seconds) when present
    keyboard               arrow keys in the terminal (q quits)
    leader:ID,ID           a second gimbal moved by hand (handled by limbctl.teleop.leader)
"""

from __future__ import annotations

import math
import os
import queue
import select
import socket
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO

from limbctl.errors import ConfigError, InvalidInputError
from limbctl.teleop.commands import MAX_LINE_BYTES, Command, parse_command


@dataclass
class SourceStats:
    """Counts kept by every source; read by the loop's status line and telemetry."""

    accepted: int = 0
    rejected: int = 0
    last_rejection: str = ""
    rejections: dict[str, int] = field(default_factory=dict)

    def reject(self, reason: str) -> None:
        self.rejected += 1
        self.last_rejection = reason
        key = reason.split(":")[0][:60]
        self.rejections[key] = self.rejections.get(key, 0) + 1


class CommandSource:
    """Base: a queue filled by a reader thread; ``poll`` drains it without blocking.

    ``latest_only`` tells the control loop how to use what arrives: a realtime source (UDP,
    keyboard, leader) is followed by its newest command only; a scripted stream (stdin,
    replay) is gated command by command.
    """

    name = "source"
    latest_only = False

    def __init__(self) -> None:
        self.stats = SourceStats()
        self._queue: queue.SimpleQueue[Command | None] = queue.SimpleQueue()
        self._stop = threading.Event()
        self._ended = threading.Event()
        self._thread: threading.Thread | None = None

    # -- lifecycle --------------------------------------------------------------------------
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
            self._thread.join(timeout=2.0)

    def _run_guarded(self) -> None:
        try:
            self._run()
        finally:
            self._ended.set()
            self._queue.put(None)

    def _run(self) -> None:  # pragma: no cover - every subclass overrides it
        raise RuntimeError("subclasses implement _run")

    # -- input ------------------------------------------------------------------------------
    def feed(self, line: bytes | str) -> None:
        """Parse one line and queue it, or count the rejection."""
        text = line.strip() if isinstance(line, str) else line.strip()
        if not text:
            return
        try:
            command = parse_command(text)
        except InvalidInputError as exc:
            self.stats.reject(str(exc))
            return
        self.stats.accepted += 1
        self._queue.put(command)

    @property
    def finished(self) -> bool:
        """True once the input ended and every queued command was polled."""
        return self._ended.is_set() and self._queue.empty()

    def wait_finished(self, timeout: float) -> bool:
        """Block until the input ends (for tests and batch use); True if it did."""
        return self._ended.wait(timeout)

    def poll(self, timeout: float = 0.0) -> list[Command]:
        """Every command parsed since the last call, oldest first.

        With ``timeout`` 0 (the control loop's use) it never blocks; otherwise it waits up to
        ``timeout`` seconds for the first command to arrive.
        """
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


class StreamSource(CommandSource):
    """JSON lines from a binary stream (standard input by default)."""

    name = "stdin"

    def __init__(self, stream: BinaryIO | None = None) -> None:
        super().__init__()
        self._stream = stream if stream is not None else sys.stdin.buffer
        self._skip_to_newline = False

    def _run(self) -> None:
        fd = self._stream.fileno()
        buffer = b""
        while not self._stop.is_set():
            ready, _, _ = select.select([fd], [], [], 0.1)
            if not ready:
                continue
            chunk = os.read(fd, 65536)
            if not chunk:
                break
            buffer += chunk
            *lines, buffer = buffer.split(b"\n")
            for line in lines:
                self._feed_bounded(line)
            if len(buffer) > MAX_LINE_BYTES:
                self.stats.reject(f"line longer than {MAX_LINE_BYTES} bytes")
                buffer = b""
                self._skip_to_newline = True
        if buffer.strip():
            self._feed_bounded(buffer)

    def _feed_bounded(self, line: bytes) -> None:
        if self._skip_to_newline:  # the tail of an oversize line already rejected
            self._skip_to_newline = False
            return
        self.feed(line)


class UdpSource(CommandSource):
    """JSON datagrams on a UDP port; binds to loopback unless a host is given.

    Oversize datagrams (more than ``MAX_LINE_BYTES``) are dropped and counted.
    """

    name = "udp"
    latest_only = True

    def __init__(self, host: str = "127.0.0.1", port: int = 0) -> None:
        super().__init__()
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self._sock.bind((host, port))
        except OSError as exc:
            self._sock.close()
            raise ConfigError(f"cannot listen on udp://{host}:{port}: {exc}") from exc
        self._sock.settimeout(0.1)
        self.address = self._sock.getsockname()

    def _run(self) -> None:
        try:
            while not self._stop.is_set():
                try:
                    data = self._sock.recv(MAX_LINE_BYTES + 1)
                except TimeoutError:
                    continue
                except OSError:
                    break
                if len(data) > MAX_LINE_BYTES:
                    self.stats.reject(f"datagram longer than {MAX_LINE_BYTES} bytes")
                    continue
                for line in data.split(b"\n"):
                    self.feed(line)
        finally:
            self._sock.close()

    @property
    def finished(self) -> bool:
        """A network source never ends by itself."""
        return False


class ReplaySource(CommandSource):
    """JSON lines from a file, paced: a line with ``"t"`` (s) is released at that time after the
    first stamped line; lines without it follow the previous one after ``1 / rate_hz``.
    """

    name = "replay"

    def __init__(self, path: str | Path, speed: float = 1.0, rate_hz: float = 100.0) -> None:
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
                stamp = _peek_time(raw)
                if stamp is not None:
                    t0 = stamp if t0 is None else t0
                    due = start + (stamp - t0) / self.speed
                else:
                    due += 1.0 / (self.rate_hz * self.speed)
                # wait for the line's time, waking at once if the source is closed
                self._stop.wait(max(0.0, due - time.monotonic()))
                self.feed(raw)


def _peek_time(raw: bytes) -> float | None:
    try:
        return parse_command(raw).t
    except InvalidInputError:
        return None


class KeyboardSource(CommandSource):
    """Arrow keys in the terminal nudge pan/tilt by ``step_deg``; ``q`` ends the session.

    Up/down raise/lower the limb (tilt), left/right turn it (pan; left is +pan, toward +y).
    ``tty_path`` is the terminal to read (the controlling terminal by default).
    """

    name = "keyboard"
    latest_only = True
    _KEYS = {b"\x1b[A": (0, 1), b"\x1b[B": (0, -1), b"\x1b[C": (-1, 0), b"\x1b[D": (1, 0)}

    def __init__(
        self,
        step_deg: float = 2.0,
        start_deg: tuple[float, float] = (0.0, 0.0),
        tty_path: str = "/dev/tty",
    ) -> None:
        super().__init__()
        import termios
        import tty

        self._fd = -1
        try:
            fd = os.open(tty_path, os.O_RDONLY | os.O_NOCTTY)
        except OSError as exc:
            raise ConfigError("keyboard source needs a terminal; use --source stdin") from exc
        try:
            # key by key from now on (no line buffering): keys pressed before the reader thread
            # runs are kept, not held back in a half-typed line
            self._saved = termios.tcgetattr(fd)
            tty.setcbreak(fd)
        except termios.error as exc:
            os.close(fd)
            raise ConfigError(f"{tty_path} is not a terminal; use --source stdin") from exc
        self._fd = fd
        self.step_deg = step_deg
        self.pan_deg, self.tilt_deg = start_deg

    def close(self) -> None:
        """Stop the reader and give the terminal back as it was; safe to call twice."""
        super().close()
        if self._thread is None:  # never started: the reader's own clean-up did not run
            self._release()

    def _release(self) -> None:
        import termios

        if self._fd >= 0:
            termios.tcsetattr(self._fd, termios.TCSADRAIN, self._saved)
            os.close(self._fd)
            self._fd = -1

    def _run(self) -> None:
        pending = b""
        try:
            while not self._stop.is_set():
                ready, _, _ = select.select([self._fd], [], [], 0.1)
                if not ready:
                    continue
                pending += os.read(self._fd, 64)
                # split the bytes into keys: an escape sequence is three bytes, others one
                while pending:
                    size = 3 if pending[:1] == b"\x1b" else 1
                    if len(pending) < size:
                        break
                    key, pending = pending[:size], pending[size:]
                    if key in (b"q", b"\x04"):
                        return
                    move = self._KEYS.get(key)
                    if move is None:
                        continue
                    self.pan_deg = min(max(self.pan_deg + move[0] * self.step_deg, -180.0), 180.0)
                    self.tilt_deg = min(max(self.tilt_deg + move[1] * self.step_deg, -90.0), 90.0)
                    self.feed(f'{{"pan": {self.pan_deg}, "tilt": {self.tilt_deg}}}')
        finally:
            self._release()


SOURCE_FORMS = ("stdin", "udp://HOST:PORT", "replay:FILE", "keyboard", "leader:ID,ID")


def open_source(spec: str) -> CommandSource:
    """Build a command source from its name (``leader:`` is built by the teleop job).

    Raises
    ------
    ConfigError
        For an unknown or malformed name, listing the accepted forms.
    """
    if spec == "stdin":
        return StreamSource()
    if spec == "keyboard":
        return KeyboardSource()
    if spec.startswith("replay:"):
        return ReplaySource(spec[len("replay:") :])
    if spec.startswith("udp://"):
        host, sep, port = spec[len("udp://") :].rpartition(":")
        if not sep or not port.isdigit() or not host:
            raise ConfigError(f"bad UDP source {spec!r}; expected udp://127.0.0.1:PORT")
        return UdpSource(host, int(port))
    raise ConfigError(f"unknown source {spec!r}; choose one of {', '.join(SOURCE_FORMS)}")
