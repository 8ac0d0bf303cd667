"""Shared fixtures. Keep this file small and generic; module-specific helpers live in tests."""

from __future__ import annotations

import os
from types import SimpleNamespace

import pytest
from dynamixel_sdk import PacketHandler, PortHandler

from firmware_sim import SimulatedBus
from firmware_sim.wire import RIG_BAUD
from tests import system_tools


@pytest.fixture
def sim(tmp_path):
    """A :class:`SimulatedBus` with servos 1 (pan) and 2 (tilt) at the rig's 4 Mbps, strict; checks
    it shuts down cleanly."""
    link = tmp_path / "ttyDXL"
    with SimulatedBus(ids=(1, 2), link=link, baud=RIG_BAUD) as bus:
        yield bus
    assert not bus.running, "the simulator process is still running"
    assert bus.exitcode == 0, f"the simulator process exited with {bus.exitcode}"
    assert not os.path.lexists(link), f"{link} was left behind"


@pytest.fixture
def sdk(sim):
    """The real dynamixel-sdk opened on ``sim`` at its servos' 4 Mbps: ``.port``, ``.packet``."""
    port = PortHandler(sim.port)
    assert port.setBaudRate(RIG_BAUD), f"cannot open {sim.port}"
    yield SimpleNamespace(port=port, packet=PacketHandler(2.0))
    port.closePort()
    assert not port.is_open


def pytest_sessionstart(session):
    """Install the programs the browser and terminal tests drive, or say in one line what to
    install (tests/system_tools.py)."""
    reporter = session.config.pluginmanager.get_plugin("terminalreporter")
    system_tools.ensure(say=reporter.write_line if reporter else print)
