"""A three-servo leader feels the edge: the haptic wall of :mod:`limbctl.teleop.haptic` on SO(3).

The leader's full orientation is the command. Its distance beyond the region is the rotation
between the command and the twist region's correction of it (the nearest orientation of the
region on SO(3), :meth:`limbctl.region.twist_region.TwistRegion.correct`)::

    d = 2 acos |<q, correct(q)>|                                      (deg; 0 inside)

The law is the two-servo leader's (:class:`~limbctl.teleop.haptic.FeelLaw`: the same deadband,
gain, cap, return speed and lead), on three joints, per cycle::

    d <= DEADBAND:  Goal Current 0 on all three                        (no torque at all)
    d >  DEADBAND:  tau = min(K (d - DEADBAND), CAP)
                    Goal Current_j = tau |s_j| / |s| / kt (rounded down), s = target - present:
                             the push's magnitude, what the hand feels, is at most tau
                    target = the corrected pose (pan, tilt, roll): its roll unwrapped within
                             the roll joint's limits nearest the leader's roll, as the gate does
                    Goal Position = present + s (target - present),
                             s = min(1, LEAD / |target - present|)  (joint space)
                             (LEAD: two ticks; three beyond 2 deg or where K (d - DEADBAND) > CAP)
                    Profile Velocity = RETURN_SPEED
    but Goal Current 0 when, with m the leader's rotation toward the correction since the last
    read (its joint motion projected on the joint-space line toward the corrected pose, period
    T), the two-servo law's rules hold (:func:`~limbctl.teleop.haptic.lets_go`):
        m > RETURN_SPEED T + SLACK       it outran the setpoints, whose loops would pull it
                                         back, away from the region
        d - m <= DEADBAND                at this pace inside the deadband by the next read
        m > 0 after a free cycle         still moving in: the wall comes on once it stops
        d <= DEADBAND + REARM after one  the wall comes on only past a band beyond the deadband
    and when the read's joint torques pull away from the correction (their component along
    ``target - present`` below -NOISE, :func:`~limbctl.teleop.haptic.pulls_outward`).

Each servo's position loop (mode 5) drives its joint toward its Goal Position with at most Goal
Current; every Goal Position lies from the leader's joint toward the corrected pose's, so the
vector of joint torques points toward the correction (its dot product with
``target - present`` is >= 0) and its norm, what the hand feels, is at most CAP. Near the edge
a rotation of ``d`` needs joint moves of about ``d`` (the chain's Jacobian is near orthonormal
away from tilt +-90 deg), so the wall's stiffness per joint, and its passivity at 200 Hz, are the
two-servo leader's (docs/haptic.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from limbctl.geometry.chains import geodesic
from limbctl.geometry.gimbal3 import pan_tilt_roll_scalar
from limbctl.servo.leader import LeaderMotor
from limbctl.teleop.haptic import (
    FeelLaw,
    Push,
    goal_lead_rad,
    lets_go,
    moved_in_deg,
    pulls_outward,
    walks_back,
)
from limbctl.teleop.haptic_currents import shared_currents

Pose3 = tuple[float, float, float]


@dataclass(frozen=True)
class Push3(Push):
    """One cycle's command to a three-servo leader's servos (currents shared along the step):
    :class:`~limbctl.teleop.haptic.Push` with the roll joint's goal.

    Attributes
    ----------
    goal_roll : float
        The roll joint's goal (rad).
    """

    goal_roll: float = 0.0

    @property
    def goal(self) -> Pose3:
        """``(pan, tilt, roll)`` goal (rad)."""
        return (self.goal_pan, self.goal_tilt, self.goal_roll)


def beyond3_deg(q: np.ndarray, corrected: np.ndarray) -> float:
    """Rotation (deg) between a command (4,) and its correction (4,); 0 when the same."""
    if np.array_equal(q, corrected):
        return 0.0
    # d = 2 acos |<q, c>|, computed as chains.geodesic does (accurate near 0)
    return math.degrees(geodesic(np.asarray(q, dtype=float), np.asarray(corrected, dtype=float)))


def held3(present: Pose3) -> Push3:
    """The push of a cycle that may not push (a held gate, a failed read of the follower):
    Goal Current 0, Profile Velocity 0, the goal where the leader is."""
    return Push3(0, 0, present[0], present[1], 0.0, 0.0, goal_roll=present[2])


def corrected_pose(
    corrected: np.ndarray, present: Pose3, roll_limits: tuple[float, float]
) -> Pose3:
    """Joint angles (rad) of the correction (4,): pan kept at tilt +-90 deg, roll unwrapped
    within ``roll_limits`` (rad) nearest the leader's present roll (as the gate does)."""
    return pan_tilt_roll_scalar(corrected, present[0], present[2], *roll_limits)


