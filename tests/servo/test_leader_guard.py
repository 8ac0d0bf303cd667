"""A felt leader's guard on the simulator's pty, and ``limbctl teleop`` killed mid-push."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from contextlib import contextmanager

from firmware_sim.wire import RIG_BAUD
from limbctl.errors import PortInUse
from limbctl.servo.bus import ServoBus
from limbctl.servo.leader_guard import GIVE_UP_S, LeaderGuard
from tests.firmware_sim.test_cli import served

#: How long a guard's own start may take on a loaded machine (Python and the bus's imports):
#: only a limit for a wait, never the bound under test.
START_S = 10.0
#: Between two tries of the port while the guard may hold it (s): the test's reads take turns
#: with the guard's on the port's lock, and a free port is tried this often.
POLL_S = 0.005


def torque_when_free(port: str, ids, deadline: float, baud: int = RIG_BAUD) -> dict[int, bool]:
    """Torque Enable of ``ids`` on ``port``, read as soon as nobody holds the port (PortInUse:
    tried again until ``deadline``, monotonic s)."""
    while True:
        try:
            bus = ServoBus(port, baud, ids).open()
        except PortInUse:
            assert time.monotonic() < deadline, "the port stayed held"
            time.sleep(POLL_S)
            continue
        with bus:
            return bus.torque_enabled()


def end_pipe(guard: LeaderGuard) -> None:
    """What the kernel does to a dead controller's end of the pipe: close it, no ``done``."""
    fd, guard._write_fd = guard._write_fd, None
    os.close(fd)


def test_a_guard_told_done_touches_nothing_its_controller_gone_switches_the_leader_off(sim, capfd):
    """Told done, nothing; controller gone, only the leader off; the port held, it gives up."""
    with ServoBus(sim.port, RIG_BAUD, (1, 2)) as bus:
        bus.set_torque(True)
        guard = LeaderGuard.start(bus, (2,))
    guard.done()  # the port is free: a guard that wrote anything could
    assert guard.process.returncode == 0
    assert torque_when_free(sim.port, (1, 2), time.monotonic() + START_S) == {1: True, 2: True}
    assert "leader guard" not in capfd.readouterr().err
    guard.done()  # twice is harmless
    with ServoBus(sim.port, RIG_BAUD, (1, 2)) as bus:
        guard = LeaderGuard.start(bus, (2,))
        end_pipe(guard)  # the controller died, but its port is not yet free
    guard.process.wait(START_S + GIVE_UP_S)
    assert guard.process.returncode == 0
    assert torque_when_free(sim.port, (1, 2), time.monotonic() + START_S) == {1: True, 2: False}
    err = capfd.readouterr().err
    assert "leader guard: the controller died; Torque Enable 0 on leader servos 2 " in err, err
    with ServoBus(sim.port, RIG_BAUD, (1, 2)) as bus:
        bus.set_torque(True)
        guard = LeaderGuard.start(bus, (2,))
        end_pipe(guard)
        guard.process.wait(START_S + GIVE_UP_S)  # the port held all along
        assert guard.process.returncode == 1
        assert bus.torque_enabled() == {1: True, 2: True}
    err = capfd.readouterr().err
    assert "could not switch off leader servos 2 " in err and "switch it off" in err, err
    took_ms = float(err.split("ms after")[0].split()[-1])
    assert took_ms <= GIVE_UP_S * 1e3 + 50.0, err  # the alarm ends it; printing takes a moment


#: The hand presses the leader 20 deg past the cone's edge at pan 30 deg and holds it there.
OPERATOR = {
    "model": "xm430-w350",
    "script": [[0.0, 0.0, 0.0], [1.5, 50.0, 0.0]],
    "stiffness_nm_deg": 0.05,
    "damping_nm_s_rad": 0.02,
    "max_torque_nm": 0.3,
}
#: A leader pushed at least this much (N m, the norm of its motors' torques) is being pushed
#: back at the edge (the cap is 0.40; a pressing hand meets 0.3 and more).
PUSHED_NM = 0.1


