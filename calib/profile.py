"""The rig profile: which port and servos a rig uses and how its joints are calibrated. A YAML file,
one key per joint (``calib/rigs/sim.yaml`` explains every field; ``sim3.yaml`` adds ``roll``) or a
``joints:`` list, saved in the form read; the chain is one of :data:`CHAINS`. Errors are one line
naming file and field; what only the servos know is checked on opening a rig."""

from __future__ import annotations

import dataclasses
import math
import os
import tempfile
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

from calib.checker import Checker, ProfileError, ProfileFileError
from calib.yaml_guard import YamlRefused, read_yaml, shown

#: Encoder ticks in one turn of a Dynamixel X-series shaft; a zero tick lies in 0..MAX_TICK.
TICKS_PER_TURN = 4096
MAX_TICK = TICKS_PER_TURN - 1
#: The port name that stands for the embedded simulator.
SIM_PORT = "sim"
#: The packaged simulated rigs (``calib/rigs/NAME.yaml``): two servos, and three with roll.
SIM_RIGS = ("sim", "sim3")
PROTOCOLS = (2.0,)
#: Largest id a servo can have (253 and up are reserved / broadcast).
MAX_SERVO_ID = 252
#: End stops (deg, either side) where a profile states none: a quarter turn, tilt straight up.
DEFAULT_END_STOP_DEG = 90.0
#: Least gap (deg) from a hard limit to its end stop: a goal there, rounded to ticks, stays clear.
END_STOP_MARGIN_DEG = 1.0
#: Longest rig name: it is copied into every recording and model and quoted in messages.
MAX_NAME_CHARS = 64
_JOINT_KEYS = ("id", "zero_tick", "direction", "min_deg", "max_deg")
_JOINT_OPTIONAL_KEYS = ("stop_min_deg", "stop_max_deg")
_CALIBRATION_KEYS = ("zero_tick", "direction", "min_deg", "max_deg")
#: The chains of joints a rig may have, by name, in chain order.
CHAINS = (("pan", "tilt"), ("pan", "tilt", "roll"))
_BUS_KEYS = ("name", "port", "baud", "model", "protocol")


@dataclass(frozen=True)
class JointProfile:
    """One calibrated joint.

    Attributes
    ----------
    id : int
        Servo id on the bus (0..252).
    zero_tick : int
        Encoder tick (0..4095) at joint angle 0.
    direction : int
        +1 if ticks grow with the joint angle, -1 if they shrink.
    min_deg, max_deg : float
        Hard joint limits (deg).
    stop_min_deg, stop_max_deg : float
        The physical end stops (deg), at least END_STOP_MARGIN_DEG outside the hard limits.
    """

    id: int
    zero_tick: int
    direction: int
    min_deg: float
    max_deg: float
    stop_min_deg: float = -DEFAULT_END_STOP_DEG
    stop_max_deg: float = DEFAULT_END_STOP_DEG

    @property
    def min_rad(self) -> float:
        """Lower hard limit in radians."""
        return math.radians(self.min_deg)

    @property
    def max_rad(self) -> float:
        """Upper hard limit in radians."""
        return math.radians(self.max_deg)


@dataclass(frozen=True)
class JointCalibration:
    """What a model depends on in one joint (fields as in :class:`JointProfile`)."""

    zero_tick: int
    direction: int
    min_deg: float
    max_deg: float


