"""The swing path of a scripted hand: where it takes the limb's pan and tilt, before its tremor
(minimum-jerk moves that stay PATH_DEPTH_FLOOR_DEG inside, planned lazily from the seed)."""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

import numpy as np

from firmware_sim.regions import Region, deepen

#: Mean speed (deg/s) through the middle: a relaxed sweep crossing 100 deg in a few seconds.
DEFAULT_SPEED_DEG_S = 40.0
#: How far inside the edge (deg) boundary tracing runs, and the least depth any move may reach.
EDGE_INSET_DEG = 1.0
MIN_PATH_DEPTH_DEG = 0.5
#: A region must reach at least this deep (deg) for the hand to have room to move.
MIN_REGION_DEPTH_DEG = 2.0 * EDGE_INSET_DEG
#: Near the edge (deg) a move eases in/out up to EDGE_EASE_S longer; traces run at a fraction.
SLOW_BAND_DEG = 15.0
EDGE_EASE_S = 0.5
EDGE_SPEED_FRACTION = 0.4
#: Middle waypoints are drawn with density proportional to depth ** WAYPOINT_DEPTH_POWER.
WAYPOINT_DEPTH_POWER = 1.5
#: Edge visits work round the perimeter in laps of this many, a move through the middle between.
EDGE_VISITS_PER_LAP = 12
#: Length (deg) of the stretch of edge traced at each visit.
EDGE_TRACE_DEG = (4.0, 8.0)
#: Shortest move (s): a person does not flick the limb.
MIN_MOVE_S = 0.3
#: Probability of a pause after a move, and its duration range (s).
PAUSE_PROBABILITY = 0.1
PAUSE_S = (0.2, 0.6)
#: Waypoints drawn per move, the nearest taken; after the trace one (long strokes fill the middle).
WAYPOINT_CHOICES = 2
WAYPOINT_CHOICES_AFTER_TRACE = 1
#: Intermediate poses tried (after the centre) to get round a corner of the region.
VIA_TRIES = 8
#: Candidate waypoints tried before backing up along the path already walked.
WAYPOINT_TRIES = 40
#: Moves bow sideways by a normal fraction of their length with this standard deviation.
ARC_BOW_FRACTION = 0.2
#: Spacing (deg) of checks along a move and of points along a traced edge.
PATH_CHECK_STEP_DEG = 0.5
#: Depth (deg) a planned move keeps everywhere: its checks keep MIN_PATH_DEPTH_DEG, and a pose
#: between two lies within half a step of one (the edge distance changes no faster than the pose).
PATH_DEPTH_FLOOR_DEG = MIN_PATH_DEPTH_DEG - 0.5 * PATH_CHECK_STEP_DEG
TRACE_STEP_DEG = 1.0
#: Speed (deg/s) of the full edge trace: a careful 10-20 deg/s; 400 deg of edge in under 30 s.
TRACE_SPEED_DEG_S = 18.0
#: The full trace's depth wobbles by up to TRACE_WOBBLE_DEG, its speed by TRACE_SPEED_WOBBLE.
TRACE_WOBBLE_DEG = 0.3
TRACE_SPEED_WOBBLE = 0.2
#: Wavelengths (deg along the edge) of the two sines in each wobble: slow drifts, not jitter.
TRACE_WOBBLE_WAVELENGTH_DEG = (23.0, 61.0)
#: Halvings of a trace step round a reflex corner: 1 deg becomes 1/8 deg, fine for any corner.
TRACE_SPLITS = 3
#: The full trace runs this fraction of the perimeter past where it started, to close the loop.
TRACE_OVERLAP = 0.03
#: Teaching styles of a region hand: what a REGION.yaml's ``style:`` may name.
STYLES = {
    "trace": "trace the whole edge once, slowly, about a degree inside; then wander",
    "wander": "wander through the middle from the start, visiting the edge every other move",
}
DEFAULT_STYLE = "trace"
#: What a visit may ask: a hand description's ``visits: [{do: ...}]``.
VISIT_KINDS = {
    "edge": "trace the edge near the place",
    "twist": "turn the twist to both stops near the place",
}
#: Least edge (deg) an ``edge`` visit traces: 5 deg either side reach past a guide's stretch.
VISIT_EDGE_DEG = 10.0
#: A ``twist`` visit circles the place at this radius (deg) for three 0.9 s twist cycles (s).
VISIT_TWIST_RADIUS_DEG = 3.0
VISIT_TWIST_S = 3.0
#: Points on a ``twist`` visit's circle (every 30 deg).
VISIT_TWIST_POINTS = 12


