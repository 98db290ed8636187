"""Memory-based goal babbling, as explauto's `nearest_neighbor` model: g(x*) is the command of
the stored example whose outcome lies nearest to x*. Each epoch the body executes, for `goals`
targets at its current size, that command plus Gaussian noise (`sigma`), saturated, and stores
what it observes. The memory starts with the home example and keeps the last `window` epochs'
(under growth, how fast stale outcomes are forgotten); window 0 keeps everything (the paper's
"stored experience is void after growth"), in gbmodel.nearest, O(goals log N) per epoch.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..growth import factors
from ..spec import Int, Number, check_fields
from ..nearest import Nearest


@dataclass(frozen=True)
class Params:
    goals: int = 2120  # per epoch: Goal Babbling's budget on arm5, V (K L + 1)
    # exploration noise [command units] (explauto's default; too little learns the grid points
    # only: docs/baselines.md)
    sigma: float = 0.1
    window: int = 10  # epochs whose examples are kept; 0: every example

    def validate(self) -> "Params":
        check_fields(self, "learner", LIMITS)
        return self


LIMITS = dict(goals=Int(1, 10**6), sigma=Number(0.0, 100.0), window=Int(0, 10_000))


@dataclass(frozen=True)
class State:
    outcomes: np.ndarray  # (window, goals, n) x of each stored example, one row per epoch
    commands: np.ndarray  # (window, goals, m) q of each stored example
    home: tuple  # (x_home, q_home): the first example, kept until the window is full
    epochs: int = 0  # epochs trained so far


@dataclass(frozen=True)
class Everything:
    """window 0: the first `count` examples of a growing Nearest (a state trained on again
    after it grew gets a copy of its own)."""
    store: Nearest
    count: int
    epochs: int = 0

    def own(self) -> Nearest:
        return self.store if self.store.count == self.count else self.store.copy_first(self.count)


def init(params: Params, body, size: float, rng: np.random.Generator):
    q_home = body.saturate(body.home)
    x_home = body.forward(q_home, factors(body, size))
    if params.window == 0:
        store = Nearest(body.n, body.m)
        store.add(x_home[None], q_home[None])
        return Everything(store, store.count)
    return State(np.zeros((params.window, params.goals, body.n)),
                 np.zeros((params.window, params.goals, body.m)), (x_home, q_home))


def memory(state) -> tuple[np.ndarray, np.ndarray]:
    if isinstance(state, Everything):
        store = state.own()
        return store.points, store.values
    filled = min(state.epochs, len(state.outcomes))
    x = state.outcomes[:filled].reshape(-1, state.outcomes.shape[-1])
    q = state.commands[:filled].reshape(-1, state.commands.shape[-1])
    if state.epochs < len(state.outcomes):
        x, q = np.concatenate([state.home[0][None], x]), np.concatenate([state.home[1][None], q])
    return x, q


def draw(params: Params, body, B: int, rng: np.random.Generator) -> tuple:
    idx = rng.integers(0, len(body.targets), size=(B, params.goals))
    return idx, rng.standard_normal((B, params.goals, body.m))


def train(state, params: Params, body, sizes, scales, draws, epochs=None):
    idx, noise = draws
    if isinstance(state, Everything):
        store = state.own()
        for e in range(len(sizes)):
            goals = body.target_set(sizes[e])[idx[e]]
            q = body.saturate(store.values[store.query(goals)] + params.sigma * noise[e])
            store.add(body.forward(q, scales[e]), q)
        return Everything(store, store.count, state.epochs + len(sizes))
    outcomes, commands, done = state.outcomes.copy(), state.commands.copy(), state.epochs
    for e in range(len(sizes)):
        known_x, known_q = memory(State(outcomes, commands, state.home, done))
        goals = body.target_set(sizes[e])[idx[e]]
        _, nearest = cKDTree(known_x).query(goals)
        q = body.saturate(known_q[nearest] + params.sigma * noise[e])
        slot = done % params.window
        outcomes[slot], commands[slot] = body.forward(q, scales[e]), q
        done += 1
    return State(outcomes, commands, state.home, done)


def predict(state, params: Params, body, x) -> np.ndarray:
    if isinstance(state, Everything):
        store = state.own()
        return store.values[store.query(np.asarray(x, dtype=np.float64))]
    known_x, known_q = memory(state)
    _, nearest = cKDTree(known_x).query(np.asarray(x, dtype=np.float64))
    return known_q[nearest]


def model(state: State) -> None:
    return None


def samples_per_epoch(params: Params, body) -> int:
    return params.goals


def sample_cost(params: Params) -> float:
    return 300.0
