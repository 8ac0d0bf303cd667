"""The X-series control tables of firmware_sim: layout, defaults and e-Manual addresses."""

from __future__ import annotations

import pytest

from firmware_sim.control_table import MEMORY_SIZE, MODELS, X330_BUILDERS, Register, get_model
from tests.servo.test_control_table import E_MANUAL

#: The e-Manual's items (address, size) as limbctl's register table has them, and Moving Status.
EMANUAL = {**E_MANUAL, "MOVING_STATUS": (123, 1, False)}
#: Items only some families have (test_models_differ_where_the_emanual_says_...).
BY_FAMILY = {"GOAL_CURRENT", "CURRENT_LIMIT", "PRESENT_LOAD"}


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
    for name, (address, size, _) in EMANUAL.items():
        if name not in BY_FAMILY or model.has(Register[name]):
            item = model.item(Register[name])
            assert (item.address, item.size) == (address, size), name


def test_models_differ_where_the_emanual_says_every_x_series_model_is_served():
    xl, xm = get_model("XL430-W250"), get_model("xm430-w350")
    assert (xl.model_number, xm.model_number) == (1060, 1020)
    assert xl.has(Register.PRESENT_LOAD) and not xl.has(Register.GOAL_CURRENT)
    assert xm.item(Register.PRESENT_CURRENT).address == 126
    with pytest.raises(ValueError, match="xl430-w250"):
        get_model("ax-12")
    assert get_model("xl330-m288").indirect_blocks == ((168, 208, 20),)
    assert X330_BUILDERS["xl330-m288"](52).indirect_blocks == ((168, 208, 20),)
    later = X330_BUILDERS["xl330-m288"](53)
    assert later.indirect_blocks == ((168, 224, 20),)
    slots = [item for item in later.items if item.register is None]
    assert len(slots) == 40
    first = min(slots, key=lambda item: item.address)
    assert (first.address, first.default, first.maximum) == (168, 224, 243)
    assert len(MODELS) == 22
    numbers = sorted(model.model_number for model in MODELS.values())
    assert numbers[:3] == [1000, 1010, 1020] and numbers[-1] == 1240
    xh430v = get_model("xh430-v350")
    assert (xh430v.model_number, xh430v.current_unit_ma, xh430v.supply_v) == (1040, 1.34, 24.0)
    assert xh430v.item(Register.CURRENT_LIMIT).default == 689
    assert xh430v.item(Register.MAX_VOLTAGE_LIMIT).default == 300
    xc430 = get_model("xc430-w240")
    assert xc430.has(Register.PRESENT_LOAD) and xc430.item(Register.TEMPERATURE_LIMIT).default == 80
    xc330t = get_model("xc330-t288@53")
    assert xc330t.indirect_blocks == ((168, 224, 20),) and xc330t.supply_v == 11.1
    assert xc330t.item(Register.CURRENT_LIMIT).default == 910


@pytest.mark.parametrize(
    ("key", "number", "velocity_limit"), [("xl330-m077", 1190, 1620), ("xl330-m288", 1200, 445)]
)
def test_the_xl330s_follow_their_e_manual_tables(key, number, velocity_limit):
    model = get_model(key)
    assert model.model_number == number
    defaults = {
        Register.CURRENT_LIMIT: (38, 1750, 0, 1750),
        Register.VELOCITY_LIMIT: (44, velocity_limit, 0, 2047),
        Register.MAX_VOLTAGE_LIMIT: (32, 70, 31, 70),  # 0.1 V: a 5 V servo, 3.1..7.0 V
        Register.MIN_VOLTAGE_LIMIT: (34, 35, 31, 70),
        Register.TEMPERATURE_LIMIT: (31, 70, 0, 100),
        Register.SHUTDOWN: (63, 53, 0, 255),
        Register.BAUD_RATE: (8, 1, 0, 6),  # no 4.5 Mbps
        Register.RETURN_DELAY_TIME: (9, 250, 0, 254),
    }
    for register, expected in defaults.items():
        item = model.item(register)
        assert (item.address, item.default, item.minimum, item.maximum) == expected, item.name
    assert model.item(Register.GOAL_CURRENT).address == 102
    assert model.item(Register.PRESENT_CURRENT).address == 126
    assert not model.has(Register.PRESENT_LOAD)
    assert model.current_unit_ma == 1.0
    assert model.operating_modes == frozenset({0, 1, 3, 4, 5, 16})  # 5: current-based position
