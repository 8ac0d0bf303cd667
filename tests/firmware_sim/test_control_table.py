"""The X-series control tables of firmware_sim: layout, defaults and e-Manual addresses."""

from __future__ import annotations

import pytest

from firmware_sim.control_table import MEMORY_SIZE, MODELS, Register, get_model

# (register, address, size) straight from the e-Manual, common to both models
EMANUAL = [
    (Register.MODEL_NUMBER, 0, 2),
    (Register.ID, 7, 1),
    (Register.OPERATING_MODE, 11, 1),
    (Register.HOMING_OFFSET, 20, 4),
    (Register.SHUTDOWN, 63, 1),
    (Register.TORQUE_ENABLE, 64, 1),
    (Register.HARDWARE_ERROR_STATUS, 70, 1),
    (Register.BUS_WATCHDOG, 98, 1),
    (Register.GOAL_POSITION, 116, 4),
    (Register.MOVING_STATUS, 123, 1),
    (Register.PRESENT_POSITION, 132, 4),
    (Register.PRESENT_TEMPERATURE, 146, 1),
]


@pytest.mark.parametrize("key", sorted(MODELS))
def test_items_do_not_overlap_and_defaults_are_in_range(key):
    model = MODELS[key]
    owner = {}
    for item in model.items:
        assert item.address + item.size <= MEMORY_SIZE
        assert item.minimum <= item.default <= item.maximum, item.name
        for offset in range(item.size):
            assert item.address + offset not in owner, f"{item.name} overlaps"
            owner[item.address + offset] = item.name
    for register, address, size in EMANUAL:
        item = model.item(register)
        assert (item.address, item.size) == (address, size)


def test_models_differ_where_the_emanual_says():
    xl, xm = get_model("XL430-W250"), get_model("xm430-w350")
    assert (xl.model_number, xm.model_number) == (1060, 1020)
    assert xl.has(Register.PRESENT_LOAD) and not xl.has(Register.GOAL_CURRENT)
    assert xm.item(Register.PRESENT_CURRENT).address == 126
    with pytest.raises(ValueError, match="xl430-w250"):
        get_model("ax-12")
