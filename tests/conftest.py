"""Shared fixtures. Keep this file small and generic; module-specific helpers live in tests."""

from __future__ import annotations

import os
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from dynamixel_sdk import PacketHandler, PortHandler

from calib.profile import default_sim_profile
from firmware_sim import SimulatedBus
from firmware_sim.wire import RIG_BAUD
from tests import system_tools

#: A 20 s recording of a hand teaching the simulated rig an irregular region.
HAND_RECORDING = Path(__file__).parent / "data" / "hand_irregular_seed0_20s.limb"


class SteppedClock:
    """A clock the test sets and steps: ``t`` seconds (the firmware_sim simulators' in
    tests/firmware_sim/conftest.py, the pacer's in tests/teleop/test_pacing.py)."""

    t = 0.0

    def __call__(self) -> float:
        return self.t


@pytest.fixture
def sim(tmp_path):
    """A :class:`SimulatedBus` of servos 1 and 2 at 4 Mbps, checked to shut down cleanly."""
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


def trained_for(rig: str = "sim") -> dict:
    """The metadata (name, calibration) of a model trained for the simulated ``rig``."""
    profile = default_sim_profile(rig)
    return {"rig": profile.name, "calibration": profile.calibration.to_dict()}


@pytest.fixture(scope="module")
def browser():
    """A headless Chromium (tests/view/browser.py) shared by a module's tests."""
    from tests.view.browser import chromium

    with chromium() as driver:
        yield driver


@pytest.fixture(scope="session")
def hand_model_path(tmp_path_factory):
    """A Rigid Map trained on :data:`HAND_RECORDING` for the ``sim`` rig, fitted once a run."""
    from limbctl.envelope import RigidMap
    from limbctl.teach.dataset import load_dataset

    path = tmp_path_factory.mktemp("hand-model") / "model.npz"
    return RigidMap().fit(load_dataset(HAND_RECORDING).quaternions).save(path, trained_for())


@pytest.fixture(scope="session")
def shoulder_model_path(tmp_path_factory):
    """A Rigid Map with twist learned from a shoulder-like region (a band narrowing upward),
    saved for the ``sim3`` rig; fitted once a run."""
    from limbctl.envelope import RigidMap
    from limbctl.envelope.synthetic_twist import ShoulderRegion

    taught = ShoulderRegion().teaching(2500, 1200, 1200, np.random.default_rng(0))
    path = tmp_path_factory.mktemp("shoulder-model") / "model.npz"
    return RigidMap(twist=True).fit(taught).save(path, trained_for("sim3"))


@pytest.fixture
def cone_file(tmp_path):
    """``cone_file(half_angle_deg, rig="sim")``: the path of a cone saved as trained for ``rig``."""

    from limbctl.envelope import Cone

    def save(half_angle_deg: float, rig: str = "sim") -> Path:
        path = tmp_path / f"cone-{rig}-{half_angle_deg:g}.npz"
        return Cone(half_angle_deg=half_angle_deg).save(path, trained_for(rig))

    return save


def pytest_sessionstart(session):
    """Install the programs the browser and terminal tests drive, or say what to install."""
    reporter = session.config.pluginmanager.get_plugin("terminalreporter")
    system_tools.ensure(say=reporter.write_line if reporter else print)
