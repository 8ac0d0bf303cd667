"""The twist values the page draws: cells over the swing plane and the gauge of the present pose."""

from __future__ import annotations

import math

import numpy as np
import pytest

from limbctl.envelope import RigidMap
from limbctl.envelope.synthetic_twist import ShoulderRegion
from limbctl.geometry.gimbal import chain_twist, pan_tilt_roll_scalar
from limbctl.geometry.twist import compose, decompose
from limbctl.live import TeleopFeed
from limbctl.teach.twist_guide import TwistPlace
from limbctl.teleop.cycle import Cycle, CycleState
from limbctl.teleop.gate import GateResult, Outcome
from limbctl.view import Board, Live, PanTilt, Scene
from limbctl.view.feed import PoseTap
from limbctl.view.twist import (
    TwistGauge,
    TwistMap,
    band_gauge,
    model_band_map,
    pose_twist,
    taught_gauge,
    taught_map,
)


@pytest.fixture(scope="module")
def shoulder_model():
    """A Rigid Map with twist learned from a shoulder-like region (a band narrowing upward)."""
    region = ShoulderRegion()
    taught = region.teaching(2500, 1200, 1200, np.random.default_rng(0))
    return region, RigidMap(twist=True).fit(taught)


def test_two_servo_json_has_no_twist_keys():
    live = Live("record", PanTilt(1.0, 2.0), 3).to_json()
    scene = Scene().to_json()
    assert "twist" not in live and "twist" not in scene
    assert list(live) == ["kind", "mode", "pose", "sample_count", "teleop", "fault", "note"]
    gauge = TwistGauge(12.345, -40.0, 35.0, "taught here")
    assert Live("record", twist=gauge).to_json()["twist"] == {
        "twist": 12.35,
        "low": -40.0,
        "high": 35.0,
        "of": "taught here",
        "written": None,
    }


def test_a_twist_map_finds_the_cell_of_a_pose_and_refuses_unknown_states():
    cells = np.array([[0, 0, -30.0, 40.0], [-1, 2, 5.0, 8.0]])
    shown = TwistMap(15.0, cells, ("turned", "short"), "taught")
    assert shown.at(7.0, 14.9) == (-30.0, 40.0, "turned")
    assert shown.at(-0.1, 31.0) == (5.0, 8.0, "short")
    assert shown.at(15.0, 0.0) is None
    assert shown.to_json()["cells"][1] == [-1, 2, 5.0, 8.0, "short"]
    with pytest.raises(ValueError, match="unknown cell states"):
        TwistMap(15.0, cells, ("turned", "maybe"), "taught")
    with pytest.raises(ValueError, match="2 cells but 1 states"):
        TwistMap(15.0, cells, ("turned",), "taught")


def test_the_taught_map_says_which_places_lack_a_stop():
    places = (
        TwistPlace(0, 0, -40.0, 40.0, 100, True),
        TwistPlace(1, 0, -2.0, 3.0, 100, False),
        TwistPlace(2, 0, 0.0, 0.0, 5, False),
    )
    shown = taught_map(places, 15.0, 30)
    assert shown.states == ("turned", "short", "few")
    # the gauge reads the range of the pose's cell, and the pose's twist exactly
    pan, tilt, roll = math.radians(20.0), math.radians(5.0), math.radians(10.0)
    gauge = taught_gauge(shown, pan, tilt, roll)
    assert (gauge.low_deg, gauge.high_deg, gauge.of) == (-2.0, 3.0, "taught here")
    # the chain's twist is roll + 2 atan(tan(pan/2) tan(tilt/2))
    assert gauge.twist_deg == pytest.approx(10.0 + math.degrees(chain_twist(pan, tilt)))
    assert taught_gauge(None, pan, tilt, roll).low_deg is None


