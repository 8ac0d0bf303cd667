"""Routing along the region: where the gate's slew step aims when the straight way leaves it.

Across a concave wall the gate's corrected step lands back on the wall every cycle (``SLEWED``,
never arriving). The gate keeps its plain step while it makes way (:meth:`Router.wanted`);
when a wall holds it, :class:`Router` gives it a *sub-goal* for that target:

1. *Straight*: the straight path (great circle on two servos, shortest rotation on three),
   sampled every ``SEGMENT_STEP_DEG``, is inside: the sub-goal is the target itself.
2. *Roadmap* (built once): a Fibonacci lattice of limb directions ``LATTICE_STEP_DEG`` apart,
   flooded from the present pose over the region (on three servos a twist found from a
   neighbour's, within ``TWIST_TRIES_DEG``); neighbours joined where the path between is inside.
3. *Distances to the target*: Dijkstra from the target over the roadmap (reused while a
   streamed target moves less than ``REUSE_SPACINGS``).
4. *Sub-goal*: the farthest point, within ``LOOKAHEAD_DEG`` along the best route, that the
   straight path from the present pose reaches inside; the gate aims there until half way,
   then asks again. On three servos the route's twist goes linearly from the present to the
   target's.

The sub-goal only aims the step: the gate still limits, corrects and checks what it writes, so
routing never weakens what the gate promises. Its reach bound (docs/safety.md) is
``REACH_FACTOR * L / max_step + REACH_EXTRA_CYCLES`` cycles, L the shortest path inside.
"""

from __future__ import annotations

import functools
import math
import time

import numpy as np
from scipy.sparse import coo_matrix, csr_matrix
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

from limbctl.geometry import scalar
from limbctl.geometry.quat import limb_direction, swing_from_direction
from limbctl.geometry.twist import compose, decompose, wrap

#: Spacing (deg) of the roadmap's lattice: a passage of the region narrower than about two of
#: them may have no node in it (the route then goes round, or the gate steps straight as
#: before); 1.5 deg keeps a 60 x 60 deg region to ~1600 nodes, built in tens of milliseconds.
LATTICE_STEP_DEG = 1.5
#: Neighbours within this many lattice spacings are joined: on a Fibonacci lattice 1.6 gives
#: each node 6-8 neighbours, so a route turns in steps of about 45 deg, not 60 or 90.
NEIGHBOUR_SPACINGS = 1.6
#: The target and the present pose join the roadmap's nodes within this many spacings: at least
#: one node of the lattice lies within one spacing of any direction, and two more let a pose in a
#: corner reach one past the corner.
ATTACH_SPACINGS = 3.0
#: Spacing (deg) of the samples that judge a straight path inside: a dent narrower than this
#: can slip between two samples, which costs nothing of safety (the gate corrects the step and
#: checks what it writes), only a step that slides on the wall.
SEGMENT_STEP_DEG = 0.5
#: A sample this far (deg) outside the region still counts as inside: a path along a straight
#: wall has its samples on the wall, which rounding puts a hair outside; a step this far out
#: is corrected back by no more than a fifth of a 120 deg/s, 200 Hz step (0.6 deg).
VISIBLE_SLACK_DEG = 0.1
#: How far along the route (deg) the sub-goal may lie: twenty default steps (0.6 deg), so the
#: step always has somewhere to go; few route points (~8), so the farthest-first search for
#: one in reach stays short.
LOOKAHEAD_DEG = 12.0
#: Twist offsets (deg) from a neighbour's twist tried for a new node on three servos, nearest
#: first: a band whose centre turns 1 deg per deg of swing moves 1.5-2.4 deg between nodes.
TWIST_TRIES_DEG = (0.0, 3.0, -3.0, 8.0, -8.0, 20.0, -20.0, 45.0, -45.0)
#: The stated bound: a target inside the region is reached within ``REACH_FACTOR * L /
#: max_step + REACH_EXTRA_CYCLES`` cycles, L the shortest path inside (on three servos plus the
#: twist to turn). The route bends at lattice nodes, up to a spacing off the wall (a few per cent
#: over a long route), and the plain step first slides into a bay until the wall holds it:
#: measured up to 24 cycles over L / max_step (benchmarks/bench_reach.py, seeds the tests do
#: not use); 40 leaves room for bays not yet measured.
REACH_FACTOR = 1.05
REACH_EXTRA_CYCLES = 40
#: A target within this many lattice spacings of the last one routed to takes the same route
#: lengths (a leader streaming a target behind a wall moves it every cycle: one Dijkstra, ~1 ms,
#: per new target would be paid every cycle); the last route point is the target itself.
REUSE_SPACINGS = 0.5
#: Rows of the probe that times one batch of ``contains`` against single calls: whichever is
#: cheaper for a call's number of rows is used (a fitted twist region's batch kernel runs on a
#: thread pool that costs ~12 ms a call on a busy two-core machine, its single kernel ~2 us a
#: row; a numpy region is the other way round).
PROBE_ROWS = 64
#: The gate's plain step is kept while it comes at least this fraction of a step nearer the
#: target: sliding along a wall up to 75 deg off the target's way still does; at a concave wall
#: the corrected step comes back to where it was (0). Routing only when stuck keeps its cost off
#: the cycles of a sweep along the boundary, where a corrected target lies on a curved edge and
#: the straight way to it leaves the region by a hair every cycle (three-servo demo).
STUCK_FRACTION = 0.25
#: A pose this close (rad) to a path or a point is on it: far above rounding (1e-12), far below
#: any step.
ON_PATH = 1e-9


