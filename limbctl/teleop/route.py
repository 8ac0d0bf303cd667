"""Routing along the region: where the slew step aims when a concave wall holds it."""

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
from limbctl.geometry.twist import compose, decompose, twisted, wrap

#: Lattice spacing (deg): a 60 x 60 deg region in ~1600 nodes; narrower passages may have none.
LATTICE_STEP_DEG = 1.5
#: Neighbours within this many spacings are joined: 6-8 per node, so a route turns ~45 deg.
NEIGHBOUR_SPACINGS = 1.6
#: The target and present pose join nodes this many spacings away: the nearest, one past a corner.
ATTACH_SPACINGS = 3.0
#: Sample spacing (deg) judging a straight path inside: a narrower dent costs a sliding step.
SEGMENT_STEP_DEG = 0.5
#: A sample this far (deg) outside still counts inside (rounding along a wall; < 1/5 step).
VISIBLE_SLACK_DEG = 0.1
#: How far along the route (deg) the sub-goal may lie: twenty default steps, ~8 route points.
LOOKAHEAD_DEG = 12.0
#: Twist offsets (deg) tried from a neighbour's for a new node on three servos, nearest first.
TWIST_TRIES_DEG = (0.0, 3.0, -3.0, 8.0, -8.0, 20.0, -20.0, 45.0, -45.0)
#: Splits of a twist interval finding a node's twist nearest a pose's (three servos), twice:
#: 180 deg / 8^2 < 3 deg, near a twist-limit step, for two ``contains`` batches of 8 rows a node.
TWIST_SPLITS = 8
#: The reach bound's terms: route bends (a few per cent over L) and a slide into a bay (measured
#: up to 24 cycles over L / max_step, benchmarks/bench_reach.py; 40 leaves room).
REACH_FACTOR = 1.05
REACH_EXTRA_CYCLES = 40
#: A target within this many spacings of the last reuses its route lengths (Dijkstra ~1 ms).
REUSE_SPACINGS = 0.5
#: Rows of the probe timing one batch ``contains`` against single calls.
PROBE_ROWS = 64
#: The plain step is kept while it comes this fraction of a step nearer (a concave wall gives 0).
STUCK_FRACTION = 0.25
#: A pose this close (rad) to a path or point is on it: far above rounding, far below a step.
ON_PATH = 1e-9
#: The same on the way to a route point (rad): the gate may correct a step up to
#: VISIBLE_SLACK_DEG off a path judged inside, which lengthens the way by at most twice that.
AIM_SLACK = 2.0 * math.radians(VISIBLE_SLACK_DEG)


