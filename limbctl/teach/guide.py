"""Guided teaching: how closed the edge is, how covered the inside is, where the gaps are, and
when the samples are complete enough to train (docs/teaching.md, "The measures").
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy import ndimage
from scipy.spatial import ConvexHull, QhullError

from limbctl.geometry.gimbal import direction_to_pan_tilt, pan_tilt_to_direction
from limbctl.geometry.quat import tangent_frame
from limbctl.geometry.scalar import direction
from limbctl.teach.edge_support import EdgeSupport
from limbctl.teach.holes import HOLE_MIN_S, Hole, find_holes

if TYPE_CHECKING:
    from limbctl.region.evidence import Stretch

#: Azimuth sectors for the outline: 5 deg each, fine for a kidney's lobes, coarse for a trace.
SECTORS = 72
#: Edge closure bins, 2 deg each: a 100 Hz trace at <= 20 deg/s fills every one 10 deg out.
EDGE_BINS = 180
#: Depth (deg) of the on-edge band below the outline: a trace's wobble plus the tremor.
EDGE_BAND_DEG = 1.5
#: Share of the way to the convex hull an edge reaches, not a notch (irregular.yaml's dent: 0.6).
NOTCH_RATIO = 0.5
#: Widest stretch (bins, 20 deg) a slow trace may leave the band for and still close: the outline
#: runs across a dent 2-3 of its 5 deg sectors wide (10-15 deg), the trace along the dent's walls
#: below the band; a dent any wider holds outline points of its own, its trace in the band.
BRIDGE_MAX_BINS = 10
#: Bins (4 deg) the trace between may stray past either end: a slanted notch's tip lies beyond
#: its mouth's corner as seen from the centre.
BRIDGE_SLACK_BINS = 2
#: Fastest (deg/s) an on-edge sample moves: edges are traced at 10-20, strokes run at 40+.
EDGE_MAX_SPEED_DEG_S = 25.0
#: Window (s) of that speed: long enough to average out a 7-12 Hz tremor.
SPEED_WINDOW_S = 0.2
#: Centre refinements by the circle fit (the second changes the centre by well under a degree).
CENTRE_ROUNDS = 2
#: Cell size (deg) of the inside-coverage grid: about the width one stroke of the hand covers.
CELL_DEG = 4.0
#: Ready to train: the edge closed in at least this share of the turn ...
READY_EDGE_CLOSED = 0.97
#: ... and this share of the inside covered: a few strokes (docs/teaching.md).
READY_INSIDE_COVERED = 0.1
#: Fewer samples than this say nothing yet (phase ``start``).
MIN_SAMPLES = 20
#: Gaps listed in a result, largest first.
MAX_GAPS = 5

#: What each phase asks of the teacher.
PHASES = {
    "start": "move the limb to its edge",
    "edge": "trace the whole edge once, slowly",
    "middle": "wander through the middle",
    "ready": "ready to train",
}


@dataclass(frozen=True)
class EdgeGap:
    """An untraced stretch of outline: share of the turn, (pan_deg, tilt_deg) of ends and middle."""

    fraction: float
    start_deg: tuple[float, float]
    middle_deg: tuple[float, float]
    end_deg: tuple[float, float]


@dataclass(frozen=True)
class InsideGap:
    """Joined uncovered inside cells: share of the inside cells, (pan_deg, tilt_deg) of the mean."""

    fraction: float
    middle_deg: tuple[float, float]


@dataclass(frozen=True)
class Guidance:
    """What the guide says about the ``samples`` so far (angles in degrees): the ``phase`` (of
    :data:`PHASES`), the share of the turn whose edge is traced and of inside cells with a
    sample, the largest gaps of each (at most :data:`MAX_GAPS`), whether ``ready`` to train, the
    picture's centre (pan, tilt), a sample's largest angle from the mean, the recording's holes,
    the stretches of edge the region would bridge and the teaching must answer, those it
    answered (held at the samples, :attr:`~limbctl.region.evidence.Stretch.settled`), and whether
    their check is still running."""

    samples: int
    phase: str
    edge_closed: float
    inside_covered: float
    edge_gaps: tuple[EdgeGap, ...]
    inside_gaps: tuple[InsideGap, ...]
    ready: bool
    centre_deg: tuple[float, float]
    spread_deg: float
    holes: tuple[Hole, ...] = ()
    unsupported: tuple[Stretch, ...] = ()
    settled: tuple[Stretch, ...] = ()
    checking: bool = False

    @property
    def open_hole(self) -> Hole | None:
        """The hole hiding the largest stretch of edge not re-traced yet; None when none."""
        holes = [h for h in self.holes if h.open]
        return max(holes, key=lambda h: h.open_fraction) if holes else None

    @property
    def largest_gap(self) -> EdgeGap | InsideGap | None:
        """The gap to teach next: the largest edge gap while tracing, else inside; or None."""
        if self.phase in ("start", "edge") and self.edge_gaps:
            return self.edge_gaps[0]
        return self.inside_gaps[0] if self.inside_gaps else None

    def line(self) -> str:
        """One line for the terminal: phase, edge closed, inside covered, largest gap, ready."""
        head = (
            f"{self.phase:6s} edge closed {100 * self.edge_closed:3.0f} %  "
            f"inside covered {100 * self.inside_covered:3.0f} %"
        )
        gap, hole = self.largest_gap, self.open_hole
        if hole is not None and hole.edge_deg is not None:
            p, t = hole.edge_deg
            where = (
                f"edge gap {100 * hole.open_fraction:.0f} % in a {hole.duration_s:.2f} s hole of "
                f"the recording around ({p:+.0f}, {t:+.0f})"
            )
            tail = f"re-trace the edge near pan {p:+.0f}, tilt {t:+.0f}"
            return f"{head}  {where} (pan, tilt deg)  -> {tail}"
        if isinstance(gap, EdgeGap):
            (p0, t0), (p1, t1) = gap.start_deg, gap.end_deg
            where = (
                f"edge gap {100 * gap.fraction:.0f} % from ({p0:+.0f}, {t0:+.0f}) "
                f"to ({p1:+.0f}, {t1:+.0f})"
            )
        elif isinstance(gap, InsideGap):
            p, t = gap.middle_deg
            where = f"inside gap {100 * gap.fraction:.0f} % around ({p:+.0f}, {t:+.0f})"
        else:
            where = "no gap"
        if self.unsupported:
            stretch = self.unsupported[0]
            where = (
                f"edge unsupported {stretch.length_deg:.1f} deg up to {stretch.distance_deg:.1f} "
                f"deg from every sample ({len(self.unsupported)} stretches)"
            )
            tail = stretch.request()
        elif self.checking:
            tail = "checking that the samples support the edge"
        else:
            tail = "READY TO TRAIN" if self.ready else PHASES[self.phase]
            if self.ready and self.settled:
                tail += f" (edge held at the samples in {len(self.settled)} places)"
        return f"{head}  {where} (pan, tilt deg)  -> {tail}"


def _project(d: np.ndarray, centre: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(rho_deg, phi_rad) of directions (N, 3) about ``centre`` (3,): azimuthal equidistant."""
    u, v = tangent_frame(centre)
    # rho = acos(d . c), phi = atan2(d . v, d . u)
    rho = np.degrees(np.arccos(np.clip(d @ centre, -1.0, 1.0)))
    phi = np.arctan2(d @ v, d @ u)
    return rho, phi


