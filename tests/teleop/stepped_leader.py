"""The stepped-clock felt-leader harness: the controller's part done on the simulated leader's
registers every 5 ms of a clock stepped 1 ms at a time, whatever the machine's load."""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence

import numpy as np

from calib.profile import default_sim_profile
from firmware_sim.control_table import MODELS
from firmware_sim.control_table import Register as SimRegister
from firmware_sim.simulator import Simulator
from limbctl.envelope import Cone
from limbctl.geometry.gimbal import pan_tilt_to_quat, pose_quat_scalar
from limbctl.servo.control_table import ModelNumber
from limbctl.servo.leader import (
    FEEL_DATA,
    FEEL_MAP,
    FELT_MODELS,
    LeaderMotor,
    encode_feel,
    feel_map,
)
from limbctl.servo.rig import Rig
from limbctl.teleop.brake import BrakeLaw
from limbctl.teleop.haptic import VELOCITY_UNIT_DEG_S, FeelLaw
from limbctl.teleop.haptic_push import beyond_deg, corrected_pose, held, push_for
from limbctl.teleop.snap import SnapLaw, SnapWatch
from tests.teleop.twist_square import square_region

#: The controller writes READ_TO_WRITE_MS after its read (the pty's p50, docs/bench_haptic.md).
READ_TO_WRITE_MS = 1
#: The follower's region in these runs: a 30 deg cone around +x (along pan, the edge at pan 30).
CONE = Cone(half_angle_deg=30.0)


def read_torque(servos: Sequence, joints: Sequence, motor: LeaderMotor) -> tuple[float, ...]:
    """The leader's motor torques (joint frame, N m) from Present Current, as ``LeaderSource``."""
    return tuple(
        joint.direction * motor.torque_of(servo.value(SimRegister.PRESENT_CURRENT))
        for servo, joint in zip(servos, joints, strict=True)
    )


def read_velocity(servos: Sequence, joints: Sequence) -> tuple[float, ...]:
    """The leader's joint speeds (deg/s, joint frame) as their Present Velocity reads."""
    return tuple(
        joint.direction * servo.value(SimRegister.PRESENT_VELOCITY) * VELOCITY_UNIT_DEG_S
        for servo, joint in zip(servos, joints, strict=True)
    )


class SteppedWatch:
    """The snap watch between the cycles (``LeaderSource.watch_snap``): a read every 1 ms while
    a wall is on, a cut 1 ms after; ``brake`` None: the snap rule alone (round 7)."""

    def __init__(
        self,
        servos: Sequence,
        joints: Sequence,
        now,
        on: bool = True,
        motor: LeaderMotor | None = None,
        law: FeelLaw = FeelLaw(),
        brake: BrakeLaw | None = BrakeLaw(),
    ) -> None:
        self.servos, self.joints, self.now, self.on = servos, joints, now, on
        self.motor = motor or FELT_MODELS[ModelNumber.XM430_W350]
        walk = law.profile_velocity_units() * VELOCITY_UNIT_DEG_S
        # today's watch (with the brake rules) brings a freed wall back on two still reads
        self.snap = SnapWatch(
            SnapLaw(), brake=brake, walk_deg_s=walk, rearm_twice=brake is not None
        )
        self.cut_due: int | None = None  # the ms at which Goal Current 0 lands

    def before_step(self, ms: int) -> bool:
        """At the start of millisecond ``ms``: write a due cut; True if one was written."""
        if self.cut_due != ms:
            return False
        self.cut_due = None
        for servo in self.servos:
            servo.write(102, bytes(2))  # Goal Current 0 alone, as LeaderSource.release
        return True

    def wrote(self, pose, goal, velocity, torque, was_engaged: bool, read_s: float) -> None:
        """After a cycle's write (``goal`` None: the wall is off): arm or disarm."""
        if goal is None:
            self.snap.disarm()
        else:
            self.snap.arm(pose, goal, velocity, torque, was_engaged, read_s)

    def after_write(self, ms: int) -> None:
        """After a cycle's write, between the cycles: read the speed, schedule a cut."""
        if not self.on or not self.snap.watching or self.cut_due is not None:
            return
        for servo in self.servos:
            servo.refresh(self.now())
        velocity = read_velocity(self.servos, self.joints)
        torque = read_torque(self.servos, self.joints, self.motor)
        if self.snap.snaps(velocity, self.now(), torque):
            self.cut_due = ms + 1


