"""Whether a region's edge stays within the taught evidence where the samples surround it
(:func:`unsupported_stretches`; docs/region.md, "Held to the taught evidence")."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial import ConvexHull, QhullError, cKDTree

from limbctl.geometry.gimbal import direction_to_pan_tilt, pan_tilt_to_direction
from limbctl.geometry.quat import tangent_frame
from limbctl.region.loops import chord, loop_area
from limbctl.region.mesh import DirectionMesh
from limbctl.region.shape import bearing_gaps

#: Farthest (deg) a surrounded station may lie from a sample: reflex corners 1.1-1.4, bays 2-4.
EVIDENCE_DEG = 1.5
#: Farthest (deg) any edge station may lie from a sample unreported: a traced edge stands 1.0-1.1.
REACH_DEG = 1.25
#: The held edge held again this close (deg): with a chord's slack (0.0625) within the 1 deg bound.
HOLD_REACH_DEG = 0.9
#: A held stretch whose learned edge stood at most this far (deg) from every sample, or past their
#: outline (a traced notch it bridges), is settled (no longer withholds READY): traced stops leave
#: it 1.26-2.07 deg off (docs/bench_guided_teaching.md) and the hold keeps the region within
#: REACH_DEG of the samples there, so containment is kept.
SETTLED_DEG = REACH_DEG + 1.0
#: Station spacing (deg): a point between stations lies at most half of it farther.
STATION_DEG = 0.25
#: A held edge's stations lie within the reach plus this (deg): its chords' slack (a quarter
#: station, edge_hold.CHORD_SLACK_DEG) twice over, for a station between two chord checks.
HELD_SLACK_DEG = 0.5 * STATION_DEG
#: A stretch cut before the hold lies at the same place as one left after it when their farthest
#: stations are within half their lengths plus this (deg): two stations' spacing, rounded up.
SAME_PLACE_DEG = 1.0
#: Surround neighbourhood (deg): wider than a bay's mouth is deep; the peel's default.
CONCAVE_RADIUS_DEG = 6.0
#: Widest empty sector (deg) of a surrounded station: a straight edge's is 180 or more.
CONCAVE_GAP_DEG = 170.0
#: Least samples in the neighbourhood to judge a bay: sparse teachings put 3-20, a hand 60-200.
CONCAVE_MIN_SAMPLES = 40
#: A sample this close (deg) to a station's outward direction is evidence beyond it: bay walls ~90.
OUTWARD_CONE_DEG = 15.0
#: A notch's floor under a bridging edge lies at most this much farther (deg) than the nearest
#: sample, toward the inside: a trace's inset (about 1 deg, EVIDENCE_DEG's); the untaught inside
#: under an unfinished trace lies farther (1.4-1.8 deg past, a hand's 30 s teaching).
FLOOR_DEG = 1.0


@dataclass(frozen=True)
class Stretch:
    """A run of edge stations the taught samples surround but do not reach: ``pan_deg``,
    ``tilt_deg``, where its farthest station lies (the gimbal's pan and tilt, deg);
    ``distance_deg``, that station's distance to its nearest taught sample (deg); ``length_deg``,
    its length along the edge (deg); ``held``, whether the region was held there
    (``distance_deg``: where the learned edge stood); ``outline_deg``, that station's distance past
    the samples' outline (:func:`past_outline`; None: unread)."""

    pan_deg: float
    tilt_deg: float
    distance_deg: float
    length_deg: float
    held: bool = False
    outline_deg: float | None = None

    @property
    def settled(self) -> bool:
        """Held here, the learned edge within ``SETTLED_DEG`` of the samples or of their outline
        (a traced notch the edge bridges: a trace cannot bring a sample nearer): asked no more."""
        outline = self.distance_deg if self.outline_deg is None else self.outline_deg
        return self.held and min(self.distance_deg, outline) <= SETTLED_DEG

    def request(self) -> str:
        """What to teach, in words (the recorder's guide)."""
        where = f"trace the edge near pan {self.pan_deg:+.0f}, tilt {self.tilt_deg:+.0f}"
        return f"held at the evidence; {where}" if self.held else where

    def line(self) -> str:
        """One line for a person: where, how far from the samples, how long, whether held."""
        text = (
            f"near pan {self.pan_deg:.0f}, tilt {self.tilt_deg:.0f}: {self.length_deg:.1f} deg "
            f"of edge up to {self.distance_deg:.1f} deg from every taught sample"
        )
        if self.held:
            text += f" (held at the evidence: the region stops within {REACH_DEG:g} deg of it)"
        return text


def outer_arcs(mesh: DirectionMesh) -> np.ndarray:
    """(E,) bool: whether each arc of ``mesh`` lies on an outer loop, not a hole's."""
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
    """Stations (S, 3) along ``mesh``'s widened edge about ``step`` (rad) apart; their arcs (S,)."""
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
    """Edge stations (S, 3), their arcs (S,), distances (S,) rad to ``data`` (N, 3), and the
    indices (B,) of the unsupported ones (see :func:`unsupported_stretches`)."""
    stations, arc = edge_stations(mesh, np.radians(STATION_DEG))
    tree = cKDTree(data)
    dist, _ = tree.query(stations)
    # chord -> angle
    delta = 2.0 * np.arcsin(np.clip(0.5 * dist, 0.0, 1.0))
    # a hole's edge never reaches past the truth: what a swing outline's hole holds is true
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
    """(P,) bool: whether ``data`` (N, 3) surround each edge point (P, 3), its outward side bare. At
    least ``CONCAVE_MIN_SAMPLES`` within ``radius`` (rad), no empty sector of bearings wider than
    ``max_gap`` (rad) and none within ``OUTWARD_CONE_DEG`` of ``outward`` (P, 3; any vector whose
    tangent part points away from the region). ``tree`` is a cKDTree over ``data``."""
    if points.shape[0] == 0:
        return np.zeros(0, dtype=bool)
    near = tree.query_ball_point(points, chord(radius))
    counts, widest = bearing_gaps(points, data, near)
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
    """The stretches of ``mesh``'s edge the taught directions ``data`` (N, 3) surround but do not
    reach: runs of consecutive stations farther than ``bound`` (rad) from their nearest sample,
    farthest first. ``radius``, ``max_gap``: the surround test's neighbourhood and widest empty
    sector (rad); ``surrounded``: count a station only where the samples surround it, else
    wherever beyond ``bound``."""
    stations, arc, delta, bad = unsupported_stations(mesh, data, bound, radius, max_gap, surrounded)
    if bad.size == 0:
        return []
    # runs: consecutive station indices on arcs that follow each other in the mesh
    prev, i = arc[bad[:-1]], arc[bad[1:]]
    same_run = (np.diff(bad) == 1) & ((i == prev) | (mesh.edges[prev, 1] == mesh.edges[i, 0]))
    runs = np.split(bad, np.flatnonzero(~same_run) + 1)
    out = []
    tree = cKDTree(data)
    for run in runs:
        k = run[int(np.argmax(delta[run]))]
        pan, tilt = direction_to_pan_tilt(stations[k : k + 1])
        out.append(
            Stretch(
                float(np.degrees(pan[0])),
                float(np.degrees(tilt[0])),
                float(np.degrees(delta[k])),
                STATION_DEG * len(run),
                outline_deg=past_outline(
                    stations[k], np.cross(*mesh.vertices[mesh.edges[arc[k]]]), data, tree
                ),
            )
        )
    return sorted(out, key=lambda s: -s.distance_deg)


def past_outline(
    point: np.ndarray, inward: np.ndarray, data: np.ndarray, tree: cKDTree
) -> float | None:
    """How far (deg) ``point`` (3,) lies past the convex hull (negative: inside) of the taught
    ``data`` (N, 3) within CONCAVE_RADIUS_DEG, on its gnomonic plane; None under
    CONCAVE_MIN_SAMPLES there, or with no sample toward ``inward`` (3,; its tangent part points
    into the region) within FLOOR_DEG of the nearest (``tree``: over ``data``). Over a notch whose
    walls and floor the samples trace: how far an edge bridging it stands past their outline."""
    near = data[tree.query_ball_point(point, chord(np.radians(CONCAVE_RADIUS_DEG)))]
    if near.shape[0] < CONCAVE_MIN_SAMPLES:
        return None
    frame = np.stack(tangent_frame(point), axis=1)
    xy = np.degrees(near @ frame / (near @ point)[:, None])
    r, w = np.linalg.norm(xy, axis=1), inward @ frame
    # the floor under the bridge, traced: a sample toward the inside, about as near as the nearest
    under = xy @ w > r * np.linalg.norm(w) * np.cos(np.radians(OUTWARD_CONE_DEG))
    if not np.any(under & (r <= r.min() + FLOOR_DEG)):
        return None
    try:
        hull = ConvexHull(xy)
    except QhullError:  # the samples on a line
        return None
    a, b = xy[hull.simplices[:, 0]], xy[hull.simplices[:, 1]]
    t = np.clip(np.einsum("ij,ij->i", -a, b - a) / np.einsum("ij,ij->i", b - a, b - a), 0.0, 1.0)
    gap = float(np.min(np.linalg.norm(a + t[:, None] * (b - a), axis=1)))
    # the point (the origin) is inside where it is inside every facet, n . x + b <= 0
    return gap if np.max(hull.equations[:, 2]) > 0.0 else -gap


def held_stretches(
    cut: tuple[Stretch, ...], region: DirectionMesh, data: np.ndarray
) -> tuple[Stretch, ...]:
    """The stretches ``cut`` from the learned edge, marked held, checked on the ``region`` the
    hold left: where it gave arcs back (their pins crossed), that region's own edge still stands
    farther than ``REACH_DEG + HELD_SLACK_DEG`` from the taught ``data`` (N, 3); those stretches
    are listed unheld instead of the cut ones at the same place. Farthest first."""
    left = _past_held_reach(region, data)
    kept = [replace(s, held=True) for s in cut]
    kept = [s for s in kept if not at_same_place(s, left)]
    return tuple(sorted(kept + left, key=lambda s: -s.distance_deg))


def cut_within_reach(
    listed: tuple[Stretch, ...], region: DirectionMesh, data: np.ndarray
) -> tuple[Stretch, ...]:
    """``listed`` read again on the cut ``region``: an unheld stretch where that region's edge
    no longer stands farther than ``REACH_DEG + HELD_SLACK_DEG`` from the taught ``data``
    (N, 3), or itself no farther than that (a neighbour of one that does), is marked held (the
    cut brought it within reach); every other stretch as it was."""
    left = _past_held_reach(region, data)
    bound = REACH_DEG + HELD_SLACK_DEG
    return tuple(
        s
        if s.held or (s.distance_deg > bound and at_same_place(s, left))
        else replace(s, held=True)
        for s in listed
    )


def at_same_place(s: Stretch, others: list[Stretch] | tuple[Stretch, ...]) -> bool:
    """Whether ``s`` lies at one of ``others``: their farthest stations within half their
    lengths plus ``SAME_PLACE_DEG`` (deg)."""
    if not others:
        return False
    where = np.array([_direction(o) for o in others])
    span = np.array([o.length_deg for o in others])
    angle = np.degrees(np.arccos(np.clip(where @ _direction(s), -1.0, 1.0)))
    return bool(np.any(angle <= 0.5 * (span + s.length_deg) + SAME_PLACE_DEG))


def _past_held_reach(region: DirectionMesh, data: np.ndarray) -> list[Stretch]:
    """The stretches of ``region``'s edge farther than ``REACH_DEG + HELD_SLACK_DEG`` from the
    taught ``data`` (N, 3)."""
    bound = np.radians(REACH_DEG + HELD_SLACK_DEG)
    return unsupported_stretches(region, data, bound, surrounded=False)


def _direction(s: Stretch) -> np.ndarray:
    return pan_tilt_to_direction(*np.radians([s.pan_deg, s.tilt_deg]))
