"""The ``firmware-sim`` command: help, ready line, serving, signals, goal log, bad options."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time

import pytest
from dynamixel_sdk import COMM_SUCCESS, PacketHandler, PortHandler

from firmware_sim.__main__ import main
from firmware_sim.simulator import Simulator
from firmware_sim.wire import RIG_BAUD
from tests.safety.support import wait_for

COMMAND = [sys.executable, "-m", "firmware_sim"]
GOAL_POSITION, TORQUE_ENABLE, PRESENT_POSITION = 116, 64, 132
ID, HARDWARE_ERROR, VOLTAGE_BIT = 7, 70, 0x01


@contextlib.contextmanager
def served(arguments: list[str]):
    """``firmware-sim ARGUMENTS`` running: (process, ready line); killed if left running."""
    process = subprocess.Popen([*COMMAND, *arguments], stdout=subprocess.PIPE, text=True)
    try:
        yield process, process.stdout.readline()
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
        process.stdout.close()


def sdk_at(port_name, baud: int) -> PortHandler:
    """The real SDK's port opened on ``port_name`` (a simulator's pty) at ``baud``."""
    port = PortHandler(str(port_name))
    assert port.setBaudRate(baud)
    return port


def await_voltage_error(packet, port, servo_id: int) -> None:
    """Wait up to 5 s for ``servo_id``'s Hardware Error Status to be the input voltage bit alone."""

    def voltage_error() -> bool:
        return packet.read1ByteTxRx(port, servo_id, HARDWARE_ERROR)[0] == VOLTAGE_BIT

    wait_for(voltage_error, 5, "an input voltage error")


def run_main(arguments: list[str]) -> int:
    """The exit status of ``firmware-sim ARGUMENTS`` run in this process."""
    try:
        return main(arguments)
    except SystemExit as done:  # argparse's exit on --help and on a malformed option
        return done.code


def test_help_documents_every_option(capsys):
    assert run_main(["--help"]) == 0
    out = capsys.readouterr().out
    options = "--ids --link --model --hand --goal-log --seed --drop --corrupt --latency-ms --event"
    words = "vanish xm430-w350 limb_dir polygon --leader --operator --leader-log docs/simulator.md"
    for option in f"{options} {words}".split():
        assert option in out


@pytest.mark.parametrize(
    "arguments, message",
    [
        (["--ids", "1,x"], "comma-separated"),
        (["--drop", "2"], "within 0..1"),
        (["--model", "ax12"], "invalid choice"),
        ([], "--link"),
        (["--operator", "hand.yaml"], "--operator and --leader-log need a leader"),
        (["--leader", "3,4,5,6"], "--leader takes two or three IDs"),
        (["--leader", "2,3"], "leader ids (2, 3) must not be the follower's"),
        (["--leader", "3,4,5", "--operator", "OPERATOR"], "it holds a 2-servo leader"),
        (["--leader", "3,4", "--operator", "missing.yaml"], "cannot read the operator file"),
        (["--factory", "2", "--leader", "3,4"], "not served with --factory"),
        (["--event", "1:melt:1:2"], "kind must be one of"),
        (["--event", "0:vanish:7:1"], "no servo answers as ID 7; the servos answer as 1, 2"),
    ],
)
def test_bad_options_are_named(tmp_path, capsys, arguments, message):
    operator = tmp_path / "operator.yaml"
    operator.write_text("script: [[0, 0, 0], [1, 40, 0]]\n")
    arguments = [str(operator) if a == "OPERATOR" else a for a in arguments]
    if arguments:
        arguments = [*arguments, "--link", str(tmp_path / "tty")]
    assert run_main(arguments) == 2 and message in capsys.readouterr().err
    assert not (tmp_path / "tty").exists()  # refused before serving


