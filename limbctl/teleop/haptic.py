"""The leader feels the edge: a haptic wall on a leader of two or three joints, from the region.

Each cycle the leader's pose is the command; ``d`` (deg) is how far it lies beyond the region
(:func:`limbctl.teleop.haptic_push.beyond_deg`). Beyond DEADBAND the law (:class:`FeelLaw`) asks
for tau = min(K (d - DEADBAND), CAP), shared over the joints along the joint-space step toward
the corrected pose, with Goal Position LEAD (plus WALK_LEAD while the wall walks a released leader
back) ahead of the leader and Profile Velocity RETURN_SPEED; :func:`lets_go` says when the wall
is left off instead. The servo's position loop (mode 5) pushes toward Goal Position with at most
Goal Current, and CAP is also each servo's Current Limit. docs/haptic.md gives the law in full,
every figure and its passivity bound (b > K T / 2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from limbctl.errors import ConfigError
from limbctl.servo.leader import LeaderMotor
from limbctl.servo.ticks import TICKS_PER_REV

#: One position tick (deg).
TICK_DEG = 360.0 / TICKS_PER_REV
#: Velocity unit of Profile Velocity and Present Velocity: 0.229 rev/min = 1.374 deg/s.
VELOCITY_UNIT_DEG_S = 0.229 * 360.0 / 60.0


@dataclass(frozen=True)
class FeelLaw:
    """The haptic wall's constants; docs/haptic.md's table gives each one's full reasoning.

    Attributes
    ----------
    deadband_deg : float
        0.4 deg: beyond the leader's tick (0.088 deg) and a hand's tremor, so a hand resting at
        the edge is not buzzed; a released leader rests within it.
    gain_nm_per_deg : float
        K = 0.2 N m/deg: K T / 2 = 0.029 N m s/rad at 200 Hz, under the simulated leader's
        damping b = 0.05 (passive with margin 1.75); a 0.3 N m hand stops 1.9 deg past the edge.
    cap_nm : float
        0.4 N m: stops a relaxed hand (0.3 N m) with room, a tenth of an XM430-W350's stall
        torque, and a person overpowers it at once.
    return_speed_deg_s : float
        14 deg/s (10 Profile Velocity units, 13.7 deg/s): a released leader walks back under
        30 deg/s, and the setpoint never reaches the goal within a cycle of the walk back (a
        setpoint that stops brakes the leader outward; at 12 units it did).
    lead_fraction : float
        0.9: Goal Position leads the leader by the whole ticks nearest 0.9 of the loop's error
        at the cap (``CAP / loop stiffness``, :attr:`LeaderMotor.loop_nm_per_deg`; two ticks on
        the XM430-W350): the least lead that holds a hand, so a let go snaps the leader the
        least. Deeper (beyond ``held_within_deg`` or K (d - DEADBAND) > CAP) the least whole
        ticks of at least CAP / KP plus half a tick (three on the XM430), so the cap is given
        wherever the leader sits in its tick.
    lead_deg : float or None
        A fixed lead (deg) instead of the one from the loop's stiffness, half as much again
        deeper (benchmarks sweep it); None (the default): from ``lead_fraction``.
    held_within_deg : float
        2 deg: the figure the wall must keep (issue 21: a hand stops within 2 deg of the edge);
        beyond it the goal leads as a deeper leader's does and pushes it back within.
    outrun_slack_deg : float
        0.1 deg: one reading tick (0.088 deg) rounded up. A leader that moved in since the last
        read by more than RETURN_SPEED times the period plus this outran its setpoint, whose
        loop would pull it back outward: the wall lets go.
    outward_noise_nm : float
        0.01 N m: two XM430-W350 current units (one is the reading's own rounding); a read
        torque pulling away from the region by more lets the wall go. On real servos set it
        above the measured current noise.
    rearm_band_deg : float
        0.05 deg: after a free cycle the wall comes on only beyond DEADBAND + this, so a leader
        coasting in slower than a tick a cycle is not braked; with half a reading tick it stays
        under the 0.5 deg rest the wall must keep.
    walk_lead_ticks : int
        2: extra lead while the wall walks its leader back (read moving in faster than
        ``walk_speed_deg_s``, torque under ``walk_hold_nm``), covering a read tick, 2.5 ms of
        write latency and a cycle 5 ms late at 13.7 deg/s, so the setpoint never stops ahead
        of the next write. 0: never.
    walk_speed_deg_s : float
        1.5 deg/s, the snap watch's STILL (one Present Velocity unit, 1.37 deg/s, is still):
        faster, the leader is walking in.
    walk_hold_nm : float
        0.06 N m, the snap watch's HOLD: a wall holding a hand pushes with more; walking a
        released leader back takes 0.02-0.03 N m.
    """

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
    walk_lead_ticks: int = 2
    walk_speed_deg_s: float = 1.5
    walk_hold_nm: float = 0.06

    def __post_init__(self) -> None:
        names = (
            "deadband_deg",
            "gain_nm_per_deg",
            "cap_nm",
            "lead_fraction",
            "outrun_slack_deg",
            "held_within_deg",
            "outward_noise_nm",
            "rearm_band_deg",
            "walk_lead_ticks",
            "walk_speed_deg_s",
            "walk_hold_nm",
        )
        for name in names:
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
        """Goal Position's lead (deg) for a leader ``distance_deg`` beyond the edge, of
        ``motor``'s model: ``lead_fraction`` of its loop's error at the cap, or, beyond
        ``held_within_deg`` or where the wall's spring asks for more than the cap, the least
        that gives the cap wherever the leader sits within its tick (see ``lead_fraction``)."""
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
    """How far (deg) a leader moved toward its correction since the last read: its joint motion
    projected on the joint-space line toward the corrected pose.

    Parameters
    ----------
    present, previous : tuple of float, (n,)
        The leader's joints now and at the last read (rad).
    step : tuple of float, (n,)
        The corrected pose's joints minus ``present`` (rad); not all zero.
    """
    # moved in = (present - previous) . step / |step|
    dot = 0.0
    for now, before, toward in zip(present, previous, step, strict=True):
        dot += (now - before) * toward
    return math.degrees(dot / math.hypot(*step))


def pulls_outward(law: FeelLaw, torque_nm: tuple[float, ...], step: tuple[float, ...]) -> bool:
    """Whether the leader's motor, read at ``torque_nm`` (joint frame, N m per joint), pulls
    away from the region by more than ``law.outward_noise_nm``: its torque's component along
    ``step`` (toward the corrected pose, joint space; not all zero) below -NOISE."""
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
    """Whether a wall that is on walks its leader back with no hand held against it: the
    leader's read speed along ``step`` (toward the corrected pose, joint space; not all zero)
    over ``law.walk_speed_deg_s``, its motors' torque along it under ``law.walk_hold_nm``
    (joint frame, N m and deg/s; either None: not read, not walking)."""
    if torque_nm is None or velocity_deg_s is None:
        return False
    return (
        along_step(velocity_deg_s, step) > law.walk_speed_deg_s
        and along_step(torque_nm, step) < law.walk_hold_nm
    )


def goal_lead_rad(
    law: FeelLaw,
    motor: LeaderMotor,
    distance_deg: float,
    walking: bool,
) -> float:
    """Goal Position's lead (rad) ahead of the leader: LEAD (:meth:`FeelLaw.lead_for_deg`),
    and ``walk_lead_ticks`` more while the wall walks the leader back (``walking``)."""
    extra = law.walk_lead_ticks * TICK_DEG if walking else 0.0
    return math.radians(law.lead_for_deg(distance_deg, motor) + extra)


def lets_go(
    law: FeelLaw, distance_deg: float, moved_in_deg: float, period_s: float, engaged: bool
) -> bool:
    """Whether a leader ``distance_deg`` beyond the edge, that moved ``moved_in_deg`` toward the
    region in the ``period_s`` since the last read, is left free (docs/haptic.md, the law's
    "but"). ``engaged``: the wall pushed in the cycle before."""
    # faster toward the region than the setpoint (at most RETURN_SPEED): the loop would pull
    # it back outward; at this pace within the deadband by the next read, its current
    # still on inside: let go in both cases
    outrun = moved_in_deg > law.return_speed_deg_s * period_s + law.outrun_slack_deg
    if outrun or distance_deg - moved_in_deg <= law.deadband_deg:
        return True
    # the wall comes on with the setpoint where the leader is (LeaderSource._write): while
    # the leader still moves toward the region the loop's damping would brake it outward; and
    # it comes on only more than REARM beyond the deadband: a leader let go there coasts in
    # slower than a tick a cycle, which the read cannot tell from standing still
    near = distance_deg - law.deadband_deg <= law.rearm_band_deg
    return not engaged and (moved_in_deg > 0.0 or near)


@dataclass
class FeelStats:
    """How long and how hard the operator pressed beyond the edge (for the teleop report).

    Attributes
    ----------
    engaged_s : float
        Time the wall was on (s).
    impulse_nm_s : float
        Integral of the leader's torque over that time (N m s).
    peak_nm : float
        The largest torque commanded (N m).
    events : list of str
        What switched the feel off (a leader restart, an alarm), with the time.
    """

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
