"""Synthetic regions of limb directions with exact ideal corrections, for tests and benchmarks:
Lee's swing cone (:class:`ConeRegion`) and (pan, tilt) degree polygons (:class:`PolygonRegion`)."""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from limbctl.geometry.gimbal import direction_to_pan_tilt, pan_tilt_to_direction
from limbctl.geometry.quat import direction_angle, swing_from_direction, tangent_frame

#: A kidney-shaped region in (pan, tilt) degrees, concave on top: the shape of a hand-taught limit.
BEAN = np.array(
    [[-55.0, -10.0], [-50.0, -28.0], [-30.0, -38.0], [0.0, -40.0], [30.0, -36.0], [50.0, -25.0],
     [58.0, -5.0], [52.0, 15.0], [38.0, 28.0], [20.0, 25.0], [5.0, 14.0], [-10.0, 14.0],
     [-25.0, 25.0], [-42.0, 24.0], [-53.0, 10.0]]
)  # fmt: skip


def rounded(polygon_deg: np.ndarray, iterations: int = 4) -> np.ndarray:
    """Chaikin's corner cutting of a closed (pan, tilt) polygon (M, 2), ``iterations`` times."""
    p = np.asarray(polygon_deg, dtype=np.float64)
    for _ in range(iterations):
        q = np.roll(p, -1, axis=0)
        # each edge p -> q gives 3/4 p + 1/4 q and 1/4 p + 3/4 q
        p = np.stack([0.75 * p + 0.25 * q, 0.25 * p + 0.75 * q], axis=1).reshape(-1, 2)
    return p


#: BEAN with its corners rounded (240 points): smooth, still irregular and concave on top.
KIDNEY = rounded(BEAN)


def egg(length_deg: float = 48.0, width_deg: float = 26.4, n: int = 240) -> np.ndarray:
    """A convex egg (n, 2) (pan, tilt) deg, ``length_deg`` by about ``width_deg``, blunt at +pan."""
    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    a, b = 0.5 * length_deg, 0.5 * width_deg
    # pan = a cos t + a / 8, tilt = b sin t (1 + cos t / 4)
    return np.column_stack([a * np.cos(t) + a / 8.0, b * np.sin(t) * (1.0 + 0.25 * np.cos(t))])


#: A convex egg 48 x 26 deg: smooth and convex, but not one circle (a tight and a blunt end).
EGG = egg()

#: KIDNEY at 0.35 scale (39 x 23 deg): reaching 19.7 deg from its axis, like a 20 deg cone.
SMALL_KIDNEY = 0.35 * KIDNEY


#: A 40 x 30 deg rectangle, (pan, tilt) deg, with a 12 x 12 deg notch cut into its top edge.
NOTCH = np.array(
    [[-20.0, -15.0], [20.0, -15.0], [20.0, 15.0], [6.0, 15.0], [6.0, 3.0], [-6.0, 3.0],
     [-6.0, 15.0], [-20.0, 15.0]]
)  # fmt: skip
#: The notch itself (pan range, tilt range) in degrees: the directions NOTCH must never reach.
NOTCH_HOLE = ((-6.0, 6.0), (3.0, 15.0))


def to_quaternions(d: np.ndarray) -> np.ndarray:
    """Twist-free quaternions (..., 4), w >= 0, that point the limb along directions ``d``."""
    return swing_from_direction(d)


def _cap_directions(n: int, axis: np.ndarray, radius: float, rng: np.random.Generator):
    """``n`` directions uniform over the cap of angular ``radius`` (rad) about unit ``axis``."""
    # uniform on a cap: cos(theta) uniform in [cos(radius), 1]
    cos_t = rng.uniform(np.cos(radius), 1.0, n)
    sin_t = np.sqrt(np.clip(1.0 - cos_t**2, 0.0, 1.0))
    phi = rng.uniform(-np.pi, np.pi, n)
    u, v = tangent_frame(axis)
    return cos_t[:, None] * axis + sin_t[:, None] * (
        np.cos(phi)[:, None] * u + np.sin(phi)[:, None] * v
    )


