"""Online Goal Babbling (Rolf, Steil & Gienger 2011), as we read it and as the IRP group's `pygb`
realises it: one continuous stream of goal-directed movements, learned sample by sample. The
path, perturbation and last sample carry over between epochs; the perturbation E_t(x) = A_t x +
b_t drifts, P <- (P + drift xi) / sqrt(1 + drift^2), xi ~ N(0, 1), so that P = [A | b] stays
N(0, 1); one gradient step per sample on w_t |g(x_t) - q_t|^2 (weights of eq. 1-3, 2010); after
a target, a return home with probability `home_probability`.

Chosen here: the 2010 paper's paths (eq. 9: L steps to each next target, uniform over the
others), amplitude (eq. 8: rows scaled to peak at R over the target box), inverse (eq. 7,
initialised alike) and home example (one sample of weight 1; the next path starts at x_home);
the step is plain gradient descent (2011 learns a local-linear map). An epoch: K targets, K L
path samples plus the returns home. goal_selection: random or progress (gbmodel/goals.py).

`train_reference` (below, numpy) states it; fast.py computes it compiled in float64 with the
same draws (its normals by numba's Generator: numpy's very numbers), to rounding
(tests/core/test_learners.py); Params.fast picks the path.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ... import evaluation, goals
from ...features import features
from ...growth import factors
from ...spec import MAX_DEGREE, Flag, Int, Number, check_fields
from ...inverse import (init_inverse, model_of as model, predict as predict_inverse,  # noqa: F401
                        predict_model, predict_state as predict, sample_weights,
                        scale_perturbations, table as _exps)
from . import fast
from .fast import train_fast  # noqa: F401 (the compiled path, named here for the tests)


@dataclass(frozen=True)
class Params:
    targets_per_epoch: int = 15  # K
    steps: int = 7  # L, linear steps to each next target (eq. 9)
    radius: float = 0.2  # R, max |E_i(x)| over the target box (eq. 8)
    # the random walk's step per sample: 0.3 keeps a perturbation ~23 samples (1 / ln sqrt(1 +
    # drift^2)); one held too long is learned as the body (docs/baselines.md)
    drift: float = 0.3
    home_probability: float = 0.1  # chance of a return home after each target
    # eta per sample; a body with smaller weights (the iCub's) has its own (conf/body_learner)
    learning_rate: float = 0.1
    init_range: float = 0.1  # |g(x) - home| bound at initialisation (as Goal Babbling)
    degree: int = 3
    fast: bool = True  # the compiled per-sample loop (fast.py); False: train_reference
    goal_selection: str = "random"
    progress_period: int = 10
    progress_window: int = 3
    progress_share: float = 0.2

    def validate(self) -> "Params":
        check_fields(self, "learner", LIMITS)
        return self


LIMITS = dict(
    targets_per_epoch=Int(1, 10_000), steps=Int(1, 1000), radius=Number(0.0, 100.0),
    drift=Number(0.0, 100.0), home_probability=Number(0.0, 1.0),
    learning_rate=Number(0.0, 1e3, lo_open=True), init_range=Number(0.0, 100.0),
    degree=Int(1, MAX_DEGREE, " (the features grow as C(n + P, P))"), fast=Flag(),
    **goals.LIMITS)


@dataclass(frozen=True)
class State:
    M: np.ndarray  # (m, p) the inverse estimate
    P: np.ndarray  # (m, n + 1) the perturbation's raw parameters [A | b]
    target: int  # index of the target last reached
    at_home: bool  # the last movement returned home: the next path starts at x_home
    last: tuple  # (x*, x, q) of the last sample, the predecessor of the next one's weight
    tracker: goals.Tracker | None = None  # the regions' errors (goal_selection=progress)


def init(params: Params, body, size: float, rng: np.random.Generator) -> State:
    M = init_inverse(body.home, *body.target_box(size), _exps(params, body), params.init_range,
                     rng)
    P = rng.standard_normal((body.m, body.n + 1))
    q_home = body.saturate(body.home)
    x_home = body.forward(q_home, factors(body, size))
    tracker = None if params.goal_selection != "progress" else goals.first(
        lambda x: predict_inverse(M, x, _exps(params, body)), body, size, params.progress_window)
    return State(M, P, target=0, at_home=True, last=(x_home, x_home, q_home), tracker=tracker)


def draw(params: Params, body, B: int, rng: np.random.Generator) -> tuple:
    """Hops to the next targets (B, K) in 1 ... N-1 (progress: uniform numbers), home coins
    (B, K), random-walk steps (B, K L, m, n+1)."""
    K = params.targets_per_epoch
    if params.goal_selection == "progress":
        hops = rng.uniform(0.0, 1.0, size=(B, K))
    else:
        hops = rng.integers(1, len(body.targets), size=(B, K))
    coins = rng.uniform(0.0, 1.0, size=(B, K))
    shape = (B, K * params.steps, body.m, body.n + 1)
    walk = fast.normals(rng, int(np.prod(shape))).reshape(shape)
    return hops, coins, walk


def train(state: State, params: Params, body, sizes, scales, draws, epochs=None) -> State:
    if params.goal_selection == "random":
        return _train(state, params, body, sizes, scales, draws)
    def step(state, chosen, lo, hi):  # chosen (C, K): the targets, as hops from the last
        flat = np.concatenate([[state.target], chosen.ravel()])
        hops = (np.diff(flat) % len(body.targets)).reshape(chosen.shape)
        return _train(state, params, body, sizes[lo:hi], scales[lo:hi],
                      (hops,) + tuple(d[lo:hi] for d in draws[1:]))
    state, tracker = goals.train(state, state.tracker, params, body, sizes, scales, draws,
                                 epochs, step, lambda s, x: predict(s, params, body, x))
    return replace(state, tracker=tracker)


def _train(state: State, params: Params, body, sizes, scales, draws) -> State:
    if params.fast:
        return fast.train_fast(state, params, body, sizes, scales, draws)
    return train_reference(state, params, body, sizes, scales, draws)


def distances(state: State, params: Params, body, scale, xs) -> np.ndarray:
    if not params.fast:
        return evaluation.distances(lambda x: predict(state, params, body, x), body, scale, xs)
    return fast.distances(state.M, params, body, scale, xs)


def samples_per_epoch(params: Params, body) -> int:
    K = params.targets_per_epoch
    return int(round(K * (params.steps + params.home_probability))) + goals.extra_samples(params,
                                                                                          body)


def sample_cost(params: Params) -> float:
    return 35.0 if params.fast else 11000.0


def plan(state, params, targets, x_home, hops, coins):
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


def perturbations(P, walk, params, lo, hi):
    """The perturbation of every path sample: A (T, m, n), b (T, m), and P after the walk."""
    keep = 1.0 / np.sqrt(1.0 + params.drift ** 2)
    raw = np.empty_like(walk)
    for t, step in enumerate(walk):
        P = keep * (P + params.drift * step)
        raw[t] = P
    A, b = scale_perturbations(raw, lo, hi, params.radius)
    return A, b, P


def train_reference(state, params, body, sizes, scales, draws):
    hops, coins, walk = draws
    exps = _exps(params, body)
    M, P = state.M.copy(), state.P
    for e in range(len(sizes)):
        q_home = body.saturate(body.home)
        x_home = body.forward(q_home, scales[e])
        xstar, home, target, at_home = plan(state, params, body.target_set(sizes[e]), x_home,
                                            hops[e], coins[e])
        A, b, P = perturbations(P, walk[e], params, *body.target_box(sizes[e]))
        last, j = state.last, 0  # j: the next path sample's perturbation
        for xs, is_home in zip(xstar, home):
            if is_home:  # the home example, weight 1 (eq. 5)
                x, q, w = x_home, q_home, 1.0
            else:
                q = body.saturate(predict_inverse(M, xs, exps) + A[j] @ xs + b[j])
                x = body.forward(q, scales[e])
                w = sample_weights(*(np.stack([a, c]) for a, c in zip(last, (xs, x, q))))[1]
                j += 1
            phi = features(x, exps)
            M -= (params.learning_rate * w) * np.outer(M @ phi - q, phi)
            last = (xs, x, q)
        state = replace(state, M=M, P=P, target=target, at_home=at_home, last=last)
    return replace(state, M=M.copy())
