"""Holes in a teaching: stretches of time with no sample, and the stretch of edge one may hide
(docs/teaching.md, "Holes")."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

#: Gap (s) that makes a hole: 5 deg of edge at 25 deg/s, the shortest loss that costs the fit.
HOLE_MIN_S = 0.2
#: Holes listed in a result, longest first.
MAX_HOLES = 5


@dataclass(frozen=True)
class Hole:
    """A stretch of time with no sample: times (s) of the samples before and after it and the
    limb's (pan, tilt) deg there; whether either lies in the outline's band (``at_edge``); the
    middle (pan, tilt) deg of the stretch of edge it may hide (``edge_deg``, or None), that
    stretch's share of the turn (``fraction``) and the share not yet re-traced."""

    start_s: float
    end_s: float
    before_deg: tuple[float, float]
    after_deg: tuple[float, float]
    at_edge: bool
    edge_deg: tuple[float, float] | None = None
    fraction: float = 0.0
    open_fraction: float = 0.0

    @property
    def duration_s(self) -> float:
        return self.end_s - self.start_s

    @property
    def open(self) -> bool:
        """It hides a stretch of edge not yet re-traced."""
        return self.open_fraction > 0.0

    def line(self) -> str:
        """One line of words and figures for the recorder's summary."""
        (p0, t0), (p1, t1) = self.before_deg, self.after_deg
        head = (
            f"{self.duration_s:.2f} s without samples from {self.start_s:.1f} s, the limb moved "
            f"from ({p0:+.0f}, {t0:+.0f}) to ({p1:+.0f}, {t1:+.0f}) (pan, tilt deg)"
        )
        if self.edge_deg is None:
            return head + ("; at the edge, no stretch of it missed" if self.at_edge else "; inside")
        p, t = self.edge_deg
        where = f"{100 * self.fraction:.0f} % of the edge around ({p:+.0f}, {t:+.0f})"
        if self.open:
            return f"{head}; {where} untaught -> re-trace the edge near pan {p:+.0f}, tilt {t:+.0f}"
        return f"{head}; {where} re-traced since"


def sample_gaps(t_s: np.ndarray, min_s: float = HOLE_MIN_S) -> np.ndarray:
    """Indices ``k`` (H,) of the samples after which comes a hole: ``t[k + 1] - t[k] > min_s``."""
    t_s = np.asarray(t_s, dtype=np.float64)
    return np.flatnonzero(np.diff(t_s) > min_s)


def hole_bins(phi_before: float, phi_after: float, bins: int) -> np.ndarray:
    """The edge bins strictly between the bins of two azimuths (rad), the shorter way round."""
    width = 2.0 * math.pi / bins
    b0 = int((phi_before + math.pi) // width) % bins
    b1 = int((phi_after + math.pi) // width) % bins
    # steps from b0 to b1 counter-clockwise; the other way round when that is shorter
    ahead = (b1 - b0) % bins
    if ahead <= bins // 2:
        return (b0 + np.arange(1, ahead)) % bins
    return (b1 + np.arange(1, bins - ahead)) % bins


def open_bins(
    t_s: np.ndarray,
    phi: np.ndarray,
    on_edge: np.ndarray,
    after_s: float,
    stretch: np.ndarray,
    bins: int,
) -> np.ndarray:
    """The bins of ``stretch`` (S,) that no on-edge sample taken after ``after_s`` lies in;
    ``t_s``, ``phi`` (rad) and ``on_edge`` (bool) are the samples' (N,)."""
    later = on_edge & (t_s > after_s)
    width = 2.0 * math.pi / bins
    seen = np.zeros(bins, dtype=bool)
    seen[((phi[later] + math.pi) // width).astype(np.int64) % bins] = True
    return stretch[~seen[stretch]]


def find_holes(
    t_s: np.ndarray,
    rho: np.ndarray,
    phi: np.ndarray,
    in_band: np.ndarray,
    on_edge: np.ndarray,
    bins: int,
    outline_at: Callable[[np.ndarray], np.ndarray],
    pan_tilt_deg: Callable[[np.ndarray, np.ndarray], list[tuple[float, float]]],
) -> tuple[tuple[Hole, ...], np.ndarray]:
    """The recording's holes (those hiding an open stretch of edge first, then the longest, at
    most MAX_HOLES) and the edge bins of every open stretch (int, repeats possible).

    ``t_s``, ``rho``, ``phi`` (N,): the samples' times (s, in order) and places in the guide's
    picture: distance from the centre (deg), azimuth (rad); ``in_band``, ``on_edge`` (N,) bool: in
    the outline's band; and on the edge (in the band and slow); ``bins``: equal bins of the turn
    the edge is judged in; ``outline_at``: ``r_out(phi)`` (deg) of azimuths (M,) rad;
    ``pan_tilt_deg``: (pan_deg, tilt_deg) of picture points x, y (M,).
    """
    unseen: list[np.ndarray] = []
    holes = []
    width = 2.0 * math.pi / bins
    for k in sample_gaps(t_s):
        ends = np.array([k, k + 1])
        before, after = pan_tilt_deg(rho[ends] * np.cos(phi[ends]), rho[ends] * np.sin(phi[ends]))
        hole = Hole(float(t_s[k]), float(t_s[k + 1]), before, after, bool(in_band[ends].any()))
        stretch = hole_bins(float(phi[k]), float(phi[k + 1]), bins) if hole.at_edge else ()
        if len(stretch):
            still = open_bins(t_s, phi, on_edge, hole.end_s, stretch, bins)
            unseen.append(still)
            middle = np.array([-math.pi + (stretch[len(stretch) // 2] + 0.5) * width])
            r = outline_at(middle)
            where = pan_tilt_deg(r * np.cos(middle), r * np.sin(middle))[0]
            fraction, still_fraction = len(stretch) / bins, len(still) / bins
            hole = Hole(
                hole.start_s, hole.end_s, before, after, True, where, fraction, still_fraction
            )
        holes.append(hole)
    holes.sort(key=lambda h: (-h.open_fraction, -h.duration_s))
    return tuple(holes[:MAX_HOLES]), np.concatenate(unseen) if unseen else np.empty(0, np.int64)
