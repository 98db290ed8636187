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
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..features import exponents, features
from ..growth import SpecError, check_int, check_number
from .goal_babbling.reference import (init_inverse, predict as predict_inverse,
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

    def validate(self) -> "Params":
        for name in ("targets_per_epoch", "steps", "degree"):
            check_int(f"learner.{name}", getattr(self, name), 1)
        for name in ("radius", "drift", "init_range"):
            check_number(f"learner.{name}", getattr(self, name), 0.0)
        check_number("learner.learning_rate", self.learning_rate, 0.0, strict=True)
        check_number("learner.home_probability", self.home_probability, 0.0)
        if self.home_probability > 1:
            raise SpecError("learner.home_probability", self.home_probability, "must be <= 1")
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


def train(state: State, params: Params, body, sizes, scales, draws) -> State:
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


def predict(state: State, params: Params, body, x) -> np.ndarray:
    return predict_inverse(state.M, x, _exps(params, body))


def model(state: State) -> np.ndarray:
    return np.array(state.M, copy=True)


def samples_per_epoch(params: Params, body) -> int:
    """K L path samples plus the returns home, K home_probability in expectation (rounded)."""
    K = params.targets_per_epoch
    return int(round(K * (params.steps + params.home_probability)))
