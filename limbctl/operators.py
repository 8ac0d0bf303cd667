"""Simulated operators for ``limbctl teleop --operator``: a scripted hand that moves the embedded
simulator's leader gimbal, so a felt leader can be tried without hardware.

An operator is named from :data:`OPERATORS` (files packaged in ``limbctl/data/``) or given as a
YAML file of the same form::

    model: xm430-w350          # the leader's servos (a felt leader needs current sensing)
    start_deg: [0.0, 10.0]     # where the leader rests when the simulator starts (pan, tilt)
    script:                    # where the hand means to go: [t_s, pan_deg, tilt_deg], linear
      - [0.0, 0.0, 10.0]       # between points, the last held; a three-servo leader adds
      - [3.5, 100.0, 10.0]     # roll_deg (and start_deg its roll)
    let_go_s: 6.0              # the hand lets go (omit: it never does)
    # release_s, stiffness_nm_deg, damping_nm_s_rad, max_torque_nm: the grip (see below)

The grip's keys are the simulator's :class:`firmware_sim.leader.Operator` parameters: its
defaults are a relaxed hand (0.3 N m at most).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from calib.yaml_guard import YamlRefused, parse_yaml, read_yaml, shown
from limbctl.errors import ConfigError
from limbctl.servo.control_table import MODEL_BY_NAME

#: Packaged operators by name -> their file in ``limbctl/data/``.
OPERATORS: dict[str, str] = {
    # the demo's two-servo run: pan 100 at tilt 10, about 20 deg past the learned edge, held,
    # let go at 6 s
    "push": "operator_push.yaml",
    # the demo's three-servo run: past the swing edge, back, past the twist band, let go at 9 s
    "push3": "operator_push3.yaml",
}
#: The keys of an operator file beside the grip's.
LEADER_KEYS = ("model", "start_deg")
#: The simulator's operator parameters (firmware_sim.leader.Operator).
GRIP_KEYS = ("script", "let_go_s", "release_s", "stiffness_nm_deg", "damping_nm_s_rad")
GRIP_KEYS += ("max_torque_nm",)


@dataclass(frozen=True)
class SimOperator:
    """A simulated operator and the leader it holds.

    Attributes
    ----------
    name : str
        The registry name or the file it came from (for messages).
    model : str
        The leader servos' model, a rig-profile model name (``"xm430-w350"``).
    start_deg : tuple of float, shape (J,)
        Where the leader rests when the simulator starts, pan, tilt (and roll) in degrees.
    grip : dict
        The simulator's operator as data (``script`` rows of J + 1 numbers, ``let_go_s``, ...).
    """

    name: str
    model: str
    start_deg: tuple[float, ...]
    grip: Mapping[str, Any]

    @property
    def joints(self) -> int:
        """How many joints the leader has (2 or 3)."""
        return len(self.start_deg)

    def leader_spec(self, ids: tuple[int, ...]) -> dict[str, Any]:
        """The simulator's ``leader`` option for a leader at ``ids`` (nobody holds it yet)."""
        return {"ids": list(ids), "model": self.model, "start_deg": list(self.start_deg)}

    def describe(self) -> str:
        """One line: who moves the leader and when the hand lets go."""
        let_go = self.grip.get("let_go_s")
        ends = "never lets go" if let_go is None else f"lets go at {float(let_go):.1f} s"
        last = self.grip["script"][-1]
        goes = ", ".join(f"{v:g}" for v in last[1:])
        return (
            f"a simulated operator ({self.name}) moves the {self.model} leader: its hand goes to "
            f"({goes}) deg by {last[0]:g} s and {ends}"
        )


def load_operator(spec: str, joints: int) -> SimOperator:
    """The operator ``spec`` names (a key of :data:`OPERATORS`) or the YAML file it is, for a
    leader of ``joints`` servos.

    Raises
    ------
    ConfigError
        An unknown name (the known ones listed), a missing or unreadable file, an unknown key, a
        model the simulator does not have, or a script or start that is not ``joints`` angles
        (plus the time) of finite numbers; the message names the file.
    """
    if spec in OPERATORS:
        text = resources.files("limbctl").joinpath("data", OPERATORS[spec]).read_text("utf-8")
        data, where = parse_yaml(text), f"operator {spec!r}"
    else:
        path = Path(spec)
        if path.suffix.lower() not in (".yaml", ".yml") and not path.exists():
            raise ConfigError(
                f"unknown operator {shown(spec)}; known: {', '.join(OPERATORS)}, or a YAML file"
            )
        where = f"operator file {path}"
        try:
            data = read_yaml(path)
        except FileNotFoundError:
            raise ConfigError(f"{where}: no such file") from None
        except (YamlRefused, OSError) as exc:
            raise ConfigError(f"{where}: {exc}") from None
    return _operator_from(data, joints, where, spec)


def _operator_from(data: Any, joints: int, where: str, name: str) -> SimOperator:
    """Check ``data`` (parsed from ``where``) and build the operator, or raise ConfigError."""
    if not isinstance(data, dict):
        raise ConfigError(f"{where}: expected a mapping of {', '.join(LEADER_KEYS + GRIP_KEYS)}")
    unknown = sorted(set(map(str, data)) - set(LEADER_KEYS + GRIP_KEYS))
    if unknown:
        raise ConfigError(
            f"{where}: unknown keys {unknown}; known: {', '.join(LEADER_KEYS + GRIP_KEYS)}"
        )
    model = data.get("model", "xm430-w350")
    if model not in MODEL_BY_NAME:
        raise ConfigError(f"{where}: unknown model {shown(model)}; known: {sorted(MODEL_BY_NAME)}")
    angles = "pan, tilt" if joints == 2 else "pan, tilt, roll"
    start = data.get("start_deg", [0.0] * joints)
    for other in {2, 3} - {joints}:  # an operator for the other kind of leader
        if _numbers(start, other):
            raise ConfigError(
                f"{where} holds a {other}-servo leader; the source's leader has {joints} servos"
            )
    if not _numbers(start, joints):
        raise ConfigError(f"{where}: start_deg must be [{angles}] in degrees, got {shown(start)}")
    script = data.get("script")
    if (
        not isinstance(script, list)
        or not script
        or not all(_numbers(row, joints + 1) for row in script)
    ):
        raise ConfigError(
            f"{where}: script must be a list of [t_s, {angles}] rows of numbers for a "
            f"{joints}-servo leader"
        )
    grip = {key: data[key] for key in GRIP_KEYS if key in data}
    try:  # the simulator's own checks (times in order, a grip of finite numbers >= 0)
        _simulator_operator(joints).from_mapping(grip)
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{where}: {exc}") from None
    return SimOperator(name, model, tuple(float(a) for a in start), grip)


def _numbers(row: Any, count: int) -> bool:
    """Whether ``row`` is a list of ``count`` finite numbers."""
    return (
        isinstance(row, list)
        and len(row) == count
        and all(isinstance(v, int | float) and not isinstance(v, bool) for v in row)
        and all(math.isfinite(v) for v in row)
    )


def _simulator_operator(joints: int) -> type:
    """The simulator's operator class for a leader of ``joints`` servos."""
    from firmware_sim.leader import Operator
    from firmware_sim.leader3 import Operator3

    return Operator3 if joints == 3 else Operator
