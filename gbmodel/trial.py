"""One trial: a body grows while a learner learns; returns its learning curve. The loop, growth,
draws, evaluation and snapshots live here, the same for every learner. Draws come in a fixed
order (initialisation, then the learner's per block of DRAW_BLOCK epochs), so the result does
not depend on where the curve is evaluated or snapshot, and both paths of a learner consume the
same numbers.
"""
from __future__ import annotations

import math
import pickle
from dataclasses import asdict, dataclass, field
from types import SimpleNamespace
from typing import Any

import numpy as np

from . import evaluation, learners
from .bodies import READS, Body, make_body
from .growth import Growth
from .spec import SpecError, check_choice, check_epochs, check_int

DRAW_BLOCK = 1000


class Diverged(ArithmeticError):
    def __init__(self, epoch: int, value: float):
        super().__init__(f"diverged: the error became {value} at epoch {epoch}")
        self.epoch = epoch


def check_evaluation(settings: dict) -> dict:
    """The evaluation settings with their defaults, SpecError naming a bad one."""
    ev = {**evaluation.DEFAULTS, **settings}
    check_choice("evaluation.points", ev["points"], evaluation.POINTS)
    check_choice("evaluation.formula", ev["formula"], evaluation.FORMULAS)
    check_int("evaluation.path_steps", ev["path_steps"], 1)
    return ev


@dataclass(frozen=True)
class TrialSpec:
    """Everything one trial depends on, as plain data mirroring the config's sections (body: a
    description for make_body; growth: Growth's fields; learner: dict(name, **Params))."""

    body: dict = field(default_factory=lambda: {"name": "arm5"})
    growth: dict = field(default_factory=dict)
    learner: dict = field(default_factory=lambda: {"name": "goal_babbling"})
    evaluation: dict = field(default_factory=dict)
    epochs: int = 1000
    evals_per_decade: int = 20
    snapshots: tuple = ()  # epochs after which a copy of the learned model is kept

    def make_body(self) -> Body:
        return make_body(self.body)

    def make_growth(self) -> Growth:
        return Growth(**self.growth)

    def make_learner(self):
        kw = dict(self.learner)
        module = learners.get(kw.pop("name", "goal_babbling"))
        try:
            params = module.Params(**kw)
        except TypeError as err:  # an unknown field
            raise SpecError("learner", sorted(kw), str(err)) from None
        return module, params.validate()

    def validate(self, body: Body | None = None) -> "TrialSpec":
        """SpecError naming the first bad value; body: this spec's, if built already."""
        self._checked(body)
        return self

    def _checked(self, body: Body | None = None) -> tuple:
        """(body, growth, learner, params), each built and checked once."""
        body = self.make_body() if body is None else body
        growth = self.make_growth().validate(body)
        learner, params = self.make_learner()
        if body.loop is not None and getattr(params, "fast", False):
            raise SpecError("learner.fast", True, f"body {body.name!r} is a body in the loop (a "
                            "Python forward function): only the numpy reference path takes it; "
                            "set learner.fast=false")
        check_epochs("learner.epochs", self.epochs)
        check_int("learner.evals_per_decade", self.evals_per_decade, 1)
        check_evaluation(self.evaluation)
        for e in self.snapshots:
            if not 1 <= e <= self.epochs:
                raise SpecError("snapshots", e, f"outside the epochs 1 ... {self.epochs}")
        return body, growth, learner, params

    def to_dict(self) -> dict:
        d = asdict(self)
        d["snapshots"] = list(self.snapshots)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "TrialSpec":
        return cls(**{**d, "snapshots": tuple(d.get("snapshots", ()))})


@dataclass
class TrialResult:
    epoch: np.ndarray  # (E,) epochs after which the curve was evaluated (1-based)
    size: np.ndarray  # (E,) size factor of the body in that epoch
    abs_error: np.ndarray  # (E,) mean distance target-hand [m]
    rel_error: np.ndarray  # (E,) abs_error / size
    M: np.ndarray | None  # the learner's final model (the inverse estimate's M), if it has one
    snapshots: dict = field(default_factory=dict)  # epoch -> model after that epoch
    samples_per_epoch: int = 0  # forward-kinematics evaluations per epoch
    largest_jump: float = float("nan")  # the final inverse's redundancy measure (evaluation)
    heldout_abs_error: np.ndarray | None = None  # (E,) abs_error on the held-out set (evaluation)
    uniform_abs_error: np.ndarray | None = None  # (E,) on its uniform points alone
    path_abs_error: np.ndarray | None = None  # (E,) on the sampled path targets (path_targets)
    state: Any = None  # the learner's final state and the generator's (bit_generator.state),
    rng: dict | None = None  # what a Checkpoint of this trial holds
    views: list = field(default_factory=list)  # run_trial's views: a TrialResult or Diverged each


