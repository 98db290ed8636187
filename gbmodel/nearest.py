"""Exact nearest neighbours over a set of examples that only grows: the memory that keeps
everything (gbmodel.learners.example_memory with window 0).

Rebuilding one k-d tree over every example after each epoch costs O(N log N) per epoch, O(E^2)
over a trial; this structure keeps the examples in levels, each a k-d tree (scipy's cKDTree) over a
contiguous run of examples, merged like the digits of a binary counter (Bentley & Saxe 1980): a new
batch is a level of its own, and while the level before it is no larger, the two are rebuilt as
one. Every example is rebuilt into a tree O(log(N / batch)) times over its life, and a query asks
at most log2(N / batch) + 1 trees.

The answer is defined, so that it is the same however the examples are split into levels: the
example at the smallest distance (as cKDTree computes it), and among equally distant examples the
one stored first (the lowest index). Within a level the two nearest are asked for, and where they
tie, more, until the tie is resolved; across levels, which run in index order, a later level wins
only at a strictly smaller distance (tests/core/test_alternatives.py compares it with a single tree over
every example and with brute force, ties included).
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree


class Nearest:
    """Points (N, n) with values (N, m), appended batch by batch; `query` returns, for each
    query point, the index of its nearest stored point (ties: the lowest index)."""

    def __init__(self, n: int, m: int):
        self._x = np.empty((0, n))
        self._q = np.empty((0, m))
        self.count = 0
        self._levels: list[tuple[int, int, cKDTree]] = []  # (start, stop, tree), in index order

    def add(self, x: np.ndarray, q: np.ndarray) -> None:
        """Append examples (k, n), (k, m) as a new level; merge while the level before it is no
        larger (capacity doubles, so appending is amortised O(1) per example)."""
        k, stop = len(x), self.count + len(x)
        if stop > len(self._x):
            cap = max(stop, 2 * len(self._x))
            self._x = np.concatenate([self._x[:self.count], np.empty((cap - self.count,
                                                                      self._x.shape[1]))])
            self._q = np.concatenate([self._q[:self.count], np.empty((cap - self.count,
                                                                      self._q.shape[1]))])
        self._x[self.count:stop], self._q[self.count:stop] = x, q
        start = self.count
        self.count = stop
        while self._levels and self._levels[-1][1] - self._levels[-1][0] <= stop - start:
            start = self._levels.pop()[0]
        if k:
            self._levels.append((start, stop, cKDTree(self._x[start:stop])))

    @property
    def points(self) -> np.ndarray:
        return self._x[:self.count]

    @property
    def values(self) -> np.ndarray:
        return self._q[:self.count]

    def query(self, xs: np.ndarray) -> np.ndarray:
        """Indices (len(xs),) of the nearest stored point of each row of xs."""
        xs = np.asarray(xs, dtype=np.float64)
        best_d = np.full(len(xs), np.inf)
        best_i = np.zeros(len(xs), dtype=np.int64)
        for start, stop, tree in self._levels:
            d, i = _lowest_nearest(tree, xs, stop - start)
            better = d < best_d  # a later level (higher indices) wins only when strictly nearer
            best_d[better], best_i[better] = d[better], i[better] + start
        return best_i

    def copy_first(self, count: int) -> "Nearest":
        """A fresh structure over the first `count` examples (a state reused after it grew)."""
        out = Nearest(self._x.shape[1], self._q.shape[1])
        out.add(self._x[:count].copy(), self._q[:count].copy())
        return out


def _lowest_nearest(tree: cKDTree, xs: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray]:
    """(distance, index) of each query's nearest point in `tree`, ties to the lowest index."""
    if size == 1:
        d, _ = tree.query(xs, k=1)
        return d, np.zeros(len(xs), dtype=np.int64)
    k = 2
    d, i = tree.query(xs, k=k)
    dist, idx = d[:, 0].copy(), i[:, 0].copy()
    todo = np.nonzero(d[:, 1] == d[:, 0])[0]  # rows with a tie among the nearest
    while len(todo):
        k = min(2 * k, size)
        d, i = tree.query(xs[todo], k=k)
        tied = d == d[:, :1]
        idx[todo] = np.where(tied, i, np.iinfo(np.int64).max).min(axis=1)
        open_ = tied[:, -1] & (k < size)  # every one of the k tied: there may be more
        todo = todo[open_]
    return dist, idx
