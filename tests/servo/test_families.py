"""The X-series family table: every model in one family, and what differs by family."""

import pytest

from limbctl.errors import ConfigError
from limbctl.servo.control_table import MODEL_BY_NAME, ModelNumber, OperatingMode
from limbctl.servo.families import FAMILIES, family_of


def test_every_model_is_in_one_family_an_unknown_one_refused_a_5_v_one_on_12_v_named():
    names = [name for family in FAMILIES.values() for name in family.models.values()]
    assert sorted(names) == sorted(MODEL_BY_NAME) and len(names) == len(set(names))
    with pytest.raises(ConfigError, match=r"unknown servo model 'ax-12': limbctl supports 2xl430"):
        family_of("ax-12")
    xl330 = family_of("xl330-m288")
    assert xl330.voltage_problem(ModelNumber.XL330_M288, 50) == ""
    assert xl330.voltage_problem(ModelNumber.XL330_M288, 120) == (
        "XL330-M288 measures 12.0 V, outside its 3.5..7.0 V limits: it expects 3.7..6 V "
        "(5 V recommended); fix the supply before torque goes on"
    )


@pytest.mark.parametrize(
    ("model", "family", "unit", "top_baud"),
    [
        ("xl330-m288", "XL330", 1.0, 4_000_000),
        ("xc330-t288", "XC330-T", 1.0, 4_000_000),
        ("xl430-w250", "XL430", None, 4_500_000),
        ("2xl430-w250", "XL430", None, 4_500_000),
        ("xc430-w240", "XC430", None, 4_500_000),
        ("xm430-w350", "XM430", 2.69, 4_500_000),
        ("xh430-v350", "XH430-V", 1.34, 4_500_000),
        ("xm540-w270", "XM540", 2.69, 4_500_000),
    ],
)
def test_families_differ_where_the_e_manual_says(model, family, unit, top_baud):
    found = family_of(model)
    assert (found.name, found.current_unit_ma, max(found.bauds)) == (family, unit, top_baud)
    assert (OperatingMode.CURRENT_BASED_POSITION in found.modes) == (
        found.current_unit_ma is not None
    )
    # the 330s have 20 slots and Indirect Data 1 at 224 or 208 (probed in that order)
    assert (found.indirect_slots, found.indirect_data) == (
        (20, (224, 208)) if "330" in family else (28, (224,))
    )
