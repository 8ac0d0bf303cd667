"""Starting a session from wherever the limb is, on both rigs through the SDK (waiting for the
hand, timing out, driving in); then ``limbctl teleop``: from outside, parking, refused lines."""

from __future__ import annotations

import io
import json
import math
import threading
import time

import numpy as np
import pytest

from calib import default_sim_profile
from limbctl.errors import ConfigError
from limbctl.jobs import Connection, TeleopOptions, run_teleop
from limbctl.servo.bus import ServoBus
from limbctl.servo.rig import Rig
from limbctl.teleop.approach import SETTLE_DEG
from limbctl.teleop.margin import START_MARGIN_DEG, margins_for
from limbctl.teleop.start import MAX_APPROACH_SPEED_DEG_S, StartOptions, start_session
from tests.safety.support import configured_rig, settle, wait_for
from tests.teleop.chains import RATE, RIGS, chain_gate, live_chain, off_axis_deg, pose_of
from tests.teleop.test_loop import write_lines


@pytest.mark.parametrize("rig_name", RIGS)
def test_outside_waits_with_torque_off_then_starts_once_moved_inside_by_hand(rig_name):
    """Outside: torque off, a waiting status; left there, exit 2; moved inside by hand, started
    once inside by the margin."""
    statuses, published = [], []
    lines, stream = io.StringIO(), io.StringIO()
    outside = pose_of(rig_name, -50.0, -10.0, 40.0)  # swing out; on sim3 the twist too
    with live_chain(rig_name) as session:
        rig, sim = session.rig, session.simulator
        left = chain_gate(session.profile)
        settle(rig, outside)
        timed_out = start_session(
            rig, left, StartOptions(wait_s=1.0, poll_hz=20.0), stream=stream,
            publish=published.append,
        )  # fmt: skip
        left_torque = rig.torque_enabled()
        rig.set_torque(True)
        gate = chain_gate(session.profile)
        settle(rig, pose_of(rig_name, 55.0, 5.0))  # torque on, outside the cone
        outcome = {}

        def starting():
            outcome["start"] = start_session(
                rig, gate, StartOptions(wait_s=30.0), stream=lines, publish=statuses.append
            )

        thread = threading.Thread(target=starting)
        thread.start()
        wait_for(lambda: len(statuses) >= 3, 10.0, "three waiting statuses")
        assert not any(rig.torque_enabled())  # switched off so the hand can move it
        first = statuses[0]
        assert not first.ready and not first.inside_region and first.inside_limits
        assert 14.0 < first.outside_deg < 16.0
        assert first.move_deg[0] < -14.0  # turn it right (toward pan 0)
        pan_id = rig.joints[0].id
        sim.push(pan_id, -15.0)  # the hand turns the pan joint right, ~15 deg/s
        thread.join(timeout=20.0)
        assert not thread.is_alive()
        sim.push(pan_id, 0.0)
        torque = rig.torque_enabled()
        present = rig.read_pose()
    assert not any(left_torque)
    assert not timed_out.started and timed_out.how == "timed out" and timed_out.exit_code == 2
    assert "--approach" in timed_out.message and "torque is off" in timed_out.message
    assert timed_out.status is not None and timed_out.status.move_deg[0] > 9.0  # turn it left
    assert left.safe_pose is None
    assert len(published) >= 10 and not any(s.ready for s in published)
    last = published[-1]
    assert all(abs(a - math.degrees(b)) < 0.5 for a, b in zip(last.pose_deg, outside))
    assert last.outside_deg > 8.0 and last.target_deg is not None
    # to a log one line every LOG_EVERY_S s: the first status's (the limb may drift after it)
    text = stream.getvalue()
    status_lines = [ln for ln in text.splitlines() if ln.startswith("waiting ")]
    assert len(status_lines) == 1 and published[0].advice().split(":")[0] in text, text
    result = outcome["start"]
    assert result.started and result.how == "moved by hand" and result.exit_code == 0
    assert all(torque)
    assert "torque switched off" in lines.getvalue()
    assert "turn it right" in lines.getvalue()
    # it started once inside by the margin, not before, and the gate started where it is
    margins = margins_for(gate, rig)
    margins.margin = math.radians(0.9 * START_MARGIN_DEG)
    assert margins.held_inside(gate.safe_pose)
    assert gate.is_safe(*present)
    assert statuses[-1].ready and not any(s.ready for s in statuses[:-1])


class WriteRecorder:
    """The real rig, remembering each pose written and when: ``writes`` of (monotonic s, pose)."""

    def __init__(self, rig):
        self.rig, self.writes = rig, []

    def __getattr__(self, name):
        return getattr(self.rig, name)

    def write_pose(self, *pose):
        goal = self.rig.write_pose(*pose)
        self.writes.append((time.monotonic(), pose))
        return goal


