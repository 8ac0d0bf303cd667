"""Answering from trained node weights (SOM and Rigid Map): the winner nearest ``x``, optionally
combined with ``k`` runner-ups (Jenkins & Angel after Goeppert & Rosenstiel) by inverse distance
(``idw``), geometric steps from the running answer (``geometric``) or from the winner
(``geometric-winner``), or geometric over the winner's output-topology neighbours
(``topological``); the formulas sit in :func:`_combine`. Answers are unit, w >= 0."""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from limbctl.errors import ConfigError
from limbctl.geometry.jit import njit

#: Metric codes (kernels take ints).
EUCLIDEAN = 0
COSINE = 1
METRICS = {"euclidean": EUCLIDEAN, "cosine": COSINE}
#: Interpolation codes.
NONE = 0
IDW = 1
GEOMETRIC = 2
GEOMETRIC_WINNER = 3
TOPOLOGICAL = 4
INTERPOLATIONS = {
    "none": NONE,
    "idw": IDW,
    "geometric": GEOMETRIC,
    "geometric-winner": GEOMETRIC_WINNER,
    "topological": TOPOLOGICAL,
}


def interpolation_code(name: str) -> int:
    """The kernel code of an interpolation name; unknown names are rejected listing choices."""
    try:
        return INTERPOLATIONS[name]
    except (KeyError, TypeError):
        raise ConfigError(
            f"unknown interpolation {name!r}; choose one of: {', '.join(INTERPOLATIONS)}"
        ) from None


def check_k(k: object) -> int:
    """Validate the number of runner-ups: an integer >= 1."""
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 1:
        raise ConfigError(f"k (runner-ups to interpolate) must be an integer >= 1, got {k!r}")
    return int(k)


@njit
def _distance(x: np.ndarray, w: np.ndarray, metric: int) -> float:
    """``|x - w|^2`` (EUCLIDEAN) or ``acos(x . w / |w|)^2`` (COSINE)."""
    if metric == EUCLIDEAN:
        total = 0.0
        for c in range(4):
            diff = x[c] - w[c]
            total += diff * diff
        return total
    dot = 0.0
    sq = 0.0
    for c in range(4):
        dot += x[c] * w[c]
        sq += w[c] * w[c]
    cosine = dot / math.sqrt(sq) if sq > 0.0 else -1.0
    angle = math.acos(min(1.0, max(-1.0, cosine)))
    return angle * angle


@njit
def _nearest(weights, x, count, metric, idx, dist) -> None:
    """Fill ``idx``, ``dist`` (count,) with the nearest weights, nearest first, ties by index."""
    for r in range(count):
        idx[r] = -1
        dist[r] = np.inf
    for i in range(weights.shape[0]):
        d = _distance(x, weights[i], metric)
        if not d < dist[count - 1]:
            continue
        r = count - 1
        while r > 0 and d < dist[r - 1]:
            idx[r] = idx[r - 1]
            dist[r] = dist[r - 1]
            r -= 1
        idx[r] = i
        dist[r] = d


@njit
def _combine(weights, x, idx, dist, count, mode, out) -> None:
    """Combine the winner ``idx[0]`` with runner-ups ``idx[1:count]``; unit answer in ``out``."""
    win = idx[0]
    y = np.empty(4)
    for c in range(4):
        y[c] = weights[win, c]
    if mode == IDW and count > 1 and dist[0] > 0.0:
        # y = sum_i w_i / d_i / sum_i 1 / d_i,   d_i = sqrt(E_i) or sqrt(D_i)
        total = 0.0
        for c in range(4):
            y[c] = 0.0
        for r in range(count):
            inv = 1.0 / math.sqrt(dist[r])
            total += inv
            for c in range(4):
                y[c] += inv * weights[idx[r], c]
        for c in range(4):
            y[c] /= total
    elif mode == GEOMETRIC or mode == GEOMETRIC_WINNER or mode == TOPOLOGICAL:
        res = np.empty(4)
        step = np.empty(4)
        for c in range(4):
            res[c] = x[c] - y[c]
        # from y = w_c, r = x - w_c, for each runner-up k, nearest first:
        for r in range(1, count):
            other = idx[r]
            dd = 0.0
            rd = 0.0
            for c in range(4):
                # d = w_k - y   (geometric-winner: d = w_k - w_c)
                base = weights[win, c] if mode == GEOMETRIC_WINNER else y[c]
                step[c] = weights[other, c] - base
                dd += step[c] * step[c]
                rd += res[c] * step[c]
            if not dd > 0.0:
                continue
            # a = clip(<r, d> / |d|^2, 0, 1);  y += a d;  r -= a d
            a = min(1.0, max(0.0, rd / dd))
            for c in range(4):
                y[c] += a * step[c]
                res[c] -= a * step[c]
    norm = math.sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2] + y[3] * y[3])
    sign = -1.0 if y[0] < 0.0 else 1.0
    for c in range(4):
        out[c] = sign * y[c] / norm


