"""Exact nearest neighbours over examples that only grow (example_memory's window 0): levels of
k-d trees over contiguous runs, merged like a binary counter (Bentley & Saxe 1980), so an example
is rebuilt O(log(N / batch)) times and a query asks at most log2(N / batch) + 1 trees. The answer
does not depend on the levels: the nearest, ties to the lowest index (within a level more
neighbours until a tie is resolved; a later level wins only strictly nearer).
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree


class Nearest:
    def __init__(self, n: int, m: int):
        self._x = np.empty((0, n))
        self._q = np.empty((0, m))
        self.count = 0
        self._levels: list[tuple[int, int, cKDTree]] = []  # (start, stop, tree), in index order

    def add(self, x: np.ndarray, q: np.ndarray) -> None:
        """Append examples as a new level, merged while the level before is no larger."""
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
        xs = np.asarray(xs, dtype=np.float64)
        best_d = np.full(len(xs), np.inf)
        best_i = np.zeros(len(xs), dtype=np.int64)
        for start, stop, tree in self._levels:
            d, i = _lowest_nearest(tree, xs, stop - start)
            better = d < best_d  # a later level (higher indices) wins only when strictly nearer
            best_d[better], best_i[better] = d[better], i[better] + start
        return best_i

    def copy_first(self, count: int) -> "Nearest":
        out = Nearest(self._x.shape[1], self._q.shape[1])
        out.add(self._x[:count].copy(), self._q[:count].copy())
        return out


def _lowest_nearest(tree: cKDTree, xs: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray]:
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
