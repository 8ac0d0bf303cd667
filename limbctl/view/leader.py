"""The leader gimbal on the live page: its pose beside the follower's, and the force it applies.

With ``--source leader:ID,ID`` the page draws the leader's pose as its own marker on the
pan/tilt plane, beside the follower's, and for a leader that feels the edge
(:mod:`limbctl.teleop.haptic`) the torque it pushes back with: an arrow from the leader's marker
toward where the wall pushes it, its length the share of the cap, and a bar with the figure in
newton metres and the cap in the side panel (``assets/leader.js``).

The app hands the view plain values: a :class:`LeaderStatus` per cycle, carried by
:class:`LeaderLive`, a :class:`~limbctl.view.state.Live` with one more part. A page without a
leader is sent a plain :class:`~limbctl.view.state.Live`, whose JSON has no ``leader`` key, so it
looks and behaves as before.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from limbctl.view.state import Live, PanTilt


@dataclass(frozen=True)
class LeaderStatus:
    """The leader gimbal in one teleop cycle, as the page shows it.

    Parameters
    ----------
    pose : PanTilt or None
        The leader's pose as last read (deg); None before its first read.
    torque_nm : float
        The torque it pushes back with this cycle (N m, >= 0; 0 while free or passive).
    cap_nm : float or None
        The most it may push (N m: the law's cap, also its Current Limit); None for a passive
        leader, which cannot push at all.
    toward : PanTilt or None
        Where the push points, as a pose on the plane (deg): the leader's Goal Position, which
        lies from the leader toward the region's correction of its pose. None while free.
    beyond_deg : float or None
        How far the leader's pose lies beyond the region's edge (deg; 0 inside); None when not
        measured (a passive leader).
    state : str
        In words: "free", "pushing back", "passive: ..." or why the feel went off.
    """

    pose: PanTilt | None
    torque_nm: float = 0.0
    cap_nm: float | None = None
    toward: PanTilt | None = None
    beyond_deg: float | None = None
    state: str = ""

    def __post_init__(self) -> None:
        for name in ("torque_nm", "beyond_deg"):
            value = getattr(self, name)
            if value is None and name == "beyond_deg":
                continue
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"leader {name} must be finite and >= 0, got {value!r}")
        if self.cap_nm is not None and not (math.isfinite(self.cap_nm) and self.cap_nm > 0.0):
            raise ValueError(f"leader cap_nm must be finite and > 0 (or None), got {self.cap_nm}")

    def to_json(self) -> dict[str, object]:
        return {
            "pose": self.pose.to_json() if self.pose else None,
            "torque_nm": round(float(self.torque_nm), 3),
            "cap_nm": None if self.cap_nm is None else round(float(self.cap_nm), 3),
            "toward": self.toward.to_json() if self.toward else None,
            "beyond_deg": None if self.beyond_deg is None else round(float(self.beyond_deg), 2),
            "state": self.state,
        }


@dataclass(frozen=True)
class LeaderLive(Live):
    """A :class:`~limbctl.view.state.Live` with the leader gimbal's part (``leader``)."""

    leader: LeaderStatus | None = None

    def to_json(self) -> dict[str, object]:
        out = super().to_json()
        out["leader"] = self.leader.to_json() if self.leader else None
        return out
