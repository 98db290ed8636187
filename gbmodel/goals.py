"""Which targets a goal-directed learner aims at: `random` (the paper's) or `progress`, after
SAGG-RIAC (Baranes & Oudeyer: interest = the change of competence in a region; not the paper's,
the numbers chosen, not tuned). The target box is halved along each axis into 2^n regions (the
centre to the lower half); every `period` epochs the unperturbed inverse's error is measured at
every target (N reaching movements, counted as samples), a region's error the mean over its
targets; its progress is |mean of the last `window` errors - mean of the window before|; a
target is drawn with probability share / N + (1 - share) progress_r / sum progress / N_r,
uniform until 2 window measurements exist or while nothing progresses. `draw` draws the uniform
numbers, `train` chooses; targets may repeat (a still segment).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .evaluation import distances
from .spec import MAX_EPOCHS, Choice, Int, Number

SELECTIONS = ("random", "progress")


# a learner's goal-selection fields and their ranges (a part of its Params.LIMITS)
LIMITS = dict(goal_selection=Choice(*SELECTIONS), progress_period=Int(1, MAX_EPOCHS),
              progress_window=Int(1, 10_000), progress_share=Number(0.0, 1.0))


def regions(targets: np.ndarray) -> np.ndarray:
    lo, hi = targets.min(axis=0), targets.max(axis=0)
    upper = targets > 0.5 * (lo + hi)
    return (upper * (2 ** np.arange(targets.shape[1]))).sum(axis=1)


def probabilities(progress: np.ndarray | None, region: np.ndarray, share: float) -> np.ndarray:
    N = len(region)
    uniform = np.full(N, 1.0 / N)
    if progress is None or not np.isfinite(progress).all() or progress.sum() <= 0:
        return uniform
    per_region = np.bincount(region, minlength=len(progress))
    p_region = progress / progress.sum()
    return share * uniform + (1.0 - share) * p_region[region] / per_region[region]


def choose(u: np.ndarray, p: np.ndarray) -> np.ndarray:
    cdf = np.cumsum(p)
    return np.minimum(np.searchsorted(cdf, u * cdf[-1], side="right"), len(p) - 1)


@dataclass(frozen=True)
class Tracker:
    history: tuple = ()  # tuples of the regions' mean errors
    n_regions: int = 1

    def measured(self, errors: np.ndarray, region: np.ndarray, window: int) -> "Tracker":
        mean = np.bincount(region, weights=errors, minlength=self.n_regions) \
            / np.maximum(np.bincount(region, minlength=self.n_regions), 1)
        return Tracker((self.history + (tuple(mean),))[-2 * window:], self.n_regions)

    def progress(self, window: int) -> np.ndarray | None:
        if len(self.history) < 2 * window:
            return None
        h = np.array(self.history)
        return np.abs(h[window:].mean(axis=0) - h[:window].mean(axis=0))


def start(targets: np.ndarray) -> Tracker:
    return Tracker((), int(regions(targets).max()) + 1 if len(targets) else 1)


def first(predict, body, size: float, window: int) -> Tracker:
    """The tracker after its first measurement, the body at `size` (a learner's init)."""
    errors = distances(predict, body, np.ones(body.m), body.target_set(size))
    return start(body.targets).measured(errors, regions(body.targets), window)


def train(state, tracker: Tracker, params, body, sizes, scales, draws, epochs, step, predict):
    """(state, tracker) after goal_selection=progress's epochs: chunks cut at the measurements,
    step(state, targets, lo, hi) learns epochs lo ... hi - 1 aiming at the chosen targets (from
    the uniform numbers draws[0]), predict(state, x) is the inverse measured."""
    region = regions(body.targets)
    for lo, hi, measure in chunks(epochs, params.progress_period):
        p = probabilities(tracker.progress(params.progress_window), region,
                          params.progress_share)
        state = step(state, choose(draws[0][lo:hi], p), lo, hi)
        if measure:
            errors = distances(lambda x: predict(state, x), body, scales[hi - 1],
                               body.target_set(sizes[hi - 1]))
            tracker = tracker.measured(errors, region, params.progress_window)
    return state, tracker


def extra_samples(params, body) -> int:
    """Reaching movements per epoch spent on measuring (progress; N every period, rounded up)."""
    if params.goal_selection != "progress":
        return 0
    return -(-len(body.targets) // params.progress_period)


def chunks(epochs: np.ndarray, period: int) -> list[tuple[int, int, bool]]:
    """(lo, hi, measure) slices of `epochs`, cut after each multiple of period, so the choices
    never depend on how the trial splits its train calls."""
    out, lo = [], 0
    for i, e in enumerate(np.asarray(epochs)):
        if e % period == 0 or i == len(epochs) - 1:
            out.append((lo, i + 1, bool(e % period == 0)))
            lo = i + 1
    return out
