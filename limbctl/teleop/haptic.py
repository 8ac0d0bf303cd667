"""The leader feels the edge: a haptic wall on a leader of two or three joints, from the region.

Each cycle the leader's pose is the command. Its distance ``d`` (deg) beyond the region is
measured between the command and the region's correction of it (not the slew-limited pose the
follower is sent): the angle between their directions on two joints, the rotation between them on
three (:func:`limbctl.teleop.haptic_push.beyond_deg`, which with
:func:`~limbctl.teleop.haptic_push.push_for` applies this law each cycle).

The law (:class:`FeelLaw`), per cycle of period T, on every joint of the chain::

    d <= DEADBAND (inside: d = 0):  Goal Current 0                   (no torque at all)
    d > DEADBAND:                   tau = min(K (d - DEADBAND), CAP)
                                    Goal Current_j = tau |s_j| / |s| / kt  (rounded down; s:
                                    the joint-space step toward the corrected pose, so the
                                    push the hand feels, the joints' torques' norm, is <= tau)
                                    Goal Position = the corrected pose, reached from the
                                    leader's pose by at most LEAD (from the servo loop's
                                    stiffness KP: about 0.9 CAP / KP, two ticks on an
                                    XM430; beyond 2 deg or where K (d - DEADBAND) > CAP
                                    at least CAP / KP wherever the leader sits in its
                                    tick, three on an XM430), and WALK_LEAD more while
                                    the wall walks its leader back (the leader read moving
                                    in, its motors' torque under HOLD: no hand held)
                                    Profile Velocity = RETURN_SPEED
    but Goal Current 0 when, with m how far the leader moved toward the correction since the
    last read (period T):
        m > RETURN_SPEED T + SLACK       it outran the servo's setpoint, whose loop would
                                         pull it back, away from the region
        d - m <= DEADBAND                at this pace inside the deadband by the next read
        m > 0 after a free cycle         still moving in: the wall comes on once it stops
        d <= DEADBAND + REARM after one  the wall comes on only past a band beyond the deadband
        tau_read . u < -NOISE            the read's motor torque (Present Current, joint frame)
                                         pulls away from the region (u: the unit step toward
                                         the correction): the servo's loop brakes a leader that
                                         outran its setpoint; the wall lets go rather than pull
                                         the hand outward for another cycle

Around the law, the snap watch (:mod:`limbctl.teleop.snap`) lets a wall that holds a still
leader go the moment the leader starts to snap toward the region (a let go), between the cycles
and at each read, frees any wall before its servo's loop would brake the leader outward (the
brake rules, :mod:`limbctl.teleop.brake`), and brings a freed wall back only on a still leader.

The servo's own position loop (mode 5) pushes toward Goal Position with at most Goal Current,
so the torque points toward the region and its magnitude never exceeds CAP (no joint's exceeds
its share of it); CAP is also written into each servo's Current Limit at start so the firmware
refuses more on any joint. The wall is a spring of stiffness K
sampled at T; it is passive when the leader's own damping b exceeds K T / 2 + B (Colgate and
Schenkel's bound for a sampled virtual wall, B = 0 here): with b = 0.05 N m s/rad (the simulated
leader) and T = 5 ms, K < 20 N m/rad = 0.35 N m/deg. docs/haptic.md states every figure.
A released leader is walked back by its own profile (at most RETURN_SPEED) until the law lets
go at the deadband, so it rests within DEADBAND of the edge, never inside the region.
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
    """The haptic wall's constants (see the module docstring for the law).

    Attributes
    ----------
    deadband_deg : float
        0.4 deg: beyond the leader's tick (0.088 deg) and a hand's tremor (a few tenths of a
        degree), so a hand resting at the edge is not buzzed; a released leader rests within it.
    gain_nm_per_deg : float
        K = 0.2 N m/deg (11.5 N m/rad): K T / 2 = 0.029 N m s/rad at 200 Hz, under the
        simulated leader's b = 0.05 with a margin of 1.75 (the loop's read-to-write delay adds
        to T); a hand of 0.3 N m stops 1.5 deg past the deadband, 1.9 deg past the edge.
    cap_nm : float
        0.4 N m: enough to stop a relaxed hand (0.3 N m) with room, a tenth of an XM430-W350's
        stall torque (the servo neither heats nor trips overload at it), and small enough that
        a person overpowers it at once.
    return_speed_deg_s : float
        14 deg/s (Profile Velocity, rounded down to 10 units = 13.7 deg/s): a released leader
        walks back well under 30 deg/s, and the setpoint never reaches the goal within a cycle
        while the wall walks the leader back (a setpoint that stops brakes the leader: an
        outward pull). The goal lies LEAD from the leader; the setpoint runs ahead of the
        leader by the loop's lag (0.066 deg at this speed on the simulated XM430 loop) and
        covers RETURN_SPEED T (0.069 deg) in a cycle: 0.135 deg of the 0.176, 3 ms of travel to
        spare. At 12 units (16.5 deg/s) none was left: the setpoint stopped twice in a walk
        back, 3 outward 1 ms samples each (decisions/haptic.md, round 4).
    lead_fraction : float
        0.9: Goal Position lies ahead of the leader's pose, toward the correction, by the whole
        number of ticks nearest the error at which the servo's loop gives 0.9 of the cap
        (``CAP / loop stiffness``, :attr:`LeaderMotor.loop_nm_per_deg`): two ticks (0.176 deg)
        on the simulated XM430-W350, five on an XL330-M288 (cap 0.12 N m), ten on an
        XL330-M077 (cap 0.11 N m, half its stall torque: a loop error of 1 deg). Holding a
        hand, the servo's setpoint sits there, and a let go snaps the leader onto it: the
        energy the loop stores is what the snap spends, so the lead is the least that still
        holds. On the XM430 the read rounds the leader's pose to a tick, so the setpoint lies
        between 1.5 and 2.5 ticks ahead: 0.27-0.45 N m, enough to stop a 0.3 N m hand coming
        from inside (it pushes the leader out until the loop's error reaches 1.66 ticks); one
        tick (at most 0.27 N m) would let a firmer hand push the leader out tick by tick. A
        lead of a fixed two ticks on an XL330, whose simulated loop is 8-19 times softer, gave
        it 0.03-0.08 N m: a relaxed hand pushed an XL330-M077
        leader 19 deg beyond, and let go it rested 8 deg beyond (decisions/haptic.md, round 6).
        It does not grow with the leader's step (as it did in round 3): the tick-quantized
        step flips between 0 and 1 tick at a slow walk, and a goal that moves back reverses
        the setpoint onto the leader (decisions/haptic.md, round 4). More for a leader deeper
        than a hand within the cap holds it (K (d - DEADBAND) > CAP: after a release, or a hand
        that overpowered the wall): the wall then pushes it back at the cap, which the loop
        must give wherever the leader sits within its tick, so the lead is the least whole
        ticks of at least CAP / KP plus half a tick: three on the XM430 (at least 2.5 ticks
        after the read, 0.45 N m; at 1.5 ticks, 0.27 N m, a hand pressing 0.27 N m held a
        released leader 15 deg beyond the edge for good), six on the XL330-M288, twelve on the
        XL330-M077 (round 5 led them by half as much again as the normal lead: on a soft loop
        that stored more than the cap needs, and an XL330-M288 snapped back at up to 58 deg/s).
    lead_deg : float or None
        A fixed lead (deg) instead of the one from the loop's stiffness, half as much again
        deeper (benchmarks sweep it); None (the default): from ``lead_fraction``.
    held_within_deg : float
        2 deg: beyond it the goal leads as a deeper leader's does. A relaxed hand (0.3 N m) is held
        1.9 deg beyond (two ticks, the least snap at its let go); a leader the loop's jitter
        let further (over the pty a held three-servo leader sat 2.31 deg beyond: two ticks give
        only 0.27 N m where it sits at the inner edge of its tick) is pushed back within it, the
        figure the wall must keep (issue 21: stop within 2 deg of the edge).
    outrun_slack_deg : float
        0.1 deg: a leader that moved toward the region since the last read by more than its
        setpoint can (RETURN_SPEED times the time between the reads) plus this has outrun the
        setpoint, and the servo's loop would pull it back, away from the region: the wall lets
        go. One reading tick (0.088 deg) rounded up, so a leader the wall walks back itself,
        read a tick early, keeps its wall (a slack under the setpoint's own speed let the wall
        go on its own walk back, and a hand pressing outward then won: decisions/haptic.md).
    outward_noise_nm : float
        0.01 N m: a read whose motor torque pulls away from the region by more than this lets
        the wall go. Two of the XM430-W350's current units (0.0048 N m each): one unit is the
        reading's own rounding, so a torque near zero read as -1 unit does not free a wall
        holding a hand; small beside the braking it is there to cut (up to 0.28 N m while a
        hand drags the leader back inside, docs/bench_haptic.md). On real servos the current
        reading's noise is to be measured and this set above it.
    rearm_band_deg : float
        0.05 deg: after a free cycle the wall comes on only beyond DEADBAND + this (read), so a
        leader let go there, coasting in slower than a tick a cycle (read as still), is not
        braked by a wall coming back on. Its top plus half a reading tick (0.044 deg) stays
        under 0.5 deg, the rest the wall must keep: a leader freed there rests within 0.5 deg
        of the edge. One tick (0.1 deg, the outrun slack) let one rest 0.512 deg beyond, read
        0.498 (decisions/haptic.md, round 5).
    walk_lead_ticks : int
        2: a wall walking its leader back (the leader read moving toward the region faster
        than ``walk_speed_deg_s``, its motors' torque toward the region under ``walk_hold_nm``:
        no hand held against the wall) leads its goal by this many ticks more. The goal must
        stay ahead of the setpoint until the next write: over the pty that write comes 1-2.5 ms
        after its read, the read rounds the pose to a tick, and a cycle may come late; with
        LEAD alone the setpoint reached its goal first in 3 of 8 push cases, stopped there, and
        the servo's loop braked the leader outward (up to 0.010 N m) before the brake rules
        freed the wall (decisions/haptic.md, round 9). Two ticks (0.18 deg) cover a read tick,
        2.5 ms of latency and a cycle 5 ms late at the setpoint's 13.7 deg/s. A hand that grabs
        the walking leader meets a setpoint at most one cycle's walk further ahead, and the
        next cycle (torque over ``walk_hold_nm``) leads by LEAD again. 0: never.
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
    region in the ``period_s`` since the last read, is left free (the module docstring's "but").
    ``engaged``: the wall pushed in the cycle before."""
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
