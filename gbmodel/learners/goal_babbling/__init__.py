"""Goal Babbling (Rolf, Steil & Gienger 2010, sec. 2.2 and 3): the paper's learner; reference.py
states an epoch in numpy, fast.py computes it compiled with the same draws (Params.fast)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ... import evaluation, goals
from ...inverse import predict_model, table as _exps  # noqa: F401 (the protocol's)
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
    # eta of the gradient step on eq. 6 (the paper gives none), fixed before the runs: 1 / W, W
    # the median weight sum per epoch at full size after 20,000 epochs of the normalised step at
    # eta = 1 (pipeline/tools/rate.py), so both steps agree at convergence: arm5 W = 1142 (the
    # iCub's and arm2's in conf/body_learner; today's kernel gives 1173, kept as fixed).
    # Alternatives measured: conf/experiment/choices_*.yaml.
    learning_rate: float = 0.000876
    # V (K L + 1) at which learning_rate was fixed (20 (15 x 7 + 1)): the plain step runs at
    # learning_rate x rate_samples / V (K L + 1), so a sweep over V, K or L keeps the step per
    # sample. null: learning_rate as it is.
    rate_samples: int | None = 2120
    init_range: float = 0.1  # |g(x) - home| bound at initialisation (sec. 3: "0.1 radian")
    degree: int = 3  # P, polynomial degree of the features (eq. 7)
    fast: bool = True  # the compiled kernel (fast.py); False: the numpy reference path
    # readings the text leaves open (the readings study measures each)
    step: str = "plain"  # plain | normalised: the gradient step of eq. 6, or divided by sum w
    amplitude: str = "exact"  # exact | uniform: each disturbance row at R, or at U(0, 1) R
    updates: str = "batch"  # batch | steps | online: one step, update_steps steps, per sample
    update_steps: int = 1  # steps per epoch for updates=steps
    # constant (the paper's), or annealed, eta tau / (tau + e - 1), tau = anneal_epochs: eta / 11
    # after 100,000 epochs, near the tenth at which continuing the iCub's models helped
    rate_schedule: str = "constant"
    anneal_epochs: float = 10000.0
    # rate_schedule=step: rate_step_factor x eta after epoch rate_step_epoch
    rate_step_epoch: int = 0
    rate_step_factor: float = 1.0
    # successive path targets: distinct, or any (a repeat is a still segment, weight 0)
    targets: str = "distinct"
    # random (the paper's) or progress (gbmodel/goals.py)
    goal_selection: str = "random"
    progress_period: int = 10  # epochs between measurements of the error at every target
    progress_window: int = 3  # measurements per half of the progress window
    progress_share: float = 0.2  # the uniform part of the choice
    # gradient (the paper's step on eq. 6) or lstsq (solve.py: M solved over the last `window`
    # epochs' samples); the solver's fields enter a trial's key only off their defaults (keyed)
    solver: str = "gradient"
    window: int = 10  # epochs whose samples the lstsq solve fits
    ridge: float = 1e-3  # the lstsq solve's ridge, times each feature's sum of w Phi_k^2
    # the pull towards the initial M (solve.py), decaying with anchor_epochs on a limited body
    # (solve.anchor_at); measured: docs/bodies.md, "The exact solver"
    anchor: float = 0.01
    anchor_epochs: float = 100.0
    # the pull of the targets' commands towards the executed (clipped) ones on a limited body
    limit_pull: float = 0.1

    @property
    def samples(self) -> int:  # per epoch: V (K L + 1)
        return self.variations * (self.targets_per_epoch * self.steps + 1)

    def validate(self) -> "Params":
        check_fields(self, "learner", LIMITS)
        if self.samples > MAX_SAMPLES:
            raise SpecError("learner.variations", self.variations,
                            f"{self.variations} x ({self.targets_per_epoch} targets x "
                            f"{self.steps} steps + 1) = {self.samples:,} samples per epoch; at most "
                            f"{MAX_SAMPLES:,} (an epoch's samples are held in memory at once)")
        if self.solver == "lstsq" and self.updates != "batch":
            raise SpecError("learner.updates", self.updates,
                            "learner.solver=lstsq solves once per epoch: needs updates=batch")
        return self

    def rate(self) -> float:
        """eta: the plain step's learning_rate x rate_samples / samples per epoch."""
        if self.rate_samples is None or self.step == "normalised":
            return self.learning_rate
        return self.learning_rate * (self.rate_samples / self.samples)

    def rates(self, epochs) -> np.ndarray:
        e = np.asarray(epochs, dtype=np.float64)
        if self.rate_schedule == "constant":
            return np.full(e.shape, self.rate())
        if self.rate_schedule == "step":
            return np.where(e > self.rate_step_epoch, self.rate_step_factor, 1.0) * self.rate()
        tau = self.anneal_epochs
        return self.rate() * tau / (tau + e - 1.0)


