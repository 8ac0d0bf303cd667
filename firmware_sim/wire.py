"""The wire between the host and the servos: its speed, its time, and what collisions do to it
(a pty carries bytes instantly at any speed)."""

from __future__ import annotations

import fcntl
import struct
from collections.abc import Sequence

#: Baud Rate register value -> bit/s (X series; 7 = 4.5 Mbps exists on the 430s and 540s only).
BAUD_BY_VALUE = dict(
    enumerate((9600, 57_600, 115_200, 1_000_000, 2_000_000, 3_000_000, 4_000_000, 4_500_000))
)
#: The factory baud rate (register value 1).
FACTORY_BAUD = 57_600
#: The simulated rig's baud: the fastest every family runs at, so a 200 Hz cycle's bytes take
#: 0.15 ms and a dropped reply's timeout still fits the 5 ms period (1 Mbps tipped it over).
RIG_BAUD = 4_000_000
#: Bits per byte on the wire: start bit, 8 data bits, stop bit (8N1).
BITS_PER_BYTE = 10
#: How late a colliding servo's bits arrive (bit times): any skew that is not a whole byte
#: garbles the frames; 3 stands for a few microseconds of clock and delay mismatch.
COLLISION_SKEW_BITS = 3
# Linux ioctl reading struct termios2 (c_ispeed/c_ospeed hold the rate in bit/s).
_TCGETS2 = 0x802C542A
_TERMIOS2_SIZE = 44
_OSPEED_OFFSET = 40


def value_for_baud(baud: int) -> int:
    """The Baud Rate register value for ``baud`` bit/s; ValueError listing the rates."""
    for value, rate in BAUD_BY_VALUE.items():
        if rate == baud:
            return value
    rates = ", ".join(str(rate) for rate in BAUD_BY_VALUE.values())
    raise ValueError(f"no X-series servo runs at {baud} baud; choose one of {rates}")


def host_baud(fd: int) -> int | None:
    """The output speed (bit/s) set on the tty behind ``fd`` (a pty master reports its
    slave's), or None when the system cannot tell."""
    buffer = bytearray(_TERMIOS2_SIZE)
    try:
        fcntl.ioctl(fd, _TCGETS2, buffer)
    except OSError:
        return None
    (speed,) = struct.unpack_from("I", buffer, _OSPEED_OFFSET)
    return int(speed) or None


def wire_s(n_bytes: int, baud: int | None) -> float:
    """Seconds ``n_bytes`` take on the wire at ``baud`` (0 when the speed is unknown)."""
    # t = n * 10 bits / (bits per second)
    return n_bytes * BITS_PER_BYTE / baud if baud else 0.0


def _bits(packet: bytes, skew: int) -> list[int]:
    """The line level bit by bit: ``skew`` idle bits (1), then each byte framed 8N1."""
    bits = [1] * skew
    for byte in packet:
        bits += [0] + [(byte >> i) & 1 for i in range(8)] + [1]
    return bits


def _frames(bits: Sequence[int]) -> bytes:
    """What a UART decodes from a line: a 0 starts a frame, 8 data bits follow, LSB first."""
    out = bytearray()
    i = 0
    while i + 9 <= len(bits):
        if bits[i] == 0:
            out.append(sum(bit << k for k, bit in enumerate(bits[i + 1 : i + 9])))
            i += 10
        else:
            i += 1
    return bytes(out)


def collide(packets: Sequence[bytes]) -> bytes:
    """The bytes the host reads when ``packets`` are sent at once: the open-drain line lets a 0
    win, each next sender's bits COLLISION_SKEW_BITS later."""
    if len(packets) == 1:
        return packets[0]
    lines = [_bits(p, k * COLLISION_SKEW_BITS) for k, p in enumerate(packets)]
    length = max(len(line) for line in lines)
    # open drain: the line is low while any transmitter pulls it low
    merged = [min(line[i] if i < len(line) else 1 for line in lines) for i in range(length)]
    return _frames(merged)
