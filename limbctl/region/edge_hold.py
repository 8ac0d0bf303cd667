"""Holding the kept edge to the taught evidence where it stands past it: containment first.

A point of the learned region within ``r`` of a taught sample lies at most ``r`` outside the
truth. Wherever the kept edge stands farther than ``REACH_DEG`` (:mod:`limbctl.region.evidence`)
from every taught sample, :func:`hold_to_evidence` holds it to ``REACH_DEG`` of the evidence
(the steps: docs/decisions/region.md, "The kept edge is held to the evidence").
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from limbctl.region.evidence import REACH_DEG, STATION_DEG, edge_stations, loop_arcs, outer_arcs
from limbctl.region.hold_kernels import crossing_arcs, first_fold
from limbctl.region.loops import chord
from limbctl.region.mesh import DirectionMesh

#: Step (deg) of a walk inward: it ends at most this much deeper than asked.
WALK_STEP_DEG = 0.05
#: Steps of a walk tried at once: a third of a station's walk (60 steps; a chord's middle walks
#: up to 250), so points that stop early cost few queries and a walk takes a few batches.
WALK_BATCH = 20
#: Farthest (deg) a station walks in along its normal; then toward the nearest sample.
WALK_DEG = 3.0
#: Farthest (deg) a far chord's middle walks in: the families' deepest bay (11 deg) plus the reach.
CHORD_WALK_DEG = 12.5
#: Held stations this many spacings apart get the edge between them sampled again.
SPREAD_STATIONS = 2.0
#: Refinement passes: 4 halvings resolve 1/16 of a station spacing.
REFINE_PASSES = 4
#: Chord-holding passes: 8 halvings take a 3 deg jump down to 0.012 deg chords.
CHORD_PASSES = 8
#: A chord may lie this much (deg) past the reach: half the report's station gap.
CHORD_SLACK_DEG = 0.25 * STATION_DEG
#: Rounds of giving held arcs back; after them none is held.
UNHOLD_ROUNDS = 4
#: Rounds a patient hold gets after UNHOLD_ROUNDS: the sparse families' 0.9 deg holds (lost
#: samples pinned, the pins crossing) held within 1-3 of them; 8 leave room past the slowest.
PATIENT_ROUNDS = 8
#: Rounds of pinning samples a hold would leave out.
PIN_ROUNDS = 3
#: A pinned sample lies this far (deg) outside the chain: far below a tick (0.088).
PIN_DEG = 0.01
#: A station moved toward a sample lands this far (rad) inside the reach: not on rounding.
INSIDE_RAD = 1e-9
#: Stations a fold may span: a bay's width, up to 14 deg (56 spacings).
FOLD_WINDOW = 60
#: Ends this close (deg) pair a far chord with one running back beside it, a sliver: a pinned
#: sample's spike held straight leaves its sides 0.01-0.02 apart; half a tick (0.088).
SLIVER_DEG = 0.05


def hold_to_evidence(
    mesh: DirectionMesh,
    data: np.ndarray,
    reach: float = np.radians(REACH_DEG),
    patient: bool = False,
    straight: bool = False,
) -> tuple[DirectionMesh, bool]:
    """``mesh`` held to within ``reach`` (rad) of the taught directions ``data`` (N, 3).

    Each round that crosses or loses a taught sample gives the held arcs nearest the trouble
    their unheld edges back. A ``patient`` hold gets ``PATIENT_ROUNDS`` more rounds, and in
    those the arcs nearest the samples a round pinned are given back too (their pins crossed):
    where a hold at ``reach`` cannot keep the samples, it keeps the held edge elsewhere. A
    ``straight`` hold moves far points straight toward their nearest sample, never along a normal.

    Returns the held region (lookup grid not built), or ``mesh`` itself when nothing is far or no
    hold keeps the taught samples it held and its arcs apart, and whether the region was held.
    """
    tree = cKDTree(data)
    stations, arc = edge_stations(mesh, np.radians(STATION_DEG))
    far = (tree.query(stations)[0] > chord(reach)) & outer_arcs(mesh)[arc]
    held = np.zeros(mesh.edges.shape[0], dtype=bool)
    held[arc[far]] = True
    if not held.any():
        return mesh, False
    before = mesh.contains(data)
    walk = 0.0 if straight else WALK_DEG
    for number in range(UNHOLD_ROUNDS + (PATIENT_ROUNDS if patient else 0)):
        loops = _held_loops(mesh, held, tree, reach, walk)
        pinned = [np.empty((0, 3))]
        for _ in range(PIN_ROUNDS):
            trouble = crossings([p for p, _, _ in loops])
            if trouble.shape[0]:
                break
            trial = DirectionMesh.from_loops(
                [p for p, _, _ in loops], [w for _, w, _ in loops], lookup=False
            )
            lost = before & ~trial.contains(data)
            if not lost.any():
                return trial, True
            trouble = data[lost]
            pinned.append(trouble)
            loops = _pinned(loops, trouble)
        if number >= UNHOLD_ROUNDS:
            # a patient round: the samples it pinned give their nearest arcs back as well
            trouble = np.vstack([trouble, *pinned])
        # the held arc nearest each sample still lost, or each crossing, keeps its unheld edge
        rows = np.flatnonzero(held[arc])
        _, k = cKDTree(stations[rows]).query(trouble)
        held[arc[rows[k]]] = False
        if not held.any():
            break
    return mesh, False


def crossings(loops: list[np.ndarray]) -> np.ndarray:
    """Middles (C, 3) of the arcs of the closed ``loops`` (each (M, 3)) that cross a non-adjacent
    arc: each one's ends on both sides of the other's great circle (ends within
    ``hold_kernels.ON_CIRCLE_RAD`` of it not across), their midpoints facing the same way.
    """
    a = np.vstack(loops)
    b = np.vstack([np.roll(lp, -1, axis=0) for lp in loops])
    owner = np.concatenate([np.full(lp.shape[0], i) for i, lp in enumerate(loops)])
    index = np.concatenate([np.arange(lp.shape[0]) for lp in loops])
    size = np.array([lp.shape[0] for lp in loops])[owner]
    pole, mid = np.cross(a, b), a + b
    pole /= np.maximum(np.linalg.norm(pole, axis=1, keepdims=True), 1e-300)
    hit_any = crossing_arcs(a, b, pole, mid, owner, index, size)
    out = mid[hit_any]
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def _pinned(
    loops: list[tuple[np.ndarray, np.ndarray, np.ndarray]], samples: np.ndarray
) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """``loops`` (points (K, 3), margins (K,), chain flags (K,) each) with each of ``samples``
    (S, 3) put into its nearest chain chord, ``PIN_DEG`` outside.
    """
    loops = list(loops)
    lift = np.radians(PIN_DEG)
    for x in samples:
        best = None
        for number, (p, _, chain) in enumerate(loops):
            k = p.shape[0]
            nxt = np.roll(np.arange(k), -1)
            on = np.flatnonzero(chain & chain[nxt])
            if on.size == 0:
                continue
            pole = np.cross(p[on], p[nxt[on]])
            pole /= np.maximum(np.linalg.norm(pole, axis=1, keepdims=True), 1e-15)
            near = _nearest_cos(x, p[on], p[nxt[on]], pole)
            j = int(np.argmax(near))
            if best is None or near[j] > best[0]:
                best = (near[j], number, int(on[j]), pole[j])
        if best is None:
            break
        _, number, i, pole = best
        p, w, chain = loops[number]
        pin = np.cos(lift) * x - np.sin(lift) * pole
        loops[number] = (
            np.insert(p, i + 1, pin / np.linalg.norm(pin), axis=0),
            np.insert(w, i + 1, 0.0),
            np.insert(chain, i + 1, True),
        )
    return loops


def _nearest_cos(x: np.ndarray, a: np.ndarray, b: np.ndarray, pole: np.ndarray) -> np.ndarray:
    """Cosines (M,) from ``x`` (3,) to the arcs ``a -> b`` (M, 3 each, unit poles ``pole``): to
    each one's foot on its great circle when between its ends, else to its nearer end."""
    foot = x - (pole @ x)[:, None] * pole
    foot /= np.maximum(np.linalg.norm(foot, axis=1, keepdims=True), 1e-15)
    between = (np.einsum("ij,ij->i", np.cross(a, foot), pole) >= 0.0) & (
        np.einsum("ij,ij->i", np.cross(foot, b), pole) >= 0.0
    )
    return np.where(between, foot @ x, np.maximum(a @ x, b @ x))


