"""The fast path: whole blocks of Goal Babbling epochs in one compiled (numba) call.

It computes what `gbmodel.learner` states, epoch by epoch and with the same random numbers, in
flat loops over all N = V * (T + 1) samples of an epoch that the compiler vectorises:

- samples are laid out variation-major, row 0 of each variation the home example, so that the
  weight of a sample only looks at the row before it;
- the rollout runs in float32 (twice the SIMD width of float64); the inverse estimate M and the
  gradient sums across blocks of samples stay float64. Positions agree with the float64
  reference to ~1e-6 m (tests/test_fast.py states the tolerances);
- the hand is carried backwards through the DH chain, one rotation about z per joint, from
  separate input and output arrays (an in-place update of three arrays defeats the compiler's
  alias analysis and leaves the loop scalar);
- sin and cos are a branch-free polynomial (fdlibm's kernels after a Cody-Waite reduction), which
  vectorises where libm's sinf/cosf would be one scalar call per element;
- features are built monomial by monomial, each a parent monomial times one coordinate;
- the gradient sum_t w (M Phi - q) Phi^T is accumulated block by block in L1-sized chunks.
Results are bit-identical from run to run on one machine (no threads, fixed loop order).
"""
from __future__ import annotations

import numba
import numpy as np
from numba import njit

from .learner import NO_MOVEMENT


def _prefer_wide_vectors():
    """Let LLVM use full 512-bit vectors where the CPU has them.

    LLVM tunes AVX-512 CPUs to prefer 256-bit vectors; these loops are long, regular and float32
    and run ~1.8x faster on 16 lanes (measured by `python -m pipeline.bench`). This sets numba's
    CPU features for the process, before anything is compiled, and only if nobody else has.
    """
    import llvmlite.binding as ll

    if numba.config.CPU_FEATURES is None:
        features = ll.get_host_cpu_features().flatten()
        if "+avx512f" in features.split(","):
            numba.config.CPU_FEATURES = features + ",-prefer-256-bit"


_prefer_wide_vectors()

F4 = np.float32
_FLAGS = {"nsz", "arcp", "contract", "reassoc"}  # no NaN/inf assumptions: divergence stays visible
_BLOCK = 256  # samples per gradient block: R and a feature row of a block stay in L1

_0, _HALF, _1, _2, _QUARTER, _4 = F4(0.0), F4(0.5), F4(1.0), F4(2.0), F4(0.25), F4(4.0)
# fdlibm's kernel coefficients for sin and cos on [-pi/4, pi/4], to float precision
_S1, _S2 = F4(-1.66666666666666324348e-01), F4(8.33333333332248946124e-03)
_S3, _S4 = F4(-1.98412698298579493134e-04), F4(2.75573137070700676789e-06)
_C1, _C2 = F4(4.16666666666666019037e-02), F4(-1.38888888888741095749e-03)
_C3, _C4 = F4(2.48015872894767294178e-05), F4(-2.75573143513906633035e-07)
_TWO_OVER_PI = F4(6.36619772367581382433e-01)
_PIO2_HI, _PIO2_LO = F4(1.5707963705062866), F4(-4.371139000186243e-08)  # pi/2 = HI + LO


@njit(fastmath=_FLAGS, inline="always", cache=True)
def sincos(x):
    """(sin x, cos x) of a float32, within 2e-6 for |x| < 10 (joint angles), branch-free."""
    k = np.floor(x * _TWO_OVER_PI + _HALF)
    r = (x - k * _PIO2_HI) - k * _PIO2_LO
    z = r * r
    s = r + r * z * (_S1 + z * (_S2 + z * (_S3 + z * _S4)))
    c = _1 - _HALF * z + z * z * (_C1 + z * (_C2 + z * (_C3 + z * _C4)))
    # quadrant 0..3: swap sin and cos in odd quadrants, then fix the signs, all by arithmetic
    quadrant = k - _4 * np.floor(_QUARTER * k)
    odd = quadrant - _2 * np.floor(_HALF * quadrant)
    upper = np.floor(_HALF * quadrant)  # quadrants 2, 3
    sn = (s + odd * (c - s)) * (_1 - _2 * upper)
    cs = (c + odd * (s - c)) * (_1 - _2 * np.abs(odd - upper))
    return sn, cs