def motor_of(model: str) -> LeaderMotor:
    """The controller's :class:`LeaderMotor` for a simulator model key (``"xl330-m288@53"``)."""
    return FELT_MODELS[ModelNumber(MODELS[model.partition("@")[0]].model_number)]


def q_of(*pose_deg: float) -> np.ndarray:
    """The orientation (4,) of a pose of either chain (deg)."""
    pose = np.radians(pose_deg)
    return np.asarray(pan_tilt_to_quat(*pose)) if len(pose) == 2 else pose_quat_scalar(*pose)


#: Each chain's stepped leader: the rig profile, the follower's ids and options, the leader's ids.
CHAINS = {
    2: ("sim", {"ids": (1, 2)}, (3, 4)),
    3: ("sim3", {"ids": (1, 2, 3), "roll_id": 3}, (4, 5, 6)),
}


def rig_of(joints: int):
    """The simulated rig of a chain of ``joints`` joints."""
    return Rig(default_sim_profile(CHAINS[joints][0]))


@functools.cache
def limits_of(joints: int) -> tuple[tuple[float, float], ...]:
    """The joints' hard limits (rad) of :func:`rig_of`, as the law is given them."""
    return tuple((j.min_rad, j.max_rad) for j in rig_of(joints).joints)


@functools.cache
def region_of(joints: int):
    """The region a chain's leader feels: CONE on two servos, twist_square.py's on three."""
    return CONE if joints == 2 else square_region()


def beyond_of(region, row) -> float:
    """How far (deg of rotation) a truth row of either chain lies beyond ``region``'s edge."""
    q = q_of(*row["pose_deg"])
    return beyond_deg(q, region.correct(q), len(row["pose_deg"]))


def way_of(region, row) -> np.ndarray:
    """The joint-space step (n,, rad) from a row's pose (either chain) toward its correction."""
    present = tuple(np.radians(row["pose_deg"]))
    corrected = region.correct(q_of(*row["pose_deg"]))
    return np.subtract(corrected_pose(corrected, present, limits_of(len(present))), present)


def stepped_leader(follower: dict, ids: Sequence[int], model: str, limit: int, operator: dict):
    """A simulator on a stepped clock with a felt leader on ``ids`` (n,) of simulator ``model``
    (Operating Mode 5, Current Limit ``limit`` units, the feel map, torque on) held by
    ``operator``, the follower's ``follower`` arguments (``CHAINS``): the simulator, the clock (a
    one-element list, s: advance it before ``sim.advance()``) and the leader's (n,) servos."""
    clock = [0.0]
    sim = Simulator(**follower, leader={"ids": list(ids), "model": model}, clock=lambda: clock[0])
    servos = [sim.servo(i) for i in ids]
    for servo in servos:
        servo.write(11, bytes([5]))  # Operating Mode 5 (EEPROM, torque off)
        servo.write(38, limit.to_bytes(2, "little"))  # Current Limit
        servo.write(FEEL_MAP.address, feel_map())
        servo.write(64, bytes([1]))  # torque on
    sim.set_operator(operator)
    return sim, clock, servos