def push3_for(
    law: FeelLaw,
    motor: LeaderMotor,
    present: Pose3,
    q: np.ndarray,
    corrected: np.ndarray,
    roll_limits: tuple[float, float],
    previous: Pose3 | None = None,
    period_s: float = 0.0,
    engaged: bool = True,
    torque_nm: Pose3 | None = None,
    velocity_deg_s: Pose3 | None = None,
) -> Push3:
    """The three-servo leader's command this cycle (see the module docstring).

    Parameters
    ----------
    law : FeelLaw
    motor : LeaderMotor
        The leader's model (its current unit and torque constant).
    present : (float, float, float)
        The leader's pose (pan, tilt, roll; rad).
    q, corrected : ndarray (4,)
        The command (the leader's orientation) and the twist region's correction of it.
    roll_limits : (float, float)
        The roll joint's hard limits (rad), within which the corrected roll is unwrapped.
    previous : (float, float, float), optional
        The leader's pose a cycle before (pan, tilt, roll; rad); None on the first cycle (and
        the law is then the wall alone, without the let-go rules).
    period_s : float, optional
        Time since ``previous`` was read (s).
    engaged : bool, optional
        Whether the wall pushed in the cycle before (with ``previous``).
    torque_nm : (float, float, float), optional
        The motors' torque as read with ``present`` (Present Current, joint frame, N m); a wall
        whose read pulls away from the region lets go (:func:`~limbctl.teleop.haptic.
        pulls_outward`). None: not read.
    velocity_deg_s : (float, float, float), optional
        The motors' speed as read with ``present`` (Present Velocity, joint frame, deg/s):
        with ``torque_nm``, whether an engaged wall walks the leader back (its goal then leads
        by ``walk_lead_ticks`` more, :func:`~limbctl.teleop.haptic.walks_back`). None: LEAD.
    """
    distance = beyond3_deg(q, corrected)
    tau = min(law.torque_nm(distance), motor.cap_nm(law.cap_nm))
    units = motor.units_for(tau)
    free = Push3(0, 0, present[0], present[1], 0.0, distance, goal_roll=present[2])
    if units == 0:
        return free
    target = corrected_pose(corrected, present, roll_limits)
    # the goal on the joint-space line toward the corrected pose, at most LEAD ahead (joint space)
    step = [t - p for t, p in zip(target, present, strict=True)]
    longest = max(abs(s) for s in step)
    if previous is not None and longest > 0.0:
        # the rotation toward the correction since the last read, on the joint-space line
        moved_in = moved_in_deg(present, previous, tuple(step))
        if lets_go(law, distance, moved_in, period_s, engaged):
            return free
    if engaged and torque_nm is not None and longest > 0.0:
        if pulls_outward(law, tuple(torque_nm), tuple(step)):
            return free
    walking = engaged and longest > 0.0 and walks_back(law, tuple(step), torque_nm, velocity_deg_s)
    lead = goal_lead_rad(law, motor, distance, walking)
    scale = min(1.0, lead / math.sqrt(sum(s * s for s in step))) if longest > 0.0 else 0.0
    goal = [p + scale * s for p, s in zip(present, step, strict=True)]
    # the push's magnitude shared along the step: the hand feels at most tau
    currents, magnitude = shared_currents(motor, tau, tuple(step)) if longest > 0.0 else ((), 0.0)
    if not any(currents):
        return free
    velocity = law.profile_velocity_units()
    return Push3(
        max(currents), velocity, *goal[:2], magnitude, distance, currents, goal_roll=goal[2]
    )