class Region(ABC):
    """A region of valid limb directions with its exact nearest valid direction (``ideal``)."""

    #: Unit axis (3,) the test commands are spread around; ``radius`` its largest angle (rad).
    axis: np.ndarray
    radius: float

    @abstractmethod
    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` teaching directions (n, 3) inside the region."""

    @abstractmethod
    def depth(self, d: np.ndarray) -> np.ndarray:
        """Signed angle (rad) from each direction (N, 3) to the boundary, positive inside."""

    @abstractmethod
    def ideal(self, d: np.ndarray) -> np.ndarray:
        """The nearest valid direction (N, 3) to each of ``d`` (N, 3); ``d`` itself inside."""

    def contains(self, d: np.ndarray) -> np.ndarray:
        """(N,) bool: each direction inside the region (boundary included)."""
        return self.depth(d) >= 0.0

    def test_directions(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` directions (n, 3) uniform within ``R + min(R, 45 deg)`` of the axis."""
        spread = self.radius + min(self.radius, np.radians(45.0))
        return _cap_directions(n, self.axis, min(spread, np.pi), rng)


class ConeRegion(Region):
    """Lee's swing cone: directions within ``half_angle`` (rad) of +x."""

    def __init__(self, half_angle: float) -> None:
        if not 0.0 < half_angle < np.pi:
            raise ValueError(f"half_angle must be in (0, pi) rad, got {half_angle}")
        self.axis = np.array([1.0, 0.0, 0.0])
        self.radius = float(half_angle)

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        return _cap_directions(n, self.axis, self.radius, rng)

    def depth(self, d: np.ndarray) -> np.ndarray:
        return self.radius - direction_angle(d, self.axis)

    def ideal(self, d: np.ndarray) -> np.ndarray:
        d = np.asarray(d, dtype=np.float64)
        out = d.copy()
        outside = ~self.contains(d)
        # keep the swing axis, set the swing angle to R: cos(R) x + sin(R) (d - d_x x)/|d - d_x x|
        side = d[outside] - d[outside, :1] * self.axis
        norm = np.linalg.norm(side, axis=1, keepdims=True)
        side = np.where(norm > 1e-15, side / np.where(norm > 0, norm, 1.0), [0.0, 1.0, 0.0])
        out[outside] = np.cos(self.radius) * self.axis + np.sin(self.radius) * side
        return out


