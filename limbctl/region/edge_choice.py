"""Which edge the gate uses: the smooth edge, the traced edge, or the data-supported loops.

The data-supported loops (:mod:`limbctl.region.shape`) run through taught samples and
are always safe, but sit inside a sparsely taught edge and have corners wherever a sample
fell. Two learned edges can replace them (:func:`learned_edge`):

1. *smooth* (:func:`limbctl.region.edge_smooth.fit_edge`): local small circles over one window
   for the whole loop, moved out by the outermost samples. Tried when the data hold no bay
   (:func:`limbctl.region.edge_smooth.protected`) and kept only when the window follows the
   loop's shape at every station (``residual_ratio`` at most ``RESOLVED_RATIO``). Best on
   round regions (a cone's edge is one circle).
2. *traced* (:func:`limbctl.region.edge_traced.trace_edge`): a curve walked out to the
   edge station by station; follows eggs, kidneys and bays, but only where the edge is taught
   densely enough (``TRACE_MAX_WINDOW_DEG``).

Either is kept only when, over all loops together, no two arcs cross, every taught direction
the supported region holds stays inside (up to ``MISS_FRACTION`` of them lying more than
``MISS_TOLERANCE_DEG`` outside), and every stretch it adds beyond the supported region is one
the local sampling density could leave empty by chance (``unexplained_gap`` at most
``GAP_EXPECTED``). Where both pass, the smooth edge (fewer free parameters, the better fit
when it is right) is kept only if it reaches nowhere more than ``CONFIRM_DEG`` beyond the
traced edge: on an egg whose tip the window cannot follow, the smooth edge passed every other
check on one teaching seed of five, reached 2.0 deg beyond the traced edge and put 24 % of
corrected outputs more than 1 deg outside the true region; on cones of 20 deg (1000 samples,
5 seeds) it reaches 0.4-0.6 deg beyond. Where neither passes, the gate keeps the supported
loops.
"""

from __future__ import annotations

import numpy as np

from limbctl.geometry.quat import direction_angle
from limbctl.region import edge_smooth as ef
from limbctl.region.edge_traced import trace_edge
from limbctl.region.mesh import DirectionMesh

#: The smooth edge may reach at most this far (deg) beyond the traced edge, where both exist.
CONFIRM_DEG = 1.0


def learned_edge(
    loops: list[np.ndarray],
    data: np.ndarray,
    supported: DirectionMesh,
    max_offset: float,
) -> tuple[str, DirectionMesh] | None:
    """The learned edge for all ``loops`` (each (M, 3)) as ``(kind, region)``, or None.

    ``kind`` is ``"smooth"`` or ``"traced"``, ``region`` the :class:`DirectionMesh` inside
    the learned edges; ``data`` (N, 3) are the taught directions, ``supported`` the
    data-supported region (a :class:`DirectionMesh` over the same loops with their learned
    margins), ``max_offset`` (rad) caps how far an edge moves past its loop in one step.
    None when the data refuse both (see the module docstring).
    """
    smooth = smooth_edges(loops, data, max_offset)
    smooth_region = agreeing_region(smooth, data, supported)
    traced = [trace_edge(loop, data, max_offset) for loop in loops]
    traced_region = agreeing_region(traced, data, supported)
    if smooth_region is not None and (
        traced_region is None or reach_beyond(smooth, traced_region) <= np.radians(CONFIRM_DEG)
    ):
        return "smooth", smooth_region
    if traced_region is not None:
        return "traced", traced_region
    return None


def reach_beyond(edges: list[np.ndarray], region: DirectionMesh) -> float:
    """How far (rad) the stations of ``edges`` (each (K, 3)) reach beyond ``region``, at most."""
    stations = np.vstack(edges)
    return float(np.max(direction_angle(region.project(stations), stations)))


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


def agreeing_region(
    edges: list[np.ndarray | None] | None, data: np.ndarray, supported: DirectionMesh
) -> DirectionMesh | None:
    """The region inside learned ``edges`` if they agree with the data, else None.

    Agreeing: every edge exists, they are simple (no two arcs cross), they hold the taught
    samples the ``supported`` region holds (up to ``MISS_FRACTION`` farther out than
    ``MISS_TOLERANCE_DEG``), and they add no stretch beyond it the sampling cannot explain.
    """
    if edges is None or any(edge is None for edge in edges):
        return None
    if ef.arcs_cross(edges):
        return None
    if any(ef.unexplained_gap(edge, data, supported) > ef.GAP_EXPECTED for edge in edges):
        return None
    learned = DirectionMesh.from_loops(edges, 0.0)
    before = supported.contains(data)
    missed = before & ~learned.contains(data)
    # a sample a hair outside (the edge estimate's own noise) is not a cut corner
    far = direction_angle(learned.project(data[missed]), data[missed]) > np.radians(
        ef.MISS_TOLERANCE_DEG
    )
    if int(far.sum()) > ef.MISS_FRACTION * max(1, int(before.sum())):
        return None
    return learned
