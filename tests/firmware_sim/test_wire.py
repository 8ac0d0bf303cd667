"""The wire's arithmetic, its speed as the pty reports it, and what a collision does."""

import os
import tty

import pytest
import serial

from firmware_sim.protocol import build_status
from firmware_sim.wire import (
    BAUD_BY_VALUE,
    collide,
    host_baud,
    value_for_baud,
    wire_s,
)


def test_baud_values_and_refusal():
    assert [value_for_baud(b) for b in (9600, 57_600, 4_000_000, 4_500_000)] == [0, 1, 6, 7]
    assert BAUD_BY_VALUE[3] == 1_000_000
    with pytest.raises(ValueError, match="no X-series servo runs at 12345 baud; choose one of"):
        value_for_baud(12345)


def test_wire_time_is_ten_bits_a_byte():
    assert wire_s(132, 57_600) == pytest.approx(132 * 10 / 57_600)  # 22.9 ms
    assert wire_s(5, None) == 0.0


@pytest.mark.parametrize("baud", [9600, 57_600, 1_000_000, 4_000_000, 4_500_000])
def test_the_hosts_speed_is_read_from_the_pty(baud):
    master, slave = os.openpty()
    try:
        tty.setraw(slave)
        with serial.Serial(os.ttyname(slave), baudrate=baud):
            assert host_baud(master) == baud  # 4.5 Mbps is a custom rate (termios2)
    finally:
        os.close(master)
        os.close(slave)


def test_two_replies_at_once_leave_no_clean_packet():
    reply = build_status(1, 0, bytes([0x24, 0x04, 46]))
    assert collide([reply]) == reply
    garbled = collide([reply, reply])  # even identical replies: the second is a little late
    assert reply not in garbled
    assert not garbled.startswith(b"\xff\xff\xfd\x00")  # the header itself is broken
