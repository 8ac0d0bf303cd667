"""Shapes the region tests build their loops from, and the benchmarks' teachings."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

from limbctl.envelope.synthetic import EGG
from limbctl.geometry.gimbal import pan_tilt_to_direction


def benchmark(name: str):
    """benchmarks/NAME.py as a module (its outlines, truths and teachings)."""
    path = Path(__file__).resolve().parents[2] / "benchmarks" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def circle(radius_deg, n, wobble_deg=0.0, seed=0, shift_deg=0.0):
    """A counter-clockwise loop (n, 3) of unit directions at ``radius_deg`` about +x (the region
    on its left seen from outside). With ``wobble_deg`` each vertex's radius is off by up to that
    much (uniform, seeded by ``seed``); with ``shift_deg`` the loop is turned that far about +z."""
    phi = np.linspace(-np.pi, np.pi, n, endpoint=False)
    r = np.radians(radius_deg)
    if wobble_deg:
        rng = np.random.default_rng(seed)
        r = np.radians(radius_deg + wobble_deg * rng.uniform(-1.0, 1.0, n))
    loop = np.column_stack(
        [np.broadcast_to(np.cos(r), (n,)), np.sin(r) * np.cos(phi), np.sin(r) * np.sin(phi)]
    )
    if not shift_deg:
        return loop
    a = np.radians(shift_deg)
    turn = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
    return loop @ turn.T


def off_x(angle_deg, around_deg):
    """Directions ``angle_deg`` from +x at bearings ``around_deg`` about it (counter-clockwise
    seen from outside, bearing 0 towards +y): (3,) of numbers, (N, 3) of arrays (N,)."""
    a, b = np.radians(angle_deg), np.radians(around_deg)
    return np.stack([np.cos(a), np.sin(a) * np.cos(b), np.sin(a) * np.sin(b)], axis=-1)


def noisy_egg(rng):
    """The egg's loop (60, 3): every 4th vertex (about 2.5 deg apart), each moved up to 1 deg."""
    pan_tilt = np.radians(EGG[::4] + rng.uniform(-1.0, 1.0, (60, 2)) / np.sqrt(2.0))
    return pan_tilt_to_direction(pan_tilt[:, 0], pan_tilt[:, 1])


def nearest_on_edges_reference(
    d: np.ndarray, vertices: np.ndarray, edges: np.ndarray, margins: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """By brute force, for directions ``d`` (N, 3): the arc minimising ``angle - margin`` (N,)
    int, the nearest point on it (N, 3) and its angle (N,) rad (``margins`` default zero)."""
    margins = np.zeros(edges.shape[0]) if margins is None else margins
    best = np.empty_like(d)
    best_angle = np.full(d.shape[0], np.inf)
    best_key = np.full(d.shape[0], np.inf)
    best_edge = np.full(d.shape[0], -1, dtype=np.int64)
    for k, (e0, e1) in enumerate(edges):
        a, b = vertices[e0], vertices[e1]
        n = np.cross(a, b)
        n /= np.linalg.norm(n)
        foot = d - np.outer(d @ n, n)
        foot /= np.linalg.norm(foot, axis=1, keepdims=True)
        within = (foot @ np.cross(n, a) >= 0) & (foot @ np.cross(b, n) >= 0)
        pa = np.arccos(np.clip(d @ a, -1, 1))
        pb = np.arccos(np.clip(d @ b, -1, 1))
        end = np.where((pa <= pb)[:, None], a, b)
        point = np.where(within[:, None], foot, end)
        ang = np.arctan2(np.linalg.norm(np.cross(d, point), axis=1), np.sum(d * point, axis=1))
        better = ang - margins[k] < best_key
        best[better] = point[better]
        best_angle[better] = ang[better]
        best_key[better] = ang[better] - margins[k]
        best_edge[better] = k
    return best_edge, best, best_angle
