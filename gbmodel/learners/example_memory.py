"""Memory-based goal babbling: a nearest-neighbour inverse model (as explauto's `nearest_neighbor`
sensorimotor model with goal babbling).

The inverse model is the memory itself: g(x*) is the command of the stored example whose outcome
lies nearest to x*. Each epoch draws `goals` targets from the target set at the body's current
size; for each, the body executes that command plus Gaussian exploration noise (`sigma`, command
units), saturated, and the example (x, q) it observes is stored. The memory starts with the home
example and keeps the examples of the last `window` epochs (window >= 1): at most
1 + window * goals examples, however long the trial. Outcomes are stored as observed, at the size
the body had then; under growth the window is how fast stale outcomes are forgotten.

window 0 keeps every example, the home example included: the memory the paper's "stored
experience is void after growth" is about. Its nearest neighbours come from gbmodel.nearest (k-d
trees merged like a binary counter, the same answers as one tree over everything, ties to the
oldest example), so that an epoch costs O(goals log N), not a rebuild over all N examples.
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
    # goals per epoch: Goal Babbling's sample budget on arm5, V (K L + 1) = 2120
    goals: int = 2120
    # exploration noise [command units] (explauto's default: 0.1 of the motor range; too little
    # learns the grid points only: docs/baselines.md, "Why the alternatives' defaults")
    sigma: float = 0.1
    # epochs whose examples are kept (memory <= 1 + window * goals): under growth stale outcomes
    # mislead, without growth more memory is better. 0: keep every example (gbmodel.nearest)
    window: int = 10

    def validate(self) -> "Params":
        check_fields(self, "learner", LIMITS)
        return self


# Params' fields and their ranges (gbmodel.spec.check_fields)
LIMITS = dict(goals=Int(1, 10**6), sigma=Number(0.0, 100.0), window=Int(0, 10_000))


@dataclass(frozen=True)
class State:
    outcomes: np.ndarray  # (window, goals, n) x of each stored example, one row per epoch
    commands: np.ndarray  # (window, goals, m) q of each stored example
    home: tuple  # (x_home, q_home): the first example, kept until the window is full
    epochs: int = 0  # epochs trained so far


@dataclass(frozen=True)
class Everything:
    """The state of the memory that keeps everything (window 0): the examples in a growing
    gbmodel.nearest.Nearest, of which this state owns the first `count` (a state trained on
    again after the structure grew gets a copy of its own examples)."""
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
    """Every stored example: outcomes (N, n), commands (N, m)."""
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
    """Goal indices (B, goals) into the target set, standard normal noise (B, goals, m)."""
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
    """The command of the stored example whose outcome is nearest to each x (N, n)."""
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
    """CPU time per sample and joint, relative to Goal Babbling's fast batch path (a k-d tree
    query and insertion per sample)."""
    return 300.0
