"""Online Goal Babbling, after Rolf, Steil & Gienger 2011 ("Online goal babbling for rapid
bootstrapping of inverse models in high dimensions"): one continuous movement, learned sample by
sample.

Taken from the 2011 paper (as we read it, and as the IRP group's open implementation `pygb`
realises it):
- a single continuous stream of goal-directed movements instead of V rollouts per epoch: the
  target moves along straight paths between targets drawn from the target set, and the path, the
  perturbation and the last sample carry over from epoch to epoch;
- the exploratory perturbation E_t(x) = A_t x + b_t drifts slowly: per sample, its parameters
  take a random-walk step that keeps their spread, P <- (P + drift xi) / sqrt(1 + drift^2),
  xi ~ N(0, 1), so that the entries of P = [A | b] stay N(0, 1)-distributed;
- one gradient step per sample on that sample's weighted error, w_t (g(x_t) - q_t)^2, weights
  w_dir * w_eff (eq. 1-3 of the 2010 paper) against the previous sample;
- after a target, a return to home with probability `home_probability`.

Chosen here:
- the paths are the 2010 paper's (eq. 9): L linear steps to each next target, the last one on it,
  the next target uniform over the other targets; an epoch is K targets, K L path samples;
- the perturbation's amplitude is the 2010 paper's (eq. 8): each row of [A | b] scaled so that
  max |E_i(x)| over the target box is exactly R (gbmodel.learners.goal_babbling.reference), so
  that R means what it means for Goal Babbling;
- a return home is one sample, the home example (q_home, x_home) with weight 1 (eq. 5 of 2010),
  and the next path starts at x_home (2011 moves home through joint space);
- the inverse estimate is Goal Babbling's polynomial (eq. 7), initialised the same way, and the
  step is plain per-sample gradient descent, M <- M - eta w_t (M Phi(x_t) - q_t) Phi(x_t)^T
  (2011 learns a local-linear map);
- samples per epoch: K L plus the returns home, K home_probability in expectation.

Two paths compute the same thing with the same draws (all random numbers come from `draw`):
`train_reference` below, plain numpy, is the readable statement; `_train_block`, the same
per-sample loop compiled with numba in float64 (no fastmath: every sum in a fixed order, so the
result does not depend on the CPU's vector width), is what runs by default. They agree to
rounding (tests/test_learners.py). `Params.fast` picks the path.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numba import njit

from ..features import exponents, features
from ..growth import SpecError, check_int, check_number
from .goal_babbling.reference import (NO_MOVEMENT, init_inverse, predict as predict_inverse,
                                      sample_weights, scale_perturbations)


@dataclass(frozen=True)
class Params:
    targets_per_epoch: int = 15  # K
    steps: int = 7  # L, linear steps to each next target (eq. 9)
    radius: float = 0.2  # R, max |E_i(x)| over the target box (eq. 8)
    # random-walk step of the perturbation's parameters per sample, relative to their spread:
    # 0.3 keeps a perturbation for about 23 samples (1 / ln sqrt(1 + drift^2)), 3 targets. On
    # arm5 (eta 0.1, seed 0), error after 500 epochs: drift 0.02 -> 102 mm, 0.1 -> 109,
    # 0.3 -> 35, 0.5 -> 26 mm: a perturbation held too long is learned as if it were the body
    drift: float = 0.3
    home_probability: float = 0.1  # chance of a return home after each target
    # eta of the per-sample step; on arm5 (drift 0.3, 500 epochs) 0.05 -> 38 mm, 0.1 -> 35 mm,
    # 0.2 -> 42 mm wavering 32-89 mm. The iCub's weights are smaller (normalised commands):
    # there 0.3 learns faster (40 epochs: 0.1 -> 0.12 m, 0.3 -> 0.081 m, 1.0 -> 0.087 m; 3.0
    # runs into the joint limits, 0.51 m)
    learning_rate: float = 0.1
    init_range: float = 0.1  # |g(x) - home| bound at initialisation (as Goal Babbling)
    degree: int = 3
    fast: bool = True  # the compiled per-sample loop (_train_block); False: the numpy reference

    def validate(self) -> "Params":
        for name in ("targets_per_epoch", "steps", "degree"):
            check_int(f"learner.{name}", getattr(self, name), 1)
        for name in ("radius", "drift", "init_range"):
            check_number(f"learner.{name}", getattr(self, name), 0.0)
        check_number("learner.learning_rate", self.learning_rate, 0.0, strict=True)
        check_number("learner.home_probability", self.home_probability, 0.0)
        if self.home_probability > 1:
            raise SpecError("learner.home_probability", self.home_probability, "must be <= 1")
        if not isinstance(self.fast, bool):
            raise SpecError("learner.fast", self.fast, "must be true or false")
        return self


@dataclass(frozen=True)
class State:
    M: np.ndarray  # (m, p) the inverse estimate
    P: np.ndarray  # (m, n + 1) the perturbation's raw parameters [A | b]
    target: int  # index of the target last reached
    at_home: bool  # the last movement returned home: the next path starts at x_home
    last: tuple  # (x*, x, q) of the last sample, the predecessor of the next one's weight


def _exps(params, body):
    return exponents(body.n, params.degree)


def init(params: Params, body, size: float, rng: np.random.Generator) -> State:
    """Goal Babbling's initial M, a random perturbation, the body at home."""
    M = init_inverse(body.home, *body.target_box(size), _exps(params, body), params.init_range,
                     rng)
    P = rng.standard_normal((body.m, body.n + 1))
    q_home = body.saturate(body.home)
    x_home = body.forward(q_home, size=size)
    return State(M, P, target=0, at_home=True, last=(x_home, x_home, q_home))


