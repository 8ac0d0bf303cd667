"""Closed loops of directions (M, 3) on S^2, region on the left: lengths, areas, stations along
them, and what is near each (radians)."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree


def chord(angle: float) -> float:
    """Chord length of an angle (rad) on the unit sphere: ``2 sin(angle / 2)``."""
    return 2.0 * np.sin(0.5 * angle)


def loops_to_edges(loops: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Stack loops into vertices (V, 3) and directed edges (V, 2) joining consecutive points."""
    vertices = np.vstack(loops)
    idx = []
    start = 0
    for lp in loops:
        i = np.arange(start, start + lp.shape[0])
        idx.append(np.column_stack([i, np.roll(i, -1)]))
        start += lp.shape[0]
    return vertices, np.vstack(idx)


def loop_area(loop: np.ndarray) -> float:
    """Signed area (sr) enclosed by a loop (M, 3): positive when the region is on its left."""
    c = loop.mean(axis=0)
    c /= np.linalg.norm(c)
    a = loop
    b = np.roll(loop, -1, axis=0)
    det = np.cross(a, b) @ c
    den = 1.0 + a @ c + np.sum(a * b, axis=1) + b @ c
    return float(np.sum(2.0 * np.arctan2(det, den)))


def vertex_turns(loop: np.ndarray) -> np.ndarray:
    """Signed turn (M,) rad of a closed loop (M, 3) per vertex, positive (convex) to the left."""
    prev = np.roll(loop, 1, axis=0)
    nxt = np.roll(loop, -1, axis=0)
    heading = -(prev - np.einsum("ij,ij->i", prev, loop)[:, None] * loop)
    out = nxt - np.einsum("ij,ij->i", nxt, loop)[:, None] * loop
    det = np.einsum("ij,ij->i", loop, np.cross(heading, out))
    return np.arctan2(det, np.einsum("ij,ij->i", heading, out))


def loop_length(loop: np.ndarray) -> float:
    """Length (rad) of a closed loop (M, 3)."""
    nxt = np.roll(loop, -1, axis=0)
    return float(np.arccos(np.clip(np.einsum("ij,ij->i", loop, nxt), -1.0, 1.0)).sum())


def resample_loop(loop: np.ndarray, step: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stations (K, 3) every ~``step`` (rad) along a closed loop (M, 3), at least 8, with their
    arc-length positions (K,) and the loop vertices' (M,), from vertex 0."""
    nxt = np.roll(loop, -1, axis=0)
    seg = np.arccos(np.clip(np.einsum("ij,ij->i", loop, nxt), -1.0, 1.0))
    at_vertex = np.concatenate([[0.0], np.cumsum(seg)[:-1]])
    total = float(seg.sum())
    k = max(8, int(np.ceil(total / step)))
    s = np.arange(k) * total / k
    e = np.clip(np.searchsorted(at_vertex, s, side="right") - 1, 0, loop.shape[0] - 1)
    t = (s - at_vertex[e]) / np.maximum(seg[e], 1e-15)
    # slerp along arc e: (sin((1 - t) om) a + sin(t om) b) / sin(om)
    om = seg[e]
    so = np.where(np.sin(om) < 1e-12, 1.0, np.sin(om))
    x = (np.sin((1.0 - t) * om) / so)[:, None] * loop[e] + (np.sin(t * om) / so)[:, None] * nxt[e]
    small = np.sin(om) < 1e-12
    x[small] = loop[e[small]]
    return x / np.linalg.norm(x, axis=1, keepdims=True), s, at_vertex


def station_positions(curve: np.ndarray) -> tuple[np.ndarray, float]:
    """Arc-length positions (K,) rad of a closed curve's evenly spaced stations, and its length."""
    total = loop_length(curve)
    return np.arange(curve.shape[0]) * total / curve.shape[0], total


def loop_gaps(a: np.ndarray, b: np.ndarray, total: float) -> np.ndarray:
    """Distances (A, B) along a closed loop of length ``total`` between positions ``a`` (A,)
    and ``b`` (B,): ``min(|a - b|, total - |a - b|)``."""
    gap = np.abs(a[:, None] - b[None, :])
    return np.minimum(gap, total - gap)


def signed_offset(a: np.ndarray, b: np.ndarray, total: float) -> np.ndarray:
    """Signed along-loop offset ``a - b`` (rad) on a closed loop of length ``total``, in
    ``[-total / 2, total / 2)``."""
    return (a - b + 0.5 * total) % total - 0.5 * total


def smooth_along(values: np.ndarray, s: np.ndarray, total: float, width: float) -> np.ndarray:
    """Gaussian smoothing (width ``width`` rad) of per-station ``values`` (K,) along the loop."""
    gap = loop_gaps(s, s, total)
    g = np.exp(-0.5 * (gap / width) ** 2)
    return (g @ values) / g.sum(axis=1)


def lift(deficit: np.ndarray, s: np.ndarray, total: float, width: float) -> np.ndarray:
    """Smooth bumps (K,) that make up every positive ``deficit`` (K,) at its station:
    ``max_j deficit_j exp(-(s_k - s_j)^2 / (2 width^2))`` over stations with a deficit."""
    short = np.flatnonzero(deficit > 0.0)
    if short.size == 0:
        return np.zeros(s.shape[0])
    gap = loop_gaps(s, s[short], total)
    return np.max(deficit[short][None, :] * np.exp(-0.5 * (gap / width) ** 2), axis=1)


def nearest_station(data: np.ndarray, stations: np.ndarray) -> np.ndarray:
    """Index (N,) of the station (K, 3) nearest to each direction of ``data`` (N, 3)."""
    return cKDTree(stations).query(data)[1]


class StationBuckets:
    """Items grouped by the station (or arc) they belong to, for reading windows of stations:
    ``owner`` (N,) int, the station of each item (none outside ``0 .. stations - 1``) of K
    ``stations``."""

    def __init__(self, owner: np.ndarray, stations: int) -> None:
        self.stations = int(stations)
        self.order = np.argsort(owner, kind="stable")
        self.bounds = np.searchsorted(owner[self.order], np.arange(self.stations + 1))

    def rows(self, stations: np.ndarray) -> np.ndarray:
        """Items (int) of the given stations, in the order given, each in its original order."""
        return np.concatenate([self.order[self.bounds[j] : self.bounds[j + 1]] for j in stations])

    def around(self, i: int, reach: int) -> np.ndarray:
        """Items of the stations ``i - reach .. i + reach``, read circularly."""
        return self.rows(np.arange(i - reach, i + reach + 1) % self.stations)
