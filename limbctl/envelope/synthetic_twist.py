"""Synthetic shoulder-like regions of full orientations, for tests and benchmarks of twist: a
swing outline in (pan, tilt) degrees with a twist band narrowing as the limb rises."""

from __future__ import annotations

import math

import numpy as np

from limbctl.envelope.synthetic import PolygonRegion, _cap_directions
from limbctl.geometry.gimbal import direction_to_pan_tilt, pan_tilt_to_direction
from limbctl.geometry.quat import rotate, swing_from_direction
from limbctl.geometry.twist import compose, decompose, wrap
from limbctl.region.twist_kernels import TWIST_TOLERANCE

#: A shoulder's swing outline in (pan, tilt) degrees: a dent between two raised lobes, away from -x.
SHOULDER = np.array(
    [[-30.0, -35.0], [20.0, -40.0], [70.0, -35.0], [100.0, -15.0], [105.0, 20.0], [85.0, 50.0],
     [50.0, 70.0], [25.0, 45.0], [0.0, 68.0], [-25.0, 55.0], [-35.0, 20.0]]
)  # fmt: skip
#: Scatter (deg, one sigma) short of the true stop with which a hand reaches a twist stop.
STOP_SCATTER_DEG = 0.2


class ShoulderRegion:
    """A swing outline with a twist band narrowing as the limb rises and drifting with the swing.

    Parameters
    ----------
    polygon_deg : array_like (V, 2)
        The swing outline in (pan, tilt) degrees.
    half_low_deg, half_high_deg : float
        Band half-widths at the outline's lowest and highest tilt.
    centre_deg, centre_pan, centre_tilt : float
        Band centre ``c0 + c_pan pan + c_tilt tilt`` (deg, deg/deg).
    """

    def __init__(
        self,
        polygon_deg: np.ndarray = SHOULDER,
        half_low_deg: float = 75.0,
        half_high_deg: float = 25.0,
        centre_deg: float = 10.0,
        centre_pan: float = 0.25,
        centre_tilt: float = -0.2,
    ) -> None:
        self.swing = PolygonRegion(polygon_deg, boundary_step_deg=0.05)
        tilts = np.asarray(polygon_deg, dtype=np.float64)[:, 1]
        self.tilt_range = (float(tilts.min()), float(tilts.max()))
        self.half_deg = (float(half_low_deg), float(half_high_deg))
        self.centre = (float(centre_deg), float(centre_pan), float(centre_tilt))

    def band(self, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Centre and half-width (rad) of the band over directions ``d`` (N, 3)."""
        pan, tilt = direction_to_pan_tilt(np.atleast_2d(d))
        pan_deg, tilt_deg = np.degrees(pan), np.degrees(tilt)
        (t0, t1), (h0, h1) = self.tilt_range, self.half_deg
        # h = h_low + (h_high - h_low)(tilt - tilt_low) / (tilt_high - tilt_low), within 5..175
        h = np.clip(h0 + (h1 - h0) * (tilt_deg - t0) / (t1 - t0), 5.0, 175.0)
        c0, cp, ct = self.centre
        # c = c0 + c_pan pan + c_tilt tilt
        return np.radians(c0 + cp * pan_deg + ct * tilt_deg), np.radians(h)

    def contains(self, q: np.ndarray) -> np.ndarray:
        """(N,) bool: direction inside the outline and twist inside the band there (+-1e-15)."""
        d, tau = decompose(np.atleast_2d(q))
        c, h = self.band(d)
        return self.swing.contains(d) & (np.abs(wrap(tau - c)) <= h + TWIST_TOLERANCE)

    def _inside_directions(self, n: int, rng: np.random.Generator) -> np.ndarray:
        out = np.empty((0, 3))
        while out.shape[0] < n:
            cand = _cap_directions(4 * n, self.swing.axis, self.swing.radius, rng)
            out = np.vstack([out, cand[self.swing.contains(cand)]])
        return out[:n]

    def _edge_directions(self, n: int, rng: np.random.Generator, inset_deg: float) -> np.ndarray:
        """``n`` directions within ``inset_deg`` inside the outline, along all of it."""
        out = np.empty((0, 3))
        b = self.swing.boundary
        while out.shape[0] < n:
            p = b[rng.integers(0, b.shape[0], 4 * n)]
            # a small random step off the edge, kept when it lands inside within inset_deg
            step = _cap_directions(4 * n, np.array([1.0, 0.0, 0.0]), math.radians(inset_deg), rng)
            cand = rotate(swing_from_direction(p), step)  # the step carried from +x onto p
            depth = self.swing.depth(cand)
            out = np.vstack([out, cand[(depth >= 0.0) & (depth <= math.radians(inset_deg))]])
        return out[:n]

    def teaching(
        self, n_uniform: int, n_edge: int, n_stops: int, rng: np.random.Generator
    ) -> np.ndarray:
        """Taught orientations (N, 4): uniform, within 1 deg of the swing edge, at twist stops."""
        d_u = self._inside_directions(n_uniform, rng)
        d_e = self._edge_directions(n_edge, rng, 1.0)
        d_s = np.vstack(
            [
                self._edge_directions(n_stops // 2, rng, 1.0),
                self._inside_directions(n_stops - n_stops // 2, rng),
            ]
        )
        parts = []
        for d in (d_u, d_e):
            c, h = self.band(d)
            parts.append(compose(d, c + h * rng.uniform(-1.0, 1.0, d.shape[0])))
        c, h = self.band(d_s)
        side = rng.choice([-1.0, 1.0], d_s.shape[0])
        short = np.abs(rng.normal(0.0, math.radians(STOP_SCATTER_DEG), d_s.shape[0]))
        parts.append(compose(d_s, c + side * (h - short)))
        return np.vstack(parts)

    def boundary(self, step_deg: float) -> np.ndarray:
        """Orientations (M, 4) on the region's boundary about ``step_deg`` apart."""
        (p0, p1), (t0, t1) = (
            (np.degrees(self.swing.polygon[:, k].min()), np.degrees(self.swing.polygon[:, k].max()))
            for k in (0, 1)
        )
        parts = []
        tilt = np.arange(t0, t1 + step_deg, step_deg)
        for t in tilt:
            # pan spacing widened by 1 / cos(tilt) so the lattice is even on the sphere
            dp = step_deg / max(math.cos(math.radians(t)), 0.05)
            pan = np.arange(p0, p1 + dp, dp)
            d = pan_tilt_to_direction(np.radians(pan), np.full(pan.shape, math.radians(t)))
            d = d[self.swing.contains(d)]
            c, h = self.band(d)
            parts += [compose(d, c - h), compose(d, c + h)]
        edge = self.swing.boundary[:: max(1, int(round(step_deg / 0.05)))]
        c, h = self.band(edge)
        k = np.ceil(2.0 * h / math.radians(step_deg)).astype(int) + 1
        rows = np.repeat(np.arange(edge.shape[0]), k)
        frac = np.concatenate([np.linspace(-1.0, 1.0, m) for m in k])
        parts.append(compose(edge[rows], c[rows] + h[rows] * frac))
        return np.vstack(parts)

    def clamp(self, q: np.ndarray) -> np.ndarray:
        """The engines' two-step answer (N, 4): nearest outline direction, then twist clamped."""
        d, tau = decompose(np.atleast_2d(q))
        d2 = self.swing.ideal(d)
        c, h = self.band(d2)
        e = wrap(tau - c)
        return compose(d2, c + np.clip(e, -h, h))


class BandRegion(ShoulderRegion):
    """A swing outline ``polygon_deg`` (V, 2) with any twist band (curved, across +-180 deg):
    ``band_deg(pan_deg (N,), tilt_deg (N,)) -> (centre_deg (N,), half_deg (N,))``, half-widths
    in (0, 180)."""

    def __init__(self, polygon_deg: np.ndarray, band_deg) -> None:
        super().__init__(polygon_deg)
        self.band_deg = band_deg

    def band(self, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Centre and half-width (rad) of the band over directions ``d`` (N, 3)."""
        pan, tilt = direction_to_pan_tilt(np.atleast_2d(d))
        c, h = self.band_deg(np.degrees(pan), np.degrees(tilt))
        return np.radians(c), np.radians(h)