@dataclass(frozen=True)
class Calibration:
    """The calibration a recording was made and a model trained under (valid only on it)."""

    joints: tuple[tuple[str, JointCalibration], ...]

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The chain's joint names in order, one of :data:`CHAINS`."""
        return tuple(name for name, _ in self.joints)

    @property
    def twists(self) -> bool:
        """True when the chain ends in a roll joint: its regions carry a twist band."""
        return self.joint_names[-1] == "roll"

    def to_dict(self) -> dict[str, dict[str, Any]]:
        """Plain data: ``{"pan": {"zero_tick": ..., ...}, "tilt": {...}[, "roll": {...}]}``."""
        return {
            name: {key: getattr(joint, key) for key in _CALIBRATION_KEYS}
            for name, joint in self.joints
        }

    def differences(self, other: Calibration) -> tuple[str, ...]:
        """Each field that differs, as ``"pan.zero_tick 2185 vs 2385"`` (self's value first);
        a joint on one side only is ``"roll present vs absent"``."""
        found = []
        mine, theirs = dict(self.joints), dict(other.joints)
        for name in dict.fromkeys((*mine, *theirs)):
            if (name in mine) != (name in theirs):
                side = "present vs absent" if name in mine else "absent vs present"
                found.append(f"{name} {side}")
                continue
            for key in _CALIBRATION_KEYS:
                a, b = getattr(mine[name], key), getattr(theirs[name], key)
                if a != b:
                    found.append(f"{name}.{key} {a:g} vs {b:g}")
        return tuple(found)


@dataclass(frozen=True)
class RigProfile:
    """A whole rig: bus settings and ``joints``, ``(name, joint)`` in chain order (``source``,
    the file read, and ``listed``, joints written as a list, are not compared)."""

    name: str
    port: str
    baud: int
    model: str
    protocol: float
    joints: tuple[tuple[str, JointProfile], ...]
    rest_direction: tuple[float, float, float] = (1.0, 0.0, 0.0)
    source: str | None = field(default=None, compare=False)
    listed: bool = field(default=False, compare=False)

    def joint(self, name: str) -> JointProfile | None:
        """The joint called ``name``, or None if the chain has none."""
        return dict(self.joints).get(name)

    @property
    def pan(self) -> JointProfile:
        """The pan joint (every chain has one)."""
        return self.joints[0][1]

    @property
    def tilt(self) -> JointProfile:
        """The tilt joint (every chain has one)."""
        return self.joints[1][1]

    @property
    def roll(self) -> JointProfile | None:
        """The roll joint, None on a two-servo rig."""
        return self.joint("roll")

    def with_joints(self, **changed: JointProfile) -> RigProfile:
        """This profile with the named joints replaced, or appended in chain order if new."""
        joints = dict(self.joints) | changed
        names = next((c for c in CHAINS if set(c) == set(joints)), tuple(joints))
        return dataclasses.replace(self, joints=tuple((n, joints[n]) for n in names))

    @property
    def twists(self) -> bool:
        """True when the chain ends in a roll joint: its regions carry a twist band."""
        return self.joints[-1][0] == "roll"

    @property
    def is_sim(self) -> bool:
        """True when the profile asks for the embedded simulator."""
        return self.port == SIM_PORT

    @property
    def calibration(self) -> Calibration:
        """Zero ticks, directions and hard limits: what a model trained on this rig depends on."""
        return Calibration(
            tuple(
                (name, JointCalibration(*(getattr(joint, key) for key in _CALIBRATION_KEYS)))
                for name, joint in self.joints
            )
        )

    @property
    def ids(self) -> tuple[int, ...]:
        """Servo ids ``(pan, tilt)``, or ``(pan, tilt, roll)`` on a three-servo rig."""
        return tuple(joint.id for _, joint in self.joints)

    def to_dict(self) -> dict[str, Any]:
        """Plain data in the shape of the YAML file it was read from (see :attr:`listed`)."""
        head = {key: getattr(self, key) for key in _BUS_KEYS}
        rest = {"rest_direction": [float(v) for v in self.rest_direction]}
        if self.listed:
            joints = [{"name": name} | _joint_dict(joint) for name, joint in self.joints]
            return head | {"joints": joints} | rest
        named = {name: _joint_dict(joint) for name, joint in self.joints}
        roll = {"roll": named.pop("roll")} if "roll" in named else {}
        return head | named | rest | roll


def _joint_dict(joint: JointProfile) -> dict[str, Any]:
    return {key: getattr(joint, key) for key in _JOINT_KEYS + _JOINT_OPTIONAL_KEYS}