def draw(params: Params, body, B: int, rng: np.random.Generator) -> tuple:
    """Per epoch: hops to the next targets (B, K) in 1 ... N-1 (so each differs from the last),
    home coins (B, K) in [0, 1), random-walk steps (B, K L, m, n+1)."""
    K = params.targets_per_epoch
    hops = rng.integers(1, len(body.targets), size=(B, K))
    coins = rng.uniform(0.0, 1.0, size=(B, K))
    walk = rng.standard_normal((B, K * params.steps, body.m, body.n + 1))
    return hops, coins, walk


def plan(state: State, params: Params, targets, x_home, hops, coins):
    """The epoch's intended positions x* (T, n), which of them are returns home (T,), and the
    state's target and at_home after it."""
    L = params.steps
    target, at_home, xs, home = state.target, state.at_home, [], []
    for hop, coin in zip(hops, coins):
        start = x_home if at_home else targets[target]
        target = (target + hop) % len(targets)
        frac = np.arange(1, L + 1)[:, None] / L
        xs.append(start + frac * (targets[target] - start))
        home += [False] * L
        at_home = coin < params.home_probability
        if at_home:
            xs.append(x_home[None])
            home.append(True)
    return np.concatenate(xs), np.array(home), target, at_home


def perturbations(P, walk, params: Params, lo, hi):
    """The perturbation of every path sample: A (T, m, n), b (T, m), and P after the walk."""
    keep = 1.0 / np.sqrt(1.0 + params.drift ** 2)
    raw = np.empty_like(walk)
    for t, step in enumerate(walk):
        P = keep * (P + params.drift * step)
        raw[t] = P
    A, b = scale_perturbations(raw, lo, hi, params.radius)
    return A, b, P


def train(state: State, params: Params, body, sizes, scales, draws, epochs=None) -> State:
    if params.fast:
        return train_fast(state, params, body, sizes, scales, draws)
    return train_reference(state, params, body, sizes, scales, draws)


def train_reference(state: State, params: Params, body, sizes, scales, draws) -> State:
    """The epochs in plain numpy, sample by sample: the readable statement of `train`."""
    hops, coins, walk = draws
    exps = _exps(params, body)
    M, P = state.M.copy(), state.P
    for e in range(len(sizes)):
        q_home = body.saturate(body.home)
        x_home = body.forward(q_home, scale=scales[e])
        xstar, home, target, at_home = plan(state, params, body.target_set(sizes[e]), x_home,
                                            hops[e], coins[e])
        A, b, P = perturbations(P, walk[e], params, *body.target_box(sizes[e]))
        last, j = state.last, 0  # j: the next path sample's perturbation
        for xs, is_home in zip(xstar, home):
            if is_home:  # the home example, weight 1 (eq. 5)
                x, q, w = x_home, q_home, 1.0
            else:
                q = body.saturate(predict_inverse(M, xs, exps) + A[j] @ xs + b[j])
                x = body.forward(q, scale=scales[e])
                w = sample_weights(*(np.stack([a, c]) for a, c in zip(last, (xs, x, q))))[1]
                j += 1
            phi = features(x, exps)
            M -= (params.learning_rate * w) * np.outer(M @ phi - q, phi)
            last = (xs, x, q)
        state = State(M, P, target, at_home, last)
    return replace(state, M=M.copy())


