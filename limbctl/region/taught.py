"""The taught region the gate enforces, built from the positions of taught samples.

:class:`TaughtRegion` runs every step from taught samples to the grid that answers commands
(all angles radians below; the settings are a :class:`~limbctl.region.params.RegionParams`):

1. *Thin*: samples at least ``thin_deg`` apart, outermost kept (:func:`limbctl.region.shape.thin`),
   at most ``support_nodes`` (the spacing grows until they fit).
2. *Shape*: the thinned directions are triangulated (spherical Delaunay); triangles with
   circumradius at most ``alpha`` are kept, ``alpha`` learned from the data's scale
   (``alpha_factor`` times the 90th percentile of the empty-circle radii of the gaps the
   samples enclose), and holes smaller than ``hole_fraction`` of the region are filled; a
   hole open to the outside only through gaps of at most ``MOUTH_SPACINGS`` thinning
   spacings (between neighbouring samples of a traced edge) counts as closed.
3. *Peel*: outside triangles whose exposed edge is longer than the peel length (``peel_factor``
   median nearest-neighbour spacings, at least ``min_peel_deg``) and whose middle the samples
   do not surround (samples within ``surround_deg`` leave an empty sector wider than
   ``SURROUND_GAP_DEG``) are peeled away, longest first: the *supported loops* run through
   taught samples, corners and concavities as taught.
4. *Margins*: each arc of the supported loops is widened to where the outermost samples put the
   edge (:func:`limbctl.region.shape.edge_margins`; windows of ``EDGE_WINDOW`` peel lengths,
   at most ``max_margin_deg``); arcs longer than ``BRIDGE_FRACTION`` peel lengths only cover
   the samples beyond them; an arc cutting a traced concave corner widens no further than
   where its neighbours' widened great circles meet (``TRACED_SPACINGS``,
   ``CORNER_TURN_DEG``). This is the *supported region*.
   Where the samples surround a stretch of that edge but lie farther than ``EVIDENCE_DEG``
   from it (a bay or notch the shape bridged, :mod:`limbctl.region.evidence`), the triangle
   behind it is carved away (``CARVE_ROUNDS``, ``CARVE_LOSS``); what cannot be carved is
   listed in :attr:`TaughtRegion.unsupported_edge`.
5. *Edge*: the edge strategy ``edge`` names (:mod:`limbctl.region.edge_choice`) replaces the
   supported loops by a learned edge where the data agree with it, or keeps them;
   :attr:`TaughtRegion.verdicts` says which strategies were refused and why. Every stretch of
   the kept edge farther than ``REACH_DEG`` from every taught sample is listed in
   :attr:`TaughtRegion.unsupported_edge` and held to within ``REACH_DEG`` of the samples
   (:func:`limbctl.region.edge_hold.hold_to_evidence`: containment over coverage;
   :attr:`TaughtRegion.held_edge`). A teaching with no such stretch keeps the edge as chosen.
6. *Mesh*: a :class:`~limbctl.region.mesh.DirectionMesh` over the chosen edge answers
   :meth:`TaughtRegion.contains` and :meth:`TaughtRegion.correct` in O(1) per command.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.spatial import cKDTree

from limbctl.errors import ConfigError, InvalidInputError
from limbctl.geometry.quat import UNIT_TOLERANCE, as_quaternions, limb_direction
from limbctl.region import correct_kernels as ck
from limbctl.region import shape as rs
from limbctl.region.acceptance import Verdict
from limbctl.region.edge_choice import choose_edge
from limbctl.region.edge_hold import hold_to_evidence
from limbctl.region.evidence import (
    REACH_DEG,
    STATION_DEG,
    Stretch,
    edge_stations,
    outer_arcs,
    unsupported_stations,
    unsupported_stretches,
)
from limbctl.region.gaps import ORDER_STATISTICS
from limbctl.region.mesh import DirectionMesh, boundary_edges
from limbctl.region.params import RegionParams

#: Half width of the windows (along the loop) the margins read, in peel lengths: wide enough to
#: hold ORDER_STATISTICS outermost samples along a sparse edge, narrow enough to stay local.
EDGE_WINDOW = 1.5
#: A point is surrounded when no empty sector about it is wider than this (deg): a point on a
#: straight edge sees every sample on one side (an empty half, 180 deg); 15 deg less leaves
#: room for the scatter of samples along the edge.
SURROUND_GAP_DEG = 165.0
#: Arcs longer than this fraction of the peel length are bridges over a gap with no sample
#: along them: the data say nothing of an edge beyond them, so they get no learned widening.
BRIDGE_FRACTION = 0.75
#: Gaps in the alpha complex up to this many thinning spacings wide close what lies behind
#: them (a hole, filled): neighbouring thinned samples of one stroke or traced edge lie 1 to 2
#: spacings apart, so a stroke encloses what it passes, not opens it to the outside.
MOUTH_SPACINGS = 2.0
#: Arcs up to this many thinning spacings long are traced (consecutive samples of a slow
#: stroke along the edge, 1 to 1.25 spacings apart); sparse data leave arcs of 2 and more.
TRACED_SPACINGS = 1.25
#: A concave corner turns the loop by at least this much (deg) over one arc: a traced corner
#: is bridged by one or two arcs turning 60-100 deg together, dents of sparse loops less
#: where their neighbours are traced.
CORNER_TURN_DEG = 60.0
#: Growth factor floor of the thinning spacing while the thinned samples exceed the cap: at
#: least 5 % a step, so the loop ends within a few steps.
THIN_GROWTH = 1.05
#: Version of what a fit builds from given samples, raised whenever the construction changes
#: the region some data give: cached `limbctl eval` results are keyed on it. Saved models carry
#: their mesh and keep answering as they did (their format is ``GATE_VERSION``'s business).
FIT_VERSION = 9
#: While the supported edge bridges a stretch the samples surround but do not reach, the
#: triangle behind each such station is carved out, at most CARVE_ROUNDS rounds: a bay bridged
#: by the shape is a few triangles deep (a 10 deg bay at the 1-2 deg spacing of thinned hand
#: strokes), so 12 rounds empty the bays of the families in docs/bench_swing_families.md.
CARVE_ROUNDS = 12
#: Carving may leave out at most this share of the taught samples the first shape held: a
#: bay's bridge holds no samples, so carving it loses none; a carve that starts dropping
#: samples is eating into sparse data, not a bay.
CARVE_LOSS = 0.002


#: How near (deg) the edge is held to the taught samples wherever a station of it stands
#: farther (:func:`limbctl.region.edge_hold.hold_to_evidence`), so that it lies within 1 deg of
#: any truth holding the samples: the hold's chords stand up to ~0.25 deg past its reach
#: (tests/region/test_edge_hold.py's strict xfail). At REACH_DEG (1.25) the swing families'
#: dense and hand teachings lay up to 1.14 deg past the truth; at 0.8, 0.77 (outlines 8-15 of
#: benchmarks/bench_swing_families.py, not tuned on), coverage 2 deg inside at least 99.94 %.
#: Where the hold at this reach leaves a station farther than REACH_DEG (sparse teachings,
#: whose hold then cuts across the samples' dents), the hold at REACH_DEG is kept.
HOLD_REACH_DEG = 0.8


class TaughtRegion:
    """The region of limb directions the gate enforces (see the module docstring).

    Parameters
    ----------
    params : RegionParams, optional
        The settings; the defaults when None.

    Attributes
    ----------
    mesh : DirectionMesh or None
        The region's mesh once fitted or loaded.
    edge : str
        The edge strategy taken (``"smooth"``, ``"traced"`` or ``"supported"``).
    verdicts : tuple of Verdict
        Every strategy judged by the last :meth:`fit`, in order (empty after loading).
    support_index : ndarray (K,) int or None
        The rows of the fitted samples the shape was built on (thinned), after :meth:`fit`.
    unsupported_edge : tuple of Stretch
        Stretches of the kept edge farther than ``REACH_DEG`` from every taught sample
        (:mod:`limbctl.region.evidence`), farthest first, each marked ``held`` when the region
        was held there; empty after loading.
    held_edge : bool
        Whether the region was held to the evidence (:mod:`limbctl.region.edge_hold`); False
        after loading.
    """

    def __init__(self, params: RegionParams | None = None) -> None:
        self.params = params if params is not None else RegionParams()
        self.mesh: DirectionMesh | None = None
        self.edge = "supported"
        self.verdicts: tuple[Verdict, ...] = ()
        self.support_index: np.ndarray | None = None
        self.unsupported_edge: tuple[Stretch, ...] = ()
        self.held_edge = False

    # ---- building ----------------------------------------------------------------------------
    def fit(self, samples: np.ndarray, lookup: bool = True) -> TaughtRegion:
        """Build the region from taught ``samples``: directions (N, 3) or quaternions (N, 4).

        With ``lookup`` the region's lookup grid is built too, ready for the gate; without,
        it is built when first needed (a live view that only draws the loops never needs it).
        """
        d = taught_directions(samples)
        self.support_index, spacing = self._thinned(d)
        self.mesh = self._build(d[self.support_index], d, spacing)
        if lookup:
            self.mesh.build_lookup()
        return self

    def _thinned(self, d: np.ndarray) -> tuple[np.ndarray, float]:
        """Rows of ``d`` (N, 3) kept by thinning, at most ``support_nodes`` of them, and the
        spacing (rad) that kept them."""
        spacing = np.radians(self.params.thin_deg)
        while True:
            keep = rs.thin(d, spacing)
            if keep.size <= self.params.support_nodes:
                return keep, spacing
            # area per sample ~ spacing^2: grow the spacing to fit the cap
            spacing *= max(THIN_GROWTH, np.sqrt(keep.size / self.params.support_nodes))

    def _build(self, d: np.ndarray, d_train: np.ndarray, thinning: float) -> DirectionMesh:
        """The mesh from the thinned directions (K, 3), all taught directions (N, 3) and the
        thinning's spacing (rad)."""
        p = self.params
        alpha = rs.learn_alpha(d, p.alpha_factor)
        self.edge, self.verdicts, self.unsupported_edge = "supported", (), ()
        self.held_edge = False
        tri, kept = self._shape(d, thinning, alpha)
        if tri is None:
            return DirectionMesh.from_loops([], 0.0)
        built = self._supported_loops(d, d_train, thinning, tri, kept)
        held_first = float(np.mean(built[2].contains(d_train)))
        for _ in range(CARVE_ROUNDS):
            stations, _, _, bad = unsupported_stations(built[2], d_train)
            if bad.size == 0:
                break
            carved = rs.carve(d, tri, kept, stations[bad])
            if np.array_equal(carved, kept):
                break
            trial = self._supported_loops(d, d_train, thinning, tri, carved)
            if float(np.mean(trial[2].contains(d_train))) < held_first - CARVE_LOSS:
                # carving ate into the taught samples: not a bay; the shape before stays, its
                # stretches reported
                break
            built, kept = trial, carved
        loops, margins, supported = built
        taken, self.verdicts = choose_edge(
            p.edge, loops, d_train, supported, np.radians(p.max_offset_deg)
        )
        self.edge = taken.strategy
        # judged on the edge the region keeps: wherever it lies farther than REACH_DEG from
        # every taught sample it may lie that far past the truth
        self.unsupported_edge = tuple(
            unsupported_stretches(taken.region, d_train, np.radians(REACH_DEG), surrounded=False)
        )
        # containment over coverage: the edge is held to HOLD_REACH_DEG of the evidence, or,
        # where that hold still leaves a station beyond REACH_DEG, to REACH_DEG
        region, self.held_edge = hold_to_evidence(taken.region, d_train, np.radians(HOLD_REACH_DEG))
        if self.held_edge and _farthest_station(region, d_train) > np.radians(REACH_DEG):
            region, self.held_edge = taken.region, False
        if not self.held_edge and self.unsupported_edge:
            region, self.held_edge = hold_to_evidence(taken.region, d_train)
        if self.held_edge:
            self.unsupported_edge = tuple(replace(s, held=True) for s in self.unsupported_edge)
        return region

    def _shape(
        self, d: np.ndarray, thinning: float, alpha: float
    ) -> tuple[np.ndarray | None, np.ndarray | None]:
        """Steps 2-3: the triangles (T, 3) over ``d`` and which are kept after the peel, or
        (None, None) when the alpha complex keeps none."""
        p = self.params
        tri, _, inside = rs.alpha_complex(d, alpha, max_hole=0.0)
        area = float(rs.triangle_area(d, tri[inside]).sum())
        # gaps up to MOUTH_SPACINGS thinning spacings close a hole
        mouth = MOUTH_SPACINGS * thinning
        tri, _, inside = rs.alpha_complex(d, alpha, max_hole=p.hole_fraction * area, mouth=mouth)
        if not inside.any():
            return None, None
        length = self._peel_length(d)
        protected = rs.surrounded(
            rs.tri_centroids(d, tri), d, np.radians(p.surround_deg), np.radians(SURROUND_GAP_DEG)
        )
        return tri, rs.peel(d, tri, inside, length, protected)

    def _peel_length(self, d: np.ndarray) -> float:
        """The peel length (rad): peel_factor x the median spacing of the support (nearest
        neighbour), at least min_peel_deg: an exposed edge longer than that bridges a gap."""
        spacing, _ = cKDTree(d).query(d, k=2)
        return max(
            np.radians(self.params.min_peel_deg),
            self.params.peel_factor * 2.0 * np.arcsin(0.5 * float(np.median(spacing[:, 1]))),
        )

    def _supported_loops(
        self, d: np.ndarray, d_train: np.ndarray, thinning: float, tri: np.ndarray, kept
    ) -> tuple[list[np.ndarray], list[np.ndarray], DirectionMesh]:
        """Step 4 on the kept triangles: the supported loops, their margins and the supported
        region (lookup grid not built)."""
        p = self.params
        length = self._peel_length(d)
        loops = [d[idx] for idx in rs.trace_loops(d, boundary_edges(tri[kept]))]
        margins = rs.edge_margins(
            loops,
            d_train,
            EDGE_WINDOW * length,
            ORDER_STATISTICS,
            np.radians(p.max_margin_deg),
            max_bridge=BRIDGE_FRACTION * length,
            traced_arc=TRACED_SPACINGS * thinning,
            corner_turn=np.radians(CORNER_TURN_DEG),
        )
        # the lookup grid waits until this region is taken (fit) or first asked (gate)
        return loops, margins, DirectionMesh.from_loops(loops, margins, lookup=False)

    # ---- answering ---------------------------------------------------------------------------
    def _mesh(self) -> DirectionMesh:
        if self.mesh is None:
            raise ConfigError("this region is not built: call fit(samples) or load a model")
        return self.mesh

    def contains(self, q: np.ndarray) -> np.ndarray | bool:
        """Whether each limb direction of ``q`` ((N, 4) or (4,)) lies in the region."""
        args = self._mesh().kernel_args()
        arr = np.asarray(q, dtype=np.float64) if isinstance(q, np.ndarray) else None
        if arr is not None and arr.shape == (4,):
            # fast path for one command (the gate's final check, every cycle): no thread pool
            _, one = ck.correct_single(arr, *args)
            if one < 0:
                as_quaternions(q)
            return bool(one == 1)
        arr, single = as_quaternions(q)
        _, status = ck.correct_rows(np.ascontiguousarray(arr), *args)
        inside = status == 1
        return bool(inside[0]) if single else inside

    def contains_from_arcs(self, q: np.ndarray) -> np.ndarray:
        """:meth:`contains` of a batch ``q`` (N, 4) -> (N,) bool, answered from the region's arcs
        (:meth:`DirectionMesh.contains_from_arcs`): the same answers, without compiling the
        gate's kernels in a process that never gates (train's summary;
        docs/decisions/first_run.md). The limb directions are those the gate's kernel computes,
        operation for operation."""
        arr, _ = as_quaternions(q)
        w, x, y, z = arr[:, 0], arr[:, 1], arr[:, 2], arr[:, 3]
        # d = (w^2 + x^2 - y^2 - z^2, 2(xy + wz), 2(xz - wy)) / |d|, as correct_kernels does
        d = np.stack(
            [w * w + x * x - y * y - z * z, 2.0 * (x * y + w * z), 2.0 * (x * z - w * y)], axis=1
        )
        norm = np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2])
        return self._mesh().contains_from_arcs(d / norm[:, None])

    def correct(self, q: np.ndarray) -> np.ndarray:
        """``q`` itself inside the region; outside, the nearest region orientation (twist kept)."""
        args = self._mesh().kernel_args()
        arr = np.asarray(q, dtype=np.float64) if isinstance(q, np.ndarray) else None
        if arr is not None and arr.shape == (4,):
            # fast path for one command: the kernel checks finiteness and norm itself
            out, status = ck.correct_single(arr, *args)
            if status < 0:
                as_quaternions(q)
            return out
        arr, single = as_quaternions(q)
        out, _ = ck.correct_rows(np.ascontiguousarray(arr), *args)
        return out[0] if single else out

    # ---- persistence -------------------------------------------------------------------------
    def arrays(self) -> dict[str, np.ndarray]:
        """The mesh's arrays, everything needed to answer without rebuilding (for saving)."""
        return self._mesh().arrays()

    @classmethod
    def from_arrays(
        cls, arrays: dict[str, np.ndarray], params: RegionParams, edge: str
    ) -> TaughtRegion:
        """Inverse of :meth:`arrays`, with the settings and the edge taken when it was fitted."""
        region = cls(params)
        region.mesh = DirectionMesh.from_arrays(arrays)
        region.edge = edge
        return region