def _tangent(normal: np.ndarray, at: np.ndarray) -> np.ndarray:
    """``normal`` (K, 3) made tangent to the sphere at ``at`` (K, 3), unit length."""
    t = normal - np.einsum("ij,ij->i", normal, at)[:, None] * at
    return t / np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-15)


def _offset(p: np.ndarray, pole: np.ndarray, margin: float) -> np.ndarray:
    """Point ``p`` (3,) moved ``margin`` (rad) outward, away from the arc's ``pole`` (3,)."""
    out = np.cos(margin) * p - np.sin(margin) * pole
    return out / np.linalg.norm(out)


def _held_loops(
    mesh: DirectionMesh, held: np.ndarray, tree: cKDTree, reach: float, walk: float
) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Per loop its points (K, 3), margins (K,) and chain flags (K,), ``held`` (E,) arcs held,
    far points walked in at most ``walk`` (deg; 0: straight toward the nearest sample)."""
    a_all = mesh.vertices[mesh.edges[:, 0]]
    b_all = mesh.vertices[mesh.edges[:, 1]]
    poles = np.cross(a_all, b_all)
    poles /= np.maximum(np.linalg.norm(poles, axis=1, keepdims=True), 1e-15)
    step = np.radians(STATION_DEG)
    loops = []
    for arcs in loop_arcs(mesh):
        # per point: position, margin of the arc leaving it, inward normal, whether on a chain
        rows = []
        for i, e in enumerate(arcs):
            m = float(mesh.margins[e])
            if not held[e]:
                rows.append((a_all[e], m, poles[e], False))
                continue
            prev = arcs[i - 1]
            # the arc's start: a vertex both chains share may move; next to a kept arc it stays
            both = poles[e] + poles[prev] if held[prev] else poles[e]
            rows.append((a_all[e], 0.0, both, bool(held[prev])))
            # its stations on the widened edge (the first, at the vertex, only when widened)
            om = _angle(a_all[e], b_all[e])
            count = max(1, int(np.ceil(om / step)))
            for t in np.arange(0 if m > 0.0 else 1, count) / count:
                rows.append(
                    (_offset(_slerp(a_all[e], b_all[e], om, t), poles[e], m), 0.0, poles[e], True)
                )
            if m > 0.0:
                rows.append((_offset(b_all[e], poles[e], m), 0.0, poles[e], True))
        p, widen, normals, chain = (np.array(c) for c in zip(*rows, strict=True))
        held_loop = _hold_chain(p, widen, _tangent(normals, p), chain, tree, reach, walk)
        loops.extend(_cut_slivers(*held_loop, tree, reach))
    return loops


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    """The angle (rad) between unit directions ``a`` and ``b`` (3,)."""
    # np.cross's products and differences, without its per-call axis handling (a tenth the time)
    cross = np.array(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    )
    return float(np.arctan2(np.linalg.norm(cross), a @ b))


def _slerp(a: np.ndarray, b: np.ndarray, om: float, t: float) -> np.ndarray:
    """The unit direction ``t`` of the way along the arc ``a -> b`` (3,) of angle ``om`` (rad)."""
    if np.sin(om) < 1e-12:
        return a.copy()
    x = (np.sin((1.0 - t) * om) * a + np.sin(t * om) * b) / np.sin(om)
    return x / np.linalg.norm(x)


def _hold_chain(
    p: np.ndarray,
    w: np.ndarray,
    n: np.ndarray,
    chain: np.ndarray,
    tree: cKDTree,
    reach: float,
    walk: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One loop's points (K, 3), margins (K,), inward normals (K, 3), chain flags (K,): held,
    refined, unfolded.
    """
    original = p.copy()
    far = chain & (tree.query(p)[0] > chord(reach))
    p = p.copy()
    p[far] = _walk(p[far], n[far], tree, reach, walk)
    spread = np.radians(SPREAD_STATIONS * STATION_DEG)
    for _ in range(REFINE_PASSES):
        nxt = np.roll(np.arange(p.shape[0]), -1)
        moved_apart = np.einsum("ij,ij->i", p, p[nxt]) < np.cos(spread)
        gap = chain & chain[nxt] & (far | far[nxt]) & moved_apart
        if not gap.any():
            break
        mid = original[gap] + original[nxt[gap]]
        mid /= np.linalg.norm(mid, axis=1, keepdims=True)
        mid_n = _tangent(n[gap] + n[nxt[gap]], mid)
        mid_far = tree.query(mid)[0] > chord(reach)
        held = mid.copy()
        held[mid_far] = _walk(mid[mid_far], mid_n[mid_far], tree, reach, walk)
        at = np.flatnonzero(gap) + 1
        p = np.insert(p, at, held, axis=0)
        original = np.insert(original, at, mid, axis=0)
        n = np.insert(n, at, mid_n, axis=0)
        w = np.insert(w, at, 0.0)
        chain = np.insert(chain, at, True)
        far = np.insert(far, at, mid_far)
    p, w, chain = _unfolded(p, w, chain)
    return _held_chords(p, w, chain, tree, reach, walk)


