"""A three-servo leader gimbal: pan, tilt and roll moved by an operator's hand and its motors.

The two-servo leader (:mod:`firmware_sim.leader`) with a third joint built like the follower's
roll joint (:data:`firmware_sim.world.ROLL_JOINT`) at the leader's third id. Each joint is the
same rotor on its own (joint frame, SI units)::

    J a = tau_motor + tau_hand - B v - C sign(v)        (sticks while |tau_motor + tau_hand| <= C)

so the chain's orientation ``q = Rz(pan) Ry(-tilt) Rx(roll)`` is what the controller reads back
from the three shafts (:mod:`firmware_sim.orientation`). The operator (:class:`Operator3`) is the
two-servo leader's bounded spring-damper on each joint, its script giving (pan, tilt, roll)::

    tau_hand = K_h (target - angle) - D_h v, |tau_hand| <= tau_max    (0 after let go)

Ground truth (pose, hand and motor torque, the work of each) is the two-servo leader's, with
three entries per list: :meth:`LeaderWorld.sample`.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from firmware_sim.leader import LeaderWorld, Operator, leader_joints
from firmware_sim.world import ROLL_JOINT, Joint


@dataclass
class Operator3(Operator):
    """A hand holding a three-servo leader: :class:`~firmware_sim.leader.Operator` whose script
    points are ``(t_s, pan_deg, tilt_deg, roll_deg)``."""

    def __post_init__(self) -> None:
        points = [tuple(float(v) for v in p) for p in self.script]
        if not points or any(len(p) != 4 or not all(map(math.isfinite, p)) for p in points):
            raise ValueError(
                "a three-servo operator's script must be [[t_s, pan_deg, tilt_deg, roll_deg], "
                "...], finite"
            )
        # the checks of the times and of the grip are the two-servo operator's
        Operator([(t, p, q) for t, p, q, _ in points], **self._grip())
        self.script = points
        self._times = [p[0] for p in points]

    def _grip(self) -> dict[str, Any]:
        keys = ("let_go_s", "release_s", "stiffness_nm_deg", "damping_nm_s_rad", "max_torque_nm")
        return {key: getattr(self, key) for key in keys}

    def target_deg(self, t: float) -> tuple[float, float, float]:  # type: ignore[override]
        """(pan, tilt, roll) the operator means at ``t`` s: linear between the script's points."""
        k = bisect.bisect_right(self._times, t)
        if k == 0:
            return self.script[0][1:]
        if k == len(self.script):
            return self.script[-1][1:]
        before, after = self.script[k - 1], self.script[k]
        u = (t - before[0]) / (after[0] - before[0]) if after[0] > before[0] else 1.0
        # linear in time: a + u (b - a) per joint
        return tuple(a + u * (b - a) for a, b in zip(before[1:], after[1:], strict=True))


def leader_joints3(ids: Sequence[int]) -> tuple[Joint, Joint, Joint]:
    """The follower's three-joint geometry at the leader's (pan, tilt, roll) ids."""
    if len(ids) != 3 or len(set(ids)) != 3:
        raise ValueError(f"a three-servo leader needs three distinct ids, got {list(ids)}")
    pan, tilt = leader_joints(ids[:2])
    roll = ROLL_JOINT
    return (
        pan,
        tilt,
        Joint(
            int(ids[2]),
            roll.name,
            roll.zero_tick,
            roll.direction,
            roll.stop_min_deg,
            roll.stop_max_deg,
        ),
    )


class LeaderWorld3(LeaderWorld):
    """The three-servo leader's physics (see the module docstring).

    Parameters
    ----------
    ids : (int, int, int)
        The leader's (pan, tilt, roll) servo ids.
    model, log
        As :class:`~firmware_sim.leader.LeaderWorld`.
    operator : Operator3 or None
        Who holds it; None: nobody.
    start_deg : (float, float, float)
        Where the leader rests at start (pan, tilt, roll).
    """

    def __init__(
        self,
        ids: Sequence[int],
        model: str,
        operator: Operator3 | None = None,
        log: str | Path | None = None,
        start_deg: tuple[float, float, float] = (0.0, 0.0, 0.0),
    ) -> None:
        joints = leader_joints3(ids)
        if len(start_deg) != 3:
            raise ValueError(f"a three-servo leader starts at (pan, tilt, roll), got {start_deg}")
        super().__init__(ids[:2], model, operator, log, (start_deg[0], start_deg[1]))
        self.joints = joints
        self.ids = tuple(j.servo_id for j in joints)
        self._lo = [math.radians(j.stop_min_deg) for j in joints]
        self._hi = [math.radians(j.stop_max_deg) for j in joints]
        self.angle = [math.radians(float(a)) for a in start_deg]
        for name in ("velocity", "hand_nm", "motor_nm", "motor_work_j", "hand_work_j"):
            setattr(self, name, [0.0, 0.0, 0.0])

    @classmethod
    def from_spec(cls, spec: Mapping[str, Any]) -> LeaderWorld3:
        """A three-servo leader from plain data: ``{"ids": [4, 5, 6], "model": ...,
        "operator": {...}, "log": path, "start_deg": [pan, tilt, roll]}``."""
        known = {"ids", "model", "operator", "log", "start_deg"}
        unknown = set(spec) - known
        if unknown:
            raise ValueError(f"unknown leader keys {sorted(unknown)}; known: {sorted(known)}")
        operator = spec.get("operator")
        return cls(
            spec["ids"],
            spec.get("model", "xm430-w350"),
            None if operator is None else Operator3.from_mapping(operator),
            spec.get("log"),
            tuple(spec.get("start_deg", (0.0, 0.0, 0.0))),
        )


def leader_world(spec: Mapping[str, Any]) -> LeaderWorld:
    """The leader of a simulator's ``leader=`` spec: three ids give a three-servo leader."""
    if len(spec.get("ids", ())) == 3:
        return LeaderWorld3.from_spec(spec)
    return LeaderWorld.from_spec(spec)


def operator_for(leader: LeaderWorld, data: Mapping[str, Any]) -> Operator:
    """The operator ``data`` describes for ``leader`` (three joints on a three-servo leader)."""
    if isinstance(leader, LeaderWorld3):
        return Operator3.from_mapping(data)
    return Operator.from_mapping(data)
