"""A body's workspace sampled from random postures within the limits, and its reach."""
from __future__ import annotations

import numpy as np

from .bodies import Body

SAMPLES = 20_000  # postures sampled (the reach of the shipped bodies to within 1 %)
SEED = 0  # a body's reach is the same in every run


def hand_samples(body: Body, samples: int = SAMPLES, seed: int = SEED,
                 factors=None) -> np.ndarray:
    box = 1.0 if body.normalized else np.pi
    q = np.random.default_rng(seed).uniform(-box, box, size=(samples, body.m))
    return body.forward(q, factors)


def diameter(points: np.ndarray) -> float:
    """The largest distance between two points, over the 512 farthest from the centre and a
    double-normal search's pair (in practice the farthest pair)."""
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
    """Half the largest distance between two hand positions [m] (arm5: 1.0)."""
    return 0.5 * diameter(hand_samples(body, samples, seed, factors))
