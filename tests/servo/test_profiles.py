"""limbctl.servo.profiles: the controller's checks of a profile and of what was trained on it."""

from dataclasses import replace

import pytest

from calib.profile import default_sim_profile
from firmware_sim import SimulatedBus
from limbctl.errors import ConfigError
from limbctl.servo.bus import ServoBus
from limbctl.servo.profiles import check_models, check_profile, check_trained_for, save_rig_profile
from tests.conftest import trained_for

PROFILE = default_sim_profile()


def test_a_profile_meets_the_end_stop_and_baud_checks_and_models_of_another_rig_are_refused(
    tmp_path,
):
    beyond = replace(PROFILE.with_joints(tilt=replace(PROFILE.tilt, max_deg=80.0)), source=None)
    with pytest.raises(ConfigError, match=r"^<profile>: tilt.max_deg 80 is not 1 deg inside"):
        check_profile(beyond)
    with pytest.raises(ConfigError, match="tilt.max_deg 80"):
        save_rig_profile(beyond, tmp_path / "rig.yaml")
    assert not (tmp_path / "rig.yaml").exists()
    assert check_profile(PROFILE) is PROFILE
    for model in ("xl430-w250", "xl330-m288"):
        fast = replace(PROFILE, baud=4_500_000, model=model, source=None)
        with pytest.raises(ConfigError) as err:
            check_profile(fast)
        assert str(err.value) == (
            "<profile>: baud 4500000 is one the servos know, but the serial driver "
            "(dynamixel-sdk) cannot open it; choose one of 9600, 57600, 115200, 1000000, "
            "2000000, 3000000, 4000000"
        )
    with pytest.raises(ConfigError, match="model.npz was trained for rig 'bench-2', not 'sim'"):
        check_trained_for({**trained_for(), "rig": "bench-2"}, PROFILE, "model.npz")
    with pytest.raises(ConfigError) as err:
        check_trained_for({**trained_for(), "rig": "b" * 100_000}, PROFILE, "model.npz")
    assert len(str(err.value)) < 200
    shifted = PROFILE.with_joints(pan=replace(PROFILE.pan, zero_tick=PROFILE.pan.zero_tick + 200))
    with pytest.raises(ConfigError) as err:
        check_trained_for(trained_for(), shifted, "model.npz")
    message = str(err.value)
    assert "model.npz was trained under another calibration" in message
    assert "(trained vs now: pan.zero_tick 2185 vs 2385)" in message
    check_trained_for(trained_for(), PROFILE, "model.npz")  # the same rig and calibration pass
    for field, value in (("direction", 1), ("min_deg", -50.0), ("max_deg", 60.0)):
        other = PROFILE.with_joints(tilt=replace(PROFILE.tilt, **{field: value}))
        with pytest.raises(ConfigError, match=f"tilt.{field} "):
            check_trained_for(trained_for(), other, "model.npz")
    # the servo id and the end stops are not part of what a model depends on
    moved = PROFILE.with_joints(tilt=replace(PROFILE.tilt, id=7, stop_max_deg=80.0))
    check_trained_for(trained_for(), moved, "model.npz")
    with pytest.raises(ConfigError) as err:
        check_trained_for({"rig": "sim"}, PROFILE, "old.npz")
    message = str(err.value)
    assert message.startswith("old.npz does not record the calibration it was trained under")
    assert "`limbctl record`, then `limbctl train`" in message
    bad = trained_for()
    bad["calibration"]["pan"]["zero_tick"] = "2185"
    with pytest.raises(ConfigError, match=r"model.npz: calibration.pan.zero_tick must be an"):
        check_trained_for(bad, PROFILE, "model.npz")


def test_a_rig_servo_of_another_model_is_refused_when_a_leader_shares_the_bus(tmp_path):
    models = "xl430-w250,xm430-w350,xl330-m288"
    with SimulatedBus(ids=(1, 2, 3), model=models, link=tmp_path / "t") as sim:
        with ServoBus(sim.port, 4_000_000, (1, 2, 3)) as bus:
            check_models(bus, (1,), "xl430-w250")  # the leader (3) is another model: fine
            with pytest.raises(ConfigError, match=r"^servo 2 is XM430-W350 \(1020\) but the rig"):
                check_models(bus, (1, 2), "xl430-w250")
