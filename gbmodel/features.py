"""Polynomial feature map Phi^P(x) of the inverse estimate (paper eq. 7).

Phi holds every monomial of the n inputs up to total degree P, constant first:
binomial(n + P, P) terms, i.e. 4, 10 and 20 for n = 1, 2, 3 at P = 3.
"""
from __future__ import annotations

import itertools

import numpy as np


def exponents(n: int, degree: int = 3) -> np.ndarray:
    """Exponent table (p, n) of all monomials of total degree <= degree.

    Row 0 is the constant; rows are ordered by total degree, then lexicographically.
    """
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
    """Phi(x) for x of shape (..., n): returns (..., p)."""
    x = np.asarray(x, dtype=np.float64)
    return _monomials(x[..., None, :], exps)


def feature_bounds(lo: np.ndarray, hi: np.ndarray, exps: np.ndarray) -> np.ndarray:
    """max |Phi_k(x)| over the box lo <= x <= hi, for each monomial k (exact)."""
    amax = np.maximum(np.abs(lo), np.abs(hi))
    return _monomials(amax[None, :], exps)


def _monomials(x: np.ndarray, exps: np.ndarray) -> np.ndarray:
    """prod_j x_j ** e_kj by repeated multiplication in a fixed order (no libm pow, whose last
    bit may differ between machines): x (..., 1, n) -> (..., p)."""
    out = np.ones(np.broadcast_shapes(x.shape[:-1], exps.shape[:-1]))
    for j in range(exps.shape[1]):
        for power in range(1, int(exps[:, j].max(initial=0)) + 1):
            out = np.where(exps[:, j] >= power, out * x[..., j], out)
    return out


def monomial_tree(exps: np.ndarray, last: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """For the compiled kernels: parent[k], var[k] with exps[k] = exps[parent[k]] + unit(var[k])
    (parent[0] = var[0] = 0), so that Phi_k = Phi_parent[k] * x_var[k], one multiplication per
    monomial (rows of exps are ordered by total degree, so a parent comes first). var[k] is the
    first coordinate in monomial k, or the last with last=True (the kernels' products then run in
    different orders, and each kernel keeps its own)."""
    table = np.asarray(exps).tolist()
    rows = {tuple(e): k for k, e in enumerate(table)}
    parent, var = np.zeros(len(table), np.int64), np.zeros(len(table), np.int64)
    for k, e in enumerate(table[1:], start=1):
        nonzero = [i for i, v in enumerate(e) if v > 0]
        j = nonzero[-1] if last else nonzero[0]
        parent[k], var[k] = rows[tuple(v - (i == j) for i, v in enumerate(e))], j
    return parent, var
