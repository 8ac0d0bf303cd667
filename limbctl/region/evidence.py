"""Whether a region's edge stays within the taught evidence where the samples enclose it.

A taught sample lies inside the true region, so a point of the learned region ``delta`` from its
nearest taught sample lies at most ``delta`` outside the truth. Along a convex or straight
stretch of edge the samples all lie on one side of the edge, and an edge between sparse samples
there bulges no further than the truth's own convex outline (the margins read it from the
outermost samples). Where the samples *surround* a point of the edge (they lie on both sides
of it and beyond: a bay or notch the edge bridges, a reflex corner the edge cuts), nothing but
those samples says where the truth's edge runs, and an edge far from every sample may bridge a
concavity the sampling never entered.

:func:`unsupported_stretches` walks the widened edge of a
:class:`~limbctl.region.mesh.DirectionMesh` station by station (``STATION_DEG`` apart) and
returns the runs of stations that are surrounded (``CONCAVE_RADIUS_DEG``, ``CONCAVE_GAP_DEG``)
and farther than ``EVIDENCE_DEG`` from every taught sample. Acceptance refuses a learned edge
with any; the fit narrows its shape until the supported edge has none, and lists the stretches
it could not remove (:class:`Stretch`: where, how far from the evidence) for ``train`` and the
recorder's guide.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from limbctl.geometry.gimbal import direction_to_pan_tilt
from limbctl.region import shape_kernels
from limbctl.region.loops import chord, loop_area
from limbctl.region.mesh import DirectionMesh

#: The farthest (deg) a surrounded station of the edge may lie from its nearest taught sample.
#: Not the 1 deg bound itself: a hand traces about 1 deg inside, so a traced reflex corner lies
#: 1.1-1.4 deg from its own samples and an edge reaching it is not outside the truth (at 0.8 the
#: demo's traced edge was refused, docs/decisions/region.md); bridged bays lie 2-4 deg away.
EVIDENCE_DEG = 1.5
#: The farthest (deg) any station of the learned edge may lie from its nearest taught sample
#: before its stretch is reported unsupported (:attr:`limbctl.region.TaughtRegion.unsupported_edge`:
#: the guide withholds READY and ``train`` lists it). The samples lie inside the truth, so an edge
#: point within r of one lies at most r outside the truth (between stations, at most
#: ``STATION_DEG / 2`` more). Unlike ``EVIDENCE_DEG`` it asks no surround: an edge that far from
#: every sample may be past an unknown truth anywhere. 1.25, not the 1 deg bound: a traced edge
#: stands 1.0-1.1 deg beyond a hand that traces about 1 deg inside the stops (the simulator's
#: hand on irregular.yaml, tests/teach/test_record.py), and at 1.0 no such teaching is ever ready;
#: bridged bays and notches stand 1.5-4 deg from the samples (docs/decisions/region.md).
REACH_DEG = 1.25
#: Spacing (deg) of the stations along the edge: a point between two stations lies at most half
#: of it farther from the evidence than the nearer station.
STATION_DEG = 0.25
#: Radius (deg) of the neighbourhood whose samples must surround a station for it to count as
#: concave: wider than a bay's mouth is deep at the scale the 1 deg bound matters (a few deg),
#: the same as the peel's ``surround_deg`` default.
CONCAVE_RADIUS_DEG = 6.0
#: A station is surrounded when its neighbourhood's samples leave no empty sector wider than this
#: (deg): a station on a straight or convex edge sees the samples within 180 deg or less of
#: bearing and an empty sector of 180 deg or more; 170 leaves the scatter of a straight edge
#: (samples a little beyond the station's tangent) out.
CONCAVE_GAP_DEG = 170.0
#: A station is judged only with at least this many samples in its neighbourhood (a half cap of
#: 56 deg^2): fewer (sparse i.i.d. teaching, 600-1000 samples, 0.05-0.3 per deg^2 at the edge:
#: 3-20) cannot tell a bay from the dents of the sampling itself, and carving them ate 5-14 % of
#: the region 2 deg inside; a hand's recording or 6000 samples put 60-200 there.
CONCAVE_MIN_SAMPLES = 40


#: A station with a taught sample within this angle (deg) of its outward direction (and within
#: ``CONCAVE_RADIUS_DEG``) has evidence beyond it: the edge there dips into a pocket the teacher
#: never wandered, inside a traced edge, not across a bay (the walls of a bay it bridges lie
#: about 90 deg to either side of the outward direction, its mouth's outside is empty).
OUTWARD_CONE_DEG = 15.0


@dataclass(frozen=True)
class Stretch:
    """A run of edge stations the taught samples surround but do not reach.

    Attributes
    ----------
    pan_deg, tilt_deg : float
        Where its farthest station lies (the gimbal's pan and tilt, deg).
    distance_deg : float
        That station's distance to its nearest taught sample (deg).
    length_deg : float
        Its length along the edge (deg).
    held : bool
        Whether the region was held there within ``REACH_DEG`` of the taught samples
        (:mod:`limbctl.region.edge_hold`): it then stands short of where the learned edge put
        it, ``distance_deg`` being how far that edge stood from the samples.
    """

    pan_deg: float
    tilt_deg: float
    distance_deg: float
    length_deg: float
    held: bool = False

    def line(self) -> str:
        """One line for a person: where, how far from the samples, how long, whether held."""
        text = (
            f"near pan {self.pan_deg:.0f}, tilt {self.tilt_deg:.0f}: {self.length_deg:.1f} deg "
            f"of edge up to {self.distance_deg:.1f} deg from every taught sample"
        )
        if self.held:
            text += (
                f" (held at the evidence: the region stops within {REACH_DEG:g} deg of it there)"
            )
        return text


def outer_arcs(mesh: DirectionMesh) -> np.ndarray:
    """(E,) bool: whether each arc of ``mesh`` lies on an outer loop (region on its left and
    enclosing positive area), not on a hole's loop."""
    outer = np.zeros(mesh.edges.shape[0], dtype=bool)
    for run in loop_arcs(mesh):
        outer[run] = loop_area(mesh.vertices[mesh.edges[run, 0]]) > 0.0
    return outer


def loop_arcs(mesh: DirectionMesh) -> list[np.ndarray]:
    """The arcs (indices into ``mesh.edges``) of each of its closed loops, in order."""
    following = np.full(mesh.vertices.shape[0], -1, dtype=np.int64)
    following[mesh.edges[:, 0]] = np.arange(mesh.edges.shape[0])
    seen = np.zeros(mesh.edges.shape[0], dtype=bool)
    out = []
    for first in range(mesh.edges.shape[0]):
        if seen[first]:
            continue
        run, e = [], first
        while not seen[e]:
            seen[e] = True
            run.append(e)
            e = following[mesh.edges[e, 1]]
        out.append(np.array(run, dtype=np.int64))
    return out


def edge_stations(mesh: DirectionMesh, step: float) -> tuple[np.ndarray, np.ndarray]:
    """Stations (S, 3) along ``mesh``'s widened edge about ``step`` (rad) apart, and the arc
    (S,) each lies on.

    A station on arc ``a -> b`` widened by ``m`` lies ``m`` outside the arc's great circle
    (the region is on the arc's left, toward ``a x b``).
    """
    a = mesh.vertices[mesh.edges[:, 0]]
    b = mesh.vertices[mesh.edges[:, 1]]
    pole = np.cross(a, b)
    pole /= np.maximum(np.linalg.norm(pole, axis=1, keepdims=True), 1e-15)
    length = np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.einsum("ij,ij->i", a, b))
    count = np.maximum(1, np.ceil(length / step).astype(np.int64))
    arc = np.repeat(np.arange(a.shape[0]), count)
    first = np.concatenate([[0], np.cumsum(count)[:-1]])
    t = (np.arange(arc.shape[0]) - np.repeat(first, count)) / count[arc]
    om = length[arc]
    so = np.where(np.sin(om) < 1e-12, 1.0, np.sin(om))
    x = (np.sin((1.0 - t) * om) / so)[:, None] * a[arc] + (np.sin(t * om) / so)[:, None] * b[arc]
    x[np.sin(om) < 1e-12] = a[arc][np.sin(om) < 1e-12]
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    m = mesh.margins[arc][:, None]
    out = np.cos(m) * x - np.sin(m) * pole[arc]
    return out / np.linalg.norm(out, axis=1, keepdims=True), arc


