"""One trial: a body grows while a learner learns; returns its learning curve.

The loop is the same for every learner (gbmodel.learners): the body and its variant, the growth
schedule, the random draws in blocks of DRAW_BLOCK epochs, the evaluation schedule and the
snapshots live here; the learner only learns. Random numbers are drawn in a fixed order
(initialisation, then per block the learner's draws), so that the result does not depend on where
the curve is evaluated or snapshot, and the fast and reference paths of a learner consume the same
numbers.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from . import evaluation, learners
from .bodies import Body, make_body
from .growth import Growth
from .spec import SpecError, check_choice, check_epochs, check_int

DRAW_BLOCK = 1000


class Diverged(ArithmeticError):
    """The learner's error became non-finite (NaN or inf): the trial cannot go on."""

    def __init__(self, epoch: int, value: float):
        super().__init__(f"diverged: the error became {value} at epoch {epoch}")
        self.epoch = epoch


@dataclass(frozen=True)
class TrialSpec:
    """Everything one trial depends on, as plain data mirroring the config's sections.

    body: the body's description (conf/body/*.yaml's fields; gbmodel.make_body), or
    dict(name) of a shipped body with single fields replaced; growth: gbmodel.Growth's fields;
    learner: dict(name, **the learner's Params); evaluation: dict(points, formula).
    Defaults: the 5-DOF arm with Goal Babbling at the paper's settings, no growth.
    """

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
        """(learner module, its validated Params)."""
        kw = dict(self.learner)
        module = learners.get(kw.pop("name", "goal_babbling"))
        try:
            params = module.Params(**kw)
        except TypeError as err:  # an unknown field
            raise SpecError("learner", sorted(kw), str(err)) from None
        return module, params.validate()

    def validate(self, body: Body | None = None) -> "TrialSpec":
        """Raise SpecError (a ValueError) naming the first bad value as `<section>.<field>`.
        body: this spec's body if the caller built it already (it is then not built again)."""
        body = self.make_body() if body is None else body
        self.make_growth().validate(body)
        _, params = self.make_learner()
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
        return self

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
    state: Any = None  # the learner's final state and the generator's (bit_generator.state),
    rng: dict | None = None  # what a Checkpoint of this trial holds


@dataclass
class Checkpoint:
    """A trial after `epoch` epochs, as a continuation starts from it: the learner's state, the
    generator's state after that trial's draws (bit_generator.state) and its result (the curve
    up to `epoch`, its snapshots). `epoch` is a multiple of DRAW_BLOCK: the draws come in blocks
    shaped by their length, so only there is the rest of a longer run's draws what follows. The
    pipeline keeps a checkpoint with the trial that ended there (gbmodel reads no file)."""
    epoch: int
    state: Any
    rng: dict
    result: TrialResult


def _resume(spec: TrialSpec, at: Checkpoint, evals: np.ndarray, rng: np.random.Generator):
    """The part of the curve (k evaluations) and the snapshots a continuation takes from its
    checkpoint, with the generator set to the checkpoint's state; SpecError if it cannot."""
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


def run_trial(spec: TrialSpec, rng: np.random.Generator,
              resume: Checkpoint | None = None) -> TrialResult:
    """Run one trial and return its learning curve; raises Diverged on a non-finite error.
    resume: continue the trial of that checkpoint (its first epochs and draws are this
    trial's), rather than start one: the result is an uninterrupted run's, to the bit."""
    body = spec.make_body()
    spec.validate(body)
    growth = spec.make_growth()
    learner, params = spec.make_learner()
    ev = {**evaluation.DEFAULTS, **spec.evaluation}
    unit_heldout = evaluation.heldout_points(body)  # at each evaluation: scaled, not rebuilt
    evals = evaluation.eval_epochs(spec.epochs, spec.evals_per_decade)
    cuts = set(evals.tolist()) | set(spec.snapshots)
    abs_error, heldout, size = (np.empty(len(evals)) for _ in range(3))
    k, snapshots, first = 0, {}, 0
    if resume is None:
        state = learner.init(params, body, growth.sizes(np.array([1]), body)[0], rng)
    else:
        k, rows, snapshots = _resume(spec, resume, evals, rng)
        state, first, done = resume.state, resume.epoch, resume.result
        for to, part in ((abs_error, done.abs_error), (heldout, done.heldout_abs_error),
                         (size, done.size)):
            to[:k] = np.asarray(part)[rows]
    # Sizes and scales are built per block of DRAW_BLOCK epochs, never for every epoch at once,
    # so a trial's memory does not grow with its epochs (each value is computed elementwise:
    # the same bytes as from the whole array).
    for start in range(first, spec.epochs, DRAW_BLOCK):  # epochs start+1 ... stop
        stop = min(start + DRAW_BLOCK, spec.epochs)
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
            if k < len(evals) and hi == evals[k]:
                err = evaluation.evaluate(learner, state, params, body, sizes[hi - 1 - start],
                                          scales[hi - 1 - start], **ev)
                if not np.isfinite(err):
                    raise Diverged(hi, err)
                abs_error[k], size[k] = err, sizes[hi - 1 - start]
                heldout[k] = evaluation.evaluate(learner, state, params, body,
                                                 sizes[hi - 1 - start], scales[hi - 1 - start],
                                                 **{**ev, "points": "heldout"}, xs=unit_heldout)
                k += 1
    jump = evaluation.largest_jump(lambda x: learner.predict(state, params, body, x), body,
                                   sizes[-1])
    return TrialResult(epoch=evals, size=size, abs_error=abs_error, rel_error=abs_error / size,
                       M=learner.model(state), snapshots=snapshots,
                       samples_per_epoch=learner.samples_per_epoch(params, body),
                       largest_jump=jump, heldout_abs_error=heldout, state=state,
                       rng=rng.bit_generator.state)
