"""How well an inverse estimate reaches, the one evaluation of every learner: the mean distance
between each point x* and the hand at f(g(x*)) (eq. 10), the body at its current size; the
relative error divides by the size (eq. 11). The readings the paper leaves open are options
(DEFAULTS; docs/choices.md). A learner may compute the distances itself (`distances`); the
formula is applied here with a correctly rounded sum (math.fsum's), the same on every CPU.
"""
from __future__ import annotations

import math

import numpy as np

from .bodies import Body, cell_centres

POINTS = ("grid", "path", "centres", "heldout")
FORMULAS = ("mean", "mean_squared", "rms")
DEFAULTS = dict(points="grid", formula="mean", path_steps=7)
# The held-out set, scored in every trial: the cell centres and HELDOUT_UNIFORM points uniform
# in the target box (seed HELDOUT_SEED), scaled with the body (200: a mean's standard error
# about 7 % of its spread).
HELDOUT_SEED = 20100907  # fixed once; any other would do
HELDOUT_UNIFORM = 200
# The path targets, scored in every trial: eq. 10's points, x* on eq. 9's paths. Their mean over
# every ordered pair and every step (points="path": 40,320 on the iCub) is sampled without bias
# by every ordered pair once at one step drawn from PATH_SEED (4,032 points on the iCub).
PATH_SEED = 20100910  # fixed once; any other would do


def heldout_points(body: Body, size: float = 1.0) -> np.ndarray:
    """The held-out set (N, n) at `size`: cell centres, then the uniform points."""
    def build(t):
        lo, hi = body.target_box(1.0)
        uniform = np.random.default_rng(HELDOUT_SEED).uniform(lo, hi, size=(HELDOUT_UNIFORM,
                                                                           len(lo)))
        return np.concatenate([cell_centres(body.targets), uniform])
    return _cached(body, ("heldout",), build) * size


_CACHE: dict = {}  # point sets by the targets' bytes and their settings


def _cached(body: Body, settings: tuple, build) -> np.ndarray:
    """build(targets), once per process and targets' bytes and settings (read-only): a set
    depends on them alone."""
    t = np.ascontiguousarray(body.targets)
    key = (settings, t.shape, t.dtype.str, t.tobytes())
    out = _CACHE.get(key)
    if out is None:
        out = build(t)
        out.flags.writeable = False
        if len(_CACHE) >= 64:
            _CACHE.clear()
        _CACHE[key] = out
    return out


def path_targets(body: Body, steps: int, size: float = 1.0) -> np.ndarray:
    """The sampled path targets (N (N - 1), n) at `size` for L = `steps`: each ordered pair of
    distinct targets (a, b) once, at (1 - l / L) x*_a + l / L x*_b."""
    def build(t):
        pairs = len(t) * (len(t) - 1)
        return _on_paths(t, np.random.default_rng(PATH_SEED).integers(0, steps, (pairs, 1)) / steps)
    return _cached(body, ("path", steps), build) * size


def _on_paths(t, frac) -> np.ndarray:
    """(1 - f) x*_a + f x*_b, every ordered pair (a, b) of distinct targets at its row of the
    fractions frac (pairs, L) (eq. 9's path points)."""
    a, b = np.nonzero(~np.eye(len(t), dtype=bool))
    path = (1.0 - frac)[..., None] * t[a][:, None, :] + frac[..., None] * t[b][:, None, :]
    return path.reshape(-1, t.shape[1])


def eval_epochs(epochs: int, per_decade: int = 20) -> np.ndarray:
    """Log-spaced evaluation epochs 1 ... epochs, about per_decade per decade."""
    k = np.arange(0, int(np.floor(per_decade * np.log10(epochs))) + 1)
    e = np.unique(np.round(10.0 ** (k / per_decade)).astype(np.int64))
    return np.union1d(e[e <= epochs], [1, epochs])


def eval_points(body: Body, size: float, which: str = "grid", path_steps: int = 7) -> np.ndarray:
    if which == "grid":
        return body.target_set(size)
    if which == "centres":
        return cell_centres(body.targets) * size
    if which == "heldout":
        return heldout_points(body, size)
    if which == "path":
        return _on_paths(body.targets, (np.arange(path_steps) / path_steps)[None]) * size
    raise ValueError(f"evaluation.points={which!r}: choose one of {list(POINTS)}")


def distances(predict, body: Body, scale, xs: np.ndarray) -> np.ndarray:
    return np.linalg.norm(body.forward(predict(xs), scale) - xs, axis=-1)


def _fsum(d: np.ndarray) -> float:
    """math.fsum of d's values, by simd.fsum (the same bits, no list of Python floats: a short
    trial's 40 evaluation sums cost it 2 ms that way); math.fsum answers a non-finite one."""
    from .simd import fsum  # numba's: loaded by a trial's kernels already

    total, ok = fsum(d)
    return float(total) if ok else math.fsum(d.tolist())


def error(d: np.ndarray, formula: str = "mean") -> float:
    d = np.asarray(d, dtype=np.float64)
    if formula == "mean":
        return _fsum(d) / len(d)
    if formula == "mean_squared":
        return _fsum(d * d) / len(d)
    if formula == "rms":
        return math.sqrt(_fsum(d * d) / len(d))
    raise ValueError(f"evaluation.formula={formula!r}: choose one of {list(FORMULAS)}")


def evaluate(learner, state, params, body: Body, size: float, scale, points: str = "grid",
             formula: str = "mean", path_steps: int = 7, xs: np.ndarray | None = None) -> float:
    """The absolute error of a learner's state, the body at `size` (factors `scale`); xs: the
    points at size 1 (eval_points(body, 1.0, ...)), scaled here (the same values)."""
    xs = eval_points(body, size, points, path_steps) if xs is None else xs * size
    return error(point_distances(learner, state, params, body, scale, xs), formula)


def point_distances(learner, state, params, body: Body, scale, xs: np.ndarray) -> np.ndarray:
    if hasattr(learner, "distances"):
        return learner.distances(state, params, body, scale, xs)
    return distances(lambda x: learner.predict(state, params, body, x), body, scale, xs)


def lines(body: Body, size: float, points: int = 201) -> np.ndarray:
    """(n, points, n): per axis a line through the target box's centre, face to face."""
    lo, hi = body.target_box(size)
    centre = 0.5 * (lo + hi)
    out = np.repeat(centre[None, None, :], body.n, axis=0).repeat(points, axis=1)
    for j in range(body.n):
        out[j, :, j] = np.linspace(lo[j], hi[j], points)
    return out


def largest_jump(predict, body: Body, size: float, points: int = 201) -> float:
    """The redundancy measure: the largest step |q(x_k+1) - q(x_k)| of the inverse between
    neighbouring points of `lines` (command units): an inverse that switches between redundant
    solutions, or a lookup table, jumps."""
    cached = _cached(body, ("lines", float(size), points), lambda t: lines(body, size, points))
    steps = [np.linalg.norm(np.diff(predict(line.copy()), axis=0), axis=-1).max()
             for line in cached]
    return float(max(steps))
