"""The server on its own: the protocol, start/stop, port errors, slow and vanished browsers."""

from __future__ import annotations

import base64
import contextlib
import fcntl
import json
import os
import socket
import termios
import threading
import time
import urllib.error
import urllib.request

import pytest
import websocket

from limbctl.view import Board, Live, PanTilt, Scene, ViewServer

#: Longest wait (s) for a message in these tests.
WAIT_S = 10.0


def connect(server: ViewServer) -> websocket.WebSocket:
    """A WebSocket client (websocket-client) on the server's push channel."""
    return websocket.create_connection(
        server.url.replace("http://", "ws://") + "ws", timeout=WAIT_S
    )


def receive(client: websocket.WebSocket, timeout: float = WAIT_S) -> dict:
    client.settimeout(timeout)
    return json.loads(client.recv())


def test_serves_the_page_and_the_newest_state_pushes_only_newer_versions_and_stop_frees_the_port():
    board = Board()
    with ViewServer(board, port=0) as server:
        page = urllib.request.urlopen(server.url, timeout=WAIT_S).read().decode()
        assert "<canvas" in page and "view.js" in page
        script = urllib.request.urlopen(server.url + "view.js", timeout=WAIT_S).read().decode()
        assert "new WebSocket" in script
        assert "http://" not in script and "https://" not in script  # nothing from the internet
        with pytest.raises(urllib.error.HTTPError) as refused:
            urllib.request.urlopen(server.url + "secrets.txt", timeout=WAIT_S)
        assert refused.value.code == 404
        assert json.loads(urllib.request.urlopen(server.url + "state.json").read()) == {}
        board.publish_live(Live(mode="demo: teach", sample_count=42))
        state = json.loads(urllib.request.urlopen(server.url + "state.json").read())
        assert state["live"]["sample_count"] == 42 and "scene" not in state, "not the newest state"
        # a browser connecting is sent the scene, then the live state
        board.publish_scene(Scene(samples_deg=[[1.0, 2.0]], region_note="n"))
        board.publish_live(Live(mode="record", pose=PanTilt(1.0, 2.0), sample_count=1))
        client = connect(server)
        first, second = receive(client), receive(client)
        assert first["kind"] == "scene" and first["samples"] == [[1.0, 2.0]]
        assert second == {
            "kind": "live",
            "mode": "record",
            "pose": [1.0, 2.0],
            "sample_count": 1,
            "teleop": None,
            "fault": "",
            "note": "",
        }
        # nothing new: nothing sent
        with pytest.raises(websocket.WebSocketTimeoutException):
            receive(client, timeout=0.3)
        # many publishes between two pushes: only the newest arrives
        for count in range(2, 1000):
            board.publish_live(Live(mode="record", sample_count=count))
        counts = []
        while not counts or counts[-1] != 999:
            counts.append(receive(client)["sample_count"])
        assert len(counts) < 100, "stale frames were queued instead of dropped"
        assert counts == sorted(counts)
        # stop closes the connected browsers and frees the port
        closed = threading.Event()

        def read_until_closed():
            try:
                while True:
                    receive(client)
            except Exception:
                closed.set()

        reader = threading.Thread(target=read_until_closed)
        reader.start()
        server.stop()
        assert closed.wait(WAIT_S), "the browser's connection stayed open after stop"
        reader.join(WAIT_S)
        client.close()
    assert not server.running
    port = int(server.url.rstrip("/").rsplit(":", 1)[1])
    with socket.socket() as probe:
        # free again: nobody listens (closed connections may linger in TIME_WAIT, as for any
        # server, hence SO_REUSEADDR, which a listener still there would make bind refuse)
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        probe.bind(("127.0.0.1", port))
        probe.listen()


def test_a_stalled_browser_does_not_slow_the_producer_nor_the_others():
    """A client that completes the handshake and never reads; the producer publishes big scenes."""
    board = Board()
    big = Scene(samples_deg=[[i * 0.01, i * 0.02] for i in range(4000)])
    with ViewServer(board, port=0) as server:
        host, port = server.url[len("http://") :].rstrip("/").split(":")
        stalled = socket.create_connection((host, int(port)), timeout=WAIT_S)
        stalled.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        key = base64.b64encode(os.urandom(16)).decode()
        stalled.sendall(
            (
                f"GET /ws HTTP/1.1\r\nHost: {host}:{port}\r\nUpgrade: websocket\r\n"
                f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
                "Sec-WebSocket-Version: 13\r\n\r\n"
            ).encode()
        )
        assert b"101" in stalled.recv(12)
        with contextlib.closing(connect(server)) as healthy:
            # 2 s of publishing: the server offers the stalled client ~50 scenes of ~60 kB, far
            # more than its socket buffers hold, while the healthy one keeps receiving
            durations = []
            scenes_seen = 0
            healthy.settimeout(0.001)
            started = time.perf_counter()
            while time.perf_counter() - started < 2.0:
                before = time.perf_counter()
                board.publish_scene(big)
                board.publish_live(Live(mode="record", sample_count=len(durations)))
                durations.append(time.perf_counter() - before)
                try:
                    scenes_seen += json.loads(healthy.recv())["kind"] == "scene"
                except websocket.WebSocketTimeoutException:
                    pass
            last = len(durations) - 1
            seen = -1
            while seen != last:
                message = receive(healthy)
                scenes_seen += message["kind"] == "scene"
                if message["kind"] == "live":
                    seen = message["sample_count"]
        unread = int.from_bytes(fcntl.ioctl(stalled, termios.FIONREAD, b"\0" * 4), "little")
        stalled.close()
        # the stalled client's buffer filled before even one whole scene fit: its sender is stuck
        scene_bytes = len(json.dumps(big.to_json(), separators=(",", ":")))
        assert 0 < unread < scene_bytes, f"{unread} bytes unread, a scene is {scene_bytes}"
        # a publish pair is a lock and two swaps (~3 us); a mean of 1 ms would mean it waited
        mean = sum(durations) / len(durations)
        assert mean < 1e-3, f"a publish took {mean * 1e6:.0f} us on average"
        assert scenes_seen >= 10, f"the healthy browser got only {scenes_seen} scenes in 2 s"