@njit(fastmath=_FLAGS, cache=True)
def _angles(Q, joints, theta):
    """Saturate commands Q (m, N) in place (if the body does) and turn them into DH joint
    angles theta (m, N): theta = offset + lo + (q + 1) / 2 * span, or offset + q."""
    normalized, saturates, q_lo, q_span, offset = joints
    for i in range(Q.shape[0]):
        qi, ti = Q[i], theta[i]
        if normalized:
            lo, span, off = q_lo[i], q_span[i], offset[i]
            if saturates:
                for r in range(len(qi)):
                    qi[r] = min(max(qi[r], -_1), _1)
            for r in range(len(qi)):
                ti[r] = off + lo + _HALF * (qi[r] + _1) * span
        else:
            off = offset[i]
            for r in range(len(qi)):
                ti[r] = off + qi[r]


@njit(fastmath=_FLAGS, cache=True)
def _joint(theta, a, d, ca, sa, px, py, pz, qx, qy, qz):
    """(qx, qy, qz) = A_i (px, py, pz) for one joint over all samples."""
    for r in range(len(theta)):
        u = px[r] + a
        v = ca * py[r] - sa * pz[r]
        w = sa * py[r] + ca * pz[r] + d
        s, c = sincos(theta[r])
        qx[r] = c * u - s * v
        qy[r] = s * u + c * v
        qz[r] = w


@njit(fastmath=_FLAGS, cache=True)
def _forward(theta, body, X, P0, P1):
    """Hand positions X (n, N) of joint angles theta (m, N); P0, P1 are (3, N) work arrays."""
    a, d, ca, sa, base, outputs = body
    P0[:] = _0
    for i in range(theta.shape[0] - 1, -1, -1):
        _joint(theta[i], a[i], d[i], ca[i], sa[i], P0[0], P0[1], P0[2], P1[0], P1[1], P1[2])
        P0, P1 = P1, P0
    for j in range(len(outputs)):
        o = outputs[j]
        b0, b1, b2, b3 = base[o, 0], base[o, 1], base[o, 2], base[o, 3]
        xj, p0, p1, p2 = X[j], P0[0], P0[1], P0[2]
        for r in range(len(xj)):
            xj[r] = b0 * p0[r] + b1 * p1[r] + b2 * p2[r] + b3


@njit(fastmath=_FLAGS, cache=True)
def _features(X, parent, var, Phi):
    """Phi (p, N) of X (n, N): monomial k = monomial parent[k] * x[var[k]], the constant first."""
    Phi[0, :] = _1
    for k in range(1, Phi.shape[0]):
        src, x, dst = Phi[parent[k]], X[var[k]], Phi[k]
        for r in range(len(dst)):
            dst[r] = src[r] * x[r]


@njit(fastmath=_FLAGS, cache=True)
def _matmul(M, Phi, out):
    """out (m, N) = M (m, p) Phi (p, N), float32."""
    for i in range(M.shape[0]):
        oi = out[i]
        oi[:] = _0
        for k in range(M.shape[1]):
            mik, pk = M[i, k], Phi[k]
            for r in range(len(oi)):
                oi[r] += mik * pk[r]


@njit(fastmath=_FLAGS, cache=True)
def _weights(path, X, Q, V, w):
    """w_dir * w_eff (eq. 1-3) of every row against the row before; home rows weigh 1 (eq. 5).

    The intended steps are the same for every variation; the first starts at the home position.
    Returns sum w (float64).
    """
    n, T = path.shape
    m = Q.shape[0]
    no_move2 = F4(NO_MOVEMENT * NO_MOVEMENT)
    dxs = np.empty((n, T), np.float32)
    nxs, dot = np.empty(T, np.float32), np.empty(T, np.float32)
    nx, nq = np.empty(T, np.float32), np.empty(T, np.float32)
    for j in range(n):
        dxs[j, 0] = path[j, 0] - X[j, 0]
        for t in range(1, T):
            dxs[j, t] = path[j, t] - path[j, t - 1]
    nxs[:] = _0
    for j in range(n):
        for t in range(T):
            nxs[t] += dxs[j, t] * dxs[j, t]
    wsum = 0.0
    for v in range(V):
        r0 = v * (T + 1)
        w[r0] = _1
        dot[:] = _0
        nx[:] = _0
        nq[:] = _0
        for j in range(n):
            xj, dj = X[j, r0:r0 + T + 1], dxs[j]
            for t in range(T):
                dx = xj[t + 1] - xj[t]
                dot[t] += dj[t] * dx
                nx[t] += dx * dx
        for i in range(m):
            qi = Q[i, r0:r0 + T + 1]
            for t in range(T):
                dq = qi[t + 1] - qi[t]
                nq[t] += dq * dq
        wv = w[r0 + 1:r0 + T + 1]
        for t in range(T):
            den = np.sqrt(nxs[t] * nx[t])
            cos = dot[t] / den if den > _0 else _0
            w_dir = _HALF * (_1 + min(max(cos, -_1), _1)) if nxs[t] > no_move2 else _0
            w_eff = np.sqrt(nx[t] / nq[t]) if nq[t] > _0 else _0
            wv[t] = w_dir * w_eff
    for r in range(len(w)):
        wsum += w[r]
    return wsum


