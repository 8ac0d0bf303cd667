"""Numba kernels of the Rigid Map (Jenkins & Angel, Table I): training, winner search, answering.
Training has a numpy reference; no ``fastmath`` (NaN fails comparisons)."""

from __future__ import annotations

import math

import numpy as np

# the SOM's answering kernels, re-exported so the Rigid Map's code and tests name them here
from limbctl.envelope.interpolation import (  # noqa: F401
    COSINE,
    EUCLIDEAN,
    INTERPOLATIONS,
    METRICS,
    respond_rows,
)
from limbctl.geometry.jit import njit


@njit
def position_winners(positions: np.ndarray, patterns: np.ndarray) -> np.ndarray:
    """Index (N,) int64 of the node position (M, 4) nearest each pattern (N, 4), first on ties."""
    # argmax_i <x, p_i>: the argmin of |x - p|^2 and of acos(x.p)^2 alike
    n = patterns.shape[0]
    m = positions.shape[0]
    out = np.empty(n, dtype=np.int64)
    for j in range(n):
        best = -np.inf
        arg = 0
        for i in range(m):
            dot = 0.0
            for c in range(4):
                dot += patterns[j, c] * positions[i, c]
            if dot > best:
                best = dot
                arg = i
        out[j] = arg
    return out


@njit
def _min_neighbour_angle(positions: np.ndarray) -> float:
    """Smallest angle (rad) between two distinct node positions."""
    m = positions.shape[0]
    best = -1.0
    for i in range(m):
        for j in range(i + 1, m):
            dot = 0.0
            for c in range(4):
                dot += positions[i, c] * positions[j, c]
            if dot > best:
                best = dot
    return math.acos(min(1.0, max(-1.0, best)))