@pytest.mark.parametrize("stop_signal", [signal.SIGINT, signal.SIGTERM])
def test_serves_a_rig_and_a_leader_logs_goals_and_the_hand_until_a_signal_removes_the_link(
    tmp_path, stop_signal
):
    """--goal-log, and --leader/--operator: the leader answers as its model, the hand turns it."""
    link, log, operator = tmp_path / "ttyDXL", tmp_path / "leader.jsonl", tmp_path / "hand.yaml"
    goals = tmp_path / "goals.jsonl"
    operator.write_text("model: xl330-m288\nscript: [[0, 0, 0], [0.5, 40, 0]]\n")
    # --model gives the limb's servos theirs; the leader's is the operator file's
    models = ["--model", "xl430-w250,xm430-w350", "--goal-log", str(goals)]
    arguments = ["--ids", "1,2", *models, "--link", str(link), "--leader", "3,4", "--operator"]
    with served([*arguments, str(operator), "--leader-log", str(log)]) as (process, ready):
        assert "ready" in ready and str(link) in ready
        assert "XL330-M288 ID 3" in ready and "XL330-M288 ID 4" in ready, ready
        assert "XL430-W250 ID 1" in ready and "XM430-W350 ID 2" in ready, ready
        assert os.path.islink(link)
        port, packet = sdk_at(link, RIG_BAUD), PacketHandler(2.0)
        start, result, error = packet.read4ByteTxRx(port, 3, PRESENT_POSITION)  # the hand starts
        assert (result, error) == (COMM_SUCCESS, 0)
        assert packet.ping(port, 3) == (1200, COMM_SUCCESS, 0)
        assert packet.ping(port, 1) == (1060, COMM_SUCCESS, 0)
        assert packet.write1ByteTxRx(port, 1, TORQUE_ENABLE, 1) == (COMM_SUCCESS, 0)
        # pan zero is at 2185 ticks: 2185 + 1024 is pan +90 deg; tilt stays where it rests
        assert packet.write4ByteTxRx(port, 1, GOAL_POSITION, 2185 + 1024) == (COMM_SUCCESS, 0)
        # the hand takes the leader's pan 40 deg (455 ticks) within 0.5 s; read until it has
        turned = 0
        deadline = time.monotonic() + 10.0
        while abs(turned) < 440 and time.monotonic() < deadline:
            now, result, _ = packet.read4ByteTxRx(port, 3, PRESENT_POSITION)
            if result == COMM_SUCCESS:
                turned = now - start
        port.closePort()
        process.send_signal(stop_signal)
        assert process.wait(timeout=10) == 0
    assert not os.path.lexists(link)
    (line,) = [json.loads(text) for text in goals.read_text().splitlines()]
    assert set(line) == {"t", "id", "goal", "limb_dir"}
    assert line["id"] == 1 and line["goal"] == 2185 + 1024
    x, y, z = line["limb_dir"]
    assert abs(x) < 0.02 and y > 0.99  # pan +90 deg points the limb along +y
    assert 440 <= abs(turned) <= 470, turned
    rows = [json.loads(line) for line in log.read_text().splitlines()]
    assert set(rows[-1]) >= {"t", "pose_deg", "hand_nm", "motor_nm", "motor_work_j"}
    assert 38.0 < rows[-1]["pose_deg"][0] < 41.0 and abs(rows[-1]["pose_deg"][1]) < 1.0
    assert all(r["motor_nm"] == [0.0, 0.0] for r in rows)  # torque off: only the hand moved it


def test_an_event_names_a_renumbered_servo_by_its_id(tmp_path, capsys):
    """After set-up made slot 2 ID 9, --event ...:9:... is that servo and ...:2:... is no one."""
    eeprom = tmp_path / "eeprom"
    sim = Simulator(factory=2, eeprom_dir=eeprom)
    sim.servo(2).write(ID, bytes([9]))
    sim.persist()
    sim.close()
    link = tmp_path / "tty"
    base = ["--factory", "2", "--eeprom", str(eeprom), "--link", str(link)]
    assert run_main([*base, "--event", "0:voltage:2:5"]) == 2
    assert "no servo answers as ID 2; the servos answer as 1, 9" in capsys.readouterr().err
    with served([*base, "--event", "0:voltage:9:5"]) as (process, ready):
        assert "ID 9 at 57600" in ready
        port, packet = sdk_at(link, 57_600), PacketHandler(2.0)
        # servo 9 sees 5 V, below the XL430's 6.0 V limit: input voltage error and the alert
        await_voltage_error(packet, port, 9)
        assert packet.read1ByteTxRx(port, 1, HARDWARE_ERROR) == (0, COMM_SUCCESS, 0)
        port.closePort()
