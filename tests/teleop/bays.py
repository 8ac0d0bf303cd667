"""Random non-convex regions for the gate's reach: outlines with a bay and a notch, exact for limb
directions (:class:`OutlineRegion`) or under a linear twist band (:class:`OutlineBandRegion`)."""

from __future__ import annotations

import math

import numpy as np

from limbctl.envelope.synthetic import PolygonRegion
from limbctl.geometry.gimbal import direction_to_pan_tilt, pan_tilt_to_direction
from limbctl.geometry.quat import limb_direction
from limbctl.geometry.twist import compose, decompose, decompose_one, wrap

#: Vertices of a random outline: one every 5 deg of its angle, three across a 14 deg notch.
OUTLINE_VERTICES = 72


def bay_outline(rng: np.random.Generator, radius_deg: tuple[float, float] = (28.0, 40.0)):
    """A random outline with a bay and a notch, of mean radius within ``radius_deg`` (deg): its
    (OUTLINE_VERTICES, 2) counter-clockwise (pan, tilt) vertices (deg)."""
    radius = rng.uniform(*radius_deg)
    centre = np.array([rng.uniform(-20.0, 20.0), rng.uniform(0.0, 20.0)])
    theta = np.linspace(0.0, 2.0 * np.pi, OUTLINE_VERTICES, endpoint=False)
    # r(theta) = R (1 + noise) (1 - bay dent) (1 - notch dent), each dent a raised cosine
    r = radius * (1.0 + 0.06 * rng.standard_normal(OUTLINE_VERTICES))
    bay_at = rng.uniform(0.0, 2.0 * np.pi)
    notch_at = bay_at + rng.uniform(0.6, 1.4) * np.pi  # the notch well away from the bay
    for at, half_width, depth in (
        (bay_at, np.radians(rng.uniform(25.0, 45.0)), rng.uniform(0.35, 0.5)),
        (notch_at, np.radians(rng.uniform(7.0, 12.0)), rng.uniform(0.55, 0.75)),
    ):
        off = np.abs(np.angle(np.exp(1j * (theta - at))))
        dent = np.where(off < half_width, 0.5 * (1.0 + np.cos(np.pi * off / half_width)), 0.0)
        r = r * (1.0 - depth * dent)
    pan = centre[0] + r * np.cos(theta)
    tilt = centre[1] + r * np.sin(theta)
    return np.stack([np.clip(pan, -100.0, 100.0), np.clip(tilt, -60.0, 75.0)], axis=1)


class OutlineRegion:
    """An outline of (V, 2) (pan, tilt) vertices (deg) as an exact envelope of limb directions."""

    def __init__(self, polygon_deg: np.ndarray) -> None:
        self.polygon_deg = np.asarray(polygon_deg, dtype=np.float64)
        self.shape = PolygonRegion(self.polygon_deg, boundary_step_deg=0.1)
        poly = np.radians(self.polygon_deg)
        nxt = np.roll(poly, -1, axis=0)
        self._edges = (poly[None, :, 0], poly[None, :, 1], nxt[None, :, 0], nxt[None, :, 1])

    def inside_directions(self, d: np.ndarray) -> np.ndarray:
        """(N,) bool: each direction (N, 3) inside the outline (even-odd ray casting along +pan)."""
        d = np.atleast_2d(np.asarray(d, dtype=np.float64))
        pan = np.arctan2(d[:, 1], d[:, 0])[:, None]
        tilt = np.arctan2(d[:, 2], np.hypot(d[:, 0], d[:, 1]))[:, None]
        x0, y0, x1, y1 = self._edges
        crosses = (y0 > tilt) != (y1 > tilt)
        with np.errstate(divide="ignore", invalid="ignore"):
            x_at = x0 + (tilt - y0) * (x1 - x0) / (y1 - y0)
        odd = np.count_nonzero(crosses & (pan < x_at), axis=1) % 2 == 1
        return odd & (d[:, 0] > -1.0 + 1e-12)

    def nearest_directions(self, d: np.ndarray) -> np.ndarray:
        """The nearest direction of the outline (N, 3) to each of ``d`` (N, 3)."""
        d = np.atleast_2d(np.asarray(d, dtype=np.float64))
        out = d.copy()
        outside = ~self.inside_directions(d)
        if outside.any():
            out[outside] = self.shape._nearest_boundary(d[outside])[0]
        return out

    def contains(self, q: np.ndarray) -> np.ndarray | bool:
        """Whether each quaternion ((4,) or (N, 4)) points the limb inside the outline."""
        q = np.asarray(q, dtype=np.float64)
        inside = self.inside_directions(limb_direction(q.reshape(-1, 4)))
        return bool(inside[0]) if q.ndim == 1 else inside

    def correct(self, q: np.ndarray) -> np.ndarray:
        """``q`` itself inside; outside, the twist-free quaternion of the nearest direction."""
        q = np.asarray(q, dtype=np.float64)
        rows = q.reshape(-1, 4).copy()
        d = limb_direction(rows)
        outside = ~self.inside_directions(d)
        if outside.any():
            rows[outside] = compose(self.nearest_directions(d[outside]), 0.0)
        return rows[0] if q.ndim == 1 else rows


