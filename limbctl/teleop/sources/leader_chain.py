"""What a leader's number of joints decides: its command, its free push, its law, its notice.

Two joints (pan, tilt) give a direction, pushed back by :func:`limbctl.teleop.haptic.push_for`
beyond a region of directions; three (pan, tilt, roll) give a full orientation, pushed back by
:func:`limbctl.teleop.haptic3.push3_for` beyond a twist region, the correction's roll unwrapped
within the roll joint's limits. Everything else of a leader source is the same for both
(:class:`~limbctl.teleop.sources.leader.LeaderSource`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from limbctl.teleop.commands import Command, command_from_pan_tilt, command_from_pose
from limbctl.teleop.haptic import FeelLaw, Push, push_for
from limbctl.teleop.haptic3 import held3, push3_for


@dataclass(frozen=True)
class LeaderChain:
    """One chain's leader rules.

    Attributes
    ----------
    command : callable (pose) -> Command
        The command of a pose (rad, one angle per joint): a direction for two joints, an
        orientation for three. Raises InvalidInputError outside the range every source's
        commands are checked against.
    free : callable (pose) -> Push
        The push of a cycle that may not push: no current, the goal at the pose (rad).
    law : callable
        ``law(feel, motor, joints, pose, q, corrected, previous, period, engaged, torque, speed)``
        -> Push: this cycle's push from the leader's pose (rad), its command ``q`` (4,) and the
        region's correction of it (4,), the pose read a cycle before (None at first) and the time
        since (s), whether the wall pushed then, the motors' torque and speed as read (joint
        frame, N m and deg/s); ``joints`` are the rig's joint profiles.
    feels : str
        What the start notice says the leader feels, ``{model}``, ``{deadband}``, ``{cap_nm}``
        and ``{cap}`` filled in.
    """

    command: Callable[[Sequence[float]], Command]
    free: Callable[[Sequence[float]], Push]
    law: Callable[..., Push]
    feels: str

    def notice(self, model: str, deadband_deg: float, cap_nm: float, cap: int) -> str:
        """What the operator is told at start when the leader feels the edge (``cap``: its
        Current Limit, units; ``cap_nm``: the torque it allows, N m)."""
        return self.feels.format(model=model, deadband=deadband_deg, cap_nm=cap_nm, cap=cap)


def _push2(law: FeelLaw, motor, joints, pose, q: np.ndarray, corrected: np.ndarray, *rest) -> Push:
    return push_for(law, motor, pose, q, corrected, *rest)


def _push3(law: FeelLaw, motor, joints, pose, q: np.ndarray, corrected: np.ndarray, *rest) -> Push:
    return push3_for(law, motor, pose, q, corrected, (joints[2].min_rad, joints[2].max_rad), *rest)


#: Each chain's rules by its number of joints.
CHAINS = {
    2: LeaderChain(
        lambda pose: command_from_pan_tilt(math.degrees(pose[0]), math.degrees(pose[1])),
        lambda pose: Push(0, 0, pose[0], pose[1], 0.0, 0.0),
        _push2,
        "leader {model} feels the edge: free inside, pushed back beyond {deadband:g} deg, "
        "at most {cap_nm:.2f} N m (Current Limit {cap})",
    ),
    3: LeaderChain(
        lambda pose: command_from_pose(*(math.degrees(a) for a in pose)),
        held3,
        _push3,
        "leader {model} (three servos) feels the edge in swing and twist: free inside, pushed "
        "back beyond {deadband:g} deg of rotation, at most {cap_nm:.2f} N m (Current Limit {cap})",
    ),
}
