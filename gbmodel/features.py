"""Phi^P(x) (eq. 7): every monomial of the n inputs up to degree P, constant first."""
from __future__ import annotations

import itertools

import numpy as np


def exponents(n: int, degree: int = 3) -> np.ndarray:
    """Exponent table (p, n), ordered by total degree, then lexicographically."""
    if n < 1 or degree < 0:
        raise ValueError(f"need n >= 1 and degree >= 0, got n={n}, degree={degree}")
    rows = [
        e
        for total in range(degree + 1)
        for e in sorted(itertools.product(range(total + 1), repeat=n), reverse=True)
        if sum(e) == total
    ]
    return np.array(rows, dtype=np.int64)


def features(x: np.ndarray, exps: np.ndarray) -> np.ndarray:
    x = np.asarray(x, dtype=np.float64)
    return _monomials(x[..., None, :], exps)


def feature_bounds(lo: np.ndarray, hi: np.ndarray, exps: np.ndarray) -> np.ndarray:
    amax = np.maximum(np.abs(lo), np.abs(hi))
    return _monomials(amax[None, :], exps)


def _monomials(x: np.ndarray, exps: np.ndarray) -> np.ndarray:
    """prod_j x_j ** e_kj by multiplications in a fixed order (libm's pow may differ)."""
    out = np.ones(np.broadcast_shapes(x.shape[:-1], exps.shape[:-1]))
    for j in range(exps.shape[1]):
        for power in range(1, int(exps[:, j].max(initial=0)) + 1):
            out = np.where(exps[:, j] >= power, out * x[..., j], out)
    return out


def monomial_tree(exps: np.ndarray, last: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """parent, var with Phi_k = Phi_parent[k] * x_var[k] for the kernels; var: the first
    coordinate of monomial k, or the last (each kernel keeps its own order)."""
    table = np.asarray(exps).tolist()
    rows = {tuple(e): k for k, e in enumerate(table)}
    parent, var = np.zeros(len(table), np.int64), np.zeros(len(table), np.int64)
    for k, e in enumerate(table[1:], start=1):
        nonzero = [i for i, v in enumerate(e) if v > 0]
        j = nonzero[-1] if last else nonzero[0]
        parent[k], var[k] = rows[tuple(v - (i == j) for i, v in enumerate(e))], j
    return parent, var
