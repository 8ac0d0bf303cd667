"""The cycle's one read through indirect addresses shows each fault; a silent servo is probed."""

from __future__ import annotations

import pytest
from dynamixel_sdk import BROADCAST_ID

from calib import default_sim_profile
from limbctl.servo.control_table import Register
from limbctl.servo.cycle import (
    CYCLE_BYTES,
    INDIRECT_MAP_BLOCK,
    ServoReport,
    cycle_wire_bytes,
    indirect_map,
    read_around_silent,
    wire_budget,
)
from tests.safety.support import configured_rig

PROFILE = default_sim_profile()


@pytest.fixture(params=[True, False], ids=["fast-sync-read", "sync-read"])
def rig(sim, request):
    with configured_rig(sim.port, fast_sync_read=request.param) as rig:
        yield rig


def read_ok(rig, tries: int = 50):
    """A cycle read that succeeded (on a loaded machine a reply may miss its 6 ms timeout)."""
    for _ in range(tries):
        read = rig.read_cycle()
        if read.ok:
            return read
    raise AssertionError(f"{tries} cycle reads failed, the last: {read.problem}")


def test_the_indirect_map_names_each_mapped_byte_and_the_wire_budget_of_a_cycle():
    addresses = [int.from_bytes(indirect_map()[k : k + 2], "little") for k in range(0, 24, 2)]
    assert addresses == [132, 133, 134, 135, 116, 117, 118, 119, 64, 70, 124, 125]
    assert CYCLE_BYTES == 12
    data = bytes([0x00, 0x08, 0, 0, 0xFF, 0x07, 0, 0, 1, 0x24, 0x8B, 0xFC])  # PWM -885
    report = ServoReport.decode(data, pwm_limit=885)
    assert report == ServoReport(2048, 2047, True, ("overheating", "overload"), -885, 885)
    # fast sync read out 14 + 2, back 8 + 2 x 16, sync write of goals 14 + 2 x 5
    assert cycle_wire_bytes(2) == 80
    assert cycle_wire_bytes(2, fast=False) == 16 + 2 * 23 + 24
    assert wire_budget(200.0, 4_000_000, 2) == ""
    assert wire_budget(200.0, 57_600, 2) == (
        "at 57600 baud one cycle's 80 bytes take 13.9 ms on the wire, so the loop runs at most "
        "72 Hz, not 200 Hz: raise the servos' baud to 1000000 (`limbctl motors setup --baud "
        "1000000 --rig PROFILE`, then `baud: 1000000` in the profile)"
    )


def test_the_cycle_read_shows_reboots_torque_alarms_saturation_and_a_silent_servo(sim, sdk, rig):
    """Also: agreement with direct reads, a pushed servo's saturated drive."""
    bus = rig.bus
    for servo_id in PROFILE.ids:
        assert bus.read_block(INDIRECT_MAP_BLOCK, servo_id) == indirect_map()
    read = read_ok(rig)
    assert read.silent == ()
    positions = bus.read_positions()
    goals = bus.sync_read(Register.GOAL_POSITION)
    pwm = bus.sync_read(Register.PRESENT_PWM)
    for servo_id, report in read.reports.items():
        assert abs(report.present - positions[servo_id]) <= 1
        assert report.goal == goals[servo_id]
        assert report.torque_on and report.hardware_error == ()
        # at rest the drive is near zero; set-up read the PWM Limit it is a fraction of
        assert abs(report.pwm) < 0.1 * report.pwm_limit and abs(pwm[servo_id]) < 0.1 * 885
        assert report.pwm_limit == bus.read(Register.PWM_LIMIT, servo_id) == 885
    assert rig.pose_of(read) == pytest.approx(rig.read_pose(), abs=2e-3)
    rig.bus.reboot(1)
    read = read_ok(rig)
    assert read.reports[1] == ServoReport(0, 0, False, ())
    assert read.reports[2].torque_on
    sdk.packet.write1ByteTxOnly(sdk.port, BROADCAST_ID, Register.TORQUE_ENABLE.address, 0)
    read = read_ok(rig)
    assert [r.torque_on for r in read.reports.values()] == [False, False]
    rig.configure()  # the reboot lost servo 1's indirect map
    rig.set_torque(True)
    sim.set_voltage(1, 5.0)  # below the voltage limit; the factory Shutdown mask keeps torque on
    sim.set_temperature(2, 90.0)  # over the limit: shuts down, torque off
    read = read_ok(rig)
    while not read.reports[2].hardware_error:  # the simulator latches on its next step
        read = read_ok(rig)
    assert read.reports[1].hardware_error == ("input voltage",) and read.reports[1].torque_on
    assert read.reports[2].hardware_error == ("overheating",) and not read.reports[2].torque_on
    sim.push(1, 300.0)  # beyond stall: the position controller's drive winds up to its limit
    for _ in range(200):  # the simulator applies the push on its next physics step
        read = read_ok(rig)
        if abs(read.reports[1].pwm) == read.reports[1].pwm_limit:
            break
    assert abs(read.reports[1].pwm) == 885 and abs(read.reports[2].pwm) < 0.1 * 885
    assert abs(read.reports[1].present - read.reports[1].goal) * 360 / 4096 > 5.0
    sim.push(1, 0.0)
    sim.vanish(2, 0.05)
    for _ in range(100):  # each probe waits one reply timeout: 100 of them outlast 0.05 s
        read = read_around_silent(rig.read_cycle, rig.ids, silent=(2,), probe=(2,), attempts=1)
        if read.ok:
            break
    assert set(read.reports) == {1, 2} and read.silent == read.unread == () and read.problem == ""
    sim.vanish(2, 5.0)
    retries = bus.stats.retries
    read = rig.read_cycle()
    assert not read.ok and read.silent == (2,) and read.reports == {}
    assert "servo 2 did not answer" in read.problem
    assert bus.stats.retries == retries, "the cycle read retried"
    # one reply timeout (~35 ms at the SDK's 16 ms latency timer), generous for a loaded machine
    assert read.duration_s < 0.5
    sim.vanish(2, 5.0)
    retries = rig.bus.stats.retries
    read = read_around_silent(rig.read_cycle, rig.ids, silent=(2,), probe=(), attempts=2)
    assert set(read.reports) == {1} and read.unread == (2,) and read.silent == ()
    assert not read.ok and "servo 2 silent, not read until its probe" in read.problem
    probed = read_around_silent(rig.read_cycle, rig.ids, silent=(2,), probe=(2,), attempts=2)
    assert set(probed.reports) == {1} and probed.silent == (2,) and probed.unread == ()
    assert "servo 2 did not answer" in probed.problem
    assert rig.bus.stats.retries == retries, "the probe retried"
    # the other servo's read is one short transfer; the probe one reply timeout (~35 ms here)
    assert read.duration_s < probed.duration_s < 0.5
