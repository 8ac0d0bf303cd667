"""Rig profiles as the controller uses them: loaded through calib, checked against the servos.

:mod:`calib` validates a profile as data and knows nothing of the controller. What only the
servo layer knows is checked here before a profile is used: the baud rate is one the servos
offer, the model is one the controller drives, and each joint's hard limits map to ticks inside
one turn of the encoder. Errors from :mod:`calib` come out as the controller's own
(:class:`~limbctl.errors.ConfigError`, :class:`~limbctl.errors.FileFormatError`).
"""

from __future__ import annotations

import os
from pathlib import Path

from calib.profile import (
    JointProfile,
    ProfileError,
    ProfileFileError,
    RigProfile,
    default_sim_profile,
    load_profile,
    save_profile,
)
from limbctl.errors import ConfigError, FileFormatError
from limbctl.servo.control_table import BAUD_RATE_VALUES, MAX_TICK, MODEL_BY_NAME
from limbctl.servo.ticks import tick_limits


def joint_tick_limits(joint: JointProfile) -> tuple[int, int]:
    """Integer tick range ``(lo, hi)`` strictly inside ``joint``'s hard limits."""
    return tick_limits(joint.min_deg, joint.max_deg, joint.zero_tick, joint.direction)


def check_profile(profile: RigProfile) -> RigProfile:
    """Check what the servo layer knows of a profile; returns it unchanged.

    Raises
    ------
    ConfigError
        Naming the profile's file and the field.
    """
    source = profile.source or "<profile>"
    if profile.baud not in BAUD_RATE_VALUES:
        choices = ", ".join(str(b) for b in BAUD_RATE_VALUES)
        raise ConfigError(f"{source}: baud must be one of {choices}, got {profile.baud!r}")
    if profile.model not in MODEL_BY_NAME:
        raise ConfigError(
            f"{source}: model must be one of {', '.join(MODEL_BY_NAME)}, got {profile.model!r}"
        )
    for field, joint in (("pan", profile.pan), ("tilt", profile.tilt)):
        lo, hi = joint_tick_limits(joint)
        if lo < 0 or hi > MAX_TICK:
            raise ConfigError(
                f"{source}: {field}.min_deg/max_deg reach ticks {lo}..{hi} from zero_tick "
                f"{joint.zero_tick}, outside one servo turn 0..{MAX_TICK}; narrow the limits "
                f"or re-mount the horn and recalibrate"
            )
    return profile


def _controller_error(exc: ProfileError) -> ConfigError | FileFormatError:
    if isinstance(exc, ProfileFileError):
        return FileFormatError(exc.path, str(exc)[len(f"{exc.path}: ") :])
    return ConfigError(str(exc))


def load_rig_profile(path: str | os.PathLike[str] | None = None) -> RigProfile:
    """The checked rig profile at ``path``, or the packaged simulated rig when ``path`` is None.

    Raises
    ------
    ConfigError
        The file is missing or a field is invalid (the message names file and field).
    FileFormatError
        The file cannot be read or is not YAML.
    """
    try:
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