@njit(fastmath=_FLAGS, cache=True)
def _gradient(M32, Phi, Q, w, G):
    """G (m, p) = sum_r w_r (M Phi_r - q_r) Phi_r^T: float32 within blocks, float64 across.

    Four feature rows are taken per pass over a block, so that each load of the residual
    feeds four multiply-adds (the loops are bound by loads, not by arithmetic).
    """
    m, p = M32.shape
    N = Q.shape[1]
    p4 = p - p % 4
    R = np.empty(_BLOCK, np.float32)
    G[:] = 0.0
    for b0 in range(0, N, _BLOCK):
        b1 = min(b0 + _BLOCK, N)
        nb = b1 - b0
        wb = w[b0:b1]
        for i in range(m):
            qi = Q[i, b0:b1]
            for r in range(nb):
                R[r] = -qi[r]
            for k in range(0, p4, 4):
                m0, m1, m2, m3 = M32[i, k], M32[i, k + 1], M32[i, k + 2], M32[i, k + 3]
                f0, f1 = Phi[k, b0:b1], Phi[k + 1, b0:b1]
                f2, f3 = Phi[k + 2, b0:b1], Phi[k + 3, b0:b1]
                for r in range(nb):
                    R[r] += m0 * f0[r] + m1 * f1[r] + m2 * f2[r] + m3 * f3[r]
            for k in range(p4, p):
                mk, fk = M32[i, k], Phi[k, b0:b1]
                for r in range(nb):
                    R[r] += mk * fk[r]
            for r in range(nb):
                R[r] *= wb[r]
            for k in range(0, p4, 4):
                f0, f1 = Phi[k, b0:b1], Phi[k + 1, b0:b1]
                f2, f3 = Phi[k + 2, b0:b1], Phi[k + 3, b0:b1]
                a0, a1, a2, a3 = _0, _0, _0, _0
                for r in range(nb):
                    x = R[r]
                    a0 += x * f0[r]
                    a1 += x * f1[r]
                    a2 += x * f2[r]
                    a3 += x * f3[r]
                G[i, k] += a0
                G[i, k + 1] += a1
                G[i, k + 2] += a2
                G[i, k + 3] += a3
            for k in range(p4, p):
                fk = Phi[k, b0:b1]
                acc = _0
                for r in range(nb):
                    acc += R[r] * fk[r]
                G[i, k] += acc


@njit(fastmath=_FLAGS, cache=True)
def _disturbances(raw, s, centre, half, radius, A, b):
    """Eq. 8: rows of [A | b] scaled so that max |A_i x + b_i| = radius over the target box."""
    m, n = A.shape
    for i in range(m):
        at_centre = raw[i, n]
        spread = 0.0
        for j in range(n):
            at_centre += raw[i, j] * s * centre[j]
            spread += abs(raw[i, j]) * s * half[j]
        k_i = radius / (abs(at_centre) + spread)
        for j in range(n):
            A[i, j] = raw[i, j] * k_i
        b[i] = raw[i, n] * k_i


