"""Shapes the region tests build their loops from."""

from __future__ import annotations

import numpy as np


def circle(radius_deg: float, n: int) -> np.ndarray:
    """A counter-clockwise loop (n, 3) of unit directions at ``radius_deg`` about +x."""
    phi = np.linspace(-np.pi, np.pi, n, endpoint=False)
    r = np.radians(radius_deg)
    return np.column_stack(
        [np.full(n, np.cos(r)), np.sin(r) * np.cos(phi), np.sin(r) * np.sin(phi)]
    )
