"""What the stepped-clock felt-leader tests read of the simulated leader, as the source does."""

from __future__ import annotations

from collections.abc import Sequence

from firmware_sim.control_table import Register as SimRegister
from limbctl.servo.leader import LeaderMotor


def read_torque(servos: Sequence, joints: Sequence, motor: LeaderMotor) -> tuple[float, ...]:
    """The leader's motor torques (joint frame, N m) as their Present Current reads, as
    ``LeaderSource`` reads them through the current map (the joint's direction turns the
    shaft's current into its frame)."""
    return tuple(
        joint.direction * motor.torque_of(servo.value(SimRegister.PRESENT_CURRENT))
        for servo, joint in zip(servos, joints, strict=True)
    )