@dataclass(frozen=True)
class Visit:
    """A guide's request: from ``after_s`` s go to (``pan_deg``, ``tilt_deg``) and ``do`` one of
    :data:`VISIT_KINDS`, tracing at least ``length_deg`` deg of edge."""

    after_s: float
    pan_deg: float
    tilt_deg: float
    do: str
    length_deg: float = VISIT_EDGE_DEG


def progress(t: float, t0: float, t1: float, minimum_jerk: bool = True) -> float:
    """Fraction in [0, 1] of a segment from ``t0`` to ``t1`` (s) done at ``t``, along a
    minimum-jerk profile (``10 s^3 - 15 s^4 + 6 s^5``) or linear in time."""
    s = min(max((t - t0) / (t1 - t0), 0.0), 1.0)
    if minimum_jerk:
        s = s * s * s * (10.0 + s * (-15.0 + 6.0 * s))
    return s


class Track:
    """Segments of a path in time, ``segments[k] = (t0, t1, ...)`` in s, appended in order."""

    def __init__(self) -> None:
        self.segments: list[tuple] = []
        self._t0: list[float] = []
        self._current = 0

    def add(self, *segment) -> None:
        self._t0.append(segment[0])
        self.segments.append(segment)

    def at(self, t: float) -> tuple:
        """The segment that holds time ``t`` (s): the first before its start, the last after it."""
        k = self._current
        if not self.segments[k][0] <= t < self.segments[k][1]:
            k = max(bisect.bisect_right(self._t0, t) - 1, 0)
            self._current = k
        return self.segments[k]


