"""Who may watch the live view and who may steer from it (docs/architecture.md)."""

from __future__ import annotations

import asyncio
import hmac
import ipaddress
import json
import secrets
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from aiohttp import WSMsgType, web

#: Secret length in bytes (URL-safe base64 makes 22 characters): 128 bits, beyond guessing.
SECRET_BYTES = 16
#: Least time (s) between messages handed to the source: half the loop's 200 Hz (newest only).
FORWARD_PERIOD_S = 0.01
#: Largest message a page may send (bytes): a command is under 100; more is refused by closing.
MAX_MESSAGE_BYTES = 4096
#: Host names that mean this machine, accepted in the Host header of a loopback server.
LOOPBACK_NAMES = frozenset({"localhost", "127.0.0.1", "::1", "[::1]"})
#: Longest tab id and name (characters) taken from a page (its own: 32 and ~25; shown to all).
MAX_TAB_ID_CHARS = 64
MAX_TAB_NAME_CHARS = 40
#: What a keyed page may ask for when it connects (see the module's docstring).
WANTS = ("take", "reload", "watch")


def is_loopback(host: str) -> bool:
    """Whether ``host`` (a bind address or name) keeps the server on this machine."""
    if host in LOOPBACK_NAMES:
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


@dataclass(frozen=True)
class Access:
    """The session's secrets: ``secret`` (``?key=``) steers and watches, ``watch_secret``
    (``?watch=``) watches when ``watch_needs_key``; ``loopback``: the Host header is checked."""

    secret: str
    watch_secret: str
    watch_needs_key: bool = False
    loopback: bool = True

    @classmethod
    def for_host(cls, host: str) -> Access:
        """New secrets; watching needs one unless ``host`` is a loopback address."""
        local = is_loopback(host)
        new = secrets.token_urlsafe
        return cls(new(SECRET_BYTES), new(SECRET_BYTES), not local, local)

    def key_ok(self, given: str | None) -> bool:
        """Whether ``given`` is the steering secret (constant-time compare)."""
        return given is not None and hmac.compare_digest(given.encode(), self.secret.encode())

    def watch_ok(self, given: str | None) -> bool:
        """Whether ``given`` is the watching secret (constant-time compare)."""
        return given is not None and hmac.compare_digest(given.encode(), self.watch_secret.encode())


@dataclass(frozen=True)
class Verdict:
    """What a request may do: ``watch``, ``steer``, or neither with the ``problem`` in words."""

    watch: bool
    steer: bool = False
    problem: str = ""


def check_request(request: web.Request, access: Access, websocket: bool) -> Verdict:
    """Judge a request for the page, its state or its WebSocket (module docstring)."""
    key, watch = request.query.get("key"), request.query.get("watch")
    if key is not None and not access.key_ok(key):
        return Verdict(False, problem="wrong key: use the address printed when the view started")
    if watch is not None and not access.watch_ok(watch):
        return Verdict(False, problem="wrong watch key: use the address printed at the start")
    keyed = key is not None
    hostname = request.host.rsplit(":", 1)[0] if request.host else ""
    if access.loopback and hostname not in LOOPBACK_NAMES:
        return Verdict(False, problem=f"host {request.host!r} is not this machine's loopback")
    if access.watch_needs_key and not keyed and watch is None:
        return Verdict(False, problem="this view is served beyond this machine: add ?watch=...")
    if not websocket:
        return Verdict(True)
    origin = request.headers.get("Origin")
    if origin is not None and origin != f"{request.scheme}://{request.host}":
        return Verdict(False, problem=f"refused the WebSocket from another site ({origin})")
    if keyed and origin is None:
        return Verdict(False, problem="steering needs the view's own page (no Origin was sent)")
    return Verdict(True, steer=keyed)


