"""The last step of containment: the region's edge cut back to ``CLIP_REACH_DEG`` of the taught
samples.

A region's farthest point from a truth lies on its edge (inside, a step outward is still in the
region and farther), unless the region closes over an untaught pocket of the outside. A point
within ``r`` of a taught sample that lies inside the truth is at most ``r`` outside it. So a
region whose every edge point lies within ``r`` of a taught sample stands at most ``r`` past any
truth that holds the samples. The holds of :mod:`limbctl.region.edge_hold` bring most of the
edge there; where they cannot (a gap between the samples wider than twice the reach, which a
straight hold cannot bridge, or a hold given back because it crossed), :func:`cut_to_evidence`
cuts the region back in two passes. First a bridged notch: every channel farther than
``NOTCH_REACH_DEG`` from every sample that opens on an edge point that far out is removed to its
end, unless the channel is a large share of the region (then the teaching's gaps have joined up
and cannot be told from a notch). A sparse teaching's gap that opens on the edge is cut too: the
evidence cannot tell it from a narrow notch, and containment wins (the guide asks there). Then
the rest:
every part of the region farther than ``CLIP_REACH_DEG`` from every sample, within ``DEEP_DEG``
of the edge and touching an edge point past that reach, is removed, so the new edge runs along
the samples' reach or ``DEEP_DEG`` inside (docs/decisions/region.md, "Cut back to the
evidence").

The cut is computed in the gnomonic plane about the region's centre, where great-circle arcs
are straight lines: the region and the reach discs are exact polygons there (the discs and the
widened arcs inscribed, so slightly smaller: never more region).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import shapely
from scipy.spatial import cKDTree
from shapely.geometry import Polygon

from limbctl.geometry.gimbal import direction_to_pan_tilt
from limbctl.geometry.quat import tangent_frame
from limbctl.region.evidence import (
    Stretch,
    at_same_place,
    edge_stations,
    loop_arcs,
    outer_arcs,
)
from limbctl.region.loops import chord, loop_area
from limbctl.region.mesh import DirectionMesh

#: Farthest (deg) an edge point may lie from a taught sample: the 1 deg promise less 0.02 for
#: the station spacing the benchmarks read the edge at (edge_excess reads 0.02 deg apart).
CLIP_REACH_DEG = 0.98
#: Station spacing (deg) of the check and of the widened arcs' outlines: a point between two
#: stations lies at most half of it farther from a sample, hence the check's threshold.
CLIP_STEP_DEG = 0.05
#: Sides of a reach disc's polygon: inscribed, its sides lie within cos(pi / 24) of the reach
#: (0.9914): 0.8 % of the reach lost, the disc's area 98.9 % kept.
DISC_SIDES = 24
#: A disc polygon's sides lie this share of its radius from its centre, at the least.
INSCRIBED = float(np.cos(np.pi / DISC_SIDES))
#: Farthest (deg) a region point may lie from the centre of the plane: the gnomonic scale is
#: 1 / cos^2 of it (33 at 80 deg); past 90 the plane does not reach.
PLANE_REACH_DEG = 80.0
#: Plane distance under which a cut piece touches a far station: far below a tick (0.088 deg
#: is 1.5e-3 rad) and far above GEOS's rounding of coordinates of order 1 (1e-15).
TOUCH_PLANE = 1e-9
#: Deepest (deg) a cut reaches into the region. Held, the region's edge stands within the
#: holds' reach of the samples almost everywhere (1.25 deg at most, 0.9 where the tight hold
#: held), so what the cut must take lies by the edge: 1.5 deg brought every one of 108 fresh
#: family teachings within 1 deg (docs/decisions/region.md). An empirical depth, not a proof:
#: across a notch bridged where the holds gave up, a point deep inside can stand far past
#: (swing outline 78, sparse: 4.96 -> 4.60 deg). Deeper cuts cost coverage where nothing stands
#: past: 1000 samples of an irregular region, commands 2 deg inside contained 98.6 % uncut,
#: 96.6 % at 1.0, 95.0 % at 1.5, 89.7 % at 3 (3 along the edge too), 41.9 % with no bound
#: (a sparse teaching's gaps join up).
DEEP_DEG = 1.5
#: Reach (deg) of the first cut, which has no depth bound: a notch the region bridges is an
#: empty channel from the edge inward, and where no sample lies within this reach the cut
#: follows it to its end. Its new edge lies at most this far from a sample, and the second cut
#: takes what stands past ``CLIP_REACH_DEG`` up to ``DEEP_DEG`` in: so the two add up. Swing
#: outlines 78 and 84, sparse (notches bridged, 4.55 and 3.42 deg past with the second cut
#: alone): 0.75 and 0.93 at 2.5 deg, 1.08 and 1.27 at 3.0. The cost falls on sparse teachings:
#: 1000 samples of the irregular region hold 96.0 % of the commands 4 deg inside, against 99.2
#: with the second cut alone (docs/decisions/region.md, "A bridged notch cut to its end").
NOTCH_REACH_DEG = CLIP_REACH_DEG + DEEP_DEG
#: Largest share of the region's (plane) area one piece of the first cut may take. A notch is a
#: small part of the region (the largest piece cut on swing outlines 78, 84, 87 and 88, sparse,
#: was 2.6 %); a piece larger than this is a network of a teaching's gaps joined up (strokes
#: over a 30 deg cone: 5.3 %, over the irregular region: 40 %; 300 samples over 45 deg: most
#: of it), where the evidence cannot tell a notch from a gap: that piece is left to the second
#: cut, and its stretch, past the settled distance, keeps the guide asking there.
NOTCH_SHARE = 0.04
#: Spacing (deg) of the edge stations the cut's depth is measured from.
DEEP_STEP_DEG = 0.5
#: Plane distance of the opening that drops zero-width spikes: 1e-7 rad is 6e-6 deg, far
#: below a tick and far above GEOS's rounding.
OPENING_PLANE = 1e-7
#: Pieces of the clipped region smaller than this (sr) are dropped: a tenth of a 1 deg disc.
SPECK_SR = 0.1 * np.pi * np.radians(1.0) ** 2


@dataclass(frozen=True)
class Clip:
    """What :func:`clip_to_evidence` did.

    Attributes
    ----------
    region : DirectionMesh
        The clipped region (lookup grid not built), or the region given when nothing was cut.
    cut_sr : float
        Area (sr) cut away.
    places : np.ndarray
        (C, 3) directions: the farthest far station of each cut piece (where to teach more).
    far_deg : np.ndarray
        (C,) how far (deg) that station stood from its nearest taught sample.
    length_deg : np.ndarray
        (C,) the length (deg) of the edge each piece was cut from: its far stations' spacing.
    fits : bool
        False when the region did not fit one plane and was left uncut.
    """

    region: DirectionMesh
    cut_sr: float
    places: np.ndarray
    far_deg: np.ndarray
    length_deg: np.ndarray
    fits: bool = True

    @property
    def cut(self) -> bool:
        """Whether anything was cut."""
        return self.places.shape[0] > 0

    @classmethod
    def nothing(cls, mesh: DirectionMesh) -> Clip:
        """``mesh`` with nothing cut."""
        return cls(mesh, 0.0, np.empty((0, 3)), np.empty(0), np.empty(0))


def clip_to_evidence(
    mesh: DirectionMesh,
    data: np.ndarray,
    reach: float = np.radians(CLIP_REACH_DEG),
    deep: float | None = np.radians(DEEP_DEG),
    largest: float = 1.0,
) -> Clip:
    """``mesh`` with every piece of it farther than ``reach`` (rad) from the taught directions
    ``data`` (N, 3) that touches its outer edge cut away, up to ``deep`` (rad) inside the edge
    (None: no bound) (module docstring); a piece over ``largest`` of the region's area is kept.

    A region that does not fit one plane (an edge point past ``PLANE_REACH_DEG`` of its centre)
    comes back uncut, ``Clip.fits`` False (docs/decisions/region.md says why that is left).
    """
    none = Clip.nothing(mesh)
    tree = cKDTree(data)
    step = np.radians(CLIP_STEP_DEG)
    stations, arc = edge_stations(mesh, step)
    dist = tree.query(stations)[0]
    # a hole's edge never reaches past the truth (evidence.unsupported_stations)
    far = (dist > chord(reach - 0.5 * step)) & outer_arcs(mesh)[arc]
    if not far.any():
        return none
    centre = mesh.vertices.mean(axis=0)
    centre /= np.linalg.norm(centre)
    if np.min(stations @ centre) < np.cos(np.radians(PLANE_REACH_DEG)):
        return replace(none, fits=False)
    plane = _Plane(centre)
    region = _region_polygon(mesh, plane, step)
    near = data[data @ centre > np.cos(np.radians(PLANE_REACH_DEG + 1.0))]
    discs = _disc_union(plane, near, reach)
    outside = region.difference(discs)
    if deep is not None:
        # the cut stops ``deep`` inside: deeper, the region lies inside any truth it stands
        # past by less; stations DEEP_STEP_DEG apart, their discs half a step wider
        ring_stations, _ = edge_stations(mesh, np.radians(DEEP_STEP_DEG))
        slack = 0.5 * np.radians(DEEP_STEP_DEG)
        outside = outside.intersection(
            _disc_union(plane, ring_stations, (deep + slack) / INSCRIBED)
        )
    most = largest * region.area
    far_xy = shapely.points(plane.to(stations[far]))
    cut = [
        p
        for p in _polygons(outside)
        if not p.is_empty
        and p.area <= most
        and bool(np.any(shapely.distance(p, far_xy) < TOUCH_PLANE))
    ]
    if not cut:
        return none
    cut_union = shapely.union_all(cut)
    # an opening (in, then out by the same hair) drops the zero-width spikes a difference
    # leaves where a cut ran along the edge: a spike's stations would stand in the region
    clipped = (
        region.difference(cut_union)
        .buffer(-OPENING_PLANE, join_style="mitre")
        .buffer(OPENING_PLANE, join_style="mitre")
    )
    places, far_deg, length_deg = _places(cut, stations[far], dist[far], plane)
    loops = [plane.back(ring) for ring in _rings(_without_specks(clipped, plane.to(near)))]
    out = DirectionMesh.from_loops(loops, 0.0, lookup=False)
    return Clip(out, _sphere_area(cut_union, plane), places, far_deg, length_deg)


def cut_to_evidence(mesh: DirectionMesh, data: np.ndarray) -> Clip:
    """``mesh`` cut back to the taught directions ``data`` (N, 3) in two passes: first every
    channel farther than ``NOTCH_REACH_DEG`` from every sample that opens on the edge, to its end
    (a bridged notch), unless it takes over ``NOTCH_SHARE`` of the region; then every edge
    point farther than ``CLIP_REACH_DEG``, ``DEEP_DEG`` in. The :class:`Clip` lists both's
    places."""
    notch = clip_to_evidence(mesh, data, np.radians(NOTCH_REACH_DEG), None, NOTCH_SHARE)
    if not notch.cut:
        return clip_to_evidence(mesh, data)
    edge = clip_to_evidence(notch.region, data)
    if not edge.cut:
        return notch
    return Clip(
        edge.region,
        notch.cut_sr + edge.cut_sr,
        np.vstack([notch.places, edge.places]),
        np.concatenate([notch.far_deg, edge.far_deg]),
        np.concatenate([notch.length_deg, edge.length_deg]),
        edge.fits,
    )


class _Plane:
    """The gnomonic plane about ``centre`` (3,): great circles map to straight lines."""

    def __init__(self, centre: np.ndarray):
        self.centre = centre
        self.u, self.v = tangent_frame(centre)

    def to(self, d: np.ndarray) -> np.ndarray:
        """(K, 2) plane points of directions ``d`` (K, 3) in the centre's hemisphere."""
        z = d @ self.centre
        return np.column_stack([d @ self.u / z, d @ self.v / z])

    def back(self, xy: np.ndarray) -> np.ndarray:
        """(K, 3) directions of plane points ``xy`` (K, 2)."""
        d = self.centre[None, :] + xy[:, :1] * self.u[None, :] + xy[:, 1:2] * self.v[None, :]
        return d / np.linalg.norm(d, axis=1, keepdims=True)


