"""A leader gimbal of two or three joints (the follower's geometry at other servo ids), moved by
an operator's hand and its own motors: rotors with friction, SI units (docs/haptic.md, "The
simulated leader"; each formula above the line that computes it)."""

from __future__ import annotations

import bisect
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import IO, Any

from firmware_sim.servo import Servo
from firmware_sim.torque import Drive, LoopGains, drive_of, motor_of, present_current_units
from firmware_sim.world import DEFAULT_JOINTS, JOINT_NAMES, RAD_PER_TICK, ROLL_JOINT, Joint

#: Rotor inertia at the joint (kg m^2): a light printed link plus a small geared motor's.
LEADER_INERTIA_KG_M2 = 1.0e-3
#: Viscous backdrive friction (N m s/rad): the device damping ``b`` of docs/haptic.md's bound.
LEADER_DAMPING_NM_S_RAD = 0.05
#: Coulomb backdrive friction (N m): a geared servo does not move under a small touch.
LEADER_COULOMB_NM = 0.01
#: Physics step (s): the position loop rings at ~340 rad/s; 0.5 ms keeps omega dt under 0.2.
LEADER_SUBSTEP_S = 0.0005
#: The operator's defaults: a relaxed grip (N m/deg, N m s/rad) pushing with at most TAU_MAX.
HAND_STIFFNESS_NM_DEG = 0.05
HAND_DAMPING_NM_S_RAD = 0.02
HAND_MAX_TORQUE_NM = 0.3
#: The follower's joints, in order: a leader of n servos has the first n.
LEADER_CHAIN = (*DEFAULT_JOINTS, ROLL_JOINT)


@dataclass
class Operator:
    """A hand holding ``joints`` (2 or 3) joints of the leader: a bounded spring-damper toward
    scripted targets.

    Parameters
    ----------
    script : sequence of (t_s, angle_deg, ...), shape (points, 1 + joints)
        Targets (deg), linear in time, holding the last; times from when it takes hold.
    let_go_s : float or None
        From this time (s) on the hand lets go; None: never.
    release_s : float
        How long (s) its bound takes to fall linearly to 0.
    stiffness_nm_deg, damping_nm_s_rad, max_torque_nm : float
        The grip: K_h (N m per deg), D_h (N m s/rad) and the bound tau_max (N m).
    """

    script: Sequence[Sequence[float]]
    let_go_s: float | None = None
    release_s: float = 0.0
    stiffness_nm_deg: float = HAND_STIFFNESS_NM_DEG
    damping_nm_s_rad: float = HAND_DAMPING_NM_S_RAD
    max_torque_nm: float = HAND_MAX_TORQUE_NM
    joints: int = 2
    _times: list[float] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if not 2 <= self.joints <= len(LEADER_CHAIN):
            raise ValueError(f"an operator holds two or three joints, got {self.joints!r}")
        points = [tuple(float(v) for v in p) for p in self.script]
        width = 1 + self.joints
        if not points or any(len(p) != width or not all(map(math.isfinite, p)) for p in points):
            angles = ", ".join(f"{name}_deg" for name in JOINT_NAMES[: self.joints])
            raise ValueError(f"operator script must be [[t_s, {angles}], ...], finite")
        times = [p[0] for p in points]
        if times != sorted(times):
            raise ValueError(f"operator script times must not decrease, got {times}")
        for name in ("release_s", "stiffness_nm_deg", "damping_nm_s_rad", "max_torque_nm"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"operator {name} must be finite and >= 0, got {value!r}")
        self.script = points
        self._times = times

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], joints: int = 2) -> Operator:
        """An operator of ``joints`` joints from plain data; ValueError naming a bad key."""
        known = {"script", "let_go_s", "release_s", "stiffness_nm_deg"}
        known |= {"damping_nm_s_rad", "max_torque_nm"}
        unknown = set(data) - known
        if unknown:
            raise ValueError(f"unknown operator keys {sorted(unknown)}; known: {sorted(known)}")
        return cls(**dict(data), joints=joints)

    def target_deg(self, t: float) -> tuple[float, ...]:
        """The joint angles (deg, shape (joints,)) the operator means at ``t`` s."""
        k = bisect.bisect_right(self._times, t)
        if k == 0:
            return self.script[0][1:]
        if k == len(self.script):
            return self.script[-1][1:]
        before, after = self.script[k - 1], self.script[k]
        u = (t - before[0]) / (after[0] - before[0]) if after[0] > before[0] else 1.0
        # linear in time: a + u (b - a) per joint
        return tuple(a + u * (b - a) for a, b in zip(before[1:], after[1:], strict=True))

    def bound_nm(self, t: float) -> float:
        """The most the hand pushes with at ``t`` s (N m): tau_max r(t)."""
        if self.let_go_s is None or t < self.let_go_s:
            return self.max_torque_nm
        # r(t) = 1 - (t - let_go) / release, down to 0
        left = 1.0 - (t - self.let_go_s) / self.release_s if self.release_s > 0.0 else 0.0
        return self.max_torque_nm * max(left, 0.0)

    def torque(self, t: float, slot: int, angle_rad: float, velocity_rad_s: float) -> float:
        """The hand's torque (N m) on joint ``slot`` at ``t`` s were it the only one it pushes."""
        bound = self.bound_nm(t)
        target = math.radians(self.target_deg(t)[slot])
        # tau = K_h (target - angle) - D_h v, K_h per rad, bounded by tau_max r(t)
        tau = (
            self.stiffness_nm_deg * math.degrees(target - angle_rad)
            - self.damping_nm_s_rad * velocity_rad_s
        )
        return min(max(tau, -bound), bound)

    def torques(
        self, t: float, angles_rad: Sequence[float], velocities_rad_s: Sequence[float]
    ) -> list[float]:
        """The hand's torque (N m, shape (joints,)) at angles (rad) and velocities (rad/s), each of
        shape (joints,), bounded as a vector."""
        bound = self.bound_nm(t)
        if bound <= 0.0:
            return [0.0] * len(angles_rad)
        targets = self.target_deg(t)
        # tau_i = K_h (target_i - angle_i) - D_h v_i
        raw = [
            self.stiffness_nm_deg * (target - math.degrees(angle))
            - self.damping_nm_s_rad * velocity
            for target, angle, velocity in zip(targets, angles_rad, velocities_rad_s, strict=True)
        ]
        # |tau| <= tau_max r(t): scaled along itself
        norm = math.sqrt(sum(v * v for v in raw))
        scale = min(1.0, bound / norm) if norm > 0.0 else 1.0
        return [v * scale for v in raw]


