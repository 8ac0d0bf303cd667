"""The teleop tests' rigs on the simulator through the SDK (:func:`live_chain`) and the start,
approach and park tests' gates: ``sim`` (a 40 deg cone about +x) and ``sim3`` (the same cone,
the twist within 30 deg of 0)."""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator
from pathlib import Path

from limbctl.envelope import Cone
from limbctl.servo.setup import configure_servos
from limbctl.session import Session, open_rig
from limbctl.teleop.gate import Gate, GateLimits
from tests.teleop.test_gate import ConeBand

RATE = 200.0
HALF_ANGLE_DEG = 40.0
RIGS = ("sim", "sim3")


def chain_gate(profile) -> Gate:
    """The gate of the profile's chain on the test region, at the rates teleop would use."""
    step = math.radians(120.0) / RATE
    if len(profile.joints) == 2:
        limits = GateLimits.for_profile(profile, step, max(3.0 * step, math.radians(1.0)))
        return Gate(Cone(math.radians(HALF_ANGLE_DEG)), limits)
    limits = GateLimits.for_profile(profile, step, math.radians(1.8))
    return Gate(ConeBand(math.radians(HALF_ANGLE_DEG), 0.0, math.radians(30)), limits)


def off_axis_deg(pan: float, tilt: float) -> float:
    """The angle (deg) of a two-servo pose (rad) from the cone's axis, +x."""
    return math.degrees(math.acos(math.cos(pan) * math.cos(tilt)))


def pose_of(rig_name: str, *degrees: float) -> tuple[float, ...]:
    """A pose (rad) for the rig from its first joints' angles (deg); the rest at 0."""
    joints = 3 if rig_name == "sim3" else 2
    return tuple(math.radians(a) for a in (*degrees, 0.0, 0.0)[:joints])


@contextlib.contextmanager
def live_chain(rig_name: str, goal_log: Path | None = None) -> Iterator[Session]:
    """The simulated rig through the real SDK: hard limits configured, torque on, at rest."""
    with open_rig(rig_path=rig_name, goal_log=goal_log) as session:
        configure_servos(session.rig.bus, session.rig.tick_limits())
        session.rig.set_torque(True)
        yield session
