"""Which edge the gate uses: interchangeable edge strategies, chosen by name.

The shape (:mod:`limbctl.region.shape`) gives the *supported loops*: they run through the
outermost taught samples, widened by learned margins, and are always safe, but sit inside a
sparsely taught edge and have corners wherever a sample fell. An edge strategy proposes an
edge from those loops and the taught directions; :func:`limbctl.region.acceptance.judge`
gives every answer its :class:`~limbctl.region.acceptance.Verdict`. The strategies
(:data:`EDGE_STRATEGIES`):

- ``"smooth"`` (:class:`SmoothEdge`, :func:`limbctl.region.edge_smooth.fit_edge`): local small
  circles over one window for the whole loop, moved out by the outermost samples. Refused
  where the data hold a bay (:func:`limbctl.region.edge_smooth.protected`) or the window cannot
  follow the loop's shape at some station (``residual_ratio`` above ``RESOLVED_RATIO``). Best
  on round regions (a cone's edge is one circle).
- ``"traced"`` (:class:`TracedEdge`, :func:`limbctl.region.edge_traced.trace_edge`): a curve
  walked out to the edge station by station; follows eggs, kidneys and bays, refused where
  the edge is taught too sparsely (estimate window above ``TRACE_MAX_WINDOW_DEG``).
- ``"supported"`` (:class:`SupportedEdge`): the supported loops themselves; the fallback,
  accepted without checks.

:func:`choose_edge` takes a choice by name (:data:`EDGE_CHOICES`). ``"auto"`` judges the
strategies of :data:`AUTO_ORDER` (smooth, traced, supported) and takes the first accepted
(a traced edge refused for bridging a stretch the samples surround is judged again held to
the evidence, :func:`limbctl.region.edge_traced.held_in`),
where an edge must also stay within ``CONFIRM_DEG`` of every learned edge accepted later in
the order (the smooth edge, fewer free parameters and the better fit when it is right, must
agree with the traced edge where both pass). A single strategy's name judges it alone and
falls back to the supported loops if it is refused.

A strategy is a class with a ``name``, a ``safe`` flag (True only for an edge that holds the
taught samples by construction) and ``propose(loops, data, supported, max_offset)``; adding
one to :data:`EDGE_STRATEGIES` makes it a choice (``docs/region.md``).
"""

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
    """What every edge strategy provides (see the module docstring)."""

    name: ClassVar[str]
    safe: ClassVar[bool]

    def propose(
        self,
        loops: list[np.ndarray],
        data: np.ndarray,
        supported: DirectionMesh,
        max_offset: float,
    ) -> Proposal | Refusal:
        """An edge for all ``loops`` (each (M, 3), counter-clockwise), or why not.

        ``data`` (N, 3) are the taught directions, ``supported`` the supported region (the
        loops widened by their margins), ``max_offset`` (rad) caps how far the edge moves
        past a loop in one step.
        """
        ...


class SupportedEdge:
    """The supported loops with their learned margins: safe by construction, the fallback."""

    name: ClassVar[str] = "supported"
    safe: ClassVar[bool] = True

    def propose(
        self,
        loops: list[np.ndarray],
        data: np.ndarray,
        supported: DirectionMesh,
        max_offset: float,
    ) -> Proposal:
        """The ``supported`` region itself (see :class:`EdgeStrategy`)."""
        note = "runs through the outermost taught samples, holding them by construction"
        return Proposal(self.name, loops, region=supported, note=note)


class SmoothEdge:
    """Local small circles over one window, moved out by the outermost samples."""

    name: ClassVar[str] = "smooth"
    safe: ClassVar[bool] = False

    def propose(
        self,
        loops: list[np.ndarray],
        data: np.ndarray,
        supported: DirectionMesh,
        max_offset: float,
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
    """A curve walked out to where the samples put the edge, station by station.

    ``hold``: each outer loop's curve is held within ``HOLD_DEG`` of the taught samples
    (:mod:`limbctl.region.edge_traced`); :func:`choose_edge` asks for it when the free curve
    bridges a stretch the samples surround.
    """

    name: ClassVar[str] = "traced"
    safe: ClassVar[bool] = False

    def __init__(self, hold: bool = False) -> None:
        self.hold = hold

    def propose(
        self,
        loops: list[np.ndarray],
        data: np.ndarray,
        supported: DirectionMesh,
        max_offset: float,
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
            edges.append(edge)
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
) -> tuple[Verdict, tuple[Verdict, ...]]:
    """The edge the gate takes and the verdicts on every strategy judged, in order.

    Parameters
    ----------
    choice : str
        One of :data:`EDGE_CHOICES` (module docstring).
    loops : list of ndarray, each (M, 3)
        The supported loops (counter-clockwise, region on the left).
    data : ndarray, shape (N, 3)
        The taught directions.
    supported : DirectionMesh
        The supported region: ``loops`` widened by their learned margins.
    max_offset : float
        The most (rad) a learned edge moves past its loop in one step.

    Returns
    -------
    taken : Verdict
        The first accepted verdict (its ``region`` is the gate's region).
    verdicts : tuple of Verdict
        Every strategy judged, in the choice's order.
    """
    order = AUTO_ORDER if check_choice(choice) == "auto" else tuple({choice: 0, FALLBACK: 0})
    judged: dict[str, Verdict] = {}
    rivals: list[Verdict] = []
    # later strategies first: an edge is checked against the learned edges accepted after it
    for name in reversed(order):
        strategy = EDGE_STRATEGIES[name]
        answer = strategy.propose(loops, data, supported, max_offset)
        verdict = judge(answer, data, supported, tuple(rivals) if choice == "auto" else ())
        if name == "traced" and "evidence_deg" in verdict.figures:
            # the free curve bridges a bay or notch: the curve held to the evidence instead
            answer = TracedEdge(hold=True).propose(loops, data, supported, max_offset)
            verdict = judge(answer, data, supported, tuple(rivals) if choice == "auto" else ())
        judged[name] = verdict
        if verdict.accepted and not strategy.safe:
            rivals.append(verdict)
    verdicts = tuple(judged[name] for name in order)
    taken = next(v for v in verdicts if v.accepted)
    return taken, verdicts
