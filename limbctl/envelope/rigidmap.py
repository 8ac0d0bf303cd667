"""The interpolated Rigid Map (Jenkins & Angel), and the exact gate built on it: ``respond`` is
the papers' network, ``contains``/``correct`` ask the taught region (docs/region.md);
``support_weights`` are a second layer on the region's thinned samples (``limbctl eval``)."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from limbctl.envelope import rigidmap_kernels as rk
from limbctl.envelope.base import Envelope
from limbctl.envelope.layouts import make_layout
from limbctl.errors import ConfigError, InvalidInputError
from limbctl.geometry.quat import as_quaternions
from limbctl.region.mesh import DirectionMesh
from limbctl.region.params import RegionParams
from limbctl.region.taught import TaughtRegion
from limbctl.region.twist_region import TwistRegion

#: Version of the gate's saved arrays; models of older versions must be retrained.
GATE_VERSION = 6
#: Nearest nodes kept per node for ``topological`` answers: twice the papers' 8 runner-ups.
TOPOLOGY_NEIGHBOURS = 16
#: Runner-ups of the geometric answer the support weights start from: the papers' 8.
SUPPORT_START_K = 8
#: The attributes that are :func:`rigidmap_kernels.train_rigid_map`'s schedule, in its order.
_SCHEDULE = (
    "learning_rate learning_rate_decay radius radius_decay neighbourhood max_epochs tol".split()
)
#: The region settings that models saved before RegionParams kept among the map's parameters.
_FLAT_REGION_KEYS = tuple(
    "support_nodes thin_deg alpha_factor hole_fraction peel_factor min_peel_deg surround_deg "
    "max_margin_deg max_offset_deg".split()
)


class RigidMap(Envelope):
    """Interpolated Rigid Map over S^3 with an exact gate.

    Parameters
    ----------
    nodes, layout, seed : int, str, int
        The papers' map: output nodes (a polytope's count or None) on a layout of
        :func:`~limbctl.envelope.layouts.make_layout`; ``seed`` seeds it and the pattern order.
    learning_rate, learning_rate_decay : float
        ``lr(t) = learning_rate exp(-learning_rate_decay t)`` (Table I: 1.0, 0.15).
    radius, radius_decay : float
        ``sigma(t) = radius exp(-radius_decay t)`` in radians (Table I: 2 pi, 1.0).
    neighbourhood : float
        Nodes with ``exp(-theta^2 / (2 sigma^2)) >= neighbourhood`` update (Table I: 0.04).
    max_epochs, tol : int, float
        Table I: 1000; training stops earlier once no weight moves more than ``tol``.
    metric : {"euclidean", "cosine"}
        Distance used to pick winners (Table I).
    region, twist : RegionParams or None, bool
        Settings of the taught region the gate enforces; learn swing and twist (three servos).
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
        region: RegionParams | None = None,
        twist: bool = False,
    ) -> None:
        if metric not in rk.METRICS:
            raise ConfigError(f"unknown metric {metric!r}; choose one of: {', '.join(rk.METRICS)}")
        if not 0.0 < neighbourhood <= 1.0:
            raise ConfigError(f"neighbourhood must be in (0, 1], got {neighbourhood}")
        if int(max_epochs) < 1:
            raise ConfigError(f"max_epochs must be >= 1, got {max_epochs}")
        if region is not None and not isinstance(region, RegionParams):
            raise ConfigError(f"region must be a RegionParams, got {type(region).__name__}")
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
        self.twist = bool(twist)
        #: The taught region the gate enforces (built by fit, or loaded).
        self.region: TaughtRegion | TwistRegion = (TwistRegion if self.twist else TaughtRegion)(
            region
        )
        self.positions = make_layout(layout, nodes, seed=seed)
        self._weights: np.ndarray | None = None
        self.support_positions: np.ndarray | None = None
        self.support_weights: np.ndarray | None = None
        self.epochs = 0
        self._topology = rk.position_topology(self.positions, TOPOLOGY_NEIGHBOURS)

    def _train(self, positions: np.ndarray, weights: np.ndarray, patterns: np.ndarray) -> int:
        schedule = (getattr(self, name) for name in _SCHEDULE)
        return rk.train_rigid_map(positions, weights, patterns, *schedule)

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
        # the gate's region, then the refinement from the map's answer on its thinned samples
        self.region = type(self.region)(self.region.params).fit(q)
        support = np.ascontiguousarray(q[self.region.support_index])
        self.support_positions = support
        support_weights = self.respond(support, interpolation="geometric", k=SUPPORT_START_K)
        self._train(support, support_weights, patterns)
        self.support_weights = support_weights
        return self

    @property
    def edge(self) -> str:
        """The edge the gate's region took: ``"smooth"``, ``"traced"`` or ``"supported"``."""
        return self.region.edge

    @property
    def mesh(self) -> DirectionMesh | None:
        """The gate's region as a mesh (None until fitted or loaded)."""
        return self.region.mesh

    def _trained(self) -> None:
        if self._weights is None or self.region.mesh is None:
            raise ConfigError("this RigidMap is not trained: call fit(q_train) or load a model")

    def respond(self, q: np.ndarray, interpolation: str = "none", k: int = 8) -> np.ndarray:
        """The papers' answer (unit, shaped like ``q``), interpolated with ``k`` runner-ups."""
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
        arr, single = as_quaternions(q)
        out = rk.respond_rows(
            self._weights,
            arr,
            int(k),
            rk.METRICS[self.metric],
            rk.INTERPOLATIONS[interpolation],
            self._topology,
        )
        return out[0] if single else out

    def contains(self, q: np.ndarray) -> np.ndarray | bool:
        """Whether each limb direction lies in the taught region: (N,) bool or bool."""
        self._trained()
        return self.region.contains(q)

    def contains_from_arcs(self, q: np.ndarray) -> np.ndarray:
        """:meth:`contains` of a batch (N, 4) without compiling the gate's kernels where it can."""
        self._trained()
        return getattr(self.region, "contains_from_arcs", self.region.contains)(q)

    def correct(self, q: np.ndarray) -> np.ndarray:
        """``q`` itself inside the region; outside, the nearest orientation of the region."""
        self._trained()
        return self.region.correct(q)

    @property
    def weights(self) -> np.ndarray:
        """Trained weights of the papers' map (nodes, 4)."""
        self._trained()
        return self._weights

    def _params(self) -> dict[str, Any]:
        # a swing-only model's header stays as it was before twist (no "twist" key)
        kind = {"twist": True} if self.twist else {}
        return {
            **kind,
            "nodes": self.nodes,
            "layout": self.layout,
            "seed": self.seed,
            **{name: getattr(self, name) for name in _SCHEDULE},
            "metric": self.metric,
            "region": self.region.params.as_dict(),
            "edge": self.region.edge,
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
            **self.region.arrays(),
        }

    @classmethod
    def _restore(cls, params: dict[str, Any], arrays: dict[str, np.ndarray]) -> RigidMap:
        params = dict(params)
        if params.pop("gate_version", 1) != GATE_VERSION:
            raise ValueError("saved by an older limbctl gate; retrain with `limbctl train`")
        epochs = int(params.pop("epochs"))
        twist = bool(params.pop("twist", False))
        edge = str(params.pop("edge"))
        if "region" in params:
            region = RegionParams.from_dict(params.pop("region"))
        else:
            # saved before RegionParams: the settings among the map's, smooth_edge for edge
            flat = {key: params.pop(key) for key in _FLAT_REGION_KEYS if key in params}
            choice = "auto" if params.pop("smooth_edge", True) else "supported"
            region = RegionParams(**flat, edge=choice)
        model = cls(**params, region=region, twist=twist)
        model.positions = np.ascontiguousarray(arrays["positions"], dtype=np.float64)
        model._topology = rk.position_topology(model.positions, TOPOLOGY_NEIGHBOURS)
        model._weights = np.ascontiguousarray(arrays["weights"], dtype=np.float64)
        model.support_positions = np.ascontiguousarray(arrays["support_positions"])
        model.support_weights = np.ascontiguousarray(arrays["support_weights"])
        model.region = (TwistRegion if twist else TaughtRegion).from_arrays(arrays, region, edge)
        model.epochs = epochs
        return model
