"""Find the servos on a port at every baud rate, and name the IDs two servos share."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field

from dynamixel_sdk.protocol2_packet_handler import Protocol2PacketHandler

from limbctl.errors import PortError
from limbctl.servo.control_table import BAUD_RATE_VALUES, SDK_BAUDS, model_name
from limbctl.servo.transfers import SDK_LATENCY_TIMER_MS, TunedPortHandler

#: Scan order: the factory rate first, then the fast ones set-up uses, then the rest.
SCAN_BAUDS = (57_600, 1_000_000, 115_200, 2_000_000, 3_000_000, 4_000_000, 9600, 4_500_000)
#: Protocol 2.0 PING: instruction number, and a status packet's length with its 3 data bytes.
PING = 0x01
STATUS = 0x55
PING_REPLY_BYTES = 14
BROADCAST_ID = 0xFE
MAX_ID = 252
#: Reply times of silence that end a broadcast ping's back-to-back replies.
QUIET_PACKETS = 3
#: Longest Return Delay Time a servo may wait (254 x 2 us), s.
MAX_RETURN_DELAY_S = 254 * 2e-6
#: Longest wait for a broadcast PING's replies (s): later ones (IDs over ~80 at 9600) are missed.
BROADCAST_CAP_S = 1.5
#: The SDK's allowance per ID slot of a broadcast PING (ms): servos answer one after another.
SLOT_MS = 3.0
#: Time (s) for the OS and USB adapter to hand bytes over beyond the latency timer (SDK: 2 ms).
HANDOVER_S = 0.002
#: Advice when nothing answers.
NOTHING_ANSWERS = (
    "no servo answered at any baud rate. Check: the servos' power (the LED blinks once at "
    "power-up; an XL330/XC330-M wants 5 V, the others 12 V); the cable (a U2D2 in TTL mode for "
    "XL/XC servos, RS-485 for XM/XH '-R' models) and --port; that you may open the port (`sudo "
    "usermod -aG dialout $USER`, then log in again); the USB adapter's latency timer (an FTDI "
    "waits 16 ms by default: install the udev rule in the README, then replug)."
)


@dataclass(frozen=True)
class Found:
    """A servo that answered: its ID, model number, firmware version and baud rate."""

    servo_id: int
    model_number: int
    firmware: int
    baud: int

    def describe(self) -> str:
        return (
            f"ID {self.servo_id:3d}  {model_name(self.model_number):24s} firmware "
            f"{self.firmware:3d}  at {self.baud} baud"
        )


@dataclass(frozen=True)
class Collision:
    """Two or more servos answer as ``servo_id`` at ``baud``."""

    servo_id: int
    baud: int

    def describe(self) -> str:
        return (
            f"two or more servos answer as ID {self.servo_id} at {self.baud} baud: their "
            f"replies collide; connect them one at a time and give each its own ID "
            f"(`limbctl motors setup`)"
        )


@dataclass
class ScanResult:
    """What a scan found (servos, collisions, garbled bauds); ``skipped``/``seconds`` by baud."""

    found: list[Found] = field(default_factory=list)
    collisions: list[Collision] = field(default_factory=list)
    unreadable: list[int] = field(default_factory=list)
    skipped: dict[int, str] = field(default_factory=dict)
    seconds: dict[int, float] = field(default_factory=dict)

    @property
    def empty(self) -> bool:
        return not (self.found or self.collisions or self.unreadable)

    def report(self) -> str:
        """The scan for a person: one line a servo, a collision, a skipped baud."""
        lines = [servo.describe() for servo in self.found]
        lines += [collision.describe() for collision in self.collisions]
        lines += [
            f"garbled replies at {baud} baud: servos share an ID there; connect them one at a time"
            for baud in self.unreadable
        ]
        lines += [f"{baud} baud not tried: {why}" for baud, why in self.skipped.items()]
        if self.empty:
            lines.append(NOTHING_ANSWERS)
        return "\n".join(lines)


class RawLink:
    """PING over an open port, keeping every byte of the answers (clean or not)."""

    def __init__(self, port: TunedPortHandler) -> None:
        self.port = port
        self._packets = Protocol2PacketHandler()

    def byte_s(self) -> float:
        """One byte's time on the wire (s): 10 bit times."""
        return 10.0 / self.port.baudrate

    def ping(self, servo_id: int, window_s: float, quiet_s: float) -> bytes:
        """Send PING to ``servo_id``; the bytes that come back until quiet or the window ends."""
        packet = [0] * 10
        packet[4], packet[5], packet[6], packet[7] = servo_id, 3, 0, PING
        self.port.is_using = False
        self._packets.txPacket(self.port, packet)
        self.port.is_using = False
        received = bytearray()
        start = last = time.monotonic()
        while True:
            chunk = self.port.readPort(4096)
            now = time.monotonic()
            if chunk:
                received += bytes(chunk)
                last = now
            elif received and now - last >= quiet_s:
                return bytes(received)
            if now - start >= window_s:
                return bytes(received)
            time.sleep(min(quiet_s, 0.0005))

    def parse(self, data: bytes) -> tuple[list[tuple[int, int, int, int]], list[int]]:
        """Clean PING replies ``(offset, id, model, firmware)`` and the offsets of junk bytes."""
        replies: list[tuple[int, int, int, int]] = []
        junk: list[int] = []
        i = 0
        while i < len(data):
            if data[i : i + 4] == b"\xff\xff\xfd\x00" and i + 7 <= len(data):
                length = data[i + 5] | (data[i + 6] << 8)
                end = i + 7 + length
                body = list(data[i:end])
                if end <= len(data) and length == PING_REPLY_BYTES - 7 and data[i + 7] == STATUS:
                    crc = self._packets.updateCRC(0, body, len(body) - 2)
                    if body[-2:] == [crc & 0xFF, crc >> 8]:
                        model = data[i + 9] | (data[i + 10] << 8)
                        replies.append((i, data[i + 4], model, data[i + 11]))
                        i = end
                        continue
            junk.append(i)
            i += 1
        return replies, junk


