"""Online Goal Babbling compiled (numba): train_reference's per-sample loop in float64, every sum
in a fixed order, no fastmath or fused multiply-adds, sin and cos simd.sincos64: the same on every
CPU, numpy's to rounding. M's rows are the lanes of simd's F64x8 (M transposed, padded); one pass
over M per sample does the step and the next prediction.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
from numba import njit

from ...features import exponents, monomial_tree
from ...inverse import NO_MOVEMENT
from ...kinematics import kernel_arrays, kernel_body
from ...simd import (
    W8, box, chain_forward64, fresh_cache, vadd8, vload8, vload18, vmul8, vsplat8, vstore8,
    vstore18, vsub8,
)

# the kernels hold simd.py's code: their caches go when it (or this folder) changes
fresh_cache(Path(__file__).parent)


@njit(cache=True)
def normals(rng, size):
    """rng.standard_normal(size) by numba's Generator: numpy's numbers and state, faster."""
    return rng.standard_normal(size)


def _kernel_arrays(body, params) -> tuple:
    """(chain, joints, parent, coord) for the kernels, once per body object and degree."""
    return kernel_arrays(body, ("f8", params.degree), lambda: kernel_body(body, np.float64)
                         + monomial_tree(exponents(body.n, params.degree), last=True))


@njit(cache=True)
def _saturate(q, normalized, saturates):
    if normalized and saturates:
        for i in range(len(q)):
            if q[i] > 1.0:
                q[i] = 1.0
            elif q[i] < -1.0:
                q[i] = -1.0


@njit(cache=True)
def _weight(lxs, lx, lq, xs, x, q):
    sxs = sx = sq = dot = 0.0
    for j in range(len(xs)):
        dxs, dx = xs[j] - lxs[j], x[j] - lx[j]
        sxs += dxs * dxs
        sx += dx * dx
        dot += dxs * dx
    for i in range(len(q)):
        dq = q[i] - lq[i]
        sq += dq * dq
    nxs, nx, nq = np.sqrt(sxs), np.sqrt(sx), np.sqrt(sq)
    denom = nxs * nx
    cos = dot / denom if denom > 0 else 0.0
    if cos > 1.0:
        cos = 1.0
    elif cos < -1.0:
        cos = -1.0
    w_dir = 0.5 * (1.0 + cos) if nxs > NO_MOVEMENT else 0.0
    w_eff = nx / nq if nq > 0 else 0.0
    return w_dir * w_eff


@njit(cache=True)
def _features_tree(x, parent, coord, phi):
    phi[0] = 1.0
    for k in range(1, len(phi)):
        phi[k] = phi[parent[k]] * x[coord[k]]


@njit(cache=True)
def _predict_rows(MT, phi, g):
    """g = M Phi from MT (p, W), over k in order."""
    p, W = MT.shape
    for j in range(0, W, W8):
        acc = vsplat8(0.0)
        for k in range(p):
            acc = vadd8(acc, vmul8(vload8(MT, k, j), vsplat8(phi[k])))
        vstore18(g, j, acc)


@njit(cache=True)
def _step_predict(MT, phi, sr, psi, g, predict):
    """M^T -= sr Phi^T (sr = eta w r) and, in the same pass, g = M_new Psi when `predict`:
    every operation in the order of a separate update and prediction."""
    p, W = MT.shape
    for j in range(0, W, W8):
        s = vload18(sr, j)
        acc = vsplat8(0.0)
        for k in range(p):
            v = vsub8(vload8(MT, k, j), vmul8(s, vsplat8(phi[k])))
            vstore8(MT, k, j, v)
            if predict:
                acc = vadd8(acc, vmul8(v, vsplat8(psi[k])))
        if predict:
            vstore18(g, j, acc)


@njit(cache=True)
def _train_block(MT, P, lxs, lx, lq, target, at_home, hops, coins, walk, sizes, scales, targets,
                 q_home, chain, joints, parent, coord, steps, radius, drift, keep,
                 home_probability, learning_rate):
    """train_reference's epochs, MT, P and the last sample in place; returns (target, at_home).
    Each epoch's plan comes first, so a step can compute the next prediction on its way."""
    p, W = MT.shape
    m = P.shape[0]
    n = targets.shape[1]
    N = targets.shape[0]
    K = hops.shape[1]
    normalized, saturates = joints[0], joints[1]
    phi, psi, r, sr, g = np.empty(p), np.empty(p), np.empty(W), np.zeros(W), np.empty(W)
    x_home, start = np.empty(n), np.empty(n)
    A, b = np.empty((m, n)), np.empty(m)
    x, q = np.empty(n), np.empty(m)
    xstar = np.empty((K * (steps + 1), n))
    home = np.zeros(K * (steps + 1), np.bool_)
    for e in range(len(sizes)):
        size, scale = sizes[e], scales[e]
        chain_forward64(q_home, scale, chain, joints, x_home)
        c, h = box(targets * size)  # the target box at this size
        T = 0  # the epoch's plan: x* of every sample, and which are returns home
        for kk in range(K):
            for j in range(n):
                start[j] = x_home[j] if at_home else targets[target, j] * size
            target = (target + hops[e, kk]) % N
            for l in range(1, steps + 1):
                frac = l / steps
                for j in range(n):
                    xstar[T, j] = start[j] + frac * (targets[target, j] * size - start[j])
                home[T] = False
                T += 1
            at_home = coins[e, kk] < home_probability
            if at_home:
                xstar[T] = x_home
                home[T] = True
                T += 1
        s = 0  # the path sample: its step of the random walk
        _features_tree(xstar[0], parent, coord, psi)  # the first sample is a path sample
        _predict_rows(MT, psi, g)
        for t in range(T):
            if home[t]:  # the home example, weight 1 (eq. 5)
                for j in range(n):
                    x[j] = x_home[j]
                for i in range(m):
                    q[i] = q_home[i]
                w = 1.0
            else:
                xs = xstar[t]
                # the perturbation: a random-walk step of P, each row scaled to peak at R
                for i in range(m):
                    for j in range(n + 1):
                        P[i, j] = keep * (P[i, j] + drift * walk[e, s, i, j])
                    Ac, Ah = 0.0, 0.0
                    for j in range(n):
                        Ac += P[i, j] * c[j]
                        Ah += abs(P[i, j]) * h[j]
                    k = radius / (abs(Ac + P[i, n]) + Ah)
                    for j in range(n):
                        A[i, j] = P[i, j] * k
                    b[i] = P[i, n] * k
                # the movement: q = saturate(g(x*) + A x* + b), x = f(q); g(x*) came with the
                # previous step (or before the first sample)
                for i in range(m):
                    Ax = 0.0
                    for j in range(n):
                        Ax += A[i, j] * xs[j]
                    q[i] = g[i] + Ax + b[i]
                _saturate(q, normalized, saturates)
                chain_forward64(q, scale, chain, joints, x)
                w = _weight(lxs, lx, lq, xs, x, q)
                s += 1
            _features_tree(x, parent, coord, phi)
            _predict_rows(MT, phi, r)  # the residual M Phi(x) - q, times eta w
            for i in range(m):
                sr[i] = (learning_rate * w) * (r[i] - q[i])
            nxt = t + 1 < T and not home[t + 1]
            if nxt:
                _features_tree(xstar[t + 1], parent, coord, psi)
            _step_predict(MT, phi, sr, psi, g, nxt)
            for j in range(n):
                lxs[j], lx[j] = xstar[t, j], x[j]
            for i in range(m):
                lq[i] = q[i]
    return target, at_home


