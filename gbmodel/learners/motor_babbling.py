"""Direct inverse learning from random motor babbling, the baseline the paper argues against:
`samples` postures per epoch uniform within +-spread of home (saturated), their hands observed,
Goal Babbling's polynomial fitted to the last `window` epochs' examples (0: all): fit=lstsq
minimises mean |M Phi - q|^2 + ridge |M|^2, fit=gradient takes one normalised gradient step per
epoch. A fit averages the postures reaching one x, and an average of solutions is in general no
solution (sec. 1). The window's statistics (Phi^T Phi, Phi^T q, count) sit in a ring of slots.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..features import features
from ..spec import MAX_DEGREE, Choice, Int, Number, check_fields
from ..inverse import (init_inverse, model_of as model, predict_model,  # noqa: F401
                       predict_state as predict, table as _exps)


@dataclass(frozen=True)
class Params:
    samples: int = 2120  # per epoch: Goal Babbling's budget on arm5, V (K L + 1)
    # half-width of the posture range around home: locally the arm is near linear and averaging
    # does little harm, over the whole range it ruins the fit (docs/baselines.md)
    spread: float = 0.4
    window: int = 10  # epochs whose examples the fit uses; 0: all so far
    fit: str = "lstsq"  # lstsq | gradient
    ridge: float = 1e-6  # per-example ridge of fit=lstsq
    learning_rate: float = 1.0  # eta of fit=gradient
    init_range: float = 0.1  # the initial estimate: Goal Babbling's (home within 0.1)
    degree: int = 3

    def validate(self) -> "Params":
        check_fields(self, "learner", LIMITS)
        return self


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


def init(params: Params, body, size: float, rng: np.random.Generator) -> State:
    exps = _exps(params, body)
    M = init_inverse(body.home, *body.target_box(size), exps, params.init_range, rng)
    slots, p = max(params.window, 1), len(exps)
    return State(M, np.zeros((slots, p, p)), np.zeros((slots, p, body.m)), np.zeros(slots))


def draw(params: Params, body, B: int, rng: np.random.Generator) -> tuple:
    return (rng.uniform(-1.0, 1.0, size=(B, params.samples, body.m)),)


def fit_inverse(M, gram, cross, count, params: Params) -> np.ndarray:
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


def samples_per_epoch(params: Params, body) -> int:
    return params.samples


def sample_cost(params: Params) -> float:
    return 60.0