def _unproject(x: np.ndarray, y: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Directions (M, 3) of picture points x, y (M,) deg."""
    u, v = tangent_frame(centre)
    rho = np.radians(np.hypot(x, y))
    phi = np.arctan2(y, x)
    return np.cos(rho)[:, None] * centre + np.sin(rho)[:, None] * (
        np.cos(phi)[:, None] * u + np.sin(phi)[:, None] * v
    )


def _pan_tilt_deg(x: np.ndarray, y: np.ndarray, centre: np.ndarray) -> list[tuple[float, float]]:
    pan, tilt = direction_to_pan_tilt(_unproject(np.atleast_1d(x), np.atleast_1d(y), centre))
    return [(math.degrees(p), math.degrees(t)) for p, t in zip(pan, tilt, strict=True)]


def _outline(rho: np.ndarray, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The outline points (phi_rad, rho_deg) sorted by phi: the outermost sample per sector."""
    sector = ((phi + math.pi) / (2.0 * math.pi) * SECTORS).astype(np.int64) % SECTORS
    outermost = np.full(SECTORS, -1.0)
    np.maximum.at(outermost, sector, rho)
    # the phi of a sample reaching its sector's outermost rho (any one of equals)
    at_max = rho == outermost[sector]
    outline_phi = np.zeros(SECTORS)
    outline_phi[sector[at_max]] = phi[at_max]
    held = outermost >= 0.0
    return outline_phi[held], outermost[held]


def _outline_at(phi: np.ndarray, outline_phi: np.ndarray, outline_rho: np.ndarray) -> np.ndarray:
    """r_out(phi): periodic linear interpolation of the outline points (deg)."""
    return np.interp(phi, outline_phi, outline_rho, period=2.0 * math.pi)


def _fit_centre(outline_phi: np.ndarray, outline_rho: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """The centre direction of the circle best fitting the outline points (Kasa)."""
    x = np.radians(outline_rho) * np.cos(outline_phi)
    y = np.radians(outline_rho) * np.sin(outline_phi)
    # x^2 + y^2 + D x + E y + F = 0 in least squares; centre (-D / 2, -E / 2)
    a = np.stack([x, y, np.ones_like(x)], axis=1)
    (d_coef, e_coef, _), *_ = np.linalg.lstsq(a, -(x * x + y * y), rcond=None)
    moved = _unproject(np.degrees([-d_coef / 2.0]), np.degrees([-e_coef / 2.0]), centre)[0]
    return moved / np.linalg.norm(moved)


def _hull_at(phi: np.ndarray, outline_phi: np.ndarray, outline_rho: np.ndarray) -> np.ndarray:
    """Distance (M,) deg from the centre (inside the hull) to the outline's hull along ``phi``."""
    points = np.stack([outline_rho * np.cos(outline_phi), outline_rho * np.sin(outline_phi)], 1)
    facets = ConvexHull(points).equations  # n . x + b <= 0 inside, |n| = 1
    ray = np.stack([np.cos(phi), np.sin(phi)], axis=1)
    # the ray t (cos phi, sin phi) leaves facet j at t = -b_j / (n_j . ray), for n_j . ray > 0
    along = ray @ facets[:, :2].T
    with np.errstate(divide="ignore"):
        exit_at = np.where(along > 1e-12, -facets[:, 2] / along, np.inf)
    return exit_at.min(axis=1)


def _speed_deg_s(t_s: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Speed (deg/s, (N,)) of the limb at each sample, over a window of about SPEED_WINDOW_S."""
    n = len(d)
    if n < 2:
        return np.zeros(n)
    step = float(np.median(np.diff(t_s)))
    w = max(1, int(round(SPEED_WINDOW_S / step))) if step > 0.0 else 1
    k = np.arange(n)
    before, after = np.maximum(k - w, 0), np.minimum(k + w, n - 1)
    # speed = angle(d[k - w], d[k + w]) / (t[k + w] - t[k - w]), angle = 2 asin(|chord| / 2)
    chord = np.linalg.norm(d[after] - d[before], axis=1)
    angle = np.degrees(2.0 * np.arcsin(np.clip(chord / 2.0, 0.0, 1.0)))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(t_s[after] > t_s[before], angle / (t_s[after] - t_s[before]), 0.0)


def _traced_across(
    t_s: np.ndarray, bins: np.ndarray, tracing: np.ndarray, on_edge: np.ndarray
) -> np.ndarray:
    """Edge bins (M,) a trace crossed below the band (across a dent the outline runs over): from
    an on-edge sample to the next, tracing without a hole, at most BRIDGE_MAX_BINS apart, every
    sample between in their bins give or take BRIDGE_SLACK_BINS (docs/teaching.md). ``t_s``,
    ``bins`` (N,): the samples' times (s, in order); their edge bins (int, of EDGE_BINS round the
    turn); ``tracing``, ``on_edge`` (N,) bool: slow and not halfway to the centre; on the edge
    (slow and in the outline's band)."""
    edge_at = np.flatnonzero(on_edge)
    # a break: a fast sample, or a hole in the recording before a sample
    broken = ~tracing
    broken[1:] |= np.diff(t_s) >= HOLE_MIN_S
    breaks = np.cumsum(broken)
    a, b = edge_at[:-1], edge_at[1:]
    # unbroken: no break in a + 1 .. b (the on-edge ends trace themselves)
    bridged = (b > a + 1) & (breaks[b] == breaks[a])
    # the shorter way round the turn from a's bin to b's, signed
    step = (bins[b] - bins[a] + EDGE_BINS // 2) % EDGE_BINS - EDGE_BINS // 2
    bridged &= (np.abs(step) >= 2) & (np.abs(step) <= BRIDGE_MAX_BINS)
    crossed = []
    for i, j, s in zip(a[bridged], b[bridged], step[bridged], strict=True):
        # along the turn from i's bin towards j's: a trace keeps within the two; a path through
        # the middle (past the centre) sweeps round the turn instead
        along = (np.sign(s) * (bins[i : j + 1] - bins[i]) + BRIDGE_SLACK_BINS) % EDGE_BINS
        if along.max() <= abs(s) + 2 * BRIDGE_SLACK_BINS:
            crossed.append((bins[i] + np.sign(s) * np.arange(abs(s) + 1)) % EDGE_BINS)
    return np.concatenate(crossed) if crossed else np.zeros(0, dtype=np.int64)


def _edge(
    t_s, rho, phi, slow, on_edge, outline_phi, outline_rho, centre, unseen
) -> tuple[float, tuple[EdgeGap, ...]]:
    # bin b covers phi in [-pi + b w, -pi + (b + 1) w); a notch at its middle is not an edge
    middles = -math.pi + (np.arange(EDGE_BINS) + 0.5) * (2.0 * math.pi / EDGE_BINS)
    try:
        hull = _hull_at(middles, outline_phi, outline_rho)
    except QhullError:
        return 0.0, ()  # the samples lie on a line: no edge to speak of
    edge_bins = _outline_at(middles, outline_phi, outline_rho) >= NOTCH_RATIO * hull
    every = ((phi + math.pi) / (2.0 * math.pi) * EDGE_BINS).astype(np.int64) % EDGE_BINS
    filled = np.zeros(EDGE_BINS, dtype=bool)
    filled[every[on_edge]] = True
    # a trace across a dent: from an edge bin to an edge bin, never halfway to the centre
    tracing = slow & (rho >= NOTCH_RATIO * _outline_at(phi, outline_phi, outline_rho))
    filled[_traced_across(t_s, every, tracing, on_edge & edge_bins[every])] = True
    filled[unseen] = False  # the stretches of edge holes of the recording hide
    filled &= edge_bins
    closed = float(filled.mean())
    if closed in (0.0, 1.0):
        return closed, ()
    # runs of empty bins, read round the turn from a filled bin so none is split in two
    first = int(np.argmax(filled))
    rolled = np.roll(filled, -first)
    edges = np.flatnonzero(np.diff(np.r_[True, rolled, True].astype(np.int8)))
    starts, ends = edges[::2], edges[1::2]  # empty runs [start, end) in the rolled order
    gaps = []
    width = 2.0 * math.pi / EDGE_BINS
    for s, e in sorted(zip(starts, ends, strict=True), key=lambda r: r[0] - r[1])[:MAX_GAPS]:
        phis = -math.pi + (np.array([s, (s + e) / 2.0, e]) + first) * width
        r = _outline_at(phis, outline_phi, outline_rho)
        ends_deg = _pan_tilt_deg(r * np.cos(phis), r * np.sin(phis), centre)
        gaps.append(EdgeGap((e - s) / EDGE_BINS, *ends_deg))
    return closed, tuple(gaps)


def _inside(rho, phi, outline_phi, outline_rho, centre) -> tuple[float, tuple[InsideGap, ...]]:
    x, y = rho * np.cos(phi), rho * np.sin(phi)
    reach = float(outline_rho.max())
    n = int(math.ceil(reach / CELL_DEG)) + 1
    # cell (i, j) spans x in [(i - n) CELL, (i - n + 1) CELL), likewise y with j
    centres = (np.arange(2 * n) - n + 0.5) * CELL_DEG
    cx, cy = np.meshgrid(centres, centres, indexing="ij")
    c_rho, c_phi = np.hypot(cx, cy), np.arctan2(cy, cx)
    inside = c_rho <= _outline_at(c_phi, outline_phi, outline_rho) - EDGE_BAND_DEG
    if not inside.any():
        return 0.0, ()
    covered = np.zeros_like(inside)
    i = np.clip(np.floor(x / CELL_DEG).astype(np.int64) + n, 0, 2 * n - 1)
    j = np.clip(np.floor(y / CELL_DEG).astype(np.int64) + n, 0, 2 * n - 1)
    covered[i, j] = True
    total = int(inside.sum())
    fraction = float((covered & inside).sum()) / total
    labels, count = ndimage.label(inside & ~covered)
    if count == 0:
        return fraction, ()
    sizes = np.bincount(labels.ravel(), minlength=count + 1)[1:]
    gaps = []
    for k in np.argsort(-sizes)[:MAX_GAPS]:
        member = labels == k + 1
        where = _pan_tilt_deg(np.array([cx[member].mean()]), np.array([cy[member].mean()]), centre)
        gaps.append(InsideGap(float(sizes[k]) / total, where[0]))
    return fraction, tuple(gaps)


def assess_directions(t_s: np.ndarray, d: np.ndarray) -> Guidance:
    """The guidance for limb directions ``d`` (N, 3) taken at times ``t_s`` (N,) s, in order."""
    d = np.asarray(d, dtype=np.float64).reshape(-1, 3)
    t_s = np.asarray(t_s, dtype=np.float64).reshape(-1)
    if len(t_s) != len(d):
        raise ValueError(f"assess: {len(t_s)} times for {len(d)} samples; give one time each")
    n = len(d)
    if n == 0:
        return Guidance(0, "start", 0.0, 0.0, (), (), False, (0.0, 0.0), 0.0)
    mean = d.sum(axis=0)
    mean /= max(float(np.linalg.norm(mean)), 1e-12)
    spread = float(np.degrees(np.arccos(np.clip(d @ mean, -1.0, 1.0))).max())
    centre = mean
    rho, phi = _project(d, centre)
    outline_phi, outline_rho = _outline(rho, phi)
    for _ in range(CENTRE_ROUNDS):
        if len(outline_phi) < 3:
            break
        centre = _fit_centre(outline_phi, outline_rho, centre)
        rho, phi = _project(d, centre)
        outline_phi, outline_rho = _outline(rho, phi)
    centre_deg = _pan_tilt_deg(np.zeros(1), np.zeros(1), centre)[0]
    if n < MIN_SAMPLES or len(outline_phi) < 3:
        return Guidance(n, "start", 0.0, 0.0, (), (), False, centre_deg, spread)
    slow = _speed_deg_s(t_s, d) <= EDGE_MAX_SPEED_DEG_S
    in_band = rho >= _outline_at(phi, outline_phi, outline_rho) - EDGE_BAND_DEG
    on_edge = slow & in_band
    holes, unseen = find_holes(
        *(t_s, rho, phi, in_band, on_edge, EDGE_BINS),
        outline_at=lambda p: _outline_at(p, outline_phi, outline_rho),
        pan_tilt_deg=lambda x, y: _pan_tilt_deg(x, y, centre),
    )
    edge_closed, edge_gaps = _edge(
        t_s, rho, phi, slow, on_edge, outline_phi, outline_rho, centre, unseen
    )
    inside_covered, inside_gaps = _inside(rho, phi, outline_phi, outline_rho, centre)
    edge_done = edge_closed >= READY_EDGE_CLOSED and not any(h.open for h in holes)
    ready = edge_done and inside_covered >= READY_INSIDE_COVERED
    phase = "ready" if ready else ("middle" if edge_done else "edge")
    fields = (edge_closed, inside_covered, edge_gaps, inside_gaps, ready, centre_deg, spread)
    return Guidance(n, phase, *fields, holes)


def assess(t_s: np.ndarray, pan_rad: np.ndarray, tilt_rad: np.ndarray) -> Guidance:
    """The guidance for samples at times ``t_s`` (N,) s given as joint angles (N,) rad."""
    d = pan_tilt_to_direction(np.asarray(pan_rad), np.asarray(tilt_rad))
    return assess_directions(t_s, d)


class Guide:
    """Collects samples as recorded (O(1) each) and assesses them on demand."""

    def __init__(self, capacity: int = 4096, support: EdgeSupport | None = None) -> None:
        self._t = np.empty(max(int(capacity), 1))
        self._d = np.empty((len(self._t), 3))
        self.samples = 0
        self.support = support

    def add(self, t_s: float, pan_rad: float, tilt_rad: float) -> None:
        """Add one sample: its time (s) and joint angles (rad)."""
        if self.samples == len(self._t):
            self._t = np.concatenate([self._t, np.empty_like(self._t)])
            self._d = np.concatenate([self._d, np.empty_like(self._d)])
        self._t[self.samples] = t_s
        self._d[self.samples] = direction(pan_rad, tilt_rad)
        self.samples += 1

    def assess(self, final: bool = False) -> Guidance:
        """The guidance for every sample so far; READY withheld while ``support`` finds a stretch
        unsupported or (unless ``final``, which waits) has not answered."""
        d = self._d[: self.samples]
        guidance = assess_directions(self._t[: self.samples], d)
        if self.support is None or not guidance.ready:
            return guidance
        if final:
            self.support.check_now(d)
        else:
            self.support.check_later(d)
        found = self.support.stretches
        settled = tuple(s for s in found or () if s.settled)
        asked = tuple(s for s in found or () if not s.settled)
        if asked:
            return dataclasses.replace(
                guidance, ready=False, phase="middle", unsupported=asked, settled=settled
            )
        if settled:
            return dataclasses.replace(guidance, settled=settled)
        if found is None and self.support.possible and not final:
            return dataclasses.replace(guidance, ready=False, phase="middle", checking=True)
        return guidance
