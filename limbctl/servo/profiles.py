"""Rig profiles loaded through calib and checked for what only the servo layer knows."""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from calib.profile import (
    SIM_RIGS,
    JointProfile,
    ProfileError,
    ProfileFileError,
    RigProfile,
    calibration_from_dict,
    default_sim_profile,
    load_profile,
    profile_from_dict,
    save_profile,
)
from calib.yaml_guard import shown
from limbctl.errors import ConfigError, FileFormatError
from limbctl.servo.control_table import (
    BAUD_RATE_VALUES,
    MAX_TICK,
    MODEL_BY_NAME,
    SDK_BAUDS,
    model_name,
)
from limbctl.servo.families import family_of
from limbctl.servo.ticks import tick_limits


def joint_tick_limits(joint: JointProfile) -> tuple[int, int]:
    """Integer tick range ``(lo, hi)`` strictly inside ``joint``'s hard limits."""
    return tick_limits(joint.min_deg, joint.max_deg, joint.zero_tick, joint.direction)


def check_profile(profile: RigProfile) -> RigProfile:
    """Check what the servo layer knows of a profile; returns it unchanged (ConfigError naming
    the profile's file and the field)."""
    source = profile.source or "<profile>"
    try:
        profile_from_dict(profile.to_dict(), source)
    except ProfileError as exc:
        raise _controller_error(exc) from None
    if profile.baud not in BAUD_RATE_VALUES:
        choices = ", ".join(str(b) for b in BAUD_RATE_VALUES)
        raise ConfigError(f"{source}: baud must be one of {choices}, got {profile.baud!r}")
    if profile.model not in MODEL_BY_NAME:
        raise ConfigError(
            f"{source}: model must be one of {', '.join(MODEL_BY_NAME)}, got {profile.model!r}"
        )
    if profile.baud not in SDK_BAUDS:
        usable = ", ".join(str(b) for b in BAUD_RATE_VALUES if b in SDK_BAUDS)
        raise ConfigError(
            f"{source}: baud {profile.baud} is one the servos know, but the serial driver "
            f"(dynamixel-sdk) cannot open it; choose one of {usable}"
        )
    family = family_of(profile.model)
    if profile.baud not in family.bauds:
        raise ConfigError(
            f"{source}: the {family.name} servos do not run at {profile.baud} baud; choose one "
            f"of {', '.join(str(b) for b in family.bauds)}"
        )
    for field, joint in profile.joints:
        lo, hi = joint_tick_limits(joint)
        if lo < 0 or hi > MAX_TICK:
            raise ConfigError(
                f"{source}: {field}.min_deg/max_deg reach ticks {lo}..{hi} from zero_tick "
                f"{joint.zero_tick}, outside one servo turn 0..{MAX_TICK}; narrow the limits "
                f"or re-mount the horn and recalibrate"
            )
    return profile


def check_models(bus: Any, ids: Sequence[int], model: str) -> None:
    """Refuse a rig servo (``ids``) on an open bus that is not the profile's ``model``
    (ConfigError naming the servo, its model and the profile's)."""
    expected = MODEL_BY_NAME[model]
    for servo_id in ids:
        found = bus.models[servo_id]
        if found != expected:
            raise ConfigError(
                f"servo {servo_id} is {model_name(found)} but the rig profile says "
                f"{model_name(expected)}: fix `model:` in the profile or connect the right servo"
            )


def _controller_error(exc: ProfileError) -> ConfigError | FileFormatError:
    if isinstance(exc, ProfileFileError):
        return FileFormatError(exc.path, str(exc)[len(f"{exc.path}: ") :])
    return ConfigError(str(exc))


def load_rig_profile(path: str | os.PathLike[str] | None = None) -> RigProfile:
    """The checked rig profile at ``path``, or a packaged one (None: ``sim``; a non-file name in
    :data:`calib.SIM_RIGS`: that one). ConfigError if the file is missing or a field is invalid
    (the message names file and field), FileFormatError if it cannot be read or is not YAML."""
    packaged = path is not None and str(path) in SIM_RIGS and not Path(path).exists()
    try:
        if packaged:
            profile = default_sim_profile(str(path))
        else:
            profile = load_profile(path) if path is not None else default_sim_profile()
    except ProfileError as exc:
        raise _controller_error(exc) from None
    return check_profile(profile)


def save_rig_profile(profile: RigProfile, path: str | os.PathLike[str]) -> Path:
    """Check ``profile`` and write it atomically to ``path``; returns the path."""
    check_profile(profile)
    try:
        return save_profile(profile, path)
    except ProfileError as exc:
        raise _controller_error(exc) from None


def check_trained_for(metadata: Mapping[str, Any], profile: RigProfile, what: str) -> None:
    """Refuse something trained on another rig, or under another calibration of this one
    (``metadata``: its recorded ``rig`` and ``calibration``; ``what``: its name in messages):
    ConfigError for another rig's name; no, a malformed or a differing calibration (naming each
    field)."""
    source = profile.source or "the rig profile"
    if not isinstance(metadata, Mapping):  # a hand-made header: it records nothing
        metadata = {}
    trained_rig = metadata.get("rig")
    if trained_rig is not None and trained_rig != profile.name:
        raise ConfigError(
            f"{what} was trained for rig {shown(trained_rig)}, not {profile.name!r}; "
            "train a model on a recording from this rig"
        )
    recorded = metadata.get("calibration")
    if recorded is None:
        raise ConfigError(
            f"{what} does not record the calibration it was trained under (it predates that "
            f"record), so nothing shows it fits {source}; record and train again with this "
            f"limbctl (`limbctl record`, then `limbctl train`)"
        )
    try:
        trained = calibration_from_dict(recorded, what)
    except ProfileError as exc:
        raise ConfigError(f"{exc}; train the model again") from None
    differences = trained.differences(profile.calibration)
    if differences:
        raise ConfigError(
            f"{what} was trained under another calibration than {source} "
            f"(trained vs now: {'; '.join(differences)}); the same ticks would be other poses. "
            f"Use the profile it was trained with, or record and train again"
        )
