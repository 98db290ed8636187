"""Direct inverse learning from random motor babbling: the baseline the paper argues against.

Each epoch the body takes `samples` postures drawn uniformly within +-spread of home (command
units: radians on the planar arms, normalised [-1, 1] units on the iCub, saturated there), and
its hand is observed at x = f(q) with the body at its current size. The inverse estimate is the
same degree-3 polynomial as Goal Babbling's, q ~ g(x) = M Phi(x), fitted to the examples of the
last `window` epochs (0: all so far):

- fit=lstsq: M minimises mean |M Phi(x) - q|^2 + ridge |M|^2 over the window;
- fit=gradient: one step of Goal Babbling's normalised gradient rule per epoch, every example
  weighted 1: M <- M - eta sum (M Phi - q) Phi^T / N over the window.

On a redundant body many postures reach the same x; a least-squares fit averages them, and the
average of solutions is in general no solution (paper sec. 1: random motor babbling "cannot
resolve redundancy"). What stays bounded: the window's sufficient statistics Phi^T Phi (p, p),
Phi^T q (p, m) and the count, one slot per epoch in a ring of `window` slots (one slot that
accumulates for window 0), whatever the number of epochs.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..features import exponents, features
from ..spec import MAX_DEGREE, Choice, Int, Number, check_fields
from ..inverse import init_inverse, predict as predict_inverse


@dataclass(frozen=True)
class Params:
    # examples per epoch: Goal Babbling's budget on arm5 at the paper's settings,
    # V (K L + 1) = 20 (15 * 7 + 1) = 2120 forward-kinematics evaluations
    samples: int = 2120
    # half-width of the uniform posture range around home [command units]: locally the arm is
    # near linear and averaging postures does little harm; over the whole joint range it ruins
    # the fit (docs/baselines.md, "Why the alternatives' defaults")
    spread: float = 0.4
    # epochs whose examples the fit uses; 0 = all so far (stale examples mislead under growth)
    window: int = 10
    fit: str = "lstsq"  # lstsq | gradient
    ridge: float = 1e-6  # per-example ridge of fit=lstsq
    learning_rate: float = 1.0  # eta of fit=gradient
    init_range: float = 0.1  # the initial estimate: Goal Babbling's (home within 0.1)
    degree: int = 3

    def validate(self) -> "Params":
        check_fields(self, "learner", LIMITS)
        return self


# Params' fields and their ranges (gbmodel.spec.check_fields)
LIMITS = dict(samples=Int(1, 10**6), spread=Number(0.0, 100.0, lo_open=True),
              window=Int(0, 10_000), fit=Choice("lstsq", "gradient"), ridge=Number(0.0, 1e6),
              learning_rate=Number(0.0, 1e3, lo_open=True), init_range=Number(0.0, 100.0),
              degree=Int(1, MAX_DEGREE, " (the features grow as C(n + P, P))"))


@dataclass(frozen=True)
class State:
    M: np.ndarray  # (m, p) the inverse estimate
    gram: np.ndarray  # (slots, p, p) Phi^T Phi of each epoch in the window
    cross: np.ndarray  # (slots, p, m) Phi^T q of each epoch in the window
    count: np.ndarray  # (slots,) examples of each epoch in the window
    epochs: int = 0  # epochs trained so far


def _exps(params, body):
    return exponents(body.n, params.degree)


def init(params: Params, body, size: float, rng: np.random.Generator) -> State:
    exps = _exps(params, body)
    M = init_inverse(body.home, *body.target_box(size), exps, params.init_range, rng)
    slots, p = max(params.window, 1), len(exps)
    return State(M, np.zeros((slots, p, p)), np.zeros((slots, p, body.m)), np.zeros(slots))


def draw(params: Params, body, B: int, rng: np.random.Generator) -> tuple:
    """Uniform posture offsets (B, samples, m) in [-1, 1], times spread when used."""
    return (rng.uniform(-1.0, 1.0, size=(B, params.samples, body.m)),)


def fit_inverse(M, gram, cross, count, params: Params) -> np.ndarray:
    """The inverse estimate from the window's statistics, by params.fit."""
    p = gram.shape[0]
    if params.fit == "lstsq":
        return np.linalg.solve(gram / count + params.ridge * np.eye(p), cross / count).T
    return M - params.learning_rate * (M @ gram - cross.T) / count


def train(state: State, params: Params, body, sizes, scales, draws, epochs=None) -> State:
    (offsets,) = draws
    exps = _exps(params, body)
    M, gram, cross, count = state.M, state.gram.copy(), state.cross.copy(), state.count.copy()
    for e in range(len(sizes)):
        q = body.saturate(body.home + params.spread * offsets[e])
        x = body.forward(q, scales[e])
        phi = features(x, exps)
        slot = (state.epochs + e) % len(count)
        keep = 1.0 if params.window == 0 else 0.0  # window 0: the one slot accumulates
        gram[slot] = keep * gram[slot] + phi.T @ phi
        cross[slot] = keep * cross[slot] + phi.T @ q
        count[slot] = keep * count[slot] + len(q)
        M = fit_inverse(M, gram.sum(axis=0), cross.sum(axis=0), count.sum(), params)
    return replace(state, M=M, gram=gram, cross=cross, count=count,
                   epochs=state.epochs + len(sizes))


def predict(state: State, params: Params, body, x) -> np.ndarray:
    return predict_inverse(state.M, x, _exps(params, body))


def model(state: State) -> np.ndarray:
    return np.array(state.M, copy=True)


def samples_per_epoch(params: Params, body) -> int:
    return params.samples


def sample_cost(params: Params) -> float:
    """CPU time per sample and joint, relative to Goal Babbling's fast batch path."""
    return 60.0


def predict_model(model, params: Params, body, x) -> np.ndarray:
    """predict from what `model` stored (M)."""
    return predict_inverse(np.asarray(model, np.float64), x, _exps(params, body))
