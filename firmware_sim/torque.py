"""What a servo's motor does to its shaft, by Operating Mode: the torque model of a leader gimbal
(joint frame, N m; docs/haptic.md, "The simulated leader"). A tripped Bus Watchdog holds the
profile and, in mode 0, zeroes the current."""

from __future__ import annotations

import math
from dataclasses import dataclass

from firmware_sim.control_table import OperatingMode, Register
from firmware_sim.servo import WATCHDOG_TRIPPED, Servo


@dataclass(frozen=True)
class Motor:
    """A model's motor: stall torque (N m) at stall current (mA), and its current unit (mA)."""

    stall_torque_nm: float
    stall_current_ma: float
    current_unit_ma: float

    @property
    def nm_per_ma(self) -> float:
        """Torque constant at the output (N m per mA): stall torque / stall current."""
        return self.stall_torque_nm / self.stall_current_ma


#: e-Manual stall figures and current units (the XL430-W250 senses no current: unit internal).
MOTORS: dict[str, Motor] = {
    "xm430-w350": Motor(4.1, 2300.0, 2.69),
    "xl430-w250": Motor(1.5, 1400.0, 1.0),
    "xl330-m077": Motor(0.215, 1470.0, 1.0),
    "xl330-m288": Motor(0.52, 1470.0, 1.0),
}

#: The position loop reaches stall torque at this error (deg): stiff, as the default P gain.
LOOP_STALL_ERROR_DEG = 2.0
#: Damping ratio of the position loop with the leader's inertia: well damped, no ringing.
LOOP_DAMPING_RATIO = 0.7


def motor_of(servo: Servo) -> Motor:
    """The motor of ``servo``'s model; ValueError naming the models known."""
    try:
        return MOTORS[servo.model.key.partition("@")[0]]  # "xl330-m288@53": its firmware
    except KeyError:
        raise ValueError(
            f"no motor data for {servo.model.title}; known: {', '.join(sorted(MOTORS))}"
        ) from None


def current_limit_ma(servo: Servo, motor: Motor) -> float:
    """The Current Limit (mA), or the stall current on a model without one."""
    if servo.model.has(Register.CURRENT_LIMIT):
        return servo.value(Register.CURRENT_LIMIT) * motor.current_unit_ma
    return motor.stall_current_ma


@dataclass(frozen=True)
class LoopGains:
    """The position loop's gains for one joint: KP (N m/rad), KD (N m s/rad)."""

    kp: float
    kd: float

    @classmethod
    def for_joint(cls, motor: Motor, inertia: float) -> LoopGains:
        # stall torque at LOOP_STALL_ERROR_DEG; KD = 2 zeta sqrt(KP J)
        kp = motor.stall_torque_nm / math.radians(LOOP_STALL_ERROR_DEG)
        return cls(kp, 2.0 * LOOP_DAMPING_RATIO * math.sqrt(kp * inertia))


@dataclass(frozen=True)
class Drive:
    """What a servo's registers let its motor do this instant: ``cap_nm``, the most its loop may
    apply (N m), or in mode 0 ``current_nm``, the torque its current asks for (N m, joint)."""

    cap_nm: float
    current_nm: float | None = None

    def torque(self, setpoint: float | None, angle: float, velocity: float, gains: LoopGains):
        """The motor's torque (N m, joint frame) toward ``setpoint`` (rad; None: torque off)."""
        if setpoint is None:
            return 0.0
        if self.current_nm is not None:
            return self.current_nm
        if self.cap_nm <= 0.0:
            return 0.0
        # tau = KP (setpoint - angle) - KD velocity, clipped at the current the mode allows
        tau = gains.kp * (setpoint - angle) - gains.kd * velocity
        return min(max(tau, -self.cap_nm), self.cap_nm)


def drive_of(servo: Servo, joint_direction: int) -> Drive:
    """The :class:`Drive` of ``servo`` now, in the joint frame of ``joint_direction`` (+-1)."""
    if not servo.torque_on:
        return Drive(0.0)
    motor = motor_of(servo)
    limit = current_limit_ma(servo, motor)
    mode = OperatingMode(servo.value(Register.OPERATING_MODE))
    goal = 0.0
    if servo.model.has(Register.GOAL_CURRENT):
        goal = servo.value(Register.GOAL_CURRENT) * motor.current_unit_ma
    if mode is OperatingMode.CURRENT:
        tripped = servo.value(Register.BUS_WATCHDOG) & 0xFF == WATCHDOG_TRIPPED
        current = 0.0 if tripped else min(max(goal, -limit), limit)
        return Drive(0.0, joint_direction * current * motor.nm_per_ma)
    cap_ma = min(abs(goal), limit) if mode is OperatingMode.CURRENT_BASED_POSITION else limit
    return Drive(cap_ma * motor.nm_per_ma)


def present_current_units(servo: Servo, torque_nm: float, joint_direction: int) -> int:
    """Present Current (the model's units, shaft frame) that follows from the joint torque."""
    motor = motor_of(servo)
    # I = tau / kt, in the shaft frame and the model's unit
    current = joint_direction * torque_nm / motor.nm_per_ma / motor.current_unit_ma
    return round(max(-32768.0, min(32767.0, current)))
