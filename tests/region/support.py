"""Shapes the region tests build their loops from."""

from __future__ import annotations

import numpy as np


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
