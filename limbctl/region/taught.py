"""The taught region the gate enforces, built from the positions of taught samples.

:class:`TaughtRegion` runs thin, shape, peel, margins (carving bays the shape bridged,
:mod:`limbctl.region.evidence`), edge (:mod:`limbctl.region.edge_choice`; stretches farther than
``REACH_DEG`` from every taught sample held to the evidence, :mod:`limbctl.region.edge_hold`)
and mesh, as docs/region.md describes, with the settings of a
:class:`~limbctl.region.params.RegionParams`. Angles are in radians.
"""

from __future__ import annotations

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
    HOLD_REACH_DEG,
    REACH_DEG,
    Stretch,
    cut_within_reach,
    held_stretches,
    unsupported_stations,
    unsupported_stretches,
)
from limbctl.region.evidence_clip import Clip, clipped_stretches, cut_to_evidence
from limbctl.region.gaps import ORDER_STATISTICS
from limbctl.region.mesh import DirectionMesh, boundary_edges
from limbctl.region.params import RegionParams

#: Margin windows' half width (peel lengths): holds ORDER_STATISTICS samples, stays local.
EDGE_WINDOW = 1.5
#: Widest empty sector (deg) about a surrounded point: an edge's is 180, less scatter.
SURROUND_GAP_DEG = 165.0
#: Arcs longer than this share of the peel length bridge a gap: no learned widening.
BRIDGE_FRACTION = 0.75
#: Gaps up to this many thinning spacings close a hole: a stroke's samples lie 1-2 apart.
MOUTH_SPACINGS = 2.0
#: Arcs up to this many spacings are traced (a slow stroke: 1-1.25); sparse data's 2+.
TRACED_SPACINGS = 1.25
#: Least turn (deg) of a concave corner: traced corners turn 60-100 deg over one arc.
CORNER_TURN_DEG = 60.0
#: Least growth of the thinning spacing a step while over the cap: ends in a few steps.
THIN_GROWTH = 1.05
#: Version of the construction, raised when it changes a region: `limbctl eval`'s cache key.
FIT_VERSION = 22
#: Carving rounds at most: a bridged bay is a few triangles deep; 12 empty the families' bays.
CARVE_ROUNDS = 12
#: Most share of taught samples carving may leave out: a bay's bridge holds none.
CARVE_LOSS = 0.002


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
        Whether the region was held to the evidence (:mod:`limbctl.region.edge_hold`, or cut
        back to it, :mod:`limbctl.region.evidence_clip`); False after loading.
    clip : Clip or None
        What the last cut back to the evidence did (None after loading).
    """

    def __init__(self, params: RegionParams | None = None) -> None:
        self.params = params if params is not None else RegionParams()
        self.mesh: DirectionMesh | None = None
        self.edge = "supported"
        self.verdicts: tuple[Verdict, ...] = ()
        self.support_index: np.ndarray | None = None
        self.unsupported_edge: tuple[Stretch, ...] = ()
        self.held_edge = False
        self.clip: Clip | None = None

    def fit(self, samples: np.ndarray, lookup: bool = True) -> TaughtRegion:
        """Build the region from taught ``samples``: directions (N, 3) or quaternions (N, 4).

        With ``lookup`` the lookup grid is built too; without, when first needed.
        """
        d = taught_directions(samples)
        self.support_index, spacing = self._thinned(d)
        self.mesh = self._clipped(self._build(d[self.support_index], d, spacing), d)
        if lookup:
            self.mesh.build_lookup()
        return self

    def _thinned(self, d: np.ndarray) -> tuple[np.ndarray, float]:
        """Rows of ``d`` (N, 3) thinned to at most ``support_nodes``, and the spacing (rad)."""
        spacing = np.radians(self.params.thin_deg)
        while True:
            keep = rs.thin(d, spacing)
            if keep.size <= self.params.support_nodes:
                return keep, spacing
            # area per sample ~ spacing^2: grow the spacing to fit the cap
            spacing *= max(THIN_GROWTH, np.sqrt(keep.size / self.params.support_nodes))

    def _build(self, d: np.ndarray, d_train: np.ndarray, thinning: float) -> DirectionMesh:
        """The mesh from the thinned (K, 3) and all taught (N, 3) directions, spacing (rad)."""
        p = self.params
        alpha = rs.learn_alpha(d, p.alpha_factor)
        self.edge, self.verdicts, self.unsupported_edge = "supported", (), ()
        self.held_edge = False
        tri, kept = self._shape(d, thinning, alpha)
        if tri is None:
            return DirectionMesh.from_loops([], 0.0)
        built = self._supported_loops(d, d_train, thinning, tri, kept)
        held_first = float(np.mean(built[1].contains(d_train)))
        for _ in range(CARVE_ROUNDS):
            stations, _, _, bad = unsupported_stations(built[1], d_train)
            if bad.size == 0:
                break
            carved = rs.carve(d, tri, kept, stations[bad])
            if np.array_equal(carved, kept):
                break
            trial = self._supported_loops(d, d_train, thinning, tri, carved)
            if float(np.mean(trial[1].contains(d_train))) < held_first - CARVE_LOSS:
                # carving ate into the taught samples: not a bay; the shape before stays
                break
            built, kept = trial, carved
        loops, supported, own_read = built
        taken, self.verdicts = choose_edge(
            p.edge, loops, d_train, supported, np.radians(p.max_offset_deg), clip=own_read
        )
        self.edge = taken.strategy
        # judged on the edge the region keeps: farther than REACH_DEG it may lie that far past
        self.unsupported_edge = tuple(
            unsupported_stretches(taken.region, d_train, np.radians(REACH_DEG), surrounded=False)
        )
        if not self.unsupported_edge and not own_read:
            return taken.region
        # own depths put the edge up to REACH_DEG from them (as far past the truth): held too
        # containment over coverage: held to REACH_DEG, then to HOLD_REACH_DEG where that holds;
        # patient (arcs by samples it cannot keep stay at REACH_DEG) only on a region held to
        # REACH_DEG: where that gave up, the samples are too sparse for any hold (a 90 deg cone's
        # 1000 samples: half its edge walked 3 deg in, no containment gained; retried straight
        # it walked 3.85 deg in, docs/decisions/region.md); the cut (_clipped) comes last
        region, self.held_edge = hold_to_evidence(taken.region, d_train)
        tight_reach = np.radians(HOLD_REACH_DEG)
        tight, held_tight = hold_to_evidence(region, d_train, tight_reach, patient=self.held_edge)
        if self.held_edge and not held_tight:
            # walked in, its chain crosses itself or leaves samples out: pulled straight instead
            tight, held_tight = hold_to_evidence(
                region, d_train, tight_reach, patient=True, straight=True
            )
        if held_tight:
            # arcs the patient hold gave back stand at REACH_DEG: pulled straight to the tight reach
            tight = hold_to_evidence(tight, d_train, tight_reach, patient=True, straight=True)[0]
            region, self.held_edge = tight, True
        if self.held_edge:
            self.unsupported_edge = held_stretches(self.unsupported_edge, region, d_train)
        return region

    def _clipped(self, region: DirectionMesh, d_train: np.ndarray) -> DirectionMesh:
        """``region`` with every edge point held within ``CLIP_REACH_DEG`` of the taught
        ``d_train`` (N, 3) (:mod:`limbctl.region.evidence_clip`); each place cut listed as a
        held stretch."""
        if region.edges.shape[0] == 0:
            return region
        clip = self.clip = cut_to_evidence(region, d_train)
        if not clip.cut:
            return region
        self.held_edge = True
        # an unheld place the cut brought within reach is named held
        listed = clipped_stretches(self.unsupported_edge, clip)
        self.unsupported_edge = cut_within_reach(listed, clip.region, d_train)
        return clip.region

    def _shape(
        self, d: np.ndarray, thinning: float, alpha: float
    ) -> tuple[np.ndarray | None, np.ndarray | None]:
        """Triangles (T, 3) over ``d`` and the kept mask after the peel; (None, None) if none."""
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
        """Peel length (rad): ``peel_factor`` median nearest-neighbour spacings, at least
        ``min_peel_deg``.
        """
        spacing, _ = cKDTree(d).query(d, k=2)
        return max(
            np.radians(self.params.min_peel_deg),
            self.params.peel_factor * 2.0 * np.arcsin(0.5 * float(np.median(spacing[:, 1]))),
        )

    def _supported_loops(
        self, d: np.ndarray, d_train: np.ndarray, thinning: float, tri: np.ndarray, kept
    ) -> tuple[list[np.ndarray], DirectionMesh, bool]:
        """The supported loops, their region (no lookup grid) and whether own depths set it."""
        p = self.params
        length = self._peel_length(d)
        loops = [d[idx] for idx in rs.trace_loops(d, boundary_edges(tri[kept]))]
        margins, own_read = rs.edge_margins(
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
        return loops, DirectionMesh.from_loops(loops, margins, lookup=False), own_read

    def _mesh(self) -> DirectionMesh:
        if self.mesh is None:
            raise ConfigError("this region is not built: call fit(samples) or load a model")
        return self.mesh

    def _answer(self, q: np.ndarray):
        """The gate's kernel on ``q`` ((N, 4) or (4,)): corrected orientations and status codes."""
        args = self._mesh().kernel_args()
        arr = np.asarray(q, dtype=np.float64) if isinstance(q, np.ndarray) else None
        if arr is not None and arr.shape == (4,):
            # fast path for one command (every cycle): no thread pool; the kernel checks the input
            out, status = ck.correct_single(arr, *args)
            if status < 0:
                as_quaternions(q)
            return out, status
        arr, single = as_quaternions(q)
        out, status = ck.correct_rows(np.ascontiguousarray(arr), *args)
        return (out[0], status[0]) if single else (out, status)

    def contains(self, q: np.ndarray) -> np.ndarray | bool:
        """Whether each limb direction of ``q`` ((N, 4) or (4,)) lies in the region."""
        inside = self._answer(q)[1] == 1
        return inside if isinstance(inside, np.ndarray) else bool(inside)

    def contains_from_arcs(self, q: np.ndarray) -> np.ndarray:
        """:meth:`contains` of a batch ``q`` (N, 4) -> (N,) bool from the region's arcs.

        The same answers without compiling the gate's kernels (docs/decisions/first_run.md): the
        limb directions are computed as the gate's kernel does, operation for operation.
        """
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
        return self._answer(q)[0]

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
