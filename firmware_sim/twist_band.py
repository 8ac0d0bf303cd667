"""A twist band over a swing outline: how far the limb may turn about its own axis, by pose.
The allowed twist (:mod:`firmware_sim.orientation`) is ``centre +- half_width`` (deg), each a
number, ``a + b pan + c tilt`` or a :class:`Curved` (the ``twist:`` forms: docs/simulator.md)."""

from __future__ import annotations

import math

import numpy as np

from firmware_sim.orientation import wrap_deg
from firmware_sim.regions import Region, grid_inside

#: Narrowest half width (deg): the hand keeps TWIST_INSET_DEG from each stop and needs room between.
MIN_HALF_WIDTH_DEG = 3.0
#: Widest half width (deg): 170 keeps the band's two stops distinct on the circle.
MAX_HALF_WIDTH_DEG = 170.0
#: Spacing (deg) of the grid on which the half width is checked over the outline.
CHECK_GRID_STEP_DEG = 2.0
_KEYS = ("centre_deg", "half_width_deg")


_CURVED = ("linear", "quadratic", "bumps")


class Curved:
    """A band value curving with the pose (the mapping form of docs/simulator.md).

    Parameters
    ----------
    linear, quadratic : tuple of 3 float
        ``(a, b, c)``: ``a + b pan + c tilt``; ``(p, m, t)``: ``p pan^2 + m pan tilt + t tilt^2``.
    bumps : tuple of (pan0, tilt0, height, width)
        Gaussian bumps (deg): ``height exp(-((pan - pan0)^2 + (tilt - tilt0)^2) / (2 width^2))``.
    """

    def __init__(self, linear=(0.0, 0.0, 0.0), quadratic=(0.0, 0.0, 0.0), bumps=()) -> None:
        self.linear = tuple(linear)
        self.quadratic = tuple(quadratic)
        self.bumps = tuple(tuple(b) for b in bumps)

    def __call__(self, pan: float, tilt: float) -> float:
        """The value (deg) at the pose (pan, tilt) deg."""
        a, b, c = self.linear
        p, m, t = self.quadratic
        out = a + b * pan + c * tilt + p * pan * pan + m * pan * tilt + t * tilt * tilt
        for p0, t0, height, width in self.bumps:
            out += height * math.exp(-((pan - p0) ** 2 + (tilt - t0) ** 2) / (2.0 * width * width))
        return out


def _value(value: object, source: str, key: str) -> tuple[float, float, float] | Curved:
    """A band value: ``(a, b, c)`` from a number or ``[a, b, c]``, or a :class:`Curved`."""
    if not isinstance(value, dict):
        return _linear(value, source, key)
    unknown = sorted(set(value) - set(_CURVED), key=str)
    if unknown:
        raise ValueError(
            f"{source}: twist.{key} takes {', '.join(_CURVED)} as a mapping, got {unknown}"
        )
    linear = _linear(value.get("linear", 0.0), source, f"{key}.linear")
    quadratic = _linear(value.get("quadratic", 0.0), source, f"{key}.quadratic")
    if value.get("quadratic", None) is not None and not isinstance(value["quadratic"], list):
        raise ValueError(f"{source}: twist.{key}.quadratic must be [p, m, t] (deg^-1)")
    bumps = value.get("bumps", [])
    if not isinstance(bumps, list) or not all(
        isinstance(b, list) and len(b) == 4 and b[3] != 0 for b in bumps
    ):
        raise ValueError(
            f"{source}: twist.{key}.bumps must be a list of [pan_deg, tilt_deg, height_deg, "
            f"width_deg] (width not 0), got {bumps!r}"
        )
    bumps = [_linear(b[:3], source, f"{key}.bumps") + (float(b[3]),) for b in bumps]
    return Curved(linear, quadratic, bumps)


def _at(value: tuple[float, float, float] | Curved, pan: float, tilt: float) -> float:
    """A band value (deg) at the pose (pan, tilt) deg."""
    if isinstance(value, Curved):
        return value(pan, tilt)
    a, b, c = value
    return a + b * pan + c * tilt


def _linear(value: object, source: str, key: str) -> tuple[float, float, float]:
    """``(a, b, c)`` of ``a + b pan + c tilt`` from a number or a list of three numbers."""

    def number(v: object) -> float:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ValueError(f"{source}: twist.{key} must hold finite numbers, got {v!r}")
        return float(v)

    if isinstance(value, (list, tuple)):
        if len(value) != 3:
            raise ValueError(
                f"{source}: twist.{key} must be a number or [a, b, c] (a + b pan + c tilt, deg), "
                f"got {value!r}"
            )
        a, b, c = (number(v) for v in value)
        return (a, b, c)
    return (number(value), 0.0, 0.0)


class TwistBand:
    """The allowed twist (deg) at a swing pose: ``centre +- half_width``, each varying with pose.

    Parameters
    ----------
    centre, half_width : tuple of 3 float or Curved
        ``(a, b, c)``: the value at (pan_deg, tilt_deg) is ``a + b pan_deg + c tilt_deg``; a
        :class:`Curved` adds quadratic terms and bumps.
    """

    def __init__(
        self,
        centre: tuple[float, float, float] | Curved,
        half_width: tuple[float, float, float] | Curved,
    ) -> None:
        self.centre = centre
        self.half_width = half_width

    @classmethod
    def from_mapping(cls, data: object, region: Region, source: str = "<twist>") -> TwistBand:
        """A band from a ``twist:`` mapping checked over ``region``; ValueError names ``source``."""
        if not isinstance(data, dict):
            raise ValueError(f"{source}: twist must be a mapping with keys {', '.join(_KEYS)}")
        unknown = sorted(set(data) - set(_KEYS), key=str)
        if unknown or "half_width_deg" not in data:
            raise ValueError(
                f"{source}: twist takes half_width_deg (required) and centre_deg, got "
                f"{sorted(data, key=str)}"
            )
        band = cls(
            _value(data.get("centre_deg", 0.0), source, "centre_deg"),
            _value(data["half_width_deg"], source, "half_width_deg"),
        )
        points = grid_inside(region, CHECK_GRID_STEP_DEG, 0.0)
        vertices = np.asarray(getattr(region, "vertices_deg", np.empty((0, 2))), dtype=float)
        points = np.concatenate([np.reshape(points, (-1, 2)), vertices.reshape(-1, 2)])
        widths = [band.limits_deg(p, t)[1] - band.limits_deg(p, t)[0] for p, t in points]
        low, high = min(widths) / 2.0, max(widths) / 2.0
        if low < MIN_HALF_WIDTH_DEG or high > MAX_HALF_WIDTH_DEG:
            raise ValueError(
                f"{source}: twist.half_width_deg runs {low:.1f}..{high:.1f} deg over the region; "
                f"keep it within {MIN_HALF_WIDTH_DEG:g}..{MAX_HALF_WIDTH_DEG:g} deg everywhere"
            )
        return band

    def limits_deg(self, pan_deg: float, tilt_deg: float) -> tuple[float, float]:
        """``(low, high)`` twist (deg) allowed at the swing pose; ``low < high``."""
        centre = _at(self.centre, pan_deg, tilt_deg)
        half = _at(self.half_width, pan_deg, tilt_deg)
        return (centre - half, centre + half)

    def contains(self, pan_deg: float, tilt_deg: float, twist_deg: float) -> bool:
        """True if ``twist_deg`` lies in the band at the pose (compared on the circle)."""
        low, high = self.limits_deg(pan_deg, tilt_deg)
        centre, half = (low + high) / 2.0, (high - low) / 2.0
        return abs(wrap_deg(twist_deg - centre)) <= half
