"""The lstsq rule in the kernel (solver=lstsq), as solve.py states it: Gram sums into a ring's
slot, M from their sum by solve.system and a compiled solve.cholesky_solve."""
from __future__ import annotations

import numpy as np
from numba import njit

from ...simd import LANES, aligned, vload, vload1, vmul, vstore, vsum
from .core import _BLOCK, _accumulate, _features
from .solve import cholesky_solve


@njit(cache=True)
def _gram_sums(X, Q, w, Npad, parent, var, Phi, Z, GG, out):
    """out (p + m, p) = solve.grams of the columns, in the gradient's register tiles."""
    p, m = Phi.shape[0], Q.shape[0]
    GG[:] = 0
    for c0 in range(0, Npad, _BLOCK):
        C = min(_BLOCK, Npad - c0)
        _features(X, c0, C, parent, var, Phi)
        for c in range(0, C, LANES):
            wc = vload1(w, c0 + c)
            for k in range(p):
                vstore(Z, k, c, vmul(vload(Phi, k, c), wc))
            for i in range(m):
                vstore(Z, p + i, c, vmul(vload(Q, i, c0 + c), wc))
        _accumulate(Z, Phi, C, GG, p)
    for i in range(p + m):
        for k in range(p):
            out[i, k] = vsum(vload(GG, i, k * LANES))
    for i in range(p):  # G is symmetric: its upper triangle from the lower
        for k in range(i + 1, p):
            out[i, k] = out[k, i]


_cholesky_solve = njit(cache=True)(cholesky_solve)


@njit(cache=True)
def _target_gram(targets, s, parent, var, phi, P, M, clip, PC):
    """P = solve.target_gram and PC = solve.limit_gram at size s, float64 in a fixed order."""
    NT, n = targets.shape
    p = P.shape[0]
    m = M.shape[0]
    P[:] = 0
    PC[:] = 0
    for t in range(NT):
        phi[0] = 1.0
        for k in range(1, p):
            phi[k] = phi[parent[k]] * (s * float(targets[t, var[k]]))
        for i in range(p):
            for j in range(i + 1):
                P[i, j] += phi[i] * phi[j]
        for r in range(m):
            c = 0.0
            for k in range(p):
                c += M[r, k] * phi[k]
            if clip:
                c = min(1.0, max(-1.0, c))
            for i in range(p):
                PC[i, r] += phi[i] * c
    for i in range(p):
        for j in range(i + 1):
            P[i, j] /= NT
            P[j, i] = P[i, j]
        for r in range(m):
            PC[i, r] /= NT


@njit(cache=True)
def solve(M, M0, ring, slot, ridge, anchor, limit, clip, X, Q, w, Npad, parent, var, Phi,
          targets, s, solver_work):
    """solve.solve in place: this epoch's Gram sums into ring[slot], M from the slots' sum."""
    Z, GG, total, A, B, L, out, P, phi, PC = solver_work
    m, p = M.shape
    _gram_sums(X, Q, w, Npad, parent, var, Phi, Z, GG, ring[slot])
    total[:] = ring[0]
    for k in range(1, ring.shape[0]):
        for i in range(p + m):
            for j in range(p):
                total[i, j] += ring[k, i, j]
    _target_gram(targets, s, parent, var, phi, P, M, clip, PC)
    la = anchor * total[0, 0]  # times the window's sum of weights
    lc = limit * total[0, 0]
    for i in range(p):
        for j in range(p):
            A[i, j] = total[i, j] + (la + lc) * P[i, j]
        d = ridge * total[i, i] if total[i, i] > 0 else 1.0
        A[i, i] += d
        for r in range(m):
            pm = 0.0
            for k in range(p):
                pm += P[i, k] * M0[r, k]
            B[i, r] = total[p + r, i] + d * M[r, i] + la * pm + lc * PC[i, r]
    _cholesky_solve(A, B, L, out)
    for r in range(m):
        for i in range(p):
            M[r, i] = out[i, r]


@njit(cache=True)
def solver_work(m, n, p, V, T, solving):
    Npad = -(-(V * (T + 1)) // LANES) * LANES
    cols = min(Npad, _BLOCK) if solving else LANES
    return (aligned(p + m, cols), aligned(p + m, p * LANES), np.empty((p + m, p)),
            np.empty((p, p)), np.empty((p, m)), np.zeros((p, p)), np.empty((p, m)),
            np.empty((p, p)), np.empty(p), np.empty((p, m)))