class _Checker(Checker):
    """The generic checks plus the joints, which build this module's dataclasses."""

    def joint_calibration(self, value: Any, field: str) -> JointCalibration:
        raw = self.mapping(value, field, _CALIBRATION_KEYS)
        return JointCalibration(
            self.integer(raw["zero_tick"], f"{field}.zero_tick", 0, MAX_TICK),
            self.direction(raw["direction"], f"{field}.direction"),
            self.number(raw["min_deg"], f"{field}.min_deg"),
            self.number(raw["max_deg"], f"{field}.max_deg"),
        )

    def joint(self, value: Any, field: str) -> JointProfile:
        raw = self.mapping(value, field, _JOINT_KEYS, _JOINT_OPTIONAL_KEYS)
        servo_id = self.integer(raw["id"], f"{field}.id", 0, MAX_SERVO_ID)
        zero_tick = self.integer(raw["zero_tick"], f"{field}.zero_tick", 0, MAX_TICK)
        direction = self.direction(raw["direction"], f"{field}.direction")
        min_deg = self.number(raw["min_deg"], f"{field}.min_deg")
        max_deg = self.number(raw["max_deg"], f"{field}.max_deg")
        if not -180.0 < min_deg < max_deg < 180.0:
            raise self.fail(
                f"{field}.min_deg/max_deg",
                f"must satisfy -180 < min_deg < max_deg < 180, got {min_deg} and {max_deg}",
            )
        stop_min, stop_max = (
            self.number(raw.get(key, sign * DEFAULT_END_STOP_DEG), f"{field}.{key}")
            for key, sign in zip(_JOINT_OPTIONAL_KEYS, (-1, 1), strict=True)
        )
        if not -180.0 <= stop_min < stop_max <= 180.0:
            raise self.fail(
                f"{field}.stop_min_deg/stop_max_deg",
                f"must satisfy -180 <= stop_min_deg < stop_max_deg <= 180, got {stop_min} and "
                f"{stop_max}",
            )
        for key, limit, stop, beyond in (
            ("min_deg", min_deg, stop_min, min_deg < stop_min + END_STOP_MARGIN_DEG),
            ("max_deg", max_deg, stop_max, max_deg > stop_max - END_STOP_MARGIN_DEG),
        ):
            if not beyond:
                continue
            stop_key = "stop_" + key
            advice = (
                f"narrow {field}.{key}, or correct {field}.{stop_key} if the joint really "
                f"travels further"
                if stop_key in raw
                else f"narrow {field}.{key}, or write down where the end stop really is "
                f"({field}.{stop_key}; unstated, it is taken to be {stop:+g})"
            )
            raise self.fail(
                f"{field}.{key}",
                f"{limit:g} is not {END_STOP_MARGIN_DEG:g} deg inside the end stop at {stop:g}: "
                f"{advice}",
            )
        return JointProfile(servo_id, zero_tick, direction, min_deg, max_deg, stop_min, stop_max)