@pytest.mark.parametrize(
    ("rig_name", "outside_deg"), [("sim", (48.0, 12.0)), ("sim3", (50.0, 10.0, -45.0))]
)
def test_approach_drives_the_limb_inside_along_a_slow_checked_path(rig_name, outside_deg):
    speed = MAX_APPROACH_SPEED_DEG_S
    with live_chain(rig_name) as session:
        rig = session.rig
        gate = chain_gate(session.profile)
        settle(rig, pose_of(rig_name, *outside_deg))
        start = rig.read_pose()
        limb = WriteRecorder(rig)
        result = start_session(
            limb, gate, StartOptions(wait_s=20.0, approach_deg_s=speed, rate_hz=RATE)
        )
        torque = rig.torque_enabled()
    assert result.started and result.how == "approached", result.message
    assert all(torque)
    m = margins_for(gate, rig)
    times = np.array([w[0] for w in limb.writes])
    poses = [w[1] for w in limb.writes]
    assert len(poses) >= 10
    # slow: one cycle's share of the speed per goal, goals at least a cycle apart
    steps = [m.angle(m.point(a), m.point(b)) for a, b in zip(poses[:-1], poses[1:], strict=True)]
    assert math.degrees(max(steps)) <= speed / RATE + 1e-9
    assert np.diff(times).min() >= 0.99 / RATE
    # never further outside than where it started (plus the gate's tolerance)
    worst = m.outside_by(start) + gate.limits.region_tolerance
    assert max(m.outside_by(p) for p in poses) <= worst
    # the session starts once the limb is within SETTLE_DEG of the target (inside by the margin)
    m.margin = math.radians(0.9 * (START_MARGIN_DEG - SETTLE_DEG))
    assert m.held_inside(gate.safe_pose)
    # the nearest such pose, not one far inside
    assert m.angle(m.point(start), m.point(poses[-1])) <= m.outside_by(start) + math.radians(
        4 * START_MARGIN_DEG
    )


# -- the job: ``limbctl teleop`` on the simulator's pty ------------------------------------------

PROFILE = default_sim_profile()


def replay(tmp_path, rows, name="cmds.jsonl"):
    return f"replay:{write_lines(tmp_path / name, rows)}"


def options(model, sim, source, **kwargs):
    """A real port's default reply timeout (~34 ms): a loaded simulator answers in time."""
    connection = Connection(port=sim.port)
    return TeleopOptions(model=model, source=source, quiet=True, connection=connection, **kwargs)


def put_limb(sim, pan_deg, tilt_deg):
    """Test set-up outside any gate: drive the limb there and leave torque on, holding it."""
    with configured_rig(sim.port) as rig:
        settle(rig, (math.radians(pan_deg), math.radians(tilt_deg)))


def present_pose(sim):
    with ServoBus.from_profile(PROFILE, port=sim.port) as bus:
        return Rig(PROFILE, bus).read_pose()


def torque(sim):
    servos = sim.truth()["servos"]
    return [servos[1]["torque_on"], servos[2]["torque_on"]]


def test_teleop_parks_at_the_end_refuses_bad_lines_and_the_outside_and_approaches(
    tmp_path, sim, cone_model, capsys
):
    """One bus: a session ending on the edge parks, the next starts at once; exit 2 when every
    line is refused (reasons counted) or the limb stays outside (torque off, saying why);
    --approach starts from outside."""
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

    rows = ["garbage", '{"pan": 500, "tilt": 0}', "not json", '{"pan": NaN, "tilt": 0}']
    rows += ['{"pan": -720, "tilt": 0}']
    telemetry = tmp_path / "telemetry.jsonl"
    refused = replay(tmp_path, rows, "refused.jsonl")
    assert run_teleop(options(cone_model, sim, refused, telemetry=telemetry)) == 2
    err = capsys.readouterr().err
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
    put_limb(sim, 52.0, -8.0)
    assert torque(sim) == [True, True]
    rest = replay(tmp_path, [{"pan": 0, "tilt": 0}], "rest.jsonl")
    assert run_teleop(options(cone_model, sim, rest, wait=1.0)) == 2
    err = capsys.readouterr().err
    assert torque(sim) == [False, False]
    assert "torque switched off so it can be moved by hand" in err
    assert "not started: the limb stayed outside for 1 s" in err
    assert "turn it right" in err and "--approach" in err

    put_limb(sim, -50.0, 10.0)
    source = replay(tmp_path, [{"pan": -20.0, "tilt": 5.0}] * 40, "approach.jsonl")
    code = run_teleop(options(cone_model, sim, source, wait=20.0, approach=20.0))
    err = capsys.readouterr().err
    assert code == 0, err
    assert "approach: driving the limb" in err and "(approached)" in err
    # then it followed the commands
    wait_for(lambda: abs(math.degrees(present_pose(sim)[0]) + 20.0) < 0.1, 5.0, "pan -20 deg")


def test_an_approach_faster_than_allowed_is_refused_before_the_port_opens(tmp_path, cone_model):
    connection = Connection(port=str(tmp_path / "no-such-port"))  # the refusal must come first
    source = replay(tmp_path, [{"pan": 0, "tilt": 0}])
    with pytest.raises(ConfigError, match="--approach must be above 0 and at most 30 deg/s"):
        run_teleop(TeleopOptions(cone_model, source, approach=45.0, connection=connection))