def _region_polygon(mesh: DirectionMesh, plane: _Plane, step: float):
    """The widened region of ``mesh`` as a plane polygon: its loops (holes clockwise) joined by
    parity, with a capsule about every widened arc."""
    area = None
    for arcs in loop_arcs(mesh):
        ring = Polygon(plane.to(mesh.vertices[mesh.edges[arcs, 0]])).buffer(0)
        area = ring if area is None else area.symmetric_difference(ring)
    widened = np.flatnonzero(mesh.margins > 0.0)
    caps = [Polygon(plane.to(_capsule(mesh, e, step))).buffer(0) for e in widened]
    return shapely.union_all([area, *caps]) if caps else area


def _capsule(mesh: DirectionMesh, e: int, step: float) -> np.ndarray:
    """(K, 3) ring about arc ``e`` at its margin: both sides along it and a half disc at each
    end, points ``step`` (rad) apart (inscribed)."""
    a, b = mesh.vertices[mesh.edges[e]]
    m = float(mesh.margins[e])
    pole = np.cross(a, b)
    pole /= np.linalg.norm(pole)
    length = np.arctan2(np.linalg.norm(np.cross(a, b)), a @ b)
    t = np.linspace(0.0, 1.0, max(2, int(np.ceil(length / step)) + 1))
    line = np.array([np.sin((1 - s) * length) * a + np.sin(s * length) * b for s in t])
    line /= np.linalg.norm(line, axis=1, keepdims=True)
    left = np.cos(m) * line + np.sin(m) * pole
    right = np.cos(m) * line - np.sin(m) * pole
    half = np.linspace(0.0, np.pi, max(3, int(np.ceil(np.pi * m / step)) + 1))[1:-1]
    # round b from the right side (-pole) ahead to the left, round a from the left back
    ahead_b, ahead_a = np.cross(pole, b), np.cross(pole, a)
    return np.vstack(
        [
            right,
            _arc_about(b, -pole, ahead_b, m, half),
            left[::-1],
            _arc_about(a, pole, -ahead_a, m, half),
        ]
    )


