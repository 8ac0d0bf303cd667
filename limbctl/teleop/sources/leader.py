"""A leader gimbal as a command source: a second pair of servos, torque off, moved by hand.

The leader sits on the same bus as the follower (``leader:3,4`` = pan id 3, tilt id 4; a
three-servo leader ``leader:4,5,6`` adds its roll id and needs a three-servo follower) and is
assumed to be built and calibrated like the follower: its ticks are read with the follower's
zero ticks and directions. Each control cycle reads both leader positions in one sync read and
offers that pose as the newest command; it goes through the gate like any other.
"""

from __future__ import annotations

import math

from limbctl.errors import BusError, ConfigError, InvalidInputError
from limbctl.servo.control_table import Register
from limbctl.servo.rig import Rig
from limbctl.teleop.commands import Command, command_from_pan_tilt, command_from_pose
from limbctl.teleop.sources.base import CommandSource


class LeaderSource(CommandSource):
    """Mirror a hand-moved leader gimbal (read synchronously in :meth:`poll`).

    Parameters
    ----------
    rig : Rig
        The follower rig; its bus must also hold the leader's ids.
    leader_ids : tuple of int
        (pan id, tilt id) of the leader, or (pan, tilt, roll) ids of a three-servo leader.
    """

    name = "leader"
    latest_only = True

    def __init__(self, rig: Rig, leader_ids: tuple[int, ...]) -> None:
        super().__init__()
        if len(leader_ids) == 3 and rig.profile.roll is None:
            raise ConfigError(
                f"a three-servo leader {leader_ids} needs a three-servo follower: rig "
                f"{rig.profile.name!r} has no roll joint to follow its twist; give leader:ID,ID"
            )
        if rig.bus is None or not set(leader_ids) <= set(rig.bus.ids):
            raise ConfigError(f"leader servos {leader_ids} are not on the bus")
        if set(leader_ids) & set(rig.profile.ids):
            raise ConfigError(f"leader ids {leader_ids} overlap the follower's {rig.profile.ids}")
        self.rig = rig
        self.leader_ids = tuple(leader_ids)
        self.read_failures = 0

    def start(self) -> None:
        """Switch the leader's torque off so a hand can move it (no reader thread)."""
        self.rig.bus.set_torque(False, self.leader_ids)

    def close(self) -> None:
        """Nothing to stop; safe to call twice."""

    @property
    def finished(self) -> bool:
        """A leader never ends by itself."""
        return False

    def poll(self, timeout: float = 0.0) -> list[Command]:
        """Read the leader's pose now and offer it as the newest command."""
        try:
            ticks = self.rig.bus.sync_read(Register.PRESENT_POSITION, self.leader_ids)
        except BusError:
            self.read_failures += 1
            return []
        try:
            # the same range checks as every other source's commands
            if len(self.leader_ids) == 3:  # a three-servo leader: read like the follower
                angles = self.rig.angles_of(tuple(ticks[i] for i in self.leader_ids))
                command = command_from_pose(*(math.degrees(a) for a in angles))
            else:
                pan, tilt = self.rig.ticks_to_angles(
                    ticks[self.leader_ids[0]], ticks[self.leader_ids[1]]
                )
                command = command_from_pan_tilt(math.degrees(pan), math.degrees(tilt))
        except InvalidInputError as exc:
            self.stats.reject(f"leader pose refused: {exc}")
            return []
        self.stats.accepted += 1
        return [command]


def leader_ids(argument: str) -> tuple[int, ...]:
    """The (pan, tilt) servo ids of a ``leader:ID,ID`` spec's argument ``ID,ID``, or the
    (pan, tilt, roll) ids of a three-servo leader's ``ID,ID,ID``.

    Raises
    ------
    ConfigError
        Unless the argument is two or three integers.
    """
    try:
        ids = tuple(int(i) for i in argument.split(","))
    except ValueError:
        raise ConfigError(f"bad leader source 'leader:{argument}'; expected leader:ID,ID") from None
    if len(ids) not in (2, 3):
        raise ConfigError(
            f"bad leader source 'leader:{argument}'; expected leader:ID,ID (pan, tilt) or "
            "leader:ID,ID,ID (pan, tilt, roll)"
        )
    return ids
