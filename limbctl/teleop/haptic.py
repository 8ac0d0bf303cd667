"""The haptic wall's law, tau = min(K (d - DEADBAND), CAP), and when it lets go (docs/haptic.md)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

from limbctl.errors import ConfigError
from limbctl.servo.leader import LeaderMotor
from limbctl.servo.ticks import TICKS_PER_REV

#: One position tick (deg).
TICK_DEG = 360.0 / TICKS_PER_REV
#: Velocity unit of Profile Velocity and Present Velocity: 0.229 rev/min = 1.374 deg/s.
VELOCITY_UNIT_DEG_S = 0.229 * 360.0 / 60.0


@dataclass(frozen=True)
class FeelLaw:
    """The haptic wall's constants (units in their names; ``lead_deg`` None: the lead from
    ``lead_fraction``); docs/haptic.md's table gives each value and its reasoning."""

    deadband_deg: float = 0.4
    gain_nm_per_deg: float = 0.2
    cap_nm: float = 0.4
    return_speed_deg_s: float = 14.0
    lead_fraction: float = 0.9
    lead_deg: float | None = None
    held_within_deg: float = 2.0
    outrun_slack_deg: float = 0.1
    outward_noise_nm: float = 0.01
    rearm_band_deg: float = 0.05
    pushed_out_deg_s: float = 1.5
    walk_lead_ticks: int = 2
    walk_speed_deg_s: float = 1.5
    walk_hold_nm: float = 0.06

    def __post_init__(self) -> None:
        checked_apart = ("return_speed_deg_s", "lead_deg")
        for name in (f.name for f in fields(self) if f.name not in checked_apart):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ConfigError(f"feel law {name} must be finite and >= 0, got {value!r}")
        if self.lead_deg is not None and not (math.isfinite(self.lead_deg) and self.lead_deg > 0):
            raise ConfigError(f"feel law lead_deg must be finite and > 0, got {self.lead_deg!r}")
        if not 0.0 < self.return_speed_deg_s <= 30.0:
            raise ConfigError(
                f"return_speed_deg_s must be in (0, 30] deg/s, got {self.return_speed_deg_s}"
            )

    def torque_nm(self, distance_deg: float) -> float:
        """The torque the law asks for at ``distance_deg`` beyond the edge (N m, >= 0)."""
        if not distance_deg > self.deadband_deg:
            return 0.0
        # tau = min(K (d - DEADBAND), CAP)
        return min(self.gain_nm_per_deg * (distance_deg - self.deadband_deg), self.cap_nm)

    def lead_for_deg(self, distance_deg: float, motor: LeaderMotor) -> float:
        """Goal Position's lead (deg) for a leader ``distance_deg`` beyond the edge."""
        cap_nm = motor.cap_nm(self.cap_nm)
        # beyond HELD_WITHIN, or K (d - DEADBAND) > CAP: deeper than a hand within the cap holds it
        deeper = self.gain_nm_per_deg * (distance_deg - self.deadband_deg) > cap_nm
        deeper = deeper or distance_deg > self.held_within_deg
        if self.lead_deg is not None:
            return self.lead_deg * (1.5 if deeper else 1.0)
        cap_ticks = cap_nm / motor.loop_nm_per_deg / TICK_DEG  # the loop's error at the cap (ticks)
        if deeper:
            # the least whole ticks that give the cap wherever the leader sits in its tick
            return math.ceil(cap_ticks + 0.5) * TICK_DEG
        # the whole ticks nearest LEAD_FRACTION of the error at the cap, at least one
        return max(1, round(self.lead_fraction * cap_ticks)) * TICK_DEG

    def passivity_margin(self, damping_nm_s_rad: float, rate_hz: float) -> float:
        """b / (K T / 2 + B) with B = 0: above 1 the sampled wall is passive."""
        stiffness_nm_rad = self.gain_nm_per_deg * 180.0 / math.pi
        # K T / 2 with T = 1 / rate
        return damping_nm_s_rad / (stiffness_nm_rad / rate_hz / 2.0)

    def profile_velocity_units(self) -> int:
        """Profile Velocity (0.229 rev/min units) no faster than ``return_speed_deg_s``."""
        return max(1, int(self.return_speed_deg_s / VELOCITY_UNIT_DEG_S))