@njit(parallel=True)
def respond_batch(
    weights: np.ndarray, q: np.ndarray, k: int, metric: int, mode: int, topology: np.ndarray
) -> np.ndarray:
    """The network's answer (N, 4), unit, w >= 0, for each row of ``q`` (N, 4).

    Parameters
    ----------
    weights : ndarray, shape (M, 4)
        Node weights.
    k, metric, mode : int
        Runner-ups (ignored for NONE); codes of :data:`METRICS` and :data:`INTERPOLATIONS`.
    topology : ndarray, shape (M, K) int64
        For TOPOLOGICAL, each node's neighbours, nearest first; else any (M, 0) array.
    """
    n = q.shape[0]
    out = np.empty((n, 4))
    count = 1 if mode == NONE else min(k + 1, weights.shape[0])
    for j in nb.prange(n):
        _respond_one(weights, q[j], count, metric, mode, topology, out[j])
    return out


@njit
def _respond_one(weights, x, count, metric, mode, topology, out) -> None:
    """One row of :func:`respond_batch`: the answer for ``x`` (4,) into ``out`` (4,)."""
    idx = np.empty(count, dtype=np.int64)
    dist = np.empty(count)
    if mode == TOPOLOGICAL:
        # the winner alone: min(count, 1) is 1 typed as count (a literal would compile again)
        _nearest(weights, x, min(count, 1), metric, idx, dist)
        used = min(count, topology.shape[1] + 1)
        for r in range(1, used):
            idx[r] = topology[idx[0], r - 1]
        _combine(weights, x, idx, dist, used, mode, out)
    else:
        _nearest(weights, x, count, metric, idx, dist)
        _combine(weights, x, idx, dist, count, mode, out)


@njit
def respond_serial(
    weights: np.ndarray, q: np.ndarray, k: int, metric: int, mode: int, topology: np.ndarray
) -> np.ndarray:
    """:func:`respond_batch` on one thread: the same answers, row for row."""
    n = q.shape[0]
    out = np.empty((n, 4))
    count = 1 if mode == NONE else min(k + 1, weights.shape[0])
    idx = np.empty(count, dtype=np.int64)
    dist = np.empty(count)
    # _respond_one's body inlined: one level of calls less to compile (decisions/first_run.md)
    for j in range(n):
        if mode == TOPOLOGICAL:
            _nearest(weights, q[j], min(count, 1), metric, idx, dist)
            used = min(count, topology.shape[1] + 1)
            for r in range(1, used):
                idx[r] = topology[idx[0], r - 1]
            _combine(weights, q[j], idx, dist, used, mode, out[j])
        else:
            _nearest(weights, q[j], count, metric, idx, dist)
            _combine(weights, q[j], idx, dist, count, mode, out[j])
    return out


#: Rows up to which :func:`respond_rows` stays on one thread (a parallel kernel compiles slowly).
PARALLEL_ROWS = 100_000


def respond_rows(
    weights: np.ndarray, q: np.ndarray, k: int, metric: int, mode: int, topology: np.ndarray
) -> np.ndarray:
    """:func:`respond_batch` or, up to :data:`PARALLEL_ROWS` rows, :func:`respond_serial`."""
    kernel = respond_batch if q.shape[0] > PARALLEL_ROWS else respond_serial
    return kernel(weights, q, k, metric, mode, topology)


@njit(parallel=True)
def nearest_distance(weights: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Euclidean distance ``min_i |q_j - w_i|`` (N,) from each row of ``q`` (N, 4) to weights."""
    n = q.shape[0]
    out = np.empty(n)
    for j in nb.prange(n):
        best = np.inf
        for i in range(weights.shape[0]):
            d = _distance(q[j], weights[i], EUCLIDEAN)
            if d < best:
                best = d
        out[j] = math.sqrt(best)
    return out


def neighbours_by_position(positions: np.ndarray, k: int) -> np.ndarray:
    """Each node's ``k`` nearest other nodes (M, k) int64 by position (M, 4) or grid (M, 2),
    nearest first, ties by index."""
    positions = np.asarray(positions, dtype=np.float64)
    sq = np.sum(positions**2, axis=1)
    # |a - b|^2 = |a|^2 + |b|^2 - 2 a.b   (exact for integer grid coordinates)
    d2 = sq[:, None] + sq[None, :] - 2.0 * positions @ positions.T
    np.fill_diagonal(d2, np.inf)
    k = min(int(k), len(positions) - 1)
    order = np.argsort(d2, axis=1, kind="stable")[:, :k]
    return np.ascontiguousarray(order, dtype=np.int64)
