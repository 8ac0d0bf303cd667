"""The X series by family: what differs between the servos limbctl drives (e-Manual defaults)."""

from __future__ import annotations

from dataclasses import dataclass

from limbctl.errors import ConfigError
from limbctl.servo.control_table import ModelNumber, OperatingMode


@dataclass(frozen=True)
class Family:
    """What one X-series family has that others do not (the columns of :data:`FAMILIES`)."""

    name: str
    models: dict[ModelNumber, str]
    rated_v: tuple[float, float, float]
    voltage_limits: tuple[int, int]
    temperature_limit: int
    shutdown: int
    current_unit_ma: float | None
    modes: frozenset[OperatingMode]
    bauds: tuple[int, ...]
    indirect_slots: int = 28
    indirect_data: tuple[int, ...] = (224,)

    def voltage_problem(self, model: ModelNumber, tenths_v: int) -> str:
        """Why a measured Present Input Voltage (0.1 V) must not meet torque ('' if fine)."""
        lo, hi = self.voltage_limits
        if lo <= tenths_v <= hi:
            return ""
        rated_lo, rated_hi, nominal = self.rated_v
        return (
            f"{self.models[model].upper()} measures {tenths_v / 10:.1f} V, outside its "
            f"{lo / 10:.1f}..{hi / 10:.1f} V limits: it expects {rated_lo:g}..{rated_hi:g} V "
            f"({nominal:g} V recommended); fix the supply before torque goes on"
        )


_M = ModelNumber
_CURRENT = frozenset(OperatingMode)
_LOAD = _CURRENT - {OperatingMode.CURRENT, OperatingMode.CURRENT_BASED_POSITION}
#: Bauds (bit/s) by Baud Rate register value: every family has up to 4 Mbps.
_4M = (9600, 57_600, 115_200, 1_000_000, 2_000_000, 3_000_000, 4_000_000)
_4M5 = (*_4M, 4_500_000)
#: The 330s' 20 indirect slots, Indirect Data 1 at 224 or (older firmware) 208.
_X330_INDIRECT = (20, (224, 208))
_X430_INDIRECT = (28, (224,))

# fmt: off
#: Every family limbctl knows, by name. Columns as :class:`Family`: models (model number ->
#: profile name); rated input voltage (lo, hi, recommended, V); factory voltage limits (32, 34;
#: 0.1 V); temperature limit (31; deg C); Shutdown (63) bits; Present Current (126) unit (mA,
#: None: Present Load, 0.1 %); operating modes; bauds by register value; indirect slots from
#: 168 and where Indirect Data 1 may be (probed in order).
FAMILIES: dict[str, Family] = {f.name: f for f in (
    Family("XL330",   {_M.XL330_M077: "xl330-m077", _M.XL330_M288: "xl330-m288"},
           (3.7, 6.0, 5.0),    (35, 70),   70, 53, 1.0,  _CURRENT, _4M,  *_X330_INDIRECT),
    Family("XC330-M", {_M.XC330_M181: "xc330-m181", _M.XC330_M288: "xc330-m288"},
           (3.7, 6.0, 5.0),    (35, 70),   70, 52, 1.0,  _CURRENT, _4M,  *_X330_INDIRECT),
    Family("XC330-T", {_M.XC330_T181: "xc330-t181", _M.XC330_T288: "xc330-t288"},
           (6.5, 12.0, 11.1),  (55, 140),  70, 52, 1.0,  _CURRENT, _4M,  *_X330_INDIRECT),
    Family("XL430",   {_M.XL430_W250: "xl430-w250", _M.XL430_W250_2X: "2xl430-w250"},
           (6.5, 12.0, 11.1),  (60, 140),  72, 52, None, _LOAD,    _4M5, *_X430_INDIRECT),
    Family("XC430",   {_M.XC430_W150: "xc430-w150", _M.XC430_W240: "xc430-w240"},
           (6.5, 12.0, 11.1),  (60, 160),  80, 52, None, _LOAD,    _4M5, *_X430_INDIRECT),
    Family("XM430",   {_M.XM430_W210: "xm430-w210", _M.XM430_W350: "xm430-w350"},
           (10.0, 14.8, 12.0), (95, 160),  80, 52, 2.69, _CURRENT, _4M5, *_X430_INDIRECT),
    Family("XH430-W", {_M.XH430_W210: "xh430-w210", _M.XH430_W350: "xh430-w350"},
           (10.0, 14.8, 12.0), (95, 160),  80, 52, 2.69, _CURRENT, _4M5, *_X430_INDIRECT),
    Family("XH430-V", {_M.XH430_V210: "xh430-v210", _M.XH430_V350: "xh430-v350"},
           (24.0, 24.0, 24.0), (110, 300), 80, 52, 1.34, _CURRENT, _4M5, *_X430_INDIRECT),
    Family("XM540",   {_M.XM540_W150: "xm540-w150", _M.XM540_W270: "xm540-w270"},
           (10.0, 14.8, 12.0), (95, 160),  80, 52, 2.69, _CURRENT, _4M5, *_X430_INDIRECT),
    Family("XH540-W", {_M.XH540_W150: "xh540-w150", _M.XH540_W270: "xh540-w270"},
           (10.0, 14.8, 12.0), (95, 160),  80, 52, 2.69, _CURRENT, _4M5, *_X430_INDIRECT),
    Family("XH540-V", {_M.XH540_V150: "xh540-v150", _M.XH540_V270: "xh540-v270"},
           (24.0, 24.0, 24.0), (110, 300), 80, 52, 2.69, _CURRENT, _4M5, *_X430_INDIRECT),
)}
# fmt: on
#: Profile model name -> family.
FAMILY_OF_NAME: dict[str, Family] = {
    name: family for family in FAMILIES.values() for name in family.models.values()
}


def family_of(model: int | str) -> Family:
    """The family of a model number or profile model name (ConfigError naming the model and the
    supported ones)."""
    for family in FAMILIES.values():
        if model in family.models or model in family.models.values():
            return family
    names = ", ".join(sorted(FAMILY_OF_NAME))
    raise ConfigError(f"unknown servo model {model!r}: limbctl supports {names}")
