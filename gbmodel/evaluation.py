"""How well an inverse estimate reaches: the one evaluation of every learner.

The absolute error is the mean Euclidean distance between each evaluation point x* and the hand
at f(g(x*)) (paper eq. 10, "the average positioning error in meters"), with the body at its
current size; the relative error divides by the size factor (eq. 11).

Where the paper leaves the reading open, each reading is an option (config `evaluation`,
DEFAULTS; docs/choices.md measures them): points grid (the default), path (eq. 10's path
targets in expectation) or centres (off-grid); formula mean (the default), mean_squared or rms.
A learner may compute the distances itself (`distances`, e.g. in its compiled kernel); the
error formula is applied here, with an exactly rounded sum (math.fsum), so that the error does
not depend on the order in which a CPU's vector units add.
"""
from __future__ import annotations

import math

import numpy as np

from .bodies import Body, cell_centres

POINTS = ("grid", "path", "centres", "heldout")
FORMULAS = ("mean", "mean_squared", "rms")
DEFAULTS = dict(points="grid", formula="mean", path_steps=7)
# The held-out set, scored beside the chosen points in every trial (TrialResult.heldout_abs_error):
# points no learner is told to reach, fixed for every trial and learner: the cell centres (the
# points farthest from the grid) and HELDOUT_UNIFORM points uniform in the target box at full
# size, from the fixed seed HELDOUT_SEED, all scaled with the body like the targets. 200 uniform
# points: the standard error of a mean distance over them is about 7 % of its spread.
HELDOUT_SEED = 20100907  # fixed once; any other would do
HELDOUT_UNIFORM = 200
# The path targets, also scored in every trial (TrialResult.path_abs_error): the points eq. 10
# sums over, x* on the straight paths of eq. 9 between successive targets. Their expectation over
# an epoch's random targets is the mean over every ordered pair of distinct targets and every
# step l = 0 ... L-1 (points="path"); that is 40,320 points on the iCub (L = 10), a third of a
# 100,000-epoch trial's time at 101 evaluations. Scored here instead: every ordered pair once, at
# one step l drawn uniformly from PATH_SEED (an unbiased, stratified sample of the same mean: 4,032
# points on the iCub, 4,290 on the 5-DOF arm).
PATH_SEED = 20100910  # fixed once; any other would do


def heldout_points(body: Body, size: float = 1.0) -> np.ndarray:
    """The held-out set (N, n) of the body at `size`: cell centres, then the uniform points.
    The set at size 1 depends on the body's targets alone: built once per process and targets
    (by their bytes), then scaled (the same values as built anew)."""
    t = np.ascontiguousarray(body.targets)
    key = (t.shape, t.dtype.str, t.tobytes())
    unit = _HELDOUT.get(key)
    if unit is None:
        lo, hi = body.target_box(1.0)
        uniform = np.random.default_rng(HELDOUT_SEED).uniform(lo, hi, size=(HELDOUT_UNIFORM,
                                                                           len(lo)))
        unit = np.concatenate([cell_centres(body.targets), uniform])
        unit.flags.writeable = False
        if len(_HELDOUT) >= 64:
            _HELDOUT.clear()
        _HELDOUT[key] = unit
    return unit * size


_HELDOUT: dict = {}  # the held-out set and path targets at size 1 by the targets' bytes


def path_targets(body: Body, steps: int, size: float = 1.0) -> np.ndarray:
    """The sampled path targets (N (N - 1), n) of the body at `size` for L = `steps` (above):
    each ordered pair of distinct targets (a, b) once, at (1 - l / L) x*_a + l / L x*_b."""
    t = np.ascontiguousarray(body.targets)
    key = ("path", steps, t.shape, t.dtype.str, t.tobytes())
    unit = _HELDOUT.get(key)
    if unit is None:
        a, b = np.nonzero(~np.eye(len(t), dtype=bool))
        frac = np.random.default_rng(PATH_SEED).integers(0, steps, size=len(a)) / steps
        unit = (1.0 - frac)[:, None] * t[a] + frac[:, None] * t[b]
        unit.flags.writeable = False
        if len(_HELDOUT) >= 64:
            _HELDOUT.clear()
        _HELDOUT[key] = unit
    return unit * size


def eval_epochs(epochs: int, per_decade: int = 20) -> np.ndarray:
    """Log-spaced evaluation epochs 1 ... epochs, about per_decade per decade, both ends included."""
    k = np.arange(0, int(np.floor(per_decade * np.log10(epochs))) + 1)
    e = np.unique(np.round(10.0 ** (k / per_decade)).astype(np.int64))
    return np.union1d(e[e <= epochs], [1, epochs])


