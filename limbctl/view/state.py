"""What the live view shows, as plain values, and the :class:`Board` keeping the latest."""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field

import numpy as np

from limbctl.view.twist import TwistGauge, TwistMap

#: Most samples sent to a browser per scene: enough to show coverage, small enough to draw at once.
MAX_DRAWN_SAMPLES = 4000
#: Cell size (deg) for thinning: samples closer than this add nothing visible at page scale.
THIN_CELL_DEG = 0.5


@dataclass(frozen=True)
class PanTilt:
    """A pose on the pan/tilt plane, degrees."""

    pan_deg: float
    tilt_deg: float

    @classmethod
    def of_rad(cls, pose) -> PanTilt:
        """The pan and tilt of a joint pose (rad; a roll is left out)."""
        return cls(math.degrees(pose[0]), math.degrees(pose[1]))

    def to_json(self) -> list[float]:
        return [round(float(self.pan_deg), 3), round(float(self.tilt_deg), 3)]


@dataclass(frozen=True)
class HardLimits:
    """The rig's hard joint limits, (low, high) degrees each."""

    pan_deg: tuple[float, float]
    tilt_deg: tuple[float, float]

    def to_json(self) -> dict[str, list[float]]:
        return {"pan": [float(v) for v in self.pan_deg], "tilt": [float(v) for v in self.tilt_deg]}


@dataclass(frozen=True)
class EdgeLoop:
    """One closed loop of the region's edge on the pan/tilt plane: its vertices ``pan_tilt_deg``
    (N, 2) in order, degrees, and ``traced`` (N,) bool, whether the stretch from vertex ``i`` to
    ``i + 1`` (mod N) was traced by the teacher."""

    pan_tilt_deg: np.ndarray
    traced: np.ndarray

    def __post_init__(self) -> None:
        points = np.asarray(self.pan_tilt_deg, dtype=np.float64).reshape(-1, 2)
        flags = np.asarray(self.traced, dtype=bool).reshape(-1)
        if len(flags) != len(points):
            raise ValueError(
                f"an edge loop has {len(points)} vertices but {len(flags)} traced flags; "
                "give one flag per vertex (the stretch to the next vertex)"
            )
        object.__setattr__(self, "pan_tilt_deg", points)
        object.__setattr__(self, "traced", flags)

    def to_json(self) -> dict[str, list]:
        return {
            "points": np.round(self.pan_tilt_deg, 3).tolist(),
            "traced": self.traced.astype(int).tolist(),
        }


@dataclass(frozen=True)
class GuideFigure:
    """One figure of the teaching guide, e.g. ("edge closed", 62.5, "%")."""

    label: str
    value: float
    unit: str = ""

    def to_json(self) -> dict[str, object]:
        return {"label": self.label, "value": float(self.value), "unit": self.unit}


@dataclass(frozen=True)
class TeleopStatus:
    """One teleop cycle as the page shows it: ``commanded`` and ``written`` poses (None before one),
    the gate's ``outcome`` and ``words``, ``rate_hz`` (Hz), ``cycles``, ``blocked`` directions."""

    commanded: PanTilt | None
    written: PanTilt | None
    outcome: str
    rate_hz: float
    cycles: int = 0
    words: str = ""
    blocked: tuple[str, ...] = ()

    def to_json(self) -> dict[str, object]:
        return {
            "commanded": self.commanded.to_json() if self.commanded else None,
            "written": self.written.to_json() if self.written else None,
            "outcome": self.outcome,
            "rate_hz": round(float(self.rate_hz), 1),
            "cycles": int(self.cycles),
            "words": self.words,
            "blocked": list(self.blocked),
        }


@dataclass(frozen=True)
class Live:
    """The fast part of the view, published as often as the producer likes: ``mode`` ("record",
    "teleop" or "demo: <phase>"), the ``pose`` last read, ``sample_count`` recorded, the
    ``teleop`` cycle (None outside teleop), the present ``fault`` ("" for none), a ``note`` for the
    person and a three-servo limb's ``twist`` gauge (None, no ``twist`` JSON key, on two servos)."""

    mode: str
    pose: PanTilt | None = None
    sample_count: int = 0
    teleop: TeleopStatus | None = None
    fault: str = ""
    note: str = ""
    twist: TwistGauge | None = None

    def to_json(self) -> dict[str, object]:
        out: dict[str, object] = {
            "kind": "live",
            "mode": self.mode,
            "pose": self.pose.to_json() if self.pose else None,
            "sample_count": int(self.sample_count),
            "teleop": self.teleop.to_json() if self.teleop else None,
            "fault": self.fault,
            "note": self.note,
        }
        if self.twist is not None:
            out["twist"] = self.twist.to_json()
        return out


