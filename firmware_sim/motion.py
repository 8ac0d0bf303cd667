"""The servo's trajectory generator: where its position controller points the shaft each instant,
in raw ticks and seconds, after the e-Manual's velocity-based and time-based profiles."""

from __future__ import annotations

import math
from dataclasses import dataclass

#: Encoder resolution of the X series (e-Manual: 0..4095 per turn).
TICKS_PER_TURN = 4096
# 1 velocity unit = 0.229 rev/min
VELOCITY_UNIT_TICKS_S = 0.229 * TICKS_PER_TURN / 60.0
# 1 acceleration unit = 214.577 rev/min^2
ACCELERATION_UNIT_TICKS_S2 = 214.577 * TICKS_PER_TURN / 3600.0


@dataclass
class ProfileLimits:
    """Peak speed (ticks/s, > 0) and acceleration (ticks/s^2, inf: a velocity step) of a move."""

    max_velocity: float
    max_acceleration: float


def velocity_based_limits(
    profile_velocity: int, profile_acceleration: int, velocity_limit: int
) -> ProfileLimits:
    """Limits of a velocity-based profile from the register values (0: no cap but the limit)."""
    cap = velocity_limit if velocity_limit > 0 else 1023
    speed_units = profile_velocity if 0 < profile_velocity <= cap else cap
    # v_max [ticks/s] = units * 0.229 rpm * 4096 / 60
    max_velocity = max(speed_units, 1) * VELOCITY_UNIT_TICKS_S
    # a_max [ticks/s^2] = units * 214.577 rev/min^2 * 4096 / 3600
    max_acceleration = (
        profile_acceleration * ACCELERATION_UNIT_TICKS_S2 if profile_acceleration > 0 else math.inf
    )
    return ProfileLimits(max_velocity, max_acceleration)


def time_based_limits(
    distance_ticks: float, duration_ms: int, ramp_ms: int, velocity_limit: int
) -> ProfileLimits:
    """Limits of a time-based profile covering ``distance_ticks`` in ``duration_ms`` with ramps of
    ``ramp_ms`` (duration 0: only the Velocity Limit)."""
    if duration_ms <= 0:
        return velocity_based_limits(0, 0, velocity_limit)
    total_s = duration_ms / 1000.0
    ramp_s = min(ramp_ms, duration_ms / 2.0) / 1000.0
    # trapezoid area: D = v_peak * (T - t_ramp)
    peak = max(abs(distance_ticks), 1e-9) / (total_s - ramp_s)
    # a = v_peak / t_ramp
    acceleration = peak / ramp_s if ramp_s > 0 else math.inf
    return ProfileLimits(peak, acceleration)


class Trajectory:
    """Position/velocity setpoint that chases a target under :class:`ProfileLimits`."""

    def __init__(self, position: float) -> None:
        self.position = float(position)
        self.velocity = 0.0
        self.target = float(position)
        self.limits = ProfileLimits(VELOCITY_UNIT_TICKS_S * 1023, math.inf)
        self.target_velocity: float | None = None  # set in velocity-like modes

    @property
    def active(self) -> bool:
        """Whether the profile is still running (setpoint not settled on the target)."""
        if self.target_velocity is not None:
            return self.velocity != self.target_velocity
        return self.position != self.target or self.velocity != 0.0

    def hold(self, position: float) -> None:
        """Stop at ``position`` immediately (torque on, reboot, mode change)."""
        self.position = self.target = float(position)
        self.velocity = 0.0
        self.target_velocity = None

    def move_to(self, target: float, limits: ProfileLimits) -> None:
        """Start a move to ``target`` (raw ticks) from the current setpoint."""
        self.target = float(target)
        self.limits = limits
        self.target_velocity = None

    def run_at(self, velocity: float, limits: ProfileLimits) -> None:
        """Ramp towards a constant ``velocity`` (ticks/s) (velocity/PWM/current modes)."""
        self.target_velocity = float(velocity)
        self.limits = limits

    def step(self, dt: float) -> float:
        """Advance by ``dt`` seconds and return the new position setpoint (raw ticks)."""
        a_max = self.limits.max_acceleration
        if self.target_velocity is not None:
            desired = self.target_velocity
        else:
            error = self.target - self.position
            if error == 0.0 and self.velocity == 0.0:
                return self.position
            # fastest speed from which we can still stop in |error|: v = sqrt(2 a |e|)
            reachable = math.sqrt(2.0 * a_max * abs(error)) if math.isfinite(a_max) else math.inf
            desired = math.copysign(min(self.limits.max_velocity, reachable), error)
        # |dv| <= a_max * dt
        change = desired - self.velocity
        max_change = a_max * dt
        if abs(change) > max_change:
            change = math.copysign(max_change, change)
        self.velocity += change
        advance = self.velocity * dt
        if self.target_velocity is None:
            error = self.target - self.position
            if abs(advance) >= abs(error) and (advance == 0.0 or (advance > 0) == (error > 0)):
                self.position = self.target
                self.velocity = 0.0
                return self.position
        self.position += advance
        return self.position
