"""The gradient rule in the kernel (solver=gradient, updates=batch | steps; reference.update).

M -= eta sum_t w (M Phi - q) Phi^T over an epoch's samples, in blocks of _BLOCK columns that
stay in cache: their features, the weighted residuals (rows in register tiles of 5), and the
gradient's lanes (core._accumulate: float32 lanes, summed in float64).
"""
from __future__ import annotations

from numba import njit

from ...simd import LANES, vload, vsum
from .core import _BLOCK, _accumulate, _features, _predict


@njit(cache=True)
def _gradient_step(M, M32, X, Q, w, Npad, parent, var, Phi, Rw, GL, eta):
    """M -= eta sum_t w (M Phi - q) Phi^T over the columns of X, Q, w (float32 lanes, float64
    sum); M32 holds M in float32 on entry."""
    m, p = M.shape
    GL[:] = 0
    for c0 in range(0, Npad, _BLOCK):  # blocks of columns: their Phi and Rw stay in cache
        C = min(_BLOCK, Npad - c0)
        _features(X, c0, C, parent, var, Phi)
        _predict(M32, Phi, C, Rw, Q, w, c0)
        _accumulate(Rw, Phi, C, GL)
    for i in range(m):
        for k in range(p):
            M[i, k] -= eta * vsum(vload(GL, i, k * LANES))



@njit(cache=True)
def gradient_steps(M, M32, X, Q, w, Npad, parent, var, Phi, Rw, GL, eta, steps):
    """`steps` gradient steps on the same samples (updates=batch: 1; updates=steps: k), M32
    holding M in float32 on entry (the rollout leaves it there)."""
    m, p = M.shape
    for u in range(steps):
        if u > 0:
            for i in range(m):
                for k in range(p):
                    M32[i, k] = M[i, k]
        _gradient_step(M, M32, X, Q, w, Npad, parent, var, Phi, Rw, GL, eta)