class SwingPath:
    """The (pan_deg, tilt_deg) a hand takes the limb along, without tremor: through a ``region``
    in one of :data:`STYLES`, drawn from ``seed``, answering ``visits`` in order of ``after_s``,
    moving through the middle at a mean ``speed_deg_s`` (deg/s); or along a ``script`` of
    (t_s, pan_deg, tilt_deg, ...) waypoints in increasing time (later columns ignored)."""

    def __init__(
        self,
        region: Region | None,
        script=None,
        speed_deg_s: float = DEFAULT_SPEED_DEG_S,
        seed: int = 0,
        style: str = DEFAULT_STYLE,
        visits=(),
    ) -> None:
        self.region = region
        self.visits = sorted(visits, key=lambda v: v.after_s)
        self.visit_spans: list[tuple[float, float, Visit]] = []  # (start s, end s, visit)
        self.speed_deg_s = speed_deg_s
        self.style = style
        self.trace_span_s: tuple[float, float] | None = None  # of the full edge trace, s
        self._seed = seed
        self.track = Track()
        if script is not None:
            # hold the first waypoint from before it (a one-second constant segment)
            first = script[0]
            self._add(first[0] - 1.0, first[0], first[1], first[2], first[1], first[2], False)
            for a, b in zip(script, script[1:], strict=False):
                self._add(a[0], b[0], a[1], a[2], b[1], b[2], False)

    def start_from(self, pan_deg: float, tilt_deg: float) -> None:
        """Take hold at (pan_deg, tilt_deg): a region path (re)starts there at t = 0."""
        if self.region is None:
            return
        self._rng = np.random.default_rng([self._seed, 1])
        self.track = Track()
        self.visit_spans = []
        self._visits_done = 0
        self._edge_u = float(self._rng.uniform())
        self._edge_step = 1.0 / EDGE_VISITS_PER_LAP
        self._edge_due = True
        # (pan, tilt, bulge) of each move since the last centre visit, to retrace if boxed in
        self._trail: list[tuple[float, float, tuple[float, float]]] = []
        pan, tilt = float(pan_deg), float(tilt_deg)
        self._add(0.0, PAUSE_S[0], pan, tilt, pan, tilt, False)
        self.trace_span_s = None
        inside = float(self.region.edge_distance_deg(pan, tilt)) >= MIN_PATH_DEPTH_DEG
        if self.style == "trace" and inside:
            self._trace_whole_edge()
        elif (pan, tilt) != self.region.center_deg:
            self._move(self.region.center_deg)
            if self.style == "trace":
                self._trace_whole_edge()

    def at(self, t: float) -> tuple[float, float]:
        """(pan_deg, tilt_deg) at ``t`` s after taking hold, planning as far as ``t``."""
        if self.region is not None:
            while self.track.segments[-1][1] <= t:
                self._plan_next()
        t0, t1, p0, q0, p1, q1, minimum_jerk, bulge_pan, bulge_tilt = self.track.at(t)
        s = progress(t, t0, t1, minimum_jerk)
        # pose = start + s (end - start) + 4 s (1 - s) bulge  (a parabolic arc, not a ruler line)
        arc = 4.0 * s * (1.0 - s)
        return p0 + s * (p1 - p0) + arc * bulge_pan, q0 + s * (q1 - q0) + arc * bulge_tilt

    def _add(self, t0, t1, p0, q0, p1, q1, minimum_jerk, bulge=(0.0, 0.0)) -> None:
        self.track.add(t0, t1, p0, q0, p1, q1, minimum_jerk, bulge[0], bulge[1])

    def _end(self) -> tuple[float, float, float]:
        segment = self.track.segments[-1]
        return segment[1], segment[4], segment[5]

    def _path_ok(self, a, b, bulge=(0.0, 0.0)) -> bool:
        """Whether the move a -> b, bowed by ``bulge``, keeps MIN_PATH_DEPTH_DEG inside at checks
        at most PATH_CHECK_STEP_DEG apart (its length, bow included, overestimated)."""
        length = math.hypot(b[0] - a[0], b[1] - a[1]) + 2.0 * math.hypot(*bulge)
        n = int(length / PATH_CHECK_STEP_DEG) + 2
        s = np.linspace(0.0, 1.0, n)
        arc = 4.0 * s * (1.0 - s)
        pan = a[0] + s * (b[0] - a[0]) + arc * bulge[0]
        tilt = a[1] + s * (b[1] - a[1]) + arc * bulge[1]
        return bool(np.all(self.region.edge_distance_deg(pan, tilt) >= MIN_PATH_DEPTH_DEG))

    def _ease_s(self, depth_deg: float) -> float:
        """Extra time (s) to ease into or out of a pose at a depth: EDGE_EASE_S at the edge."""
        return EDGE_EASE_S * (1.0 - min(max(depth_deg, 0.0) / SLOW_BAND_DEG, 1.0))

    def _move(self, target: tuple[float, float], bulge=(0.0, 0.0), retrace=False) -> None:
        """A minimum-jerk move to ``target``, eased when either end is near the edge."""
        t, pan, tilt = self._end()
        depth = self.region.edge_distance_deg([pan, target[0]], [tilt, target[1]])
        distance = math.hypot(target[0] - pan, target[1] - tilt)
        # duration = distance / speed + ease at either end near the edge
        duration = distance / self.speed_deg_s + self._ease_s(depth[0]) + self._ease_s(depth[1])
        duration = max(duration, MIN_MOVE_S)
        self._add(t, t + duration, pan, tilt, target[0], target[1], True, bulge)
        if not retrace:
            self._trail.append((pan, tilt, bulge))
        if (target[0], target[1]) == self.region.center_deg:
            self._trail.clear()

    def _pause(self) -> None:
        t, pan, tilt = self._end()
        self._add(t, t + float(self._rng.uniform(*PAUSE_S)), pan, tilt, pan, tilt, False)

    def _draw_waypoint(self) -> tuple[float, float]:
        """A pose inside, drawn with a density that grows with its depth (dense in the middle)."""
        pan_lo, pan_hi, tilt_lo, tilt_hi = self.region.bbox_deg
        while True:
            pan = float(self._rng.uniform(pan_lo, pan_hi))
            tilt = float(self._rng.uniform(tilt_lo, tilt_hi))
            depth = float(self.region.edge_distance_deg(pan, tilt))
            # accept with probability (depth / depth_max) ** WAYPOINT_DEPTH_POWER
            accept = (max(depth, 0.0) / self.region.depth_max_deg) ** WAYPOINT_DEPTH_POWER
            if depth >= EDGE_INSET_DEG and self._rng.uniform() < accept:
                return pan, tilt

    def _reach(self, target: tuple[float, float]) -> bool:
        """Move to ``target`` bowed, straight or via one pose, staying inside; False if none."""
        _, pan, tilt = self._end()
        # bulge: perpendicular to the move, N(0, ARC_BOW_FRACTION) of its length
        bow = float(self._rng.normal(0.0, ARC_BOW_FRACTION))
        bulge = (-(target[1] - tilt) * bow, (target[0] - pan) * bow)
        for candidate in (bulge, (0.0, 0.0)):
            if self._path_ok((pan, tilt), target, candidate):
                self._move(target, candidate)
                return True
        # around a corner: via the centre, else via a drawn waypoint both ends can see
        for via in [self.region.center_deg] + [self._draw_waypoint() for _ in range(VIA_TRIES)]:
            if self._path_ok((pan, tilt), via) and self._path_ok(via, target):
                self._move(via)
                self._move(target)
                return True
        return False

    def _plan_next(self) -> None:
        """Append the next stretch: a due request, an edge visit, or a move through the middle."""
        if self._visits_done < len(self.visits):
            visit = self.visits[self._visits_done]
            if self._end()[0] >= visit.after_s:
                self._visits_done += 1
                self._answer(visit)
                return
        traced = self.trace_span_s is not None
        if self._edge_due and not traced:
            self._edge_due = False
            # next visit: one spacing further round, jittered by up to a sixth of a spacing
            self._edge_u = (self._edge_u + self._edge_step) % 1.0
            jitter = float(self._rng.uniform(-1.0, 1.0)) * self._edge_step / 6.0
            if self._visit_edge(self._edge_u + jitter):
                return
        self._edge_due = True
        _, pan, tilt = self._end()
        for _ in range(WAYPOINT_TRIES):
            # of the drawn waypoints a person picks the nearest: no pointless tours
            choices = WAYPOINT_CHOICES_AFTER_TRACE if traced else WAYPOINT_CHOICES
            options = [self._draw_waypoint() for _ in range(choices)]
            nearest = min(options, key=lambda w: math.hypot(w[0] - pan, w[1] - tilt))
            if self._reach(nearest):
                break
        else:
            # boxed in (a very irregular polygon): retrace the path walked since the centre; the
            # arc a -> b bowed by B, walked backwards, is b -> a bowed by the same B
            if self._trail:
                pan, tilt, bulge = self._trail.pop()
                self._move((pan, tilt), bulge, retrace=True)
            else:
                self._move(self.region.center_deg)
        if self._rng.uniform() < PAUSE_PROBABILITY:
            self._pause()

    def _visit_edge(self, u_start: float) -> bool:
        """Go to the edge at perimeter fraction ``u_start`` and trace a short stretch slowly."""
        region = self.region
        length = float(self._rng.uniform(*EDGE_TRACE_DEG))
        sense = 1.0 if self._rng.uniform() < 0.5 else -1.0
        n = max(int(length / TRACE_STEP_DEG), 1) + 1
        u = u_start + sense * (length / region.perimeter_deg) * np.linspace(0.0, 1.0, n)
        points = [region.boundary_point(float(v), EDGE_INSET_DEG) for v in u]
        depth = region.edge_distance_deg([p[0] for p in points], [p[1] for p in points])
        points = [p for p, d in zip(points, depth, strict=True) if d >= MIN_PATH_DEPTH_DEG]
        if len(points) < 2 or not self._reach(points[0]):
            return False
        edge_speed = self.speed_deg_s * EDGE_SPEED_FRACTION
        for b in points[1:]:
            t, pan, tilt = self._end()
            duration = math.hypot(b[0] - pan, b[1] - tilt) / edge_speed
            if duration <= 0.0 or not self._path_ok((pan, tilt), b):
                continue  # skip a point the edge cannot be followed to; try the next
            self._add(t, t + duration, pan, tilt, b[0], b[1], False)
            self._trail.append((pan, tilt, (0.0, 0.0)))
        return True

    def _trace_whole_edge(self) -> None:
        """Trace the whole edge once from its point nearest the hand; sets trace_span_s."""
        region = self.region
        _, pan, tilt = self._end()
        n = max(int(region.perimeter_deg / TRACE_STEP_DEG), 8)
        u = np.arange(n) / n
        starts = np.array([region.boundary_point(float(v), EDGE_INSET_DEG) for v in u])
        order = np.argsort(np.hypot(starts[:, 0] - pan, starts[:, 1] - tilt))
        for k in order[:WAYPOINT_TRIES]:
            if self._reach((float(starts[k, 0]), float(starts[k, 1]))):
                break
        else:
            return  # no edge point reachable inside the region: wander only
        t_start = self._end()[0]
        sense = 1.0 if self._rng.uniform() < 0.5 else -1.0
        steps = int(n * (1.0 + TRACE_OVERLAP))
        arc_deg = np.arange(steps + 1) * (region.perimeter_deg / n)
        # wobble(s) = amplitude (0.6 sin(2 pi s / L1 + f1) + 0.4 sin(2 pi s / L2 + f2)), s in deg
        phases = self._rng.uniform(0.0, 2.0 * math.pi, size=4)
        shape = [
            0.6 * np.sin(2.0 * math.pi * arc_deg / TRACE_WOBBLE_WAVELENGTH_DEG[0] + phases[a])
            + 0.4 * np.sin(2.0 * math.pi * arc_deg / TRACE_WOBBLE_WAVELENGTH_DEG[1] + phases[b])
            for a, b in ((0, 1), (2, 3))
        ]
        inset = EDGE_INSET_DEG + TRACE_WOBBLE_DEG * shape[0]
        speed = TRACE_SPEED_DEG_S * (1.0 + TRACE_SPEED_WOBBLE * shape[1])
        u_trace = u[int(k)] + sense * arc_deg / region.perimeter_deg
        points = np.array(
            [region.boundary_point(float(v), float(d)) for v, d in zip(u_trace, inset, strict=True)]
        )
        points = deepen(self.region, points, inset)
        for b, d, v in zip(points[1:], inset[1:], speed[1:], strict=True):
            self._trace_to((float(b[0]), float(b[1])), float(d), float(v), TRACE_SPLITS)
        self.trace_span_s = (t_start, self._end()[0])

    def _trace_to(
        self, b: tuple[float, float], depth_deg: float, speed: float, splits: int
    ) -> bool:
        """Trace to ``b`` at ``speed`` deg/s, straight or via midpoints ``depth_deg`` deep (up to
        ``splits`` halvings); False when that fails."""
        t, pan, tilt = self._end()
        duration = math.hypot(b[0] - pan, b[1] - tilt) / speed
        if duration <= 0.0:
            return True
        if self._path_ok((pan, tilt), b):
            self._add(t, t + duration, pan, tilt, b[0], b[1], False)
            self._trail.append((pan, tilt, (0.0, 0.0)))
            return True
        if splits == 0:
            return False
        middle = deepen(
            self.region, np.array([[(pan + b[0]) / 2, (tilt + b[1]) / 2]]), np.array([depth_deg])
        )[0]
        if not self._trace_to((float(middle[0]), float(middle[1])), depth_deg, speed, splits - 1):
            return False
        return self._trace_to(b, depth_deg, speed, splits - 1)

    def in_visit(self, t: float) -> bool:
        """Whether ``t`` (s) falls in a visit's span (planned so far)."""
        return any(t0 <= t < t1 for t0, t1, _ in self.visit_spans)

    def _answer(self, visit: Visit) -> None:
        """Go to the visit's place, do what it asks and record its span."""
        region = self.region
        if visit.do == "edge":
            # the stretch of edge round the place's nearest edge point, EDGE_INSET_DEG inside
            u0 = float(region.boundary_fraction(visit.pan_deg, visit.tilt_deg))
            length = max(visit.length_deg, VISIT_EDGE_DEG)
            n = max(int(length / TRACE_STEP_DEG), 1) + 1
            u = u0 + (length / region.perimeter_deg) * np.linspace(-0.5, 0.5, n)
            points = np.array([region.boundary_point(float(v), EDGE_INSET_DEG) for v in u])
            points = deepen(region, points, np.full(n, EDGE_INSET_DEG))
        else:
            # a circle round the place, the place first set at least EDGE_INSET_DEG deep
            middle = deepen(
                region,
                np.array([[visit.pan_deg, visit.tilt_deg]]),
                np.array([EDGE_INSET_DEG + VISIT_TWIST_RADIUS_DEG]),
            )[0]
            angle = np.linspace(0.0, 2.0 * math.pi, VISIT_TWIST_POINTS + 1)
            points = middle + VISIT_TWIST_RADIUS_DEG * np.stack(
                [np.cos(angle), np.sin(angle)], axis=1
            )
            points = deepen(region, points, np.full(len(points), EDGE_INSET_DEG))
        start = (float(points[0, 0]), float(points[0, 1]))
        if not self._reach(start):
            return  # no path inside to the place: the request stays unanswered
        t_start = self._end()[0]
        speed = TRACE_SPEED_DEG_S
        if visit.do != "edge":
            speed = 2.0 * math.pi * VISIT_TWIST_RADIUS_DEG / VISIT_TWIST_S
        for b in points[1:]:
            self._trace_to((float(b[0]), float(b[1])), EDGE_INSET_DEG, speed, TRACE_SPLITS)
        self.visit_spans.append((t_start, self._end()[0], visit))
