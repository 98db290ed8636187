"""A body's workspace, sampled: where its hand can be with every joint within its limits, and
how far it reaches.

All from hand positions of random postures within the limits (uniform commands: [-1, 1] where
normalised, else [-pi, pi]): a sampled workspace, not a guess from the link lengths. The
pipeline's body inspector (`python -m pipeline.tools.body`) prints them; the aggregate stage
states held-out errors in % of `reach`.
"""
from __future__ import annotations

import numpy as np

from .bodies import Body

SAMPLES = 20_000  # postures sampled (the reach of the shipped bodies to within 1 %)
SEED = 0  # a body's reach is the same in every run


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
