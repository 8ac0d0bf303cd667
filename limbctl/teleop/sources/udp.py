"""Command source ``udp://HOST:PORT``: JSON lines as UDP datagrams (loopback by default)."""

from __future__ import annotations

import socket

from limbctl.errors import ConfigError
from limbctl.teleop.commands import MAX_LINE_BYTES
from limbctl.teleop.sources.base import WAKE_INTERVAL_S, CommandSource


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
