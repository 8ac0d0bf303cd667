"""Disjoint sets over ``0 .. n - 1`` (union-find with path halving and union by size)."""

from __future__ import annotations

import numpy as np


class UnionFind:
    """Pieces of ``n`` items joined pair by pair; each item starts as its own piece."""

    def __init__(self, n: int) -> None:
        self.parent = np.arange(n)
        self.size = np.ones(n, dtype=np.int64)

    def root(self, i: int) -> int:
        """The representative of ``i``'s piece."""
        parent = self.parent
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return int(i)

    def union(self, a: int, b: int) -> int:
        """Join the pieces of ``a`` and ``b``; returns the joined piece's representative."""
        ra, rb = self.root(a), self.root(b)
        if ra == rb:
            return ra
        if self.size[ra] < self.size[rb]:
            ra, rb = rb, ra
        self.parent[rb] = ra
        self.size[ra] += self.size[rb]
        return ra

    def labels(self) -> np.ndarray:
        """(n,) int: the representative of every item's piece."""
        return np.array([self.root(i) for i in range(self.parent.shape[0])])
