"""The simulated gimbal: its chain's geometry, tracking, end stops, load, backdriving, stepping."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from firmware_sim.hand import Hand
from firmware_sim.orientation import (
    chain_quat,
    chain_twist,
    roll_for_twist_deg,
    wrap_deg,
)
from firmware_sim.world import (
    DEFAULT_JOINTS,
    LOAD_LIMIT_PCT,
    ROLL_JOINT,
    STIFFNESS_PCT_PER_DEG,
    Joint,
    World,
)
from tests.geometry.test_gimbal import chain_by_products, twist_about_x

REGIONS = Path(__file__).resolve().parents[2] / "examples" / "regions"
PAN, TILT = DEFAULT_JOINTS
OFF = {1: None, 2: None}


def run(world: World, seconds: float, drive: dict, dt: float = 0.001) -> None:
    for _ in range(round(seconds / dt)):
        world.step(dt, drive)


def tick_at(joint: Joint, angle_deg: float) -> float:
    return joint.raw_tick(math.radians(angle_deg))


def test_ticks_angles_and_directions_round_trip_from_the_true_zeros_to_the_stops():
    world = World()
    rng = np.random.default_rng(3)
    for _ in range(200):
        pan_deg = rng.uniform(PAN.stop_min_deg, PAN.stop_max_deg)
        tilt_deg = rng.uniform(TILT.stop_min_deg, TILT.stop_max_deg)
        raw = {1: tick_at(PAN, pan_deg), 2: tick_at(TILT, tilt_deg)}
        assert math.degrees(PAN.angle_rad(raw[1])) == pytest.approx(pan_deg, abs=1e-9)
        assert math.degrees(TILT.angle_rad(raw[2])) == pytest.approx(tilt_deg, abs=1e-9)
        d = world.direction_for_ticks(raw)
        assert np.linalg.norm(d) == pytest.approx(1.0, abs=1e-12)
        # back from the direction: pan = atan2(dy, dx), tilt = asin(dz)
        assert math.degrees(math.atan2(d[1], d[0])) == pytest.approx(pan_deg, abs=1e-9)
        assert math.degrees(math.asin(d[2])) == pytest.approx(tilt_deg, abs=1e-9)
    assert world.direction_for_ticks({1: 2185.0, 2: 1890.0}) == pytest.approx([1.0, 0.0, 0.0])
    # pan +1: 512 ticks more (45 deg) turns the limb toward +y
    assert world.direction_for_ticks({1: 2185.0 + 512, 2: 1890.0}) == pytest.approx(
        [math.sqrt(0.5), math.sqrt(0.5), 0.0]
    )
    # tilt -1: fewer ticks raise the limb toward +z
    up = world.direction_for_ticks({1: 2185.0, 2: 1890.0 - 4096 / 12})
    assert up == pytest.approx([math.cos(math.pi / 6), 0.0, 0.5])
    # past a stop is where the limb ends up
    beyond = world.direction_for_ticks({1: tick_at(PAN, 170.0), 2: tick_at(TILT, 0.0)})
    at_stop = world.direction_for_ticks({1: tick_at(PAN, 120.0), 2: tick_at(TILT, 0.0)})
    assert beyond == pytest.approx(at_stop)


def test_tracks_a_setpoint_with_small_lag_and_load_and_reads_a_ramps_velocity():
    world = World(seed=1)
    drive = {1: tick_at(PAN, 30.0), 2: tick_at(TILT, -20.0)}
    peak_load = 0.0
    for _ in range(1000):
        world.step(0.001, drive)
        peak_load = max(peak_load, abs(world.load_percent(1)), abs(world.load_percent(2)))
    angles = world.joint_angles_deg()
    assert angles["pan"] == pytest.approx(30.0, abs=0.01)
    assert angles["tilt"] == pytest.approx(-20.0, abs=0.01)
    assert world.raw_tick(1) == pytest.approx(drive[1], abs=0.2)
    assert 5.0 < peak_load < 100.0  # accelerating shows load; a free move never overloads
    assert abs(world.load_percent(1)) < 1.0 and abs(world.velocity(1)) < 1.0
    world = World()
    start = world.raw_tick(1)
    rate = 300.0  # ticks/s
    for k in range(1, 1501):
        world.step(0.001, {1: start + rate * k * 0.001, 2: None})
    assert world.velocity(1) == pytest.approx(rate, rel=1e-3)


@pytest.mark.parametrize(("joint", "beyond_deg"), [(PAN, 130.0), (PAN, -125.0), (TILT, 80.0)])
def test_end_stop_holds_and_load_rises_past_100(joint, beyond_deg):
    world = World()
    other = TILT if joint is PAN else PAN
    drive = {joint.servo_id: tick_at(joint, beyond_deg), other.servo_id: tick_at(other, 0.0)}
    stop = joint.stop_max_deg if beyond_deg > 0 else joint.stop_min_deg
    for _ in range(2000):
        world.step(0.001, drive)
        angle = world.joint_angles_deg()[joint.name]
        assert joint.stop_min_deg - 1e-9 <= angle <= joint.stop_max_deg + 1e-9
    assert world.joint_angles_deg()[joint.name] == pytest.approx(stop, abs=1e-9)
    load = world.load_percent(joint.servo_id)
    assert abs(load) > 100.0
    # the motor pushes toward its setpoint, in shaft ticks
    assert np.sign(load) == np.sign(drive[joint.servo_id] - world.raw_tick(joint.servo_id))


def test_blocked_load_grows_with_the_blocked_error_a_push_loads_a_held_joint_a_stop_carries_it():
    loads = []
    for past_stop_deg in (0.5, 1.0, 1.5, 3.0, 6.0):
        world = World()
        run(world, 1.5, {1: tick_at(PAN, 120.0 + past_stop_deg), 2: None})
        loads.append(world.load_percent(1))
    # load = K * blocked error while below the driver's limit
    expected = [STIFFNESS_PCT_PER_DEG * e for e in (0.5, 1.0, 1.5, 3.0)]
    assert loads[:4] == pytest.approx(expected, rel=0.01)
    assert loads[3] > 100.0  # blocked by a few degrees overloads
    assert loads[4] == pytest.approx(LOAD_LIMIT_PCT)
    world = World(hand=Hand.from_yaml(REGIONS / "cone30.yaml", seed=2))
    drive = {1: tick_at(PAN, 10.0), 2: tick_at(TILT, 5.0)}
    run(world, 1.0, drive)
    assert world.joint_angles_deg() == pytest.approx({"pan": 10.0, "tilt": 5.0}, abs=0.01)
    assert world.hand_time_s == 0.0  # the hand only moves joints whose torque is off
    world.push(1, 130.0)
    run(world, 0.5, drive)
    assert world.load_percent(1) == pytest.approx(-130.0, abs=1.0)
    deflection = world.joint_angles_deg()["pan"] - 10.0
    assert deflection == pytest.approx(130.0 / STIFFNESS_PCT_PER_DEG, abs=0.01)
    world.push(1, 0.0)
    run(world, 0.5, drive)
    assert world.joint_angles_deg()["pan"] == pytest.approx(10.0, abs=0.01)
    assert abs(world.load_percent(1)) < 1.0
    world = World()
    drive = {1: tick_at(PAN, 120.0), 2: None}
    run(world, 1.0, drive)
    world.push(1, 150.0)  # toward increasing ticks = past the +120 stop
    run(world, 0.3, drive)
    assert world.joint_angles_deg()["pan"] == pytest.approx(120.0, abs=1e-9)
    assert abs(world.load_percent(1)) < 1.0


def test_torque_off_stays_put_without_a_hand_and_a_push_backdrives_it_to_the_stop():
    world = World(seed=4)
    before = world.joint_angles_deg()
    run(world, 1.0, OFF)
    assert world.joint_angles_deg() == before
    assert world.load_percent(1) == 0.0 and world.velocity(2) == 0.0
    world.push(2, -40.0)  # toward fewer ticks: tilt (direction -1) rises at 1 deg/s per %
    run(world, 1.0, OFF)
    assert world.joint_angles_deg()["tilt"] == pytest.approx(before["tilt"] + 40.0, abs=1.0)
    run(world, 2.0, OFF)
    assert world.joint_angles_deg()["tilt"] == pytest.approx(TILT.stop_max_deg, abs=1e-9)
    assert world.load_percent(2) == 0.0


def test_the_hand_moves_only_the_free_joint_once_per_millisecond_substep_and_by_its_seed():
    hand = Hand.from_yaml(REGIONS / "irregular.yaml", seed=5)
    world = World(hand=hand)
    drive = {1: tick_at(PAN, 20.0), 2: None}
    tilts = []
    for _ in range(5000):
        world.step(0.001, drive)
        tilts.append(world.joint_angles_deg()["tilt"])
    assert world.joint_angles_deg()["pan"] == pytest.approx(20.0, abs=0.01)
    assert np.ptp(tilts) > 10.0
    assert world.hand_time_s == pytest.approx(5.0)
    # long steps split into millisecond substeps
    fine = World(hand=Hand.from_yaml(REGIONS / "cone30.yaml", seed=6), seed=6)
    coarse = World(hand=Hand.from_yaml(REGIONS / "cone30.yaml", seed=6), seed=6)
    run(fine, 2.0, OFF, dt=0.001)
    run(coarse, 2.0, OFF, dt=0.005)
    assert coarse.joint_angles_deg() == pytest.approx(fine.joint_angles_deg(), abs=1e-9)
    assert coarse.time_s == pytest.approx(2.0)
    # one simulated second is a thousand hand evaluations (timing lives in benchmarks/)
    hand = Hand.from_yaml(REGIONS / "irregular.yaml", seed=7)
    world = World(hand=hand)
    calls = 0
    pose_deg = hand.pose_deg

    def counting(t):
        nonlocal calls
        calls += 1
        return pose_deg(t)

    hand.pose_deg = counting
    run(world, 1.0, OFF)
    assert calls == 1000
    assert world.time_s == pytest.approx(1.0) and world.hand_time_s == pytest.approx(1.0)

    def trajectory(seed):
        hand = Hand.from_yaml(REGIONS / "irregular.yaml", seed=seed)
        world = World(hand=hand, seed=seed)
        out = []
        for _ in range(30):
            run(world, 0.1, OFF)
            out.append((world.raw_tick(1), world.raw_tick(2)))
        return out

    assert trajectory(8) == trajectory(8), "the same seed gave another world"
    assert trajectory(8) != trajectory(9), "another seed gave the same world"


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda world: world.step(0.001, {1: float("nan"), 2: None}), "finite raw tick"),
        (lambda world: world.step(-0.001, OFF), "dt"),
        (lambda world: world.raw_tick(3), "no joint on servo ID 3"),
        (lambda world: world.push(1, float("inf")), "finite"),
        (lambda _: Joint(1, "pan", 2048.0, 2, -90.0, 90.0), "direction"),
        (lambda _: Joint(1, "pan", 2048.0, 1, 90.0, -90.0), "below"),
        (lambda _: World(joints=(PAN, Joint(1, "tilt", 2048.0, 1, -60.0, 60.0))), "distinct"),
        (lambda _: World(joints=(PAN, TILT, ROLL_JOINT, ROLL_JOINT)), "at most one 'roll'"),
        (lambda _: World(joints=(PAN, TILT, Joint(2, "roll", 0.0, 1, -90.0, 90.0))), "distinct"),
    ],
)
def test_bad_calls_raise_clear_errors(call, message):
    with pytest.raises(ValueError, match=message):
        call(World())


def test_the_roll_joint_tracks_like_the_others_and_the_chain_quat_is_the_product():
    three = World(joints=(PAN, TILT, ROLL_JOINT), seed=2)
    two = World(seed=2)
    drive = {1: tick_at(PAN, 20.0), 2: tick_at(TILT, 10.0), 3: tick_at(ROLL_JOINT, 130.0)}
    run(three, 2.0, drive)
    run(two, 2.0, {1: drive[1], 2: drive[2]})
    angles = three.joint_angles_deg()
    # the roll drives to its end stop (105 deg) and loads the motor; pan and tilt as without it
    assert angles["roll"] == pytest.approx(105.0)
    assert three.load_percent(3) == pytest.approx(LOAD_LIMIT_PCT)
    assert angles["pan"] == two.joint_angles_deg()["pan"]
    assert angles["tilt"] == two.joint_angles_deg()["tilt"]
    q = three.orientation_for_ticks({})
    assert np.allclose(q, chain_quat(*(math.radians(angles[k]) for k in ("pan", "tilt", "roll"))))
    rng = np.random.default_rng(3)
    for pan, tilt, roll in rng.uniform([-3, -1.5, -3], [3, 1.5, 3], size=(200, 3)):
        q = np.array(chain_quat(pan, tilt, roll))
        assert np.allclose(q, chain_by_products(pan, tilt, roll), atol=1e-12)
        twist = math.degrees(twist_about_x(q))
        expected = math.degrees(roll + chain_twist(pan, tilt))
        assert wrap_deg(twist - expected) == pytest.approx(0.0, abs=1e-9)
        # the roll that gives a twist undoes the chain's own twist
        back = roll_for_twist_deg(math.degrees(pan), math.degrees(tilt), twist)
        assert wrap_deg(back - math.degrees(roll)) == pytest.approx(0.0, abs=1e-9)
    for pan, tilt, tau in ((30, 30, 8.2), (60, 45, 26.9), (90, 60, 60.0)):  # the figures
        figure = math.degrees(chain_twist(math.radians(pan), math.radians(tilt)))
        assert figure == pytest.approx(tau, abs=0.05)
    # +-180 wraps to +180
    assert [wrap_deg(a) for a in (180.0, -180.0, -540.0)] == [180.0, 180.0, 180.0]
    assert wrap_deg(190.0) == pytest.approx(-170.0)
