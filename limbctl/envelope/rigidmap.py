"""The interpolated Rigid Map (Jenkins & Angel), and the exact gate built on it.

``respond`` is the papers' network, faithfully: node positions fixed on S^3 by a layout, weights
trained from valid orientations only (winner by position while training, Table I's exponential
schedules, see :mod:`limbctl.envelope.rigidmap_kernels`), winner by weight when answering,
optionally interpolated with the runner-ups.

``contains``/``correct`` make that system exact, on top of the trained map
(:mod:`limbctl.region.shape` holds the geometry):

1. *Support refinement*: a second layer of nodes is placed where the data lies: positions at
   training orientations thinned to at least ``thin_deg`` apart (outermost kept; at most
   ``support_nodes``, the spacing grows until they fit), weights initialised with the trained
   map's geometric-interpolated answer there and trained by the same rule and schedule on all
   the data (``support_weights``: the papers' answering rule on nodes where the data lie, which
   `limbctl eval` scores).
2. *Region shape*: the gate's shape is built on those nodes' *positions* (real taught
   samples, the outermost kept), not on their weights: a trained weight is the mean of the
   samples it wins, so the outermost weights sit inside the outermost samples and a shape on
   them refuses taught poses. The positions' limb directions are triangulated (spherical
   Delaunay); triangles with circumradius at most ``alpha`` are kept, where ``alpha`` is
   learned from the data's scale (``alpha_factor`` times the 90th percentile of the
   empty-circle radii of the gaps the samples enclose), and holes smaller than
   ``hole_fraction`` of the region are filled: the gaps between a hand's strokes close.
3. *Peel*: a large alpha also bridges concavities and bays open to the outside. Outside
   triangles whose exposed edge is longer than ``peel_factor`` times the support's median
   nearest-neighbour spacing (at least ``min_peel_deg``) and whose middle the samples do not
   surround (samples within ``surround_deg`` leave an empty sector wider than
   ``SURROUND_GAP_DEG``) are peeled away, longest first (a chi-shape): the boundary runs
   through taught samples, corners and concavities stay as taught, nothing is smoothed.
4. *Learned edge*: each boundary arc is widened by where the data say the true edge lies (the
   outermost samples' depths and the spacing of their order statistics), at least to every
   sample beyond it, at most ``max_margin_deg``: the region never reaches more than that
   beyond the data-supported shape. Arcs longer than ``BRIDGE_FRACTION`` of the peel length
   (bridges across gaps with no sample along them) widen only to cover samples beyond them.
5. *Learned edge* (``smooth_edge``, :mod:`limbctl.region.edge_choice`): each loop is
   replaced by a learned curve moved out to where the outermost samples put the edge (each
   round at most ``max_offset_deg``): the *smooth* edge, local small circles over one window
   (:mod:`limbctl.region.edge_smooth`), or else the *traced* edge, a curve walked out station
   by station that follows eggs, kidneys and bays where the edge is taught densely enough
   (:mod:`limbctl.region.edge_traced`). A learned edge is kept only when the data agree with
   it (no crossing arcs, every taught sample still inside, every stretch it adds one the
   sampling density explains, and for the smooth edge no bay and a window that follows the
   loop's shape); otherwise the gate keeps the supported loops of step 4. ``edge`` says which
   one a trained model uses: ``"smooth"``, ``"traced"`` or ``"supported"``.

``contains(q)`` asks whether the limb direction lies in that region; ``correct(q)`` returns
``q`` itself then, otherwise the orientation whose limb direction is the nearest direction of
the region (exact: great-circle boundary arcs), keeping the twist about the limb. Both answer
from one precomputed grid over directions in O(1) per command.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from scipy.spatial import cKDTree

from limbctl.envelope import rigidmap_kernels as rk
from limbctl.envelope.base import Envelope
from limbctl.envelope.layouts import make_layout
from limbctl.errors import ConfigError, InvalidInputError
from limbctl.geometry.quat import as_quaternions, limb_direction
from limbctl.region import shape as rs
from limbctl.region.edge_choice import learned_edge
from limbctl.region.mesh import DirectionMesh, boundary_edges

#: Outermost samples per boundary window used to estimate the gap to the true edge.
EDGE_ORDER_STATISTICS = 12
#: Half width of the boundary windows (along the loop), in units of the peel length.
EDGE_WINDOW = 1.5
#: A point is surrounded by samples when no empty sector about it is wider than this (deg).
SURROUND_GAP_DEG = 165.0
#: Arcs longer than this fraction of the peel length count as bridges (no learned widening).
BRIDGE_FRACTION = 0.75
#: Version of the gate's saved arrays; models of older versions must be retrained.
GATE_VERSION = 6


class RigidMap(Envelope):
    """Interpolated Rigid Map over S^3 with an exact gate (see the module docstring).

    Parameters
    ----------
    nodes : int
        Output nodes of the papers' map (for polytope layouts: their count or None).
    layout : str
        Node layout name (see :func:`limbctl.envelope.layouts.make_layout`).
    seed : int
        Seeds the layout (``uniform``) and the order patterns are presented in.
    learning_rate, learning_rate_decay : float
        ``lr(t) = learning_rate exp(-learning_rate_decay t)`` (Table I: 1.0, 0.15).
    radius, radius_decay : float
        ``sigma(t) = radius exp(-radius_decay t)`` in radians (Table I: 2 pi, 1.0).
    neighbourhood : float
        Nodes with ``exp(-theta^2 / (2 sigma^2)) >= neighbourhood`` update (Table I: 0.04).
    max_epochs : int
        Table I: 1000. Training stops earlier once no weight moves more than ``tol``.
    metric : {"euclidean", "cosine"}
        Distance used to pick winners (Table I).
    support_nodes : int
        Largest number of refinement nodes placed on the data for the gate.
    thin_deg : float
        Smallest spacing (degrees) of the refinement nodes' positions.
    alpha_factor, hole_fraction, peel_factor : float
        Gate shape parameters (module docstring).
    min_peel_deg, surround_deg : float
        Shortest exposed edge (degrees) the peel removes; radius (degrees) of the
        neighbourhood whose samples must surround a triangle for it to stay.
    max_margin_deg : float
        How far (degrees) the learned edge may lie beyond the data-supported shape.
    smooth_edge : bool
        Try the learned edges of step 5 (each kept only when the data agree with it); False
        keeps the supported loops.
    max_offset_deg : float
        The most (degrees) a learned edge is moved out in one step (beyond the smooth edge's
        fitted curve; beyond the traced curve in one round).
    """

    kind: ClassVar[str] = "rigidmap"
    settable: ClassVar[tuple[str, ...]] = ("seed", "nodes", "layout")

    def __init__(
        self,
        nodes: int | None = 2000,
        layout: str = "uniform",
        seed: int = 0,
        learning_rate: float = 1.0,
        learning_rate_decay: float = 0.15,
        radius: float = 2.0 * np.pi,
        radius_decay: float = 1.0,
        neighbourhood: float = 0.04,
        max_epochs: int = 1000,
        tol: float = 1e-9,
        metric: str = "euclidean",
        support_nodes: int = 3000,
        thin_deg: float = 1.0,
        alpha_factor: float = 2.0,
        hole_fraction: float = 0.2,
        peel_factor: float = 8.0,
        min_peel_deg: float = 4.0,
        surround_deg: float = 6.0,
        max_margin_deg: float = 0.75,
        smooth_edge: bool = True,
        max_offset_deg: float = 3.0,
    ) -> None:
        if metric not in rk.METRICS:
            raise ConfigError(f"unknown metric {metric!r}; choose one of: {', '.join(rk.METRICS)}")
        if not 0.0 < neighbourhood <= 1.0:
            raise ConfigError(f"neighbourhood must be in (0, 1], got {neighbourhood}")
        if int(max_epochs) < 1 or int(support_nodes) < 3:
            raise ConfigError("max_epochs must be >= 1 and support_nodes >= 3")
        for name, value in (
            ("thin_deg", thin_deg),
            ("alpha_factor", alpha_factor),
            ("peel_factor", peel_factor),
            ("min_peel_deg", min_peel_deg),
            ("surround_deg", surround_deg),
        ):
            if not value > 0.0:
                raise ConfigError(f"{name} must be > 0, got {value}")
        if not (hole_fraction >= 0.0 and max_margin_deg >= 0.0 and max_offset_deg >= 0.0):
            raise ConfigError("hole_fraction, max_margin_deg and max_offset_deg must be >= 0")
        self.nodes = nodes
        self.layout = layout
        self.seed = int(seed)
        self.learning_rate = float(learning_rate)
        self.learning_rate_decay = float(learning_rate_decay)
        self.radius = float(radius)
        self.radius_decay = float(radius_decay)
        self.neighbourhood = float(neighbourhood)
        self.max_epochs = int(max_epochs)
        self.tol = float(tol)
        self.metric = metric
        self.support_nodes = int(support_nodes)
        self.thin_deg = float(thin_deg)
        self.alpha_factor = float(alpha_factor)
        self.hole_fraction = float(hole_fraction)
        self.peel_factor = float(peel_factor)
        self.min_peel_deg = float(min_peel_deg)
        self.surround_deg = float(surround_deg)
        self.max_margin_deg = float(max_margin_deg)
        self.smooth_edge = bool(smooth_edge)
        self.max_offset_deg = float(max_offset_deg)
        #: Which edge the gate uses: "smooth" (fitted, step 5) or "supported" (steps 2-4).
        self.edge = "supported"
        self.positions = make_layout(layout, nodes, seed=seed)
        self._weights: np.ndarray | None = None
        self.support_positions: np.ndarray | None = None
        self.support_weights: np.ndarray | None = None
        self.mesh: DirectionMesh | None = None
        self.epochs = 0
        self._topology = rk.position_topology(self.positions, 16)

    # ---- learning ----------------------------------------------------------------------------
    def _train(self, positions: np.ndarray, weights: np.ndarray, patterns: np.ndarray) -> int:
        return rk.train_rigid_map(
            positions,
            weights,
            patterns,
            self.learning_rate,
            self.learning_rate_decay,
            self.radius,
            self.radius_decay,
            self.neighbourhood,
            self.max_epochs,
            self.tol,
        )

    def fit(self, q_train: np.ndarray) -> RigidMap:
        """Train the map, then its support refinement and the gate, from valid ``q_train``."""
        q, _ = as_quaternions(q_train, name="q_train")
        if q.shape[0] < 3:
            raise InvalidInputError(f"q_train: need at least 3 orientations, got {q.shape[0]}")
        rng = np.random.default_rng(self.seed)
        patterns = np.ascontiguousarray(q[rng.permutation(q.shape[0])])
        weights = self.positions.copy()
        self.epochs = self._train(self.positions, weights, patterns)
        self._weights = weights
        # refinement: nodes where the data lies, starting from the map's answer there
        d_train = limb_direction(q)
        support = np.ascontiguousarray(q[self._support_indices(d_train)])
        self.support_positions = support
        support_weights = self.respond(support, interpolation="geometric", k=8)
        self._train(support, support_weights, patterns)
        self.support_weights = support_weights
        self.mesh = self._build_mesh(support, d_train)
        return self

    def _support_indices(self, d: np.ndarray) -> np.ndarray:
        """Training rows for the refinement nodes: thinned, at most ``support_nodes``."""
        spacing = np.radians(self.thin_deg)
        while True:
            keep = rs.thin(d, spacing)
            if keep.size <= self.support_nodes:
                return keep
            # area per node ~ spacing^2: grow the spacing to fit the cap
            spacing *= max(1.05, np.sqrt(keep.size / self.support_nodes))

    def _build_mesh(self, support: np.ndarray, d_train: np.ndarray) -> DirectionMesh:
        """The gate's region from the support orientations (K, 4) and all taught directions."""
        d = limb_direction(support)
        alpha = rs.learn_alpha(d, self.alpha_factor)
        tri, _, inside = rs.alpha_complex(d, alpha, max_hole=0.0)
        area = float(rs.triangle_area(d, tri[inside]).sum())
        tri, _, inside = rs.alpha_complex(d, alpha, max_hole=self.hole_fraction * area)
        if not inside.any():
            return DirectionMesh.from_loops([], 0.0)
        # peel length: peel_factor x the median spacing of the support (nearest neighbour),
        # at least min_peel_deg: an exposed edge longer than that bridges a gap in the data
        spacing, _ = cKDTree(d).query(d, k=2)
        length = max(
            np.radians(self.min_peel_deg),
            self.peel_factor * 2.0 * np.arcsin(0.5 * float(np.median(spacing[:, 1]))),
        )
        protected = rs.surrounded(
            rs.tri_centroids(d, tri),
            d,
            np.radians(self.surround_deg),
            np.radians(SURROUND_GAP_DEG),
        )
        kept = rs.peel(d, tri, inside, length, protected)
        loops = [d[idx] for idx in rs.trace_loops(d, boundary_edges(tri[kept]))]
        margins = rs.edge_margins(
            loops,
            d_train,
            EDGE_WINDOW * length,
            EDGE_ORDER_STATISTICS,
            np.radians(self.max_margin_deg),
            max_bridge=BRIDGE_FRACTION * length,
        )
        supported = DirectionMesh.from_loops(loops, margins)
        self.edge = "supported"
        if not self.smooth_edge:
            return supported
        learned = learned_edge(loops, d_train, supported, np.radians(self.max_offset_deg))
        if learned is None:
            return supported
        self.edge, region = learned
        return region

    # ---- answering ---------------------------------------------------------------------------
    def _trained(self) -> None:
        if self._weights is None or self.mesh is None:
            raise ConfigError("this RigidMap is not trained: call fit(q_train) or load a model")

    def respond(self, q: np.ndarray, interpolation: str = "none", k: int = 8) -> np.ndarray:
        """The papers' answer: winner by weight, interpolated with ``k`` runner-ups.

        ``interpolation``: ``none``, ``idw``, ``geometric`` (d = w_k - y),
        ``geometric-winner`` (d = w_k - w_c) or ``topological`` (runner-ups are the winner's
        nearest nodes by position). Returns unit quaternions shaped like ``q``.
        """
        if self._weights is None:
            raise ConfigError("this RigidMap is not trained: call fit(q_train) or load a model")
        if interpolation not in rk.INTERPOLATIONS:
            raise ConfigError(
                f"unknown interpolation {interpolation!r}; choose one of: "
                f"{', '.join(rk.INTERPOLATIONS)}"
            )
        top = self._topology.shape[1] if interpolation == "topological" else self._weights.shape[0]
        if not 0 <= int(k) <= top:
            raise ConfigError(f"k must be in 0..{top} for {interpolation} interpolation")
        arr, single = self._input(q)
        out = rk.respond_batch(
            self._weights,
            arr,
            int(k),
            rk.METRICS[self.metric],
            rk.INTERPOLATIONS[interpolation],
            self._topology,
        )
        return out[0] if single else out

    def _mesh_args(self) -> tuple:
        return self.mesh.kernel_args()

    def contains(self, q: np.ndarray) -> np.ndarray | bool:
        """Whether each limb direction lies in the learned region: (N,) bool or bool."""
        self._trained()
        arr = np.asarray(q, dtype=np.float64) if isinstance(q, np.ndarray) else None
        if arr is not None and arr.shape == (4,):
            # fast path for one command (the gate's final check, every cycle): no thread pool
            _, one = rk.correct_single(arr, *self._mesh_args())
            if one < 0:
                as_quaternions(q)
            return bool(one == 1)
        arr, single = self._input(q)
        _, status = rk.correct_batch(arr, *self._mesh_args())
        inside = status == 1
        return bool(inside[0]) if single else inside

    def correct(self, q: np.ndarray) -> np.ndarray:
        """``q`` itself inside the region; outside, the nearest region orientation (twist kept)."""
        self._trained()
        arr = np.asarray(q, dtype=np.float64) if isinstance(q, np.ndarray) else None
        if arr is not None and arr.shape == (4,):
            # fast path for one command: the kernel checks finiteness and norm itself
            out, status = rk.correct_single(arr, *self._mesh_args())
            if status < 0:
                as_quaternions(q)
            return out
        arr, single = self._input(q)
        out, _ = rk.correct_batch(arr, *self._mesh_args())
        return out[0] if single else out

    @property
    def weights(self) -> np.ndarray:
        """Trained weights of the papers' map (nodes, 4)."""
        self._trained()
        return self._weights

    # ---- persistence -------------------------------------------------------------------------
    def _params(self) -> dict[str, Any]:
        return {
            "nodes": self.nodes,
            "layout": self.layout,
            "seed": self.seed,
            "learning_rate": self.learning_rate,
            "learning_rate_decay": self.learning_rate_decay,
            "radius": self.radius,
            "radius_decay": self.radius_decay,
            "neighbourhood": self.neighbourhood,
            "max_epochs": self.max_epochs,
            "tol": self.tol,
            "metric": self.metric,
            "support_nodes": self.support_nodes,
            "thin_deg": self.thin_deg,
            "alpha_factor": self.alpha_factor,
            "hole_fraction": self.hole_fraction,
            "peel_factor": self.peel_factor,
            "min_peel_deg": self.min_peel_deg,
            "surround_deg": self.surround_deg,
            "max_margin_deg": self.max_margin_deg,
            "smooth_edge": self.smooth_edge,
            "max_offset_deg": self.max_offset_deg,
            "edge": self.edge,
            "gate_version": GATE_VERSION,
            "epochs": self.epochs,
        }

    def _arrays(self) -> dict[str, np.ndarray]:
        self._trained()
        return {
            "positions": self.positions,
            "weights": self._weights,
            "support_positions": self.support_positions,
            "support_weights": self.support_weights,
            **self.mesh.arrays(),
        }

    @classmethod
    def _restore(cls, params: dict[str, Any], arrays: dict[str, np.ndarray]) -> RigidMap:
        params = dict(params)
        if params.pop("gate_version", 1) != GATE_VERSION:
            raise ValueError("saved by an older limbctl gate; retrain with `limbctl train`")
        epochs = int(params.pop("epochs"))
        edge = str(params.pop("edge"))
        model = cls(**params)
        model.edge = edge
        model.positions = np.ascontiguousarray(arrays["positions"], dtype=np.float64)
        model._topology = rk.position_topology(model.positions, 16)
        model._weights = np.ascontiguousarray(arrays["weights"], dtype=np.float64)
        model.support_positions = np.ascontiguousarray(arrays["support_positions"])
        model.support_weights = np.ascontiguousarray(arrays["support_weights"])
        model.mesh = DirectionMesh.from_arrays(arrays)
        model.epochs = epochs
        return model