def run_stepped(
    sim,
    clock: list,
    servos: Sequence,
    rig,
    watch: SteppedWatch,
    seconds: float,
    decide: Callable,
    cycles: dict | None = None,
    cut_s: float | None = None,
    engage_at_write: bool = False,
    profile_always: bool = False,
) -> list[dict]:
    """The controller's part every 5 ms for ``seconds`` (s): read, ``decide`` the push, write it
    READ_TO_WRITE_MS later, the ``watch`` between the cycles; the leader's 1 ms truth rows.

    ``decide(k, ticks, velocity, torque, engaged, read_s)`` of cycle ``k`` (ticks (n,), deg/s
    (n,), N m (n,)) returns the pose (n,, rad) and the push; ``cycles`` maps a cycle to "late"
    (nothing written) or "silent" (Goal Current 0 alone); at ``cut_s`` (s) Goal Current 0 is
    written and nothing after; ``engage_at_write``: the wall comes on judged at the write (as
    ``LeaderSource``), else at the read; ``profile_always``: Profile Velocity with every push."""
    rows, engaged, cut, goal = [], False, False, None
    for k in range(round(seconds * 200.0)):
        if watch.before_step(5 * k):
            engaged = False  # the watch let the wall go: LeaderSource.release
        for servo in servos:
            servo.refresh(sim.time_s)
        ticks = tuple(servo.value(SimRegister.PRESENT_POSITION) for servo in servos)
        velocity = read_velocity(servos, rig.joints)
        torque = read_torque(servos, rig.joints, watch.motor)
        read_s = sim.time_s  # when the cycle read the leader
        pose, push = decide(k, ticks, velocity, torque, engaged, read_s)
        instead = (cycles or {}).get(k)
        if instead == "silent":
            engaged = False  # LeaderSource.release: the next push is the wall coming on again
            watch.snap.disarm()
            for servo in servos:
                servo.write(102, bytes(2))  # Goal Current 0 alone
        goal = goal if cut else rig.angles_to_ticks(*push.goal)
        engaging = push.goal_current > 0 and not engaged
        for step in range(5):
            if step and watch.before_step(5 * k + step):
                engaged = False
            if cut_s is not None and not cut and clock[0] >= cut_s - 1e-9:
                cut = True
                for servo, tick in zip(servos, goal, strict=True):
                    servo.write(FEEL_DATA.address, encode_feel(0, tick))
            if step == READ_TO_WRITE_MS and instead not in ("late", "silent") and not cut:
                if engage_at_write:
                    engaging = push.goal_current > 0 and not engaged
                was_engaged, engaged = engaged, push.goal_current > 0
                shares = push.currents(len(servos))
                for servo, tick, current in zip(servos, goal, shares, strict=True):
                    if engaging:  # the wall comes on from the present position
                        servo.write(64, bytes([0]))
                        servo.write(64, bytes([1]))
                    if push.goal_current or profile_always:  # its own write in the source
                        servo.write(112, push.profile_velocity.to_bytes(4, "little"))
                    servo.write(FEEL_DATA.address, encode_feel(current, tick))
                goal_on = push.goal if push.goal_current else None
                watch.wrote(pose, goal_on, velocity, torque, was_engaged, read_s)
            if step >= READ_TO_WRITE_MS:  # the loop's wait, from right after its write
                watch.after_write(5 * k + step)
            clock[0] += 0.001
            sim.advance()
            rows.append(sim.leader.sample())
    return rows


def felt_at_200_hz(
    script,
    seconds,
    stiffness=0.05,
    let_go_s=None,
    cycles=None,
    model="xm430-w350",
    law=FeelLaw(),
    max_torque_nm=0.3,
    motor=None,
    snap_watch=True,
    release_s=0.0,
    brake=BrakeLaw(),
    rules=True,
    pushes=None,
):
    """:func:`run_stepped` with ``push_for`` in the script's chain's :func:`region_of`: the 1 ms
    truth. ``cycles`` also "held"; ``motor`` None: the model's; ``snap_watch`` False: the law alone
    (round 6); ``rules`` False: no let-go rules; ``pushes`` gets each (pose, push, instead)."""
    motor = motor or motor_of(model)
    joints = len(script[0]) - 1
    _, follower, ids = CHAINS[joints]
    rig, limits = rig_of(joints), limits_of(joints)
    region = region_of(joints)
    limit = motor.units_for(motor.cap_nm(law.cap_nm))
    hand = {"script": script, "let_go_s": let_go_s, "stiffness_nm_deg": stiffness}
    hand["release_s"] = release_s
    operator = {**hand, "damping_nm_s_rad": 0.02, "max_torque_nm": max_torque_nm}
    sim, clock, servos = stepped_leader(follower, ids, model, limit, operator)
    on = snap_watch and rules
    watch = SteppedWatch(servos, rig.joints, lambda: sim.time_s, on, motor, law, brake)
    previous = None

    def decide(k, ticks, velocity, torque, engaged, read_s):
        nonlocal previous
        pose = rig.ticks_to_angles(*ticks)
        q = q_of(*np.degrees(pose)) if joints == 2 else pose_quat_scalar(*pose)
        # today's law (the watch with its brake rules) also reads the speed: the walking lead
        speed = velocity if on and brake is not None else None
        past = (previous, 0.005, engaged, torque, speed) if rules else ()
        push = push_for(law, motor, pose, q, region.correct(q), *past, limits=limits)
        if on and push.goal_current:
            if not watch.snap.allows(pose, push.goal, velocity, engaged, read_s, torque):
                push = held(pose, push.distance_deg)
        previous = pose
        instead = (cycles or {}).get(k)
        if instead == "held":
            push = held(pose)
        if pushes is not None:
            pushes.append((pose, push, instead))
        return pose, push

    return run_stepped(
        sim, clock, servos, rig, watch, seconds, decide, cycles, engage_at_write=True
    )
