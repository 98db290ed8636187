"""The rollout of one epoch in the kernel (reference.samples), and the evaluation's rollout of g
itself (`_distances`)."""
from __future__ import annotations

import numpy as np
from numba import njit
from numba.extending import intrinsic

from ...simd import (
    _VEC8, F4, LANES, W8, F64x8, _1, _HALF, _llvm, aligned, chain_kinematics, vadd, vadd8, vclip, vdiv,
    vdiv8, vfma, vload, vload1, vload8, vload8f, vmul, vmul8, vsplat, vsplat8, vsqrt, vsqrt8, vstore,
    vstore1, vstore8, vstore18, vsub, vsub8, vwhere, wide_vectors,
)
from .core import _BLOCK, _features, _predict
from .reference import NO_MOVEMENT

_IOTA = np.arange(LANES, dtype=np.float32)  # lane l: l (the path's fractions l / steps)


@intrinsic
def _vabs8(typingctx, a):
    """|a| lane by lane (llvm.fabs: the sign bit cleared, as abs does)."""
    return F64x8(a), lambda context, builder, sig, args: _llvm(builder, "llvm.fabs", args, _VEC8)


@njit(cache=True)
def _disturbances(raw, amp, s, centre, half, radius, A, K):
    """Eq. 8: rows of [A | b] scaled to max |A_i x + b_i| = radius amp[v, i] over the target box
    at size s, in float64 on W8 rows r = v m + i at a time (each row's operations in the
    scalar order) in K (n + 2, V m rounded up to W8: [A | b]^T, then amp), stored as float32
    in A (n + 1, V, m): A[n] is b."""
    V, m, n1 = raw.shape
    R = V * m
    raw, amp, A = raw.reshape(R, n1), amp.reshape(R), A.reshape(n1, R)
    for j in range(n1):
        for r in range(R):
            K[j, r] = raw[r, j]
    K[n1, :R] = amp
    for r in range(0, R, W8):
        at_centre, spread = vload8(K, n1 - 1, r), vsplat8(0.0)
        for j in range(n1 - 1):
            x = vmul8(vload8(K, j, r), vsplat8(s))
            at_centre = vadd8(at_centre, vmul8(x, vsplat8(centre[j])))
            spread = vadd8(spread, vmul8(vmul8(_vabs8(vload8(K, j, r)), vsplat8(s)),
                                         vsplat8(half[j])))
        k = vmul8(vdiv8(vsplat8(radius), vadd8(_vabs8(at_centre), spread)), vload8(K, n1, r))
        for j in range(n1):
            vstore8(K, j, r, vmul8(vload8(K, j, r), k))
    for j in range(n1):
        for r in range(R):
            A[j, r] = F4(K[j, r])


@njit(cache=True)
def _commands(gpath, path, A, home, T, Npad, Q):
    """Q: per variation the home posture, then g + A x* + b along the path; home in the padding.
    (A variation's last vector runs into the next one's columns: in order.)"""
    m, Bv = gpath.shape
    V, n = A.shape[1], path.shape[0]
    for v in range(V):
        r0 = v * (T + 1)
        if wide_vectors():  # row by row: Q's rows are written in order, A's splats made once
            for i in range(m):
                a0, a1, a2, b = (vsplat(A[0, v, i]), vsplat(A[min(1, n - 1), v, i]),
                                 vsplat(A[min(2, n - 1), v, i]), vsplat(A[n, v, i]))
                for u in range(0, Bv, LANES):
                    q = vfma(a0, vload(path, 0, u), vadd(vload(gpath, i, u), b))
                    if n > 1:
                        q = vfma(a1, vload(path, 1, u), q)
                    if n > 2:
                        q = vfma(a2, vload(path, 2, u), q)
                    for j in range(3, n):
                        q = vfma(vsplat(A[j, v, i]), vload(path, j, u), q)
                    vstore(Q, i, r0 + u, q)
                Q[i, r0] = home[i]
            continue
        for u in range(0, Bv, LANES):
            # x* of these columns (n <= 3: the hand coordinates controlled), in registers
            x0 = vload(path, 0, u)
            x1 = vload(path, min(1, n - 1), u)
            x2 = vload(path, min(2, n - 1), u)
            for i in range(m):
                q = vfma(vsplat(A[0, v, i]), x0, vadd(vload(gpath, i, u), vsplat(A[n, v, i])))
                if n > 1:
                    q = vfma(vsplat(A[1, v, i]), x1, q)
                if n > 2:
                    q = vfma(vsplat(A[2, v, i]), x2, q)
                for j in range(3, n):
                    q = vfma(vsplat(A[j, v, i]), vload(path, j, u), q)
                vstore(Q, i, r0 + u, q)
        for i in range(m):
            Q[i, r0] = home[i]
    for i in range(m):
        Q[i, V * (T + 1):Npad] = home[i]


