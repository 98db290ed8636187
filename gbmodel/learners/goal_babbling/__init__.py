"""Goal Babbling (Rolf, Steil & Gienger 2010, sec. 2.2 and 3): the paper's learner.

`reference.py` states one epoch in plain numpy, step by step as the paper writes it; `fast.py`
computes the same epoch in compiled float32 loops (numba) and is tested against it with the same
random draws. `Params.fast` picks the path. gbmodel/goals.py: which targets it aims at
(goal_selection: random, the paper's, or progress).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ... import evaluation, goals
from ...features import exponents
from ...spec import (MAX_DEGREE, MAX_EPOCHS, Choice, Flag, Int, Maybe, Number, SpecError,
                      check_fields)
from . import reference, solve


@dataclass(frozen=True)
class Params:
    """The paper's planar-arm settings (sec. 3.1); the iCub's come with its body (conf)."""

    variations: int = 20  # V
    radius: float = 0.2  # R, bound of the exploratory disturbance (eq. 8)
    targets_per_epoch: int = 15  # K
    steps: int = 7  # L, linear steps between successive targets (eq. 9)
    # eta of the gradient step on eq. 6 (reference.gradient_step); the paper gives none. The
    # plain step's rule, fixed before its runs: eta = 1 / W, W the median sum of the weights per
    # epoch at full size after 20,000 epochs of the normalised step at eta = 1.0, so that both
    # steps agree at full-size convergence (pipeline/tools/rate.py: weight_sum); arm5 W = 1142, so
    # eta = 1 / 1142; the iCub's (1 / 1791) and the 2-DOF arm's (1 / 1931) come with the body
    # (conf/body_learner). Recomputed with today's kernel W is 1173 (arm5) and 1782 (iCub): the
    # rates were kept as fixed before the runs. Measured alternatives (0.5 to 2 / W, the
    # normalised step): conf/experiment/choices_*.yaml (outputs/report/choices.md).
    learning_rate: float = 0.000876
    # the samples per epoch, V (K L + 1), at which learning_rate was fixed (the paper's arm
    # settings: 20 (15 x 7 + 1) = 2120). The plain step sums over the samples, so its effective
    # rate is learning_rate x rate_samples / V (K L + 1): a sweep over V, K or L keeps the step per
    # sample, instead of secretly sweeping the step size. null: learning_rate as it is.
    rate_samples: int | None = 2120
    init_range: float = 0.1  # |g(x) - home| bound at initialisation (sec. 3: "0.1 radian")
    degree: int = 3  # P, polynomial degree of the features (eq. 7)
    fast: bool = True  # the compiled kernel (fast.py); False: the numpy reference path
    # readings of the text it leaves open (reference.py; the readings study measures each)
    step: str = "plain"  # plain | normalised: the gradient step of eq. 6, or divided by sum w
    amplitude: str = "exact"  # exact | uniform: each disturbance row at R, or at U(0, 1) R
    updates: str = "batch"  # batch | steps | online: one step, update_steps steps, per sample
    update_steps: int = 1  # steps per epoch for updates=steps
    # the rate over the epochs: constant (the paper's), or annealed, eta tau / (tau + e - 1) in
    # epoch e with tau = anneal_epochs (not the paper's). tau = 10,000: eta / 11 at the end of a
    # 100,000-epoch run, near the tenth at which continuing the iCub's models lowered the error
    # (pipeline/studies/explain.py: continuation)
    rate_schedule: str = "constant"
    anneal_epochs: float = 10000.0
    # rate_schedule=step: eta up to epoch rate_step_epoch, rate_step_factor x eta after it (a
    # trained model continued at a smaller rate, as one trial: conf/experiment/explain_fig7_*)
    rate_step_epoch: int = 0
    rate_step_factor: float = 1.0
    # successive path targets: distinct (each differs from the one before) or any (uniform
    # over all targets, repeats allowed: a repeat is a still segment whose samples weigh 0)
    targets: str = "distinct"
    # goal_selection: random (the paper's: the path targets as above) or progress (gbmodel/goals.py:
    # drawn by the regions' recent change of error; not the paper's)
    goal_selection: str = "random"
    progress_period: int = 10  # epochs between measurements of the error at every target
    progress_window: int = 3  # measurements per half of the progress window
    progress_share: float = 0.2  # the uniform part of the choice
    # how M learns from an epoch's samples: gradient (the paper's step on eq. 6, at the rate
    # above) or lstsq (solve.py: M solved from eq. 6's weighted normal equations over the
    # samples of the last `window` epochs, with a ridge relative to each feature's scale that
    # pulls towards the current M and an anchor towards the initial M over the targets; no
    # rate). Neither enters a trial's key at its default (keyed).
    solver: str = "gradient"
    window: int = 10  # epochs whose samples the lstsq solve fits
    ridge: float = 1e-3  # the lstsq solve's ridge, times each feature's sum of w Phi_k^2
    # the lstsq solve's pull towards the initial M over the targets, times the window's sum of
    # weights (solve.py says why); on a body with joint limits it decays as tau / (tau + e - 1),
    # tau = anchor_epochs (solve.anchor_at). Measured: docs/bodies.md, "The exact solver"
    anchor: float = 0.01
    anchor_epochs: float = 100.0
    # the lstsq solve's pull of the commands at the targets towards those the body executes
    # (clipped at its joint limits), times the window's sum of weights, on a body with joint
    # limits (solve.py): frees a run whose first solves command joints past their limits
    limit_pull: float = 0.1

    def validate(self) -> "Params":
        check_fields(self, "learner", LIMITS)
        samples = self.variations * (self.targets_per_epoch * self.steps + 1)
        if samples > MAX_SAMPLES:
            raise SpecError("learner.variations", self.variations,
                            f"{self.variations} x ({self.targets_per_epoch} targets x "
                            f"{self.steps} steps + 1) = {samples:,} samples per epoch; at most "
                            f"{MAX_SAMPLES:,} (an epoch's samples are held in memory at once)")
        if self.solver == "lstsq" and self.updates != "batch":
            raise SpecError("learner.updates", self.updates,
                            "learner.solver=lstsq solves once per epoch: needs updates=batch")
        return self

    def rate(self) -> float:
        """eta of the plain step at these V, K, L: learning_rate scaled by rate_samples / the
        samples per epoch (exactly learning_rate at the samples it was fixed for). The normalised
        step divides by the sum of the weights, so it takes learning_rate as it is."""
        if self.rate_samples is None or self.step == "normalised":
            return self.learning_rate
        samples = self.variations * (self.targets_per_epoch * self.steps + 1)
        return self.learning_rate * (self.rate_samples / samples)

    def rates(self, epochs) -> np.ndarray:
        """eta in each of the (1-based) epochs."""
        e = np.asarray(epochs, dtype=np.float64)
        if self.rate_schedule == "constant":
            return np.full(e.shape, self.rate())
        if self.rate_schedule == "step":
            return np.where(e > self.rate_step_epoch, self.rate_step_factor, 1.0) * self.rate()
        tau = self.anneal_epochs
        return self.rate() * tau / (tau + e - 1.0)


SOLVERS = ("gradient", "lstsq")
MAX_SAMPLES = 10**6  # samples of one epoch, V (K L + 1): the paper's 2,120, the iCub's 6,020
# learner.ridge: below MIN_RIDGE the compiled path's float32 Gram sums make the system lose
# definiteness (0 gives NaN at epoch 1 where numpy's solver returns an answer; 1e-9 ends 0.1 %
# away from the reference after 200 epochs on arm5); at it both paths end within 1e-3 of each
# other on arm5 and the iCub (docs/faults.md). Above MAX_RIDGE M stays the initial M to 1e-8
# (nothing is learned) and ridge x the Gram sums nears overflow.
MIN_RIDGE, MAX_RIDGE = 1e-5, 1e6
MAX_WINDOW = 1000  # epochs of Gram sums held (window x (p + m) x p floats) and summed per epoch
# Params' fields and their ranges (gbmodel.spec.check_fields); validate() adds what relates two
LIMITS = dict(
    variations=Int(1, 1000), radius=Number(0.0, 100.0), targets_per_epoch=Int(1, 10_000),
    steps=Int(1, 1000), learning_rate=Number(0.0, 1e3, lo_open=True),
    rate_samples=Maybe(Int(1, 10**9)), init_range=Number(0.0, 100.0),
    degree=Int(1, MAX_DEGREE, " (the features grow as C(n + P, P))"), fast=Flag(),
    step=Choice("normalised", "plain"), amplitude=Choice("exact", "uniform"),
    updates=Choice("batch", "steps", "online"), update_steps=Int(1, 1000),
    rate_schedule=Choice("constant", "annealed", "step"),
    anneal_epochs=Number(0.0, 1e12, lo_open=True), rate_step_epoch=Int(0, MAX_EPOCHS),
    rate_step_factor=Number(0.0, 1e3, lo_open=True), targets=Choice("distinct", "any"),
    **goals.LIMITS, solver=Choice(*SOLVERS),
    window=Int(1, MAX_WINDOW, " epochs (a window of Gram sums is held in memory)"),
    ridge=Number(MIN_RIDGE, MAX_RIDGE, why=" (beyond it nothing is learned)"),
    anchor=Number(0.0, MAX_RIDGE, why=" (beyond it nothing is learned)"),
    anchor_epochs=Number(0.0, 1e12, lo_open=True),
    limit_pull=Number(0.0, MAX_RIDGE, why=" (beyond it nothing is learned)"))
KEYED_DEFAULTS = dict(solver="gradient", window=10, ridge=1e-3, anchor=0.01,
                      anchor_epochs=100.0, limit_pull=0.1)


def keyed(learner: dict) -> dict:
    """The learner's fields as a trial's key holds them: the solver's fields left out at their
    defaults (the paper's gradient step), so that a gradient trial's key does not name options
    it does not use; any other value stays (and is validated)."""
    return {k: v for k, v in learner.items()
            if k not in KEYED_DEFAULTS or v != KEYED_DEFAULTS[k]}


_EXPS: dict = {}  # (n, degree) -> the exponent table, read-only


def _exps(params, body):
    """The monomials' exponent table (features.exponents), built once per (n, degree): a trial
    asks for it at every block and evaluation (about 200 times in 5,000 epochs of arm5)."""
    key = (body.n, params.degree)
    exps = _EXPS.get(key)
    if exps is None:
        exps = _EXPS[key] = exponents(*key)
        exps.setflags(write=False)
    return exps


@dataclass(frozen=True)
class Progressive:
    """The state under goal_selection=progress: M and the regions' error measurements."""
    M: np.ndarray
    tracker: goals.Tracker


def _M(state) -> np.ndarray:
    state = state.M if isinstance(state, Progressive) else state
    return state.M if isinstance(state, solve.Solved) else state


def init(params: Params, body, size: float, rng: np.random.Generator):
    """M: home plus a random polynomial within init_range of it over the target box (with
    goal_selection=progress, and the error at every target measured once)."""
    M = reference.init_inverse(body.home, *body.target_box(size), _exps(params, body),
                               params.init_range, rng)
    if params.solver == "lstsq":
        M = solve.start(M, params.window)
    if params.goal_selection == "random":
        return M
    errors = goals.reaching_errors(lambda x: predict(M, params, body, x), body, size,
                                   np.ones(body.m))
    tracker = goals.start(body.targets)
    return Progressive(M, tracker.measured(errors, goals.regions(body.targets),
                                           params.progress_window))


def draw(params: Params, body, B: int, rng: np.random.Generator) -> tuple:
    """Target indices (B, K+1) and raw disturbances (B, V, m, n+1) of B epochs, and with
    amplitude=uniform the amplitude factors (B, V, m), drawn last.

    With targets=distinct, successive targets of a path differ (the next is uniform over the
    other targets), so that every path step is a movement with a direction; with targets=any
    the next is uniform over all targets. With goal_selection=progress the first array holds
    uniform numbers (B, K+1) in [0, 1), turned into targets in train (gbmodel/goals.py).
    """
    n_targets, K = len(body.targets), params.targets_per_epoch
    if params.goal_selection == "progress":
        idx = rng.uniform(0.0, 1.0, size=(B, K + 1))
    else:
        first = rng.integers(0, n_targets, size=(B, 1))
        hops = rng.integers(1 if params.targets == "distinct" else 0, n_targets, size=(B, K))
        idx = np.cumsum(np.concatenate([first, hops], axis=1), axis=1) % n_targets
    raw = _uniform(rng, (B, params.variations, body.m, body.n + 1))
    if params.amplitude == "uniform":
        return idx, raw, rng.uniform(0.0, 1.0, size=(B, params.variations, body.m))
    return idx, raw


def _uniform(rng: np.random.Generator, shape) -> np.ndarray:
    """rng.uniform(-1.0, 1.0, shape) to the bit, about a quarter faster: numpy computes
    -1 + 2 u from the same doubles u in [0, 1), and 2 u - 1 is that sum (2 u is exact, the one
    rounding is the addition's)."""
    raw = rng.random(shape)
    raw *= 2.0
    raw -= 1.0
    return raw


def train(state, params: Params, body, sizes, scales, draws, epochs):
    if params.goal_selection == "random":
        return _train(state, params, body, sizes, scales, draws, epochs)
    M, tracker = state.M, state.tracker
    region = goals.regions(body.targets)
    for lo, hi, measure in goals.chunks(epochs, params.progress_period):
        p = goals.probabilities(tracker.progress(params.progress_window), region,
                                params.progress_share)
        part = (goals.choose(draws[0][lo:hi], p),) + tuple(d[lo:hi] for d in draws[1:])
        M = _train(M, params, body, sizes[lo:hi], scales[lo:hi], part, epochs[lo:hi])
        if measure:
            errors = goals.reaching_errors(lambda x: predict(M, params, body, x), body,
                                           sizes[hi - 1], scales[hi - 1])
            tracker = tracker.measured(errors, region, params.progress_window)
    return Progressive(M, tracker)


def _train(M, params: Params, body, sizes, scales, draws, epochs) -> np.ndarray:
    idx, raw, *amp = draws
    exps = _exps(params, body)
    rates = params.rates(epochs)
    if params.fast:
        from . import fast
        return fast.run_block(M, body, params, exps, sizes, scales, rates, idx, raw, *amp)
    if params.solver == "lstsq":
        for e in range(len(sizes)):
            _, x, q, w = reference.samples(M.M, body, sizes[e], scales[e], exps, idx[e], raw[e],
                                           params.radius, params.steps, amp[0][e] if amp else None)
            targets = body.target_set(sizes[e])
            P = solve.target_gram(targets, exps)
            anchor = solve.anchor_at(params.anchor, params.anchor_epochs, M.epochs + 1, body)
            PC = solve.limit_gram(targets, exps, M.M, True) if body.limited else None
            M = solve.solve(M, solve.grams(x, q, w, exps), params.ridge, P, anchor, PC,
                            params.limit_pull)
        return M
    for e in range(len(sizes)):
        M, _ = reference.epoch(M, body, sizes[e], scales[e], exps, idx[e], raw[e], params.radius,
                               params.steps, rates[e], amp[0][e] if amp else None,
                               params.step, params.updates, params.update_steps)
    return M


def predict(M, params: Params, body, x) -> np.ndarray:
    return reference.predict(_M(M), x, _exps(params, body))


def distances(M, params: Params, body, scale, xs) -> np.ndarray:
    """|f(g(x*)) - x*| per point: on the fast path computed by the kernel (its float32 rollout,
    bit-identical across CPUs), else by the shared numpy evaluation."""
    M = _M(M)
    if params.fast:
        from . import fast
        return fast.distances(M, body, _exps(params, body), scale, xs)
    return evaluation.distances(lambda x: predict(M, params, body, x), body, scale, xs)


def model(M) -> np.ndarray:
    return np.array(_M(M), copy=True)


def samples_per_epoch(params: Params, body) -> int:
    """V rollouts of K L path targets plus the home example each (with goal_selection=progress,
    plus the measurements of the error at every target, goals.samples)."""
    extra = goals.samples(body, params.progress_period) if params.goal_selection == "progress" \
        else 0
    return params.variations * (params.targets_per_epoch * params.steps + 1) + extra


def sample_cost(params: Params) -> float:
    """CPU time per sample and joint, relative to the fast batch path (for a run's ETA and its
    shards' balance; `python -m pipeline.tools.bench costs` measures them): the numpy reference
    about 60 times, one step per sample (updates=online) about 2 times the batch step."""
    return (1.0 if params.fast else 60.0) * (2.0 if params.updates == "online" else 1.0)


def notes(params: Params, body) -> list[str]:
    """What a user should know about these settings on this body: a body other than arm5 whose
    plain step runs at the default rate, which the 1 / W rule fixed for arm5 (nothing wrong,
    but a rate not made for it). Only where that rate is in effect: the gradient solver's plain
    step (solver=lstsq solves M exactly and has no rate)."""
    if params.solver == "gradient" and params.step == "plain" \
            and params.learning_rate == Params().learning_rate and body.name != "arm5":
        return [f"body {body.name} learns at the 5-DOF arm's plain-step rate (learner."
                "learning_rate = 1 / W fixed for arm5); `python -m pipeline.tools.rate "
                f"body={body.name} --write` (with this command's hydra.searchpath, if any) writes "
                "its own, or learner.solver=lstsq needs none"]
    return []


def predict_model(model, params: Params, body, x) -> np.ndarray:
    """predict from what `model` stored (M)."""
    return reference.predict(np.asarray(model, np.float64), x, _exps(params, body))
