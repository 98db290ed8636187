"""A body's workspace, sampled: where its hand can be with every joint within its limits, how far
it reaches, and a target grid inside it.

All from hand positions of random postures within the limits (uniform commands: [-1, 1] where
normalised, else [-pi, pi]): a sampled workspace, not a guess from the link lengths. The
pipeline's body inspector (`python -m pipeline.tools.body`) prints them; the aggregate stage
states held-out errors in % of `reach`.
"""
from __future__ import annotations

import numpy as np

from .bodies import Body, unreachable

SAMPLES = 20_000  # postures sampled (the reach of the shipped bodies to within 1 %)
SEED = 0  # a body's reach and proposed grid are the same in every run


def hand_samples(body: Body, samples: int = SAMPLES, seed: int = SEED,
                 factors=None) -> np.ndarray:
    """Hand positions (samples, n) of random postures within the limits [m]."""
    box = 1.0 if body.normalized else np.pi
    q = np.random.default_rng(seed).uniform(-box, box, size=(samples, body.m))
    return body.forward(q, factors)


def diameter(points: np.ndarray) -> float:
    """The largest distance between two of `points` (N, n): exact over the 512 points farthest
    from their centre and the pair a double-normal search finds, which hold the farthest pair of
    a workspace's samples in practice."""
    p = np.asarray(points, np.float64)
    if len(p) < 2:
        return 0.0
    d0 = np.linalg.norm(p - p.mean(axis=0), axis=1)
    candidates = set(np.argsort(d0)[-512:].tolist())
    a = int(np.argmax(d0))
    for _ in range(4):  # a -> the point farthest from a -> ...: a double normal of the set
        b = int(np.argmax(np.linalg.norm(p - p[a], axis=1)))
        candidates |= {a, b}
        a = b
    c = p[sorted(candidates)]
    return float(np.sqrt(((c[:, None, :] - c[None]) ** 2).sum(-1)).max())


def reach(body: Body, factors=None, samples: int = SAMPLES, seed: int = SEED) -> float:
    """The body's reach [m]: half the largest distance between two hand positions within the
    limits (an arm that turns about its shoulder: the radius of its workspace about it; the
    5-DOF arm: 1.0 m)."""
    return 0.5 * diameter(hand_samples(body, samples, seed, factors))


def propose_grid(body: Body, num=None, bins: int = 12, least: int = 3, side: float = 0.6,
                 samples: int = SAMPLES, seed: int = SEED) -> dict | None:
    """A target grid (dict(lo, hi, num), as a body file's `grid:`) inside the sampled workspace,
    around the hand's home position (where Goal Babbling starts), whose every target some
    posture within the limits reaches (unreachable, at full and half size): the workspace's
    bounding box cut into `bins` cells per axis; a box of cells grown from the home cell while
    every cell it takes holds at least `least` samples and no side exceeds `side` x the reach;
    its cells' centres as the grid's bounds, shrunk about its centre until every target is
    reached. num: points per axis (the body's own grid's when it has as many axes; else 4).
    None when no such box is found."""
    x = hand_samples(body, samples, seed)
    n = x.shape[1]
    num = list(num) if num is not None and len(num) == n else [4] * n
    lo, hi = x.min(axis=0), x.max(axis=0)
    width = np.where(hi > lo, (hi - lo) / bins, 1.0)
    cell = np.clip(((x - lo) / width).astype(int), 0, bins - 1)
    counts = np.zeros((bins,) * n, int)
    np.add.at(counts, tuple(cell.T), 1)
    full = counts >= least
    home = np.clip(((body.forward(body.home) - lo) / width).astype(int), 0, bins - 1)
    box = [[int(h), int(h)] for h in home]  # per axis the first and last cell taken
    longest = side * 0.5 * diameter(x)

    def covered(b) -> bool:
        return (all((z - a) * w <= longest for (a, z), w in zip(b, width))
                and bool(full[tuple(slice(a, z + 1) for a, z in b)].all()))

    grown = True
    while grown:
        grown = False
        for axis in range(n):
            for side, step in ((0, -1), (1, 1)):
                trial = [list(b) for b in box]
                trial[axis][side] += step
                if 0 <= trial[axis][side] < bins and covered(trial):
                    box, grown = trial, True
    b_lo = lo + (np.array([b[0] for b in box]) + 0.5) * width
    b_hi = lo + (np.array([b[1] for b in box]) + 0.5) * width
    centre = 0.5 * (b_lo + b_hi)
    from dataclasses import replace

    from .bodies import grid_points

    for shrink in (1.0, 0.8, 0.6, 0.4, 0.2):
        g_lo, g_hi = centre - shrink * (centre - b_lo), centre + shrink * (centre - b_lo)
        grid = dict(lo=[round(float(v), 3) for v in g_lo], hi=[round(float(v), 3) for v in g_hi],
                    num=[int(k) for k in num])
        if any(h <= low for low, h in zip(grid["lo"], grid["hi"])):
            return None
        candidate = replace(body, targets=grid_points(**grid))
        if all(unreachable(candidate, np.random.default_rng(seed), size=s).size == 0
               for s in (1.0, 0.5)):
            return grid
    return None
