"""Simulated operators for ``limbctl teleop --operator``: a scripted hand moving the embedded
simulator's leader, named from :data:`OPERATORS` or a YAML file of
:mod:`firmware_sim.operator_file`'s form."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from calib.yaml_guard import YamlRefused, parse_yaml, read_yaml, shown
from limbctl.errors import ConfigError

#: Packaged operators by name -> their file in ``limbctl/data/``.
OPERATORS: dict[str, str] = {
    "push": "operator_push.yaml",  # about 20 deg past the learned edge, let go at 6 s
    "push3": "operator_push3.yaml",  # past the swing edge, back, past the twist band; 9 s
}


@dataclass(frozen=True)
class SimOperator:
    """A simulated operator (``name``: registry name or file) and the leader it holds: the leader
    servos' ``model``, where they rest at the start (``start_deg`` (J,)), and the simulator's
    operator as data (``grip``: ``script`` rows of J + 1 numbers, ``let_go_s``, ...)."""

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
        An unknown name, a missing or unreadable file, or one the simulator refuses.
    """
    from firmware_sim.operator_file import leader_spec

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
    try:
        leader = leader_spec(data, tuple(range(joints)))
    except ValueError as exc:
        raise ConfigError(f"{where}: {exc}") from None
    return SimOperator(spec, leader["model"], tuple(leader["start_deg"]), leader["operator"])
