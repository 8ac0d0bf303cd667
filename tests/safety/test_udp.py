"""Promise 6: the UDP source listens on loopback unless told, drops oversize or malformed datagrams
(counted), survives any bytes, and cannot be made to skip the gate."""

from __future__ import annotations

import socket

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from limbctl.errors import ConfigError, InvalidInputError
from limbctl.teleop.commands import MAX_LINE_BYTES, parse_command
from limbctl.teleop.loop import LoopConfig
from limbctl.teleop.sources import UdpSource, open_source
from tests.safety.support import (
    LoopThread,
    RecordingGate,
    assert_goals_safe,
    bean_model,
    gate_limits,
    goal_log_poses,
    live_rig,
    wait_for,
)


def processed(source: UdpSource) -> int:
    return source.stats.accepted + source.stats.rejected


def test_default_is_loopback_and_any_address_must_be_asked_for():
    with UdpSource() as src:
        assert src.address[0] == "127.0.0.1"
    with open_source("udp://127.0.0.1:0") as src:
        assert src.address[0] == "127.0.0.1"
    # the host is never implied: a port alone is refused with the expected form
    with pytest.raises(ConfigError, match="udp://127.0.0.1:PORT"):
        open_source("udp://:9000")
    with pytest.raises(ConfigError, match="cannot listen"):
        UdpSource("203.0.113.7", 0)  # an address this machine does not have


# any bytes at all, plus near-valid JSON with hostile values
datagrams = st.one_of(
    st.binary(max_size=MAX_LINE_BYTES + 64),
    st.text(max_size=200).map(str.encode),
    st.sampled_from(
        [
            b'{"pan": 1' + b"0" * 400 + b', "tilt": 0}',
            b'{"pan": NaN, "tilt": 0}',
            b'{"q": [1, 0, 0, 0], "gate": false}',
            b'{"pan": 10, "tilt": 5, "unsafe": true}',
            b'{"dir": [1e-320, 0, 0]}',
            b'{"pan": 10, "tilt": 5}\n{"pan": 400, "tilt": 0}',
            b"[" * 600,
            b"\xff\xfe" + b"x" * 10,
        ]
    ),
)


def expected_counts(data: bytes) -> tuple[int, int]:
    """(accepted, rejected) lines the parser makes of one datagram."""
    if len(data) > MAX_LINE_BYTES:
        return 0, 1
    accepted = rejected = 0
    for line in data.split(b"\n"):
        if not line.strip():
            continue
        try:
            parse_command(line.strip())
            accepted += 1
        except InvalidInputError:
            rejected += 1
    return accepted, rejected


@pytest.fixture(scope="module")
def udp():
    with UdpSource() as src, socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx:
        yield src, tx


@settings(max_examples=150, deadline=None)
@given(batch=st.lists(datagrams, min_size=1, max_size=8))
@example(batch=[b"y" * (MAX_LINE_BYTES + 1), b'{"pan": 1, "tilt": "a"}', b'{"pan": 3, "tilt": 4}'])
def test_any_datagram_is_parsed_or_counted_and_the_reader_survives(udp, batch):
    src, tx = udp
    src.poll()
    before = (src.stats.accepted, src.stats.rejected)
    want = [expected_counts(d) for d in batch]
    for data in batch:
        tx.sendto(data, src.address)
    total = sum(a + r for a, r in want)
    wait_for(lambda: processed(src) - sum(before) >= total, 10.0, "the reader to count them")
    assert src.stats.accepted - before[0] == sum(a for a, _ in want)
    assert src.stats.rejected - before[1] == sum(r for _, r in want)
    # a valid probe still gets through afterwards: the reader thread is alive
    tx.sendto(b'{"pan": 1, "tilt": 2}', src.address)
    got: list = []

    def probe_arrived() -> bool:
        got.extend(src.poll())
        return len(got) == sum(a for a, _ in want) + 1

    wait_for(probe_arrived, 10.0, "the probe command behind the batch")


def test_hostile_udp_stream_cannot_skip_the_gate(tmp_path):
    """Commands far outside the region, with extra keys and junk, go through the gate."""
    log = tmp_path / "goals.jsonl"
    limits = gate_limits(200.0, 360.0)
    hostile = [
        b'{"pan": 110, "tilt": 65}',
        b'{"pan": -179, "tilt": -89}',
        b'{"pan": 10, "tilt": 5, "gate": "off"}',
        b'{"q": [0, 0, 0, 1]}',
        b'{"dir": [-1, 0, 0]}',
        b'{"dir": [0, 0, 1]}',
        b'{"pan": 1' + b"0" * 400 + b', "tilt": 0}',
        b'{"pan": 90, "tilt": 0}\n{"pan": -90, "tilt": 0}',
    ]
    with live_rig(goal_log=log) as (sim, rig):
        gate = RecordingGate(bean_model(), limits)
        with UdpSource() as src, socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx:
            config = LoopConfig(rate_hz=200.0, duration_s=120.0)
            with LoopThread(rig, gate, src, config) as loop:
                for _ in range(3):
                    for data in hostile:
                        seen = processed(src)
                        tx.sendto(data, src.address)
                        wait_for(lambda s=seen: processed(src) > s, 10.0, "the datagram")
                        # let the loop chase it for a while (40 cycles = 0.2 s at 200 Hz)
                        loop.cycles.wait_cycles(len(loop.cycles.items) + 40)
        rig.read_pose()
    summary, cycles = loop.summary, loop.cycles
    assert summary.exit_code == 0, summary.fault
    assert summary.rejected == 3 * 2  # extra key and the huge number, three times
    logged = goal_log_poses(log)
    assert len(logged) > 100
    assert_goals_safe(logged, gate.envelope, limits, gate.produced_ticks(rig))
    outcomes = {r["outcome"] for r in cycles.items}
    assert "corrected" in outcomes or "clamped" in outcomes
    # nothing that arrived by UDP was written without the gate: every written pose is a result
    written = [r for r in cycles.items if r["written"]]
    assert len(written) == summary.goals_written