class Router:
    """Sub-goals for a gate's slew step, along the region (see the module docstring).

    Parameters
    ----------
    envelope : RegionModel
        The region: ``contains``/``correct`` on one quaternion (4,) and, when it can, (N, 4).
    twist : bool
        False for a two-servo rig (poses are limb directions, the path between two a great
        circle), True for three servos (poses are orientations, the path the shortest rotation).
    """

    def __init__(self, envelope, twist: bool) -> None:
        self.envelope = envelope
        self.twist = twist
        self._batch: bool | None = None
        self._batch_rows = math.inf  # rows from which a batch call is the cheaper
        self._nodes: np.ndarray | None = None  # (M, 3) directions of the roadmap's nodes
        self._node_twist: np.ndarray | None = None  # (M,) a twist inside at each node (rad)
        self._graph = None  # (M, M) csr of edge lengths (rad)
        self._tree: cKDTree | None = None
        self._field_key: np.ndarray | None = None  # the target the field was computed for
        self._field: tuple[np.ndarray, np.ndarray] | None = None
        self._straight: tuple[bytes, np.ndarray] | None = None  # (target, start) judged inside
        self._aim: tuple | None = None  # (target, start, route point, distance at the start)
        self._engaged: np.ndarray | None = None  # the target routing began for

    # ---- the region --------------------------------------------------------------------------
    @property
    def batched(self) -> bool:
        """Whether the envelope answers ``contains`` for (N, 4) at once (the fitted regions and
        the papers' models do; a test's scalar region may not)."""
        if self._batch is None:
            probe = np.tile([1.0, 0.0, 0.0, 0.0], (PROBE_ROWS, 1))
            try:
                t0 = time.perf_counter()
                shape = np.asarray(self.envelope.contains(probe)).shape
                t1 = time.perf_counter()
                for row in probe[:4]:
                    self.envelope.contains(row)
                t2 = time.perf_counter()
            except (TypeError, ValueError, IndexError):
                shape = ()
            self._batch = shape == (PROBE_ROWS,)
            if self._batch:  # a batch pays for itself from this many rows on (timed once)
                self._batch_rows = max(2.0, (t1 - t0) / max((t2 - t1) / 4.0, 1e-9))
        return self._batch

    def inside_many(self, q: np.ndarray) -> np.ndarray:
        """(N,) bool: ``contains`` of each orientation (N, 4), strictly (building the roadmap)."""
        q = np.ascontiguousarray(q, dtype=np.float64).reshape(-1, 4)
        if self.batched and q.shape[0] >= self._batch_rows:
            return np.asarray(self.envelope.contains(q), dtype=bool).copy()
        return np.array([bool(self.envelope.contains(row)) for row in q], dtype=bool)

    def inside(self, q: np.ndarray) -> bool:
        """One orientation (4,) inside the region, up to ``VISIBLE_SLACK_DEG``."""
        if bool(self.envelope.contains(q)):
            return True
        fixed = np.asarray(self.envelope.correct(q), dtype=np.float64)
        return self._distance(q, fixed) <= math.radians(VISIBLE_SLACK_DEG)

    def _distance(self, a: np.ndarray, b: np.ndarray) -> float:
        """Distance (rad) of two poses (4,): limb directions' angle, or geodesic on SO(3)
        (scalar arithmetic: the gate's hot path)."""
        if not self.twist:
            return scalar.angle(scalar.limb(a), scalar.limb(b))
        aw, ax, ay, az = a.tolist()
        bw, bx, by, bz = b.tolist()
        if aw * bw + ax * bx + ay * by + az * bz < 0.0:
            bw, bx, by, bz = -bw, -bx, -by, -bz
        # 4 atan2(|a - b|, |a + b|) = 2 acos |<a, b>|, accurate near 0
        return 4.0 * math.atan2(
            math.sqrt((aw - bw) ** 2 + (ax - bx) ** 2 + (ay - by) ** 2 + (az - bz) ** 2),
            math.sqrt((aw + bw) ** 2 + (ax + bx) ** 2 + (ay + by) ** 2 + (az + bz) ** 2),
        )

    def _near_target(self, before: np.ndarray, target_q: np.ndarray) -> bool:
        """Whether ``target_q`` is within REUSE_SPACINGS lattice spacings of ``before``."""
        return self._distance(before, target_q) <= math.radians(REUSE_SPACINGS * LATTICE_STEP_DEG)

    def _on_path(self, a: np.ndarray, p: np.ndarray, b: np.ndarray) -> bool:
        """Whether pose ``p`` lies on the straight path from ``a`` to ``b`` (all (4,))."""
        return self._distance(a, p) + self._distance(p, b) - self._distance(a, b) <= ON_PATH

    def _distance_rows(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Distances (rad) row by row of (N, 4) poses."""
        if not self.twist:
            return _arc(limb_direction(a), limb_direction(b))
        return 2.0 * _arc(a, b, signed=True)

    # ---- straight paths ----------------------------------------------------------------------
    def _samples(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Quaternions (n_i - 1, 4) along the straight paths from each pose of ``a`` to the same
        row of ``b`` (N, 4), ``1/n_i`` of it apart with ``n_i = ceil(length_i /
        SEGMENT_STEP_DEG)``, the ends left out; (N, S, 4), short paths padded with their start."""
        va, vb = (a, b) if self.twist else (limb_direction(a), limb_direction(b))
        n = np.ceil(self._distance_rows(a, b) / math.radians(SEGMENT_STEP_DEG))
        n = np.maximum(n, 1.0)[:, None]  # (N, 1)
        k = np.arange(1, max(int(n.max(initial=1.0)), 2))[None, :]  # (1, S)
        f = np.where(k < n, k / n, 0.0)  # (N, S)
        pts = _slerp_rows(va, vb, f, signed=self.twist)
        return pts if self.twist else swing_from_direction(pts)

    def paths_inside(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """(N,) bool: the straight path from each pose of ``a`` to the same row of ``b`` (both
        (N, 4)) strictly inside at its samples (building the roadmap)."""
        pts = self._samples(a, b)
        return self.inside_many(pts.reshape(-1, 4)).reshape(pts.shape[:2]).all(axis=1)

    def clear(self, a: np.ndarray, b: np.ndarray) -> bool:
        """Whether the straight path from pose ``a`` to ``b`` (4,) is inside, up to
        ``VISIBLE_SLACK_DEG``, at the samples of :meth:`_samples`; judged in bisection order
        (middle, quarters, ...), so a blocked path is found out in a few calls."""
        pts = self._samples(a[None], b[None])[0]
        count = pts.shape[0] + 1
        if count < 2:
            return True
        order = _bisection_order(count)
        return all(self.inside(pts[k - 1]) for k in order)

    # ---- the gate's question -----------------------------------------------------------------
    def wanted(self, target_q: np.ndarray, progress: float, moved: float, max_step: float) -> bool:
        """Whether the gate should aim along the region this cycle: its plain step (straight
        toward ``target_q``, corrected) came ``progress`` rad nearer the target, less than
        ``STUCK_FRACTION`` of ``max_step`` (a wall holds it), or its correction moved it
        ``moved`` rad from the last pose, more than ``max_step`` plus the slack (it jumped
        across a dent), or routing already began for this target (it stays on until the target
        moves on or the straight way is inside)."""
        if self._engaged is not None and self._near_target(self._engaged, target_q):
            return True
        self._engaged = None
        jumped = moved > max_step + math.radians(VISIBLE_SLACK_DEG)
        return progress < STUCK_FRACTION * max_step or jumped

    def subgoal(self, current_q: np.ndarray, target_q: np.ndarray) -> np.ndarray:
        """Where to aim this cycle's step: ``target_q`` itself when the straight path from
        ``current_q`` to it is inside, else a route point toward it (both (4,) quaternions)."""
        key = target_q.tobytes()
        if self._straight is not None and self._straight[0] == key:
            if self._on_path(self._straight[1], current_q, target_q):
                return target_q  # still on the path judged inside
        if self._aim is not None and self._near_target(self._aim[0], target_q):
            _, start, aim, first = self._aim
            # still on the way to the last route point, and not yet half way: keep aiming there
            if self._on_path(start, current_q, aim) and self._distance(current_q, aim) > first / 2:
                return aim
        self._straight = self._aim = None
        if self.clear(current_q, target_q):
            self._straight, self._engaged = (key, current_q.copy()), None
            return target_q
        self._engaged = target_q.copy()
        aim = self._aim_along(current_q, target_q)
        if aim is not target_q:
            self._aim = (target_q.copy(), current_q.copy(), aim, self._distance(current_q, aim))
        return aim

    def _aim_along(self, current_q: np.ndarray, target_q: np.ndarray) -> np.ndarray:
        """The farthest route point toward ``target_q`` the straight path from ``current_q``
        reaches inside; ``target_q`` itself when the roadmap knows no way."""
        route = self._route(current_q, target_q)
        if route is None:
            return target_q  # no way round known: the plain step
        for k in range(route.shape[0] - 1, -1, -1):
            if self.clear(current_q, route[k]):
                if k + 1 < route.shape[0] and self._distance(current_q, route[k]) < ON_PATH:
                    # on a route point whose next one the samples judge a hair outside: aim
                    # at it anyway, the gate corrects the step
                    return route[k + 1]
                return route[k]
        return route[0]

    def _route(self, current_q: np.ndarray, target_q: np.ndarray) -> np.ndarray | None:
        """Route points (K, 4) from near ``current_q`` toward ``target_q``, at most
        LOOKAHEAD_DEG along, or None when the roadmap knows no way."""
        self.prepare(current_q)
        dist, pred = self._field_for(target_q)
        d_cur, tau_cur = _split(current_q, self.twist)
        near = self._near(d_cur)
        near = near[np.isfinite(dist[near])]
        if near.size == 0:
            return None
        cost = _arc(d_cur[None, :], self._nodes[near]) + dist[near]
        poses = self._node_poses(near)
        entry = next((i for i in np.argsort(cost) if self.clear(current_q, poses[i])), None)
        if entry is None:
            return None
        path, walked, m = [int(near[entry])], 0.0, self._nodes.shape[0]
        while walked < math.radians(LOOKAHEAD_DEG) and pred[path[-1]] != m:
            nxt = int(pred[path[-1]])
            if nxt < 0:
                return None
            walked += float(_arc(self._nodes[path[-1]], self._nodes[nxt]))
            path.append(nxt)
        points = self._waypoints(d_cur, tau_cur, self._nodes[np.array(path)], target_q)
        if pred[path[-1]] == m:  # the target is within the look-ahead: the route ends there
            return np.vstack([points, target_q])
        return points

    def _waypoints(self, d_cur, tau_cur, dirs: np.ndarray, target_q: np.ndarray) -> np.ndarray:
        """Poses (K, 4) at the route's directions ``dirs`` (K, 3); on three servos the twist
        goes linearly by route length from ``tau_cur`` to the target's (the region's own
        correction where that is outside)."""
        if not self.twist:
            return swing_from_direction(dirs)
        d_t, tau_t = _split(target_q, True)
        done = np.cumsum(_arc(np.vstack([d_cur, dirs[:-1]]), dirs))
        left = done[-1] + float(_arc(dirs[-1], d_t)) + 1e-12
        q = compose(dirs, tau_cur + wrap(tau_t - tau_cur) * done / left)
        for k in range(q.shape[0]):
            if not bool(self.envelope.contains(q[k])):
                q[k] = self.envelope.correct(q[k])
        return q

    # ---- the roadmap -------------------------------------------------------------------------
    def prepare(self, seed_q: np.ndarray) -> None:
        """Build the roadmap now (once) by flooding the region from pose ``seed_q`` (4,): the
        gate does it at start on regions that answer batches, so no cycle pays for it."""
        if self._nodes is None:
            self._build(np.asarray(seed_q, dtype=np.float64))

    def _node_poses(self, idx: np.ndarray) -> np.ndarray:
        return compose(self._nodes[idx], self._node_twist[idx] if self.twist else 0.0)

    def _near(self, d: np.ndarray) -> np.ndarray:
        r = 2.0 * math.sin(0.5 * math.radians(ATTACH_SPACINGS * LATTICE_STEP_DEG))
        return np.asarray(self._tree.query_ball_point(d, r), dtype=np.int64)

    def _build(self, seed_q: np.ndarray) -> None:
        """Flood the lattice over the region from ``seed_q``'s direction; join neighbours."""
        points, tree, adjacency, pairs = lattice()
        d0, tau0 = _split(seed_q, self.twist)
        twist = np.full(points.shape[0], np.nan)  # NaN: not tried, inf: tried, outside
        start = int(tree.query(d0)[1])
        twist[start] = tau0
        frontier = np.array([start])
        while frontier.size:
            rows = adjacency[frontier]  # the frontier's lattice neighbours, row by row
            cand = rows.indices
            parent = np.repeat(frontier, np.diff(rows.indptr))
            fresh = np.isnan(twist[cand])
            cand, first = np.unique(cand[fresh], return_index=True)
            found = self._node_twists(points[cand], twist[parent[fresh][first]])
            twist[cand] = np.where(np.isnan(found), np.inf, found)
            frontier = cand[np.isfinite(found)]
        keep = np.isfinite(twist)
        index = np.cumsum(keep) - 1  # lattice point -> node
        self._nodes, self._node_twist = points[keep], twist[keep]
        self._tree = cKDTree(self._nodes)
        pairs = index[pairs[keep[pairs[:, 0]] & keep[pairs[:, 1]]]]
        ok = self.paths_inside(self._node_poses(pairs[:, 0]), self._node_poses(pairs[:, 1]))
        i, j = pairs[ok, 0], pairs[ok, 1]
        m = self._nodes.shape[0]
        w = _arc(self._nodes[i], self._nodes[j])
        self._graph = coo_matrix((w, (i, j)), shape=(m, m)).tocsr()

    def _node_twists(self, d: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """A twist (rad) inside at each direction (N, 3) near ``tau`` (N,), NaN where none of
        TWIST_TRIES_DEG is (two servos: twist 0, NaN where the direction is outside)."""
        if not self.twist:
            return np.where(self.inside_many(compose(d, 0.0)), 0.0, np.nan)
        found = np.full(d.shape[0], np.nan)
        for offset in np.radians(TWIST_TRIES_DEG):  # nearest first, only where none fit yet
            left = np.flatnonzero(np.isnan(found))
            if left.size == 0:
                break
            taus = wrap(tau[left] + offset)
            ok = self.inside_many(compose(d[left], taus))
            found[left[ok]] = taus[ok]
        return found

    def _field_for(self, target_q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Route lengths (M,) from each node to the target and each node's next node (M,)
        (M itself: the target; -9999: none)."""
        if self._field is not None and self._near_target(self._field_key, target_q):
            return self._field  # a target streamed a little further: the same way there
        m = self._nodes.shape[0]
        d_t, _ = _split(target_q, self.twist)
        near = self._near(d_t)
        poses = self._node_poses(near)
        near = near[[self.clear(target_q, p) for p in poses]] if near.size else near
        w = _arc(d_t[None, :], self._nodes[near])
        extra = coo_matrix((w, (near, np.full(near.size, m))), shape=(m + 1, m + 1))
        graph = self._graph.tocoo()
        full = coo_matrix((graph.data, (graph.row, graph.col)), shape=(m + 1, m + 1)) + extra
        dist, pred = dijkstra(full, directed=False, indices=m, return_predecessors=True)
        self._field_key, self._field = target_q.copy(), (dist[:m], pred[:m])
        return self._field


def _bisection_order(count: int) -> list[int]:
    """1 .. count - 1, each once, middle first, then the middles of the halves left, and so on."""
    order, spans = [], [(1, count - 1)]
    while spans:
        lo, hi = spans.pop(0)
        if lo <= hi:
            mid = (lo + hi) // 2
            order.append(mid)
            spans += [(lo, mid - 1), (mid + 1, hi)]
    return order


@functools.cache
def lattice() -> tuple[np.ndarray, cKDTree, csr_matrix, np.ndarray]:
    """The roadmap's lattice, built once per process: points (N, 3) LATTICE_STEP_DEG apart, their
    tree, the neighbour adjacency (N, N) (within NEIGHBOUR_SPACINGS spacings) and its pairs
    (P, 2), i < j."""
    points = fibonacci_sphere(math.radians(LATTICE_STEP_DEG))
    tree = cKDTree(points)
    r = 2.0 * math.sin(0.5 * math.radians(NEIGHBOUR_SPACINGS * LATTICE_STEP_DEG))
    pairs = tree.query_pairs(r, output_type="ndarray").reshape(-1, 2)
    n = points.shape[0]
    both = np.concatenate([pairs, pairs[:, ::-1]])
    adjacency = coo_matrix((np.ones(both.shape[0]), (both[:, 0], both[:, 1])), shape=(n, n))
    return points, tree, adjacency.tocsr(), pairs


def fibonacci_sphere(spacing: float) -> np.ndarray:
    """Directions (N, 3) spread evenly over the sphere, about ``spacing`` rad apart:
    ``N = 4 pi / spacing^2``, point k at height ``1 - (2k + 1) / N`` and longitude
    ``k pi (3 - sqrt 5)`` (the golden angle)."""
    n = int(math.ceil(4.0 * math.pi / spacing**2))
    k = np.arange(n)
    z = 1.0 - (2.0 * k + 1.0) / n
    lon = k * math.pi * (3.0 - math.sqrt(5.0))
    rho = np.sqrt(1.0 - z * z)
    return np.stack([rho * np.cos(lon), rho * np.sin(lon), z], axis=1)


def _split(q: np.ndarray, twist: bool) -> tuple[np.ndarray, float]:
    """Limb direction (3,) and twist (rad; 0 on two servos) of one quaternion (4,)."""
    d, tau = decompose(q)
    return d, float(tau) if twist else 0.0


def _arc(a: np.ndarray, b: np.ndarray, signed: bool = False) -> np.ndarray:
    """Angle (rad) between unit vectors row by row, ``2 atan2(|a - s b|, |a + s b|)``, with
    ``s = sign(a . b)`` when ``signed`` (q and -q one rotation), else 1."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    if signed:
        b = np.where(np.sum(a * b, axis=-1, keepdims=True) < 0.0, -b, b)
    return 2.0 * np.arctan2(np.linalg.norm(a - b, axis=-1), np.linalg.norm(a + b, axis=-1))


def _slerp_rows(a: np.ndarray, b: np.ndarray, f: np.ndarray, signed: bool) -> np.ndarray:
    """Points (N, S, dim) at fractions ``f`` (N, S) along the short arcs from each unit ``a``
    (N, dim) to the same row of ``b`` (N, dim): ``sin((1 - f) h) / sin h a + sin(f h) / sin h
    b``, h the arc."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    if signed:
        b = np.where(np.sum(a * b, axis=1, keepdims=True) < 0.0, -b, b)
    h = _arc(a, b)[:, None]  # (N, 1)
    s = np.sin(h)
    small = s < 1e-12
    s = np.where(small, 1.0, s)
    fa = np.where(small, 1.0 - f, np.sin((1.0 - f) * h) / s)[..., None]
    fb = np.where(small, f, np.sin(f * h) / s)[..., None]
    p = fa * a[:, None, :] + fb * b[:, None, :]
    return p / np.linalg.norm(p, axis=-1, keepdims=True)
