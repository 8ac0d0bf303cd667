"""ServoBus through the real dynamixel-sdk over the simulator's pty (no mocks)."""

import pytest

from calib import default_sim_profile
from firmware_sim import SimulatedBus
from limbctl.errors import (
    BusError,
    BusTimeout,
    ConfigError,
    CorruptReply,
    InvalidInputError,
    PortError,
    ServoAlarm,
)
from limbctl.servo.bus import ServoBus
from limbctl.servo.control_table import ModelNumber, OperatingMode, Register
from limbctl.servo.profiles import joint_tick_limits
from limbctl.servo.setup import configure_servos
from tests.safety.support import wait_for

PROFILE = default_sim_profile()
LIMITS = {
    PROFILE.pan.id: joint_tick_limits(PROFILE.pan),
    PROFILE.tilt.id: joint_tick_limits(PROFILE.tilt),
}


def open_bus(sim, **options):
    return ServoBus.from_profile(PROFILE, port=sim.port, **options)


def test_open_configure_goals_retries_and_refusals_on_one_bus(sim, tmp_path):
    """Also: dropped replies retried; silence, corruption, a vanished servo, unplugging named."""
    bus = open_bus(sim)
    with bus:
        assert bus.is_open
        assert bus.models == {1: ModelNumber.XL430_W250, 2: ModelNumber.XL430_W250}
        assert all(version > 0 for version in bus.firmware.values())
        assert bus.fast_sync_read is True  # the simulator's firmware has Fast Sync Read
    assert not bus.is_open
    bus.close()
    bus.close()
    with pytest.raises(PortError, match="not open"):
        bus.read_positions()
    absent = ServoBus(str(tmp_path / "ttyUSB9"), 57600, (1, 2))
    other_model = ServoBus(sim.port, PROFILE.baud, PROFILE.ids, model="xm430-w350")
    missing = ServoBus(sim.port, PROFILE.baud, (1, 7), retry_budget_s=0.05, max_attempts=2)
    refused = (
        (absent, PortError, r"ttyUSB9 does not exist: check the cable / permissions"),
        (other_model, ConfigError, r"servo 1 is XL430-W250 \(1060\).*XM430-W350 \(1020\)"),
        (missing, BusTimeout, r"ping servo 7: servo 7 did not answer after 2 attempts"),
    )
    for bus, error, message in refused:
        with pytest.raises(error, match=message):
            bus.open()
        assert not bus.is_open, message
    goals = {1: PROFILE.pan.zero_tick + 200, 2: PROFILE.tilt.zero_tick - 150}
    with open_bus(sim) as bus:
        before = sim.truth()["servos"][1]["goal_position"]
        with pytest.raises(InvalidInputError, match=r"servo 1 must be an integer tick in 0..4095"):
            bus.write_goals({1: 5000, 2: 2000})
        with pytest.raises(InvalidInputError):
            bus.write_goals({1: 2000.5, 2: 2000})
        with pytest.raises(ConfigError, match="not on this bus"):
            bus.write_goals({9: 2000})
        assert sim.truth()["servos"][1]["goal_position"] == before
        bus.set_torque(True)
        # an EEPROM write with torque on is refused by the servo
        with pytest.raises(BusError, match=r"servo 1 refused it \(error 7: .*torque on"):
            bus.write(Register.MAX_POSITION_LIMIT, 1, 3000)
        configure_servos(bus, LIMITS, profile_velocity=120, profile_acceleration=40)
        assert bus.torque_enabled() == {1: False, 2: False}
        for servo_id, (lo, hi) in LIMITS.items():
            assert bus.read(Register.MIN_POSITION_LIMIT, servo_id) == lo
            assert bus.read(Register.MAX_POSITION_LIMIT, servo_id) == hi
            assert bus.read(Register.OPERATING_MODE, servo_id) == OperatingMode.POSITION
            assert bus.read(Register.RETURN_DELAY_TIME, servo_id) == 0
            assert bus.read(Register.PROFILE_VELOCITY, servo_id) == 120
            assert bus.read(Register.PROFILE_ACCELERATION, servo_id) == 40
        with pytest.raises(ConfigError, match="exactly the servos"):
            configure_servos(bus, {1: (0, 10)})
        with pytest.raises(ConfigError, match=r"servo 2 must satisfy 0 <= min <= max"):
            configure_servos(bus, {1: (0, 10), 2: (20, 10)})
        configure_servos(bus, LIMITS, profile_velocity=0, profile_acceleration=0)
        bus.set_torque(True)
        bus.write_goals(goals)
        truth = sim.truth()["servos"]
        assert {i: truth[i]["goal_position"] for i in goals} == goals

        def arrived():
            present = bus.read_positions()
            return all(abs(present[i] - goals[i]) <= 3 for i in goals)

        wait_for(arrived, 10.0, "both servos to reach their goals")
    with open_bus(sim, max_attempts=8, retry_budget_s=2.0) as bus:
        sim.set_faults(drop=0.3, seed=3)
        for _ in range(20):
            assert set(bus.read_positions()) == {1, 2}
        assert bus.stats.retries > 0
    with open_bus(sim, max_attempts=2, retry_budget_s=0.2) as bus:
        sim.set_faults(drop=1.0)
        with pytest.raises(BusTimeout, match="did not answer after 2 attempts"):
            bus.read_positions()
        with pytest.raises(BusTimeout, match="servo 2"):
            bus.read(Register.PRESENT_TEMPERATURE, 2)
        sim.set_faults(corrupt=1.0)
        with pytest.raises(CorruptReply, match="kept failing CRC/framing after 2 attempts"):
            bus.read(Register.PRESENT_POSITION, 1)
        sim.set_faults()
        assert set(bus.read_positions()) == {1, 2}
        sim.vanish(2, 0.3)
        with pytest.raises(BusTimeout, match="servo 2"):
            bus.read(Register.PRESENT_POSITION, 2)
        wait_for(lambda: _answers(bus, 2), 5.0, "servo 2 to come back")
        sim.close()  # the adapter is unplugged: the pty goes away (the fixture checks the exit)
        with pytest.raises(PortError, match="was the adapter unplugged"):
            bus.read_positions()


