"""Which edge the gate uses: interchangeable edge strategies, chosen by name and judged by
:func:`limbctl.region.acceptance.judge` (docs/region.md, "Edge strategies")."""

from __future__ import annotations

from typing import ClassVar, Protocol

import numpy as np

from limbctl.errors import ConfigError
from limbctl.region import edge_smooth as ef
from limbctl.region import edge_traced as et
from limbctl.region.acceptance import Proposal, Refusal, Verdict, judge
from limbctl.region.loops import loop_area, resample_loop
from limbctl.region.mesh import DirectionMesh


class EdgeStrategy(Protocol):
    """What every edge strategy provides (docs/region.md, "Adding an edge strategy")."""

    name: ClassVar[str]
    safe: ClassVar[bool]

    def propose(
        self, loops: list[np.ndarray], data: np.ndarray, supported: DirectionMesh, max_offset: float
    ) -> Proposal | Refusal:
        """An edge for all ``loops`` (each (M, 3)) from taught ``data`` (N, 3), or why not
        (``max_offset``: most rad it moves past a loop in one step)."""
        ...


class SupportedEdge:
    """The supported loops with their learned margins: safe by construction, the fallback."""

    name: ClassVar[str] = "supported"
    safe: ClassVar[bool] = True

    def propose(
        self, loops: list[np.ndarray], data: np.ndarray, supported: DirectionMesh, max_offset: float
    ) -> Proposal:
        """The ``supported`` region itself (see :class:`EdgeStrategy`)."""
        note = "runs through the outermost taught samples, holding them by construction"
        return Proposal(self.name, loops, region=supported, note=note)


class SmoothEdge:
    """Local small circles over one window, moved out by the outermost samples."""

    name: ClassVar[str] = "smooth"
    safe: ClassVar[bool] = False

    def propose(
        self, loops: list[np.ndarray], data: np.ndarray, supported: DirectionMesh, max_offset: float
    ) -> Proposal | Refusal:
        """The smooth edge of every loop, or the first loop's reason to refuse it."""
        edges = []
        for number, loop in enumerate(loops):
            _, s, at_vertex = resample_loop(loop, np.radians(ef.STEP_DEG))
            if ef.protected(loop, data, s, at_vertex).any():
                if loop_area(loop) < 0.0:
                    return Refusal(self.name, f"loop {number} is a hole (concave throughout)")
                worth = max((w for _, _, w in ef.pockets(loop, data)), default=np.inf)
                return Refusal(
                    self.name,
                    f"loop {number} holds a bay worth {worth:.0f} samples "
                    f"(at most {ef.POCKET_SAMPLES:.0f}) that a smooth curve would bridge",
                    {"bay_samples": float(worth)},
                )
            edge, ratio = ef.fit_edge(loop, data, max_offset)
            if ratio > ef.RESOLVED_RATIO:
                return Refusal(
                    self.name,
                    f"its window cannot follow loop {number}'s shape (a station's fit "
                    f"residual is {ratio:.2f} x the median, at most {ef.RESOLVED_RATIO:g})",
                    {"residual_ratio": ratio},
                )
            edges.append(edge)
        return Proposal(self.name, edges)


