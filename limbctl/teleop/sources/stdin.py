"""Command source ``stdin``: JSON lines on standard input (or any binary stream)."""

from __future__ import annotations

import os
import select
import sys
from typing import BinaryIO

from limbctl.teleop.commands import MAX_LINE_BYTES
from limbctl.teleop.sources.base import WAKE_INTERVAL_S, CommandSource

#: Most bytes taken per read: the size of a Linux pipe's buffer, so one read drains it.
READ_CHUNK_BYTES = 65536


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
