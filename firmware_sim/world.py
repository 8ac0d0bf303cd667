"""The simulated gimbal's physical world: true geometry, end stops, tracking, load, the hand.
Torque on, a joint tracks its servo's setpoint like a stiff, critically damped position loop,
and a push deflects it from that *free* angle; torque off, it follows the hand's grip, or drifts
under a push, reading no load. Loads and pushes are % of stall in the shaft frame; velocities
raw ticks per second."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from firmware_sim.hand import Hand
from firmware_sim.motion import TICKS_PER_TURN
from firmware_sim.orientation import chain_quat

RAD_PER_TICK = 2.0 * math.pi / TICKS_PER_TURN
#: Position loop: natural frequency (rad/s) of the critically damped tracking response.
TRACKING_OMEGA_RAD_S = 80.0
#: XL430-W250 no-load speed, 57 rpm at 12 V, and an acceleration limit of a light limb.
MAX_SPEED_RAD_S = 57.0 * 2.0 * math.pi / 60.0
MAX_ACCEL_RAD_S2 = 150.0
#: Loop stiffness: load (% of stall) per degree the joint is held away from its tracked angle.
STIFFNESS_PCT_PER_DEG = 50.0
#: The driver's current limit: the load reading saturates here (% of stall).
LOAD_LIMIT_PCT = 200.0
#: Load (% of stall) per rad/s^2 of acceleration and per rad/s of speed of a free move.
INERTIA_PCT_PER_RAD_S2 = 0.3
VISCOUS_PCT_PER_RAD_S = 1.5
#: The hand's grip: time constant (s) and top speed (rad/s) the limb follows the hand with.
GRIP_TIME_CONSTANT_S = 0.015
GRIP_MAX_SPEED_RAD_S = math.radians(300.0)
#: Torque off and no hand: speed (rad/s) per percent of push of the backdriven joint.
BACKDRIVE_RAD_S_PER_PCT = math.radians(1.0)
#: The limb rests within this many degrees of its zero pose at start (drawn from the seed).
REST_SCATTER_DEG = 0.5
#: Longest physics step (s): 1 ms keeps the 80 rad/s tracking loop stable (omega * dt = 0.08).
MAX_SUBSTEP_S = 0.001

_STIFFNESS_PCT_PER_RAD = STIFFNESS_PCT_PER_DEG * 180.0 / math.pi


#: The joints a world may have, in the order a hand's pose lists them.
JOINT_NAMES = ("pan", "tilt", "roll")


@dataclass(frozen=True)
class Joint:
    """One joint's true geometry (``angle_rad = direction * (raw - zero_tick) * 2 pi / 4096``)
    and its end stops (deg)."""

    servo_id: int
    name: str
    zero_tick: float
    direction: int
    stop_min_deg: float
    stop_max_deg: float

    def __post_init__(self) -> None:
        if self.name not in JOINT_NAMES:
            raise ValueError(
                f"joint name must be one of {', '.join(JOINT_NAMES)}, got {self.name!r}"
            )
        if self.direction not in (1, -1):
            raise ValueError(f"joint {self.name}: direction must be +1 or -1, got {self.direction}")
        numbers = (self.zero_tick, self.stop_min_deg, self.stop_max_deg)
        if not all(math.isfinite(v) for v in numbers):
            raise ValueError(f"joint {self.name}: zero_tick and end stops must be finite")
        if not self.stop_min_deg < self.stop_max_deg:
            raise ValueError(
                f"joint {self.name}: stop_min_deg {self.stop_min_deg} must be below "
                f"stop_max_deg {self.stop_max_deg}"
            )

    def angle_rad(self, raw_tick: float) -> float:
        """Joint angle (rad) at a raw shaft position (ticks)."""
        return self.direction * (raw_tick - self.zero_tick) * RAD_PER_TICK

    def raw_tick(self, angle_rad: float) -> float:
        """Raw shaft position (ticks) at a joint angle (rad): the inverse of :meth:`angle_rad`."""
        return self.zero_tick + self.direction * angle_rad / RAD_PER_TICK


DEFAULT_JOINTS = (
    Joint(1, "pan", 2185.0, +1, -120.0, 120.0),
    Joint(2, "tilt", 1890.0, -1, -60.0, 75.0),
)  # must match calib/rigs/sim.yaml
#: The roll joint of the three-servo gimbal (must match calib/rigs/sim3.yaml).
ROLL_JOINT = Joint(3, "roll", 1960.0, +1, -105.0, 105.0)


class World:
    """The gimbal's physics, stepped by the servos: ``joints`` are one "pan", one "tilt" and at
    most one "roll", ``hand`` moves those whose torque is off, ``seed`` draws the rest pose."""

    def __init__(self, joints=DEFAULT_JOINTS, hand: Hand | None = None, seed: int = 0) -> None:
        joints = tuple(joints)
        if sorted(j.name for j in joints) not in (["pan", "tilt"], ["pan", "roll", "tilt"]):
            raise ValueError(
                "World needs exactly one 'pan' and one 'tilt' joint, and at most one 'roll'"
            )
        if len({j.servo_id for j in joints}) != len(joints):
            raise ValueError(
                f"the joints need distinct servo IDs, got {[j.servo_id for j in joints]}"
            )
        self.joints = joints
        count = len(joints)
        self._index = {j.servo_id: i for i, j in enumerate(joints)}
        self._pose_slot = [JOINT_NAMES.index(j.name) for j in joints]
        self._lo = [math.radians(j.stop_min_deg) for j in joints]
        self._hi = [math.radians(j.stop_max_deg) for j in joints]
        rng = np.random.default_rng(seed)
        scatter = rng.uniform(-REST_SCATTER_DEG, REST_SCATTER_DEG, size=len(joints))
        self._angle = [
            min(max(math.radians(float(s)), lo), hi)
            for s, lo, hi in zip(scatter, self._lo, self._hi, strict=True)
        ]
        self._free = list(self._angle)  # the position loop's tracked angle (rad)
        self._free_velocity = [0.0] * count  # rad/s
        self._velocity = [0.0] * count  # actual joint velocity, rad/s
        self._load = [0.0] * count  # joint frame, % of stall
        self._push = [0.0] * count  # joint frame, % of stall
        self._torque_on = [False] * count
        self.time_s = 0.0
        self.set_hand(hand)

    def step(self, dt: float, drive: dict[int, float | None]) -> None:
        """Advance ``dt`` s in substeps of at most 1 ms; ``drive[servo_id]`` is the commanded raw
        tick, ``None`` (or absent) with torque off."""
        if not dt >= 0.0 or not math.isfinite(dt):
            raise ValueError(f"World.step: dt must be a finite number >= 0 s, got {dt!r}")
        setpoints = [drive.get(j.servo_id) for j in self.joints]
        for k, tick in enumerate(setpoints):
            if tick is not None:
                if not math.isfinite(tick):
                    raise ValueError(
                        f"World.step: setpoint of servo {self.joints[k].servo_id} "
                        f"is {tick!r}; it must be a finite raw tick"
                    )
                setpoints[k] = self.joints[k].angle_rad(tick)
        n = math.ceil(dt / MAX_SUBSTEP_S - 1e-9) if dt > 0.0 else 0
        for _ in range(n):
            self._substep(dt / n, setpoints)

    def _substep(self, h: float, setpoints: list[float | None]) -> None:
        pose = None
        if self.hand is not None and None in setpoints:
            self.hand_time_s += h
            pose = self.hand.pose_deg(self.hand_time_s)
        self.time_s += h
        for i in range(len(setpoints)):
            target = setpoints[i]
            angle = self._angle[i]
            lo, hi = self._lo[i], self._hi[i]
            if target is None:
                self._torque_on[i] = False
                # a hand that gives no roll leaves the roll joint to pushes, like no hand
                if pose is not None and self._pose_slot[i] < len(pose):
                    # grip: implicit first-order lag toward the hand, alpha = h / (tau + h)
                    step = (math.radians(pose[self._pose_slot[i]]) - angle) * (
                        h / (GRIP_TIME_CONSTANT_S + h)
                    )
                    limit = GRIP_MAX_SPEED_RAD_S * h
                    step = min(max(step, -limit), limit)
                else:
                    step = self._push[i] * BACKDRIVE_RAD_S_PER_PCT * h
                new_angle = min(max(angle + step, lo), hi)
                self._free[i] = new_angle
                self._free_velocity[i] = 0.0
                self._load[i] = 0.0
            else:
                if not self._torque_on[i]:
                    self._torque_on[i] = True
                    self._free[i] = angle
                    self._free_velocity[i] = 0.0
                free = self._free[i]
                velocity = self._free_velocity[i]
                # critically damped loop: a = w^2 (setpoint - free) - 2 w v, limited
                accel = TRACKING_OMEGA_RAD_S * (
                    TRACKING_OMEGA_RAD_S * (target - free) - 2.0 * velocity
                )
                accel = min(max(accel, -MAX_ACCEL_RAD_S2), MAX_ACCEL_RAD_S2)
                new_velocity = min(max(velocity + accel * h, -MAX_SPEED_RAD_S), MAX_SPEED_RAD_S)
                accel = (new_velocity - velocity) / h
                free += new_velocity * h
                self._free[i] = free
                self._free_velocity[i] = new_velocity
                # a push deflects the held joint through the loop's stiffness; stops clamp it
                new_angle = min(max(free + self._push[i] / _STIFFNESS_PCT_PER_RAD, lo), hi)
                # load = K (free - angle) + I a + B v, saturated at the driver's limit
                load = (
                    _STIFFNESS_PCT_PER_RAD * (free - new_angle)
                    + INERTIA_PCT_PER_RAD_S2 * accel
                    + VISCOUS_PCT_PER_RAD_S * new_velocity
                )
                self._load[i] = min(max(load, -LOAD_LIMIT_PCT), LOAD_LIMIT_PCT)
            self._velocity[i] = (new_angle - angle) / h
            self._angle[i] = new_angle

    def _slot(self, servo_id: int) -> int:
        try:
            return self._index[servo_id]
        except KeyError:
            raise ValueError(
                f"no joint on servo ID {servo_id}; the world has {sorted(self._index)}"
            ) from None

    def raw_tick(self, servo_id: int) -> float:
        """Where the shaft actually is (raw ticks, float)."""
        i = self._slot(servo_id)
        return self.joints[i].raw_tick(self._angle[i])

    def velocity(self, servo_id: int) -> float:
        """Shaft velocity (raw ticks/s)."""
        i = self._slot(servo_id)
        return self.joints[i].direction * self._velocity[i] / RAD_PER_TICK

    def load_percent(self, servo_id: int) -> float:
        """Motor load (% of stall, shaft frame); 0 while torque is off."""
        i = self._slot(servo_id)
        return self.joints[i].direction * self._load[i]

    def push(self, servo_id: int, torque_percent: float) -> None:
        """Apply a steady external torque (% of stall, shaft frame) to a joint; 0 clears it."""
        i = self._slot(servo_id)
        if not math.isfinite(torque_percent):
            raise ValueError(f"push on servo {servo_id} must be finite, got {torque_percent!r}")
        self._push[i] = self.joints[i].direction * float(torque_percent)

    def set_hand(self, hand: Hand | None) -> None:
        """Give the limb to ``hand`` (it takes hold where the limb is), or take it away."""
        self.hand = hand
        #: Seconds the hand has held the limb.
        self.hand_time_s = 0.0
        if hand is not None:
            angles = self.joint_angles_deg()
            hand.start_from(angles["pan"], angles["tilt"], angles.get("roll", 0.0))

    def joint_angles_deg(self) -> dict[str, float]:
        """The true joint angles, ``{"pan": deg, "tilt": deg}`` (and ``"roll"`` if it has one)."""
        return {j.name: math.degrees(a) for j, a in zip(self.joints, self._angle, strict=True)}

    def direction_for_ticks(self, raw: dict[int, float]) -> np.ndarray:
        """Unit limb direction (3,) with the shafts at ``raw`` ticks (true geometry, stops)."""
        pan, tilt = self._angles_for_ticks(raw)[:2]
        # d = (cos t cos p, cos t sin p, sin t)
        return np.array(
            [math.cos(tilt) * math.cos(pan), math.cos(tilt) * math.sin(pan), math.sin(tilt)]
        )

    @property
    def has_roll(self) -> bool:
        """True when the limb has a roll joint (a three-servo gimbal)."""
        return len(self.joints) == 3

    def _angles_for_ticks(self, raw: dict[int, float]) -> list[float]:
        """Joint angles (rad) in JOINT_NAMES order at ``raw``, clamped; a missing servo as is."""
        angles = [0.0, 0.0, 0.0]
        for i, joint in enumerate(self.joints):
            tick = raw.get(joint.servo_id)
            angle = self._angle[i] if tick is None else joint.angle_rad(float(tick))
            angles[self._pose_slot[i]] = min(max(angle, self._lo[i]), self._hi[i])
        return angles

    def orientation_for_ticks(self, raw: dict[int, float]) -> tuple[float, float, float, float]:
        """Full orientation ``(w, x, y, z)``, w >= 0, with the shafts at ``raw`` ticks."""
        return chain_quat(*self._angles_for_ticks(raw))
