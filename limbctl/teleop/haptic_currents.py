"""A felt leader's Goal Current per joint: the push's magnitude shared along its step.

The wall pushes the leader along the joint-space step toward the corrected pose (its normal,
:mod:`limbctl.teleop.haptic`). Each servo's position loop gives its joint at most its own Goal
Current, so the torque the hand feels is the vector of the joints' torques; sharing the push's
magnitude among the joints by the step's direction caps that vector's norm, not each joint's.
"""

from __future__ import annotations

import math

from limbctl.servo.leader import LeaderMotor


def shared_currents(
    motor: LeaderMotor, torque_nm: float, step: tuple[float, ...]
) -> tuple[tuple[int, ...], float]:
    """Goal Current per joint for a push of magnitude ``torque_nm`` (N m) along ``step`` (joint
    space, toward the corrected pose; not all zero), and the magnitude those currents allow::

        I_j = tau |s_j| / |s| / kt        (rounded down; |I| = tau / kt: the hand feels tau)

    Each servo's loop pushes its joint toward its goal with at most its I_j, so the torque the
    hand feels, the norm of the joints' torques, is at most ``torque_nm`` in any direction (the
    same current on every joint let a diagonal push reach sqrt(2) CAP: 0.56 N m of a 0.40 cap,
    docs/decisions/haptic.md). A joint the step does not move gets none: the wall pushes along
    its normal and a hand slides along it freely.

    Returns
    -------
    currents : tuple of int, (n,)
        Goal Current units per joint.
    magnitude_nm : float
        sqrt(sum_j torque_of(I_j)^2) (N m).
    """
    # |s| = sqrt(sum_j s_j^2)
    norm = math.sqrt(sum(s * s for s in step))
    currents = tuple(motor.units_for(torque_nm * abs(s) / norm) for s in step)
    magnitude = math.sqrt(sum(motor.torque_of(c) ** 2 for c in currents))
    return currents, magnitude
