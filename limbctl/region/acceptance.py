"""Whether a proposed edge agrees with the taught samples: :func:`judge` turns a strategy's
:class:`Proposal` or :class:`Refusal` into a :class:`Verdict` by the checks docs/region.md lists."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from limbctl.geometry.gimbal import pan_tilt_to_direction
from limbctl.geometry.quat import direction_angle
from limbctl.region.edge_hold import crossings
from limbctl.region.evidence import EVIDENCE_DEG, unsupported_stretches
from limbctl.region.loops import loop_length
from limbctl.region.mesh import DirectionMesh

#: Share of the supported region's samples a learned edge may leave out: sharp turns.
MISS_FRACTION = 0.001
#: Samples this close (deg) outside do not count: the estimate's noise, about a tick.
MISS_TOLERANCE_DEG = 0.1
#: Most samples an added stretch may be worth: sparse teaching a few, a bay tens or more.
GAP_EXPECTED = 40.0
#: Density neighbourhood (deg): its half cap holds about 5 samples at a sparse edge.
DENSITY_RADIUS_DEG = 6.0
#: Farthest (deg) past a rival: the gate's 1 deg bound (cones' smooth edges: 0.4-0.6).
CONFIRM_DEG = 1.0


@dataclass(frozen=True, eq=False)
class Proposal:
    """A strategy's candidate edge: ``edges`` (each (K, 3)), closed counter-clockwise loops of
    unit directions, the region on their left; ``region``, given where the edge holds the samples
    by construction: accepted as it is; ``note``, why a proposal with a region needs no checks."""

    strategy: str
    edges: list[np.ndarray]
    region: DirectionMesh | None = None
    note: str = ""


@dataclass(frozen=True, eq=False)
class Refusal:
    """A strategy's answer when the data refuse it an edge: the ``reason``, what in the data
    refuses the edge, for a person, and the ``figures`` behind it (units in their names)."""

    strategy: str
    reason: str
    figures: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class Verdict:
    """Whether an edge is ``accepted`` (the gate may use it), and why: ``reasons``, for a person
    (the first failed check when refused), and the ``figures`` behind them (units in their names);
    ``region``, the region inside the edge when accepted."""

    strategy: str
    accepted: bool
    reasons: tuple[str, ...]
    figures: dict[str, float] = field(default_factory=dict)
    region: DirectionMesh | None = field(default=None, repr=False)

    def line(self) -> str:
        """One line: ``accepted: ...`` or ``refused: ...``."""
        return f"{'accepted' if self.accepted else 'refused'}: {'; '.join(self.reasons)}"


def refused(strategy: str, reason: str, **figures: float) -> Verdict:
    """A refusing :class:`Verdict` with one reason and its figures."""
    return Verdict(strategy, False, (reason,), {k: float(v) for k, v in figures.items()})


def judge(
    candidate: Proposal | Refusal,
    data: np.ndarray,
    supported: DirectionMesh,
    rivals: tuple[Verdict, ...] = (),
) -> Verdict:
    """The verdict on a strategy's answer ``candidate``, given the taught directions ``data``
    (N, 3), the ``supported`` region and ``rivals``, accepted verdicts of other edges the
    candidate must stay within ``CONFIRM_DEG`` of."""
    name = candidate.strategy
    if isinstance(candidate, Refusal):
        return Verdict(name, False, (candidate.reason,), dict(candidate.figures))
    if candidate.region is not None:
        return Verdict(name, True, (candidate.note,), {}, candidate.region)
    edges = candidate.edges
    if arcs_cross(edges):
        return refused(name, "two of its arcs cross")
    for number, edge in enumerate(edges):
        worth = unexplained_gap(edge, data, supported)
        if worth > GAP_EXPECTED:
            return refused(
                name,
                f"loop {number} adds a stretch where the taught density puts {worth:.0f} "
                f"samples and none was taught (at most {GAP_EXPECTED:.0f})",
                unexplained_samples=worth,
            )
    learned = DirectionMesh.from_loops(edges, 0.0, lookup=False)
    before = supported.contains(data)
    missed = before & ~learned.contains(data)
    # a sample a hair outside (the edge estimate's own noise) is not a cut corner
    far = direction_angle(learned.project(data[missed]), data[missed]) > np.radians(
        MISS_TOLERANCE_DEG
    )
    allowed = MISS_FRACTION * max(1, int(before.sum()))
    if int(far.sum()) > allowed:
        return refused(
            name,
            f"it leaves {int(far.sum())} taught samples more than {MISS_TOLERANCE_DEG:g} deg "
            f"outside (at most {allowed:.1f})",
            samples_left_out=int(far.sum()),
        )
    added = [s for s in unsupported_stretches(learned, data) if not _held(supported, s)]
    if added:
        return refused(
            name,
            f"it bridges a stretch the taught samples surround, {added[0].line()} (at most "
            f"{EVIDENCE_DEG:g} deg), beyond the supported edge",
            evidence_deg=added[0].distance_deg,
        )
    for rival in rivals:
        reach = reach_beyond(edges, rival.region)
        if reach > np.radians(CONFIRM_DEG):
            return refused(
                name,
                f"it reaches {np.degrees(reach):.2f} deg beyond the {rival.strategy} edge "
                f"(at most {CONFIRM_DEG:g})",
                reach_beyond_deg=np.degrees(reach),
            )
    agreed = "holds the taught samples and adds no stretch the sampling cannot explain"
    also = tuple(f"within {CONFIRM_DEG:g} deg of the {r.strategy} edge" for r in rivals)
    return Verdict(name, True, (agreed, *also), {}, learned)


def _held(region: DirectionMesh, stretch) -> bool:
    """Whether ``region`` holds the farthest station of ``stretch`` (a bridge it has too)."""
    d = pan_tilt_to_direction(np.radians(stretch.pan_deg), np.radians(stretch.tilt_deg))
    return bool(region.contains(np.asarray(d, dtype=np.float64).reshape(1, 3))[0])


def reach_beyond(edges: list[np.ndarray], region: DirectionMesh) -> float:
    """How far (rad) the stations of ``edges`` (each (K, 3)) reach beyond ``region``, at most."""
    stations = np.vstack(edges)
    return float(np.max(direction_angle(region.project(stations), stations)))


def arcs_cross(loops: list[np.ndarray]) -> bool:
    """Whether any two non-adjacent arcs of the closed ``loops`` (each (M, 3)) cross: each one's
    ends on both sides of the other's great circle, their midpoints facing the same way
    (:func:`limbctl.region.edge_hold.crossings`)."""
    return crossings(loops).shape[0] > 0


def unexplained_gap(edge: np.ndarray, data: np.ndarray, supported: DirectionMesh) -> float:
    """The most samples (expected) any stretch the ``edge`` (K, 3) adds would hold: over a run of
    stations beyond the supported region by ``b_k`` (rad), ``sum_k rho_k b_k ds``, ``rho`` the
    taught density (per half cap of ``DENSITY_RADIUS_DEG``) at the nearest supported point."""
    foot = supported.project(edge)
    beyond = np.arccos(np.clip(np.einsum("ij,ij->i", foot, edge), -1.0, 1.0))
    beyond[supported.contains(edge)] = 0.0
    if not np.any(beyond > 0.0):
        return 0.0
    ds = loop_length(edge) / edge.shape[0]
    radius = np.radians(DENSITY_RADIUS_DEG)
    counts = np.sum(foot @ data.T >= np.cos(radius), axis=1)
    # half a cap of angular radius r has area pi (1 - cos r)
    rho = counts / (np.pi * (1.0 - np.cos(radius)))
    worst = 0.0
    out = beyond > 0.0
    # runs of stations beyond the supported region, the loop read circularly
    first = int(np.argmin(out)) if not out.all() else 0
    expected = 0.0
    for i in np.roll(np.arange(edge.shape[0]), -first):
        if out[i]:
            expected += rho[i] * beyond[i] * ds
            worst = max(worst, expected)
        else:
            expected = 0.0
    return worst
