"""An operator file: a leader gimbal and the hand that holds it, as one YAML mapping, read by
``firmware-sim --operator`` and ``limbctl teleop --operator`` (docs/simulator.md); every key but
``script`` may be left out (:class:`Operator`'s defaults)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import yaml

from firmware_sim.leader import Operator
from firmware_sim.torque import MOTORS
from firmware_sim.world import JOINT_NAMES

#: The keys that describe the leader, beside the grip's.
LEADER_KEYS = ("model", "start_deg")
#: The operator's parameters (:class:`firmware_sim.leader.Operator`).
GRIP_KEYS = ("script", "let_go_s", "release_s", "stiffness_nm_deg", "damping_nm_s_rad")
GRIP_KEYS += ("max_torque_nm",)
DEFAULT_MODEL = "xm430-w350"


def read_operator_file(path: str | Path) -> Any:
    """The parsed YAML of an operator file; ValueError naming the file and the problem."""
    path = Path(path)
    try:
        return yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: cannot read the operator file ({exc})") from None
    except yaml.YAMLError as exc:
        raise ValueError(f"{path}: not valid YAML ({' '.join(str(exc).split())})") from None


def leader_spec(data: Any, ids: Sequence[int], log: str | None = None) -> dict[str, Any]:
    """The simulator's ``leader`` option for a leader at ``ids`` held as an operator file's
    ``data`` says; ``log``: its ground-truth log. ValueError names the key that is unknown or
    malformed, or what the operator refuses."""
    joints = len(ids)
    if not isinstance(data, Mapping):
        raise ValueError(f"expected a mapping of {', '.join(LEADER_KEYS + GRIP_KEYS)}")
    unknown = sorted(set(map(str, data)) - set(LEADER_KEYS + GRIP_KEYS))
    if unknown:
        raise ValueError(f"unknown keys {unknown}; known: {', '.join(LEADER_KEYS + GRIP_KEYS)}")
    model = data.get("model", DEFAULT_MODEL)
    if model not in MOTORS:
        raise ValueError(f"no simulated leader of model {model!r}; known: {', '.join(MOTORS)}")
    angles = ", ".join(JOINT_NAMES[:joints])
    start = data.get("start_deg", [0.0] * joints)
    script = data.get("script")
    for other in {2, 3} - {joints}:  # a file for the other kind of leader
        rows = script if isinstance(script, list) and script else [None]
        if _numbers(start, other) or all(_numbers(row, other + 1) for row in rows):
            raise ValueError(f"it holds a {other}-servo leader; this leader has {joints} servos")
    if not _numbers(start, joints):
        raise ValueError(f"start_deg must be [{angles}] in degrees, got {start!r}")
    if not isinstance(script, list) or not script:
        raise ValueError(f"script must be a list of [t_s, {angles}] rows")
    if not all(_numbers(row, joints + 1) for row in script):
        raise ValueError(f"script must be a list of [t_s, {angles}] rows of finite numbers")
    let_go = data.get("let_go_s")
    if let_go is not None and not (_numbers([let_go], 1) and let_go >= 0.0):
        raise ValueError(f"let_go_s must be a time >= 0 in s (or left out), got {let_go!r}")
    grip = {key: data[key] for key in GRIP_KEYS if key in data}
    try:  # the operator's own checks: times in order, a grip of finite numbers >= 0
        Operator.from_mapping(grip, joints)
    except TypeError as exc:
        raise ValueError(str(exc)) from None
    spec = {"ids": list(ids), "model": model, "start_deg": [float(a) for a in start]}
    return {**spec, "operator": grip, **({} if log is None else {"log": log})}


def _numbers(row: Any, count: int) -> bool:
    """Whether ``row`` is a list of ``count`` finite numbers (not booleans)."""
    return (
        isinstance(row, list)
        and len(row) == count
        and all(isinstance(v, int | float) and not isinstance(v, bool) for v in row)
        and all(math.isfinite(v) for v in row)
    )
