"""One controller per port: a second ServoBus is refused at once, naming the holder."""

from __future__ import annotations

import os
import subprocess
import sys
import time

import pytest
from dynamixel_sdk import PortHandler

from limbctl.errors import PortInUse
from limbctl.servo.bus import ServoBus
from limbctl.servo.port_lock import PortHolder, port_holders

#: A controller in another process: opens the bus, says so, holds it until stdin closes.
HOLDER_SCRIPT = (
    "import sys\n"
    "from limbctl.servo.bus import ServoBus\n"
    "with ServoBus(sys.argv[1], 4000000, (1, 2), latency_timer_ms=2.0) as bus:\n"
    "    print('holding', flush=True)\n"
    "    sys.stdin.read()\n"
)


def open_bus(port: str) -> ServoBus:
    return ServoBus(port, 4_000_000, (1, 2), latency_timer_ms=2.0)


def test_a_second_bus_in_this_or_another_process_is_refused_naming_the_holder(sim, tmp_path):
    """The lock names its holder; holders without one are found by their open file."""
    with open_bus(sim.port) as first:
        before = first.read_positions()
        start = time.monotonic()
        with pytest.raises(PortInUse) as refused:
            open_bus(sim.port).open()
        refused_after_s = time.monotonic() - start
        message = str(refused.value)
        assert f"pid {os.getpid()}" in message and "this process" in message
        assert "cable" not in message and "thread" not in message
        # refused at once: no ping was tried (a ping would wait for replies)
        assert refused_after_s < 1.0
        first.write_goals(before)
        assert first.read_positions().keys() == {1, 2}
    # closed: the lock went with it
    with open_bus(sim.port) as again:
        assert again.read_positions().keys() == {1, 2}
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLDER_SCRIPT, sim.port],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
        env=env,
    )
    try:
        assert holder.stdout.readline().strip() == "holding"
        assert PortHolder(holder.pid, " ".join(holder.args)) in port_holders(sim.port)
        with pytest.raises(PortInUse) as refused:
            open_bus(sim.port).open()
        message = str(refused.value)
        assert f"pid {holder.pid} (" in message
        assert "ServoBus(sys.argv[1]" in message, "the holder's command line is named"
        assert "this process" not in message
    finally:
        holder.stdin.close()
        assert holder.wait(timeout=30) == 0
    # the holder ended: the port is free again
    with open_bus(sim.port) as bus:
        assert bus.read_positions().keys() == {1, 2}
    plain = PortHandler(sim.port)  # the SDK alone opens without locking
    assert plain.openPort()
    try:
        # the simulator keeps the pty's slave end open too; both are this test's processes
        pids = {holder.pid for holder in port_holders(sim.port)}
        assert os.getpid() in pids
    finally:
        plain.closePort()
    assert port_holders(tmp_path / "ttyNONE") == []