def moved_in_deg(
    present: tuple[float, ...], previous: tuple[float, ...], step: tuple[float, ...]
) -> float:
    """How far (deg) a leader moved toward its correction since the last read: joints (n,)
    ``present`` and ``previous`` (rad), ``step`` (n,) the correction minus ``present`` (rad)."""
    # moved in = (present - previous) . step / |step|
    dot = 0.0
    for now, before, toward in zip(present, previous, step, strict=True):
        dot += (now - before) * toward
    return math.degrees(dot / math.hypot(*step))


def pulls_outward(law: FeelLaw, torque_nm: tuple[float, ...], step: tuple[float, ...]) -> bool:
    """Whether the read ``torque_nm`` (N m per joint) along ``step`` is below -NOISE."""
    return along_step(torque_nm, step) < -law.outward_noise_nm


def along_step(values: tuple[float, ...], step: tuple[float, ...]) -> float:
    """The component of per-joint ``values`` along ``step`` (joint space; not all zero)."""
    # v . step / |step|
    dot = sum(v * s for v, s in zip(values, step, strict=True))
    return dot / math.sqrt(sum(s * s for s in step))


def walks_back(
    law: FeelLaw,
    step: tuple[float, ...],
    torque_nm: tuple[float, ...] | None,
    velocity_deg_s: tuple[float, ...] | None,
) -> bool:
    """Whether the wall walks its leader back, no hand against it: speed (deg/s) along ``step``
    over ``walk_speed_deg_s``, torque (N m) under ``walk_hold_nm`` (None: not read)."""
    if torque_nm is None or velocity_deg_s is None:
        return False
    return (
        along_step(velocity_deg_s, step) > law.walk_speed_deg_s
        and along_step(torque_nm, step) < law.walk_hold_nm
    )


def goal_lead_rad(law: FeelLaw, motor: LeaderMotor, distance_deg: float, walking: bool) -> float:
    """Goal Position's lead (rad), ``walk_lead_ticks`` more while ``walking``."""
    extra = law.walk_lead_ticks * TICK_DEG if walking else 0.0
    return math.radians(law.lead_for_deg(distance_deg, motor) + extra)


def pushed_out(
    law: FeelLaw, step: tuple[float, ...], velocity_deg_s: tuple[float, ...] | None
) -> bool:
    """Whether a leader read at ``velocity_deg_s`` (deg/s per joint) moves away from the region
    along ``step`` faster than ``pushed_out_deg_s``: a hand pushes it (None: not read)."""
    if velocity_deg_s is None:
        return False
    return along_step(velocity_deg_s, step) < -law.pushed_out_deg_s


def lets_go(
    law: FeelLaw, distance_deg: float, moved_in_deg: float, period_s: float, engaged: bool
) -> bool:
    """Whether a leader ``distance_deg`` beyond, moved ``moved_in_deg`` in, is left free."""
    # outran the setpoint (its loop would pull it outward), or inside the deadband next read
    outrun = moved_in_deg > law.return_speed_deg_s * period_s + law.outrun_slack_deg
    if outrun or distance_deg - moved_in_deg <= law.deadband_deg:
        return True
    # re-armed only still and beyond REARM: the loop's damping would brake a leader moving in
    near = distance_deg - law.deadband_deg <= law.rearm_band_deg
    return not engaged and (moved_in_deg > 0.0 or near)


@dataclass
class FeelStats:
    """How long (``engaged_s``, s) and how hard (``impulse_nm_s``, N m s; ``peak_nm``, N m) the
    operator pressed beyond the edge; ``events``: what switched the feel off, with the time."""

    engaged_s: float = 0.0
    impulse_nm_s: float = 0.0
    peak_nm: float = 0.0
    events: list[str] = field(default_factory=list)

    def add(self, torque_nm: float, period_s: float) -> None:
        """Count one cycle of ``period_s`` with the wall at ``torque_nm`` (0: not engaged)."""
        if torque_nm > 0.0:
            self.engaged_s += period_s
            self.impulse_nm_s += torque_nm * period_s
            self.peak_nm = max(self.peak_nm, torque_nm)

    def describe(self) -> str:
        """One line for the teleop report."""
        if self.engaged_s == 0.0:
            return "leader: never pressed beyond the edge"
        mean = self.impulse_nm_s / self.engaged_s
        return (
            f"leader: pressed beyond the edge for {self.engaged_s:.2f} s, "
            f"pushed back with {mean:.2f} N m on average, {self.peak_nm:.2f} N m at most"
        )