SOLVERS = ("gradient", "lstsq")
MAX_SAMPLES = 10**6  # samples of one epoch, V (K L + 1): the paper's 2,120, the iCub's 6,020
# below MIN_RIDGE the kernel's float32 Gram sums lose definiteness (0: NaN at epoch 1; 1e-9:
# 0.1 % off the reference); at it both paths agree to 1e-3 (docs/faults.md). Above MAX_RIDGE
# nothing is learned and ridge x the Gram sums nears overflow.
MIN_RIDGE, MAX_RIDGE = 1e-5, 1e6
MAX_WINDOW = 1000  # epochs of Gram sums held (window x (p + m) x p floats) and summed per epoch
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
KEYED_DEFAULTS = {k: getattr(Params, k) for k in ("solver", "window", "ridge", "anchor",
                                                  "anchor_epochs", "limit_pull")}


def keyed(learner: dict) -> dict:
    """The learner's fields as a trial's key holds them: the solver's left out at defaults."""
    return {k: v for k, v in learner.items()
            if k not in KEYED_DEFAULTS or v != KEYED_DEFAULTS[k]}


@dataclass(frozen=True)
class Progressive:
    """The state under goal_selection=progress: M and the regions' error measurements."""
    M: np.ndarray
    tracker: goals.Tracker


def _M(state) -> np.ndarray:
    state = state.M if isinstance(state, Progressive) else state
    return state.M if isinstance(state, solve.Solved) else state


def init(params: Params, body, size: float, rng: np.random.Generator):
    """M: home plus a random polynomial within init_range (progress: errors measured once)."""
    M = reference.init_inverse(body.home, *body.target_box(size), _exps(params, body),
                               params.init_range, rng)
    if params.solver == "lstsq":
        M = solve.start(M, params.window)
    if params.goal_selection == "random":
        return M
    return Progressive(M, goals.first(lambda x: predict(M, params, body, x), body, size,
                                      params.progress_window))


def draw(params: Params, body, B: int, rng: np.random.Generator) -> tuple:
    """Target indices (B, K+1) (progress: uniform numbers, chosen in train), raw disturbances
    (B, V, m, n+1), and with amplitude=uniform the amplitude factors (B, V, m), drawn last."""
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
    """rng.uniform(-1.0, 1.0, shape) to the bit, a quarter faster (2 u exact, one rounding)."""
    raw = rng.random(shape)
    raw *= 2.0
    raw -= 1.0
    return raw


def train(state, params: Params, body, sizes, scales, draws, epochs):
    if params.goal_selection == "random":
        return _train(state, params, body, sizes, scales, draws, epochs)
    def step(M, chosen, lo, hi):
        part = (chosen,) + tuple(d[lo:hi] for d in draws[1:])
        return _train(M, params, body, sizes[lo:hi], scales[lo:hi], part, epochs[lo:hi])
    return Progressive(*goals.train(state.M, state.tracker, params, body, sizes, scales, draws,
                                    epochs, step, lambda M, x: predict(M, params, body, x)))


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
    M = _M(M)
    if params.fast:
        from . import fast
        return fast.distances(M, body, _exps(params, body), scale, xs)
    return evaluation.distances(lambda x: predict(M, params, body, x), body, scale, xs)


def model(M) -> np.ndarray:
    return np.array(_M(M), copy=True)


def samples_per_epoch(params: Params, body) -> int:
    return params.samples + goals.extra_samples(params, body)


def sample_cost(params: Params) -> float:
    """Relative CPU time per sample and joint (`python -m pipeline.tools.bench costs`)."""
    return (1.0 if params.fast else 60.0) * (2.0 if params.updates == "online" else 1.0)


def notes(params: Params, body) -> list[str]:
    """A body other than arm5 whose plain gradient step runs at arm5's default rate."""
    if params.solver == "gradient" and params.step == "plain" \
            and params.learning_rate == Params().learning_rate and body.name != "arm5":
        return [f"body {body.name} learns at the 5-DOF arm's plain-step rate (learner."
                "learning_rate = 1 / W fixed for arm5); `python -m pipeline.tools.rate "
                f"body={body.name} --write` (with this command's hydra.searchpath, if any) writes "
                "its own, or learner.solver=lstsq needs none"]
    return []
