"""Joint angle (rad) <-> servo encoder tick, ``zero_tick + direction * angle * 4096 / (2 pi)``."""

from __future__ import annotations

import math

import numpy as np

from limbctl.servo.control_table import TICKS_PER_REV

#: Encoder ticks per radian of joint rotation.
TICKS_PER_RAD = TICKS_PER_REV / (2.0 * math.pi)
#: Slack (in ticks) that keeps an exactly integral limit from being rounded away by float error.
_LIMIT_SLACK = 1e-9


def angle_to_ticks_float(angle: np.ndarray | float, zero_tick: int, direction: int) -> np.ndarray:
    """Unrounded tick position of joint angle ``angle`` (rad); any shape."""
    return zero_tick + direction * np.asarray(angle, dtype=np.float64) * TICKS_PER_RAD


def angle_to_ticks(angle: np.ndarray | float, zero_tick: int, direction: int) -> np.ndarray:
    """Nearest integer tick (int64 array, same shape as ``angle``) of joint angle ``angle``."""
    return np.rint(angle_to_ticks_float(angle, zero_tick, direction)).astype(np.int64)


def ticks_to_angle(ticks: np.ndarray | int, zero_tick: int, direction: int) -> np.ndarray:
    """Joint angle (rad, float64, same shape as ``ticks``) at encoder position ``ticks``."""
    # angle = direction * (ticks - zero_tick) * 2 pi / 4096
    return direction * (np.asarray(ticks, dtype=np.float64) - zero_tick) / TICKS_PER_RAD


def tick_limits(min_deg: float, max_deg: float, zero_tick: int, direction: int) -> tuple[int, int]:
    """The integer tick range ``(lo, hi)``, ``lo <= hi``, rounded inward from [min_deg, max_deg]."""
    ends = angle_to_ticks_float(np.radians([min_deg, max_deg]), zero_tick, direction)
    lo = math.ceil(float(ends.min()) - _LIMIT_SLACK)
    hi = math.floor(float(ends.max()) + _LIMIT_SLACK)
    return lo, hi