def eval_points(body: Body, size: float, which: str = "grid", path_steps: int = 7) -> np.ndarray:
    """The evaluation points (N, n) of the body at `size`."""
    if which == "grid":
        return body.target_set(size)
    if which == "centres":
        return cell_centres(body.targets) * size
    if which == "heldout":
        return heldout_points(body, size)
    if which == "path":
        t = body.targets
        a, b = np.nonzero(~np.eye(len(t), dtype=bool))  # every ordered pair of distinct targets
        frac = (np.arange(path_steps) / path_steps)[None, :, None]
        path = (1.0 - frac) * t[a][:, None, :] + frac * t[b][:, None, :]
        return path.reshape(-1, t.shape[1]) * size
    raise ValueError(f"evaluation.points={which!r}: choose one of {list(POINTS)}")


def distances(predict, body: Body, scale, xs: np.ndarray) -> np.ndarray:
    """|f(g(x*)) - x*| for every point x* (rows of xs), the body at per-joint factors `scale`."""
    return np.linalg.norm(body.forward(predict(xs), scale) - xs, axis=-1)


def error(d: np.ndarray, formula: str = "mean") -> float:
    # math.fsum of a list of floats: the same correctly rounded sum, about twice as fast as over
    # the array's numpy scalars (an evaluation per curve point of every trial)
    d = np.asarray(d, dtype=np.float64)
    if formula == "mean":
        return math.fsum(d.tolist()) / len(d)
    if formula == "mean_squared":
        return math.fsum((d * d).tolist()) / len(d)
    if formula == "rms":
        return math.sqrt(math.fsum((d * d).tolist()) / len(d))
    raise ValueError(f"evaluation.formula={formula!r}: choose one of {list(FORMULAS)}")


def evaluate(learner, state, params, body: Body, size: float, scale, points: str = "grid",
             formula: str = "mean", path_steps: int = 7, xs: np.ndarray | None = None) -> float:
    """The absolute error of a learner's state, with the body at size `size` (per-joint length
    factors `scale`): the learner's own `distances` if it has one, else f(predict(x*)) here.
    xs: the points of `points` at size 1, built once by the caller (eval_points(body, 1.0, ...)),
    scaled here to `size`: the same values as eval_points(body, size, ...) builds."""
    xs = eval_points(body, size, points, path_steps) if xs is None else xs * size
    return error(point_distances(learner, state, params, body, scale, xs), formula)


def point_distances(learner, state, params, body: Body, scale, xs: np.ndarray) -> np.ndarray:
    """|f(g(x*)) - x*| at the points xs (N, n): the learner's own `distances` if it has one."""
    if hasattr(learner, "distances"):
        return learner.distances(state, params, body, scale, xs)
    return distances(lambda x: learner.predict(state, params, body, x), body, scale, xs)


def lines(body: Body, size: float, points: int = 201) -> np.ndarray:
    """Straight lines through the target box at `size`: one per axis, through the box's centre,
    `points` points each from one face to the other: (n, points, n)."""
    lo, hi = body.target_box(size)
    centre = 0.5 * (lo + hi)
    out = np.repeat(centre[None, None, :], body.n, axis=0).repeat(points, axis=1)
    for j in range(body.n):
        out[j, :, j] = np.linspace(lo[j], hi[j], points)
    return out


def largest_jump(predict, body: Body, size: float, points: int = 201) -> float:
    """The redundancy measure: the largest joint-space step |q(x_k+1) - q(x_k)| of the inverse
    between neighbouring points on the lines through the target box (`lines`), in command units.
    A smooth inverse changes little between points 1/200 of the box apart; an inverse that
    switches between redundant solutions (branch switching) or is a lookup table jumps."""
    steps = [np.linalg.norm(np.diff(predict(line.copy()), axis=0), axis=-1).max()
             for line in _lines(body, size, points)]
    return float(max(steps))


def _lines(body: Body, size: float, points: int) -> np.ndarray:
    """lines(body, size, points), built once per process and (targets, size, points): every
    trial of a condition ends at the same size (read-only; largest_jump hands out copies)."""
    t = np.ascontiguousarray(body.targets)
    key = (t.shape, t.dtype.str, t.tobytes(), float(size), points)
    out = _LINES.get(key)
    if out is None:
        out = lines(body, size, points)
        out.flags.writeable = False
        if len(_LINES) >= 64:
            _LINES.clear()
        _LINES[key] = out
    return out


_LINES: dict = {}  # _lines by the targets' bytes, the size and the points
