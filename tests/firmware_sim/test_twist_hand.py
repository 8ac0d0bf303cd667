"""The twist hand: the protocol's order (edge with both twist stops, then wander), the band kept,
the roll it gives, and the three-joint simulator it drives, read through the real dynamixel-sdk."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from dynamixel_sdk import PacketHandler, PortHandler

from firmware_sim import SimulatedBus
from firmware_sim.hand import Hand
from firmware_sim.orientation import chain_quat
from firmware_sim.twist_hand import TWIST_INSET_DEG, TwistHand, hand_from_mapping, hand_from_yaml
from firmware_sim.world import ROLL_JOINT, World
from limbctl.session import demo_region_path

REGION3 = demo_region_path().with_name("demo_region3.yaml")
#: The hand's tremor (0.2 deg peak) rides on top of the band position; half of it on the twist.
TREMOR_SLACK_DEG = 0.15


def sample(hand, t_end, dt=0.02):
    times = np.arange(0.0, t_end, dt)
    poses = np.array([hand.pose_deg(float(t)) for t in times])
    twist = np.array([hand.twist_deg(*p) for p in poses])
    limits = np.array([hand.band.limits_deg(p, t) for p, t, _ in poses])
    return times, poses, twist, limits


def test_a_region_without_twist_is_the_plain_hand_and_with_twist_a_twist_hand():
    data = {"region": {"cone": {"half_angle_deg": 30}}}
    assert type(hand_from_mapping(data)) is Hand
    hand = hand_from_mapping({**data, "twist": {"half_width_deg": 20}})
    assert isinstance(hand, TwistHand)
    with pytest.raises(ValueError, match="not to a script"):
        hand_from_mapping({"script": [[0, 0, 0]], "twist": {"half_width_deg": 20}})


def test_twist_stays_in_the_band_and_reaches_both_stops_along_the_edge_then_in_the_middle():
    hand = hand_from_yaml(REGION3, seed=2)
    start, end = hand.trace_span_s
    times, poses, twist, limits = sample(hand, end + 30.0)
    low, high = limits[:, 0], limits[:, 1]
    assert np.all(twist >= low + TWIST_INSET_DEG - TREMOR_SLACK_DEG)
    assert np.all(twist <= high - TWIST_INSET_DEG + TREMOR_SLACK_DEG)
    near_high = twist >= high - TWIST_INSET_DEG - 0.5
    near_low = twist <= low + TWIST_INSET_DEG + 0.5
    tracing = (times >= start) & (times < end)
    depth = hand.region.edge_distance_deg(poses[:, 0], poses[:, 1])
    # along the edge trace: both stops, at several places round the edge (>= 3 each)
    for near in (near_high, near_low):
        at_edge = near & tracing & (depth < 3.0)
        places = hand.region.boundary_fraction(poses[at_edge, 0], poses[at_edge, 1])
        assert len(np.unique(np.round(places * 8))) >= 3
    # after the trace, the wander still turns to both stops
    assert np.any(near_high & (times > end)) and np.any(near_low & (times > end))


def test_same_seed_same_path_whatever_the_sampling():
    a, b = hand_from_yaml(REGION3, seed=5), hand_from_yaml(REGION3, seed=5)
    coarse = [a.pose_deg(t) for t in np.arange(0.0, 40.0, 0.5)]
    for t in np.arange(0.0, 40.0, 0.01):
        b.pose_deg(float(t))
    fine = [b.pose_deg(t) for t in np.arange(0.0, 40.0, 0.5)]
    assert np.allclose(coarse, fine, atol=1e-12)


def test_the_world_gives_the_hand_the_roll_joint():
    hand = hand_from_yaml(REGION3, seed=1)
    world = World(joints=(*World().joints, ROLL_JOINT), hand=hand, seed=1)
    for _ in range(3000):
        world.step(0.001, {1: None, 2: None, 3: None})
    angles = world.joint_angles_deg()
    pan, tilt, roll = hand.pose_deg(world.hand_time_s)
    # the grip lags the hand by ~15 ms: the roll lies among the hand's rolls of the last 30 ms
    # (a brisk twist turns a few degrees in that time), and the roll really moved
    recent = [hand.pose_deg(world.hand_time_s - 0.001 * k)[2] for k in range(31)]
    assert min(recent) - 1.0 <= angles["roll"] <= max(recent) + 1.0
    assert abs(roll) > 1.0
    assert angles["pan"] == pytest.approx(pan, abs=3.0)
    # a plain hand leaves the roll joint where it rests
    plain = World(
        joints=(*World().joints, ROLL_JOINT),
        hand=hand_from_mapping({"region": {"cone": {"half_angle_deg": 30}}}),
        seed=1,
    )
    rest = plain.joint_angles_deg()["roll"]
    for _ in range(500):
        plain.step(0.001, {1: None, 2: None, 3: None})
    assert plain.joint_angles_deg()["roll"] == rest


def test_simulator_with_a_roll_joint_logs_the_full_orientation(tmp_path):
    log = tmp_path / "goals.jsonl"
    with SimulatedBus(ids=(1, 2, 3), roll_id=3, goal_log=log, link=tmp_path / "tty") as sim:
        port, packet = PortHandler(sim.port), PacketHandler(2.0)
        assert port.openPort()
        try:
            goals = {1: 2185 + 200, 2: 1890 - 150, 3: 1960 + 300}
            for servo_id, tick in goals.items():
                result, error = packet.write4ByteTxRx(port, servo_id, 116, tick)
                assert (result, error) == (0, 0)
        finally:
            port.closePort()
    rows = [json.loads(line) for line in log.read_text().splitlines()]
    assert [r["id"] for r in rows] == [1, 2, 3]
    last = rows[-1]
    rad = 2 * math.pi / 4096
    expected = chain_quat(200 * rad, 150 * rad, 300 * rad)
    assert np.allclose(last["limb_q"], expected, atol=1e-12)
    assert last["limb_q"][0] >= 0
    d = np.array(last["limb_dir"])
    assert np.allclose(
        d,
        [
            math.cos(150 * rad) * math.cos(200 * rad),
            math.cos(150 * rad) * math.sin(200 * rad),
            math.sin(150 * rad),
        ],
    )


def test_roll_id_must_be_a_listed_servo_other_than_pan_and_tilt():
    from firmware_sim.simulator import Simulator

    with pytest.raises(ValueError, match="roll joint's servo 4"):
        Simulator(ids=(1, 2, 3), roll_id=4)
    with pytest.raises(ValueError, match="roll joint's servo 2"):
        Simulator(ids=(1, 2, 3), roll_id=2)
    two = Simulator(ids=(1, 2, 3))
    assert not two.world.has_roll  # servo 3 is a free shaft unless named the roll


def test_a_script_with_roll_turns_the_roll_linearly_and_refuses_mixed_rows():
    hand = hand_from_mapping(
        {"script": [[0, 0, 0, 0], [2, 10, 0, 40]], "tremor_deg": 0}, source="s.yaml"
    )
    assert hand.turns_roll
    assert hand.pose_deg(1.0) == pytest.approx((5.0, 0.0, 20.0))
    assert hand.pose_deg(5.0) == pytest.approx((10.0, 0.0, 40.0))
    with pytest.raises(
        ValueError, match=r"script\[1\] must be \[t_s, pan_deg, tilt_deg, roll_deg\]"
    ):
        hand_from_mapping({"script": [[0, 0, 0, 0], [2, 10, 0]]}, source="s.yaml")
    with pytest.raises(ValueError, match="roll must be finite"):
        hand_from_mapping({"script": [[0, 0, 0, 0], [2, 10, 0, float("nan")]]}, source="s.yaml")


def test_a_minute_of_the_hand_teaches_a_band_within_the_truth_or_names_what_is_missing():
    """The issue's demo: a 60 s teaching at the recorder's 125 Hz, learned. Issue 35: the band
    never reaches more than 1 deg past the true one; it holds >= 99 % of the true region's
    orientations 2 deg inside only where the stops support it, and otherwise lists the places
    whose stops are missing, so the guide withholds READY TO TRAIN (containment wins over
    coverage). Measured: 75.5 % held, 107 places, never past the truth (0.79 deg inside it at
    the nearest); before the evidence cap 99.98 % held, and the band reached 4.66 deg past the
    true stop."""
    from limbctl.demo import true_twist_probes
    from limbctl.geometry.gimbal import direction_to_pan_tilt
    from limbctl.geometry.twist import decompose, wrap
    from limbctl.region.twist_region import TwistRegion

    hand = hand_from_yaml(REGION3, seed=1)
    hand.start_from(0.0, 0.0, 0.0)
    poses = np.radians([hand.pose_deg(float(t)) for t in np.arange(0.0, 60.0, 1.0 / 125.0)])
    q = np.array([chain_quat(*p) for p in poses])
    region = TwistRegion().fit(q)
    probes = true_twist_probes(REGION3)
    d = np.unique(np.round(decompose(probes)[0], 12), axis=0)
    pan, tilt = (np.degrees(a) for a in direction_to_pan_tilt(d))
    low, high = np.radians([hand.band.limits_deg(p, t) for p, t in zip(pan, tilt)]).T
    c, h = region.band.at(d)
    off = wrap(c - 0.5 * (low + high))
    past = np.degrees(np.fmax(off + h, h - off) - 0.5 * (high - low))
    assert past.max() <= 1.0, f"the band reaches {past.max():.2f} deg past the true stop"
    held = np.mean(region.contains(probes))
    assert held >= 0.99 or region.unsupported, f"{100 * held:.2f} % held, nothing asked for"


def test_a_hand_over_a_curved_band_with_bumps_keeps_to_it_and_reaches_its_stops():
    data = {
        "region": {"polygon": [[-40, -30], [40, -30], [40, 40], [-40, 40]]},
        "twist": {
            "centre_deg": {"linear": [10, 0.2, 0], "quadratic": [0.003, 0, -0.002]},
            "half_width_deg": {"linear": [35, 0, -0.2], "bumps": [[0, 5, -10, 8]]},
        },
    }
    hand = hand_from_mapping(data, seed=2)
    _, poses, twist, limits = sample(hand, 40.0)
    low, high = limits[:, 0], limits[:, 1]
    # the band is curved: its width at the bump differs from a plane's by its height
    assert hand.band.limits_deg(0, 5)[1] - hand.band.limits_deg(0, 5)[0] < 2 * (35 - 1 - 9)
    slack = TWIST_INSET_DEG - TREMOR_SLACK_DEG
    assert np.all(twist <= high - slack + 1e-9) and np.all(twist >= low + slack - 1e-9)
    # and it turns to both stops (within its inset and tremor) along the way
    assert np.sum(twist >= high - TWIST_INSET_DEG - TREMOR_SLACK_DEG) > 10
    assert np.sum(twist <= low + TWIST_INSET_DEG + TREMOR_SLACK_DEG) > 10