@dataclass
class Checkpoint:
    """A trial after `epoch` epochs (a multiple of DRAW_BLOCK: only there does a longer run's
    draws continue), as a continuation starts from it: the learner's and generator's states and
    the result so far."""
    epoch: int
    state: Any
    rng: dict
    result: TrialResult


def _resume(spec: TrialSpec, at: Checkpoint, evals: np.ndarray, rng: np.random.Generator):
    """(k, rows, snapshots) a continuation takes from its checkpoint; sets the generator."""
    if not (0 < at.epoch < spec.epochs and at.epoch % DRAW_BLOCK == 0):
        raise SpecError("resume.epoch", at.epoch, f"a continuation starts after a multiple of "
                        f"{DRAW_BLOCK} epochs (the draw block) before the end ({spec.epochs})")
    k = int(np.searchsorted(evals, at.epoch, side="right"))
    have = np.asarray(at.result.epoch)
    rows = np.minimum(np.searchsorted(have, evals[:k]), len(have) - 1)
    if k and (not len(have) or np.any(have[rows] != evals[:k])):
        raise SpecError("resume.result", at.epoch, "the checkpoint's curve lacks an evaluation "
                        "of this trial's (evals_per_decade must agree)")
    snaps = [e for e in spec.snapshots if e <= at.epoch]
    if any(e not in at.result.snapshots for e in snaps):
        raise SpecError("resume.result", at.epoch, "the checkpoint lacks a snapshot of this trial")
    rng.bit_generator.state = at.rng
    return k, rows, {e: at.result.snapshots[e] for e in snaps}


_SETUPS: dict = {}  # a spec's content (pickled) -> its set-up (_setup_of)
MAX_SETUPS = 64


def _setup_of(spec: TrialSpec) -> SimpleNamespace:
    """What a trial's loop needs before its first draw, all given by its spec (none by its
    seed), built and validated; for a DH body (nothing read) the one built for the same content
    before: a condition's trials differ by their seed only, and set-up was most of a short
    trial's cost."""
    key = None
    if spec.body.get("dh") is not None and all(spec.body.get(k) is None for k in READS):
        try:  # pickle tells 1 from 1.0 and "1", a tuple from a list: no two contents share one
            key = pickle.dumps((spec.body, spec.growth, spec.learner, spec.evaluation,
                                spec.epochs, spec.evals_per_decade, spec.snapshots), protocol=5)
        except Exception:  # something that does not pickle: built every time
            key = None
    hit = _SETUPS.get(key) if key is not None else None
    if hit is not None and hit.learner is learners.get(spec.learner.get("name", "goal_babbling")):
        return hit  # (a learner registered again under the name is not the one it was built with)
    body, growth, learner, params = spec._checked()
    evals = evaluation.eval_epochs(spec.epochs, spec.evals_per_decade)
    sizes = growth.sizes(np.arange(1, min(DRAW_BLOCK, spec.epochs) + 1), body)
    ev = {**evaluation.DEFAULTS, **spec.evaluation}
    steps = getattr(params, "steps", ev["path_steps"])  # eq. 9's L of a learner that has one
    setup = SimpleNamespace(  # unit_*: at size 1, scaled at each evaluation; at: evals as ints
        body=body, growth=growth, learner=learner, params=params, ev=ev,
        unit_heldout=evaluation.heldout_points(body),
        unit_path=evaluation.path_targets(body, steps), evals=evals, at=tuple(evals.tolist()),
        cuts=frozenset(evals.tolist()) | frozenset(spec.snapshots),
        size_one=growth.sizes(np.array([1]), body)[0], sizes=sizes,  # of the first block
        scales=growth.scales(body, sizes))
    if key is not None:
        if len(_SETUPS) >= MAX_SETUPS:
            _SETUPS.clear()
        _SETUPS[key] = setup
    return setup


class _Scores:
    """One evaluation setting's columns of a curve: its points (ev) and formula, the sampled path
    targets of its L, and where it diverged."""

    def __init__(self, ev: dict, n: int, unit_path):
        self.ev, self.formula, self.unit_path = ev, ev["formula"], unit_path
        self.abs, self.heldout, self.uniform, self.path = (np.empty(n) for _ in range(4))
        self.diverged: Diverged | None = None

    def score(self, k, hi, err, dist, unit_heldout):
        """Column k (epoch hi) from its error and dist(points at size 1): distances, each set's
        computed once for all settings."""
        if not math.isfinite(err):
            self.diverged = Diverged(hi, err)
            return
        d = dist(unit_heldout)  # the held-out set and its uniform part from one set of distances
        self.abs[k] = err
        self.heldout[k] = evaluation.error(d, self.formula)
        self.uniform[k] = evaluation.error(d[-evaluation.HELDOUT_UNIFORM:], self.formula)
        self.path[k] = evaluation.error(dist(self.unit_path), self.formula)