def _winner_slots(winners: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
    """The distinct winners (U,) in order of first appearance, and each pattern's slot (N,)."""
    values, first = np.unique(winners, return_index=True)
    distinct = np.ascontiguousarray(values[np.argsort(first)], dtype=np.int64)
    slot = np.full(m, -1, dtype=np.int64)
    slot[distinct] = np.arange(distinct.shape[0])
    return distinct, np.ascontiguousarray(slot[winners])


@njit
def _winner_angles(positions: np.ndarray, distinct: np.ndarray) -> np.ndarray:
    """``theta[i, s]`` (M, U): ``acos(p_c . p_i)`` (rad) between node ``i`` and distinct winner
    ``s``, exactly 0 for the winner itself."""
    m = positions.shape[0]
    theta = np.empty((m, distinct.shape[0]))
    for i in range(m):
        for s in range(distinct.shape[0]):
            c = distinct[s]
            dot = 0.0
            for k in range(4):
                dot += positions[c, k] * positions[i, k]
            theta[i, s] = 0.0 if i == c else math.acos(min(1.0, max(-1.0, dot)))
    return theta


def _slot_patterns(pattern_slot: np.ndarray, u: int) -> tuple[np.ndarray, np.ndarray]:
    """Patterns grouped by their winner's slot, in order: (start (U + 1,), patterns (N,))."""
    start = np.zeros(u + 1, dtype=np.int64)
    np.cumsum(np.bincount(pattern_slot, minlength=u), out=start[1:])
    return start, np.argsort(pattern_slot, kind="stable").astype(np.int64)


@njit
def _patterns_near(
    h: np.ndarray,
    slot_start: np.ndarray,
    slot_patterns: np.ndarray,
    buffer: np.ndarray,
    mark: np.ndarray,
) -> int:
    """The patterns whose winner has ``h > 0``, in order, into ``buffer``: their count, or -1 over
    a quarter of all. Marked in ``mark`` (N,) bool (all False, and left so): no sort to compile."""
    total = 0
    for s in range(h.shape[0]):
        if h[s] > 0.0:
            total += slot_start[s + 1] - slot_start[s]
    if 4 * total > slot_patterns.shape[0]:
        return -1
    lo = slot_patterns.shape[0]
    hi = -1
    for s in range(h.shape[0]):
        if h[s] > 0.0:
            for k in range(slot_start[s], slot_start[s + 1]):
                j = slot_patterns[k]
                mark[j] = True
                lo = min(lo, j)
                hi = max(hi, j)
    count = 0
    for j in range(lo, hi + 1):
        if mark[j]:
            mark[j] = False
            buffer[count] = j
            count += 1
    return count


def train_rigid_map(
    positions: np.ndarray,
    weights: np.ndarray,
    patterns: np.ndarray,
    lr0: float,
    lr_decay: float,
    sigma0: float,
    sigma_decay: float,
    phi: float,
    max_epochs: int,
    tol: float,
) -> int:
    """Train ``weights`` (M, 4) in place by the Rigid Map rule; returns the epochs run. Each epoch
    ``t``, for each pattern ``x`` in order, every node within ``h = exp(-theta_ci^2 / (2
    sigma(t)^2)) >= phi`` of the winner ``c`` by position moves ``w_i += lr(t) h (x - w_i)``, until
    ``max_epochs`` or no component moved over ``tol``. Winners never change, so they are found once;
    an epoch runs node by node (the same weights to the bit as pattern by pattern)."""
    winners = position_winners(positions, patterns)
    distinct, pattern_slot = _winner_slots(winners, positions.shape[0])
    grouped = (winners, distinct, pattern_slot, *_slot_patterns(pattern_slot, distinct.shape[0]))
    schedule = (lr0, lr_decay, sigma0, sigma_decay, phi, max_epochs, tol)
    return _train_epochs(positions, weights, patterns, *grouped, *schedule)


@njit
def _train_epochs(
    positions: np.ndarray,
    weights: np.ndarray,
    patterns: np.ndarray,
    winners: np.ndarray,
    distinct: np.ndarray,
    pattern_slot: np.ndarray,
    slot_start: np.ndarray,
    slot_patterns: np.ndarray,
    lr0: float,
    lr_decay: float,
    sigma0: float,
    sigma_decay: float,
    phi: float,
    max_epochs: int,
    tol: float,
) -> int:
    """:func:`train_rigid_map`'s epochs, given each pattern's winner (N,), the distinct winners
    (U,), each pattern's slot among them (N,) and the patterns grouped by slot (U + 1,), (N,)."""
    n = patterns.shape[0]
    m = positions.shape[0]
    min_angle = _min_neighbour_angle(positions) if m > 1 else np.pi
    theta = _winner_angles(positions, distinct)
    h = np.empty(distinct.shape[0])
    buffer = np.empty(n, dtype=np.int64)
    mark = np.zeros(n, dtype=np.bool_)
    epochs = 0
    for t in range(max_epochs):
        epochs = t + 1
        # lr(t) = lr0 exp(-k_lr t);  sigma(t) = sigma0 exp(-k_sigma t)
        lr = lr0 * math.exp(-lr_decay * t)
        sigma = sigma0 * math.exp(-sigma_decay * t)
        # h >= phi  <=>  theta <= sigma sqrt(2 ln(1/phi))
        reach = sigma * math.sqrt(2.0 * math.log(1.0 / phi)) if phi < 1.0 else 0.0
        # beyond reach + 1e-9 rad, h falls below phi < 1 by far more than exp's rounding
        far = reach + 1e-9 if phi < 1.0 else np.inf
        moved = 0.0
        if reach < min_angle:
            for j in range(n):
                c = winners[j]
                for k in range(4):
                    step = lr * (patterns[j, k] - weights[c, k])
                    weights[c, k] += step
                    moved = max(moved, abs(step))
        else:
            for i in range(m):
                near = False
                for s in range(distinct.shape[0]):
                    th = theta[i, s]
                    h[s] = 0.0
                    if th > far:
                        continue
                    # h = exp(-theta^2 / (2 sigma^2)); h >= phi > 0 marks a neighbour
                    value = math.exp(-(th * th) / (2.0 * sigma * sigma))
                    if value >= phi:
                        h[s] = value
                        near = True
                if not near:
                    continue
                order = _patterns_near(h, slot_start, slot_patterns, buffer, mark)
                w0, w1, w2, w3 = weights[i, 0], weights[i, 1], weights[i, 2], weights[i, 3]
                # the largest step per component, kept apart so the four updates do not wait
                m0 = m1 = m2 = m3 = 0.0
                for jj in range(n if order < 0 else order):
                    j = jj if order < 0 else buffer[jj]
                    value = h[pattern_slot[j]]
                    if value == 0.0:
                        continue
                    a = lr * value
                    step0 = a * (patterns[j, 0] - w0)
                    step1 = a * (patterns[j, 1] - w1)
                    step2 = a * (patterns[j, 2] - w2)
                    step3 = a * (patterns[j, 3] - w3)
                    w0 += step0
                    w1 += step1
                    w2 += step2
                    w3 += step3
                    m0 = max(m0, abs(step0))
                    m1 = max(m1, abs(step1))
                    m2 = max(m2, abs(step2))
                    m3 = max(m3, abs(step3))
                weights[i, 0], weights[i, 1], weights[i, 2], weights[i, 3] = w0, w1, w2, w3
                moved = max(moved, max(max(m0, m1), max(m2, m3)))
        if moved < tol:
            break
    return epochs


def train_rigid_map_reference(
    positions: np.ndarray,
    weights: np.ndarray,
    patterns: np.ndarray,
    lr0: float,
    lr_decay: float,
    sigma0: float,
    sigma_decay: float,
    phi: float,
    max_epochs: int,
    tol: float,
    metric: int = EUCLIDEAN,
) -> int:
    """Plain numpy :func:`train_rigid_map` (same rule, same result; winners by ``metric``)."""
    epochs = 0
    for t in range(max_epochs):
        epochs = t + 1
        lr = lr0 * np.exp(-lr_decay * t)
        sigma = sigma0 * np.exp(-sigma_decay * t)
        moved = 0.0
        for x in patterns:
            if metric == EUCLIDEAN:
                # E = |x - p|^2
                dist = np.sum((x - positions) ** 2, axis=1)
            else:
                # D = acos(x . p)^2
                dist = np.arccos(np.clip(positions @ x, -1.0, 1.0)) ** 2
            c = int(np.argmin(dist))
            theta = np.arccos(np.clip(positions @ positions[c], -1.0, 1.0))
            theta[c] = 0.0
            h = np.exp(-(theta * theta) / (2.0 * sigma * sigma))
            near = h >= phi
            step = (lr * h[near])[:, None] * (x - weights[near])
            weights[near] += step
            if step.size:
                moved = max(moved, float(np.max(np.abs(step))))
        if moved < tol:
            break
    return epochs


def position_topology(positions: np.ndarray, k: int) -> np.ndarray:
    """Each node's ``k`` nearest other nodes (M, k) int64 by ``p_i . p_j``, nearest first."""
    dots = positions @ positions.T
    np.fill_diagonal(dots, -np.inf)
    return _largest_per_row(dots, min(k, positions.shape[0] - 1))


@njit
def _largest_per_row(values: np.ndarray, k: int) -> np.ndarray:
    """Columns (M, k) of each row's ``k`` largest values, largest first, ties by column."""
    m, n = values.shape
    out = np.empty((m, k), dtype=np.int64)
    best = np.empty(k)
    for i in range(m):
        size = 0
        for j in range(n):
            x = values[i, j]
            if size == k and not x > best[k - 1]:
                continue
            # after every kept value >= x: equal values stay in column order
            at = min(size, k - 1)
            while at > 0 and best[at - 1] < x:
                at -= 1
            for s in range(min(size, k - 1), at, -1):
                best[s] = best[s - 1]
                out[i, s] = out[i, s - 1]
            best[at] = x
            out[i, at] = j
            size = min(size + 1, k)
    return out