class PolygonRegion(Region):
    """A polygon in (pan, tilt) degrees: straight edges in joint space, taught densely inside.

    Parameters
    ----------
    polygon_deg : array_like, shape (V, 2)
        Vertices (pan, tilt) in degrees, either winding, not self-intersecting.
    edge_density, ramp_deg : float
        Sample density at the edge relative to the middle (0 < it <= 1), rising to 1 over the
        depth ``ramp_deg``.
    boundary_step_deg : float
        Spacing of the dense boundary sampling used for depth and the ideal correction.
    """

    def __init__(
        self,
        polygon_deg: np.ndarray = BEAN,
        edge_density: float = 0.3,
        ramp_deg: float = 10.0,
        boundary_step_deg: float = 0.05,
    ) -> None:
        self.polygon = np.radians(np.asarray(polygon_deg, dtype=np.float64))
        self.edge_density = float(edge_density)
        self.ramp = np.radians(ramp_deg)
        closed = np.vstack([self.polygon, self.polygon[:1]])
        pts = []
        for a, b in zip(closed[:-1], closed[1:], strict=True):
            steps = max(2, int(np.ceil(np.degrees(np.linalg.norm(b - a)) / boundary_step_deg)))
            s = np.linspace(0.0, 1.0, steps, endpoint=False)[:, None]
            pts.append(a + s * (b - a))
        pan_tilt = np.vstack(pts)
        self.boundary = pan_tilt_to_direction(pan_tilt[:, 0], pan_tilt[:, 1])
        centre = self.boundary.mean(axis=0)
        self.axis = centre / np.linalg.norm(centre)
        self.radius = float(np.max(direction_angle(self.boundary, self.axis)))

    def _inside_joint_space(self, d: np.ndarray) -> np.ndarray:
        pan, tilt = direction_to_pan_tilt(d)
        poly = self.polygon
        inside = np.zeros(pan.shape, dtype=bool)
        # even-odd ray casting along +pan in (pan, tilt)
        for (x0, y0), (x1, y1) in zip(poly, np.roll(poly, -1, axis=0), strict=True):
            crosses = (y0 > tilt) != (y1 > tilt)
            with np.errstate(divide="ignore", invalid="ignore"):
                x_at = x0 + (tilt - y0) * (x1 - x0) / (y1 - y0)
            inside ^= crosses & (pan < x_at)
        # the polygon lives in pan in (-pi, pi): directions behind the limb are outside
        return inside & (d[..., 0] > -1.0 + 1e-12)

    def _nearest_boundary(self, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Nearest boundary direction (N, 3) and its angle (N,) for each of ``d`` (N, 3)."""
        nearest = np.empty_like(d)
        angle = np.empty(d.shape[0])
        b = self.boundary
        nb_ = b.shape[0]
        for start in range(0, d.shape[0], 2048):
            chunk = d[start : start + 2048]
            i = np.argmax(chunk @ b.T, axis=1)
            # refine on the two boundary chords next to the nearest sample (great-circle arcs)
            best = b[i]
            best_angle = direction_angle(chunk, best)
            for j in ((i - 1) % nb_, (i + 1) % nb_):
                p, a = _nearest_on_arc(chunk, b[i], b[j])
                better = a < best_angle
                best[better] = p[better]
                best_angle[better] = a[better]
            nearest[start : start + 2048] = best
            angle[start : start + 2048] = best_angle
        return nearest, angle

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        out = np.empty((0, 3))
        while out.shape[0] < n:
            cand = _cap_directions(4 * n, self.axis, self.radius, rng)
            depth = self.depth(cand)
            # density = edge + (1 - edge) * smoothstep(depth / ramp) inside, 0 outside
            s = np.clip(depth / self.ramp, 0.0, 1.0)
            density = np.where(depth >= 0, self.edge_density + (1 - self.edge_density) * s, 0.0)
            keep = rng.uniform(0.0, 1.0, cand.shape[0]) < density
            out = np.vstack([out, cand[keep]])
        return out[:n]

    def depth(self, d: np.ndarray) -> np.ndarray:
        d = np.atleast_2d(np.asarray(d, dtype=np.float64))
        _, angle = self._nearest_boundary(d)
        return np.where(self._inside_joint_space(d), angle, -angle)

    def ideal(self, d: np.ndarray) -> np.ndarray:
        d = np.atleast_2d(np.asarray(d, dtype=np.float64))
        nearest, _ = self._nearest_boundary(d)
        return np.where(self._inside_joint_space(d)[:, None], d, nearest)


def trajectory_samples(
    region: Region,
    n: int,
    rng: np.random.Generator,
    step_deg: float = 0.3,
    edge_share: float = 0.3,
    edge_inset_deg: float = 0.5,
) -> np.ndarray:
    """``n`` directions (n, 3) as a hand teaches: strokes ``step_deg`` apart between inside
    waypoints, or (``edge_share``) 10-40 deg along the edge ``edge_inset_deg`` inside."""
    step = np.radians(step_deg)
    edge = _edge_track(region, np.radians(edge_inset_deg))
    out = [region.sample(1, rng)[0]]
    total = 1
    while total < n:
        here = out[-1]
        if rng.uniform() < edge_share:
            # creep along the inset boundary from its point nearest the hand
            start = int(np.argmax(edge @ here))
            length = rng.uniform(np.radians(10.0), np.radians(40.0))
            count = max(2, int(length / (step / 3.0)))
            # samples step / 3 apart along a track of len(edge) points over its length
            advance = (step / 3.0) * len(edge) / _track_length(edge)
            way = 1.0 if rng.uniform() < 0.5 else -1.0
            idx = np.round(start + way * advance * np.arange(count)).astype(int)
            stroke = edge[idx % len(edge)]
        else:
            target = region.sample(1, rng)[0]
            angle = float(direction_angle(here, target))
            count = max(2, int(np.ceil(angle / step)))
            t = np.linspace(0.0, 1.0, count)[:, None]
            # slerp between here and target: sin((1-t)a)/sin(a) here + sin(ta)/sin(a) target
            stroke = (np.sin((1.0 - t) * angle) * here + np.sin(t * angle) * target) / np.sin(
                max(angle, 1e-12)
            )
            if not region.contains(stroke).all():
                continue
        out.extend(stroke)
        total += len(stroke)
    return np.asarray(out[:n])


def covered(
    d: np.ndarray, samples: np.ndarray, radius_deg: float = 6.0, max_gap_deg: float = 150.0
) -> np.ndarray:
    """(N,) bool: directions ``d`` (N, 3) the taught ``samples`` (K, 3) cover: those within
    ``radius_deg`` surround it with no empty sector wider than ``max_gap_deg``."""
    from limbctl.region.shape import surrounded

    return surrounded(
        np.asarray(d, dtype=np.float64),
        np.asarray(samples, dtype=np.float64),
        np.radians(radius_deg),
        np.radians(max_gap_deg),
    )


def _edge_track(region: Region, inset: float) -> np.ndarray:
    """Dense directions (K, 3) ``inset`` (rad) inside the region's boundary, in loop order."""
    if isinstance(region, ConeRegion):
        t = np.linspace(-np.pi, np.pi, 3600, endpoint=False)
        u, v = tangent_frame(region.axis)
        r = region.radius - inset
        return np.cos(r) * region.axis + np.sin(r) * (
            np.cos(t)[:, None] * u + np.sin(t)[:, None] * v
        )
    b = region.boundary
    # move each boundary point toward the axis until it is ``inset`` deep (a few steps)
    track = b.copy()
    for _ in range(3):
        deficit = inset - region.depth(track)
        toward = region.axis - (track @ region.axis)[:, None] * track
        toward /= np.linalg.norm(toward, axis=1, keepdims=True)
        track = track + deficit[:, None] * toward
        track /= np.linalg.norm(track, axis=1, keepdims=True)
    return track[region.contains(track)]


def _track_length(track: np.ndarray) -> float:
    """Length (rad) of a closed track of directions (K, 3)."""
    return float(np.sum(direction_angle(track, np.roll(track, -1, axis=0))))


def _nearest_on_arc(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Nearest point on the short great-circle arcs a-b (rows) to directions p, and its angle."""
    n = np.cross(a, b)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    # project onto the arc's plane: p' = p - (p.n) n
    foot = p - np.sum(p * n, axis=-1, keepdims=True) * n
    foot /= np.linalg.norm(foot, axis=-1, keepdims=True)
    within = (np.sum(np.cross(a, foot) * n, axis=-1) >= 0) & (
        np.sum(np.cross(foot, b) * n, axis=-1) >= 0
    )
    da = direction_angle(p, a)
    db = direction_angle(p, b)
    end = np.where((da <= db)[:, None], a, b)
    point = np.where(within[:, None], foot, end)
    return point, direction_angle(p, point)


def inset_track(polygon_deg: np.ndarray, inset_deg: float, step_deg: float) -> np.ndarray:
    """Points (K, 2) ``step_deg`` apart along the inner parallel curve ``inset_deg`` inside a
    (pan, tilt) polygon (M, 2) deg, from its first vertex (arcs round reflex corners)."""
    p = np.asarray(polygon_deg, dtype=np.float64)
    x, y = p[:, 0], p[:, 1]
    # shoelace: positive area = counter-clockwise, the region on the left of each edge
    if np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) < 0.0:
        p = p[::-1]
    edge = np.roll(p, -1, axis=0) - p
    tangent = edge / np.linalg.norm(edge, axis=1, keepdims=True)
    # the inward normal is the tangent turned left
    normal = np.column_stack([-tangent[:, 1], tangent[:, 0]])
    m = len(p)
    enter, leave, arcs = np.empty((m, 2)), np.empty((m, 2)), []
    for k in range(m):
        i = k - 1
        # turn at corner p[k] from edge i to edge k: >= 0 convex, < 0 reflex
        turn = tangent[i, 0] * tangent[k, 1] - tangent[i, 1] * tangent[k, 0]
        if turn >= 0.0:
            # the moved edges meet at p_k + r (n_i + n_k) / (1 + t_i . t_k)
            corner = p[k] + inset_deg * (normal[i] + normal[k]) / (1.0 + tangent[i] @ tangent[k])
            enter[k] = leave[k] = corner
            arcs.append(np.empty((0, 2)))
            continue
        enter[k] = p[k] + inset_deg * normal[i]
        leave[k] = p[k] + inset_deg * normal[k]
        a0 = np.arctan2(normal[i, 1], normal[i, 0])
        # a reflex corner turns clockwise: the arc about p_k runs from n_i down to n_k
        sweep = (a0 - np.arctan2(normal[k, 1], normal[k, 0])) % (2.0 * np.pi)
        a = a0 - np.linspace(0.0, sweep, max(2, int(np.ceil(sweep * inset_deg / step_deg))))
        arcs.append(p[k] + inset_deg * np.column_stack([np.cos(a), np.sin(a)])[:-1])
    path = []
    for k in range(m):
        nxt = (k + 1) % m
        length = float(np.linalg.norm(enter[nxt] - leave[k]))
        s = np.linspace(0.0, 1.0, max(2, int(np.ceil(length / step_deg))), endpoint=False)
        path.append(leave[k] + s[:, None] * (enter[nxt] - leave[k]))
        path.append(arcs[nxt])
    return np.vstack(path)


def traced_teaching(
    region: PolygonRegion,
    seconds: float,
    rng: np.random.Generator,
    rate_hz: float = 125.0,
    trace_deg_s: float = 15.0,
    inset_deg: float = 1.0,
    wander_deg_s: float = 30.0,
) -> tuple[np.ndarray, int]:
    """A teaching that traces the edge once at ``trace_deg_s``, then wanders at ``wander_deg_s``:
    directions (n, 3), ``n = seconds * rate_hz``, and the trace's length."""
    n = int(round(seconds * rate_hz))
    track = inset_track(np.degrees(region.polygon), inset_deg, trace_deg_s / rate_hz)
    trace = pan_tilt_to_direction(np.radians(track[:, 0]), np.radians(track[:, 1]))[:n]
    rest = n - trace.shape[0]
    if rest <= 0:
        return trace, trace.shape[0]
    wander = trajectory_samples(region, rest, rng, step_deg=wander_deg_s / rate_hz, edge_share=0.0)
    return np.vstack([trace, wander]), trace.shape[0]


def reach_into(
    contains, region: PolygonRegion, box_deg=NOTCH_HOLE, step_deg: float = 0.05
) -> float:
    """How far (deg) ``contains`` ((N, 4) -> (N,) bool) reaches into the box ``((pan_min,
    pan_max), (tilt_min, tilt_max))`` deg outside ``region``: its deepest held grid point."""
    (p0, p1), (t0, t1) = box_deg
    pan, tilt = np.meshgrid(
        np.arange(p0, p1 + 0.5 * step_deg, step_deg), np.arange(t0, t1 + 0.5 * step_deg, step_deg)
    )
    d = pan_tilt_to_direction(np.radians(pan.ravel()), np.radians(tilt.ravel()))
    held = d[np.asarray(contains(to_quaternions(d)), dtype=bool)]
    if held.shape[0] == 0:
        return 0.0
    return float(max(0.0, np.degrees(-region.depth(held)).max()))