def test_the_band_gauge_and_map_agree_with_the_region(shoulder_model):
    region, model = shoulder_model
    band = model.region.band
    rng = np.random.default_rng(1)
    checked = 0
    for q in region.teaching(400, 0, 0, rng):
        d, tau = decompose(q)
        tau_deg = math.degrees(float(tau))
        if not model.region.mesh.contains(np.reshape(d, (1, 3)))[0]:
            continue
        for offset in (-100.0, -30.0, 0.0, 30.0, 100.0):
            p = compose(d, math.radians(tau_deg + offset))
            pose = tuple(float(a) for a in pan_tilt_roll_scalar(p, 0.0, 0.0, -math.pi, math.pi))
            gauge = band_gauge(band, pose, None)
            assert gauge.twist_deg == pytest.approx(math.degrees(decompose(p)[1]), abs=1e-9)
            twist = gauge.twist_deg
            # inside the gauge's range (away from its limits) exactly when the model holds it
            room = min(twist - gauge.low_deg, gauge.high_deg - twist)
            if abs(room) > 0.05:
                assert (room > 0) == bool(model.contains(p)), (pose, gauge)
                checked += 1
    assert checked > 1000
    # the map: cells inside the swing region, each the band at its centre
    shown = model_band_map(model, (-115.0, 115.0), (-55.0, 70.0))
    assert len(shown.cells) > 100 and set(shown.states) == {"band"}
    widths = shown.cells[:, 3] - shown.cells[:, 2]
    tilt = (shown.cells[:, 1] + 0.5) * shown.cell_deg
    # the shoulder's band narrows as the limb rises (75 deg half-width low, 25 high)
    assert np.corrcoef(tilt, widths)[0, 1] < -0.8
    assert model_band_map(RigidMap(), (-1.0, 1.0), (-1.0, 1.0)) is None


def test_the_teleop_feed_shows_the_twist_of_a_three_servo_rig(shoulder_model):
    _, model = shoulder_model
    board = Board()
    feed = TeleopFeed(board)
    feed.band = model.region.band
    present = (math.radians(20.0), math.radians(10.0), math.radians(15.0))
    written = GateResult((present[0], present[1], math.radians(12.0)), Outcome.PASSED)
    feed(
        Cycle(
            index=0,
            t=0.0,
            state=CycleState.RUNNING,
            complete=True,
            command_deg=(20.0, 10.0),
            result=written,
            present=present,
            written=True,
        )
    )
    live = board.live
    assert live.pose.pan_deg == pytest.approx(20.0)
    expected = band_gauge(model.region.band, present, pose_twist(*written.pose))
    assert live.twist == expected and live.twist.written_deg is not None
    # a two-servo feed has no band and shows no twist
    plain = Board()
    two = TeleopFeed(plain)
    two(Cycle(index=0, t=0.0, state=CycleState.RUNNING, present=(0.1, 0.2)))
    assert plain.live.twist is None and "twist" not in plain.live.to_json()


class StillLimb:
    """A three-servo limb held still by a hand at one pose (rad)."""

    def __init__(self, pose: tuple[float, float, float]) -> None:
        self.pose = pose

    def read_pose(self) -> tuple[float, float, float]:
        return self.pose


def test_the_pose_tap_shows_a_new_taught_range_at_once_with_the_last_pose():
    board = Board()
    pose = (math.radians(20.0), math.radians(5.0), math.radians(10.0))
    tap = PoseTap(StillLimb(pose), board, "record")
    assert tap.read_pose() == pose
    first = board.live.twist
    assert first.low_deg is None and first.of == "nothing taught here yet"
    assert first.twist_deg == pytest.approx(math.degrees(pose_twist(*pose)))
    # the guide's next assessment: the range there shows without waiting for the next read
    places = (TwistPlace(1, 0, -30.0, 45.0, 100, True),)
    tap.set_twist_map(taught_map(places, 15.0, 30))
    shown = board.live
    assert (shown.twist.low_deg, shown.twist.high_deg) == (-30.0, 45.0)
    assert shown.sample_count == 1 and shown.pose.pan_deg == pytest.approx(20.0)