def _pushed(log) -> bool:
    """Whether the simulator's leader log's last whole row shows the leader pushed back."""
    try:
        lines = log.read_text().splitlines()
    except FileNotFoundError:
        return False
    for line in reversed(lines[-3:]):
        try:
            row = json.loads(line)
        except ValueError:
            continue  # a row being written
        return math.hypot(*row["motor_nm"]) >= PUSHED_NM
    return False


@contextmanager
def _teleop(tmp_path, model, *options: str):
    """A simulated rig and felt leader (ids 3, 4) pressed by OPERATOR, and ``limbctl teleop
    --source leader:3,4`` with ``model`` on it; yields (teleop process, link, leader log)."""
    link, log, hand = tmp_path / "tty", tmp_path / "leader.jsonl", tmp_path / "hand.yaml"
    hand.write_text(json.dumps(OPERATOR))
    leader = ["--leader", "3,4", "--operator", str(hand), "--leader-log", str(log)]
    rig = ["--ids", "1,2", "--baud", str(RIG_BAUD), "--link", str(link)]
    with served([*rig, *leader]) as (simulator, ready):
        assert "ready" in ready
        teleop = subprocess.Popen(
            [sys.executable, "-m", "limbctl", "teleop", "--port", str(link), "--model", str(model)]
            + ["--source", "leader:3,4", "--latency-timer", "1", "--no-view", "--quiet"]
            + list(options),
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            yield teleop, str(link), log
        finally:
            if teleop.poll() is None:
                teleop.kill()
            teleop.communicate(timeout=START_S + GIVE_UP_S)
            simulator.send_signal(signal.SIGTERM)
            simulator.wait(START_S)


def _wait_pushed(teleop, log) -> None:
    """Until the leader is pushed back at the edge (the controller must still run)."""
    deadline = time.monotonic() + 120.0
    while not _pushed(log):
        assert teleop.poll() is None, teleop.communicate()[1]
        assert time.monotonic() < deadline, "the leader was never pushed back"
        time.sleep(0.02)  # the log grows a row a millisecond: read it now and then


def test_a_controller_killed_mid_push_leaves_its_leader_limp_within_the_bound(tmp_path, cone_file):
    with _teleop(tmp_path, cone_file(30.0)) as (teleop, link, log):
        _wait_pushed(teleop, log)
        killed_at = time.monotonic()
        os.kill(teleop.pid, signal.SIGKILL)
        # the guard shares the controller's stderr: its end is the guard's exit, the port free
        err = teleop.communicate(timeout=START_S + GIVE_UP_S)[1]
        limp_s = time.monotonic() - killed_at
        torque = torque_when_free(link, (1, 2, 3, 4), time.monotonic() + START_S)
    assert teleop.returncode == -signal.SIGKILL
    assert torque == {1: True, 2: True, 3: False, 4: False}  # the follower left as it was
    assert limp_s <= GIVE_UP_S, limp_s
    assert "leader guard: the controller died; Torque Enable 0 on leader servos 3, 4" in err, err
    said = next(line for line in err.splitlines() if line.startswith("leader guard"))
    print(f"kill -9 to the guard's exit, both leader servos limp: {limp_s * 1e3:.1f} ms; {said}")


def test_a_clean_end_leaves_the_leader_to_the_controller(tmp_path, cone_file):
    """The controller's own end switches the leader off; its guard, told done, says nothing."""
    with _teleop(tmp_path, cone_file(30.0), "--duration", "60") as (teleop, link, log):
        _wait_pushed(teleop, log)
        teleop.send_signal(signal.SIGINT)  # Ctrl-C: the session ends cleanly
        err = teleop.communicate(timeout=60.0)[1]
        torque = torque_when_free(link, (1, 2, 3, 4), time.monotonic() + START_S)
    assert teleop.returncode == 0, err
    assert "feels the edge" in err and "leader guard" not in err, err
    assert not torque[3] and not torque[4]