class ControlDesk:
    """The one controller slot and the sink its text goes to (thread-safe)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._sink: Callable[[str], None] | None = None
        self._holder: object | None = None
        self._holder_text = ""
        self._holder_tab = ""  # the holding page's tab id ("" for a program)
        self.version = 0  # bumped whenever who holds control changes
        self.forwarded = 0  # messages handed to the sink
        self.superseded = 0  # messages replaced by a newer one before they were handed on
        self.ignored = 0  # messages from pages that do not hold control

    def attach(self, sink: Callable[[str], None]) -> tuple[Callable[[], None], Callable[[], str]]:
        """Send the controller's text to ``sink``; returns ``(detach, holder)``."""
        with self._lock:
            self._sink = sink
            self.version += 1

        def detach() -> None:
            with self._lock:
                self._sink = None
                self.version += 1

        return detach, self.holder

    def holder(self) -> str:
        """Who steers, in words."""
        with self._lock:
            if self._sink is None:
                return "nobody: this session takes no commands from the page"
            return self._holder_text or "nobody yet: open the address with the key"

    def claim(self, token: object, who: str, tab: str = "", reload: bool = False) -> bool:
        """Give the slot to ``token`` if free or ``reload``-ed by its ``tab``; whether it has it."""
        with self._lock:
            taken = self._holder is not None and self._holder is not token
            same_tab = reload and bool(tab) and tab == self._holder_tab
            if taken and not same_tab:
                return False
            self._holder, self._holder_text, self._holder_tab = token, who, tab
            self.version += 1
            return True

    def told(self, token: object, keyed: bool) -> tuple[bool, str]:
        """Whether ``token`` steers now, and what its page is told about control."""
        with self._lock:
            mine = self._holder is token
            if not keyed:
                who = self._holder_text or "nobody"
                return False, f"watching (steering needs the key); steered by {who}"
            if mine and self._sink is None:
                return False, "you hold control, but this session takes no commands from the page"
            if mine:
                return True, f"you steer the limb from this tab ({self._holder_text})"
            if self._holder is None:
                return False, 'nobody steers: click "take control" to steer from this tab'
            return False, (
                f"refused: {self._holder_text} steers; let go there (or close it), "
                'then click "take control" here'
            )

    def release(self, token: object) -> None:
        """Free the slot if ``token`` holds it."""
        with self._lock:
            if self._holder is token:
                self._holder, self._holder_text, self._holder_tab = None, "", ""
                self.version += 1

    def forward(self, token: object, text: str) -> bool:
        """Hand ``text`` to the sink if ``token`` holds control; False (counted) otherwise."""
        with self._lock:
            sink = self._sink if self._holder is token else None
            if sink is None:
                self.ignored += 1
                return False
            self.forwarded += 1
        sink(text)
        return True


def describe_peer(request: web.Request, name: str = "") -> str:
    """The page in words, e.g. "tab K7, opened 19:02:13 (127.0.0.1:51512, connected 19:03:07)"."""
    peer = request.transport.get_extra_info("peername") if request.transport else None
    where = f"{peer[0]}:{peer[1]}" if peer else (request.remote or "?")
    since = time.strftime("%H:%M:%S")
    if name:
        return f"{name} ({where}, connected {since})"
    return f"the page at {where}, since {since}"


def tab_of(request: web.Request) -> tuple[str, str, str]:
    """The page's ``(tab id, tab name, want)`` from its query, cut to size."""
    query = request.query
    tab = query.get("tab", "")[:MAX_TAB_ID_CHARS]
    name = "".join(c for c in query.get("name", "") if c.isprintable())[:MAX_TAB_NAME_CHARS]
    want = query.get("want", "take")
    return tab, name.strip(), want if want in WANTS else "take"


def control_request(text: str) -> str | None:
    """ "take" or "release" when ``text`` is a person's click (``{"control": ...}``), else None."""
    if not text.startswith('{"control"'):
        return None
    try:
        asked = json.loads(text).get("control")
    except (ValueError, AttributeError):
        return None
    return asked if asked in ("take", "release") else None


async def read_commands(
    socket: web.WebSocketResponse,
    desk: ControlDesk,
    token: object,
    clicked: Callable[[str], None] | None = None,
) -> None:
    """Read what a page sends: the controller's newest text goes to the desk at most once per
    :data:`FORWARD_PERIOD_S` (the rest counted); a click goes to ``clicked`` (None: no key)."""
    newest: list[str] = []
    arrived = asyncio.Event()

    async def hand_on() -> None:
        while True:
            await arrived.wait()
            arrived.clear()
            if newest:
                desk.forward(token, newest.pop())
            await asyncio.sleep(FORWARD_PERIOD_S)

    forwarder = asyncio.ensure_future(hand_on())
    try:
        async for message in socket:
            if message.type in (WSMsgType.CLOSE, WSMsgType.ERROR):
                break
            if message.type is not WSMsgType.TEXT:
                continue
            asked = control_request(message.data)
            if asked is not None:
                if clicked is None:
                    desk.ignored += 1
                else:
                    clicked(asked)
                continue
            if newest:
                desk.superseded += 1
                newest.clear()
            newest.append(message.data)
            arrived.set()
        if newest:  # the page closed with a message waiting: every message is accounted for
            desk.forward(token, newest.pop())
    finally:
        forwarder.cancel()