def _windows(link: RawLink, latency_s: float) -> tuple[float, float]:
    """(window, quiet) for one PING at the port's baud: bytes out, delay, reply, latency."""
    byte_s = link.byte_s()
    reply_s = PING_REPLY_BYTES * byte_s
    # window = instruction + longest Return Delay Time + reply + 2 latency timers + handover
    window = 10 * byte_s + MAX_RETURN_DELAY_S + reply_s + 2 * latency_s + HANDOVER_S
    quiet = QUIET_PACKETS * (reply_s + MAX_RETURN_DELAY_S) + latency_s + HANDOVER_S
    return window, quiet


def scan_baud(link: RawLink, baud: int, latency_s: float, deadline: float) -> ScanResult:
    """Broadcast PING at ``baud`` (the port already set to it), then name collided IDs."""
    result = ScanResult()
    window, quiet = _windows(link, latency_s)
    # every ID may answer: 253 slots of a reply and the SDK's 3 ms each, capped; quiet ends it
    slot_s = PING_REPLY_BYTES * link.byte_s() + SLOT_MS / 1000.0
    data = link.ping(BROADCAST_ID, min(window + (MAX_ID + 1) * slot_s, BROADCAST_CAP_S), quiet)
    replies, junk = link.parse(data)
    for _, servo_id, model, firmware in replies:
        result.found.append(Found(servo_id, model, firmware, baud))
    if not junk:
        return result
    candidates: list[int] = []
    for start in _junk_runs(junk):
        before = [r[1] for r in replies if r[0] < start]
        after = [r[1] for r in replies if r[0] > start]
        low = max(before) + 1 if before else 0
        high = min(after) - 1 if after else MAX_ID
        # the factory ID first: it is where fresh servos collide
        span = sorted(range(low, high + 1), key=lambda i: (i != 1, i))
        candidates += [i for i in span if i not in candidates]
    named = 0
    for servo_id in candidates:
        if time.monotonic() > deadline or named >= len(_junk_runs(junk)):
            break
        answer = link.ping(servo_id, window, quiet)
        clean, bad = link.parse(answer)
        if bad:
            result.collisions.append(Collision(servo_id, baud))
            named += 1
        elif clean and all(f.servo_id != servo_id for f in result.found):
            _, _, model, firmware = clean[0]
            result.found.append(Found(servo_id, model, firmware, baud))
    if named == 0:
        result.unreadable.append(baud)
    return result


def _junk_runs(junk: Sequence[int]) -> list[int]:
    """Start offsets of runs of consecutive junk bytes (one garbled reply each)."""
    return [offset for k, offset in enumerate(junk) if k == 0 or junk[k - 1] != offset - 1]


def scan(
    port_name: str,
    bauds: Iterable[int] = SCAN_BAUDS,
    latency_timer_ms: float = 16.0,
    on_baud: Callable[[int, int, int], None] | None = None,
    budget_per_baud_s: float = 2.0,
) -> ScanResult:
    """Ping every servo on ``port_name`` at each of ``bauds``. ``latency_timer_ms`` is the USB
    adapter's (ms; at least the SDK's 16 ms is allowed); ``on_baud(index, count, baud)`` is called
    before each baud (a progress bar); ``budget_per_baud_s`` is the most time (s) spent naming
    collided IDs at one baud. PortError if the port cannot be opened."""
    bauds = list(bauds)
    latency_timer_ms = max(latency_timer_ms, SDK_LATENCY_TIMER_MS)
    total = ScanResult()
    port = TunedPortHandler(port_name, latency_timer_ms)
    link = RawLink(port)
    try:
        for index, baud in enumerate(bauds):
            if on_baud is not None:
                on_baud(index, len(bauds), baud)
            if baud not in BAUD_RATE_VALUES:
                total.skipped[baud] = "no X-series servo runs at it"
                continue
            if baud not in SDK_BAUDS:
                total.skipped[baud] = "the serial driver (dynamixel-sdk) cannot open it"
                continue
            started = time.monotonic()
            try:
                opened = port.setBaudRate(baud)
            except OSError as exc:
                raise PortError(f"cannot open serial port {port_name} ({exc})") from exc
            if not opened:
                total.skipped[baud] = "the serial driver refused it"
                continue
            part = scan_baud(link, baud, latency_timer_ms / 1000.0, started + budget_per_baud_s)
            total.found += part.found
            total.collisions += part.collisions
            total.unreadable += part.unreadable
            total.seconds[baud] = time.monotonic() - started
    finally:
        if port.is_open:
            port.closePort()
    return total
