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
- samples per epoch: K L plus the returns home, K home_probability in expectation;
- goal_selection: random (the above: each next target uniform over the others) or progress
  (gbmodel/goals.py: by the regions' recent change of error, not the 2011 paper's).

Two paths compute the same thing with the same draws (all random numbers come from `draw`):
`reference.py`, plain numpy, is the readable statement; `fast.py`, the same per-sample loop
compiled with numba in float64 (no fastmath: every sum in a fixed order, so the result does not
depend on the CPU's vector width), is what runs by default. They agree to rounding
(tests/core/test_learners.py). `Params.fast` picks the path. The random walk's normals are drawn by
numba's Generator from the trial's generator (fast.normals): numpy's very numbers.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ... import evaluation, goals
from ...features import exponents
from ...growth import factors
from ...spec import MAX_DEGREE, Flag, Int, Number, check_fields
from ...inverse import init_inverse, predict as predict_inverse
from . import fast, reference
from .fast import train_fast  # noqa: F401 (the two paths, named here for the tests)
from .reference import perturbations, plan, train_reference  # noqa: F401


@dataclass(frozen=True)
class Params:
    targets_per_epoch: int = 15  # K
    steps: int = 7  # L, linear steps to each next target (eq. 9)
    radius: float = 0.2  # R, max |E_i(x)| over the target box (eq. 8)
    # random-walk step of the perturbation's parameters per sample, relative to their spread:
    # 0.3 keeps a perturbation for about 23 samples (1 / ln sqrt(1 + drift^2)), 3 targets; a
    # perturbation held too long is learned as if it were the body (docs/baselines.md, "Why the
    # alternatives' defaults")
    drift: float = 0.3
    home_probability: float = 0.1  # chance of a return home after each target
    # eta of the per-sample step; a body with smaller weights (normalised commands, the iCub's)
    # may need its own (conf/body_learner/<body>_online_goal_babbling.yaml, docs/baselines.md)
    learning_rate: float = 0.1
    init_range: float = 0.1  # |g(x) - home| bound at initialisation (as Goal Babbling)
    degree: int = 3
    fast: bool = True  # the compiled per-sample loop (fast.py); False: reference.py
    # which targets (gbmodel/goals.py): random (the paper's) or progress, and its settings
    goal_selection: str = "random"
    progress_period: int = 10
    progress_window: int = 3
    progress_share: float = 0.2

    def validate(self) -> "Params":
        check_fields(self, "learner", LIMITS)
        return self


# Params' fields and their ranges (gbmodel.spec.check_fields)
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


def _exps(params, body):
    return exponents(body.n, params.degree)


def init(params: Params, body, size: float, rng: np.random.Generator) -> State:
    """Goal Babbling's initial M, a random perturbation, the body at home."""
    M = init_inverse(body.home, *body.target_box(size), _exps(params, body), params.init_range,
                     rng)
    P = rng.standard_normal((body.m, body.n + 1))
    q_home = body.saturate(body.home)
    x_home = body.forward(q_home, factors(body, size))
    tracker = None
    if params.goal_selection == "progress":
        errors = goals.reaching_errors(lambda x: predict_inverse(M, x, _exps(params, body)),
                                       body, size, np.ones(body.m))
        tracker = goals.start(body.targets).measured(errors, goals.regions(body.targets),
                                                     params.progress_window)
    return State(M, P, target=0, at_home=True, last=(x_home, x_home, q_home), tracker=tracker)


def draw(params: Params, body, B: int, rng: np.random.Generator) -> tuple:
    """Per epoch: hops to the next targets (B, K) in 1 ... N-1 (so each differs from the last),
    home coins (B, K) in [0, 1), random-walk steps (B, K L, m, n+1). With goal_selection=progress
    the first array holds uniform numbers (B, K) in [0, 1), turned into targets in train."""
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
    region, N = goals.regions(body.targets), len(body.targets)
    for lo, hi, measure in goals.chunks(epochs, params.progress_period):
        p = goals.probabilities(state.tracker.progress(params.progress_window), region,
                                params.progress_share)
        chosen = goals.choose(draws[0][lo:hi], p)  # (C, K) the targets, as hops from the last
        flat = np.concatenate([[state.target], chosen.ravel()])
        hops = (np.diff(flat) % N).reshape(chosen.shape)
        state = _train(state, params, body, sizes[lo:hi], scales[lo:hi],
                       (hops,) + tuple(d[lo:hi] for d in draws[1:]))
        if measure:
            errors = goals.reaching_errors(lambda x: predict(state, params, body, x), body,
                                           sizes[hi - 1], scales[hi - 1])
            state = replace(state, tracker=state.tracker.measured(errors, region,
                                                                  params.progress_window))
    return state


def _train(state: State, params: Params, body, sizes, scales, draws) -> State:
    if params.fast:
        return fast.train_fast(state, params, body, sizes, scales, draws)
    return reference.train_reference(state, params, body, sizes, scales, draws)


def predict(state: State, params: Params, body, x) -> np.ndarray:
    return predict_inverse(state.M, x, _exps(params, body))


def distances(state: State, params: Params, body, scale, xs) -> np.ndarray:
    """|f(g(x*)) - x*| per point (rows of xs), the body at per-joint factors `scale`: on the
    fast path by fast.distances (the kernel's float64 features, prediction and kinematics, every
    sum in order), else by the shared numpy evaluation; they agree to rounding."""
    if not params.fast:
        return evaluation.distances(lambda x: predict(state, params, body, x), body, scale, xs)
    return fast.distances(state.M, params, body, scale, xs)


def model(state: State) -> np.ndarray:
    return np.array(state.M, copy=True)


def samples_per_epoch(params: Params, body) -> int:
    """K L path samples plus the returns home, K home_probability in expectation (rounded)."""
    K = params.targets_per_epoch
    extra = goals.samples(body, params.progress_period) if params.goal_selection == "progress" \
        else 0
    return int(round(K * (params.steps + params.home_probability))) + extra


def sample_cost(params: Params) -> float:
    """CPU time per sample and joint, relative to Goal Babbling's fast batch path: the
    per-sample loop (one pass over M per sample) about 35 times, its numpy reference about
    11,000 times."""
    return 35.0 if params.fast else 11000.0


def predict_model(model, params: Params, body, x) -> np.ndarray:
    """predict from what `model` stored (M)."""
    return predict_inverse(np.asarray(model, np.float64), x, _exps(params, body))
