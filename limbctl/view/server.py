"""The live view's web server: the page, its assets and a WebSocket per browser."""

from __future__ import annotations

import asyncio
import json
import threading
import weakref
from importlib import resources

from aiohttp import web

from limbctl.errors import ConfigError
from limbctl.view.control import (
    MAX_MESSAGE_BYTES,
    Access,
    ControlDesk,
    check_request,
    describe_peer,
    read_commands,
    tab_of,
)
from limbctl.view.state import Board

#: How often each browser's coroutine looks for a newer state (s): twice the page's 5 Hz promise.
PUSH_PERIOD_S = 0.1
#: WebSocket ping interval (s): a browser that stops answering is dropped within two of these.
HEARTBEAT_S = 5.0
#: Longest wait (s) for the server thread to bind its port or to stop.
START_STOP_TIMEOUT_S = 10.0
#: The page's files (package data in limbctl/view/assets) and their content types.
ASSETS = {
    "index.html": "text/html",
    "view.js": "application/javascript",
    "control.js": "application/javascript",
    "twist.js": "application/javascript",
    "leader.js": "application/javascript",
    "view.css": "text/css",
}
DEFAULT_HOST = "127.0.0.1"
#: The view's usual port; when it is taken and no port was asked for, any free port is used.
DEFAULT_PORT = 8765