# ---- the fast path: the same per-sample loop, compiled ------------------------------------------
# Plain float64, sequential: every sum runs in a fixed order (first term first), nothing is
# compiled with fastmath (no reassociation, no fused multiply-adds), so the results do not depend
# on the CPU's vector width; sin and cos are the C library's. They differ from the numpy path's
# only by rounding, where numpy (or its BLAS) sums in another order or calls its own sin and cos.
def _body_arrays(body) -> tuple:
    """The body as the kernel takes it, float64: the full-size chain (a, d, cos alpha, sin
    alpha, base, outputs) and the joint map (normalized, saturates, q_min, q_max - q_min,
    theta_offset)."""
    f8 = lambda x: np.ascontiguousarray(x, np.float64)  # noqa: E731
    full = body.chain(1.0)  # the kernel scales a and d epoch by epoch
    chain = tuple(f8(full[k]) for k in ("a", "d", "cos_alpha", "sin_alpha", "base")) \
        + (np.array(body.outputs, np.int64),)
    normalized, zeros = body.normalized, np.zeros(body.m)
    joints = (normalized, bool(body.saturates), f8(body.q_min if normalized else zeros),
              f8(body.q_max - body.q_min if normalized else zeros), f8(body.theta_offset))
    return chain, joints


@njit(cache=True)
def _saturate(q, normalized, saturates):
    """body.saturate in place: clip to [-1, 1] (a NaN stays NaN)."""
    if normalized and saturates:
        for i in range(len(q)):
            if q[i] > 1.0:
                q[i] = 1.0
            elif q[i] < -1.0:
                q[i] = -1.0


@njit(cache=True)
def _forward(q, scale, chain, joints, out):
    """body.forward(q, scale=scale) into out (n,): the hand point carried backwards through the
    DH chain (gbmodel.kinematics.hand_position), operation by operation."""
    a, d, ca, sa, base, outputs = chain
    normalized, _, q_min, q_span, offset = joints
    px = py = pz = 0.0
    for i in range(len(q) - 1, -1, -1):
        if normalized:
            theta = q_min[i] + 0.5 * (q[i] + 1.0) * q_span[i]
        else:
            theta = q[i]
        theta = theta + offset[i]
        u = px + a[i] * scale[i]
        v = ca[i] * py - sa[i] * pz
        w = sa[i] * py + ca[i] * pz + d[i] * scale[i]
        c, s = np.cos(theta), np.sin(theta)
        px, py, pz = c * u - s * v, s * u + c * v, w
    for j in range(len(outputs)):
        o = outputs[j]
        out[j] = px * base[o, 0] + py * base[o, 1] + pz * base[o, 2] + base[o, 3]


@njit(cache=True)
def _features(x, exps, phi):
    """features(x, exps) into phi (p,): each monomial by repeated multiplication, coordinate by
    coordinate (gbmodel.features._monomials' order)."""
    for k in range(exps.shape[0]):
        v = 1.0
        for j in range(exps.shape[1]):
            for _ in range(exps[k, j]):
                v = v * x[j]
        phi[k] = v


@njit(cache=True)
def _weight(lxs, lx, lq, xs, x, q):
    """sample_weights(...)[1]: w_dir * w_eff of sample (xs, x, q) against its predecessor."""
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
def _step(M, x, q, w, learning_rate, exps, phi, r):
    """M <- M - (eta w) (M Phi(x) - q) Phi(x)^T, in place."""
    _features(x, exps, phi)
    m, p = M.shape
    for i in range(m):
        acc = 0.0
        for k in range(p):
            acc += M[i, k] * phi[k]
        r[i] = acc - q[i]
    s = learning_rate * w
    for i in range(m):
        for k in range(p):
            M[i, k] -= s * (r[i] * phi[k])


