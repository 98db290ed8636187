"""One trial: a growing body learns by Goal Babbling; returns its learning curve.

Random draws are made in blocks of DRAW_BLOCK epochs, in a fixed order (initialisation, then per
block: target indices, then perturbations), so that the fast and the reference paths consume the
same numbers and the result does not depend on where the curve is evaluated or snapshot.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from . import learner
from .bodies import BODIES, GROWTH_PATTERNS, Body, make_body
from .features import exponents

DRAW_BLOCK = 1000

# Learning rate eta of the normalised gradient step (learner.gradient_step); the paper gives none.
# 1.0 was chosen on convergence before the full run: on arm5 (20k epochs, 3 seeds) 0.5 -> 22 mm,
# 1.0 -> 20 mm, 1.5 -> 28 mm with oscillation, and larger rates are worse still; on the iCub 0.5,
# 1.0 and 1.5 end alike (16-17 mm). The measured table is `make choices` (outputs/report/choices.md).
DEFAULT_LEARNING_RATE = 1.0


@dataclass(frozen=True)
class TrialSpec:
    """Plain parameters of one trial (defaults: the paper's 5-DOF arm settings, sec. 3.1)."""

    body: str = "arm5"
    pattern: str = "proportional"  # which segments grow (GROWTH_PATTERNS)
    start_size: float = 0.5  # size factor in the first epoch
    end_size: float = 1.0  # size factor after growth
    period: int = 0  # T_G: epochs over which the size goes linearly from start to end
    epochs: int = 1000
    variations: int = 20  # V
    radius: float = 0.2  # R, bound of the exploratory disturbance
    targets_per_epoch: int = 15  # K
    steps: int = 7  # L, linear steps between successive targets
    learning_rate: float = DEFAULT_LEARNING_RATE  # eta
    init_range: float = 0.1  # |g(x) - home| bound at initialisation
    degree: int = 3  # P, polynomial degree of the features
    evals_per_decade: int = 20
    snapshot_epochs: tuple = ()  # epochs after which a copy of M is kept

    def validate(self) -> "TrialSpec":
        """Raise ValueError naming the first bad value."""
        def bad(name, why):
            raise ValueError(f"{name}={getattr(self, name)!r}: {why}")

        if self.body not in BODIES:
            bad("body", f"unknown body; choose one of {sorted(BODIES)}")
        if self.pattern not in GROWTH_PATTERNS:
            bad("pattern", f"unknown growth pattern; choose one of {list(GROWTH_PATTERNS)}")
        for name in ("epochs", "variations", "targets_per_epoch", "steps", "degree",
                     "evals_per_decade"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                bad(name, "must be a positive integer")
        if isinstance(self.period, bool) or not isinstance(self.period, (int, np.integer)) \
                or self.period < 0:
            bad("period", "must be a non-negative integer (epochs of growth)")
        for name in ("start_size", "end_size", "learning_rate", "radius", "init_range"):
            v = getattr(self, name)
            if not isinstance(v, (int, float)) or not math.isfinite(v):
                bad(name, "must be a finite number")
        for name in ("start_size", "end_size", "learning_rate"):
            if getattr(self, name) <= 0:
                bad(name, "must be > 0")
        for name in ("radius", "init_range"):
            if getattr(self, name) < 0:
                bad(name, "must be >= 0")
        body = make_body(self.body)
        for name in ("start_size", "end_size"):
            try:
                body.segment_scale(getattr(self, name), self.pattern)
            except ValueError as err:
                bad(name, str(err))
        for e in self.snapshot_epochs:
            if not 1 <= e <= self.epochs:
                bad("snapshot_epochs", f"epoch {e} is outside 1 ... {self.epochs}")
        return self

    def to_dict(self) -> dict:
        d = asdict(self)
        d["snapshot_epochs"] = list(self.snapshot_epochs)
        return d


@dataclass
class TrialResult:
    epoch: np.ndarray  # (E,) epochs after which the curve was evaluated (1-based)
    size: np.ndarray  # (E,) size factor of the body in that epoch
    abs_error: np.ndarray  # (E,) mean distance target-hand [m]
    rel_error: np.ndarray  # (E,) abs_error / size
    M: np.ndarray  # (m, p) final inverse estimate
    snapshots: dict = field(default_factory=dict)  # epoch -> M after that epoch


def size_schedule(spec: TrialSpec, epochs: np.ndarray | None = None) -> np.ndarray:
    """Size factor during epochs e = 1 ... : linear from start_size (e = 1) to end_size
    (e = T_G + 1) and constant afterwards; T_G = 0 means end_size from the start."""
    e = np.arange(1, spec.epochs + 1) if epochs is None else np.asarray(epochs)
    if spec.period == 0:
        return np.full(e.shape, float(spec.end_size))
    frac = np.clip((e - 1) / spec.period, 0.0, 1.0)
    return spec.start_size + (spec.end_size - spec.start_size) * frac


def eval_epochs(epochs: int, per_decade: int = 20) -> np.ndarray:
    """Log-spaced evaluation epochs 1 ... epochs, about per_decade per decade, both ends included."""
    k = np.arange(0, int(np.floor(per_decade * np.log10(epochs))) + 1)
    e = np.unique(np.round(10.0 ** (k / per_decade)).astype(np.int64))
    return np.union1d(e[e <= epochs], [1, epochs])


def run_trial(spec: TrialSpec, rng: np.random.Generator, fast: bool = True,
              body: Body | None = None) -> TrialResult:
    """Run one trial of Goal Babbling and return its learning curve.

    fast=True runs the compiled kernel (gbmodel.fast), fast=False the numpy reference path; both
    consume the same random numbers and agree to rounding. `body` replaces make_body(spec.body),
    for variants of a body (another target set, home posture or limit handling).
    """
    spec.validate()
    body = make_body(spec.body) if body is None else body
    exps = exponents(body.n, spec.degree)
    sizes = size_schedule(spec)
    M = learner.init_inverse(body.home, *body.target_box(sizes[0]), exps, spec.init_range, rng)

    evals = eval_epochs(spec.epochs, spec.evals_per_decade)
    is_eval = np.zeros(spec.epochs + 1, bool)
    is_eval[evals] = True
    cuts = set(spec.snapshot_epochs)
    abs_error = np.empty(spec.epochs + 1)
    snapshots = {}
    step = _fast_block if fast else _reference_block
    shape = dict(V=spec.variations, m=body.m, n=body.n, K=spec.targets_per_epoch)
    for start in range(0, spec.epochs, DRAW_BLOCK):  # epochs start+1 ... stop
        stop = min(start + DRAW_BLOCK, spec.epochs)
        idx, raw = _draw(rng, stop - start, len(body.targets), **shape)
        bounds = sorted({start, stop} | {e for e in cuts if start < e < stop})
        for lo, hi in zip(bounds[:-1], bounds[1:]):
            sl = slice(lo - start, hi - start)
            M = step(M, body, spec, exps, sizes[lo:hi], idx[sl], raw[sl], is_eval[lo + 1:hi + 1],
                     abs_error[lo + 1:hi + 1])
            if hi in cuts:
                snapshots[hi] = M.copy()
    size = sizes[evals - 1]
    err = abs_error[evals]
    return TrialResult(epoch=evals, size=size, abs_error=err, rel_error=err / size, M=M,
                       snapshots=snapshots)


def _draw(rng, B, n_targets, V, m, n, K):
    """Random numbers of B epochs: target indices (B, K+1), raw disturbances (B, V, m, n+1).

    Successive targets of a path differ (the next is uniform over the other n_targets - 1), so
    that every path step is a movement with a direction.
    """
    first = rng.integers(0, n_targets, size=(B, 1))
    hops = rng.integers(1, n_targets, size=(B, K))
    idx = np.cumsum(np.concatenate([first, hops], axis=1), axis=1) % n_targets
    raw = rng.uniform(-1.0, 1.0, size=(B, V, m, n + 1))
    return idx, raw


def _reference_block(M, body, spec, exps, sizes, idx, raw, is_eval, abs_out):
    for e in range(len(sizes)):
        M, _ = learner.epoch(M, body, sizes[e], spec.pattern, exps, idx[e], raw[e], spec.radius,
                             spec.steps, spec.learning_rate)
        if is_eval[e]:
            abs_out[e] = learner.evaluate(M, body, sizes[e], spec.pattern, exps)
    return M


def _fast_block(M, body, spec, exps, sizes, idx, raw, is_eval, abs_out):
    from . import fast

    return fast.run_block(M, body, spec, exps, sizes, idx, raw, is_eval, abs_out)
