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
        ev = {**evaluation.DEFAULTS, **self.evaluation}
        check_choice("evaluation.points", ev["points"], evaluation.POINTS)
        check_choice("evaluation.formula", ev["formula"], evaluation.FORMULAS)
        check_int("evaluation.path_steps", ev["path_steps"], 1)
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


class _Curve:
    """The curve of one trial a run scores (its own, or a view's): its evaluation epochs, points
    and formula (its set-up's), snapshots, columns, and where it diverged or ended."""

    def __init__(self, spec: TrialSpec, setup):
        self.epochs, self.snaps, self.ev, self.formula = (spec.epochs, set(spec.snapshots),
                                                          setup.ev, setup.ev["formula"])
        self.evals, self.at, self.unit_path = setup.evals.copy(), setup.at, setup.unit_path
        self.abs, self.heldout, self.uniform, self.path, self.size = (
            np.empty(len(self.evals)) for _ in range(5))
        self.k, self.snapshots, self.diverged, self.result = 0, {}, None, None

    def after(self, hi, now, scale, state, run, dist) -> None:
        """After epoch hi (the body at size `now`, factors `scale`; run: the set-up): the
        snapshot and the evaluation this curve takes there; dist(unit): the distances of a
        point set at size 1, each set's computed once for all curves."""
        if hi in self.snaps:
            self.snapshots[hi] = run.learner.model(state)
        if self.k < len(self.at) and hi == self.at[self.k]:
            err = evaluation.evaluate(run.learner, state, run.params, run.body, now, scale,
                                      **self.ev)
            if not math.isfinite(err):
                self.diverged = Diverged(hi, err)
                return
            d = dist(run.unit_heldout)  # the held-out set and its uniform part: one set of distances
            k, f = self.k, self.formula
            self.abs[k], self.size[k] = err, now
            self.heldout[k] = evaluation.error(d, f)
            self.uniform[k] = evaluation.error(d[-evaluation.HELDOUT_UNIFORM:], f)
            self.path[k] = evaluation.error(dist(self.unit_path), f)
            self.k += 1

    def finish(self, state, run, size, rng) -> TrialResult:
        jump = evaluation.largest_jump(
            lambda x: run.learner.predict(state, run.params, run.body, x), run.body, size)
        return TrialResult(
            epoch=self.evals, size=self.size, abs_error=self.abs, rel_error=self.abs / self.size,
            M=run.learner.model(state), snapshots=self.snapshots,
            samples_per_epoch=run.learner.samples_per_epoch(run.params, run.body),
            largest_jump=jump, heldout_abs_error=self.heldout, uniform_abs_error=self.uniform,
            path_abs_error=self.path, state=state, rng=rng.bit_generator.state)


LEARNING = ("body", "growth", "learner")  # what a view shares with its trial


def _view_curves(spec: TrialSpec, views: tuple) -> list[_Curve]:
    """A curve per view: a spec whose learning is `spec`'s first epochs (ValueError if not)."""
    out = []
    for v in views:
        if any(getattr(v, f) != getattr(spec, f) for f in LEARNING) or v.epochs > spec.epochs \
                or (v.epochs < spec.epochs and v.epochs % DRAW_BLOCK):
            raise ValueError(f"run_trial: a view shares the trial's {', '.join(LEARNING)} and its "
                             f"first epochs, a multiple of {DRAW_BLOCK} (the draw block) or all")
        out.append(_Curve(v, _setup_of(v)))
    return out


def run_trial(spec: TrialSpec, rng: np.random.Generator, resume: Checkpoint | None = None,
              views: tuple = ()) -> TrialResult:
    """One trial's learning curve (Diverged on a non-finite error); resume: continue from that
    checkpoint, to the bit an uninterrupted run's result. views: TrialSpecs whose learning is
    this one's (the same body, growth and learner, their epochs its first), each scored on the
    way (another evaluation, fewer epochs), its result (or Diverged) in `views`, to the bit
    run_trial's of it alone (evaluation draws nothing; the draws come per block); no state."""
    run = _setup_of(spec)
    body, growth, learner, params = run.body, run.growth, run.learner, run.params
    if views and resume is not None:
        raise ValueError("run_trial: a continuation has no views")
    mine, others = _Curve(spec, run), _view_curves(spec, views)
    curves = [mine, *others]
    cuts = run.cuts.union(*(set(c.at) | c.snaps for c in others))
    first = 0
    if resume is None:
        state = learner.init(params, body, run.size_one, rng)
    else:
        mine.k, rows, mine.snapshots = _resume(spec, resume, mine.evals, rng)
        state, first, done = resume.state, resume.epoch, resume.result
        for to, part in ((mine.abs, done.abs_error), (mine.heldout, done.heldout_abs_error),
                         (mine.uniform, done.uniform_abs_error), (mine.path, done.path_abs_error),
                         (mine.size, done.size)):
            to[:mine.k] = np.asarray(part)[rows]
    # sizes and scales per block, so memory does not grow with the epochs (elementwise: the
    # same bytes as from the whole array)
    for start in range(first, spec.epochs, DRAW_BLOCK):  # epochs start+1 ... stop
        stop = min(start + DRAW_BLOCK, spec.epochs)
        if start == 0:  # the set-up's, copied: a learner may not share them with other trials
            sizes, scales = run.sizes.copy(), run.scales.copy()
        else:
            sizes = growth.sizes(np.arange(start + 1, stop + 1), body)  # of epochs start+1 ... stop
            scales = growth.scales(body, sizes)
        draws = learner.draw(params, body, stop - start, rng)
        bounds = sorted({start, stop} | {e for e in cuts if start < e < stop})
        for lo, hi in zip(bounds[:-1], bounds[1:]):
            part = tuple(d[lo - start:hi - start] for d in draws)
            state = learner.train(state, params, body, sizes[lo - start:hi - start],
                                  scales[lo - start:hi - start], part, np.arange(lo + 1, hi + 1))
            now, scale, found = sizes[hi - 1 - start], scales[hi - 1 - start], {}

            def dist(unit):
                if id(unit) not in found:
                    found[id(unit)] = evaluation.point_distances(learner, state, params, body,
                                                                 scale, unit * now)
                return found[id(unit)]
            for c in curves:
                if c.diverged is None and c.result is None:
                    c.after(hi, now, scale, state, run, dist)
                    if c is not mine and hi == c.epochs and c.diverged is None:
                        c.result = c.finish(state, run, now, rng)
                        c.result.state = None
            if mine.diverged is not None:
                raise mine.diverged
    result = mine.finish(state, run, sizes[-1], rng)
    result.views = [c.diverged or c.result for c in others]
    return result
