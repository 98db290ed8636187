"""Which targets a goal-directed learner aims at: `random` (the paper's: uniform over the target
set) or `progress`, goals chosen by learning progress, in the spirit of intrinsically motivated
goal exploration (Baranes & Oudeyer's SAGG-RIAC: interest = the change of competence in a region).

progress (not the paper's; the numbers below are chosen here, not tuned):
- the target set is split into regions: each axis of the target box halved at its centre (2^n
  regions: 4 on the planar arms, 8 on the iCub), a target belongs to the half it lies in (the
  centre itself to the lower one);
- every `period` epochs (10) the learner's own reaching error |f(g(x*)) - x*| is measured at every
  target of the set (the unperturbed inverse, at the body's current size: N reaching movements,
  counted in the learner's samples per epoch); a region's error is the mean over its targets;
- its progress is |mean of its last `window` (3) errors - mean of the `window` before them|, the
  recent change of its error, whichever the sign (forgetting after growth is interesting too);
- a target is drawn with probability share / N + (1 - share) progress_r / (sum of the regions'
  progress) / N_r (share = 0.2, the small random part that keeps every region visited; N_r the
  region's targets); uniform until 2 window measurements exist or while no region progresses.
The uniform numbers behind each choice are drawn by the learner's `draw` (from the Generator
passed in), one per target; the choice itself happens in `train`, where the errors are known.
Successive targets may repeat (as with targets=any): a repeat is a still segment.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .spec import MAX_EPOCHS, Choice, Int, Number, check_fields

SELECTIONS = ("random", "progress")


# a learner's goal-selection fields and their ranges (a part of its Params.LIMITS)
LIMITS = dict(goal_selection=Choice(*SELECTIONS), progress_period=Int(1, MAX_EPOCHS),
              progress_window=Int(1, 10_000), progress_share=Number(0.0, 1.0))


def check(params) -> None:
    """Validate a learner's goal-selection fields (goal_selection, progress_*)."""
    check_fields(params, "learner", LIMITS)


def regions(targets: np.ndarray) -> np.ndarray:
    """Region index (N,) of each target: the halves of the box it lies in, as bits."""
    lo, hi = targets.min(axis=0), targets.max(axis=0)
    upper = targets > 0.5 * (lo + hi)
    return (upper * (2 ** np.arange(targets.shape[1]))).sum(axis=1)


def probabilities(progress: np.ndarray | None, region: np.ndarray, share: float) -> np.ndarray:
    """p (N,) over the targets from the regions' progress (indexed by region number)."""
    N = len(region)
    uniform = np.full(N, 1.0 / N)
    if progress is None or not np.isfinite(progress).all() or progress.sum() <= 0:
        return uniform
    per_region = np.bincount(region, minlength=len(progress))
    p_region = progress / progress.sum()
    return share * uniform + (1.0 - share) * p_region[region] / per_region[region]


def choose(u: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Target indices for uniform numbers u in [0, 1) (any shape) under p: inverse CDF."""
    cdf = np.cumsum(p)
    return np.minimum(np.searchsorted(cdf, u * cdf[-1], side="right"), len(p) - 1)


@dataclass(frozen=True)
class Tracker:
    """The regions' error measurements so far (oldest first), at most 2 window kept."""
    history: tuple = ()  # tuples of the regions' mean errors
    n_regions: int = 1

    def measured(self, errors: np.ndarray, region: np.ndarray, window: int) -> "Tracker":
        """The tracker after one more measurement: per-target errors (N,)."""
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


def reaching_errors(predict, body, size: float, scale) -> np.ndarray:
    """|f(g(x*)) - x*| at every target of the set at `size` (the unperturbed inverse)."""
    xs = body.target_set(size)
    return np.linalg.norm(body.forward(predict(xs), scale) - xs, axis=-1)


def chunks(epochs: np.ndarray, period: int) -> list[tuple[int, int, bool]]:
    """(lo, hi, measure) slices of a train call's epochs (1-based numbers `epochs`), cut after
    every epoch that is a multiple of period (measure: the slice ends on one), so that the
    choices never depend on how the trial splits its train calls."""
    out, lo = [], 0
    for i, e in enumerate(np.asarray(epochs)):
        if e % period == 0 or i == len(epochs) - 1:
            out.append((lo, i + 1, bool(e % period == 0)))
            lo = i + 1
    return out


def samples(body, period: int) -> int:
    """Reaching movements per epoch spent on measuring (N every period epochs, rounded up)."""
    return -(-len(body.targets) // period)
