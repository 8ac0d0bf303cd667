"""Whether a proposed edge agrees with the taught samples: one acceptance for every strategy.

An edge strategy (:mod:`limbctl.region.edge_choice`) answers with a :class:`Proposal` (closed
loops (K, 3) for the region's edge) or a :class:`Refusal` (why it cannot propose one, in words
and numbers). :func:`judge` turns either into a :class:`Verdict`. A learned edge is accepted
only when, over all its loops together:

1. no two arcs cross (:func:`arcs_cross`);
2. every stretch it adds beyond the supported region is one the local sampling density could
   leave empty by chance (:func:`unexplained_gap` at most ``GAP_EXPECTED`` samples);
3. it holds the taught directions the supported region holds (at most ``MISS_FRACTION`` of
   them lie more than ``MISS_TOLERANCE_DEG`` outside);
4. it reaches at most ``CONFIRM_DEG`` beyond each *rival*: an accepted edge later in the
   choice's order that the caller asks it to agree with (:func:`reach_beyond`);
5. it adds no stretch beyond the supported region that the taught samples surround but do not
   reach within ``EVIDENCE_DEG`` (:func:`limbctl.region.evidence.unsupported_stretches`): a
   bay or notch the sampling density "explains" is still a bay the edge would bridge.

The supported edge runs through the outermost taught samples: its proposal comes with its
region and is accepted without checks (it is what the gate falls back to).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from limbctl.geometry.gimbal import pan_tilt_to_direction
from limbctl.geometry.quat import direction_angle
from limbctl.region.evidence import EVIDENCE_DEG, unsupported_stretches
from limbctl.region.loops import loop_length
from limbctl.region.mesh import DirectionMesh

#: A learned edge may leave out at most this fraction of the taught directions the supported
#: region holds: one in a thousand, the samples a hair outside at a sharp turn of the edge.
MISS_FRACTION = 0.001
#: A taught direction at most this far (deg) outside a learned edge does not count as left out:
#: the edge estimate's own noise, about a servo tick.
MISS_TOLERANCE_DEG = 0.1
#: A stretch added beyond the supported region may be worth at most this many samples: sparse
#: i.i.d. teaching leaves gaps worth a few, a bay the hand went around tens to hundreds.
GAP_EXPECTED = 40.0
#: Radius (deg) of the neighbourhood the local sample density is counted in: its half cap
#: (56 deg^2) holds a few samples even at a sparse edge (0.08 per deg^2: about 5).
DENSITY_RADIUS_DEG = 6.0
#: A learned edge may reach at most this far (deg) beyond a rival's region: the gate's accuracy
#: bound for outputs outside the true region (cones of 20 deg reach 0.4-0.6 deg beyond the
#: traced edge with their smooth edge).
CONFIRM_DEG = 1.0


@dataclass(frozen=True, eq=False)
class Proposal:
    """A strategy's candidate edge.

    Attributes
    ----------
    strategy : str
        The strategy's name.
    edges : list of ndarray, each (K, 3)
        Closed counter-clockwise loops of unit directions, the region on their left.
    region : DirectionMesh or None
        Given only by a strategy whose edge holds the taught samples by construction (the
        supported edge): :func:`judge` accepts it as it is. Otherwise None, and the region is
        built from ``edges`` once they pass the checks.
    note : str
        Why a proposal with a region needs no checks.
    """

    strategy: str
    edges: list[np.ndarray]
    region: DirectionMesh | None = None
    note: str = ""


@dataclass(frozen=True, eq=False)
class Refusal:
    """A strategy's answer when the data refuse it an edge: why, in words and numbers.

    Attributes
    ----------
    strategy : str
        The strategy's name.
    reason : str
        What in the data refuses the edge, for a person.
    figures : dict of str to float
        The numbers behind the reason (units in their names).
    """

    strategy: str
    reason: str
    figures: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class Verdict:
    """Whether an edge is accepted, and why.

    Attributes
    ----------
    strategy : str
        The strategy's name.
    accepted : bool
        Whether the gate may use the edge.
    reasons : tuple of str
        Why, for a person (the first failed check when refused).
    figures : dict of str to float
        The numbers behind the reasons (units in their names).
    region : DirectionMesh or None
        The region inside the edge when accepted.
    """

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
    """The verdict on a strategy's answer (the checks of the module docstring).

    Parameters
    ----------
    candidate : Proposal or Refusal
        What the strategy answered.
    data : ndarray, shape (N, 3)
        The taught directions.
    supported : DirectionMesh
        The supported region: the supported loops widened by their learned margins.
    rivals : tuple of Verdict
        Accepted verdicts of other edges the candidate must stay within ``CONFIRM_DEG`` of.
    """
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
    """Whether any two non-adjacent arcs of the closed ``loops`` (each (M, 3)) cross.

    Arcs ``i`` and ``j`` cross when the ends of each lie on both sides of the other's great
    circle (``sign(a_j . p_i) != sign(b_j . p_i)``, ``p_i = a_i x b_i``, and the converse) and
    their midpoints face the same way.
    """
    a = np.vstack(loops)
    b = np.vstack([np.roll(lp, -1, axis=0) for lp in loops])
    owner = np.concatenate([np.full(lp.shape[0], i) for i, lp in enumerate(loops)])
    index = np.concatenate([np.arange(lp.shape[0]) for lp in loops])
    size = np.array([lp.shape[0] for lp in loops])[owner]
    pole = np.cross(a, b)
    mid = a + b
    for start in range(0, a.shape[0], 256):
        sl = slice(start, start + 256)
        # (J, I): arc j's ends on both sides of arc i's great circle, and the converse
        j_split = np.sign(a @ pole[sl].T) * np.sign(b @ pole[sl].T) < 0
        i_split = (np.sign(a[sl] @ pole.T) * np.sign(b[sl] @ pole.T)).T < 0
        hit = j_split & i_split & (mid @ mid[sl].T > 0.0)
        rows = np.arange(a.shape[0])[:, None]
        cols = np.arange(a.shape[0])[sl][None, :]
        apart = np.abs(index[rows] - index[cols])
        adjacent = (owner[rows] == owner[cols]) & ((apart <= 1) | (apart == size[rows] - 1))
        if np.any(hit & ~adjacent):
            return True
    return False


def unexplained_gap(edge: np.ndarray, data: np.ndarray, supported: DirectionMesh) -> float:
    """The most samples (expected) any stretch the ``edge`` (K, 3) adds would hold.

    Each station lies ``b_k`` (rad) beyond the supported region (0 inside). Over a run of
    consecutive stations with ``b_k > 0`` the added area is ``A = sum_k b_k ds`` (``ds`` the
    station spacing), and a teacher sampling at the local density ``rho`` (taught directions
    within ``DENSITY_RADIUS_DEG`` of the stations' nearest supported points, per area of half
    that cap: those points sit on the supported edge) would have put ``rho A`` samples
    there; the chance of finding none is ``exp(-rho A)``. Sparse i.i.d. teaching leaves
    gaps worth a few samples; a bay the hand went around is worth tens to hundreds.
    """
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
