"""Guided calibration on the simulator finds the world's true zero ticks and directions."""

import threading
from importlib import resources
from pathlib import Path

import pytest

from calib.profile import default_sim_profile, load_profile
from limbctl.cli import build_parser, main
from limbctl.errors import BusTimeout, ConfigError, SafetyError
from limbctl.servo.calibrate import (
    MAX_FAILED_READS,
    CalibrationResult,
    profile_from_calibration,
    wait_still,
)
from limbctl.servo.control_table import Register


class FlakyStillLimb:
    """A limb held still at ``ticks`` whose reads fail where ``fails(n)`` says (read n)."""

    def __init__(self, ticks, fails):
        self.ticks, self.fails, self.reads = ticks, fails, 0

    def read_ticks(self):
        self.reads += 1
        if self.fails(self.reads):
            raise BusTimeout("servo 1 did not answer", 1)
        return self.ticks

    def set_torque(self, enabled):
        pass


@pytest.mark.parametrize(
    ("options", "limits"),
    [
        (
            ["--name", "bench", "--pan-limits=-100,100", "--tilt-limits=-40,60"],
            {"pan": (-100.0, 100.0), "tilt": (-40.0, 60.0)},
        ),
        # --ids 1,2,3 takes sim3's roll (--rig sim3 loading it: the refusals below)
        (["--ids", "1,2,3", "--roll-limits=-80,80"], {"pan": None, "roll": (-80.0, 80.0)}),
    ],
    ids=["sim", "three-ids"],
)
def test_calibration_on_the_simulator_finds_the_truth(tmp_path, options, limits):
    out = tmp_path / "rig.yaml"
    args = build_parser().parse_args(["calibrate", "--out", str(out), *options])
    assert args.job(args) == 0  # the typed calibrate job the parser chose
    found = load_profile(out)
    truth = default_sim_profile("sim3" if len(found.joints) == 3 else "sim")  # the true geometry
    assert [n for n, _ in found.joints] == [n for n, _ in truth.joints]
    for name, true in truth.joints:
        joint = found.joint(name)
        assert abs(joint.zero_tick - true.zero_tick) <= 3, name
        assert (joint.id, joint.direction) == (true.id, true.direction), name
        if name in limits:  # hard limits as asked, or (None) the base profile's
            assert (joint.min_deg, joint.max_deg) == (limits[name] or (true.min_deg, true.max_deg))
        # the simulator's profile describes the calibrated limb: its end stops carry over
        assert (joint.stop_min_deg, joint.stop_max_deg) == (true.stop_min_deg, true.stop_max_deg)
    assert found.port == "sim"
    if "--name" in options:
        assert found.name == "bench"


def test_limits_must_contain_the_rest_pose_and_reads_may_drop_now_and_then_not_always():
    result = CalibrationResult(2000, 2000, 1, -1)
    with pytest.raises(SafetyError, match="rest pose"):
        profile_from_calibration(default_sim_profile(), result, "x", "sim", (10, 90), (-10, 10))
    limb = FlakyStillLimb((2000, 1500), fails=lambda n: n % 3 == 0)  # every third read fails
    assert wait_still(limb, lambda t: True, 5.0, threading.Event()) == (2000, 1500)
    assert limb.reads > 3
    limb = FlakyStillLimb((2000, 1500), fails=lambda n: n > 5)
    with pytest.raises(BusTimeout) as err:
        wait_still(limb, lambda t: False, 30.0, threading.Event())
    assert limb.reads == 5 + MAX_FAILED_READS
    assert err.value.servo_id == 1
    assert f"{MAX_FAILED_READS} reads in a row failed" in str(err.value)
    assert "nothing was written" in str(err.value)


def test_on_a_port_the_servos_named_by_ids_are_calibrated_inside_the_assumed_end_stops(
    tmp_path, capsys, sim, sdk
):
    """--ids are the servos read; on a port without a profile the stops are taken as +-90 deg."""
    hand = Path(str(resources.files("limbctl").joinpath("data", "calibration_hand.yaml")))
    out = tmp_path / "rig.yaml"
    truth = default_sim_profile()
    for old_id, new_id in ((1, 5), (2, 6)):  # torque is off: ID is EEPROM, written at once
        assert sdk.packet.write1ByteTxRx(sdk.port, old_id, Register.ID.address, new_id)[0] == 0
    sdk.port.closePort()
    sim.set_hand(hand)
    assert main(["calibrate", "--port", sim.port, "--ids", "5,6", "--out", str(out)]) == 0
    found = load_profile(out)
    assert (found.pan.id, found.tilt.id) == (5, 6)
    assert abs(found.pan.zero_tick - truth.pan.zero_tick) <= 3
    assert abs(found.tilt.zero_tick - truth.tilt.zero_tick) <= 3
    assert found.tilt.direction == truth.tilt.direction
    assert (found.pan.min_deg, found.pan.max_deg) == (-89.0, 89.0)  # base -115..115 narrowed
    assert (found.pan.stop_min_deg, found.pan.stop_max_deg) == (-90.0, 90.0)
    assert (found.tilt.min_deg, found.tilt.max_deg) == (truth.tilt.min_deg, truth.tilt.max_deg)
    said = capsys.readouterr().err
    assert "pan hard limits -89..89 deg (1 deg inside the end stops -90..90)" in said


@pytest.mark.parametrize(
    ("options", "problem"),
    [
        (["--tilt-limits=-40,80"], "tilt.max_deg 80 is not 1 deg inside the end stop at 75"),
        (
            ["--pan-stops=-95,95", "--pan-limits=-100,100"],
            "pan.min_deg -100 is not 1 deg inside the end stop at -95",
        ),
        (["--ids", "1,2,3,4"], "--ids expects two or three integers like 1,2 (pan, tilt)"),
        (["--rig", "sim3", "--ids", "1,2"], "has a roll joint (servo 3): give three ids"),
        (["--roll-limits=-10,10"], "--roll-limits and --roll-stops need a roll joint"),
    ],
)
def test_limits_past_the_end_stops_and_ids_or_roll_options_not_fitting_the_rig_are_refused(
    tmp_path, options, problem
):
    out = tmp_path / "rig.yaml"
    args = build_parser().parse_args(["calibrate", "--out", str(out), *options])
    with pytest.raises(ConfigError) as err:
        args.job(args)  # raised before the simulator starts: nothing to clean up
    assert problem in str(err.value)
    if "end stop" in problem:
        assert "--pan-limits inside --pan-stops" in str(err.value)
        assert not str(err.value).startswith("limbctl calibrate")  # the CLI adds its own prefix
    assert not out.exists()