class OutlineBandRegion(OutlineRegion):
    """An outline under a twist band ``|wrap(tau - centre)| <= half_width`` (rad), with
    ``centre = c0 + c_pan pan + c_tilt tilt`` and ``half_width = w0 + w_pan pan + w_tilt tilt``
    (pan, tilt in rad; ``half_width`` positive over the outline)."""

    def __init__(self, polygon_deg: np.ndarray, centre, half_width) -> None:
        super().__init__(polygon_deg)
        self.centre = tuple(float(c) for c in centre)
        self.half_width = tuple(float(w) for w in half_width)

    @classmethod
    def random(cls, rng: np.random.Generator) -> OutlineBandRegion:
        """A random outline under a random linear band (half-width 8 deg or more on it)."""
        polygon = bay_outline(rng)
        centre = (np.radians(rng.uniform(-40, 40)), *rng.uniform(-0.8, 0.8, 2))
        slope = rng.uniform(-0.25, 0.25, 2)
        pan, tilt = np.radians(polygon[:, 0]), np.radians(polygon[:, 1])
        w0 = max(
            np.radians(rng.uniform(25, 40)),
            np.radians(8.0) - (slope[0] * pan + slope[1] * tilt).min(),
        )
        return cls(polygon, centre, (w0, *slope))

    def band(self, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Centre and half-width (rad) of the band at each direction (N, 3)."""
        pan, tilt = direction_to_pan_tilt(np.atleast_2d(d))
        c0, cp, ct = self.centre
        w0, wp, wt = self.half_width
        return c0 + cp * pan + ct * tilt, w0 + wp * pan + wt * tilt

    def contains(self, q: np.ndarray) -> np.ndarray | bool:
        """Whether each orientation ((4,) or (N, 4)) is inside: direction and twist."""
        q = np.asarray(q, dtype=np.float64)
        if q.ndim == 1:  # one pose, the gate's question: scalar arithmetic
            d, tau = decompose_one(q)
            if not self.inside_directions(np.array([d]))[0]:
                return False
            pan, tilt = math.atan2(d[1], d[0]), math.atan2(d[2], math.hypot(d[0], d[1]))
            (c0, cp, ct), (w0, wp, wt) = self.centre, self.half_width
            off = math.remainder(tau - (c0 + cp * pan + ct * tilt), 2.0 * math.pi)
            return abs(off) <= w0 + wp * pan + wt * tilt
        d, tau = decompose(q.reshape(-1, 4))
        centre, half = self.band(d)
        return self.inside_directions(d) & (np.abs(wrap(tau - centre)) <= half)

    def correct(self, q: np.ndarray) -> np.ndarray:
        """``q`` inside; outside, the direction onto the outline, then the twist into its band."""
        q = np.asarray(q, dtype=np.float64)
        rows = q.reshape(-1, 4).copy()
        out = ~np.asarray(self.contains(rows), dtype=bool).reshape(-1)
        if out.any():
            d, tau = decompose(rows[out])
            d = self.nearest_directions(d)
            centre, half = self.band(d)
            tau = centre + np.clip(wrap(tau - centre), -half, half)
            rows[out] = compose(d, tau)
        return rows[0] if q.ndim == 1 else rows


def teaching(region: OutlineRegion, seconds: float, rng: np.random.Generator) -> np.ndarray:
    """A traced teaching of ``region``: directions (N, 3), or for a banded region orientations
    (N, 4), a third of their twists at either limit of the band (within 2 %)."""
    from limbctl.envelope.synthetic import traced_teaching

    d, _ = traced_teaching(PolygonRegion(region.polygon_deg), seconds, rng)
    if not isinstance(region, OutlineBandRegion):
        return d
    centre, half = region.band(d)
    u = rng.choice([-0.98, 0.98, 0.0], d.shape[0])
    u = np.where(u == 0.0, rng.uniform(-0.98, 0.98, d.shape[0]), u)
    return compose(d, centre + u * half)


def inside_points(region: OutlineRegion, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` random poses inside ``region``: twist-free quaternions (n, 4), or for a banded
    region orientations with a twist uniform in the band."""
    poly = region.polygon_deg
    out = np.empty((0, 3))
    while out.shape[0] < n:
        pan = np.radians(rng.uniform(poly[:, 0].min(), poly[:, 0].max(), 4 * n))
        tilt = np.radians(rng.uniform(poly[:, 1].min(), poly[:, 1].max(), 4 * n))
        d = pan_tilt_to_direction(pan, tilt)
        out = np.vstack([out, d[region.inside_directions(d)]])
    d = out[:n]
    if not isinstance(region, OutlineBandRegion):
        return compose(d, 0.0)
    centre, half = region.band(d)
    return compose(d, centre + rng.uniform(-1.0, 1.0, n) * half)


#: Spacing (deg) of the points that judge an arc of the visibility graph inside, and how far
#: outside (deg) one may lie: the outline's edges are straight in (pan, tilt), not great circles.
VISIBLE_STEP_DEG, VISIBLE_SLACK_DEG = 0.1, 0.05


class InsidePaths:
    """Shortest paths of limb directions inside ``region``'s outline: Dijkstra over the visibility
    graph of its concave corners (where a shortest path among polygonal walls bends)."""

    def __init__(self, region: OutlineRegion) -> None:
        self.region = region
        poly = np.radians(region.polygon_deg)
        prev, nxt = np.roll(poly, 1, axis=0), np.roll(poly, -1, axis=0)
        e1, e2 = poly - prev, nxt - poly
        turn = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
        area = np.sum(poly[:, 0] * nxt[:, 1] - nxt[:, 0] * poly[:, 1])
        concave = turn * np.sign(area) < 0.0  # turning against the winding
        self.corners = pan_tilt_to_direction(poly[concave, 0], poly[concave, 1])
        n = self.corners.shape[0]
        i, j = np.triu_indices(n, 1)
        self.weight = np.zeros((n + 2, n + 2))
        ok, length = self._visible(self.corners[i], self.corners[j])
        self.weight[i[ok] + 2, j[ok] + 2] = self.weight[j[ok] + 2, i[ok] + 2] = length[ok]

    def _visible(self, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Whether each arc from ``a`` to ``b`` (N, 3) lies inside, and its length (rad)."""
        from limbctl.geometry.quat import direction_angle

        h = np.maximum(direction_angle(a, b), 1e-12)[:, None]  # (N, 1)
        m = max(2, int(np.ceil(h.max(initial=0.0) / np.radians(VISIBLE_STEP_DEG))) + 1)
        t = np.linspace(0.0, 1.0, m)[None, :]  # (1, M)
        # p(t) = sin((1 - t) h) / sin h a + sin(t h) / sin h b (0 < h < pi here)
        pts = (
            np.sin((1 - t) * h)[..., None] * a[:, None, :]
            + np.sin(t * h)[..., None] * b[:, None, :]
        ) / np.sin(h)[..., None]
        pts = pts.reshape(-1, 3)
        inside = self.region.inside_directions(pts)
        out = np.flatnonzero(~inside)
        if out.size:
            inside[out] = self._wall_distance(pts[out]) <= np.radians(VISIBLE_SLACK_DEG)
        return inside.reshape(a.shape[0], m).all(axis=1), h[:, 0]

    def _wall_distance(self, d: np.ndarray) -> np.ndarray:
        """Distance (rad) of directions (N, 3) to the nearest edge, by (cos(tilt) dpan, dtilt)."""
        pan, tilt = direction_to_pan_tilt(d)
        poly = np.radians(self.region.polygon_deg)
        a, b = poly, np.roll(poly, -1, axis=0)  # (V, 2) edges a -> b
        c = np.cos(tilt)[:, None]  # (N, 1)
        px, py = (pan[:, None] - a[None, :, 0]) * c, tilt[:, None] - a[None, :, 1]
        ex, ey = (b[None, :, 0] - a[None, :, 0]) * c, b[None, :, 1] - a[None, :, 1]
        u = np.clip((px * ex + py * ey) / np.maximum(ex * ex + ey * ey, 1e-30), 0.0, 1.0)
        return np.hypot(px - u * ex, py - u * ey).min(axis=1)

    def length(self, a: np.ndarray, b: np.ndarray) -> float:
        """Length (rad) of the shortest path inside from direction ``a`` (3,) to ``b`` (3,)."""
        from scipy.sparse.csgraph import dijkstra

        n = self.corners.shape[0]
        w = self.weight.copy()
        ends = np.vstack([a, b])
        ok, length = self._visible(ends[[0, 0, 1]], np.vstack([b, ends[1:2]])[[0, 0, 0]])
        if ok[0]:
            return float(length[0])
        for row, end in enumerate(ends):
            vis, arc = self._visible(np.repeat(end[None], n, axis=0), self.corners)
            w[row, 2:][vis] = w[2:, row][vis] = arc[vis]
        return float(dijkstra(w, directed=False, indices=0)[1])
