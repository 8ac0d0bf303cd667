"""Scanning a port: servos at every baud the simulator serves, and collisions named."""

import pytest

from firmware_sim import SimulatedBus
from limbctl.servo.bus import ServoBus
from limbctl.servo.control_table import MODEL_BY_NAME
from limbctl.servo.scan import NOTHING_ANSWERS, SCAN_BAUDS, scan
from limbctl.servo.setup import configure_servos


@pytest.mark.parametrize("baud", [b for b in SCAN_BAUDS if b != 4_500_000])
def test_a_servo_is_found_at_each_baud(tmp_path, baud):
    with SimulatedBus(ids=(3,), baud=baud, model="xl330-m288", link=tmp_path / "tty") as sim:
        result = scan(sim.port, [baud], latency_timer_ms=2.0)
    assert [(f.servo_id, f.model_number, f.baud) for f in result.found] == [(3, 1200, baud)]
    assert result.collisions == [] and not result.empty


def test_factory_servos_collide_two_bauds_are_both_found_and_nothing_is_said_so(tmp_path):
    with SimulatedBus(factory=2, link=tmp_path / "tty") as sim:
        result = scan(sim.port, [57_600, 4_500_000], latency_timer_ms=2.0)
    assert result.found == []
    assert [(c.servo_id, c.baud) for c in result.collisions] == [(1, 57_600)]
    assert result.report().splitlines() == [
        "two or more servos answer as ID 1 at 57600 baud: their replies collide; connect them "
        "one at a time and give each its own ID (`limbctl motors setup`)",
        "4500000 baud not tried: the serial driver (dynamixel-sdk) cannot open it",
    ]
    with SimulatedBus(factory=2, connect=(2,), link=tmp_path / "tty") as sim:
        result = scan(sim.port, [4_000_000, 57_600], latency_timer_ms=2.0)
    assert [(f.servo_id, f.baud) for f in result.found] == [(1, 57_600)]
    with SimulatedBus(ids=(1,), baud=4_000_000, link=tmp_path / "tty") as sim:
        result = scan(sim.port, [57_600], latency_timer_ms=2.0)
    assert result.empty and result.report() == NOTHING_ANSWERS
    assert "dialout" in NOTHING_ANSWERS and "latency timer" in NOTHING_ANSWERS


def test_every_model_on_one_bus_is_found_and_set_up_for_the_cycle(tmp_path):
    names = sorted(MODEL_BY_NAME)
    ids = tuple(range(1, len(names) + 1))
    with SimulatedBus(ids=ids, model=",".join(names), link=tmp_path / "tty") as sim:
        result = scan(sim.port, [4_000_000], latency_timer_ms=2.0)
        assert {f.servo_id: f.model_number for f in result.found} == {
            i: MODEL_BY_NAME[name] for i, name in zip(ids, names, strict=True)
        }
        with ServoBus(sim.port, 4_000_000, ids) as bus:
            # each family on its own supply passes the voltage check; 330s and 430s mix
            configure_servos(bus, {i: (0, 4095) for i in ids})
            assert set(bus.read_cycle(attempts=5).reports) == set(ids)
