"""The leader gimbal on the live page: its pose and the force it applies."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from limbctl.geometry.gimbal import pose_quat_scalar
from limbctl.geometry.twist import decompose_one
from limbctl.view.state import Live, PanTilt

Pose3 = tuple[float, float, float]


@dataclass(frozen=True)
class LeaderStatus:
    """The leader gimbal in one teleop cycle, as the page shows it: its ``pose`` as last read and
    ``toward`` its Goal Position (None before a read / while free); the ``torque_nm`` it pushes back
    with and its ``cap_nm`` (N m, also its Current Limit; None: passive); how far it lies
    ``beyond_deg`` the edge (deg, 0 inside; None: not measured); its ``state`` in words; a
    three-servo leader's ``twist_deg`` and ``toward_twist_deg`` (deg) and the ``sensed_nm`` norm of
    its motors' torque as last read (N m; None: passive)."""

    pose: PanTilt | None
    torque_nm: float = 0.0
    cap_nm: float | None = None
    toward: PanTilt | None = None
    beyond_deg: float | None = None
    state: str = ""
    twist_deg: float | None = None
    toward_twist_deg: float | None = None
    sensed_nm: float | None = None

    def __post_init__(self) -> None:
        for name in ("torque_nm", "beyond_deg", "sensed_nm"):
            value = getattr(self, name)
            if value is None and name != "torque_nm":
                continue
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"leader {name} must be finite and >= 0, got {value!r}")
        if self.cap_nm is not None and not (math.isfinite(self.cap_nm) and self.cap_nm > 0.0):
            raise ValueError(f"leader cap_nm must be finite and > 0 (or None), got {self.cap_nm}")
        for name in ("twist_deg", "toward_twist_deg"):
            value = getattr(self, name)
            if value is not None and not math.isfinite(value):
                raise ValueError(f"leader {name} must be finite (or None), got {value!r}")

    def to_json(self) -> dict[str, object]:
        def rounded(value: float | None, digits: int) -> float | None:
            return None if value is None else round(float(value), digits)

        out = {
            "pose": self.pose.to_json() if self.pose else None,
            "torque_nm": round(float(self.torque_nm), 3),
            "cap_nm": rounded(self.cap_nm, 3),
            "toward": self.toward.to_json() if self.toward else None,
            "beyond_deg": rounded(self.beyond_deg, 2),
            "state": self.state,
        }
        if self.sensed_nm is not None:
            out["sensed_nm"] = rounded(self.sensed_nm, 3)
        if self.twist_deg is not None:
            out["twist_deg"] = rounded(self.twist_deg, 2)
            out["toward_twist_deg"] = rounded(self.toward_twist_deg, 2)
        return out


#: A three-servo push is drawn on the pan/tilt plane only if its swing is this share of its step.
SWING_SHARE_DRAWN = 0.1


def with_twist(status: LeaderStatus, pose: Pose3, goal: Pose3 | None) -> LeaderStatus:
    """``status`` (its pan and tilt part) of a three-servo leader with the twist of its
    ``pose`` (pan, tilt, roll; rad) and of its ``goal`` (rad; None while free or passive)."""
    _, twist = decompose_one(pose_quat_scalar(*pose))
    if goal is None:
        return replace(status, twist_deg=math.degrees(twist))
    _, toward = decompose_one(pose_quat_scalar(*goal))
    # swing step = |(d pan, d tilt)|, against the largest joint step
    swing = math.hypot(goal[0] - pose[0], goal[1] - pose[1])
    largest = max(swing, abs(goal[2] - pose[2]))
    drawn = status.toward if largest > 0.0 and swing >= SWING_SHARE_DRAWN * largest else None
    return replace(
        status, toward=drawn, twist_deg=math.degrees(twist), toward_twist_deg=math.degrees(toward)
    )


@dataclass(frozen=True)
class LeaderLive(Live):
    """A :class:`~limbctl.view.state.Live` with the leader gimbal's part (``leader``)."""

    leader: LeaderStatus | None = None

    def to_json(self) -> dict[str, object]:
        out = super().to_json()
        out["leader"] = self.leader.to_json() if self.leader else None
        return out