def unsupported_stations(
    mesh: DirectionMesh,
    data: np.ndarray,
    bound: float = np.radians(EVIDENCE_DEG),
    radius: float = np.radians(CONCAVE_RADIUS_DEG),
    max_gap: float = np.radians(CONCAVE_GAP_DEG),
    surrounded: bool = True,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The edge's stations (S, 3), the arc (S,) each lies on, its distance (S,) rad to the
    nearest of ``data`` (N, 3), and the indices (B,) of the unsupported ones (farther than
    ``bound`` and, if ``surrounded``, surrounded: see :func:`unsupported_stretches`)."""
    stations, arc = edge_stations(mesh, np.radians(STATION_DEG))
    tree = cKDTree(data)
    dist, _ = tree.query(stations)
    # chord -> angle
    delta = 2.0 * np.arcsin(np.clip(0.5 * dist, 0.0, 1.0))
    # a hole's edge bounds what the region leaves out: a swing outline has no holes, so what
    # lies inside a hole belongs to the truth and its edge never reaches past it
    far = np.flatnonzero((delta > bound) & outer_arcs(mesh)[arc])
    if far.size == 0 or not surrounded:
        return stations, arc, delta, far
    # the station's outward direction (tangent at it, away from the region's side of its arc)
    a = mesh.vertices[mesh.edges[arc[far], 0]]
    b = mesh.vertices[mesh.edges[arc[far], 1]]
    bridged = surrounded_bare(stations[far], -np.cross(a, b), data, tree, radius, max_gap)
    return stations, arc, delta, far[bridged]


def surrounded_bare(
    points: np.ndarray,
    outward: np.ndarray,
    data: np.ndarray,
    tree: cKDTree,
    radius: float = np.radians(CONCAVE_RADIUS_DEG),
    max_gap: float = np.radians(CONCAVE_GAP_DEG),
) -> np.ndarray:
    """(P,) bool: whether the taught ``data`` (N, 3) surround each edge point (P, 3) and leave
    its outward side bare.

    True where at least ``CONCAVE_MIN_SAMPLES`` of ``data`` lie within ``radius`` (rad), their
    bearings leave no empty sector wider than ``max_gap`` (rad) and none of them lies within
    ``OUTWARD_CONE_DEG`` of the point's ``outward`` direction (P, 3; any vector whose part
    tangent to the sphere at the point points away from the region). ``tree`` is a
    :class:`scipy.spatial.cKDTree` over ``data``.
    """
    if points.shape[0] == 0:
        return np.zeros(0, dtype=bool)
    near = tree.query_ball_point(points, chord(radius))
    counts = np.array([len(rows) for rows in near], dtype=np.int64)
    start = np.concatenate([[0], np.cumsum(counts)])
    flat = np.fromiter((j for rows in near for j in rows), dtype=np.int64, count=int(start[-1]))
    widest = shape_kernels.widest_bearing_gaps(
        np.ascontiguousarray(points), np.ascontiguousarray(data), start, flat
    )
    out = outward - np.einsum("ij,ij->i", outward, points)[:, None] * points
    out /= np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-15)
    beyond = np.zeros(points.shape[0], dtype=bool)
    for k, rows in enumerate(near):
        v = data[rows] - np.outer(data[rows] @ points[k], points[k])
        cos = (v @ out[k]) / np.maximum(np.linalg.norm(v, axis=1), 1e-15)
        beyond[k] = bool(np.any(cos > np.cos(np.radians(OUTWARD_CONE_DEG))))
    return (counts >= CONCAVE_MIN_SAMPLES) & (widest < max_gap) & ~beyond


def unsupported_stretches(
    mesh: DirectionMesh,
    data: np.ndarray,
    bound: float = np.radians(EVIDENCE_DEG),
    radius: float = np.radians(CONCAVE_RADIUS_DEG),
    max_gap: float = np.radians(CONCAVE_GAP_DEG),
    surrounded: bool = True,
) -> list[Stretch]:
    """The stretches of ``mesh``'s edge the taught ``data`` (N, 3) surround but do not reach
    (or, with ``surrounded`` False, do not reach at all).

    Parameters
    ----------
    mesh : DirectionMesh
        The region.
    data : ndarray, shape (N, 3)
        The taught directions.
    bound : float
        How far (rad) a surrounded station may lie from its nearest sample.
    radius, max_gap : float
        The surround test's neighbourhood and widest empty sector (rad).
    surrounded : bool
        Whether a station counts only where the samples surround it (the carving's test), or
        wherever it lies farther than ``bound`` (the report's, ``REACH_DEG``).

    Returns
    -------
    list of Stretch
        Runs of consecutive stations (along one arc or its neighbours) farther than ``bound``
        from every sample and surrounded by the samples within ``radius``; farthest first.
    """
    stations, arc, delta, bad = unsupported_stations(mesh, data, bound, radius, max_gap, surrounded)
    if bad.size == 0:
        return []
    # runs: consecutive station indices on arcs that follow each other in the mesh
    runs: list[list[int]] = [[int(bad[0])]]
    for i in bad[1:]:
        prev = runs[-1][-1]
        same_run = i == prev + 1 and (
            arc[i] == arc[prev] or mesh.edges[arc[prev], 1] == mesh.edges[arc[i], 0]
        )
        if same_run:
            runs[-1].append(int(i))
        else:
            runs.append([int(i)])
    out = []
    for run in runs:
        k = run[int(np.argmax(delta[run]))]
        pan, tilt = direction_to_pan_tilt(stations[k : k + 1])
        out.append(
            Stretch(
                float(np.degrees(pan[0])),
                float(np.degrees(tilt[0])),
                float(np.degrees(delta[k])),
                STATION_DEG * len(run),
            )
        )
    return sorted(out, key=lambda s: -s.distance_deg)