@dataclass(frozen=True)
class Scene:
    """The slow part of the view, published at least twice a second and when a fit is done.

    Parameters
    ----------
    samples_deg : ndarray, shape (M, 2)
        Samples to draw, pan/tilt degrees (thinned by :func:`thin_samples`).
    loops, limits, guide : tuple of EdgeLoop, HardLimits or None, tuple of GuideFigure
        The region's edge learned so far (empty until one can be fitted); the rig's hard limits.
    region_note, guide_text : str
        How the region was obtained (or why there is none); the guide's advice.
    twist : TwistMap or None
        A three-servo limb's twist map; None (no ``twist`` JSON key) on two servos.
    """

    samples_deg: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    loops: tuple[EdgeLoop, ...] = ()
    limits: HardLimits | None = None
    region_note: str = ""
    guide: tuple[GuideFigure, ...] = ()
    guide_text: str = ""
    twist: TwistMap | None = None

    def __post_init__(self) -> None:
        samples = np.asarray(self.samples_deg, dtype=np.float64).reshape(-1, 2)
        object.__setattr__(self, "samples_deg", samples)
        object.__setattr__(self, "loops", tuple(self.loops))
        object.__setattr__(self, "guide", tuple(self.guide))

    def to_json(self) -> dict[str, object]:
        out: dict[str, object] = {
            "kind": "scene",
            "samples": np.round(self.samples_deg, 2).tolist(),
            "loops": [loop.to_json() for loop in self.loops],
            "limits": self.limits.to_json() if self.limits else None,
            "region_note": self.region_note,
            "guide": [figure.to_json() for figure in self.guide],
            "guide_text": self.guide_text,
        }
        if self.twist is not None:
            out["twist"] = self.twist.to_json()
        return out


def thin_samples(
    pan_tilt_deg: np.ndarray, cell_deg: float = THIN_CELL_DEG, limit: int = MAX_DRAWN_SAMPLES
) -> np.ndarray:
    """Samples ``pan_tilt_deg`` (N, 2) (deg, in recording order) thinned for drawing: the first
    of each occupied ``cell_deg`` grid cell (deg), in recording order, (M, 2), M <= ``limit``."""
    points = np.asarray(pan_tilt_deg, dtype=np.float64).reshape(-1, 2)
    if len(points) == 0:
        return points
    cells = np.floor(points / cell_deg).astype(np.int64)
    _, first = np.unique(cells, axis=0, return_index=True)
    kept = points[np.sort(first)]
    # Ceiling division: the stride that brings the kept cells down to at most ``limit``.
    stride = max(1, -(-len(kept) // limit))
    return kept[::stride]


@dataclass(frozen=True)
class Snapshot:
    """The board's contents at one instant; a version increases with every publish of its part."""

    live: Live | None
    live_version: int
    scene: Scene | None
    scene_version: int


class Board:
    """The latest :class:`Live` and :class:`Scene`, swapped under a lock from any thread."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._live: Live | None = None
        self._scene: Scene | None = None
        self._live_version = 0
        self._scene_version = 0

    def publish_live(self, live: Live) -> None:
        """Make ``live`` the newest fast part."""
        with self._lock:
            self._live = live
            self._live_version += 1

    def publish_scene(self, scene: Scene) -> None:
        """Make ``scene`` the newest slow part."""
        with self._lock:
            self._scene = scene
            self._scene_version += 1

    def snapshot(self) -> Snapshot:
        """The newest of both parts with their versions, read together."""
        with self._lock:
            return Snapshot(self._live, self._live_version, self._scene, self._scene_version)

    @property
    def live(self) -> Live | None:
        """The newest fast part (None before the first publish)."""
        return self.snapshot().live

    @property
    def scene(self) -> Scene | None:
        """The newest slow part (None before the first publish)."""
        return self.snapshot().scene
