"""A twist band over a swing outline: how far the limb may turn about its own axis, by pose.

A REGION.yaml for a three-joint gimbal adds a ``twist:`` section beside its ``region:``::

    twist:
      centre_deg: 0                  # or [c0, c_pan, c_tilt]
      half_width_deg: [40, 0, -0.3]  # or one number

Each value is either a number (the same everywhere) or ``[a, b, c]``, meaning
``a + b * pan_deg + c * tilt_deg`` at the swing pose (pan_deg, tilt_deg): the band's limits may vary
with pan and tilt (``[40, 0, -0.3]`` narrows as the limb rises, as a shoulder's rotation does).
At a pose the allowed twist is ``centre - half_width .. centre + half_width`` (deg), where twist is
the swing-twist angle about the limb's rest axis (:mod:`firmware_sim.orientation`), not the roll
joint's angle. Over the whole swing outline the half width must stay within
MIN_HALF_WIDTH_DEG..MAX_HALF_WIDTH_DEG; the check runs on a CHECK_GRID_STEP_DEG grid of the outline
and at its vertices.
"""

from __future__ import annotations

import math

import numpy as np

from firmware_sim.regions import Region, grid_inside

#: Narrowest half width (deg): the hand keeps TWIST_INSET_DEG from each stop and needs room between.
MIN_HALF_WIDTH_DEG = 3.0
#: Widest half width (deg): a band of 360 deg or more would be no limit; 170 keeps a gap so the
#: band's two stops stay distinct on the circle.
MAX_HALF_WIDTH_DEG = 170.0
#: Spacing (deg) of the grid on which the half width is checked over the outline.
CHECK_GRID_STEP_DEG = 2.0
_KEYS = ("centre_deg", "half_width_deg")


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
    """The allowed twist (deg) at each swing pose: ``centre +- half_width``, each linear in pose.

    Parameters
    ----------
    centre, half_width : tuple of 3 float
        ``(a, b, c)``: the value at (pan_deg, tilt_deg) is ``a + b pan_deg + c tilt_deg``.
    """

    def __init__(
        self, centre: tuple[float, float, float], half_width: tuple[float, float, float]
    ) -> None:
        self.centre = centre
        self.half_width = half_width

    @classmethod
    def from_mapping(cls, data: object, region: Region, source: str = "<twist>") -> TwistBand:
        """A band from a REGION.yaml's ``twist:`` mapping, checked over ``region``; ValueError
        names ``source`` and the problem."""
        if not isinstance(data, dict):
            raise ValueError(f"{source}: twist must be a mapping with keys {', '.join(_KEYS)}")
        unknown = sorted(set(data) - set(_KEYS), key=str)
        if unknown or "half_width_deg" not in data:
            raise ValueError(
                f"{source}: twist takes half_width_deg (required) and centre_deg, got "
                f"{sorted(data, key=str)}"
            )
        band = cls(
            _linear(data.get("centre_deg", 0.0), source, "centre_deg"),
            _linear(data["half_width_deg"], source, "half_width_deg"),
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
        a, b, c = self.centre
        centre = a + b * pan_deg + c * tilt_deg
        a, b, c = self.half_width
        half = a + b * pan_deg + c * tilt_deg
        return (centre - half, centre + half)

    def contains(self, pan_deg: float, tilt_deg: float, twist_deg: float) -> bool:
        """True if ``twist_deg`` lies in the band at the pose (compared on the circle)."""
        low, high = self.limits_deg(pan_deg, tilt_deg)
        centre, half = (low + high) / 2.0, (high - low) / 2.0
        # |wrap(twist - centre)| <= half
        offset = twist_deg - centre
        offset -= 360.0 * math.ceil((offset - 180.0) / 360.0)
        return abs(offset) <= half