def _held_chords(
    p: np.ndarray, w: np.ndarray, chain: np.ndarray, tree: cKDTree, reach: float, walk: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points (K, 3), margins (K,), chain flags (K,) with chain points and chords held within
    ``reach`` (rad): a chord whose middle or quarters lie ``CHORD_SLACK_DEG`` farther gets its
    middle held.
    """
    bound, slack = chord(reach), chord(reach + np.radians(CHORD_SLACK_DEG))
    chord_walk = CHORD_WALK_DEG if walk > 0.0 else 0.0
    for _ in range(CHORD_PASSES):
        k = p.shape[0]
        nxt, prev = np.roll(np.arange(k), -1), np.roll(np.arange(k), 1)
        pole = np.cross(p, p[nxt])
        pole /= np.maximum(np.linalg.norm(pole, axis=1, keepdims=True), 1e-15)
        lone = chain & (tree.query(p)[0] > bound)
        if lone.any():
            p = p.copy()
            n_lone = _tangent(pole[lone] + pole[prev[lone]], p[lone])
            p[lone] = _walk(p[lone], n_lone, tree, reach, walk)
        mid = p + p[nxt]
        mid /= np.linalg.norm(mid, axis=1, keepdims=True)
        # a chain chord, or the first or last chord of a chain (from the vertex a kept arc ends at)
        gap = (chain | chain[nxt]) & (w == 0.0) & (_worst(p, tree) > slack)
        if not gap.any() and not lone.any():
            break
        at = np.flatnonzero(gap)
        # straight toward the nearest sample: the least move, no jump across a bay to fold back
        held = _walk(
            mid[at], _tangent(np.cross(p[at], p[nxt[at]]), mid[at]), tree, reach, chord_walk
        )
        p = np.insert(p, at + 1, held, axis=0)
        w = np.insert(w, at + 1, 0.0)
        chain = np.insert(chain, at + 1, True)
        p, w, chain = _unfolded(p, w, chain)
    # a point the walk put on its neighbour (both met the same sample's reach) is dropped
    nxt = np.roll(np.arange(p.shape[0]), -1)
    keep = ~(chain & (np.einsum("ij,ij->i", p, p[nxt]) >= 1.0 - 1e-15))
    return p[keep], w[keep], chain[keep]


def _worst(p: np.ndarray, tree: cKDTree) -> np.ndarray:
    """Per chord ``i -> i+1`` of the closed loop ``p`` (K, 3): the farthest (chord length) its
    quarters and middle lie from the taught directions in ``tree``."""
    q = np.stack([(1.0 - t) * p + t * np.roll(p, -1, axis=0) for t in (0.25, 0.5, 0.75)])
    q /= np.linalg.norm(q, axis=2, keepdims=True)
    return tree.query(q)[0].max(axis=0)


def _cut_slivers(
    p: np.ndarray, w: np.ndarray, chain: np.ndarray, tree: cKDTree, reach: float
) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The closed loop ``p`` (K, 3), margins ``w`` (K,), chain flags (K,) cut at its slivers.

    A sliver: a chain chord ``i -> i+1`` lying past the reach as ``_held_chords`` judges it, and
    a chain chord ``j -> j+1`` running back beside it, ``p[j]`` and ``p[j+1]`` within
    ``SLIVER_DEG`` of ``p[i+1]`` and ``p[i]``, no taught sample that near the first. Cut, the
    loop closes ``i -> j+1`` and ``i+1 .. j`` closes on its own (dropped under 3 points), each
    then unfolded (the hairpins a cut leaves at its ends cross): the region loses the sliver
    alone. Returns the loops (points, margins, chain flags).
    """
    k, width = p.shape[0], np.radians(SLIVER_DEG)
    nxt = np.roll(np.arange(k), -1)
    bare = chain & chain[nxt] & (w == 0.0)
    far = bare & (_worst(p, tree) > chord(reach + np.radians(CHORD_SLACK_DEG)))
    for i in np.flatnonzero(far):
        a, b = p[i], p[nxt[i]]
        # j -> j+1 back beside i -> i+1, j not i, leaving the rest of the loop 3 points
        back = bare & (np.linalg.norm(p - b, axis=1) <= chord(width))
        back &= (np.linalg.norm(p[nxt] - a, axis=1) <= chord(width)) & ((nxt - i - 2) % k < k - 3)
        arc = (a[None], b[None], np.cross(a, b)[None] / np.linalg.norm(np.cross(a, b)))
        near = tree.data[tree.query_ball_point(a, np.linalg.norm(a - b) + chord(width))]
        if back.any() and all(_nearest_cos(x, *arc)[0] < np.cos(width) for x in near):
            parts = np.split(np.roll(np.arange(k), -(i + 1)), [(np.flatnonzero(back)[0] - i) % k])
            cut = [_unfolded(p[t], w[t], chain[t]) for t in parts if t.size >= 3]
            return [c for part in cut for c in _cut_slivers(*part, tree, reach)]
    return [(p, w, chain)]


def _walk(
    p: np.ndarray, n: np.ndarray, tree: cKDTree, reach: float, walk: float = WALK_DEG
) -> np.ndarray:
    """Points (F, 3) walked in along their inward normals (F, 3) to the first place within
    ``reach`` (rad) of a taught direction, at most ``walk`` (deg), or toward the nearest one.
    """
    out = p.copy()
    left = np.arange(p.shape[0])
    bound = chord(reach)
    steps = np.arange(1, int(round(walk / WALK_STEP_DEG)) + 1)
    for first in range(0, steps.size, WALK_BATCH):
        if left.size == 0:
            return out
        # the next WALK_BATCH steps of every point left, at once: q[s, f] is point f, step s
        d = np.radians(steps[first : first + WALK_BATCH] * WALK_STEP_DEG)[:, None, None]
        q = np.cos(d) * p[left][None] + np.sin(d) * n[left][None]
        q /= np.linalg.norm(q, axis=2, keepdims=True)
        got = tree.query(q)[0] <= bound
        # each point stops at its first step within the reach
        stopped = got.any(axis=0)
        at = np.argmax(got, axis=0)[stopped]
        out[left[stopped]] = q[at, np.flatnonzero(stopped)]
        left = left[~stopped]
    if left.size:
        # along the great circle from the nearest sample y toward the point, ``reach`` from y
        _, nearest = tree.query(p[left])
        y = tree.data[nearest]
        t = _tangent(p[left] - y, y)
        # a hair inside the reach: a later test against it must not sit where rounding decides
        inside = reach - INSIDE_RAD
        out[left] = np.cos(inside) * y + np.sin(inside) * t
        out[left] /= np.linalg.norm(out[left], axis=1, keepdims=True)
    return out


def _unfolded(
    p: np.ndarray, w: np.ndarray, chain: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The closed loop ``p`` (K, 3), margins ``w`` (K,), chain flags, with held folds cut.

    Where chord ``i -> i+1`` crosses chord ``j -> j+1`` (``j - i`` at most ``FOLD_WINDOW``), points
    ``i+1 .. j`` become the crossing point; the region only shrinks there.
    """
    while True:
        k = p.shape[0]
        pole = np.cross(p, np.roll(p, -1, axis=0))
        unit = pole / np.maximum(np.linalg.norm(pole, axis=1, keepdims=True), 1e-300)
        # the unheld loop has no crossing: every one is a held chain's
        i, j = first_fold(p, unit, min(FOLD_WINDOW, k - 3))
        if i < 0:
            return p, w, chain
        x = np.cross(pole[i], pole[(i + j) % k])
        x /= np.linalg.norm(x)
        x = x if x @ p[i] > 0.0 else -x
        at = (i + 1) % k
        p, w, chain = p.copy(), w.copy(), chain.copy()
        # x -> the point after j runs along the chord j: its widening stays
        p[at], w[at], chain[at] = x, w[(i + j) % k], True
        keep = np.ones(k, dtype=bool)
        keep[(i + 2 + np.arange(j - 1)) % k] = False
        p, w, chain = p[keep], w[keep], chain[keep]
