"""Regions of (pan, tilt) a scripted hand may move the simulated limb through (degrees): a
polygon or a cone (docs/simulator.md); bad input raises ValueError naming the source."""

from __future__ import annotations

import math

import numpy as np

#: Grid step (deg) of the search for a polygon's deepest point.
CENTER_GRID_STEP_DEG = 1.0
#: :func:`deepen`'s gradient steps, difference step (deg) and tolerance (deg): the distance is
#: piecewise linear or smooth, so a few rounds settle even a corner.
DEEPEN_ROUNDS = 4
DEEPEN_STEP_DEG = 0.05
DEEPEN_TOLERANCE_DEG = 0.02


def _number(value: object, source: str, what: str) -> float:
    """``value`` as a finite float, or a ValueError naming ``source`` and ``what``."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"{source}: {what} must be a number, got {value!r}")
    number = float(value)
    if not math.isfinite(number):
        raise ValueError(f"{source}: {what} must be finite, got {value!r}")
    return number


def _segments_cross(p1, p2, p3, p4) -> bool:
    """True when closed segments p1-p2 and p3-p4 touch or cross (2-D, tuples of floats)."""

    def orient(a, b, c) -> float:
        # z of (b - a) x (c - a): > 0 when a, b, c turn counter-clockwise
        return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])

    def on_segment(a, b, c) -> bool:
        return min(a[0], b[0]) <= c[0] <= max(a[0], b[0]) and min(a[1], b[1]) <= c[1] <= max(
            a[1], b[1]
        )

    d1, d2 = orient(p3, p4, p1), orient(p3, p4, p2)
    d3, d4 = orient(p1, p2, p3), orient(p1, p2, p4)
    if ((d1 > 0) != (d2 > 0)) and ((d3 > 0) != (d4 > 0)) and 0 not in (d1, d2, d3, d4):
        return True
    return (
        (d1 == 0 and on_segment(p3, p4, p1))
        or (d2 == 0 and on_segment(p3, p4, p2))
        or (d3 == 0 and on_segment(p1, p2, p3))
        or (d4 == 0 and on_segment(p1, p2, p4))
    )


class _Shape:
    """What both shapes answer alike from their ``edge_distance_deg``."""

    def contains(self, pan_deg: float, tilt_deg: float) -> bool:
        """True when the pose lies inside the region or on its boundary."""
        return bool(self.edge_distance_deg(pan_deg, tilt_deg) >= 0.0)

    def contains_many(self, pan_deg: np.ndarray, tilt_deg: np.ndarray) -> np.ndarray:
        """Vectorised :meth:`contains` for arrays (M,) -> (M,) bool."""
        return self.edge_distance_deg(pan_deg, tilt_deg) >= 0.0


class PolygonRegion(_Shape):
    """A simple polygon in the (pan_deg, tilt_deg) plane (``source`` names it in errors).

    Parameters
    ----------
    vertices_deg : array_like, shape (N, 3 <= N)
        Corner poses ``[pan_deg, tilt_deg]`` in order around the polygon (either sense; a last
        vertex equal to the first is dropped).
    """

    kind = "polygon"

    def __init__(self, vertices_deg, source: str = "<region>") -> None:
        if not isinstance(vertices_deg, (list, tuple)):
            raise ValueError(f"{source}: region.polygon must be a list of [pan_deg, tilt_deg]")
        points = []
        for k, vertex in enumerate(vertices_deg):
            if not isinstance(vertex, (list, tuple)) or len(vertex) != 2:
                raise ValueError(
                    f"{source}: region.polygon[{k}] must be [pan_deg, tilt_deg], got {vertex!r}"
                )
            points.append(tuple(_number(v, source, f"region.polygon[{k}]") for v in vertex))
        if len(points) >= 2 and points[0] == points[-1]:
            points.pop()
        if len(points) < 3:
            raise ValueError(
                f"{source}: region.polygon needs at least 3 vertices, got {len(points)}"
            )
        n = len(points)
        for k in range(n):
            if points[k] == points[(k + 1) % n]:
                raise ValueError(f"{source}: region.polygon[{k}] repeats the next vertex")
        for i in range(n):
            for j in range(i + 2, n):
                if i == 0 and j == n - 1:
                    continue  # adjacent through the closing edge
                if _segments_cross(points[i], points[i + 1], points[j], points[(j + 1) % n]):
                    raise ValueError(
                        f"{source}: region.polygon crosses itself (edge {i}-{i + 1} meets edge "
                        f"{j}-{(j + 1) % n}); list the vertices in order around the region"
                    )
        vertices = np.array(points, dtype=np.float64)
        # shoelace: area = 1/2 sum(x_k y_{k+1} - x_{k+1} y_k), > 0 counter-clockwise
        following = np.roll(vertices, -1, axis=0)
        signed_area = 0.5 * float(
            np.sum(vertices[:, 0] * following[:, 1] - following[:, 0] * vertices[:, 1])
        )
        if abs(signed_area) < 1e-9:
            raise ValueError(f"{source}: region.polygon has zero area")
        if signed_area < 0:
            vertices = vertices[::-1].copy()
        self.vertices_deg = vertices
        self.area_deg2 = abs(signed_area)
        self._starts = vertices
        self._deltas = np.roll(vertices, -1, axis=0) - vertices
        self._lengths = np.hypot(self._deltas[:, 0], self._deltas[:, 1])
        # counter-clockwise polygon: the interior is left of each edge, normal = (-dy, dx) / |d|
        self._inward = np.stack([-self._deltas[:, 1], self._deltas[:, 0]], axis=1)
        self._inward /= self._lengths[:, None]
        self._arc_start = np.concatenate([[0.0], np.cumsum(self._lengths)[:-1]])
        self.perimeter_deg = float(np.sum(self._lengths))
        lo, hi = vertices.min(axis=0), vertices.max(axis=0)
        self.bbox_deg = (float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1]))
        pan_grid, tilt_grid = np.meshgrid(
            np.arange(lo[0], hi[0] + CENTER_GRID_STEP_DEG, CENTER_GRID_STEP_DEG),
            np.arange(lo[1], hi[1] + CENTER_GRID_STEP_DEG, CENTER_GRID_STEP_DEG),
        )
        depth = self.edge_distance_deg(pan_grid.ravel(), tilt_grid.ravel())
        deepest = int(np.argmax(depth))
        self.center_deg = (float(pan_grid.ravel()[deepest]), float(tilt_grid.ravel()[deepest]))
        self.depth_max_deg = float(depth[deepest])

    def _nearest(self, pan_deg, tilt_deg):
        """Input shape, points (M, 1, 2), nearest fractions (M, N) along edges, gaps (M, N, 2)."""
        pan = np.asarray(pan_deg, dtype=np.float64)
        tilt = np.asarray(tilt_deg, dtype=np.float64)
        points = np.stack([pan.ravel(), tilt.ravel()], axis=1)[:, None, :]
        offset = points - self._starts[None]  # (M, N, 2)
        # closest point on edge k: a_k + s d_k, s = clip((p - a_k).d_k / |d_k|^2, 0, 1)
        s = np.clip(np.sum(offset * self._deltas, axis=2) / self._lengths**2, 0.0, 1.0)
        return pan.shape, points, s, offset - s[:, :, None] * self._deltas

    def edge_distance_deg(self, pan_deg, tilt_deg) -> np.ndarray:
        """Signed distance (deg, shape of the inputs) to the boundary: > 0 inside, < 0 outside."""
        shape, points, _, gap = self._nearest(pan_deg, tilt_deg)
        distance = np.sqrt(np.min(np.sum(gap * gap, axis=2), axis=1))
        # even-odd rule: count edges whose tilt span straddles the point and lie right of it
        y0 = self._starts[:, 1][None]
        y1 = (self._starts[:, 1] + self._deltas[:, 1])[None]
        py, px = points[:, :, 1], points[:, :, 0]
        straddles = (y0 > py) != (y1 > py)
        with np.errstate(divide="ignore", invalid="ignore"):
            x_cross = self._starts[:, 0][None] + (py - y0) * self._deltas[:, 0][None] / (y1 - y0)
        inside = (np.sum(straddles & (px < x_cross), axis=1) % 2) == 1
        return np.where(inside | (distance == 0.0), distance, -distance).reshape(shape)

    def boundary_fraction(self, pan_deg, tilt_deg) -> np.ndarray:
        """Perimeter fraction in [0, 1) (inputs' shape) of the edge point nearest each pose."""
        shape, points, s, gap = self._nearest(pan_deg, tilt_deg)
        nearest = np.argmin(np.sum(gap * gap, axis=2), axis=1)
        rows = np.arange(points.shape[0])
        arc = self._arc_start[nearest] + s[rows, nearest] * self._lengths[nearest]
        return (arc / self.perimeter_deg % 1.0).reshape(shape)

    def boundary_point(self, u: float, inset_deg: float) -> tuple[float, float]:
        """The edge point a fraction ``u`` (wraps) round, moved ``inset_deg`` inward."""
        arc = (u % 1.0) * self.perimeter_deg
        k = int(np.searchsorted(self._arc_start, arc, side="right")) - 1
        s = (arc - self._arc_start[k]) / self._lengths[k]
        point = self._starts[k] + s * self._deltas[k] + inset_deg * self._inward[k]
        return float(point[0]), float(point[1])


class ConeRegion(_Shape):
    """Directions within ``half_angle_deg`` of +x: ``acos(cos t cos p) <= half_angle``."""

    kind = "cone"

    def __init__(self, half_angle_deg: float, source: str = "<region>") -> None:
        half_angle = _number(half_angle_deg, source, "region.cone.half_angle_deg")
        if not 0.0 < half_angle < 180.0:
            raise ValueError(
                f"{source}: region.cone.half_angle_deg must lie in (0, 180), got {half_angle}"
            )
        self.half_angle_deg = half_angle
        self.center_deg = (0.0, 0.0)
        self.depth_max_deg = half_angle
        # the boundary circle on the unit sphere has radius sin(A): perimeter 360 sin(A) deg
        self.perimeter_deg = 360.0 * math.sin(math.radians(half_angle))
        self.bbox_deg = (-half_angle, half_angle, -min(half_angle, 90.0), min(half_angle, 90.0))

    def edge_distance_deg(self, pan_deg, tilt_deg) -> np.ndarray:
        """Angular margin (deg, shape of the inputs) to the cone: A - angle(d, +x), > 0 inside."""
        pan = np.radians(np.asarray(pan_deg, dtype=np.float64))
        tilt = np.radians(np.asarray(tilt_deg, dtype=np.float64))
        # angle between d and +x: acos(d . x) = acos(cos t cos p)
        angle = np.degrees(np.arccos(np.clip(np.cos(tilt) * np.cos(pan), -1.0, 1.0)))
        return self.half_angle_deg - angle

    def boundary_fraction(self, pan_deg, tilt_deg) -> np.ndarray:
        """Azimuth about +x of each pose as a fraction of a turn in [0, 1) (inputs' shape)."""
        pan = np.radians(np.asarray(pan_deg, dtype=np.float64))
        tilt = np.radians(np.asarray(tilt_deg, dtype=np.float64))
        # phi = atan2(d_z, d_y) with d_y = cos t sin p, d_z = sin t
        phi = np.arctan2(np.sin(tilt), np.cos(tilt) * np.sin(pan))
        return (phi / (2.0 * math.pi)) % 1.0

    def boundary_point(self, u: float, inset_deg: float) -> tuple[float, float]:
        """Pose ``inset_deg`` inside the cone's edge, at azimuth ``2 pi u`` about +x."""
        phi = 2.0 * math.pi * (u % 1.0)
        a = math.radians(max(self.half_angle_deg - inset_deg, 0.0))
        # d = (cos a, sin a cos phi, sin a sin phi): pan = atan2(d_y, d_x), tilt = asin(d_z)
        pan = math.atan2(math.sin(a) * math.cos(phi), math.cos(a))
        tilt = math.asin(math.sin(a) * math.sin(phi))
        return math.degrees(pan), math.degrees(tilt)


Region = PolygonRegion | ConeRegion


def deepen(region: Region, points_deg: np.ndarray, depth_deg: np.ndarray) -> np.ndarray:
    """(pan_deg, tilt_deg) points (M, 2) moved inward along the edge distance's gradient until
    each is ``depth_deg`` (M,) deg inside ``region``: a new (M, 2) array, points already deep
    enough unchanged."""
    points = np.array(points_deg, dtype=np.float64)
    h = DEEPEN_STEP_DEG
    for _ in range(DEEPEN_ROUNDS):
        short = depth_deg - region.edge_distance_deg(points[:, 0], points[:, 1])
        if np.all(short <= DEEPEN_TOLERANCE_DEG):
            break
        # inward = grad(edge distance) / |grad|, by central differences of step h
        grad = np.stack(
            [
                region.edge_distance_deg(points[:, 0] + h, points[:, 1])
                - region.edge_distance_deg(points[:, 0] - h, points[:, 1]),
                region.edge_distance_deg(points[:, 0], points[:, 1] + h)
                - region.edge_distance_deg(points[:, 0], points[:, 1] - h),
            ],
            axis=1,
        )
        norm = np.maximum(np.hypot(grad[:, 0], grad[:, 1]), 1e-12)
        move = np.where(short > DEEPEN_TOLERANCE_DEG, short, 0.0)
        points += grad / norm[:, None] * move[:, None]
    return points


def grid_inside(region: Region, step_deg: float, min_depth_deg: float) -> np.ndarray:
    """(pan_deg, tilt_deg), shape (M, 2), of a ``step_deg`` grid at least ``min_depth_deg`` in."""
    pan_lo, pan_hi, tilt_lo, tilt_hi = region.bbox_deg
    pan, tilt = (
        a.ravel()
        for a in np.meshgrid(
            np.arange(pan_lo, pan_hi + step_deg, step_deg),
            np.arange(tilt_lo, tilt_hi + step_deg, step_deg),
        )
    )
    keep = region.edge_distance_deg(pan, tilt) >= min_depth_deg
    return np.stack([pan[keep], tilt[keep]], axis=1)


def region_from_mapping(spec: object, source: str = "<region>") -> Region:
    """Build a region from the mapping under a REGION.yaml's ``region:`` key (ValueError naming
    ``source`` and what is wrong with the shape or its numbers)."""
    if not isinstance(spec, dict):
        raise ValueError(
            f"{source}: 'region' must be a mapping such as {{polygon: [[pan, tilt], ...]}} or "
            f"{{cone: {{half_angle_deg: A}}}}, got {spec!r}"
        )
    shapes = sorted(set(spec) & {"polygon", "cone"})
    unknown = sorted(set(spec) - {"polygon", "cone"}, key=str)
    if unknown:
        raise ValueError(f"{source}: unknown key(s) {unknown} under 'region'; use polygon or cone")
    if len(shapes) != 1:
        raise ValueError(f"{source}: 'region' needs exactly one of polygon or cone, got {shapes}")
    if shapes[0] == "polygon":
        return PolygonRegion(spec["polygon"], source)
    cone = spec["cone"]
    if not isinstance(cone, dict) or "half_angle_deg" not in cone:
        raise ValueError(f"{source}: region.cone must be {{half_angle_deg: A}}, got {cone!r}")
    extra = sorted(set(cone) - {"half_angle_deg"}, key=str)
    if extra:
        raise ValueError(f"{source}: unknown key(s) {extra} under region.cone")
    return ConeRegion(cone["half_angle_deg"], source)
