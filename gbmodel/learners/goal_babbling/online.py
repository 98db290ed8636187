"""The online rule in the kernel (updates=online; reference.update): one float64 step per
sample, the rows of M the lanes of F64x8 vectors (see `online`)."""
from __future__ import annotations

import numpy as np
from numba import njit

from ...simd import (
    W8, aligned, wide_vectors, vadd8, vfma8, vload8, vload8f, vload18, vmul8, vsplat8, vstore8,
    vstore18, vsub8, transpose8,
)

_CHUNK = 128  # samples whose float64 features and commands are laid out together


@njit(inline="always")
def _row8(Q, i, m, c):
    return vload8f(Q, i, c) if i < m else vsplat8(0.0)


@njit(cache=True)
def _online_rows(MT, Ph, D, QT, w, c0, C, eta, g, P, b):
    """The chunk's C samples on rows b ... b + 7 of M, two samples per pass over M (M_t and
    M_t+1 from one load of M_t-1), g_t and P_t+1 in registers."""
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
    """_online_rows on rows b ... b + 15, two vectors side by side (features loaded once)."""
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
def online(M, X, Q, w, N, parent, var, eta):
    """M_t = M_t-1 - s_t phi_t^T, s_t = eta w_t (M_t-1 phi_t - q_t), columns 0 ... N-1 in order
    (X needs W8 + 2 columns past N, Q W8). The prediction M_t-1 phi_t is g_t = P_t - s_t-1
    d_t-1, P_t = M_t-2 phi_t summed in the pass that wrote M_t-2, d_t-1 = phi_t-1 . phi_t: a
    sample waits for a few operations, not a sum over p. Per chunk of _CHUNK samples, features,
    commands and d first, then per block of rows (independent) one pass over M (transposed,
    padded, in whole cache lines) per pair of samples. Every sum in a fixed order (P: even and
    odd k apart): the same bytes on every CPU, the numpy reference's to rounding."""
    m, p = M.shape
    W = -(-m // W8) * W8
    MT = aligned(p, W, np.float64)
    for i in range(m):
        for k in range(p):
            MT[k, i] = M[i, k]
    L = _CHUNK + 2 * W8  # the chunk's columns and those looked ahead, in whole vectors
    Ph = aligned(p, L, np.float64)  # features (row 0: the constant)
    Ph[0] = 1.0
    D = np.zeros(_CHUNK)  # D[j] = phi_j . phi_j+1
    QT = aligned(_CHUNK, W, np.float64)  # commands, a row per sample (0 in the padding lanes)
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
        if wide_vectors():  # two vectors of rows: the features loaded once
            for b in range(0, W - W8, 2 * W8):
                _online_rows2(MT, Ph, D, QT, w, c0, C, eta, g, P, b)
            if W % (2 * W8):
                _online_rows(MT, Ph, D, QT, w, c0, C, eta, g, P, W - W8)
        else:  # AVX2: _online_rows2's 16 vectors of sums would spill; a vector of rows at a
            # time (the rows are independent: the same bits)
            for b in range(0, W, W8):
                _online_rows(MT, Ph, D, QT, w, c0, C, eta, g, P, b)
    for i in range(m):
        for k in range(p):
            M[i, k] = MT[k, i]
