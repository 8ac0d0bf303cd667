"""The self-organising map of Jenkins & Dacey (UKSim 2011): the project's baseline envelope.
Each pattern's winner (least squared distance) and the nodes within grid distance ``radius(t)``
move ``w += lr(t) (x - w)``, until no winner changes. ``contains(q)``: q within ``threshold``
(the training set's largest distance) of a normalised node; ``correct`` answers the winner."""

from __future__ import annotations

from typing import Any

import numpy as np

from limbctl.envelope import interpolation as ip
from limbctl.envelope.base import Envelope
from limbctl.envelope.som_kernels import train_som
from limbctl.errors import ConfigError
from limbctl.geometry.quat import as_quaternions, canonical


def table_i_schedule(
    max_steps: int = 10_000,
    lr0: float = 1.0,
    lr_min: float = 0.02,
    lr_factor: float = 0.5,
    radius0: float = 4.0,
    radius_min: float = 0.0,
    radius_factor: float = 0.5,
    period: int = 10,
    periods: int = 5,
) -> tuple[np.ndarray, np.ndarray]:
    """The SOM paper's stepwise learning-rate and neighbourhood schedule (Table I).

    Parameters
    ----------
    lr0, lr_min, lr_factor, radius0, radius_min, radius_factor : float
        Initial value, floor, and factor per period of the learning rate and the radius (grid).
    period, periods, max_steps : int
        Time steps per period; periods in the table, the last lasting until ``max_steps``.

    Returns
    -------
    learning_rates, radii : ndarray, shape (max_steps,)
    """
    t = np.arange(max_steps)
    p = np.minimum(t // period, periods - 1)
    # lr(t) = max(lr0 * factor^p, lr_min)
    learning_rates = np.maximum(lr0 * lr_factor**p, lr_min)
    # radius(t) = max(radius0 * factor^p, radius_min)
    radii = np.maximum(radius0 * radius_factor**p, radius_min)
    return learning_rates.astype(np.float64), radii.astype(np.float64)


class SOM(Envelope):
    """Kohonen SOM over unit quaternions, trained on valid orientations (Jenkins & Dacey): a
    ``rows x cols`` grid, initial weights uniform in [-init_scale, init_scale] from ``seed`` (an
    int seed starts each ``fit`` afresh), Table I's schedule (:func:`table_i_schedule`)."""

    kind = "som"
    settable = ("seed",)

    def __init__(
        self,
        rows: int = 30,
        cols: int = 30,
        seed: int | np.random.Generator = 0,
        *,
        max_steps: int = 10_000,
        lr0: float = 1.0,
        lr_min: float = 0.02,
        lr_factor: float = 0.5,
        radius0: float = 4.0,
        radius_min: float = 0.0,
        radius_factor: float = 0.5,
        period: int = 10,
        periods: int = 5,
        init_scale: float = 0.1,
    ) -> None:
        self.rows = _positive_int(rows, "rows")
        self.cols = _positive_int(cols, "cols")
        if not isinstance(seed, np.random.Generator):
            seed = _non_negative_int(seed, "seed")
        self.seed = seed
        self.max_steps = _positive_int(max_steps, "max_steps")
        self.period = _positive_int(period, "period")
        self.periods = _positive_int(periods, "periods")
        self.lr0 = _positive(lr0, "lr0")
        self.lr_min = _positive(lr_min, "lr_min")
        self.lr_factor = _positive(lr_factor, "lr_factor")
        self.radius0 = _non_negative(radius0, "radius0")
        self.radius_min = _non_negative(radius_min, "radius_min")
        self.radius_factor = _positive(radius_factor, "radius_factor")
        self.init_scale = _positive(init_scale, "init_scale")
        if self.lr0 > 1.0 or self.lr_min > 1.0:
            raise ConfigError("SOM: learning rates above 1 overshoot the pattern; use <= 1")
        self._weights: np.ndarray | None = None
        self.threshold: float | None = None
        self.steps: int = 0
        self.converged: bool = False
        self._topology: dict[int, np.ndarray] = {}

    @property
    def nodes(self) -> int:
        """Number of output nodes, rows * cols."""
        return self.rows * self.cols

    def grid(self) -> np.ndarray:
        """Grid coordinates (row, col) of node i = row * cols + col: (nodes, 2) float64."""
        r, c = np.divmod(np.arange(self.nodes), self.cols)
        return np.stack([r, c], axis=1).astype(np.float64)

    def grid_distance(self) -> np.ndarray:
        """Euclidean distance between nodes on the grid: (nodes, nodes) float64."""
        g = self.grid()
        # g_ij = sqrt((r_i - r_j)^2 + (c_i - c_j)^2)
        return np.sqrt(np.sum((g[:, None, :] - g[None, :, :]) ** 2, axis=2))

    def schedule(self) -> tuple[np.ndarray, np.ndarray]:
        """This SOM's (learning_rates, radii) per time step, (max_steps,) each."""
        return table_i_schedule(*(getattr(self, name) for name in _SCHEDULE))

    def initial_weights(self) -> np.ndarray:
        """Small random initial weights, uniform in [-init_scale, init_scale]: (nodes, 4)."""
        rng = (
            self.seed
            if isinstance(self.seed, np.random.Generator)
            else np.random.default_rng(self.seed)
        )
        return rng.uniform(-self.init_scale, self.init_scale, size=(self.nodes, 4))

    def fit(self, q_train: np.ndarray) -> SOM:
        """Train on valid orientations ``q_train`` (N, 4), N >= 1. Returns self."""
        patterns, _ = as_quaternions(q_train)
        if len(patterns) == 0:
            raise ConfigError("SOM.fit: q_train is empty; record some valid orientations first")
        weights = self.initial_weights()
        learning_rates, radii = self.schedule()
        winners = np.full(len(patterns), -1, dtype=np.int64)
        steps, converged = train_som(
            weights, patterns, self.grid_distance(), learning_rates, radii, winners
        )
        self._weights = weights
        self.steps = int(steps)
        self.converged = bool(converged)
        self.threshold = float(np.max(ip.nearest_distance(self._answer_nodes(), patterns)))
        return self

    def respond(self, q: np.ndarray, interpolation: str = "none", k: int = 8) -> np.ndarray:
        """The SOM's answer to ``q`` (4,) or (N, 4), shaped like it, by ``interpolation``."""
        mode = ip.interpolation_code(interpolation)
        k = ip.check_k(k)
        arr, single = as_quaternions(q)
        weights = self.weights
        topology = self._grid_topology(k) if mode == ip.TOPOLOGICAL else _NO_TOPOLOGY
        out = ip.respond_batch(weights, arr, k, ip.EUCLIDEAN, mode, topology)
        return out[0] if single else out

    @property
    def weights(self) -> np.ndarray:
        """Trained weights (nodes, 4), node i at grid (i // cols, i % cols)."""
        if self._weights is None:
            raise ConfigError("SOM is not trained yet: call fit(q_train) or SOM.load(path)")
        return self._weights

    def _answer_nodes(self) -> np.ndarray:
        """The answers the nodes give: normalised, canonical weights (nodes, 4)."""
        w = self.weights
        return np.ascontiguousarray(canonical(w / np.linalg.norm(w, axis=1, keepdims=True)))

    def _inside(self, q: np.ndarray) -> np.ndarray:
        """Distance to the nearest normalised node <= ``threshold``."""
        if self.threshold is None:
            raise ConfigError("SOM is not trained yet: call fit(q_train) or SOM.load(path)")
        distance = ip.nearest_distance(self._answer_nodes(), q)
        # NaN-safe: a NaN distance is never inside
        return distance <= self.threshold

    def _to_boundary(self, q: np.ndarray) -> np.ndarray:
        """The paper's answer ``respond(q, "none")``."""
        return ip.respond_batch(self.weights, q, 1, ip.EUCLIDEAN, ip.NONE, _NO_TOPOLOGY)

    def _grid_topology(self, k: int) -> np.ndarray:
        if k not in self._topology:
            self._topology[k] = ip.neighbours_by_position(self.grid(), k)
        return self._topology[k]

    def _params(self) -> dict[str, Any]:
        self.weights  # noqa: B018 -- refuse to save an untrained SOM
        return {
            "rows": self.rows,
            "cols": self.cols,
            "seed": None if isinstance(self.seed, np.random.Generator) else self.seed,
            **{name: getattr(self, name) for name in _SCHEDULE},
            "init_scale": self.init_scale,
            "threshold": self.threshold,
            "steps": self.steps,
            "converged": self.converged,
        }

    def _arrays(self) -> dict[str, np.ndarray]:
        return {"weights": self.weights}

    @classmethod
    def _restore(cls, params: dict[str, Any], arrays: dict[str, np.ndarray]) -> SOM:
        p = dict(params)
        seed = p.pop("seed")
        threshold = float(p.pop("threshold"))
        steps = int(p.pop("steps"))
        converged = bool(p.pop("converged"))
        # a Generator seed is saved as None; the reloaded SOM refits from seed 0
        som = cls(seed=0 if seed is None else seed, **p)
        weights = np.asarray(arrays["weights"], dtype=np.float64)
        if weights.shape != (som.nodes, 4) or not np.isfinite(weights).all():
            raise ValueError(f"weights must be finite, shape ({som.nodes}, 4); got {weights.shape}")
        som._weights = weights
        som.threshold = threshold
        som.steps = steps
        som.converged = converged
        return som

    def __repr__(self) -> str:
        state = f"trained, {self.steps} steps" if self._weights is not None else "untrained"
        return f"SOM(rows={self.rows}, cols={self.cols}, seed={self.seed!r}; {state})"


_NO_TOPOLOGY = np.empty((0, 0), dtype=np.int64)
#: The attributes that are :func:`table_i_schedule`'s arguments, in its order.
_SCHEDULE = "max_steps lr0 lr_min lr_factor radius0 radius_min radius_factor period periods".split()


def _positive_int(value: object, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ConfigError(f"SOM: {name} must be an integer >= 1, got {value!r}")
    return int(value)


def _non_negative_int(value: object, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
        raise ConfigError(f"SOM: {name} must be an integer >= 0 or a Generator, got {value!r}")
    return int(value)


def _non_negative(value: object, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ConfigError(f"SOM: {name} must be a number, got {value!r}")
    if not (np.isfinite(value) and value >= 0):
        raise ConfigError(f"SOM: {name} must be finite and >= 0, got {value!r}")
    return float(value)


def _positive(value: object, name: str) -> float:
    number = _non_negative(value, name)
    if number == 0.0:
        raise ConfigError(f"SOM: {name} must be > 0, got {value!r}")
    return number