def taught_directions(samples: np.ndarray) -> np.ndarray:
    """Limb directions (N, 3) of taught ``samples``: directions (N, 3) or quaternions (N, 4).

    Raises
    ------
    InvalidInputError
        For fewer than 3 samples, another shape, non-finite values or non-unit rows.
    """
    arr = np.asarray(samples, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] not in (3, 4):
        raise InvalidInputError(
            f"samples: need directions (N, 3) or quaternions (N, 4), got shape {arr.shape}"
        )
    if arr.shape[0] < 3:
        raise InvalidInputError(f"samples: need at least 3, got {arr.shape[0]}")
    if arr.shape[1] == 4:
        q, _ = as_quaternions(arr, name="samples")
        return limb_direction(q)
    norm = np.linalg.norm(arr, axis=1)
    if not (np.all(np.isfinite(arr)) and np.all(np.abs(norm - 1.0) <= UNIT_TOLERANCE)):
        raise InvalidInputError("samples: directions must be finite unit vectors")
    return arr


def _farthest_station(mesh: DirectionMesh, data: np.ndarray) -> float:
    """The largest angle (rad) from a station of ``mesh``'s outer loops to its nearest taught
    direction of ``data`` (N, 3)."""
    stations, arc = edge_stations(mesh, np.radians(STATION_DEG))
    outer = stations[outer_arcs(mesh)[arc]]
    if outer.shape[0] == 0:
        return 0.0
    gap = cKDTree(data).query(outer)[0]
    return float(2.0 * np.arcsin(min(1.0, gap.max() / 2.0)))
