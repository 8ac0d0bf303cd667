"""Numpy twins of the band's fitting kernels (:mod:`limbctl.region.twist_fit_kernels`): plain
loops over all candidates at once, the tests' reference."""

from __future__ import annotations

import numpy as np


def upper_hull_reference(px: np.ndarray, py: np.ndarray, t: np.ndarray, top: int) -> float:
    """Numpy twin of :func:`limbctl.region.twist_fit_kernels.upper_hull` (all triangles at once)."""
    order = np.argsort(-t, kind="stable")[:top]
    a, b, c = np.array(
        [
            (i, j, k)
            for i in range(len(order))
            for j in range(i + 1, len(order))
            for k in range(j + 1, len(order))
        ]
    ).T
    ia, ib, ic = order[a], order[b], order[c]
    cab = px[ia] * py[ib] - py[ia] * px[ib]
    cbc = px[ib] * py[ic] - py[ib] * px[ic]
    cca = px[ic] * py[ia] - py[ic] * px[ia]
    area = cab + cbc + cca
    ok = area != 0
    la, lb, lc = (np.where(ok, x / np.where(ok, area, 1.0), -1.0) for x in (cbc, cca, cab))
    held = ok & (la >= 0) & (lb >= 0) & (lc >= 0)
    if not held.any():
        return float("nan")
    return float(np.max((la * t[ia] + lb * t[ib] + lc * t[ic])[held]))
