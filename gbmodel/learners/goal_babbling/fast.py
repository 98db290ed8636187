"""The fast path of Goal Babbling: whole blocks of epochs in one compiled (numba) call.

It computes what `reference.py` states, epoch by epoch and with the same random numbers, in
float32 vector loops over the samples of an epoch:

- samples are columns, laid out variation-major, T + 1 columns per variation: the home example,
  then the path; the weight of a sample only looks at the column before it. After the last
  variation, padding up to a multiple of LANES (the home posture, weight 0, so that it adds
  exactly nothing);
- every step of the epoch is one pass over all columns (commands, kinematics, weights), the
  last ones in blocks of _BLOCK columns that stay in cache (features, weighted residuals,
  gradient);
- the rollout runs in float32; M stays float64 and is updated once per epoch (updates=batch;
  updates=steps repeats the gradient pass, updates=online goes sample by sample in float64
  vectors over M's rows, _online). Positions agree with the float64 reference to ~2e-7 m
  (tests/core/test_fast.py states the tolerances);
- the hand is carried backwards through the chain, one rotation about z per joint, in
  registers, LANES samples at a time: DH rows, or a general (URDF) chain's fixed rotation and
  translation per joint (gbmodel.kinematics.chain_layout, simd.chain_kinematics);
- sin and cos are a branch-free polynomial (Cephes' kernels after a Cody-Waite reduction);
- features are built monomial by monomial, each a parent monomial times one coordinate;
- the gradient sum_t w (M Phi - q) Phi^T: the weighted residuals (rows in register tiles of 5),
  then 5 x 5 tiles of vector accumulators (10 loads per 25 fused multiply-adds), float32 lanes
  over the epoch whose sum is float64.

Bit-identical results on every x86-64 CPU, with or without AVX-512, whatever vector width LLVM
prefers (tests/core/test_kernel_targets.py: AVX2 + FMA, AVX-512, and the SSE2 baseline without FMA):
- every loop over samples is written on explicit LANES-wide vectors (`F32x16`, gbmodel/simd.py:
  LLVM <16 x float>, one zmm register, or two ymm halves without AVX-512, with the same result lane
  by lane), so the compiler never chooses how to split a sum: every sum over samples (the
  gradient, sum w) has one partial sum per lane, added up lane by lane in a fixed order at the
  end;
- multiply-adds are explicit fused multiply-adds (llvm.fma: one instruction on an FMA CPU, a
  correctly rounded libm call without), divisions and square roots exact IEEE operations;
- nothing is compiled with fastmath: no reassociation, no contraction of a * b + c, no
  approximate reciprocals, no NaN/inf assumptions (a diverging learner stays visible);
- no threads.
(Tested with numba 0.68 / llvmlite 0.50; LLVM may not change what these operations compute.)
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ...features import monomial_tree
from ...kinematics import chain_layout
from ...simd import (
    F4, LANES, W8, _1, _HALF, chain_kinematics, vadd, vadd8, vclip, vdiv, vfma, vfma8, vload, vload1,
    vload8, vload8f, vload18, vmul, vmul8, vsplat, vsplat8, vsqrt, vstore, vstore1, vstore8, vstore18,
    vsub, vsub8, vsum, vwhere, transpose8,
)
from .reference import NO_MOVEMENT
from .solve import Solved, cholesky_solve

_BLOCK = 512  # columns per block of features, residuals and gradient (multiple of LANES)
_CHUNK = 128  # samples whose float64 features and commands are laid out together (updates=online)
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


# ---- the gradient: register tiles of vector accumulators ---------------------------------------
@njit(inline="always")
def _flush(GL, i, k, b0, b1, b2, b3, b4):
    """GL[i, lanes of k ... k + 4] += b0 ... b4."""
    o = k * LANES
    vstore(GL, i, o, vadd(vload(GL, i, o), b0))
    vstore(GL, i, o + LANES, vadd(vload(GL, i, o + LANES), b1))
    vstore(GL, i, o + 2 * LANES, vadd(vload(GL, i, o + 2 * LANES), b2))
    vstore(GL, i, o + 3 * LANES, vadd(vload(GL, i, o + 3 * LANES), b3))
    vstore(GL, i, o + 4 * LANES, vadd(vload(GL, i, o + 4 * LANES), b4))


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
def _tile1x1(Rw, Phi, C, i, k, GL):
    """Lanes of G[i, k] += Rw[i, :C] . Phi[k, :C]."""
    a = vsplat(0)
    for c in range(0, C, LANES):
        a = vfma(vload(Rw, i, c), vload(Phi, k, c), a)
    vstore(GL, i, k * LANES, vadd(vload(GL, i, k * LANES), a))


@njit(cache=True)
def _accumulate(Rw, Phi, C, GL, symmetric=0):
    """Lanes of the gradient, GL (m, p * LANES) += Rw[:, :C] Phi[:, :C]^T: lane l of G[i, k]
    sums the columns c = l (mod LANES) in order, whatever the CPU. With `symmetric` rows (the
    first rows of Rw are Phi's, weighted: a Gram matrix), the tiles of those rows wholly above
    the diagonal are left out (the caller mirrors them)."""
    m, p = Rw.shape[0], Phi.shape[0]
    mt, pt = m - m % _TILE, p - p % _TILE
    for i in range(0, mt, _TILE):
        for k in range(0, pt, _TILE):
            if i + _TILE <= symmetric and k >= i + _TILE:
                continue
            _tile5x5(Rw, Phi, C, i, k, GL)
    for i in range(mt, m):
        for k in range(0, pt, _TILE):
            _tile1x5(Rw, Phi, C, i, k, GL)
    for i in range(m):
        for k in range(pt, p):
            _tile1x1(Rw, Phi, C, i, k, GL)


# ---- one epoch -----------------------------------------------------------------------------------
@njit(cache=True)
def _disturbances(raw, amp, s, centre, half, radius, A, b):
    """Eq. 8: rows of [A | b] of every variation, scaled so that max |A_i x + b_i| = radius
    times amp[v, i] over the target box (centre +- half) at size s (float64; stored as float32;
    amp is 1 for the exact reading, U(0, 1) for the uniform one)."""
    V, m, n = A.shape
    for v in range(V):
        for i in range(m):
            at_centre = raw[v, i, n]
            spread = 0.0
            for j in range(n):
                at_centre += raw[v, i, j] * s * centre[j]
                spread += abs(raw[v, i, j]) * s * half[j]
            k_i = radius / (abs(at_centre) + spread) * amp[v, i]
            for j in range(n):
                A[v, i, j] = F4(raw[v, i, j] * k_i)
            b[v, i] = F4(raw[v, i, n] * k_i)


@njit(cache=True)
def _commands(gpath, path, A, b, home, T, Npad, Q):
    """Commands of every variation, v in the columns v (T + 1) ... v (T + 1) + T of Q: the home
    posture, then g + A x* + b along the path; home again in the columns N ... Npad - 1.
    (A variation's last vector runs into the next variation's columns, which that variation
    then writes; hence in order.)"""
    m, Bv = gpath.shape
    V, n = A.shape[0], path.shape[0]
    for v in range(V):
        r0 = v * (T + 1)
        for u in range(0, Bv, LANES):
            # x* of these columns (n <= 3: the hand coordinates controlled), in registers
            x0 = vload(path, 0, u)
            x1 = vload(path, min(1, n - 1), u)
            x2 = vload(path, min(2, n - 1), u)
            for i in range(m):
                q = vfma(vsplat(A[v, i, 0]), x0, vadd(vload(gpath, i, u), vsplat(b[v, i])))
                if n > 1:
                    q = vfma(vsplat(A[v, i, 1]), x1, q)
                if n > 2:
                    q = vfma(vsplat(A[v, i, 2]), x2, q)
                for j in range(3, n):
                    q = vfma(vsplat(A[v, i, j]), vload(path, j, u), q)
                vstore(Q, i, r0 + u, q)
        for i in range(m):
            Q[i, r0] = home[i]
    for i in range(m):
        Q[i, V * (T + 1):Npad] = home[i]


@njit(cache=True)
def _weights(dxs, nxs, X, Q, V, T, Npad, w):
    """w_dir * w_eff (eq. 1-3) of every path column r0 + 1 ... r0 + T of a variation (r0 =
    v (T + 1)) against the column before, w = 1 for its home column r0 (eq. 5); 0 for the
    columns N ... Npad - 1. dxs, nxs: the intended steps u -> u + 1 and their squared lengths,
    the same for every variation. (In order, as _commands.)"""
    n, m = X.shape[0], Q.shape[0]
    Bv = len(nxs)
    zero, one, half = vsplat(0), vsplat(_1), vsplat(_HALF)
    no_move2 = vsplat(F4(NO_MOVEMENT * NO_MOVEMENT))
    for v in range(V):
        r0 = v * (T + 1)
        for u in range(0, Bv, LANES):
            c = r0 + u
            dot = nx = nq = zero
            for j in range(n):
                dx = vsub(vload(X, j, c + 1), vload(X, j, c))
                dot = vfma(vload(dxs, j, u), dx, dot)
                nx = vfma(dx, dx, nx)
            for i in range(m):
                dq = vsub(vload(Q, i, c + 1), vload(Q, i, c))
                nq = vfma(dq, dq, nq)
            nxs_u = vload1(nxs, u)
            den = vsqrt(vmul(nxs_u, nx))
            cos = vwhere(den, zero, vdiv(dot, den), zero)
            cos = vclip(cos)
            w_dir = vwhere(nxs_u, no_move2, vmul(half, vadd(one, cos)), zero)
            w_eff = vwhere(nq, zero, vsqrt(vdiv(nx, nq)), zero)
            vstore1(w, c + 1, vmul(w_dir, w_eff))
        w[r0] = _1
    w[V * (T + 1):Npad] = 0


@njit(cache=True)
def _lane_sum(w, C):
    """sum w[:C] (C a multiple of LANES): LANES partial sums, then the lanes (vsum)."""
    acc = vsplat(0)
    for c in range(0, C, LANES):
        acc = vadd(acc, vload1(w, c))
    return vsum(acc)


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
def _zeros64(shape):
    """np.zeros(shape) (float64) starting on a 64-byte boundary: a row of whole F64x8 vectors
    then lies in whole cache lines (a vector across two lines is a split load or store, and a
    split store is not forwarded to the next load)."""
    n = shape[0] * shape[1]
    buf = np.zeros(n + W8)
    off = (-(buf.ctypes.data // 8)) % W8
    return buf[off:off + n].reshape(shape)


@njit(inline="always")
def _row8(Q, i, m, c):
    """Q[i, c:c + 8] as float64 lanes, zeros for a row i >= m."""
    return vload8f(Q, i, c) if i < m else vsplat8(0.0)


@njit(cache=True)
def _online_rows(MT, Ph, D, QT, w, c0, C, eta, g, P, b):
    """_online's steps of the chunk's C samples on the rows b ... b + 7 of M (lanes of MT[:, b:]),
    g_t and P_t+1 in registers while the samples run (g, P: at the chunk's start and end).
    Two samples per pass over M: M_t and M_t+1 from one load of M_t-1, one store of M_t+1."""
    p = MT.shape[0]
    pe = p - p % 2
    g0, P0 = vload18(g, b), vload18(P, b)
    for j in range(0, C - C % 2, 2):
        # minus s_t, exactly: eta w (q - g); then g_t+1 = M_t phi_t+1 = P_t+1 - s_t d_t
        s0 = vmul8(vsplat8(eta * float(w[c0 + j])), vsub8(vload8(QT, j, b), g0))
        g0 = vfma8(s0, vsplat8(D[j]), P0)
        s1 = vmul8(vsplat8(eta * float(w[c0 + j + 1])), vsub8(vload8(QT, j + 1, b), g0))
        # M_t = M_t-1 - s_t phi_t^T, P_t+2 = M_t phi_t+2; M_t+1, Q_t+3 = M_t+1 phi_t+3 (even k,
        # odd k)
        a0, a1, e0, e1 = vsplat8(0.0), vsplat8(0.0), vsplat8(0.0), vsplat8(0.0)
        for k in range(0, pe, 2):
            v0 = vfma8(s0, vsplat8(Ph[k, j]), vload8(MT, k, b))
            v1 = vfma8(s0, vsplat8(Ph[k + 1, j]), vload8(MT, k + 1, b))
            u0 = vfma8(s1, vsplat8(Ph[k, j + 1]), v0)
            u1 = vfma8(s1, vsplat8(Ph[k + 1, j + 1]), v1)
            vstore8(MT, k, b, u0)
            vstore8(MT, k + 1, b, u1)
            a0, a1 = vfma8(v0, vsplat8(Ph[k, j + 2]), a0), vfma8(v1, vsplat8(Ph[k + 1, j + 2]), a1)
            e0, e1 = vfma8(u0, vsplat8(Ph[k, j + 3]), e0), vfma8(u1, vsplat8(Ph[k + 1, j + 3]), e1)
        if pe < p:
            v0 = vfma8(s0, vsplat8(Ph[pe, j]), vload8(MT, pe, b))
            u0 = vfma8(s1, vsplat8(Ph[pe, j + 1]), v0)
            vstore8(MT, pe, b, u0)
            a0 = vfma8(v0, vsplat8(Ph[pe, j + 2]), a0)
            e0 = vfma8(u0, vsplat8(Ph[pe, j + 3]), e0)
        g0 = vfma8(s1, vsplat8(D[j + 1]), vadd8(a0, a1))
        P0 = vadd8(e0, e1)
    if C % 2:  # the chunk's last sample on its own
        j = C - 1
        s0 = vmul8(vsplat8(eta * float(w[c0 + j])), vsub8(vload8(QT, j, b), g0))
        g0 = vfma8(s0, vsplat8(D[j]), P0)
        a0, a1 = vsplat8(0.0), vsplat8(0.0)
        for k in range(0, pe, 2):
            v0 = vfma8(s0, vsplat8(Ph[k, j]), vload8(MT, k, b))
            v1 = vfma8(s0, vsplat8(Ph[k + 1, j]), vload8(MT, k + 1, b))
            vstore8(MT, k, b, v0)
            vstore8(MT, k + 1, b, v1)
            a0, a1 = vfma8(v0, vsplat8(Ph[k, j + 2]), a0), vfma8(v1, vsplat8(Ph[k + 1, j + 2]), a1)
        if pe < p:
            v0 = vfma8(s0, vsplat8(Ph[pe, j]), vload8(MT, pe, b))
            vstore8(MT, pe, b, v0)
            a0 = vfma8(v0, vsplat8(Ph[pe, j + 2]), a0)
        P0 = vadd8(a0, a1)
    vstore18(g, b, g0)
    vstore18(P, b, P0)


@njit(cache=True)
def _online_rows2(MT, Ph, D, QT, w, c0, C, eta, g, P, b):
    """_online_rows on the rows b ... b + 15, two vectors side by side (the features loaded
    once, two independent chains)."""
    p = MT.shape[0]
    pe = p - p % 2
    b1 = b + W8
    g0, P0, g1, P1 = vload18(g, b), vload18(P, b), vload18(g, b1), vload18(P, b1)
    for j in range(0, C - C % 2, 2):
        ge, dv = vsplat8(eta * float(w[c0 + j])), vsplat8(D[j])
        s0 = vmul8(ge, vsub8(vload8(QT, j, b), g0))
        s1 = vmul8(ge, vsub8(vload8(QT, j, b1), g1))
        g0, g1 = vfma8(s0, dv, P0), vfma8(s1, dv, P1)
        ge = vsplat8(eta * float(w[c0 + j + 1]))
        r0 = vmul8(ge, vsub8(vload8(QT, j + 1, b), g0))
        r1 = vmul8(ge, vsub8(vload8(QT, j + 1, b1), g1))
        a0, a1, e0, e1 = vsplat8(0.0), vsplat8(0.0), vsplat8(0.0), vsplat8(0.0)
        c0_, c1_, d0, d1 = vsplat8(0.0), vsplat8(0.0), vsplat8(0.0), vsplat8(0.0)
        for k in range(0, pe, 2):
            f0, f1 = vsplat8(Ph[k, j]), vsplat8(Ph[k + 1, j])
            n0, n1 = vsplat8(Ph[k, j + 1]), vsplat8(Ph[k + 1, j + 1])
            h0, h1 = vsplat8(Ph[k, j + 2]), vsplat8(Ph[k + 1, j + 2])
            o0, o1 = vsplat8(Ph[k, j + 3]), vsplat8(Ph[k + 1, j + 3])
            v0 = vfma8(s0, f0, vload8(MT, k, b))
            v1 = vfma8(s0, f1, vload8(MT, k + 1, b))
            u0 = vfma8(s1, f0, vload8(MT, k, b1))
            u1 = vfma8(s1, f1, vload8(MT, k + 1, b1))
            a0, a1 = vfma8(v0, h0, a0), vfma8(v1, h1, a1)
            e0, e1 = vfma8(u0, h0, e0), vfma8(u1, h1, e1)
            v0, v1 = vfma8(r0, n0, v0), vfma8(r0, n1, v1)
            u0, u1 = vfma8(r1, n0, u0), vfma8(r1, n1, u1)
            vstore8(MT, k, b, v0)
            vstore8(MT, k + 1, b, v1)
            vstore8(MT, k, b1, u0)
            vstore8(MT, k + 1, b1, u1)
            c0_, c1_ = vfma8(v0, o0, c0_), vfma8(v1, o1, c1_)
            d0, d1 = vfma8(u0, o0, d0), vfma8(u1, o1, d1)
        if pe < p:
            f0, n0 = vsplat8(Ph[pe, j]), vsplat8(Ph[pe, j + 1])
            h0, o0 = vsplat8(Ph[pe, j + 2]), vsplat8(Ph[pe, j + 3])
            v0 = vfma8(s0, f0, vload8(MT, pe, b))
            u0 = vfma8(s1, f0, vload8(MT, pe, b1))
            a0, e0 = vfma8(v0, h0, a0), vfma8(u0, h0, e0)
            v0, u0 = vfma8(r0, n0, v0), vfma8(r1, n0, u0)
            vstore8(MT, pe, b, v0)
            vstore8(MT, pe, b1, u0)
            c0_, d0 = vfma8(v0, o0, c0_), vfma8(u0, o0, d0)
        dv = vsplat8(D[j + 1])
        g0, g1 = vfma8(r0, dv, vadd8(a0, a1)), vfma8(r1, dv, vadd8(e0, e1))
        P0, P1 = vadd8(c0_, c1_), vadd8(d0, d1)
    if C % 2:  # the chunk's last sample on its own
        j = C - 1
        ge, dv = vsplat8(eta * float(w[c0 + j])), vsplat8(D[j])
        s0 = vmul8(ge, vsub8(vload8(QT, j, b), g0))
        s1 = vmul8(ge, vsub8(vload8(QT, j, b1), g1))
        g0, g1 = vfma8(s0, dv, P0), vfma8(s1, dv, P1)
        a0, a1, e0, e1 = vsplat8(0.0), vsplat8(0.0), vsplat8(0.0), vsplat8(0.0)
        for k in range(p):
            f0, h0 = vsplat8(Ph[k, j]), vsplat8(Ph[k, j + 2])
            v0 = vfma8(s0, f0, vload8(MT, k, b))
            u0 = vfma8(s1, f0, vload8(MT, k, b1))
            vstore8(MT, k, b, v0)
            vstore8(MT, k, b1, u0)
            if k % 2:
                a1, e1 = vfma8(v0, h0, a1), vfma8(u0, h0, e1)
            else:
                a0, e0 = vfma8(v0, h0, a0), vfma8(u0, h0, e0)
        P0, P1 = vadd8(a0, a1), vadd8(e0, e1)
    vstore18(g, b, g0)
    vstore18(P, b, P0)
    vstore18(g, b1, g1)
    vstore18(P, b1, P1)


@njit(cache=True)
def _online(M, X, Q, w, N, parent, var, eta):
    """One step per sample, columns 0 ... N-1 in order (reference.update, updates=online), in
    float64: M_t = M_t-1 - s_t phi_t^T with s_t = eta w_t (M_t-1 phi_t - q_t) (a weight 0 steps
    by 0). X needs W8 + 2 columns past N, Q W8 (read, not used).

    The step waits for nothing but s_t, and s_t for the prediction M_t-1 phi_t, which is
    g_t = P_t - s_t-1 d_t-1 with P_t = M_t-2 phi_t (summed while the pass over M wrote M_t-2)
    and d_t-1 = phi_t-1 . phi_t (with the features): a sample waits for a few operations, not
    for a sum over the p features. Per chunk of _CHUNK samples, their features, commands and
    the products d first; then, per block of rows of M (the rows are independent), one pass
    over M per pair of samples, the rows of M the lanes of F64x8 vectors (M kept transposed,
    MT (p, W), zero-padded to whole vectors, in whole cache lines). Fused multiply-adds,
    every sum in a fixed order (P: even and odd k apart, then added): the same bytes on every
    CPU. It agrees with the numpy reference to rounding (tests/core/test_fast.py)."""
    m, p = M.shape
    W = -(-m // W8) * W8
    MT = _zeros64((p, W))
    for i in range(m):
        for k in range(p):
            MT[k, i] = M[i, k]
    L = _CHUNK + 2 * W8  # the chunk's columns and those looked ahead, in whole vectors
    Ph = _zeros64((p, L))  # features (row 0: the constant)
    Ph[0] = 1.0
    D = np.zeros(_CHUNK)  # D[j] = phi_j . phi_j+1
    QT = _zeros64((_CHUNK, W))  # commands, a row per sample (0 in the padding lanes)
    g, P = np.zeros(W), np.zeros(W)  # g_t, P_t+1
    for c0 in range(0, N, _CHUNK):
        C = min(_CHUNK, N - c0)
        CL = -(-(C + 2) // W8) * W8
        for k in range(1, p):
            src, coord = parent[k], var[k]
            for j in range(0, CL, W8):
                vstore8(Ph, k, j, vmul8(vload8(Ph, src, j), vload8f(X, coord, c0 + j)))
        for j in range(0, C, W8):
            d = vmul8(vload8(Ph, 0, j), vload8(Ph, 0, j + 1))
            for k in range(1, p):
                d = vfma8(vload8(Ph, k, j), vload8(Ph, k, j + 1), d)
            vstore18(D, j, d)
        for j in range(0, C, W8):  # 8 x 8 blocks of Q, transposed
            for b in range(0, W, W8):
                t = transpose8(_row8(Q, b, m, c0 + j), _row8(Q, b + 1, m, c0 + j),
                               _row8(Q, b + 2, m, c0 + j), _row8(Q, b + 3, m, c0 + j),
                               _row8(Q, b + 4, m, c0 + j), _row8(Q, b + 5, m, c0 + j),
                               _row8(Q, b + 6, m, c0 + j), _row8(Q, b + 7, m, c0 + j))
                for l in range(W8):
                    vstore8(QT, j + l, b, t[l])
        if c0 == 0:  # g_0 = M phi_0, P_1 = M phi_1
            for b in range(0, W, W8):
                a0, a1 = vsplat8(0.0), vsplat8(0.0)
                for k in range(p):
                    mk = vload8(MT, k, b)
                    a0 = vfma8(mk, vsplat8(Ph[k, 0]), a0)
                    a1 = vfma8(mk, vsplat8(Ph[k, 1]), a1)
                vstore18(g, b, a0)
                vstore18(P, b, a1)
        for b in range(0, W - W8, 2 * W8):  # two vectors of rows: the features loaded once
            _online_rows2(MT, Ph, D, QT, w, c0, C, eta, g, P, b)
        if W % (2 * W8):
            _online_rows(MT, Ph, D, QT, w, c0, C, eta, g, P, W - W8)
    for i in range(m):
        for k in range(p):
            M[i, k] = MT[k, i]


@njit(cache=True)
def _gram_sums(X, Q, w, Npad, parent, var, Phi, Z, GG, out):
    """out (p + m, p) = [sum_t w Phi Phi^T; sum_t w q Phi^T] over the columns of X, Q, w
    (solve.grams): the rows w Phi and w q in blocks, their products with Phi in the gradient's
    register tiles (float32 lanes, float64 sum)."""
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
def _solve(M, ring, slot, ridge, X, Q, w, Npad, parent, var, Phi, solver_work):
    """solver=lstsq (solve.solve): this epoch's Gram sums into ring[slot], then M from the sum
    of the slots (in slot order) by the ridge system, in place."""
    Z, GG, total, A, B, L, out = solver_work
    m, p = M.shape
    _gram_sums(X, Q, w, Npad, parent, var, Phi, Z, GG, ring[slot])
    total[:] = ring[0]
    for k in range(1, ring.shape[0]):
        for i in range(p + m):
            for j in range(p):
                total[i, j] += ring[k, i, j]
    for i in range(p):
        for j in range(p):
            A[i, j] = total[i, j]
        d = ridge * total[i, i] if total[i, i] > 0 else 1.0
        A[i, i] += d
        for r in range(m):
            B[i, r] = total[p + r, i] + d * M[r, i]
    _cholesky_solve(A, B, L, out)
    for r in range(m):
        for i in range(p):
            M[r, i] = out[i, r]


@njit(cache=True)
def _solver_work(m, n, p, V, T, window):
    """Work arrays of solver=lstsq (a window of 0: none, for the gradient step)."""
    Npad = -(-(V * (T + 1)) // LANES) * LANES
    cols = min(Npad, _BLOCK) if window > 0 else LANES
    f4 = np.float32
    return (np.empty((p + m, cols), f4), np.empty((p + m, p * LANES), f4), np.empty((p + m, p)),
            np.empty((p, p)), np.empty((p, m)), np.zeros((p, p)), np.empty((p, m)))


BATCH, STEPS, ONLINE = 0, 1, 2  # the updates readings, as the kernel takes them


@njit(cache=True)
def _epoch(M, idx, raw, amp, s, body, targets, home, parent, var, joints, radius, steps,
           rate, plain, updates, update_steps, box, work, ring, slot, ridge, solver_work):
    """One epoch (see reference.epoch): rolls out, weights, updates M in place with rate eta,
    or (a ring of Gram sums given, len(ring) > 0: solver=lstsq) solves M (_solve, its slot).

    Leaves the samples in work: Q (m, N) postures, X (n, N) reached positions, w (N) weights,
    variation v in the columns v (T + 1) ... v (T + 1) + T (N = V (T + 1); then columns of
    padding up to a multiple of LANES, and LANES spare ones).
    """
    Q, X, w, Phi, Rw, path, Phip, gpath, dxs, nxs, A, b, M32, GL, Qh, Xh = work
    m, p = M.shape
    n = targets.shape[1]
    V = raw.shape[0]
    Bv = gpath.shape[1]
    Npad = len(w) - LANES
    T = (len(idx) - 1) * steps
    s4 = F4(s)
    # the home posture and where it puts the hand (every lane the same)
    for i in range(m):
        vstore(Qh, i, 0, vsplat(home[i]))
    chain_kinematics(Qh, Xh, LANES, joints, body)
    # the target path (eq. 9) at the current size in columns 1 ... T, the hand at home in
    # column 0, the last target in the rest
    for j in range(n):
        path[j, 0] = Xh[j, 0]
    for k in range(len(idx) - 1):
        t0, t1 = idx[k], idx[k + 1]
        for l in range(steps):
            f = F4(l) / F4(steps)
            for j in range(n):
                # t0 + f (t1 - t0): exactly t0 along a repeated target (targets=any), so that
                # its intended steps are 0 and weigh nothing, as in the float64 reference
                path[j, 1 + k * steps + l] = s4 * (targets[t0, j] +
                                                   f * (targets[t1, j] - targets[t0, j]))
    for u in range(T + 1, path.shape[1]):
        for j in range(n):
            path[j, u] = s4 * targets[idx[-1], j]
    # the intended steps u -> u + 1 and their squared lengths
    nxs[:] = 0
    for j in range(n):
        for u in range(Bv):
            dxs[j, u] = path[j, u + 1] - path[j, u]
            nxs[u] += dxs[j, u] * dxs[j, u]
    # g along the path
    for i in range(m):
        for k in range(p):
            M32[i, k] = M[i, k]
    _features(path, 0, Bv, parent, var, Phip)
    _predict(M32, Phip, Bv, gpath, Q, w[:0], 0)
    # the variations' disturbances (eq. 8), their rollouts, weights, residuals, gradient lanes
    _disturbances(raw, amp, s, box[0], box[1], radius, A, b)
    _commands(gpath, path, A, b, home, T, Npad, Q)
    chain_kinematics(Q, X, Npad, joints, body)
    _weights(dxs, nxs, X, Q, V, T, Npad, w)
    if len(ring) > 0:
        _solve(M, ring, slot, ridge, X, Q, w, Npad, parent, var, Phi, solver_work)
        return
    # gradient descent on the weighted command error (eq. 6), plain or normalised by sum w
    eta = rate if plain else rate / _lane_sum(w, Npad)
    if updates == ONLINE:
        _online(M, X, Q, w, V * (T + 1), parent, var, eta)
        return
    for u in range(update_steps if updates == STEPS else 1):
        if u > 0:
            for i in range(m):
                for k in range(p):
                    M32[i, k] = M[i, k]
        _gradient_step(M, M32, X, Q, w, Npad, parent, var, Phi, Rw, GL, eta)


@njit(cache=True)
def _work(m, n, p, V, T):
    """Work arrays of one epoch: Npad = V (T + 1) rounded up to LANES sample columns (and LANES
    spare), Bv = T + 1 rounded up for the path."""
    Bv = -(-(T + 1) // LANES) * LANES
    Npad = -(-(V * (T + 1)) // LANES) * LANES
    N = Npad + LANES
    f4 = np.float32
    return (np.zeros((m, N), f4), np.zeros((n, N), f4), np.zeros(N, f4),
            np.empty((p, min(Npad, _BLOCK)), f4), np.empty((m, min(Npad, _BLOCK)), f4),
            np.empty((n, Bv + LANES), f4), np.empty((p, Bv), f4), np.empty((m, Bv), f4),
            np.empty((n, Bv), f4), np.empty(Bv, f4),
            np.empty((V, m, n), f4), np.empty((V, m), f4),
            np.empty((m, p), f4), np.empty((m, p * LANES), f4),
            np.empty((m, LANES), f4), np.empty((n, LANES), f4))


@njit(cache=True)
def _box(targets):
    """(centre, half width) of the box around the targets (at full size), per coordinate."""
    n = targets.shape[1]
    centre, half = np.empty(n), np.empty(n)
    for j in range(n):
        lo, hi = float(targets[:, j].min()), float(targets[:, j].max())
        centre[j], half[j] = 0.5 * (lo + hi), 0.5 * (hi - lo)
    return centre, half


@njit(cache=True)
def _block(M, idx, raw, amp, sizes, scales, rates, chain, targets, home, parent, var, joints,
           radius, steps, plain, updates, update_steps, ring, done, ridge):
    """Epochs e = 0 ... B-1 with sizes[e], per-joint length factors scales[e] and rates[e]
    (solver=lstsq: ring, the Gram sums of the window, after `done` epochs learned)."""
    a, d, ca, sa, base, outputs, ty, R, general = chain
    m, p = M.shape
    n = targets.shape[1]
    V, T = raw.shape[1], (idx.shape[1] - 1) * steps
    work = _work(m, n, p, V, T)
    solver_work = _solver_work(m, n, p, V, T, len(ring))
    box = _box(targets)
    ae = np.empty(m, np.float32)
    de = np.empty(m, np.float32)
    ye = np.empty(m, np.float32)
    for e in range(idx.shape[0]):
        for i in range(m):
            ae[i] = a[i] * scales[e, i]
            de[i] = d[i] * scales[e, i]
            ye[i] = ty[i] * scales[e, i]
        body = (ae, de, ca, sa, base, outputs, ye, R, general)
        _epoch(M, idx[e], raw[e], amp[e], sizes[e], body, targets, home, parent, var, joints,
               radius, steps, rates[e], plain, updates, update_steps, box, work, ring,
               (done + e) % max(len(ring), 1), ridge, solver_work)


@njit(cache=True)
def _distances(M, scale, chain, xs, parent, var, joints, out):
    """out[t] = |f(g(xs_t)) - xs_t| (float64) with the chain's lengths times scale."""
    a, d, ca, sa, base, outputs, ty, R, general = chain
    m, p = M.shape
    NT, n = xs.shape
    ae, de, ye = np.empty(m, np.float32), np.empty(m, np.float32), np.empty(m, np.float32)
    for i in range(m):
        ae[i], de[i], ye[i] = a[i] * scale[i], d[i] * scale[i], ty[i] * scale[i]
    body = (ae, de, ca, sa, base, outputs, ye, R, general)
    M32 = np.empty((m, p), np.float32)
    for i in range(m):
        for k in range(p):
            M32[i, k] = M[i, k]
    C = -(-NT // LANES) * LANES
    X, Phi, Q = np.empty((n, C), np.float32), np.empty((p, C), np.float32), np.empty((m, C),
                                                                                      np.float32)
    for t in range(C):
        for j in range(n):
            X[j, t] = xs[min(t, NT - 1), j]
    _features(X, 0, C, parent, var, Phi)
    _predict(M32, Phi, C, Q, Q, np.empty(0, np.float32), 0)
    chain_kinematics(Q, X, C, joints, body)
    for t in range(NT):
        d2 = 0.0
        for j in range(n):
            dx = float(X[j, t]) - xs[t, j]
            d2 += dx * dx
        out[t] = np.sqrt(d2)


_ARRAYS: dict = {}  # (id(body), exps) -> (body, arrays); the body is kept so its id stays its own


def _arrays(body, exps):
    """The body as the kernels take it: float32 chain and joint map, plus the monomial tree.
    Built once per body object (bodies are frozen) and monomial table."""
    exps = np.asarray(exps)
    key = (id(body), exps.shape, exps.tobytes())
    hit = _ARRAYS.get(key)
    if hit is not None and hit[0] is body:
        return hit[1]
    f4 = lambda x: np.ascontiguousarray(x, np.float32)  # noqa: E731
    chain = chain_layout(body)
    normalized = body.normalized
    joints = (normalized, body.saturates,
              f4(body.q_min if normalized else np.zeros(body.m)),
              f4(body.q_max - body.q_min if normalized else np.ones(body.m)),
              f4(body.theta_offset))
    parent, var = monomial_tree(exps)
    arr = dict(
        chain=(f4(chain["a"]), f4(chain["d"]), f4(chain["cos_alpha"]), f4(chain["sin_alpha"]),
               f4(chain["base"]), np.array(body.outputs, np.int64), f4(chain["ty"]),
               f4(chain["R"]), chain["general"]),
        targets=f4(body.targets), home=f4(body.saturate(body.home)), parent=parent, var=var,
        joints=joints,
    )
    if len(_ARRAYS) >= 32:
        _ARRAYS.clear()
    _ARRAYS[key] = (body, arr)
    return arr


def _amplitudes(raw, amp):
    """The amplitude factors (..., V, m): the drawn ones (uniform reading), or 1 (exact)."""
    if amp is None:
        return np.ones(raw.shape[:-1])
    return np.ascontiguousarray(amp, np.float64)


_UPDATES = {"batch": BATCH, "steps": STEPS, "online": ONLINE}


def _options(params):
    return dict(radius=float(params.radius), steps=int(params.steps),
                plain=params.step == "plain", updates=_UPDATES[params.updates],
                update_steps=int(params.update_steps))


_NO_RING = np.zeros((0, 1, 1))


def run_block(M, body, params, exps, sizes, scales, rates, idx, raw, amp=None):
    """Epochs with sizes `sizes`, per-joint length factors `scales` (B, m), rates eta (B,) and
    draws idx, raw (and amp, the amplitude factors of the uniform reading). Returns the
    updated M, or with M a solve.Solved state (solver=lstsq) the next Solved state."""
    solved = isinstance(M, Solved)
    ring = np.array(M.ring, dtype=np.float64, order="C") if solved else _NO_RING
    done = M.epochs if solved else 0
    out = np.array(M.M if solved else M, dtype=np.float64, order="C")
    _block(out, np.ascontiguousarray(idx, np.int64), np.ascontiguousarray(raw, np.float64),
           _amplitudes(raw, amp), np.ascontiguousarray(sizes, np.float64),
           np.ascontiguousarray(scales, np.float32).reshape(len(sizes), body.m),
           np.ascontiguousarray(rates, np.float64), **_options(params), **_arrays(body, exps),
           ring=ring, done=done, ridge=float(params.ridge))
    return Solved(out, ring, done + len(sizes)) if solved else out


def distances(M, body, exps, scale, xs):
    """|f(g(x*)) - x*| for every row of xs (N, n): the evaluation on the fast path."""
    arr = _arrays(body, exps)
    out = np.empty(len(xs))
    _distances(np.ascontiguousarray(M, np.float64), np.ascontiguousarray(scale, np.float32),
               arr["chain"], np.ascontiguousarray(xs, np.float64), arr["parent"], arr["var"],
               arr["joints"], out)
    return out


def epoch_samples(M, body, params, exps, size, scale, idx, raw, amp=None, rate=None):
    """One epoch on the fast path, for tests: returns (M after, Q, X, w) with the samples laid
    out as (V, T + 1, ...) like reference.epoch's (rate: eta, params.learning_rate if None)."""
    M = np.array(M, dtype=np.float64, order="C")
    arr = _arrays(body, exps)
    a, d, ca, sa, base, outputs, ty, R, general = arr["chain"]
    k = np.asarray(scale, np.float32)
    chain = (a * k, d * k, ca, sa, base, outputs, ty * k, R, general)
    T = (len(idx) - 1) * params.steps
    V = raw.shape[0]
    work = _work(body.m, body.n, len(exps), V, T)
    _epoch(M, np.asarray(idx, np.int64), np.ascontiguousarray(raw, np.float64),
           _amplitudes(raw, amp), float(size), chain, arr["targets"], arr["home"], arr["parent"],
           arr["var"], arr["joints"], rate=float(params.learning_rate if rate is None else rate),
           box=_box(arr["targets"]), work=work, ring=_NO_RING, slot=0, ridge=0.0,
           solver_work=_solver_work(body.m, body.n, len(exps), V, T, 0), **_options(params))
    Q, X, w = work[0], work[1], work[2]
    N = V * (T + 1)
    return (M, Q[:, :N].T.reshape(V, T + 1, -1), X[:, :N].T.reshape(V, T + 1, -1),
            w[:N].reshape(V, T + 1))
