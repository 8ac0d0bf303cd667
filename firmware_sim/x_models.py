"""The rest of the X series, registered into ``control_table.MODELS`` (:func:`register_into`):
each shares a sibling's table with its own model number and its family's changes."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

from firmware_sim.registers import Register


@dataclass(frozen=True)
class Family:
    """What a family changes in its sibling's table (None: the sibling's); ``voltage`` is
    ``(range min, range max, default max, default min)`` in 0.1 V; ``stall_ma`` scales load."""

    base: str
    voltage: tuple[int, int, int, int] | None = None
    temperature_limit: int | None = None
    shutdown: int | None = None
    current_limit: int | None = None
    current_unit_ma: float | None = None
    supply_v: float | None = None
    stall_ma: float | None = None


FAMILIES = {
    # 5 V, like the XL330 (its table; its own model number)
    "XC330-M": Family("xl330-m288", shutdown=52, stall_ma=1800.0),
    "XC330-T": Family(
        "xl330-m288", (55, 140, 140, 55), 70, 52, 910, 1.0, supply_v=11.1, stall_ma=800.0
    ),
    "XL430": Family("xl430-w250"),
    "XC430": Family("xl430-w250", (60, 160, 160, 60), 80),
    "XM430": Family("xm430-w350"),
    "XH430-W": Family("xm430-w350", current_limit=648, stall_ma=1300.0),
    "XH430-V": Family(
        "xm430-w350", (110, 300, 300, 110), 80, 52, 689, 1.34, supply_v=24.0, stall_ma=700.0
    ),
    "XM540": Family("xm430-w350", current_limit=2047, stall_ma=4400.0),
    "XH540-W": Family("xm430-w350", current_limit=2047, stall_ma=4400.0),
    "XH540-V": Family(
        "xm430-w350", (110, 300, 300, 110), 80, 52, 2047, 2.69, supply_v=24.0, stall_ma=2400.0
    ),
}
#: (key, title, model number, family) of every model the base tables do not cover.
X_MODELS = (
    ("xc330-m181", "XC330-M181", 1230, "XC330-M"),
    ("xc330-m288", "XC330-M288", 1240, "XC330-M"),
    ("xc330-t181", "XC330-T181", 1210, "XC330-T"),
    ("xc330-t288", "XC330-T288", 1220, "XC330-T"),
    ("2xl430-w250", "2XL430-W250", 1090, "XL430"),
    ("xc430-w150", "XC430-W150", 1070, "XC430"),
    ("xc430-w240", "XC430-W240", 1080, "XC430"),
    ("xm430-w210", "XM430-W210", 1030, "XM430"),
    ("xh430-w210", "XH430-W210", 1010, "XH430-W"),
    ("xh430-w350", "XH430-W350", 1000, "XH430-W"),
    ("xh430-v210", "XH430-V210", 1050, "XH430-V"),
    ("xh430-v350", "XH430-V350", 1040, "XH430-V"),
    ("xm540-w150", "XM540-W150", 1130, "XM540"),
    ("xm540-w270", "XM540-W270", 1120, "XM540"),
    ("xh540-w150", "XH540-W150", 1110, "XH540-W"),
    ("xh540-w270", "XH540-W270", 1100, "XH540-W"),
    ("xh540-v150", "XH540-V150", 1150, "XH540-V"),
    ("xh540-v270", "XH540-V270", 1140, "XH540-V"),
)


def derive(base: Any, key: str, title: str, number: int, family: Family) -> Any:
    """``base``'s table (a ``control_table.Model``) as model ``number`` of ``family``."""
    reg = Register
    updates: dict[Register, dict[str, int]] = {reg.MODEL_NUMBER: {"default": number}}
    if family.voltage is not None:
        lo, hi, top, bottom = family.voltage
        updates[reg.MAX_VOLTAGE_LIMIT] = {"default": top, "minimum": lo, "maximum": hi}
        updates[reg.MIN_VOLTAGE_LIMIT] = {"default": bottom, "minimum": lo, "maximum": hi}
    if family.temperature_limit is not None:
        updates[reg.TEMPERATURE_LIMIT] = {"default": family.temperature_limit}
    if family.shutdown is not None:
        updates[reg.SHUTDOWN] = {"default": family.shutdown}
    if family.current_limit is not None:
        limit = family.current_limit
        updates[reg.CURRENT_LIMIT] = {"default": limit, "maximum": limit}
        updates[reg.GOAL_CURRENT] = {"minimum": -limit, "maximum": limit}
    items = tuple(
        replace(item, **updates[item.register]) if item.register in updates else item
        for item in base.items
    )
    unit = base.current_unit_ma if family.current_unit_ma is None else family.current_unit_ma
    return replace(
        base,
        key=key,
        title=title,
        model_number=number,
        items=items,
        current_unit_ma=unit,
        stall_current_ma=family.stall_ma or base.stall_current_ma,
        supply_v=family.supply_v or base.supply_v,
    )


def register_into(models: dict[str, Any], x330_builders: dict[str, Callable[[int], Any]]) -> None:
    """Add every model of :data:`X_MODELS` to ``models``, and the 330s' to ``x330_builders``."""
    for key, title, number, name in X_MODELS:
        family = FAMILIES[name]
        if family.base in x330_builders:
            base_builder = x330_builders[family.base]

            def build(firmware: int, b=base_builder, k=key, t=title, n=number, f=family):
                return derive(b(firmware), k, t, n, f)

            x330_builders[key] = build
            models[key] = build(models[family.base].firmware_version)
        else:
            models[key] = derive(models[family.base], key, title, number, family)