@njit(fastmath=_FLAGS, cache=True)
def _epoch(M, idx, raw, s, body, targets, home, parent, var, joints, radius, steps,
           learning_rate, work):
    """One epoch (see gbmodel.learner.epoch): rolls out, weights, updates M in place.

    Leaves the samples in work: Q (m, N) postures, X (n, N) reached positions, w (N) weights.
    """
    Q, theta, X, Phi, P0, P1, w, path, Phip, gpath, M32, G = work
    m, p = M.shape
    n = targets.shape[1]
    V = raw.shape[0]
    T = path.shape[1]
    s4 = F4(s)
    # target path (eq. 9) at the current size, and g along it
    for k in range(len(idx) - 1):
        t0, t1 = idx[k], idx[k + 1]
        for l in range(steps):
            f = F4(l) / F4(steps)
            for j in range(n):
                path[j, k * steps + l] = s4 * ((_1 - f) * targets[t0, j] + f * targets[t1, j])
    for i in range(m):
        for k in range(p):
            M32[i, k] = M[i, k]
    _features(path, parent, var, Phip)
    _matmul(M32, Phip, gpath)
    # commands of all variations, variation-major; row v * (T + 1) is the home example
    centre = np.empty(n)
    half = np.empty(n)
    for j in range(n):
        lo, hi = targets[:, j].min(), targets[:, j].max()
        centre[j], half[j] = 0.5 * (lo + hi), 0.5 * (hi - lo)
    A = np.empty((m, n))
    b = np.empty(m)
    for v in range(V):
        _disturbances(raw[v], s, centre, half, radius, A, b)
        r0 = v * (T + 1)
        for i in range(m):
            Q[i, r0] = home[i]
            qi, gi, bi = Q[i, r0 + 1:r0 + 1 + T], gpath[i], F4(b[i])
            for t in range(T):
                qi[t] = gi[t] + bi
            for j in range(n):
                aij, pj = F4(A[i, j]), path[j]
                for t in range(T):
                    qi[t] += aij * pj[t]
    _angles(Q, joints, theta)
    _forward(theta, body, X, P0, P1)
    wsum = _weights(path, X, Q, V, w)
    # one normalised gradient step on the weighted command error (eq. 6)
    _features(X, parent, var, Phi)
    _gradient(M32, Phi, Q, w, G)
    step = learning_rate / wsum
    for i in range(m):
        for k in range(p):
            M[i, k] -= step * G[i, k]


@njit(fastmath=_FLAGS, cache=True)
def _evaluate(M, s, body, targets, parent, var, joints, work):
    """Mean distance between every target (at size s) and the hand under g (float64 sum)."""
    X, Phi, Q, theta, P0, P1, M32 = work
    NT, n = targets.shape
    s4 = F4(s)
    for i in range(M.shape[0]):
        for k in range(M.shape[1]):
            M32[i, k] = M[i, k]
    for t in range(NT):
        for j in range(n):
            X[j, t] = s4 * targets[t, j]
    _features(X, parent, var, Phi)
    _matmul(M32, Phi, Q)
    _angles(Q, joints, theta)
    _forward(theta, body, X, P0, P1)
    total = 0.0
    for t in range(NT):
        d2 = 0.0
        for j in range(n):
            dx = float(X[j, t]) - s * float(targets[t, j])
            d2 += dx * dx
        total += np.sqrt(d2)
    return total / NT


@njit(cache=True)
def _work(m, n, p, V, T, NT):
    """Work arrays of one epoch (N = V (T + 1) samples) and of one evaluation (NT targets)."""
    N = V * (T + 1)
    f4 = np.float32
    epoch = (np.empty((m, N), f4), np.empty((m, N), f4), np.empty((n, N), f4),
             np.empty((p, N), f4), np.empty((3, N), f4), np.empty((3, N), f4), np.empty(N, f4),
             np.empty((n, T), f4), np.empty((p, T), f4), np.empty((m, T), f4),
             np.empty((m, p), f4), np.empty((m, p)))
    evaluation = (np.empty((n, NT), f4), np.empty((p, NT), f4), np.empty((m, NT), f4),
                  np.empty((m, NT), f4), np.empty((3, NT), f4), np.empty((3, NT), f4),
                  np.empty((m, p), f4))
    return epoch, evaluation


