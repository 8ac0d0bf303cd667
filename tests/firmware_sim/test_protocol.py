"""Protocol 2.0 framing of firmware_sim: CRC, stuffing, golden bytes, parser resync."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from firmware_sim.protocol import (
    CorruptPacket,
    Instruction,
    InstructionPacket,
    PacketParser,
    build_fast_status,
    build_packet,
    build_status,
    crc16,
    stuff,
    unstuff,
)

# Golden packets of the e-Manual's Protocol 2.0 examples.
PING_ID1 = bytes.fromhex("FF FF FD 00 01 03 00 01 19 4E")
# ID 1 answers PING: model 1030 (0x0406), firmware 0x26
PING_REPLY_ID1 = bytes.fromhex("FF FF FD 00 01 07 00 55 00 06 04 26 65 5D")
# READ ID 1, address 132, 4 bytes
READ_PRESENT_POSITION_ID1 = bytes.fromhex("FF FF FD 00 01 07 00 02 84 00 04 00 1D 15")
# WRITE ID 1, address 116, value 512
WRITE_GOAL_512_ID1 = bytes.fromhex("FF FF FD 00 01 09 00 03 74 00 00 02 00 00 CA 89")


def bitwise_crc(data: bytes) -> int:
    """CRC-16/BUYPASS one bit at a time: the reference for the table-driven crc16."""
    crc = 0
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x8005) if crc & 0x8000 else crc << 1
            crc &= 0xFFFF
    return crc


def test_golden_packets_stuffing_and_fast_status_are_built_byte_for_byte_and_parse_back():
    assert build_packet(1, Instruction.PING) == PING_ID1
    assert build_status(1, 0, bytes([0x06, 0x04, 0x26])) == PING_REPLY_ID1
    assert build_packet(1, Instruction.READ, bytes([0x84, 0, 4, 0])) == READ_PRESENT_POSITION_ID1
    assert build_packet(1, Instruction.WRITE, bytes([0x74, 0, 0, 2, 0, 0])) == WRITE_GOAL_512_ID1
    assert crc16(b"123456789") == 0xFEE8
    for packet in (PING_ID1, PING_REPLY_ID1, READ_PRESENT_POSITION_ID1, WRITE_GOAL_512_ID1):
        assert crc16(packet[:-2]) == packet[-2] | (packet[-1] << 8)
    packet = build_fast_status([(1, 0, bytes([1, 2, 3, 4])), (2, 0x80, bytes([5, 6, 7, 8]))])
    length = packet[5] | (packet[6] << 8)
    assert packet[4] == 0xFE and packet[7] == 0x55
    # LEN = instruction + 2 * (error + id + 4 data + crc)
    assert length == 1 + 2 * 8 == len(packet) - 7
    first_crc = packet[14] | (packet[15] << 8)
    assert first_crc == crc16(packet[:14])
    assert crc16(packet[:-2]) == packet[-2] | (packet[-1] << 8)
    assert packet[16:18] == bytes([0x80, 2])
    body = bytes([0x55, 0x00, 0xFF, 0xFF, 0xFD, 0x01])
    assert stuff(body) == bytes([0x55, 0x00, 0xFF, 0xFF, 0xFD, 0xFD, 0x01])
    packet = build_status(1, 0, bytes([0xFF, 0xFF, 0xFD, 0x01]))
    # LEN counts the stuffing byte: instr + err + 4 data + 1 stuffing + 2 CRC = 9
    assert packet[5] == 9 and packet[7:-2] == stuff(body)
    params = bytes([0x68, 0x00, 0xFF, 0xFF, 0xFD, 0x00])
    packet = build_packet(3, Instruction.WRITE, params)
    assert b"\xff\xff\xfd\xfd" in packet
    (parsed,) = PacketParser().feed(packet, 0.0)
    assert parsed == InstructionPacket(3, Instruction.WRITE, params)


@given(st.binary(max_size=64))
def test_table_crc_matches_bitwise_reference(data):
    assert crc16(data) == bitwise_crc(data)
    # continuing a CRC equals computing it at once
    half = len(data) // 2
    assert crc16(data[half:], crc16(data[:half])) == crc16(data)


@given(st.lists(st.sampled_from([0x00, 0xFF, 0xFD, 0x12]), max_size=40).map(bytes))
def test_stuffing_round_trip_and_no_header_inside(body):
    stuffed = stuff(body)
    assert unstuff(stuffed) == body
    # every FF FF FD in the stuffed field is followed by the stuffing FD
    for k in range(len(stuffed) - 2):
        if stuffed[k : k + 3] == b"\xff\xff\xfd":
            assert stuffed[k + 3 : k + 4] == b"\xfd"


def test_parser_resynchronises_after_junk_partial_corrupt_stale_and_impossible_packets():
    parser = PacketParser()
    good = build_packet(1, Instruction.PING)
    corrupt = bytearray(build_packet(2, Instruction.READ, bytes([0x84, 0, 4, 0])))
    corrupt[-1] ^= 0x55
    junk = b"\x00\xff\xff\x13\xff\xff\xfd"
    events = list(parser.feed(junk + bytes(corrupt) + good[:5], 0.0))
    assert events == [CorruptPacket(2, Instruction.READ)]
    events = list(parser.feed(good[5:] + b"\xfe", 0.001))
    assert events == [InstructionPacket(1, Instruction.PING, b"")]
    assert parser.junk_bytes >= len(junk)
    parser = PacketParser(stale_after_s=0.05)
    assert list(parser.feed(good[:6], 0.0)) == []
    # the rest arrives far too late: the firmware had already given up on the fragment
    assert list(parser.feed(good[6:], 1.0)) == []
    # a header announcing LEN = 0xFFFF is junk, the packet after it is found
    assert list(parser.feed(b"\xff\xff\xfd\x00\x01\xff\xff" + good, 2.0)) == [
        InstructionPacket(1, Instruction.PING, b"")
    ]
