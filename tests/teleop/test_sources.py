import json
import os

import pytest

from calib import default_sim_profile
from limbctl.errors import ConfigError
from limbctl.servo.rig import Rig
from limbctl.teleop.commands import MAX_LINE_BYTES
from limbctl.teleop.sources import (
    SOURCE_FORMS,
    SOURCES,
    ReplaySource,
    SourceContext,
    StreamSource,
    open_source,
    parse_source,
)
from tests.safety.support import wait_for


def drain(source, timeout=5.0):
    assert source.wait_finished(timeout), "source did not reach end of input"
    return source.poll()


def test_stream_source_parses_counts_and_ends_and_replay_keeps_order(tmp_path):
    r, w = os.pipe()
    with os.fdopen(r, "rb", buffering=0) as reader, StreamSource(reader) as src:
        lines = [
            b'{"pan": 10, "tilt": 5}',
            b'{"pan": NaN, "tilt": 0}',
            b"garbage",
            b'{"dir": [1, 0, 0]}',
            b"x" * (MAX_LINE_BYTES + 10),
            b'{"pan": -5, "tilt": 0}',
        ]
        os.write(w, b"\n".join(lines) + b"\n")
        os.close(w)
        assert len(drain(src)) == 3
        assert (src.stats.accepted, src.stats.rejected) == (3, 3)
        assert src.finished
    path = tmp_path / "cmds.jsonl"
    rows = [{"t": 0.01 * i, "pan": float(i), "tilt": 0.0} for i in range(20)]
    path.write_text("\n".join(json.dumps(r) for r in rows) + "\n")
    with ReplaySource(path, speed=10.0) as src:
        commands = drain(src)
    assert [c.t for c in commands] == [r["t"] for r in rows]


def test_an_oversize_line_arriving_in_two_reads_is_one_refusal_and_its_tail_is_not_fed():
    """The tail of an oversize line, read after the line was already refused, is dropped
    up to its newline: it is neither a second refusal nor a command."""
    r, w = os.pipe()
    with os.fdopen(r, "rb", buffering=0) as reader, StreamSource(reader) as src:
        os.write(w, b'{"pan": ' + b"1" * (MAX_LINE_BYTES + 10))
        wait_for(lambda: src.stats.rejected == 1, 5.0, "the oversize head's refusal")
        os.write(w, b'1, "tilt": 0}\n{"pan": -5, "tilt": 0}\n')
        os.close(w)
        commands = drain(src)
    assert len(commands) == 1 and src.stats.accepted == 1
    assert src.stats.rejected == 1, "the oversize line's tail was fed on as a line of its own"


def test_open_source_rejects_unknown_names():
    with pytest.raises(ConfigError, match="choose one of"):
        open_source("serial:/dev/null")
    with pytest.raises(ConfigError, match="udp://127.0.0.1:PORT"):
        open_source("udp://nohostport")
    with pytest.raises(ConfigError, match="does not exist"):
        open_source("replay:/nonexistent/file.jsonl")
    # every scheme is in the registry and named in the refusal
    assert tuple(SOURCES) == ("stdin", "udp", "replay", "keyboard", "leader", "page")
    with pytest.raises(ConfigError) as refused:
        parse_source("serial:/dev/ttyUSB0")
    for form in SOURCE_FORMS:
        assert form in str(refused.value)
    with pytest.raises(ConfigError, match="takes no argument"):
        open_source("stdin:now")


def test_leader_spec_names_its_servos_and_needs_the_open_rig_whose_twist_sources_keep():
    spec = parse_source("leader:3,4")
    assert spec.kind.scheme == "leader" and spec.extra_ids == (3, 4)
    assert parse_source("udp://127.0.0.1:9000").extra_ids == ()
    # a three-servo leader names its roll too
    assert parse_source("leader:4,5,6").extra_ids == (4, 5, 6)
    for bad in ("leader:3", "leader:3,x", "leader:3,4,5,6"):
        with pytest.raises(ConfigError, match="leader:ID,ID"):
            parse_source(bad)
    # each servo once, and a servo id the protocol has (0..252; 253-255 are reserved)
    for bad in ("leader:3,3", "leader:4,5,4", "leader:253,4", "leader:-1,4", "leader:3,300"):
        with pytest.raises(ConfigError, match=r"each id once, in 0\.\.252"):
            parse_source(bad)
    with pytest.raises(ConfigError, match="needs the open rig"):
        spec.open()
    # a source on a three-servo rig keeps twist
    rig = Rig(default_sim_profile("sim3"))
    assert parse_source("udp://127.0.0.1:0").open(SourceContext(rig=rig)).twist
    assert not parse_source("udp://127.0.0.1:0").open(SourceContext()).twist
