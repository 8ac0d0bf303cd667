"""Parse one command (a JSON line or datagram, the README's forms) into a target orientation."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

import numpy as np

from limbctl.errors import InvalidInputError
from limbctl.geometry.gimbal import pan_tilt_roll_to_quat, pan_tilt_to_direction
from limbctl.geometry.quat import canonical, limb_direction, swing_from_direction
from limbctl.geometry.twist import compose

#: Longest accepted line or datagram (bytes): a full-precision command is under 200.
MAX_LINE_BYTES = 1024
#: Allowed | |q| - 1 |: 3 decimals a component are off by at most sqrt(4) * 5e-4 = 1e-3.
QUAT_NORM_TOLERANCE = 1e-3
#: Shortest accepted ``dir``: shorter is zero up to rounding.
MIN_DIRECTION_NORM = 1e-6
#: Largest accepted component: far beyond any valid value, its square no overflow.
MAX_COMPONENT = 1e6

_FORMS = ("pan/tilt", "dir", "q")
_ALLOWED_KEYS = {"pan", "tilt", "dir", "q", "t"}
#: Keys that carry twist: accepted only on a three-servo rig.
_TWIST_KEYS = {"roll", "twist"}


@dataclass(frozen=True)
class Command:
    """A parsed, validated target: orientation ``q`` (4,) (w >= 0; twist-free on two servos), its
    unit limb ``direction`` (3,) and the line's timestamp ``t`` (s) if it had one."""

    q: np.ndarray
    direction: np.ndarray
    t: float | None = None


def _finite_number(value: object, name: str) -> float:
    # bool is an int subclass in Python; `true` is not a number here
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InvalidInputError(f"{name} must be a number, got {type(value).__name__}")
    try:
        x = float(value)
    except OverflowError:  # a JSON integer too large for a float
        raise InvalidInputError(f"{name} is out of range: {value!r:.40}") from None
    if not math.isfinite(x):
        raise InvalidInputError(f"{name} must be finite, got {value!r}")
    if abs(x) > MAX_COMPONENT:
        raise InvalidInputError(f"{name} is out of range: {value!r}")
    return x


def _vector(value: object, name: str, length: int) -> np.ndarray:
    if not isinstance(value, list) or len(value) != length:
        raise InvalidInputError(f"{name} must be a list of {length} numbers")
    return np.array([_finite_number(v, f"{name}[{i}]") for i, v in enumerate(value)])


def parse_command(line: str | bytes, twist: bool = False) -> Command:
    """Parse one JSON object (a trailing newline allowed) into a :class:`Command`; ``twist`` (a
    three-servo rig): the target keeps its twist and ``roll``/``twist`` are accepted.
    InvalidInputError, with the reason, for anything that is not exactly one valid command."""
    if isinstance(line, bytes):
        if len(line) > MAX_LINE_BYTES:
            raise InvalidInputError(f"line longer than {MAX_LINE_BYTES} bytes")
        try:
            line = line.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise InvalidInputError("line is not UTF-8") from exc
    if len(line.encode("utf-8", "surrogatepass")) > MAX_LINE_BYTES:
        raise InvalidInputError(f"line longer than {MAX_LINE_BYTES} bytes")
    try:
        # NaN/Infinity literals are refused at parse time, not just later
        obj = json.loads(line, parse_constant=_refuse_constant)
    except (json.JSONDecodeError, RecursionError) as exc:
        raise InvalidInputError(f"malformed JSON: {exc}") from exc
    if not isinstance(obj, dict):
        raise InvalidInputError('expected a JSON object such as {"pan": 10, "tilt": 5}')
    carried = sorted(_TWIST_KEYS & set(obj))
    if carried and not twist:
        raise InvalidInputError(
            f"{carried[0]!r} carries twist, and this rig has two servos (no roll joint) to turn "
            "the limb about its own axis; send pan/tilt, dir or q, or use a three-servo rig"
        )
    unknown = set(obj) - _ALLOWED_KEYS - (_TWIST_KEYS if twist else set())
    if unknown:
        raise InvalidInputError(f"unknown key(s) {sorted(unknown)}; use one of {_FORMS}")
    t = _finite_number(obj["t"], "t") if "t" in obj else None
    forms = [("pan" in obj or "tilt" in obj), "dir" in obj, "q" in obj]
    if sum(forms) != 1:
        raise InvalidInputError(f"give exactly one of {_FORMS}")
    if "roll" in obj and not forms[0]:
        raise InvalidInputError("roll goes with pan and tilt")
    if "twist" in obj and not forms[1]:
        raise InvalidInputError('twist goes with dir: {"dir": [x, y, z], "twist": deg}')
    if forms[0]:
        if "pan" not in obj or "tilt" not in obj:
            raise InvalidInputError("pan and tilt must be given together")
        if "roll" in obj:
            return command_from_pose(obj["pan"], obj["tilt"], obj["roll"], t)
        return command_from_pan_tilt(obj["pan"], obj["tilt"], t)
    if forms[1]:
        d = _vector(obj["dir"], "dir", 3)
        norm = float(np.linalg.norm(d))
        if not norm >= MIN_DIRECTION_NORM:
            raise InvalidInputError(f"dir has length {norm:.3g}; it needs a direction")
        direction = d / norm
        if twist:
            tau = _angle_deg(obj.get("twist", 0.0), "twist", 180.0)
            return Command(q=compose(direction, math.radians(tau)), direction=direction, t=t)
    else:
        q = _vector(obj["q"], "q", 4)
        norm = float(np.linalg.norm(q))
        if not abs(norm - 1.0) <= QUAT_NORM_TOLERANCE:
            raise InvalidInputError(f"q has norm {norm:.6g}; send a unit quaternion")
        direction = limb_direction(q / norm)
        if twist:
            return Command(q=canonical(q / norm), direction=direction, t=t)
    return Command(q=swing_from_direction(direction), direction=direction, t=t)


def _angle_deg(value: object, name: str, bound: float) -> float:
    angle = _finite_number(value, name)
    if not -bound <= angle <= bound:
        raise InvalidInputError(f"{name} {angle} deg is outside [-{bound:g}, {bound:g}]")
    return angle


def command_from_pose(
    pan_deg: object, tilt_deg: object, roll_deg: object, t: float | None = None
) -> Command:
    """A three-servo :class:`Command` from joint angles (deg), checked as a JSON line is
    (InvalidInputError for a value that is not a finite number or lies outside its range)."""
    swing = command_from_pan_tilt(pan_deg, tilt_deg, t)
    roll = _angle_deg(roll_deg, "roll", 180.0)
    pan, tilt = float(pan_deg), float(tilt_deg)  # checked just above
    q = pan_tilt_roll_to_quat(math.radians(pan), math.radians(tilt), math.radians(roll))
    return Command(q=q, direction=swing.direction, t=t)


def command_from_pan_tilt(pan_deg: object, tilt_deg: object, t: float | None = None) -> Command:
    """A :class:`Command` from pan in [-180, 180] and tilt in [-90, 90] deg, ``t`` (s) kept
    (InvalidInputError for a value that is not a finite number or lies outside its range)."""
    pan, tilt = _finite_number(pan_deg, "pan"), _finite_number(tilt_deg, "tilt")
    pan, tilt = _angle_deg(pan, "pan", 180.0), _angle_deg(tilt, "tilt", 90.0)
    direction = pan_tilt_to_direction(math.radians(pan), math.radians(tilt))
    return Command(q=swing_from_direction(direction), direction=direction, t=t)


def _refuse_constant(name: str) -> float:
    raise InvalidInputError(f"{name} is not a valid number")