class TracedEdge:
    """A curve walked out station by station (``hold``: within ``HOLD_DEG`` of the samples;
    ``clip``: its stations past the supported region projected onto that region's edge)."""

    name: ClassVar[str] = "traced"
    safe: ClassVar[bool] = False

    def __init__(self, hold: bool = False, clip: bool = False) -> None:
        self.hold, self.clip = hold, clip

    def propose(
        self, loops: list[np.ndarray], data: np.ndarray, supported: DirectionMesh, max_offset: float
    ) -> Proposal | Refusal:
        """The traced edge of every loop, or the first loop taught too sparsely."""
        edges = []
        for number, loop in enumerate(loops):
            edge = et.trace_edge(loop, data, max_offset, self.hold)
            if edge is None:
                curve, _, _ = resample_loop(loop, np.radians(et.TRACE_STEP_DEG))
                window = np.degrees(et.trace_window(curve, data))
                return Refusal(
                    self.name,
                    f"loop {number} is taught too sparsely (its estimate window would be "
                    f"{window:.1f} deg, at most {et.TRACE_MAX_WINDOW_DEG:g})",
                    {"window_deg": float(window)},
                )
            reach = np.degrees(et.evidence_reach(edge, data)) if self.hold else 0.0
            if reach > et.HELD_REACH_DEG:
                return Refusal(
                    self.name,
                    f"held to the evidence, loop {number} still lies {reach:.2f} deg from every "
                    f"taught sample (at most {et.HELD_REACH_DEG:g})",
                    {"held_reach_deg": float(reach)},
                )
            edges.append(supported.project(edge) if self.clip else edge)
        return Proposal(self.name, edges)


#: The edge strategies by name.
EDGE_STRATEGIES: dict[str, EdgeStrategy] = {
    strategy.name: strategy for strategy in (SmoothEdge(), TracedEdge(), SupportedEdge())
}
#: The order ``"auto"`` judges the strategies in; the first accepted is taken.
AUTO_ORDER = ("smooth", "traced", "supported")
#: The strategy every choice falls back to (safe: always accepted).
FALLBACK = "supported"
#: Every name :func:`choose_edge` takes.
EDGE_CHOICES = ("auto", *EDGE_STRATEGIES)


def check_choice(choice: str) -> str:
    """``choice`` itself if it names an edge choice; otherwise ConfigError listing them."""
    if choice not in EDGE_CHOICES:
        raise ConfigError(f"unknown edge {choice!r}; choose one of: {', '.join(EDGE_CHOICES)}")
    return choice


def choose_edge(
    choice: str,
    loops: list[np.ndarray],
    data: np.ndarray,
    supported: DirectionMesh,
    max_offset: float,
    clip: bool = False,
) -> tuple[Verdict, tuple[Verdict, ...]]:
    """The edge the gate takes (the first accepted verdict: its ``region`` is the gate's region)
    and the verdicts on every strategy judged, in the order of ``choice`` (one of
    :data:`EDGE_CHOICES`).

    ``loops`` (each (M, 3)): the supported loops (counter-clockwise, region on the left); ``data``
    (N, 3): the taught directions; ``supported``: ``loops`` widened by their learned margins;
    ``max_offset`` (rad): the most a learned edge moves past its loop in one step; ``clip``:
    whether a traced edge refused for unexplained samples is proposed again clipped to
    ``supported`` (where the samples' own depths set its margins).
    """
    order = AUTO_ORDER if check_choice(choice) == "auto" else tuple({choice: 0, FALLBACK: 0})
    judged: dict[str, Verdict] = {}
    rivals: list[Verdict] = []
    # later strategies first: an edge is checked against the learned edges accepted after it
    for name in reversed(order):
        strategy = EDGE_STRATEGIES[name]
        answer = strategy.propose(loops, data, supported, max_offset)
        against = tuple(rivals) if choice == "auto" else ()
        verdict = judge(answer, data, supported, against)
        hold = name == "traced" and "evidence_deg" in verdict.figures
        if hold:
            # the free curve bridges a bay or notch: the curve held to the evidence instead
            answer = TracedEdge(hold=True).propose(loops, data, supported, max_offset)
            verdict = judge(answer, data, supported, against)
        if clip and name == "traced" and "unexplained_samples" in verdict.figures:
            # the curve stands past the supported edge where samples were due: held to it there
            answer = TracedEdge(hold=hold, clip=True).propose(loops, data, supported, max_offset)
            verdict = judge(answer, data, supported, against)
        judged[name] = verdict
        if verdict.accepted and not strategy.safe:
            rivals.append(verdict)
    verdicts = tuple(judged[name] for name in order)
    taken = next(v for v in verdicts if v.accepted)
    return taken, verdicts
