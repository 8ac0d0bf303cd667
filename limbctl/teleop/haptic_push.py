"""A felt leader's push this cycle: the wall law of :mod:`limbctl.teleop.haptic` on its chain."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from limbctl.geometry.chains import geodesic
from limbctl.geometry.gimbal import pan_tilt_roll_scalar, quat_to_pan_tilt
from limbctl.geometry.quat import direction_angle, limb_direction
from limbctl.servo.leader import LeaderMotor
from limbctl.teleop.haptic import (
    FeelLaw,
    goal_lead_rad,
    lets_go,
    moved_in_deg,
    pulls_outward,
    pushed_out,
    walks_back,
)


@dataclass(frozen=True)
class Push:
    """One cycle's command to the leader's servos: Goal Current units (0: no torque; the largest of
    ``joint_currents``, one per joint, empty: this on every joint), Profile Velocity units (0
    while free: not written), the ``goal`` pose (rad, one per joint), the push's magnitude the
    currents allow (N m, the norm of the joints' torques) and how far the command lies beyond the
    region (deg)."""

    goal_current: int
    profile_velocity: int
    goal: tuple[float, ...]
    torque_nm: float
    distance_deg: float
    joint_currents: tuple[int, ...] = ()

    def currents(self, joints: int) -> tuple[int, ...]:
        """Goal Current units for each of ``joints`` joints."""
        return self.joint_currents or (self.goal_current,) * joints


def shared_currents(
    motor: LeaderMotor, torque_nm: float, step: tuple[float, ...]
) -> tuple[tuple[int, ...], float]:
    """Goal Current units per joint, ``I_j = tau |s_j| / |s| / kt`` rounded down, for a push of
    ``torque_nm`` (N m) along ``step`` (n,) (rad; not all zero), and their magnitude sqrt(sum_j
    torque_of(I_j)^2) (N m), never over the push one joint alone gives, torque_of(units_for(tau)).
    """
    norm = math.sqrt(sum(s * s for s in step))
    currents = [motor.units_for(torque_nm * abs(s) / norm) for s in step]
    # each joint rounded down keeps the size under tau, but not under one joint's whole units:
    # a diagonal could feel up to a unit more than a straight push; the largest gives a unit back
    most = motor.torque_of(motor.units_for(torque_nm))
    magnitude = math.sqrt(sum(motor.torque_of(c) ** 2 for c in currents))
    while magnitude > most:
        currents[currents.index(max(currents))] -= 1
        magnitude = math.sqrt(sum(motor.torque_of(c) ** 2 for c in currents))
    return tuple(currents), magnitude


def held(present: Sequence[float], distance_deg: float = 0.0) -> Push:
    """No push: currents 0, the goal at ``present`` (rad), ``distance_deg`` beyond the region."""
    return Push(0, 0, tuple(present), 0.0, distance_deg)


def beyond_deg(q: np.ndarray, corrected: np.ndarray, joints: int) -> float:
    """How far (deg) a command (4,) lies beyond its correction (4,), in direction or rotation."""
    if np.array_equal(q, corrected):
        return 0.0
    if joints == 3:
        # d = 2 acos |<q, c>|, computed as chains.geodesic does (accurate near 0)
        return math.degrees(geodesic(np.asarray(q, dtype=float), np.asarray(corrected, float)))
    # the angle between the limb's directions, atan2(|a x b|, a . b) (any length of either)
    return math.degrees(float(direction_angle(limb_direction(q), limb_direction(corrected))))


def corrected_pose(
    corrected: np.ndarray,
    present: Sequence[float],
    limits: Sequence[tuple[float, float]] | None = None,
) -> tuple[float, ...]:
    """Joint angles (rad) of the correction (4,) on ``present``'s chain, unwrapped as the gate
    does (three joints need ``limits``, one ``(lo, hi)`` (rad) per joint)."""
    if len(present) == 2:
        return tuple(float(v) for v in quat_to_pan_tilt(corrected))
    if limits is None:
        raise ValueError("a three-joint leader's corrected pose needs its joint limits")
    return pan_tilt_roll_scalar(corrected, present[0], present[2], *limits[2])


def _length(step: Sequence[float]) -> float:
    """|s| (rad), with the arithmetic each chain's law was measured with."""
    if len(step) == 2:
        return math.hypot(*step)
    return math.sqrt(sum(s * s for s in step))


def push_for(
    law: FeelLaw,
    motor: LeaderMotor,
    present: Sequence[float],
    q: np.ndarray,
    corrected: np.ndarray,
    previous: Sequence[float] | None = None,
    period_s: float = 0.0,
    engaged: bool = True,
    torque_nm: Sequence[float] | None = None,
    velocity_deg_s: Sequence[float] | None = None,
    limits: Sequence[tuple[float, float]] | None = None,
) -> Push:
    """The leader's command this cycle (:mod:`limbctl.teleop.haptic`'s law on its chain).

    ``present``, ``previous`` (n,): the leader's pose now and a cycle before (rad; ``previous``
    None: no let-go rules); ``q``, ``corrected`` (4,): the command and the region's correction of
    it; ``period_s``: time since ``previous`` was read (s); ``engaged``: the wall pushed the cycle
    before; ``torque_nm``, ``velocity_deg_s`` (n,): the motors' read torque (N m) and speed
    (deg/s), None: not read; ``limits`` (n,): each joint's hard limits (rad), for
    :func:`corrected_pose` on three joints.
    """
    distance = beyond_deg(q, corrected, len(present))
    tau = min(law.torque_nm(distance), motor.cap_nm(law.cap_nm))
    units = motor.units_for(tau)
    free = held(present, distance)
    if units == 0:
        return free
    target = corrected_pose(corrected, present, limits)
    # the goal on the joint-space line toward the corrected pose, at most LEAD ahead
    step = tuple(t - p for t, p in zip(target, present, strict=True))
    longest = max(abs(s) for s in step)
    # a free leader read moving outward is pushed by a hand: the wall comes back whatever it
    # moved in since the last read (a cut taken for a let go while the hand still pushed)
    comes_back = longest > 0.0 and not engaged and pushed_out(law, step, velocity_deg_s)
    if previous is not None and longest > 0.0 and not comes_back:
        moved_in = moved_in_deg(present, previous, step)
        if lets_go(law, distance, moved_in, period_s, engaged):
            return free
    if engaged and torque_nm is not None and longest > 0.0 and pulls_outward(law, torque_nm, step):
        return free
    walking = engaged and longest > 0.0 and walks_back(law, step, torque_nm, velocity_deg_s)
    lead = goal_lead_rad(law, motor, distance, walking)
    # at most LEAD from the leader in joint space (|s|): a diagonal stores no more than one joint
    scale = min(1.0, lead / _length(step)) if longest > 0.0 else 0.0
    goal = tuple(p + scale * s for p, s in zip(present, step, strict=True))
    # the push's magnitude shared along the step: the hand feels at most tau
    currents, magnitude = shared_currents(motor, tau, step) if longest > 0.0 else ((), 0.0)
    if not any(currents):
        return free
    velocity = law.profile_velocity_units()
    return Push(max(currents), velocity, goal, magnitude, distance, currents)