def train_fast(state, params, body, sizes, scales, draws):
    hops, coins, walk = draws
    f8 = lambda x: np.array(x, dtype=np.float64, order="C")  # noqa: E731 (copies)
    m, p = state.M.shape
    MT = np.zeros((p, -(-m // W8) * W8))  # M^T, padded to whole vectors with zeros
    MT[:, :m] = state.M.T
    P = f8(state.P)
    lxs, lx, lq = (f8(a) for a in state.last)
    chain, joints, parent, coord = _kernel_arrays(body, params)
    target, at_home = _train_block(
        MT, P, lxs, lx, lq, int(state.target), bool(state.at_home),
        np.ascontiguousarray(hops, np.int64), np.ascontiguousarray(coins, np.float64),
        np.ascontiguousarray(walk, np.float64), np.ascontiguousarray(sizes, np.float64),
        np.ascontiguousarray(scales, np.float64).reshape(len(sizes), body.m),
        np.ascontiguousarray(body.targets, np.float64), f8(body.saturate(body.home)), chain,
        joints, parent, coord, int(params.steps), float(params.radius), float(params.drift),
        1.0 / np.sqrt(1.0 + params.drift ** 2), float(params.home_probability),
        float(params.learning_rate))
    return replace(state, M=np.ascontiguousarray(MT[:, :m].T), P=P, target=int(target),
                   at_home=bool(at_home), last=(lxs, lx, lq))


def distances(M, params, body, scale, xs) -> np.ndarray:
    chain, joints, parent, coord = _kernel_arrays(body, params)
    out = np.empty(len(xs))
    _distances(np.ascontiguousarray(M, np.float64), np.ascontiguousarray(xs, np.float64),
               np.ascontiguousarray(scale, np.float64).reshape(body.m), chain, joints, parent,
               coord, out)
    return out


@njit(cache=True)
def _distances(M, xs, scale, chain, joints, parent, coord, out):
    m, p = M.shape
    n = xs.shape[1]
    phi, q, x = np.empty(p), np.empty(m), np.empty(n)
    for t in range(len(xs)):
        _features_tree(xs[t], parent, coord, phi)
        for i in range(m):
            g = 0.0
            for k in range(p):
                g += M[i, k] * phi[k]
            q[i] = g
        _saturate(q, joints[0], joints[1])
        chain_forward64(q, scale, chain, joints, x)
        d = 0.0
        for j in range(n):
            d += (x[j] - xs[t, j]) ** 2
        out[t] = np.sqrt(d)