class Router:
    """Sub-goals for a gate's slew step along the region ``envelope`` (``contains``/``correct`` on
    (4,), maybe (N, 4)); paths are shortest rotations with ``twist``, else great circles."""

    def __init__(self, envelope, twist: bool) -> None:
        self.envelope = envelope
        self.twist = twist
        self._batch: bool | None = None
        self._batch_rows = math.inf  # rows from which a batch call is the cheaper
        self._nodes: np.ndarray | None = None  # (M, 3) directions of the roadmap's nodes
        self._node_twist: np.ndarray | None = None  # (M,) a twist inside at each node (rad)
        # the roadmap's edges both ways, as CSR arrays (indptr, indices, length in rad)
        self._edges: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._tree: cKDTree | None = None
        self._field_key: np.ndarray | None = None  # the target the field was computed for
        self._field: tuple[np.ndarray, np.ndarray] | None = None
        self._straight: tuple[bytes, np.ndarray] | None = None  # (target, start) judged inside
        self._aim: tuple | None = None  # (target, start, route point, distance at the start)
        self._engaged: np.ndarray | None = None  # the target routing began for

    @property
    def batched(self) -> bool:
        """Whether the envelope answers ``contains`` for (N, 4) at once."""
        if self._batch is None:
            probe = np.tile([1.0, 0.0, 0.0, 0.0], (PROBE_ROWS, 1))
            try:
                # untimed, and before the loop's clock (Gate.start asks this): a kernel's first
                # call may load it or compile it (seconds), correct()'s too, which routing asks
                for rows in (probe, probe[0]):
                    self.envelope.contains(rows)
                    self.envelope.correct(rows)
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
        """Distance (rad) of two poses (4,): limb directions' angle, or geodesic on SO(3)."""
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

    def _on_path(self, a: np.ndarray, p: np.ndarray, b: np.ndarray, slack: float = ON_PATH) -> bool:
        """Whether pose ``p`` lies on the straight path from ``a`` to ``b`` (all (4,)): the way
        through it at most ``slack`` (rad) longer."""
        return self._distance(a, p) + self._distance(p, b) - self._distance(a, b) <= slack

    def _distance_rows(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Distances (rad) row by row of (N, 4) poses."""
        if not self.twist:
            return _arc(limb_direction(a), limb_direction(b))
        return 2.0 * _arc(a, b, signed=True)

    def _samples(self, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Samples (N, S, 4) SEGMENT_STEP_DEG apart along the paths from rows of ``a`` to ``b``
        (N, 4), ends left out, and which are samples (N, S) bool (short paths are padded with
        their start)."""
        va, vb = (a, b) if self.twist else (limb_direction(a), limb_direction(b))
        # the path's length: the limb directions' angle, or the geodesic (_distance_rows)
        length = 2.0 * _arc(a, b, signed=True) if self.twist else _arc(va, vb)
        n = np.ceil(length / math.radians(SEGMENT_STEP_DEG))
        n = np.maximum(n, 1.0)[:, None]  # (N, 1)
        k = np.arange(1, max(int(n.max(initial=1.0)), 2))[None, :]  # (1, S)
        on = k < n  # (N, S)
        f = np.where(on, k / n, 0.0)
        pts = _slerp_rows(va, vb, f, signed=self.twist)
        return (pts if self.twist else swing_from_direction(pts)), on

    def paths_inside(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """(N,) bool: the path from each row of ``a`` to ``b`` (N, 4) strictly inside."""
        pts, _ = self._samples(a, b)
        return self.inside_many(pts.reshape(-1, 4)).reshape(pts.shape[:2]).all(axis=1)

    def clear_rows(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """(N,) bool: :meth:`clear` of the paths from ``a`` (4,) to each row of ``b`` (N, 4),
        every sample of every path judged by ``contains`` in one batch, the refused ones by
        ``correct`` a round at a time (the roadmap's and the route's checks)."""
        b = np.asarray(b, dtype=np.float64).reshape(-1, 4)
        if b.shape[0] == 0:
            return np.zeros(0, dtype=bool)
        pts, on = self._samples(np.broadcast_to(a, b.shape), b)
        on[:, 0] = True  # a path within one sample step is judged at its start, as in clear
        ok = np.ones(on.shape, dtype=bool)
        ok[on] = self.inside_many(pts[on])
        # a sample contains() refused may lie within the slack: correct() (on three servos ~100
        # times dearer) judges one such sample per path a round, until each path has one
        # beyond the slack or none left
        clear = np.ones(b.shape[0], dtype=bool)
        while True:
            paths = np.flatnonzero(clear & ~ok.all(axis=1))
            if paths.size == 0:
                return clear
            first = np.argmin(ok[paths], axis=1)  # each path's first sample not yet judged in
            q = pts[paths, first]
            if self.batched and paths.size >= self._batch_rows:
                fixed = np.asarray(self.envelope.correct(q), dtype=np.float64).reshape(-1, 4)
            else:
                fixed = np.array([self.envelope.correct(row) for row in q], dtype=np.float64)
            within = self._distance_rows(q, fixed) <= math.radians(VISIBLE_SLACK_DEG)
            ok[paths[within], first[within]] = True
            clear[paths[~within]] = False

    def clear(self, a: np.ndarray, b: np.ndarray) -> bool:
        """Whether the path from ``a`` to ``b`` (4,) is inside up to VISIBLE_SLACK_DEG."""
        pts = self._samples(a[None], b[None])[0][0]
        count = pts.shape[0] + 1
        if count < 2:
            return True
        return all(self.inside(pts[k - 1]) for k in _bisection_order(count))

    def wanted(self, target_q: np.ndarray, progress: float, moved: float, max_step: float) -> bool:
        """Whether to route this cycle: the plain step made too little ``progress`` or jumped."""
        if self._engaged is not None and self._near_target(self._engaged, target_q):
            return True
        self._engaged = None
        jumped = moved > max_step + math.radians(VISIBLE_SLACK_DEG)
        return progress < STUCK_FRACTION * max_step or jumped

    def subgoal(self, current_q: np.ndarray, target_q: np.ndarray) -> np.ndarray:
        """Where to aim (4,): ``target_q`` when the path there is inside, else a route point."""
        key = target_q.tobytes()
        if self._straight is not None and self._straight[0] == key:
            if self._on_path(self._straight[1], current_q, target_q):
                return target_q  # still on the path judged inside
        if self._aim is not None and self._near_target(self._aim[0], target_q):
            _, start, aim, first = self._aim
            # still on the way to the last route point, and not yet half way: keep aiming there
            on_way = self._on_path(start, current_q, aim, AIM_SLACK)
            if on_way and self._distance(current_q, aim) > first / 2:
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
        """The farthest route point reachable straight from ``current_q`` (else ``target_q``)."""
        found = self._route(current_q, target_q)
        if found is None:
            return target_q  # no way round known: the plain step
        route, entry = found
        visible = self.clear_rows(current_q, route)
        for k in range(route.shape[0] - 1, -1, -1):
            if visible[k]:
                if k + 1 < route.shape[0] and self._distance(current_q, route[k]) < ON_PATH:
                    # on a route point whose next one is judged a hair outside: the gate corrects
                    return route[k + 1]
                return route[k]
        # none seen: the route's first point has the twist turned toward the target's, which
        # may put it past a wall; the entry node as it was judged seen is reachable straight
        return entry

    def _route(
        self, current_q: np.ndarray, target_q: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """Route points (K, 4) toward ``target_q``, LOOKAHEAD_DEG at most, and the pose (4,) of
        its entry node as judged seen from ``current_q``; None where no way is known."""
        self.prepare(current_q)
        dist, pred = self._field_for(target_q)
        d_cur, tau_cur = _split(current_q, self.twist)
        near = self._near(d_cur)
        near = near[np.isfinite(dist[near])]
        if near.size == 0:
            return None
        cost = _arc(d_cur[None, :], self._nodes[near]) + dist[near]
        poses = self._poses_at(near, tau_cur)
        order = np.argsort(cost)
        visible = order[self.clear_rows(current_q, poses[order])]
        if visible.size == 0:
            return None
        entry = int(visible[0])
        path, walked, m = [int(near[entry])], 0.0, self._nodes.shape[0]
        while walked < math.radians(LOOKAHEAD_DEG) and pred[path[-1]] != m:
            nxt = int(pred[path[-1]])
            if nxt < 0:
                return None
            walked += float(_arc(self._nodes[path[-1]], self._nodes[nxt]))
            path.append(nxt)
        points = self._waypoints(d_cur, tau_cur, np.array(path), target_q)
        if pred[path[-1]] == m:  # the target is within the look-ahead: the route ends there
            points = np.vstack([points, target_q])
        return points, poses[entry]

    def _waypoints(self, d_cur, tau_cur, path: np.ndarray, target_q: np.ndarray) -> np.ndarray:
        """Poses (K, 4) at the nodes ``path`` (K,), twist turning linearly to the target's, or
        where that is outside, the twist inside nearest it (:meth:`_poses_at`)."""
        dirs = self._nodes[path]
        if not self.twist:
            return swing_from_direction(dirs)
        d_t, tau_t = _split(target_q, True)
        done = np.cumsum(_arc(np.vstack([d_cur, dirs[:-1]]), dirs))
        left = done[-1] + float(_arc(dirs[-1], d_t)) + 1e-12
        return self._poses_at(path, tau_cur + wrap(tau_t - tau_cur) * done / left)

    def prepare(self, seed_q: np.ndarray) -> None:
        """Build the roadmap once, flooding the region from ``seed_q`` (4,)."""
        if self._nodes is None:
            self._build(np.asarray(seed_q, dtype=np.float64))

    def _node_poses(self, idx: np.ndarray) -> np.ndarray:
        return compose(self._nodes[idx], self._node_twist[idx] if self.twist else 0.0)

    def _poses_at(self, idx: np.ndarray, tau) -> np.ndarray:
        """Poses (K, 4) of nodes ``idx`` (K,): the roadmap's own on two servos; else at twists
        ``tau`` (rad, scalar or (K,)) where inside, else at the twist inside nearest it on the
        way to the node's flood twist, to 1/TWIST_SPLITS^2 of that way (the band at a direction
        is one interval of twist). A path to a node then turns the limb only as far as the band
        makes it, so it has a few samples, not one per 0.5 deg of a twist difference."""
        if not self.twist or idx.size == 0:
            return self._node_poses(idx)
        tau = np.broadcast_to(np.asarray(tau, dtype=np.float64), idx.shape)
        dirs = self._nodes[idx]
        poses = compose(dirs, tau)
        left = np.flatnonzero(~self.inside_many(poses))
        if left.size:
            sw = swing_from_direction(dirs[left])[:, None, :]  # (L, 1, 4)
            lo = tau[left]  # outside
            hi = lo + wrap(self._node_twist[idx[left]] - lo)  # inside
            rows, steps = np.arange(left.size), np.arange(1, TWIST_SPLITS + 1) / TWIST_SPLITS
            for _ in range(2):  # the way split in TWIST_SPLITS, then the first inside split again
                cand = lo[:, None] + (hi - lo)[:, None] * steps  # (L, S), the last one hi
                ok = self.inside_many(twisted(sw, cand).reshape(-1, 4)).reshape(cand.shape)
                ok[:, -1] = True
                first = np.argmax(ok, axis=1)
                lo = np.where(first > 0, cand[rows, first - 1], lo)
                hi = cand[rows, first]
            poses[left] = twisted(sw[:, 0, :], hi)
        return poses

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
        # both ways of each edge, rows sorted: the field's graph appends the target's row to it
        both = coo_matrix((np.r_[w, w], (np.r_[i, j], np.r_[j, i])), shape=(m, m)).tocsr()
        both.sum_duplicates()
        self._edges = (both.indptr, both.indices, both.data)

    def _node_twists(self, d: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """A twist (N,) (rad) inside at each direction (N, 3) near ``tau``, else NaN."""
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
        """Route lengths (M,) to the target and each node's next (M,) (M: target; <0: none)."""
        if self._field is not None and self._near_target(self._field_key, target_q):
            return self._field  # a target streamed a little further: the same way there
        m = self._nodes.shape[0]
        d_t, tau_t = _split(target_q, self.twist)
        near = self._near(d_t)
        poses = self._poses_at(near, tau_t)
        near = near[self.clear_rows(target_q, poses)] if near.size else near
        if near.size == 0:  # no node seen from the target: no way known (Dijkstra's -9999)
            none = (np.full(m, np.inf), np.full(m, -9999, dtype=np.int32))
            self._field_key, self._field = target_q.copy(), none
            return self._field
        w = _arc(d_t[None, :], self._nodes[near])
        # the roadmap's edges both ways and the target's out of it, as node M: M + 1 nodes
        indptr, cols, lengths = self._edges
        order = np.argsort(near, kind="stable")
        full = csr_matrix(
            (
                np.concatenate([lengths, w[order]]),
                np.concatenate([cols, near[order]]),
                np.r_[indptr, indptr[-1] + near.size],
            ),
            shape=(m + 1, m + 1),
        )
        dist, pred = dijkstra(full, directed=True, indices=m, return_predecessors=True)
        self._field_key, self._field = target_q.copy(), (dist[:m], pred[:m])
        return self._field


@functools.cache
def _bisection_order(count: int) -> tuple[int, ...]:
    """1 .. count - 1, each once, middle first, then the middles of the halves left, and so on."""
    order, spans = [], [(1, count - 1)]
    while spans:
        lo, hi = spans.pop(0)
        if lo <= hi:
            mid = (lo + hi) // 2
            order.append(mid)
            spans += [(lo, mid - 1), (mid + 1, hi)]
    return tuple(order)


@functools.cache
def lattice() -> tuple[np.ndarray, cKDTree, csr_matrix, np.ndarray]:
    """Lattice points (N, 3), their tree, adjacency (N, N) and pairs (P, 2), i < j (cached)."""
    points = fibonacci_sphere(math.radians(LATTICE_STEP_DEG))
    tree = cKDTree(points)
    r = 2.0 * math.sin(0.5 * math.radians(NEIGHBOUR_SPACINGS * LATTICE_STEP_DEG))
    pairs = tree.query_pairs(r, output_type="ndarray").reshape(-1, 2)
    n = points.shape[0]
    both = np.concatenate([pairs, pairs[:, ::-1]])
    adjacency = coo_matrix((np.ones(both.shape[0]), (both[:, 0], both[:, 1])), shape=(n, n))
    return points, tree, adjacency.tocsr(), pairs


def fibonacci_sphere(spacing: float) -> np.ndarray:
    """Directions (N, 3) about ``spacing`` rad apart (Fibonacci lattice, golden angle)."""
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
    """Angle (rad) between unit vectors row by row; ``signed``: q and -q one rotation."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    if signed:
        b = np.where(np.sum(a * b, axis=-1, keepdims=True) < 0.0, -b, b)
    return 2.0 * np.arctan2(np.linalg.norm(a - b, axis=-1), np.linalg.norm(a + b, axis=-1))


def _slerp_rows(a: np.ndarray, b: np.ndarray, f: np.ndarray, signed: bool) -> np.ndarray:
    """Points (N, S, dim) at fractions ``f`` (N, S) along the arcs from rows of ``a`` to ``b``."""
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