def run_trial(spec: TrialSpec, rng: np.random.Generator, resume: Checkpoint | None = None,
              views: tuple = ()) -> TrialResult:
    """One trial's learning curve (Diverged on a non-finite error); resume: continue from that
    checkpoint, to the bit an uninterrupted run's result. views: other evaluation settings
    (spec.evaluation's fields) scored on the same learning, each result (or its Diverged) in
    `views`, to the bit the trial with that evaluation would give alone (evaluation draws
    nothing)."""
    setup = _setup_of(spec)
    body, growth, learner, params = setup.body, setup.growth, setup.learner, setup.params
    unit_heldout, cuts = setup.unit_heldout, setup.cuts
    evals, at = setup.evals.copy(), setup.at  # the result's own; the epochs as ints
    if views and resume is not None:
        raise ValueError("run_trial: views of a continuation are not kept")
    steps = getattr(params, "steps", None)  # eq. 9's L of a learner that has one

    scores = [_Scores(setup.ev, len(evals), setup.unit_path)]
    for ev in map(check_evaluation, views):
        same = steps is not None or ev["path_steps"] == setup.ev["path_steps"]
        scores.append(_Scores(ev, len(evals), setup.unit_path if same else
                              evaluation.path_targets(body, ev["path_steps"])))
    mine, size = scores[0], np.empty(len(evals))
    k, snapshots, first = 0, {}, 0
    if resume is None:
        state = learner.init(params, body, setup.size_one, rng)
    else:
        k, rows, snapshots = _resume(spec, resume, evals, rng)
        state, first, done = resume.state, resume.epoch, resume.result
        for to, part in ((mine.abs, done.abs_error), (mine.heldout, done.heldout_abs_error),
                         (mine.uniform, done.uniform_abs_error), (mine.path, done.path_abs_error),
                         (size, done.size)):
            to[:k] = np.asarray(part)[rows]
    # sizes and scales per block, so memory does not grow with the epochs (elementwise: the
    # same bytes as from the whole array)
    for start in range(first, spec.epochs, DRAW_BLOCK):  # epochs start+1 ... stop
        stop = min(start + DRAW_BLOCK, spec.epochs)
        if start == 0:  # the set-up's, copied: a learner may not share them with other trials
            sizes, scales = setup.sizes.copy(), setup.scales.copy()
        else:
            sizes = growth.sizes(np.arange(start + 1, stop + 1), body)  # of epochs start+1 ... stop
            scales = growth.scales(body, sizes)
        draws = learner.draw(params, body, stop - start, rng)
        bounds = sorted({start, stop} | {e for e in cuts if start < e < stop})
        for lo, hi in zip(bounds[:-1], bounds[1:]):
            part = tuple(d[lo - start:hi - start] for d in draws)
            state = learner.train(state, params, body, sizes[lo - start:hi - start],
                                  scales[lo - start:hi - start], part, np.arange(lo + 1, hi + 1))
            if hi in spec.snapshots:
                snapshots[hi] = learner.model(state)
            if k < len(at) and hi == at[k]:
                now, scale = sizes[hi - 1 - start], scales[hi - 1 - start]
                size[k], found = now, {}

                def dist(unit):
                    if id(unit) not in found:
                        found[id(unit)] = evaluation.point_distances(
                            learner, state, params, body, scale, unit * now)
                    return found[id(unit)]
                for s in scores:
                    if s.diverged is None:
                        err = evaluation.evaluate(learner, state, params, body, now, scale, **s.ev)
                        s.score(k, hi, err, dist, unit_heldout)
                if mine.diverged is not None:
                    raise mine.diverged
                k += 1
    jump = evaluation.largest_jump(lambda x: learner.predict(state, params, body, x), body,
                                   sizes[-1])
    results = [s.diverged or TrialResult(
        epoch=evals, size=size, abs_error=s.abs, rel_error=s.abs / size, M=learner.model(state),
        snapshots=snapshots, samples_per_epoch=learner.samples_per_epoch(params, body),
        largest_jump=jump, heldout_abs_error=s.heldout, uniform_abs_error=s.uniform,
        path_abs_error=s.path, state=state, rng=rng.bit_generator.state) for s in scores]
    results[0].views = results[1:]
    return results[0]