@njit(fastmath=_FLAGS, cache=True)
def _block(M, idx, raw, sizes, scales, is_eval, abs_out, chain, targets, home, parent, var,
           joints, radius, steps, learning_rate):
    """Epochs e = 0 ... B-1 with sizes[e] and per-joint length factors scales[e]."""
    a, d, ca, sa, base, outputs = chain
    m, p = M.shape
    n = targets.shape[1]
    T = (idx.shape[1] - 1) * steps
    work, ework = _work(m, n, p, raw.shape[1], T, targets.shape[0])
    ae = np.empty(m, np.float32)
    de = np.empty(m, np.float32)
    for e in range(idx.shape[0]):
        for i in range(m):
            ae[i] = a[i] * scales[e, i]
            de[i] = d[i] * scales[e, i]
        body = (ae, de, ca, sa, base, outputs)
        _epoch(M, idx[e], raw[e], sizes[e], body, targets, home, parent, var, joints, radius,
               steps, learning_rate, work)
        if is_eval[e]:
            abs_out[e] = _evaluate(M, sizes[e], body, targets, parent, var, joints, ework)


def monomial_tree(exps: np.ndarray):
    """parent[k], var[k] with exps[k] = exps[parent[k]] + unit(var[k]) (parent[0] = var[0] = 0)."""
    rows = {tuple(e): k for k, e in enumerate(exps)}
    parent = np.zeros(len(exps), np.int64)
    var = np.zeros(len(exps), np.int64)
    for k, e in enumerate(exps[1:], start=1):
        j = int(np.flatnonzero(e)[0])
        lower = e.copy()
        lower[j] -= 1
        parent[k], var[k] = rows[tuple(lower)], j
    return parent, var


def _arrays(body, exps):
    """The body as the kernels take it: float32 chain and joint map, plus the monomial tree."""
    f4 = lambda x: np.ascontiguousarray(x, np.float32)  # noqa: E731
    chain = body.chain(1.0)
    normalized = body.normalized
    joints = (normalized, body.saturates,
              f4(body.q_min if normalized else np.zeros(body.m)),
              f4(body.q_max - body.q_min if normalized else np.ones(body.m)),
              f4(body.theta_offset))
    parent, var = monomial_tree(exps)
    return dict(
        chain=(f4(chain["a"]), f4(chain["d"]), f4(chain["cos_alpha"]), f4(chain["sin_alpha"]),
               f4(body.base), np.array(body.outputs, np.int64)),
        targets=f4(body.targets), home=f4(body.saturate(body.home)), parent=parent, var=var,
        joints=joints,
    )


def run_block(M, body, spec, exps, sizes, idx, raw, is_eval, abs_out):
    """Epochs with sizes `sizes` and draws idx, raw; fills abs_out where is_eval. Returns M."""
    M = np.array(M, dtype=np.float64, order="C")
    scales = body.segment_scale(sizes, spec.pattern).astype(np.float32)
    _block(M, np.ascontiguousarray(idx, np.int64), np.ascontiguousarray(raw, np.float64),
           np.ascontiguousarray(sizes, np.float64), scales.reshape(len(sizes), body.m),
           np.ascontiguousarray(is_eval), abs_out, radius=float(spec.radius),
           steps=int(spec.steps), learning_rate=float(spec.learning_rate), **_arrays(body, exps))
    return M


def epoch_samples(M, body, spec, exps, size, idx, raw):
    """One epoch on the fast path, for tests: returns (M after, Q, X, w) with the samples laid
    out as (V, T + 1, ...) like gbmodel.learner.epoch's."""
    M = np.array(M, dtype=np.float64, order="C")
    arr = _arrays(body, exps)
    a, d, ca, sa, base, outputs = arr["chain"]
    k = body.segment_scale(size, spec.pattern).astype(np.float32)
    chain = (a * k, d * k, ca, sa, base, outputs)
    T = (len(idx) - 1) * spec.steps
    V = raw.shape[0]
    work, _ = _work(body.m, body.n, len(exps), V, T, len(body.targets))
    _epoch(M, np.asarray(idx, np.int64), np.ascontiguousarray(raw, np.float64), float(size),
           chain, arr["targets"], arr["home"], arr["parent"], arr["var"], arr["joints"],
           float(spec.radius), int(spec.steps), float(spec.learning_rate), work)
    Q, X, w = work[0], work[2], work[6]
    return M, Q.T.reshape(V, T + 1, -1), X.T.reshape(V, T + 1, -1), w.reshape(V, T + 1)
