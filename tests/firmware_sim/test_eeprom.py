"""A servo's EEPROM in a file: what one run sets, the next finds; a foreign file is refused."""

import pytest

from firmware_sim.control_table import Register, get_model
from firmware_sim.eeprom import EepromFile
from firmware_sim.servo import Servo


def test_eeprom_survives_a_power_cycle_and_ram_does_not(tmp_path):
    first = Servo(1, get_model("xl430-w250"), 2048.0)
    assert not EepromFile(tmp_path, 1).load(first)  # no file yet: factory-fresh
    store = EepromFile(tmp_path, 1)
    first.write(7, bytes([2]))  # ID 2
    first.write(8, bytes([6]))  # 4 Mbps
    first.write(65, bytes([1]))  # LED (RAM)
    store.save(first)
    again = Servo(1, get_model("xl430-w250"), 2048.0)
    assert EepromFile(tmp_path, 1).load(again)
    assert (again.servo_id, again.value(Register.BAUD_RATE)) == (2, 6)
    assert again.value(Register.LED) == 0


def test_an_eeprom_of_another_model_is_refused(tmp_path):
    xl = Servo(1, get_model("xl430-w250"), 2048.0)
    xl.write(7, bytes([3]))
    EepromFile(tmp_path, 1).save(xl)
    with pytest.raises(ValueError, match=r"servo-1.eeprom is not the EEPROM of a XL330-M288"):
        EepromFile(tmp_path, 1).load(Servo(1, get_model("xl330-m288"), 2048.0))