def leader_joints(ids: Sequence[int]) -> tuple[Joint, ...]:
    """The follower's joint geometry at the leader's ids: (pan, tilt) or (pan, tilt, roll)."""
    if not 2 <= len(ids) <= len(LEADER_CHAIN) or len(set(ids)) != len(ids):
        raise ValueError(
            f"a leader needs two or three distinct ids (pan, tilt[, roll]), got {list(ids)}"
        )
    return tuple(
        replace(j, servo_id=int(i)) for i, j in zip(ids, LEADER_CHAIN[: len(ids)], strict=True)
    )


class LeaderWorld:
    """The leader gimbal's physics (see the module docstring): servos ``ids`` (pan, tilt[, roll])
    of ``model``, held by ``operator`` (None: only the motors and friction act), logging its
    ground truth to ``log`` (JSON lines, one per physics step), resting at start at ``start_deg``
    (deg, shape (joints,); None: every joint at 0)."""

    def __init__(
        self,
        ids: Sequence[int],
        model: str,
        operator: Operator | None = None,
        log: str | Path | None = None,
        start_deg: Sequence[float] | None = None,
    ) -> None:
        self.joints = leader_joints(ids)
        self.ids = tuple(j.servo_id for j in self.joints)
        self.model = model
        count = len(self.joints)
        if start_deg is None:
            start_deg = [0.0] * count
        if len(start_deg) != count:
            names = ", ".join(JOINT_NAMES[:count])
            raise ValueError(f"a {count}-servo leader starts at ({names}), got {start_deg}")
        self._check(operator)
        self._lo = [math.radians(j.stop_min_deg) for j in self.joints]
        self._hi = [math.radians(j.stop_max_deg) for j in self.joints]
        self.angle = [math.radians(float(a)) for a in start_deg]
        self.velocity = [0.0] * count
        self.hand_nm = [0.0] * count
        self.motor_nm = [0.0] * count
        # work (J) each motor and the hand did on each joint since the start: sum of tau dtheta
        self.motor_work_j = [0.0] * count
        self.hand_work_j = [0.0] * count
        self.time_s = 0.0
        self.operator_time_s = 0.0
        self.operator = operator
        self._gains: list[LoopGains] | None = None
        self._log: IO[str] | None = None
        if log is not None:
            self._log = open(log, "a", encoding="utf-8")  # noqa: SIM115 (closed by close())

    @classmethod
    def from_spec(cls, spec: Mapping[str, Any]) -> LeaderWorld:
        """A leader from plain data: keys ids, model, operator, log, start_deg."""
        known = {"ids", "model", "operator", "log", "start_deg"}
        unknown = set(spec) - known
        if unknown:
            raise ValueError(f"unknown leader keys {sorted(unknown)}; known: {sorted(known)}")
        ids = spec.get("ids", (3, 4))
        joints = len(leader_joints(ids))
        operator, start = spec.get("operator"), spec.get("start_deg")
        return cls(
            ids,
            spec.get("model", "xm430-w350"),
            None if operator is None else Operator.from_mapping(operator, joints),
            spec.get("log"),
            None if start is None else tuple(start),
        )

    def _check(self, operator: Operator | None) -> None:
        if operator is not None and operator.joints != len(self.joints):
            raise ValueError(
                f"a {operator.joints}-joint operator cannot hold a {len(self.joints)}-servo leader"
            )

    def set_operator(self, operator: Operator | None) -> None:
        """Hand the leader to ``operator`` (its script's clock starts now), or let it go."""
        self._check(operator)
        self.operator = operator
        self.operator_time_s = 0.0

    def raw_tick(self, servo_id: int) -> float:
        """Where the shaft of ``servo_id`` is (raw ticks)."""
        i = self.ids.index(servo_id)
        return self.joints[i].raw_tick(self.angle[i])

    def step(self, dt: float, servos: Mapping[int, Servo], setpoints: Mapping[int, float | None]):
        """Advance ``dt`` s with each servo's motor driving toward its setpoint (raw ticks)."""
        if self._gains is None:
            self._gains = [
                LoopGains.for_joint(motor_of(servos[i]), LEADER_INERTIA_KG_M2) for i in self.ids
            ]
        targets, drives = [], []
        for joint in self.joints:
            tick = setpoints.get(joint.servo_id)
            targets.append(None if tick is None else joint.angle_rad(tick))
            drives.append(drive_of(servos[joint.servo_id], joint.direction))
        count = max(1, math.ceil(dt / LEADER_SUBSTEP_S - 1e-9))
        h = dt / count
        for _ in range(count):
            self._substep(h, drives, targets)
        for i, joint in enumerate(self.joints):
            servo = servos[joint.servo_id]
            servo.current_units = present_current_units(servo, self.motor_nm[i], joint.direction)
            stall = motor_of(servo).stall_torque_nm
            # shaft frame: ticks/s = direction * v / rad per tick; load in % of stall
            servo.observe(
                joint.raw_tick(self.angle[i]),
                joint.direction * self.velocity[i] / RAD_PER_TICK,
                joint.direction * 100.0 * self.motor_nm[i] / stall,
                dt,
            )
        self._write_log()

    def _substep(self, h: float, drives: list[Drive], targets: list[float | None]) -> None:
        self.time_s += h
        self.operator_time_s += h
        hands = [0.0] * len(self.joints)
        if self.operator is not None:
            hands = self.operator.torques(self.operator_time_s, self.angle, self.velocity)
        for i in range(len(self.joints)):
            angle, velocity = self.angle[i], self.velocity[i]
            motor = drives[i].torque(targets[i], angle, velocity, self._gains[i])
            hand = hands[i]
            drive = motor + hand
            if velocity == 0.0 and abs(drive) <= LEADER_COULOMB_NM:
                new_velocity = 0.0  # stiction holds it
            else:
                sliding = math.copysign(LEADER_COULOMB_NM, velocity if velocity else drive)
                # J a = tau_motor + tau_hand - B v - C sign(v), semi-implicit in the damping
                new_velocity = (velocity + h * (drive - sliding) / LEADER_INERTIA_KG_M2) / (
                    1.0 + h * LEADER_DAMPING_NM_S_RAD / LEADER_INERTIA_KG_M2
                )
                if velocity and new_velocity * velocity < 0.0:
                    new_velocity = 0.0  # friction stops it; it does not push it back
            new_angle = angle + new_velocity * h
            if not self._lo[i] <= new_angle <= self._hi[i]:
                new_angle, new_velocity = min(max(new_angle, self._lo[i]), self._hi[i]), 0.0
            # the motor's work on the joint: tau_motor * dtheta
            self.motor_work_j[i] += motor * (new_angle - angle)
            self.hand_work_j[i] += hand * (new_angle - angle)
            self.angle[i], self.velocity[i] = new_angle, new_velocity
            self.hand_nm[i], self.motor_nm[i] = hand, motor

    def _write_log(self) -> None:
        if self._log is not None:
            self._log.write(json.dumps(self.sample()) + "\n")

    def sample(self) -> dict[str, Any]:
        """The ground truth now: time, pose (deg), hand and motor torque (N m), their work (J)."""
        return {
            "t": round(self.time_s, 6),
            "pose_deg": [math.degrees(a) for a in self.angle],
            "velocity_deg_s": [math.degrees(v) for v in self.velocity],
            "hand_nm": list(self.hand_nm),
            "motor_nm": list(self.motor_nm),
            "motor_work_j": list(self.motor_work_j),
            "hand_work_j": list(self.hand_work_j),
        }

    def truth(self) -> dict[str, Any]:
        """:meth:`sample`, the log flushed."""
        if self._log is not None:
            self._log.flush()
        return self.sample()

    def close(self) -> None:
        """Close the log (safe to call twice)."""
        if self._log is not None:
            self._log.close()
            self._log = None