def profile_from_dict(data: Any, source: str = "<profile>") -> RigProfile:
    """Validate plain data (as parsed from YAML) into a :class:`RigProfile` (ProfileError naming
    ``source`` and the offending field)."""
    check = _Checker(source)
    listed = isinstance(data, dict) and "joints" in data
    required = (*_BUS_KEYS, *(("joints",) if listed else CHAINS[0]))
    if not isinstance(data, dict):
        raise check.fail("top level", f"must be a mapping with keys {', '.join(required)}")
    raw = dict(data)
    raw.setdefault("rest_direction", [1.0, 0.0, 0.0])
    optional = () if listed else CHAINS[1][2:]
    check.mapping(raw, "profile", (*required, "rest_direction"), optional)
    name = check.text(raw["name"], "name", MAX_NAME_CHARS)
    port = check.text(raw["port"], "port")
    baud = check.integer(raw["baud"], "baud", 1, 10_500_000)
    model = check.text(raw["model"], "model")
    protocol = raw["protocol"]
    if isinstance(protocol, bool) or protocol not in PROTOCOLS:
        raise check.fail("protocol", f"must be 2.0 (X series, Protocol 2.0), got {shown(protocol)}")
    if listed:
        entries = raw["joints"]
        names = tuple(
            e.get("name") if isinstance(e, dict) else None
            for e in (entries if isinstance(entries, list) else ())
        )
        if names not in CHAINS:
            chains = " or ".join(", ".join(c) for c in CHAINS)
            raise check.fail("joints", f"must be a list of joints named {chains}, in that order")
        fields = {
            label: {k: v for k, v in e.items() if k != "name"}
            for label, e in zip(names, entries, strict=True)
        }
    else:
        names = tuple(n for n in CHAINS[1] if n in raw)
        fields = {name: raw[name] for name in names}
    joints: list[tuple[str, JointProfile]] = []
    for label in names:
        joint = check.joint(fields[label], label)
        before = [(n, j.id) for n, j in joints]
        if joint.id in (i for _, i in before):
            others = " and ".join(f"{n}.id" for n, _ in before)
            ids = ", ".join(str(i) for _, i in before)
            raise check.fail(f"{label}.id", f"must differ from {others} ({ids}), got {joint.id}")
        joints.append((label, joint))
    rest = check.direction3(raw["rest_direction"], "rest_direction")
    return RigProfile(
        name, port, int(baud), model, float(protocol), tuple(joints), rest, source, listed
    )


def calibration_from_dict(data: Any, source: str = "<calibration>") -> Calibration:
    """Validate plain data (as :meth:`Calibration.to_dict` wrote it) into a :class:`Calibration`
    (ProfileError naming ``source`` and the offending field)."""
    check = _Checker(source)
    raw = check.mapping(data, "calibration", ("pan", "tilt"), ("roll",))
    names = next(chain for chain in reversed(CHAINS) if set(chain) <= set(raw))
    return Calibration(
        tuple((name, check.joint_calibration(raw[name], f"calibration.{name}")) for name in names)
    )


def load_profile(path: str | os.PathLike[str]) -> RigProfile:
    """Read and validate the rig profile at ``path``: ProfileError if the file is missing or a
    field is invalid (the message names file and field), ProfileFileError if it is not readable
    YAML."""
    path = Path(path)
    try:
        data = read_yaml(path)
    except FileNotFoundError:
        raise ProfileError(
            f"{path}: no such rig profile; give the right path or create one with "
            f"`limbctl calibrate`"
        ) from None
    except YamlRefused as exc:
        raise ProfileFileError(path, str(exc)) from None
    except OSError as exc:
        raise ProfileFileError(path, f"cannot read the rig profile ({exc.strerror})") from None
    return profile_from_dict(data, str(path))


def save_profile(profile: RigProfile, path: str | os.PathLike[str]) -> Path:
    """Validate ``profile`` and write it to ``path`` atomically (temp file, fsync, rename)."""
    path = Path(path)
    profile_from_dict(profile.to_dict(), str(path))
    text = "# limbctl rig profile\n" + yaml.safe_dump(
        profile.to_dict(), sort_keys=False, default_flow_style=None
    )
    directory = path.parent if str(path.parent) else Path(".")
    fd, tmp_name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=directory)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as handle:
            handle.write(text)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp_name, path)
    except BaseException:
        Path(tmp_name).unlink(missing_ok=True)
        raise
    dir_fd = os.open(directory, os.O_RDONLY)
    try:
        os.fsync(dir_fd)
    finally:
        os.close(dir_fd)
    return path


def default_sim_profile(name: str = "sim") -> RigProfile:
    """The packaged profile ``calib/rigs/NAME.yaml`` of a simulated rig (one of SIM_RIGS)."""
    if name not in SIM_RIGS:
        raise ProfileError(f"no packaged rig {name!r}; the packaged rigs are {', '.join(SIM_RIGS)}")
    resource = resources.files("calib").joinpath("rigs").joinpath(f"{name}.yaml")
    with resources.as_file(resource) as path:
        return load_profile(path)
