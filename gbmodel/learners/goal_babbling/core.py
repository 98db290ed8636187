"""The shared core of Goal Babbling's kernels: sample columns as LANES-wide float32 vectors.

What every update rule and the rollout use (fast.py says how the kernels fit together and why
they give the same bits on every x86-64 CPU):
- `_features`: Phi of a block of columns, monomial by monomial, each a parent monomial times
  one coordinate;
- `_predict`: M Phi of a block of columns (or the weighted residuals w (M Phi - q)), rows of M
  in register tiles of _TILE;
- `_accumulate`: lanes of R Phi^T over a block of columns in register tiles of vector
  accumulators, 5 x 5 (10 loads per 25 fused multiply-adds) where the target has 32 vector
  registers of 16 lanes (AVX-512), 2 x 2 where it has 16 of 8 (AVX2): the gradient, and the
  Gram sums of solver=lstsq; float32 lanes whose sum is float64;
- `_lane_sum`, `_zeros64`: a sum over columns in lanes; float64 rows aligned to cache lines.

Each is a function of arrays (the samples, M, its work arrays) and nothing else, so that a kernel
over many trials at once can call them per trial.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from numba import njit

from ...simd import (
    LANES, W8, _1, fresh_cache, vadd, vfma, vload, vload1, vmul, vsplat, vstore, vsub, vsum,
    wide_vectors,
)

# every kernel file imports this one first: numba's caches of this folder are removed when any
# of its files (or simd.py) changed, before a kernel is loaded from them
fresh_cache(Path(__file__).parent)

_BLOCK = 512  # columns per block of features, residuals and gradient (multiple of LANES)
_TILE = 5  # rows of a register tile of M Phi and of the gradient (m = 5, 10; p = 10, 20)

@njit(cache=True)
def _features(X, c0, C, parent, var, Phi):
    """Phi[:, :C] of X[:, c0:c0 + C]: monomial k = monomial parent[k] * x[var[k]], the constant
    first."""
    one = vsplat(_1)
    for c in range(0, C, LANES):
        vstore(Phi, 0, c, one)
    for k in range(1, Phi.shape[0]):
        src, coord = parent[k], var[k]
        for c in range(0, C, LANES):
            vstore(Phi, k, c, vmul(vload(Phi, src, c), vload(X, coord, c0 + c)))


@njit(cache=True)
def _predict(M32, Phi, C, out, Q, w, c0):
    """out[:, :C] = M Phi[:, :C] (float32, summed over k in order); with weights w given
    (len(w) > 0), the weighted residuals w (M Phi - Q) of the columns c0 ... c0 + C - 1 of Q
    and w instead. Rows in tiles of _TILE, a tile's
    LANES columns in registers while k runs."""
    m, p = M32.shape
    residual = len(w) > 0
    mt = m - m % _TILE
    for i in range(0, mt, _TILE):
        for c in range(0, C, LANES):
            f = vload(Phi, 0, c)
            a0, a1 = vmul(vsplat(M32[i, 0]), f), vmul(vsplat(M32[i + 1, 0]), f)
            a2, a3 = vmul(vsplat(M32[i + 2, 0]), f), vmul(vsplat(M32[i + 3, 0]), f)
            a4 = vmul(vsplat(M32[i + 4, 0]), f)
            for k in range(1, p):
                f = vload(Phi, k, c)
                a0 = vfma(vsplat(M32[i, k]), f, a0)
                a1 = vfma(vsplat(M32[i + 1, k]), f, a1)
                a2 = vfma(vsplat(M32[i + 2, k]), f, a2)
                a3 = vfma(vsplat(M32[i + 3, k]), f, a3)
                a4 = vfma(vsplat(M32[i + 4, k]), f, a4)
            if residual:
                wc = vload1(w, c0 + c)
                a0 = vmul(vsub(a0, vload(Q, i, c0 + c)), wc)
                a1 = vmul(vsub(a1, vload(Q, i + 1, c0 + c)), wc)
                a2 = vmul(vsub(a2, vload(Q, i + 2, c0 + c)), wc)
                a3 = vmul(vsub(a3, vload(Q, i + 3, c0 + c)), wc)
                a4 = vmul(vsub(a4, vload(Q, i + 4, c0 + c)), wc)
            vstore(out, i, c, a0)
            vstore(out, i + 1, c, a1)
            vstore(out, i + 2, c, a2)
            vstore(out, i + 3, c, a3)
            vstore(out, i + 4, c, a4)
    for i in range(mt, m):
        for c in range(0, C, LANES):
            a0 = vmul(vsplat(M32[i, 0]), vload(Phi, 0, c))
            for k in range(1, p):
                a0 = vfma(vsplat(M32[i, k]), vload(Phi, k, c), a0)
            if residual:
                a0 = vmul(vsub(a0, vload(Q, i, c0 + c)), vload1(w, c0 + c))
            vstore(out, i, c, a0)


# ---- R Phi^T: register tiles of vector accumulators --------------------------------------------
# A tile's accumulators start at 0, add the block's columns in order, then are added to GL: lane
# l of G[i, k] adds the columns c = l (mod LANES) one by one in order whatever the tile's shape,
# so the shape follows the target's registers without moving a bit: 5 x 5 tiles (25
# accumulators, 10 loads per 25 fused multiply-adds) where an F32x16 is one register of 32
# (AVX-512), 2 x 2 tiles where it is two of 16 (AVX2: 4 accumulators in 8 registers, 4 loads per
# 4; a 5 x 5 tile would spill its accumulators to the stack at every step, twice as slow).
@njit(inline="always")
def _put(GL, i, o, a):
    """GL[i, lanes o ... o + LANES - 1] += a."""
    vstore(GL, i, o, vadd(vload(GL, i, o), a))


@njit(inline="always")
def _flush(GL, i, k, b0, b1, b2, b3, b4):
    """GL[i, lanes of k ... k + 4] += b0 ... b4."""
    o = k * LANES
    _put(GL, i, o, b0)
    _put(GL, i, o + LANES, b1)
    _put(GL, i, o + 2 * LANES, b2)
    _put(GL, i, o + 3 * LANES, b3)
    _put(GL, i, o + 4 * LANES, b4)


@njit(cache=True)
def _tile5x5(Rw, Phi, C, i, k, GL):
    """Lanes of G[i:i+5, k:k+5] += Rw[i:i+5, :C] Phi[k:k+5, :C]^T: 25 vector accumulators, 10
    loads per 25 fused multiply-adds."""
    a00 = a01 = a02 = a03 = a04 = vsplat(0)
    a10 = a11 = a12 = a13 = a14 = vsplat(0)
    a20 = a21 = a22 = a23 = a24 = vsplat(0)
    a30 = a31 = a32 = a33 = a34 = vsplat(0)
    a40 = a41 = a42 = a43 = a44 = vsplat(0)
    for c in range(0, C, LANES):
        x0, x1, x2 = vload(Rw, i, c), vload(Rw, i + 1, c), vload(Rw, i + 2, c)
        x3, x4 = vload(Rw, i + 3, c), vload(Rw, i + 4, c)
        y = vload(Phi, k, c)
        a00, a10, a20 = vfma(x0, y, a00), vfma(x1, y, a10), vfma(x2, y, a20)
        a30, a40 = vfma(x3, y, a30), vfma(x4, y, a40)
        y = vload(Phi, k + 1, c)
        a01, a11, a21 = vfma(x0, y, a01), vfma(x1, y, a11), vfma(x2, y, a21)
        a31, a41 = vfma(x3, y, a31), vfma(x4, y, a41)
        y = vload(Phi, k + 2, c)
        a02, a12, a22 = vfma(x0, y, a02), vfma(x1, y, a12), vfma(x2, y, a22)
        a32, a42 = vfma(x3, y, a32), vfma(x4, y, a42)
        y = vload(Phi, k + 3, c)
        a03, a13, a23 = vfma(x0, y, a03), vfma(x1, y, a13), vfma(x2, y, a23)
        a33, a43 = vfma(x3, y, a33), vfma(x4, y, a43)
        y = vload(Phi, k + 4, c)
        a04, a14, a24 = vfma(x0, y, a04), vfma(x1, y, a14), vfma(x2, y, a24)
        a34, a44 = vfma(x3, y, a34), vfma(x4, y, a44)
    _flush(GL, i, k, a00, a01, a02, a03, a04)
    _flush(GL, i + 1, k, a10, a11, a12, a13, a14)
    _flush(GL, i + 2, k, a20, a21, a22, a23, a24)
    _flush(GL, i + 3, k, a30, a31, a32, a33, a34)
    _flush(GL, i + 4, k, a40, a41, a42, a43, a44)


@njit(cache=True)
def _tile1x5(Rw, Phi, C, i, k, GL):
    """Lanes of G[i, k:k+5] += Rw[i, :C] Phi[k:k+5, :C]^T."""
    a0 = a1 = a2 = a3 = a4 = vsplat(0)
    for c in range(0, C, LANES):
        x = vload(Rw, i, c)
        a0, a1 = vfma(x, vload(Phi, k, c), a0), vfma(x, vload(Phi, k + 1, c), a1)
        a2, a3 = vfma(x, vload(Phi, k + 2, c), a2), vfma(x, vload(Phi, k + 3, c), a3)
        a4 = vfma(x, vload(Phi, k + 4, c), a4)
    _flush(GL, i, k, a0, a1, a2, a3, a4)


@njit(cache=True)
def _tile2x2(Rw, Phi, C, i, k, GL):
    """Lanes of G[i:i+2, k:k+2] += Rw[i:i+2, :C] Phi[k:k+2, :C]^T: 4 vector accumulators, 4
    loads per 4 fused multiply-adds."""
    a00 = a01 = a10 = a11 = vsplat(0)
    for c in range(0, C, LANES):
        x0, x1 = vload(Rw, i, c), vload(Rw, i + 1, c)
        y = vload(Phi, k, c)
        a00, a10 = vfma(x0, y, a00), vfma(x1, y, a10)
        y = vload(Phi, k + 1, c)
        a01, a11 = vfma(x0, y, a01), vfma(x1, y, a11)
    o = k * LANES
    _put(GL, i, o, a00)
    _put(GL, i, o + LANES, a01)
    _put(GL, i + 1, o, a10)
    _put(GL, i + 1, o + LANES, a11)


@njit(cache=True)
def _tile1x2(Rw, Phi, C, i, k, GL):
    """Lanes of G[i, k:k+2] += Rw[i, :C] Phi[k:k+2, :C]^T."""
    a0 = a1 = vsplat(0)
    for c in range(0, C, LANES):
        x = vload(Rw, i, c)
        a0, a1 = vfma(x, vload(Phi, k, c), a0), vfma(x, vload(Phi, k + 1, c), a1)
    o = k * LANES
    _put(GL, i, o, a0)
    _put(GL, i, o + LANES, a1)


@njit(cache=True)
def _tile1x1(Rw, Phi, C, i, k, GL):
    """Lanes of G[i, k] += Rw[i, :C] . Phi[k, :C]."""
    a = vsplat(0)
    for c in range(0, C, LANES):
        a = vfma(vload(Rw, i, c), vload(Phi, k, c), a)
    _put(GL, i, k * LANES, a)


@njit(cache=True)
def _accumulate(Rw, Phi, C, GL, symmetric=0):
    """Lanes of the gradient, GL (m, p * LANES) += Rw[:, :C] Phi[:, :C]^T: lane l of G[i, k]
    sums the columns c = l (mod LANES) in order, whatever the CPU. With `symmetric` rows (the
    first rows of Rw are Phi's, weighted: a Gram matrix), the tiles of those rows wholly above
    the diagonal are left out (the caller mirrors them). Tiles of 5 x 5 or 2 x 2 by the
    target's registers (simd.wide_vectors: a compile-time constant)."""
    m, p = Rw.shape[0], Phi.shape[0]
    t = _TILE if wide_vectors() else 2
    mt, pt = m - m % t, p - p % t
    for i in range(0, mt, t):
        for k in range(0, pt, t):
            if i + t <= symmetric and k >= i + t:
                continue
            if t == _TILE:
                _tile5x5(Rw, Phi, C, i, k, GL)
            else:
                _tile2x2(Rw, Phi, C, i, k, GL)
    for i in range(mt, m):
        for k in range(0, pt, t):
            if t == _TILE:
                _tile1x5(Rw, Phi, C, i, k, GL)
            else:
                _tile1x2(Rw, Phi, C, i, k, GL)
    for i in range(m):
        for k in range(pt, p):
            _tile1x1(Rw, Phi, C, i, k, GL)


@njit(cache=True)
def _lane_sum(w, C):
    """sum w[:C] (C a multiple of LANES): LANES partial sums, then the lanes (vsum)."""
    acc = vsplat(0)
    for c in range(0, C, LANES):
        acc = vadd(acc, vload1(w, c))
    return vsum(acc)


@njit(cache=True)
def _zeros64(shape):
    """np.zeros(shape) (float64) starting on a 64-byte boundary: a row of whole F64x8 vectors
    then lies in whole cache lines (a vector across two lines is a split load or store, and a
    split store is not forwarded to the next load)."""
    n = shape[0] * shape[1]
    buf = np.zeros(n + W8)
    off = (-(buf.ctypes.data // 8)) % W8
    return buf[off:off + n].reshape(shape)
