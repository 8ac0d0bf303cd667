"""The experiment grids of `limbctl eval`: which data sets, models and answers each point runs,
at three scales: ``full`` (the papers' grids, 10 seeds), ``quick`` and ``smoke`` (1 seed)."""

from __future__ import annotations

import hashlib
from collections.abc import Iterable
from dataclasses import dataclass, replace
from typing import Any

from limbctl.errors import ConfigError

#: Interpolations of the Rigid Map paper (``none`` is the discrete answer).
INTERPOLATIONS = ("idw", "geometric", "geometric-winner", "topological")

SCALES = ("full", "quick", "smoke")


@dataclass(frozen=True)
class DataSpec:
    """How one data set of twist-free orientations is drawn: ``range_deg``, the true cone's
    half-angle R; ``patterns`` valid for training, ``test_patterns`` spread over the ``"sphere"``
    or ``"around"`` the cone; ``boundary_ratio``, training density in the band (swing in (R/2,
    R]) over the central cap's (1: uniform)."""

    range_deg: float
    patterns: int
    test_patterns: int
    test_spread: str = "around"
    boundary_ratio: float = 1.0


@dataclass(frozen=True)
class Answer:
    """One way of answering: ``respond`` (the paper's), ``correct`` (the gate) or ``data-nodes``."""

    how: str
    interpolation: str = "none"
    k: int = 0

    @property
    def label(self) -> str:
        if self.how == "correct":
            return "correct (gate)"
        if self.how == "data-nodes":
            return f"data nodes {self.interpolation}"
        return f"respond {self.interpolation}"


@dataclass(frozen=True)
class ModelSpec:
    """A model to train on each task's data (a ``seed`` added per task) and its answers."""

    label: str
    kind: str
    options: tuple[tuple[str, Any], ...]
    answers: tuple[Answer, ...]


@dataclass(frozen=True)
class Task:
    """One data set and the models trained on it (``x_from_k``: each row's x is its answer's k)."""

    grid: str
    experiment: str
    x_name: str
    x: float
    seed: int
    data: DataSpec
    models: tuple[ModelSpec, ...]
    x_from_k: bool = False

    @property
    def key(self) -> str:
        """A short hash of the definition and the gate's and fit's versions: resumes never mix."""
        from limbctl.envelope.rigidmap import GATE_VERSION
        from limbctl.region.taught import FIT_VERSION

        versions = f"gate {GATE_VERSION} fit {FIT_VERSION}"
        return hashlib.sha1(f"{self!r}|{versions}".encode()).hexdigest()[:16]


def respond_all(methods: Iterable[str], k: int) -> tuple[Answer, ...]:
    """The discrete answer plus each interpolation in ``methods`` with ``k`` runner-ups."""
    return (Answer("respond"),) + tuple(Answer("respond", m, k) for m in methods)


@dataclass(frozen=True)
class Scale:
    """Sizes of one grid scale (see the module docstring)."""

    seeds: int
    test_patterns: int
    som_ranges: tuple[float, ...]
    som_range_sides: tuple[int, ...]
    som_patterns: tuple[int, ...]
    som_pattern_sides: tuple[int, ...]
    som_sides: tuple[int, ...]
    som_ratios: tuple[float, ...]
    som_default_patterns: int
    rm_ranges: tuple[float, ...]
    rm_ks: tuple[int, ...]
    rm_patterns: int
    uniform_nodes: int
    k_polytope: int
    k_uniform: int


_FULL = Scale(
    seeds=10,
    test_patterns=1000,
    som_ranges=(30.0, 45.0, 60.0, 90.0, 120.0, 150.0),
    som_range_sides=(10, 20, 30),
    som_patterns=(500, 1000, 2000, 3000, 4000, 5000),
    som_pattern_sides=(10, 30),
    som_sides=(10, 15, 20, 25, 30),
    som_ratios=(0.25, 0.5, 1.0, 2.0, 4.0, 8.0),
    som_default_patterns=500,
    rm_ranges=(10.0, 20.0, 30.0, 45.0, 60.0, 90.0),
    rm_ks=(1, 2, 3, 4, 6, 8, 12, 16),
    rm_patterns=1000,
    uniform_nodes=2000,
    k_polytope=2,
    k_uniform=8,
)
SCALE_SIZES = {
    "full": _FULL,
    # the full grid's sizes at fewer points, 2 seeds
    "quick": replace(
        _FULL,
        seeds=2,
        som_ranges=(45.0, 90.0, 150.0),
        som_range_sides=(10, 30),
        som_patterns=(500, 5000),
        som_sides=(10, 20, 30),
        som_ratios=(0.5, 1.0, 4.0),
        rm_ranges=(10.0, 20.0, 45.0),
        rm_ks=(1, 2, 4, 8, 16),
    ),
    "smoke": Scale(
        seeds=1,
        test_patterns=200,
        som_ranges=(45.0, 90.0),
        som_range_sides=(5,),
        som_patterns=(200, 400),
        som_pattern_sides=(5,),
        som_sides=(4, 6),
        som_ratios=(1.0, 4.0),
        som_default_patterns=200,
        rm_ranges=(20.0, 45.0),
        rm_ks=(1, 4),
        rm_patterns=300,
        uniform_nodes=300,
        k_polytope=2,
        k_uniform=4,
    ),
}