def test_reads_match_the_world_one_packet_each_and_an_alarm_is_raised_until_a_reboot(sim):
    for fast in (True, False):  # Fast Sync Read, then Sync Read, on the same servos
        with open_bus(sim, fast_sync_read=fast) as bus:
            positions = bus.read_positions()
            truth = sim.truth()["servos"]
            for servo_id in PROFILE.ids:
                assert abs(positions[servo_id] - truth[servo_id]["raw_tick"]) <= 1.0
            assert bus.stats.transactions > 0 and bus.stats.timeouts == 0
            # one instruction packet per pose read and per goal write
            configure_servos(bus, LIMITS)
            bus.set_torque(True)
            before = sim.truth()["packets"]
            bus.read_positions()
            after_read = sim.truth()["packets"]
            bus.write_goals({1: PROFILE.pan.zero_tick, 2: PROFILE.tilt.zero_tick})
            after_write = sim.truth()["packets"]
            assert (after_read - before, after_write - after_read) == (1, 1)
            sim.set_temperature(2, 95.0)  # above the 72 degC limit: overheating shutdown
            with pytest.raises(ServoAlarm) as info:
                wait_for(lambda: bus.read_positions() and False, 5.0, "the alarm")
            assert info.value.servo_id == 2
            assert info.value.bits == ("overheating",)
            assert "let it cool" in str(info.value) and "reboot" in str(info.value)
            assert bus.read_hardware_errors() == {1: (), 2: ("overheating",)}
            # X-series shutdown: the overheated servo dropped its torque; the other kept it
            torque = bus.sync_read(Register.TORQUE_ENABLE, check_alert=False)
            assert torque == {1: 1, 2: 0}
            with pytest.raises(ServoAlarm):
                bus.torque_enabled()  # the alarm persists until a reboot
            with pytest.raises(ServoAlarm, match="servo 2: overheating"):
                bus.check_alarms()
            sim.set_temperature(2, 30.0)
            bus.reboot(2)
            bus.check_alarms()
            assert bus.read_hardware_errors() == {1: (), 2: ()}
            assert len(bus.read_positions()) == 2


def _answers(bus, servo_id):
    try:
        bus.read(Register.PRESENT_POSITION, servo_id)
    except BusTimeout:
        return False
    return True


@pytest.mark.parametrize(
    ("model", "named", "numbers", "firmware", "indirect_at"),
    [
        ("xl330-m077", "xl330-m077", (1190, 1190), 52, (208, 208)),
        ("xl330-m288", "xl330-m288", (1200, 1200), 52, (208, 208)),
        # a follower and a leader of two layouts: an XL430 (at 224), an XL330 of firmware 52 (208)
        ("xl430-w250,xl330-m288", None, (1060, 1200), None, (224, 208)),
        # a 330 with later firmware is found at 224
        ("xl330-m288@53", "xl330-m288", (1200, 1200), 53, (224, 224)),
    ],
)
def test_a_bus_finds_each_servos_indirect_data_and_reads_the_cycle(
    tmp_path, model, named, numbers, firmware, indirect_at
):
    with SimulatedBus(ids=(1, 2), model=model, link=tmp_path / "ttyDXL") as sim:
        with ServoBus(sim.port, PROFILE.baud, (1, 2), named) as bus:
            assert bus.models == dict(zip((1, 2), numbers))
            if firmware is not None:
                assert bus.firmware == {1: firmware, 2: firmware}
            configure_servos(bus, LIMITS)
            assert bus.indirect_at == dict(zip((1, 2), indirect_at))
            read = bus.read_cycle(attempts=5)
            assert read.ok, read.problem
            goals = bus.sync_read(Register.GOAL_POSITION)
            assert {i: r.goal for i, r in read.reports.items()} == goals
            assert not any(r.torque_on for r in read.reports.values())
