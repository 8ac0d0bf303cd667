"""Which servos a leader is: the ids a ``leader:`` source names, checked against the rig."""

from __future__ import annotations

from calib.profile import RigProfile
from limbctl.errors import ConfigError
from limbctl.servo.scan import MAX_ID


def leader_ids(argument: str) -> tuple[int, ...]:
    """The servo ids a leader source's argument names: ``ID,ID`` (pan, tilt), ``ID,ID,ID``
    (ConfigError unless the argument is two or three distinct servo ids, 0..252)."""
    try:
        ids = tuple(int(i) for i in argument.split(","))
    except ValueError:
        raise ConfigError(f"bad leader source 'leader:{argument}'; expected leader:ID,ID") from None
    if len(ids) not in (2, 3):
        raise ConfigError(
            f"bad leader source 'leader:{argument}'; expected leader:ID,ID (pan, tilt) or "
            "leader:ID,ID,ID (pan, tilt, roll)"
        )
    if not all(0 <= i <= MAX_ID for i in ids) or len(set(ids)) != len(ids):
        raise ConfigError(f"bad leader source 'leader:{argument}'; each id once, in 0..{MAX_ID}")
    return ids


def check_leader_fits(ids: tuple[int, ...], profile: RigProfile) -> None:
    """Refuse a leader ``ids`` with another number of joints than ``profile`` or a rig's servo
    (ConfigError naming the rig, its ids and the form to give)."""
    joints = len(profile.ids)
    if len(ids) != joints:
        form = "leader:ID,ID,ID (pan, tilt, roll)" if joints == 3 else "leader:ID,ID (pan, tilt)"
        raise ConfigError(
            f"a {len(ids)}-servo leader {ids} needs a {len(ids)}-servo follower: rig "
            f"{profile.name!r} has {joints} servos; give {form}"
        )
    if shared := sorted(set(ids) & set(profile.ids)):
        servos = "servos" if shared[1:] else "servo"
        raise ConfigError(
            f"leader {ids} names the rig's {servos} {', '.join(map(str, shared))} "
            f"({profile.name!r} is ids {', '.join(map(str, profile.ids))}): a leader is a "
            "second gimbal with ids of its own"
        )
