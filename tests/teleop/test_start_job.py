"""``limbctl teleop`` from a limb outside the region, parking at the end, and refused lines:
the real job on the simulator's pty through the real SDK (the simulator outlives each session)."""

from __future__ import annotations

import json
import math

import pytest

from calib import default_sim_profile
from limbctl.envelope import Cone
from limbctl.errors import ConfigError
from limbctl.jobs import Connection, TeleopOptions, run_teleop
from limbctl.servo.bus import ServoBus
from limbctl.servo.rig import Rig
from limbctl.teleop.margin import START_MARGIN_DEG
from tests.safety.support import settle_at, wait_for

PROFILE = default_sim_profile()


@pytest.fixture
def cone_model(tmp_path):
    path = tmp_path / "cone.npz"
    Cone(half_angle_deg=40.0).save(
        path, metadata={"rig": PROFILE.name, "calibration": PROFILE.calibration.to_dict()}
    )
    return path


def replay(tmp_path, rows, name="cmds.jsonl"):
    path = tmp_path / name
    path.write_text("".join((r if isinstance(r, str) else json.dumps(r)) + "\n" for r in rows))
    return f"replay:{path}"


def options(model, sim, source, **kwargs):
    # the default reply timeout of a real port (~34 ms): the simulator answers in time on a
    # loaded machine too
    connection = Connection(port=sim.port)
    return TeleopOptions(model=model, source=source, quiet=True, connection=connection, **kwargs)


def put_limb(sim, pan_deg, tilt_deg):
    """Test set-up outside any gate: drive the limb there and leave torque on, holding it."""
    with ServoBus.from_profile(PROFILE, port=sim.port) as bus:
        rig = Rig(PROFILE, bus)
        rig.configure()
        rig.set_torque(True)
        settle_at(rig, math.radians(pan_deg), math.radians(tilt_deg))


def present_pose(sim):
    with ServoBus.from_profile(PROFILE, port=sim.port) as bus:
        return Rig(PROFILE, bus).read_pose()


def torque(sim):
    servos = sim.truth()["servos"]
    return [servos[1]["torque_on"], servos[2]["torque_on"]]


def off_axis_deg(pan, tilt):
    # angle from +x: acos(cos(tilt) cos(pan))
    return math.degrees(math.acos(math.cos(tilt) * math.cos(pan)))


def test_refusing_to_start_leaves_torque_off_and_says_why(tmp_path, sim, cone_model, capsys):
    put_limb(sim, 52.0, -8.0)
    assert torque(sim) == [True, True]
    code = run_teleop(options(cone_model, sim, replay(tmp_path, [{"pan": 0, "tilt": 0}]), wait=1.0))
    err = capsys.readouterr().err
    assert code == 2
    assert torque(sim) == [False, False]
    assert "torque switched off so it can be moved by hand" in err
    assert "not started: the limb stayed outside for 1 s" in err
    assert "turn it right" in err and "--approach" in err


def test_approach_starts_the_session_from_outside(tmp_path, sim, cone_model, capsys):
    put_limb(sim, -50.0, 10.0)
    source = replay(tmp_path, [{"pan": -20.0, "tilt": 5.0}] * 40)
    code = run_teleop(options(cone_model, sim, source, wait=20.0, approach=20.0))
    err = capsys.readouterr().err
    assert code == 0, err
    assert "approach: driving the limb" in err and "(approached)" in err
    # then it followed the commands
    wait_for(lambda: abs(math.degrees(present_pose(sim)[0]) + 20.0) < 0.1, 5.0, "pan -20 deg")


def test_a_session_ending_on_the_edge_is_parked_and_the_next_starts_at_once(
    tmp_path, sim, cone_model, capsys
):
    # commands far outside the cone: the gate slides the limb onto the edge and ends there
    source = replay(tmp_path, [{"pan": 30.0 + 0.5 * i, "tilt": 35.0} for i in range(60)])
    assert run_teleop(options(cone_model, sim, source)) == 0
    first = capsys.readouterr().err
    assert "parked the limb" in first
    # the limb settles inside by the margin (and not far from the edge)
    inside = 40.0 - 0.9 * START_MARGIN_DEG
    wait_for(lambda: off_axis_deg(*present_pose(sim)) <= inside, 5.0, "the limb to settle")
    assert off_axis_deg(*present_pose(sim)) >= 40.0 - 3.0 * START_MARGIN_DEG

    again = replay(tmp_path, [{"pan": 5.0, "tilt": 5.0}] * 20, "again.jsonl")
    assert run_teleop(options(cone_model, sim, again, wait=1.0)) == 0
    second = capsys.readouterr().err
    assert "not started" not in second and "started after" not in second
    assert "ended by           end of input" in second


def test_every_line_refused_exits_2_with_the_reasons(tmp_path, sim, cone_model, capsys):
    rows = ["garbage", '{"pan": 500, "tilt": 0}', "not json", '{"pan": NaN, "tilt": 0}']
    rows += ['{"pan": -720, "tilt": 0}']
    telemetry = tmp_path / "telemetry.jsonl"
    code = run_teleop(options(cone_model, sim, replay(tmp_path, rows), telemetry=telemetry))
    err = capsys.readouterr().err
    assert code == 2
    assert "0 accepted (0 skipped as stale), 5 refused" in err
    assert "refused      2 x malformed JSON (e.g. line 1: 'garbage', line 3: 'not json')" in err
    assert "refused      2 x pan N deg is outside [N, N] (e.g. line 2: " in err
    assert "refused      1 x NaN is not a valid number (e.g. line 4: " in err
    assert "ERROR: every one of the 5 command lines was refused" in err
    logged = [json.loads(line) for line in telemetry.read_text().splitlines()]
    reasons = [reason for row in logged for reason in row["refused"]]
    assert sorted(reasons) == sorted(
        ["malformed JSON"] * 2 + ["pan N deg is outside [N, N]"] * 2 + ["NaN is not a valid number"]
    )


def test_an_approach_faster_than_allowed_is_refused_before_the_port_opens(tmp_path, cone_model):
    # a port that does not exist: the refusal must come first
    connection = Connection(port=str(tmp_path / "no-such-port"))
    source = replay(tmp_path, [{"pan": 0, "tilt": 0}])
    with pytest.raises(ConfigError, match="--approach must be above 0 and at most 30 deg/s"):
        run_teleop(TeleopOptions(cone_model, source, approach=45.0, connection=connection))