@njit(cache=True)
def _weights(dxs, nxs, X, Q, V, T, Npad, w):
    """w_dir * w_eff (eq. 1-3) of each path column against the one before, 1 for home columns,
    0 for the padding; dxs, nxs: the intended steps and their squared lengths."""
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
def rollout(M, idx, raw, amp, s, body, targets, home, parent, var, joints, radius, steps, box,
            work):
    """Steps 1-4 of an epoch (reference.samples) into work: Q (m, N) postures, X (n, N) hands,
    w (N) weights, variation v in columns v (T + 1) ... v (T + 1) + T, then weight-0 padding to
    a multiple of LANES and LANES spare columns; M in float32 in work's M32."""
    Q, X, w, _, _, path, Phip, gpath, dxs, nxs, A, K, M32, _ = work
    m, p = M.shape
    n = targets.shape[1]
    V = raw.shape[0]
    Bv = gpath.shape[1]
    Npad = len(w) - LANES
    T = (len(idx) - 1) * steps
    s4 = F4(s)
    # the target path (eq. 9) at the current size in columns 1 ... T, the last target in the
    # rest (column 0, the hand at home, after the rollout); a + f d, f = l / steps: exactly a
    # along a repeated target (targets=any), so that its intended steps are 0 and weigh
    # nothing, as in the float64 reference. A vector of l runs into the next target's columns.
    f0 = vdiv(vload1(_IOTA, 0), vsplat(F4(steps)))
    for j in range(n):
        for k in range(len(idx) - 1):
            a = targets[idx[k], j]
            d = vsplat(targets[idx[k + 1], j] - a)
            for l in range(0, steps, LANES):
                f = f0 if l == 0 else vdiv(vadd(vload1(_IOTA, 0), vsplat(l)), vsplat(F4(steps)))
                vstore(path, j, 1 + k * steps + l, vmul(vsplat(s4), vadd(vsplat(a), vmul(f, d))))
        for u in range(T + 1, path.shape[1]):
            path[j, u] = s4 * targets[idx[-1], j]
    # g along the path
    for i in range(m):
        for k in range(p):
            M32[i, k] = M[i, k]
    _features(path, 0, Bv, parent, var, Phip)
    _predict(M32, Phip, Bv, gpath, Q, w[:0], 0)
    # the variations' disturbances (eq. 8), their rollouts and weights
    _disturbances(raw, amp, s, box[0], box[1], radius, A, K)
    _commands(gpath, path, A, home, T, Npad, Q)
    chain_kinematics(Q, X, Npad, joints, body)
    # the intended steps u -> u + 1 and their squared lengths
    for j in range(n):  # the hand at home: variation 0's column 0 (g's there is not used)
        path[j, 0] = X[j, 0]
    for u in range(0, Bv, LANES):
        nx = vsplat(0)
        for j in range(n):
            dx = vsub(vload(path, j, u + 1), vload(path, j, u))
            vstore(dxs, j, u, dx)
            nx = vadd(nx, vmul(dx, dx))
        vstore1(nxs, u, nx)
    _weights(dxs, nxs, X, Q, V, T, Npad, w)


@njit(cache=True)
def _work(m, n, p, V, T):
    Bv = -(-(T + 1) // LANES) * LANES
    Npad = -(-(V * (T + 1)) // LANES) * LANES
    N = Npad + LANES
    f4 = np.float32
    return (aligned(m, N), aligned(n, N), aligned(1, N)[0],
            aligned(p, min(Npad, _BLOCK)), aligned(m, min(Npad, _BLOCK)),
            aligned(n, Bv + LANES), aligned(p, Bv), aligned(m, Bv),
            aligned(n, Bv), aligned(1, Bv)[0],
            np.empty((n + 1, V, m), f4), np.empty((n + 2, -(-(V * m) // W8) * W8)),
            np.empty((m, p), f4), aligned(m, p * LANES))


@njit(cache=True)
def scaled(chain, k, out):
    """The chain with its translations (a, d, ty) times the length factors k, held in out (3, m)."""
    a, d, ca, sa, base, outputs, ty, R, general = chain
    for i in range(len(a)):
        out[0, i], out[1, i], out[2, i] = a[i] * k[i], d[i] * k[i], ty[i] * k[i]
    return (out[0], out[1], ca, sa, base, outputs, out[2], R, general)


@njit(cache=True)
def _distances(M, scale, chain, xs, parent, var, joints, out):
    """out[t] = |f(g(x_t)) - x_t| (float64) of the points xs, _BLOCK at a time (the work arrays
    stay in cache), the padding the last point: each point's value is its own."""
    m, p = M.shape
    NT, n = xs.shape
    body = scaled(chain, scale, np.empty((3, m), np.float32))
    M32 = np.empty((m, p), np.float32)
    for i in range(m):
        for k in range(p):
            M32[i, k] = M[i, k]
    B = max(LANES, min(_BLOCK, -(-NT // LANES) * LANES))  # (no points: none computed)
    X, Phi, Q = aligned(n, B), aligned(p, B), aligned(m, B)
    X64, D = aligned(n, B, np.float64), aligned(1, B, np.float64)[0]
    for t0 in range(0, NT, B):
        N = min(B, NT - t0)
        C = -(-N // LANES) * LANES
        for j in range(n):
            for t in range(C):
                X64[j, t] = xs[t0 + min(t, N - 1), j]
            for t in range(C):
                X[j, t] = X64[j, t]
        _features(X, 0, C, parent, var, Phi)
        _predict(M32, Phi, C, Q, Q, np.empty(0, np.float32), 0)
        chain_kinematics(Q, X, C, joints, body)
        for t in range(0, C, W8):  # (0 + dx0^2 + ... is dx0^2 + ...: the same bits)
            dx = vsub8(vload8f(X, 0, t), vload8(X64, 0, t))
            d2 = vmul8(dx, dx)
            for j in range(1, n):
                dx = vsub8(vload8f(X, j, t), vload8(X64, j, t))
                d2 = vadd8(d2, vmul8(dx, dx))
            vstore18(D, t, vsqrt8(d2))
        out[t0:t0 + N] = D[:N]