def _arc_about(x: np.ndarray, start: np.ndarray, through: np.ndarray, m: float, phi: np.ndarray):
    """(K, 3) points ``m`` (rad) from ``x`` (3,) toward the tangents cos(phi) start + sin(phi)
    through (unit tangents at ``x``, (3,) each), at the angles ``phi`` (K,)."""
    tangent = np.cos(phi)[:, None] * start[None, :] + np.sin(phi)[:, None] * through[None, :]
    return np.cos(m) * x[None, :] + np.sin(m) * tangent


def _disc_union(plane: _Plane, centres: np.ndarray, radius: float):
    """The plane polygon of the discs of ``radius`` (rad) about ``centres`` (N, 3), inscribed."""
    return shapely.union_all([Polygon(plane.to(ring)) for ring in _disc_rings(centres, radius)])


def _disc_rings(centres: np.ndarray, reach: float) -> np.ndarray:
    """(N, DISC_SIDES, 3) rings of points ``reach`` (rad) about each of ``centres`` (N, 3)."""
    u = np.cross(
        np.where(np.abs(centres[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[0.0, 1.0, 0.0]]), centres
    )
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(centres, u)
    phi = np.linspace(0.0, 2.0 * np.pi, DISC_SIDES, endpoint=False)
    t = np.cos(phi)[None, :, None] * u[:, None, :] + np.sin(phi)[None, :, None] * v[:, None, :]
    return np.cos(reach) * centres[:, None, :] + np.sin(reach) * t


def _without_specks(poly, taught_xy: np.ndarray):
    """``poly``'s pieces, less those under ``SPECK_SR`` holding no taught point ((N, 2) plane)."""
    kept = []
    for p in _polygons(poly):
        # the plane's area is the sphere's or more (the gnomonic scale is 1 or more)
        small = p.area < SPECK_SR
        if not small or shapely.contains_xy(p, *taught_xy.T).any():
            kept.append(p)
    return shapely.MultiPolygon(kept)


def _polygons(geometry) -> list:
    """The polygons of a geometry (a polygon, multipolygon or collection), lines dropped."""
    if isinstance(geometry, Polygon):
        return [] if geometry.is_empty else [geometry]
    return [p for g in getattr(geometry, "geoms", []) for p in _polygons(g)]


def _rings(poly) -> list[np.ndarray]:
    """Plane rings (K, 2) of a (multi)polygon, region on the left (exteriors counter-clockwise,
    holes clockwise), the closing point dropped."""
    out = []
    for p in _polygons(poly):
        p = shapely.geometry.polygon.orient(p, 1.0)
        out.append(np.asarray(p.exterior.coords)[:-1])
        out.extend(np.asarray(h.coords)[:-1] for h in p.interiors)
    return out


def _places(cut: list, stations: np.ndarray, dist: np.ndarray, plane: _Plane):
    """Per cut piece its farthest far station (3,), that station's distance (deg) and the
    length (deg) of the far edge it touches."""
    xy = plane.to(stations)
    places, far_deg, length_deg = [], [], []
    for piece in cut:
        touching = shapely.distance(piece, shapely.points(xy)) < TOUCH_PLANE
        k = np.flatnonzero(touching)
        if k.size == 0:
            continue
        j = k[np.argmax(dist[k])]
        places.append(stations[j])
        far_deg.append(np.degrees(2.0 * np.arcsin(min(1.0, 0.5 * dist[j]))))
        length_deg.append(k.size * CLIP_STEP_DEG)
    return np.array(places).reshape(-1, 3), np.array(far_deg), np.array(length_deg)


def clipped_stretches(stretches: tuple[Stretch, ...], clip: Clip) -> tuple[Stretch, ...]:
    """``stretches`` and, held, each place ``clip`` cut that none of them lies at already
    (within half their lengths plus ``SAME_PLACE_DEG``): farthest first."""
    out = list(stretches)
    pan, tilt = direction_to_pan_tilt(clip.places)
    for i in range(clip.places.shape[0]):
        new = Stretch(
            float(np.degrees(pan[i])),
            float(np.degrees(tilt[i])),
            float(clip.far_deg[i]),
            float(clip.length_deg[i]),
            held=True,
        )
        if not at_same_place(new, out):
            out.append(new)
    return tuple(sorted(out, key=lambda s: -s.distance_deg))


def _sphere_area(poly, plane: _Plane) -> float:
    """Area (sr) of a plane (multi)polygon on the sphere: its exteriors less its holes."""
    return float(sum(loop_area(plane.back(r)) for r in _rings(poly)))