def som_spec(side: int, label: str | None = None) -> ModelSpec:
    """The SOM paper's network, ``side x side`` nodes: its answer and its threshold gate."""
    answers = (Answer("respond"), Answer("correct"))
    label = label or f"SOM {side}x{side}"
    return ModelSpec(label, "som", (("rows", side), ("cols", side)), answers)


def gate_spec() -> ModelSpec:
    """The gate: the project's default Rigid Map (2000 uniform nodes on w >= 0) with ``correct``."""
    return ModelSpec("gate (RigidMap uniform-2000)", "rigidmap", (), (Answer("correct"),))


def paper_rigid_maps(scale: Scale, answers_720, answers_uniform) -> tuple[ModelSpec, ...]:
    """The Rigid Map paper's two layouts (S^3 density on w >= 0), super-Fibonacci; gates too."""
    n, k = scale.uniform_nodes, scale.k_uniform
    fibonacci = (Answer("respond", "geometric", k), Answer("correct"), Answer("data-nodes"))
    fibonacci += (Answer("data-nodes", "geometric", k),)
    layouts = (
        ("RigidMap polytope-720", None, "polytope-720", answers_720),
        (f"RigidMap uniform-{n} (S^3 density)", n // 2, "uniform", answers_uniform),
        (f"RigidMap super-fibonacci-{n}", n, "super-fibonacci", fibonacci),
    )
    return tuple(
        ModelSpec(label, "rigidmap", (("nodes", nodes), ("layout", layout)), answers)
        for label, nodes, layout, answers in layouts
    )


def build_tasks(scale_name: str) -> list[Task]:
    """Every task of one scale (``full``, ``quick`` or ``smoke``), SOM paper first."""
    if scale_name not in SCALE_SIZES:
        raise ConfigError(f"unknown eval scale {scale_name!r}; choose one of: {', '.join(SCALES)}")
    s = SCALE_SIZES[scale_name]
    tasks: list[Task] = []

    def add(experiment, x_name, x, data, models, x_from_k=False):
        for seed in range(s.seeds):
            tasks.append(
                Task(scale_name, experiment, x_name, x, seed, data, tuple(models), x_from_k)
            )

    som_data = DataSpec(90.0, s.som_default_patterns, s.test_patterns, "sphere")
    for r in s.som_ranges:
        data = DataSpec(r, s.som_default_patterns, s.test_patterns, "sphere")
        add("som-range", "range_deg", r, data, [*map(som_spec, s.som_range_sides), gate_spec()])
    for p in s.som_patterns:
        data = DataSpec(90.0, p, s.test_patterns, "sphere")
        models = [*map(som_spec, s.som_pattern_sides), gate_spec()]
        add("som-patterns", "patterns", p, data, models)
    for side in s.som_sides:
        # the data does not change with the node count: the gate runs once, drawn as a line
        gate = [gate_spec()] if side == s.som_sides[0] else []
        add("som-nodes", "nodes", side * side, som_data, [som_spec(side, "SOM"), *gate])
    for ratio in s.som_ratios:
        data = DataSpec(90.0, s.som_default_patterns, s.test_patterns, "sphere", ratio)
        models = [som_spec(s.som_range_sides[0]), gate_spec()]
        add("som-ratio", "boundary_ratio", ratio, data, models)

    answers_720 = (*respond_all(INTERPOLATIONS, s.k_polytope), Answer("correct"))
    answers_uniform = (*respond_all(INTERPOLATIONS, s.k_uniform), Answer("correct"))
    for r in s.rm_ranges:
        data = DataSpec(r, s.rm_patterns, s.test_patterns, "around")
        add("rm-range", "range_deg", r, data, paper_rigid_maps(s, answers_720, answers_uniform))
    by_k = (Answer("respond"), Answer("correct")) + tuple(
        Answer("respond", m, k) for k in s.rm_ks for m in INTERPOLATIONS
    )
    data = DataSpec(20.0, s.rm_patterns, s.test_patterns, "around")
    add("rm-k", "k", 20.0, data, paper_rigid_maps(s, by_k, by_k)[:2], x_from_k=True)
    return tasks
