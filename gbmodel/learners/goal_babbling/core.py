"""The shared core of Goal Babbling's kernels on LANES-wide float32 sample columns (fast.py says
why they give the same bits on every x86-64 CPU): features, M Phi (or weighted residuals), the
register tiles of R Phi^T (the gradient; lstsq.py's Gram sums) and the gradient rule. Each is a
function of arrays alone, so that a kernel over many trials can call them per trial.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from numba import njit

from ...simd import (
    LANES, _1, fresh_cache, vadd, vfma, vload, vload1, vmul, vsplat, vstore, vsub, vsum,
    wide_vectors,
)

# every kernel file imports this one first: the folder's stale numba caches go before a load
fresh_cache(Path(__file__).parent)

_BLOCK = 512  # columns per block of features, residuals and gradient (multiple of LANES)
_TILE = 5  # rows of a register tile of M Phi and of the gradient (m = 5, 10; p = 10, 20)

@njit(cache=True)
def _features(X, c0, C, parent, var, Phi):
    """Phi[:, :C] of X[:, c0:c0 + C]: monomial k = monomial parent[k] * x[var[k]]."""
    one = vsplat(_1)
    for c in range(0, C, LANES):
        vstore(Phi, 0, c, one)
    for k in range(1, Phi.shape[0]):
        src, coord = parent[k], var[k]
        for c in range(0, C, LANES):
            vstore(Phi, k, c, vmul(vload(Phi, src, c), vload(X, coord, c0 + c)))


@njit(inline="always")
def _first5(M32, i, f):
    return (vmul(vsplat(M32[i, 0]), f), vmul(vsplat(M32[i + 1, 0]), f),
            vmul(vsplat(M32[i + 2, 0]), f), vmul(vsplat(M32[i + 3, 0]), f),
            vmul(vsplat(M32[i + 4, 0]), f))


@njit(inline="always")
def _next5(M32, i, k, f, a):
    return (vfma(vsplat(M32[i, k]), f, a[0]), vfma(vsplat(M32[i + 1, k]), f, a[1]),
            vfma(vsplat(M32[i + 2, k]), f, a[2]), vfma(vsplat(M32[i + 3, k]), f, a[3]),
            vfma(vsplat(M32[i + 4, k]), f, a[4]))


@njit(inline="always")
def _put5(out, Q, w, residual, i, c, c0, a):
    for r in range(_TILE):
        x = a[r]
        if residual:
            x = vmul(vsub(x, vload(Q, i + r, c0 + c)), vload1(w, c0 + c))
        vstore(out, i + r, c, x)


_WIDE = 4  # column vectors of a wide tile of M Phi: 5 x 4 accumulators, each splat used 4 times


@njit(cache=True)
def _predict(M32, Phi, C, out, Q, w, c0):
    """out[:, :C] = M Phi[:, :C] (summed over k in order), or with len(w) > 0 the weighted
    residuals w (M Phi - Q) of columns c0 ...; rows in register tiles of _TILE, with 32 vector
    registers (AVX-512) _WIDE column vectors at a time (a splat of M loaded once for them)."""
    m, p = M32.shape
    residual = len(w) > 0
    mt = m - m % _TILE
    wide = _WIDE * LANES if wide_vectors() else C + 1
    for i in range(0, mt, _TILE):
        for c in range(0, C - C % wide, wide):
            a = _first5(M32, i, vload(Phi, 0, c))
            b = _first5(M32, i, vload(Phi, 0, c + LANES))
            d = _first5(M32, i, vload(Phi, 0, c + 2 * LANES))
            e = _first5(M32, i, vload(Phi, 0, c + 3 * LANES))
            for k in range(1, p):
                a = _next5(M32, i, k, vload(Phi, k, c), a)
                b = _next5(M32, i, k, vload(Phi, k, c + LANES), b)
                d = _next5(M32, i, k, vload(Phi, k, c + 2 * LANES), d)
                e = _next5(M32, i, k, vload(Phi, k, c + 3 * LANES), e)
            _put5(out, Q, w, residual, i, c, c0, a)
            _put5(out, Q, w, residual, i, c + LANES, c0, b)
            _put5(out, Q, w, residual, i, c + 2 * LANES, c0, d)
            _put5(out, Q, w, residual, i, c + 3 * LANES, c0, e)
        for c in range(C - C % wide, C, LANES):
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
# Lane l of G[i, k] adds the columns c = l (mod LANES) in order whatever the tile's shape, so the
# shape follows the registers without moving a bit: 5 x 5 where an F32x16 is one of 32 registers
# (AVX-512), 2 x 2 where it is two of 16 (AVX2: a 5 x 5 tile would spill, twice as slow).
@njit(inline="always")
def _put(GL, i, o, a):
    vstore(GL, i, o, vadd(vload(GL, i, o), a))


@njit(inline="always")
def _flush(GL, i, k, b0, b1, b2, b3, b4):
    o = k * LANES
    _put(GL, i, o, b0)
    _put(GL, i, o + LANES, b1)
    _put(GL, i, o + 2 * LANES, b2)
    _put(GL, i, o + 3 * LANES, b3)
    _put(GL, i, o + 4 * LANES, b4)


@njit(cache=True)
def _tile5x5(Rw, Phi, C, i, k, GL):
    """Lanes of G[i:i+5, k:k+5] += Rw[i:i+5, :C] Phi[k:k+5, :C]^T."""
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
    a0 = a1 = a2 = a3 = a4 = vsplat(0)
    for c in range(0, C, LANES):
        x = vload(Rw, i, c)
        a0, a1 = vfma(x, vload(Phi, k, c), a0), vfma(x, vload(Phi, k + 1, c), a1)
        a2, a3 = vfma(x, vload(Phi, k + 2, c), a2), vfma(x, vload(Phi, k + 3, c), a3)
        a4 = vfma(x, vload(Phi, k + 4, c), a4)
    _flush(GL, i, k, a0, a1, a2, a3, a4)


@njit(cache=True)
def _tile2x2(Rw, Phi, C, i, k, GL):
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
    a0 = a1 = vsplat(0)
    for c in range(0, C, LANES):
        x = vload(Rw, i, c)
        a0, a1 = vfma(x, vload(Phi, k, c), a0), vfma(x, vload(Phi, k + 1, c), a1)
    o = k * LANES
    _put(GL, i, o, a0)
    _put(GL, i, o + LANES, a1)


@njit(cache=True)
def _tile1x1(Rw, Phi, C, i, k, GL):
    a = vsplat(0)
    for c in range(0, C, LANES):
        a = vfma(vload(Rw, i, c), vload(Phi, k, c), a)
    _put(GL, i, k * LANES, a)


@njit(cache=True)
def _accumulate(Rw, Phi, C, GL, symmetric=0):
    """Lanes of GL (m, p * LANES) += Rw[:, :C] Phi[:, :C]^T. With `symmetric` rows (a Gram
    matrix's), their tiles wholly above the diagonal are left out (the caller mirrors them)."""
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
    acc = vsplat(0)
    for c in range(0, C, LANES):
        acc = vadd(acc, vload1(w, c))
    return vsum(acc)


@njit(cache=True, inline="always")
def _gradient_step(M, M32, X, Q, w, Npad, parent, var, Phi, Rw, GL, eta):
    """M -= eta sum_t w (M Phi - q) Phi^T over the columns (M32: M in float32 on entry)."""
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


@njit(cache=True, inline="always")
def gradient_steps(M, M32, X, Q, w, Npad, parent, var, Phi, Rw, GL, eta, steps):
    """`steps` gradient steps on the same samples (updates=batch: 1; updates=steps: k)."""
    m, p = M.shape
    for u in range(steps):
        if u > 0:
            for i in range(m):
                for k in range(p):
                    M32[i, k] = M[i, k]
        _gradient_step(M, M32, X, Q, w, Npad, parent, var, Phi, Rw, GL, eta)
