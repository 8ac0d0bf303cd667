"""The command sources of JSON lines: ``stdin``, ``udp://HOST:PORT``, ``replay:FILE``, ``page``."""

from __future__ import annotations

import math
import os
import select
import socket
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO

from limbctl.errors import ConfigError, InvalidInputError
from limbctl.teleop.commands import MAX_LINE_BYTES, parse_command
from limbctl.teleop.sources.base import WAKE_INTERVAL_S, CommandSource

#: Most bytes taken per read: the size of a Linux pipe's buffer, so one read drains it.
READ_CHUNK_BYTES = 65536
#: Rate (lines/s) of lines without a ``"t"``: half the loop's 200 Hz, so each is gated, not skipped.
UNSTAMPED_RATE_HZ = 100.0
#: Attaches a text sink to the page's controller, returns the detach and a "who holds control".
Connect = Callable[[Callable[[str], None]], tuple[Callable[[], None], Callable[[], str]]]


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
            ready, _, _ = select.select([fd], [], [], WAKE_INTERVAL_S)
            if not ready:
                continue
            chunk = os.read(fd, READ_CHUNK_BYTES)
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
    """JSON datagrams on a UDP port (loopback unless a host is given); oversize ones counted."""

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
        self._sock.settimeout(WAKE_INTERVAL_S)
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


class PageSource(CommandSource):
    """Commands from the page that holds control of the live view (``connect``: :data:`Connect`)."""

    name = "page"
    latest_only = True
    explains = True

    def __init__(self, connect: Connect) -> None:
        super().__init__()
        self._connect = connect
        self._holder: Callable[[], str] = lambda: "nobody"

    def describe(self) -> str:
        """Who steers, for the status line."""
        return f"page: {self._holder()}"

    def _run(self) -> None:
        detach, self._holder = self._connect(self.feed)
        try:
            # the text arrives on the view's thread; this one only waits for the close
            while not self._stop.wait(WAKE_INTERVAL_S):
                pass
        finally:
            detach()
