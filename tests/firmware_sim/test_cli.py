"""The ``firmware-sim`` command: help, ready line, serving, signals, goal log, bad options."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys

import pytest
from dynamixel_sdk import COMM_SUCCESS, PacketHandler, PortHandler

from firmware_sim.wire import RIG_BAUD

COMMAND = [sys.executable, "-m", "firmware_sim"]
GOAL_POSITION, TORQUE_ENABLE = 116, 64


def test_help_documents_every_option():
    result = subprocess.run([*COMMAND, "--help"], capture_output=True, text=True, check=True)
    for option in (
        "--ids",
        "--link",
        "--model",
        "--hand",
        "--goal-log",
        "--seed",
        "--drop",
        "--corrupt",
        "--latency-ms",
        "--event",
        "vanish:ID:S",
        "xm430-w350",
        "limb_dir",
        "polygon",
    ):
        assert option in result.stdout


@pytest.mark.parametrize(
    "arguments, message",
    [
        (["--ids", "1,x"], "comma-separated"),
        (["--drop", "2"], "within 0..1"),
        (["--model", "ax12"], "invalid choice"),
        ([], "--link"),
    ],
)
def test_bad_options_are_named(tmp_path, arguments, message):
    if arguments:
        arguments = [*arguments, "--link", str(tmp_path / "tty")]
    result = subprocess.run([*COMMAND, *arguments], capture_output=True, text=True)
    assert result.returncode == 2 and message in result.stderr


@pytest.mark.parametrize("stop_signal", [signal.SIGINT, signal.SIGTERM])
def test_serves_until_signal_then_removes_link(tmp_path, stop_signal):
    link = tmp_path / "ttyDXL"
    log = tmp_path / "goals.jsonl"
    process = subprocess.Popen(
        [*COMMAND, "--ids", "1,2", "--link", str(link), "--goal-log", str(log)],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        ready = process.stdout.readline()
        assert "ready" in ready and str(link) in ready
        assert os.path.islink(link)
        port = PortHandler(str(link))
        assert port.setBaudRate(RIG_BAUD)
        packet = PacketHandler(2.0)
        assert packet.ping(port, 1) == (1060, COMM_SUCCESS, 0)
        assert packet.write1ByteTxRx(port, 1, TORQUE_ENABLE, 1) == (COMM_SUCCESS, 0)
        # pan zero is at 2185 ticks: 2185 + 1024 is pan +90 deg; tilt stays where it rests
        assert packet.write4ByteTxRx(port, 1, GOAL_POSITION, 2185 + 1024) == (COMM_SUCCESS, 0)
        port.closePort()
        process.send_signal(stop_signal)
        assert process.wait(timeout=10) == 0
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
        process.stdout.close()
    assert not os.path.lexists(link)
    (line,) = [json.loads(text) for text in log.read_text().splitlines()]
    assert set(line) == {"t", "id", "goal", "limb_dir"}
    assert line["id"] == 1 and line["goal"] == 2185 + 1024
    x, y, z = line["limb_dir"]
    assert abs(x) < 0.02 and y > 0.99  # pan +90 deg points the limb along +y
