"""Which edge the gate uses: the smooth edge, the traced edge, or the data-supported loops.

The data-supported loops (:mod:`limbctl.envelope.region_shape`) run through taught samples and
are always safe, but sit inside a sparsely taught edge and have corners wherever a sample
fell. Two learned edges can replace them (:func:`learned_edge`), tried in this order:

1. *smooth* (:func:`limbctl.envelope.edge_fit.fit_edge`): local small circles over one window
   for the whole loop, moved out by the outermost samples. Tried when the data hold no bay
   (:func:`limbctl.envelope.edge_fit.protected`) and kept only when the window follows the
   loop's shape at every station (``residual_ratio`` at most ``RESOLVED_RATIO``). Best on
   round regions (a cone's edge is one circle).
2. *traced* (:func:`limbctl.envelope.edge_trace.trace_edge`): a curve walked out to the
   edge station by station; follows eggs, kidneys and bays, but only where the edge is taught
   densely enough (``TRACE_MAX_WINDOW_DEG``).

Either is kept only when, over all loops together, no two arcs cross, every taught direction
the supported region holds stays inside (up to ``MISS_FRACTION`` of them lying more than
``MISS_TOLERANCE_DEG`` outside), and every stretch it adds beyond the supported region is one
the local sampling density could leave empty by chance (``unexplained_gap`` at most
``GAP_EXPECTED``). Otherwise the gate keeps the supported loops.
"""

from __future__ import annotations

import numpy as np

from limbctl.envelope import edge_fit as ef
from limbctl.envelope.boundary import DirectionMesh
from limbctl.envelope.edge_trace import trace_edge
from limbctl.quat import direction_angle


def learned_edge(
    loops: list[np.ndarray],
    data: np.ndarray,
    supported: DirectionMesh,
    max_offset: float,
) -> tuple[str, list[np.ndarray]] | None:
    """The learned edge for all ``loops`` (each (M, 3)) as ``(kind, edges)``, or None.

    ``kind`` is ``"smooth"`` or ``"traced"``; ``data`` (N, 3) are the taught directions,
    ``supported`` the data-supported region (a :class:`DirectionMesh` over the same loops with
    their learned margins), ``max_offset`` (rad) caps how far an edge moves past its loop.
    None when the data refuse both (see the module docstring).
    """
    smooth = smooth_edges(loops, data, max_offset)
    if smooth is not None and agrees(smooth, data, supported):
        return "smooth", smooth
    traced = [trace_edge(loop, data, max_offset) for loop in loops]
    if all(edge is not None for edge in traced) and agrees(traced, data, supported):
        return "traced", traced
    return None


def smooth_edges(
    loops: list[np.ndarray], data: np.ndarray, max_offset: float
) -> list[np.ndarray] | None:
    """Smooth edges for all ``loops``, or None where a bay or an unresolved shape refuses them."""
    edges = []
    for loop in loops:
        _, s, at_vertex = ef.resample_loop(loop, np.radians(ef.STEP_DEG))
        if ef.protected(loop, data, s, at_vertex).any():
            return None
        edge, ratio = ef.fit_edge(loop, data, max_offset)
        if ratio > ef.RESOLVED_RATIO:
            return None
        edges.append(edge)
    return edges


def agrees(edges: list[np.ndarray], data: np.ndarray, supported: DirectionMesh) -> bool:
    """Whether learned ``edges`` agree with the data: simple, holding the taught samples, and
    adding no stretch beyond the ``supported`` region the sampling cannot explain."""
    if ef.arcs_cross(edges):
        return False
    if any(ef.unexplained_gap(edge, data, supported) > ef.GAP_EXPECTED for edge in edges):
        return False
    learned = DirectionMesh.from_loops(edges, 0.0)
    before = supported.contains(data)
    missed = before & ~learned.contains(data)
    # a sample a hair outside (the edge estimate's own noise) is not a cut corner
    far = direction_angle(learned.project(data[missed]), data[missed]) > np.radians(
        ef.MISS_TOLERANCE_DEG
    )
    return int(far.sum()) <= ef.MISS_FRACTION * max(1, int(before.sum()))