@njit(cache=True)
def _train_block(M, P, lxs, lx, lq, target, at_home, hops, coins, walk, sizes, scales, targets,
                 q_home, chain, joints, exps, steps, radius, drift, keep, home_probability,
                 learning_rate):
    """train_reference's epochs: M, P and the last sample (lxs, lx, lq) updated in place;
    returns the target last reached and whether the last movement returned home."""
    m, p = M.shape
    n = targets.shape[1]
    N = targets.shape[0]
    normalized, saturates = joints[0], joints[1]
    phi, r = np.empty(p), np.empty(m)
    x_home, start, goal = np.empty(n), np.empty(n), np.empty(n)
    lo, hi, c, h = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    A, b = np.empty((m, n)), np.empty(m)
    xs, x, q = np.empty(n), np.empty(n), np.empty(m)
    for e in range(len(sizes)):
        size, scale = sizes[e], scales[e]
        _forward(q_home, scale, chain, joints, x_home)
        for j in range(n):  # the target box at this size
            lo[j] = hi[j] = targets[0, j] * size
            for t in range(1, N):
                v = targets[t, j] * size
                lo[j] = min(lo[j], v)
                hi[j] = max(hi[j], v)
            c[j], h[j] = 0.5 * (lo[j] + hi[j]), 0.5 * (hi[j] - lo[j])
        s = 0  # the path sample: its step of the random walk
        for kk in range(hops.shape[1]):
            for j in range(n):
                start[j] = x_home[j] if at_home else targets[target, j] * size
            target = (target + hops[e, kk]) % N
            for j in range(n):
                goal[j] = targets[target, j] * size
            for l in range(1, steps + 1):
                frac = l / steps
                for j in range(n):
                    xs[j] = start[j] + frac * (goal[j] - start[j])
                # the perturbation: a random-walk step of P, each row scaled to peak at R
                for i in range(m):
                    for j in range(n + 1):
                        P[i, j] = keep * (P[i, j] + drift * walk[e, s, i, j])
                for i in range(m):
                    Ac, Ah = 0.0, 0.0
                    for j in range(n):
                        Ac += P[i, j] * c[j]
                        Ah += abs(P[i, j]) * h[j]
                    k = radius / (abs(Ac + P[i, n]) + Ah)
                    for j in range(n):
                        A[i, j] = P[i, j] * k
                    b[i] = P[i, n] * k
                # the movement: q = saturate(g(x*) + A x* + b), x = f(q)
                _features(xs, exps, phi)
                for i in range(m):
                    g, Ax = 0.0, 0.0
                    for kf in range(p):
                        g += phi[kf] * M[i, kf]
                    for j in range(n):
                        Ax += A[i, j] * xs[j]
                    q[i] = g + Ax + b[i]
                _saturate(q, normalized, saturates)
                _forward(q, scale, chain, joints, x)
                w = _weight(lxs, lx, lq, xs, x, q)
                _step(M, x, q, w, learning_rate, exps, phi, r)
                lxs[:], lx[:], lq[:] = xs, x, q
                s += 1
            at_home = coins[e, kk] < home_probability
            if at_home:  # the home example, weight 1 (eq. 5)
                _step(M, x_home, q_home, 1.0, learning_rate, exps, phi, r)
                lxs[:], lx[:], lq[:] = x_home, x_home, q_home
    return target, at_home


def train_fast(state: State, params: Params, body, sizes, scales, draws) -> State:
    """train on the compiled path: the same epochs, with the same draws, as train_reference."""
    hops, coins, walk = draws
    f8 = lambda x: np.array(x, dtype=np.float64, order="C")  # noqa: E731 (copies)
    M, P = f8(state.M), f8(state.P)
    lxs, lx, lq = (f8(a) for a in state.last)
    chain, joints = _body_arrays(body)
    target, at_home = _train_block(
        M, P, lxs, lx, lq, int(state.target), bool(state.at_home),
        np.ascontiguousarray(hops, np.int64), np.ascontiguousarray(coins, np.float64),
        np.ascontiguousarray(walk, np.float64), np.ascontiguousarray(sizes, np.float64),
        np.ascontiguousarray(scales, np.float64).reshape(len(sizes), body.m),
        np.ascontiguousarray(body.targets, np.float64), f8(body.saturate(body.home)), chain,
        joints, np.ascontiguousarray(_exps(params, body), np.int64), int(params.steps),
        float(params.radius), float(params.drift), 1.0 / np.sqrt(1.0 + params.drift ** 2),
        float(params.home_probability), float(params.learning_rate))
    return State(M, P, int(target), bool(at_home), (lxs, lx, lq))


def predict(state: State, params: Params, body, x) -> np.ndarray:
    return predict_inverse(state.M, x, _exps(params, body))


def model(state: State) -> np.ndarray:
    return np.array(state.M, copy=True)


def samples_per_epoch(params: Params, body) -> int:
    """K L path samples plus the returns home, K home_probability in expectation (rounded)."""
    K = params.targets_per_epoch
    return int(round(K * (params.steps + params.home_probability)))