class _JsonCache:
    """The JSON text of the newest scene and live state, made once per version."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._texts: dict[str, tuple[int, str]] = {}

    def text(self, part: str, version: int, value) -> str:
        with self._lock:
            cached = self._texts.get(part)
            if cached is not None and cached[0] == version:
                return cached[1]
        text = json.dumps(value.to_json(), separators=(",", ":"))
        with self._lock:
            self._texts[part] = (version, text)
        return text


def build_app(
    board: Board,
    access: Access | None = None,
    desk: ControlDesk | None = None,
    heartbeat_s: float = HEARTBEAT_S,
) -> web.Application:
    """The aiohttp application serving ``board`` (``/``, the assets, ``/ws``, ``/state.json``) to
    whom ``access`` allows, ``desk`` the controller slot, ``heartbeat_s`` (s) the WebSocket ping
    interval."""
    access = access or Access.for_host(DEFAULT_HOST)
    desk = desk or ControlDesk()
    app = web.Application()
    cache = _JsonCache()
    sockets: weakref.WeakSet[web.WebSocketResponse] = weakref.WeakSet()
    assets = resources.files("limbctl.view") / "assets"

    def allowed(request: web.Request, websocket: bool = False):
        verdict = check_request(request, access, websocket)
        if not verdict.watch:
            raise web.HTTPForbidden(text=verdict.problem)
        return verdict

    async def page(request: web.Request) -> web.Response:
        name = request.match_info.get("name") or "index.html"
        if name == "index.html":
            allowed(request)
        if name not in ASSETS:
            raise web.HTTPNotFound(text=f"no such file: {name}; the page has {sorted(ASSETS)}")
        body = (assets / name).read_bytes()
        return web.Response(
            body=body, content_type=ASSETS[name], headers={"Cache-Control": "no-store"}
        )

    async def state(request: web.Request) -> web.Response:
        allowed(request)
        snap = board.snapshot()
        parts = {}
        if snap.scene is not None:
            parts["scene"] = json.loads(cache.text("scene", snap.scene_version, snap.scene))
        if snap.live is not None:
            parts["live"] = json.loads(cache.text("live", snap.live_version, snap.live))
        return web.json_response(parts)

    async def stream(request: web.Request) -> web.WebSocketResponse:
        verdict = allowed(request, websocket=True)
        socket = web.WebSocketResponse(heartbeat=heartbeat_s, max_msg_size=MAX_MESSAGE_BYTES)
        await socket.prepare(request)
        sockets.add(socket)
        token = object()  # this page, as the controller slot knows it
        tab, name, want = tab_of(request)
        who = describe_peer(request, name)
        if verdict.steer and want != "watch":  # a person opened or reloaded the page
            desk.claim(token, who, tab, reload=want == "reload")

        def clicked(asked: str) -> None:  # a person's click on this page
            if asked == "take":
                desk.claim(token, describe_peer(request, name), tab)
            else:
                desk.release(token)

        steer_clicks = clicked if verdict.steer else None
        reader = asyncio.ensure_future(read_commands(socket, desk, token, steer_clicks))
        sent_scene = sent_live = sent_control = 0
        try:
            while not socket.closed and not reader.done():
                if desk.version != sent_control:
                    sent_control = desk.version
                    await socket.send_str(_control_text(desk, token, verdict.steer))
                snap = board.snapshot()
                if snap.scene is not None and snap.scene_version != sent_scene:
                    await socket.send_str(cache.text("scene", snap.scene_version, snap.scene))
                    sent_scene = snap.scene_version
                if snap.live is not None and snap.live_version != sent_live:
                    await socket.send_str(cache.text("live", snap.live_version, snap.live))
                    sent_live = snap.live_version
                await asyncio.sleep(PUSH_PERIOD_S)
        except (ConnectionError, RuntimeError):
            pass  # the browser went away mid-send: nothing to do but stop serving it
        finally:
            reader.cancel()
            desk.release(token)
            await socket.close()
        return socket

    async def close_sockets(app: web.Application) -> None:
        for socket in list(sockets):
            await socket.close(message=b"server stopping")

    app.router.add_get("/", page)
    app.router.add_get("/ws", stream)
    app.router.add_get("/state.json", state)
    app.router.add_get("/{name}", page)
    app.on_shutdown.append(close_sockets)
    return app


def _control_text(desk: ControlDesk, token: object, keyed: bool) -> str:
    """The control message a page gets: whether it steers, and what it is told."""
    steer, told = desk.told(token, keyed)
    return json.dumps({"kind": "control", "keyed": keyed, "steer": steer, "told": told})


class ViewServer:
    """The live view served from a background thread (a context manager; ``port`` 0: any):
    :attr:`url` watches, :attr:`control_url` steers (with the key); the rest as for
    :func:`build_app`."""

    def __init__(
        self,
        board: Board,
        host: str = DEFAULT_HOST,
        port: int = DEFAULT_PORT,
        desk: ControlDesk | None = None,
        heartbeat_s: float = HEARTBEAT_S,
    ) -> None:
        self.board = board
        self.heartbeat_s = heartbeat_s
        self.host = host
        self.port = port
        self.desk = desk or ControlDesk()
        self.access = Access.for_host(host)
        self.url = self.control_url = ""
        self._thread: threading.Thread | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop: asyncio.Event | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None

    def __enter__(self) -> ViewServer:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def start(self) -> None:
        """Bind and serve; returns once :attr:`url` is known (ConfigError if it cannot)."""
        self._thread = threading.Thread(target=self._run, name="limbctl-view", daemon=True)
        self._thread.start()
        if not self._ready.wait(START_STOP_TIMEOUT_S):
            raise ConfigError(f"the live view did not start within {START_STOP_TIMEOUT_S:.0f} s")
        if self._error is not None:
            self._thread.join(START_STOP_TIMEOUT_S)
            raise ConfigError(
                f"the live view cannot serve on {self.host}:{self.port} ({self._error}); "
                "pick another port with --view-port (0 lets the system choose) or pass --no-view"
            ) from self._error

    def stop(self) -> None:
        """Close every browser's connection and the port, and end the thread."""
        if self._thread is None:
            return
        if self._loop is not None and self._stop is not None and self._thread.is_alive():
            self._loop.call_soon_threadsafe(self._stop.set)
        self._thread.join(START_STOP_TIMEOUT_S)
        self._thread = None

    @property
    def running(self) -> bool:
        """Whether the server thread is alive."""
        return self._thread is not None and self._thread.is_alive()

    def _run(self) -> None:
        try:
            asyncio.run(self._serve())
        except BaseException as error:  # reported to start(); the thread must not die silently
            self._error = error
            self._ready.set()

    async def _serve(self) -> None:
        self._loop = asyncio.get_running_loop()
        self._stop = asyncio.Event()
        runner = web.AppRunner(
            build_app(self.board, self.access, self.desk, self.heartbeat_s),
            handle_signals=False,
            access_log=None,
            shutdown_timeout=1.0,
        )
        await runner.setup()
        try:
            site = web.TCPSite(runner, self.host, self.port)
            await site.start()
            host, port = runner.addresses[0][:2]
            base = f"http://{host}:{port}/"
            self.control_url = f"{base}?key={self.access.secret}"
            watching = f"{base}?watch={self.access.watch_secret}"
            self.url = watching if self.access.watch_needs_key else base
            self._ready.set()
            await self._stop.wait()
        finally:
            await runner.cleanup()
