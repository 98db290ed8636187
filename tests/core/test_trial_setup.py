"""A trial's set-up (body, validated spec, growth, learner, evaluation points and epochs, the
first block's sizes and scales) depends on its spec, not its seed: the trials of one condition
share one, built once per process, and every trial's result keeps its bytes."""
import copy

import numpy as np
import pytest

import gbmodel
import gbmodel.learners
from gbmodel import trial
from gbmodel.bodies import read_description
from conftest import stay_home_module


def _spec(**kw) -> gbmodel.TrialSpec:
    """A spec as the pipeline plans it: the body's whole description (its DH table)."""
    return gbmodel.TrialSpec(**{"body": read_description("arm5"), "epochs": 12,
                                "growth": dict(pattern="proportional", period=5),
                                "snapshots": (3, 12), **kw})


def _bytes(r) -> list:
    arrays = [r.epoch, r.size, r.abs_error, r.rel_error, r.heldout_abs_error, r.M,
              *[r.snapshots[e] for e in sorted(r.snapshots)]]
    return [np.asarray(a).tobytes() for a in arrays] + [r.largest_jump, sorted(r.snapshots)]


def test_one_conditions_trials_share_one_setup():
    spec = _spec()
    again = gbmodel.TrialSpec.from_dict(copy.deepcopy(spec.to_dict()))  # another copy of it
    assert trial._setup_of(spec) is trial._setup_of(again)
    assert trial._setup_of(_spec(growth=dict(pattern="proportional", period=6))) \
        is not trial._setup_of(spec)
    by_name = gbmodel.TrialSpec(body={"name": "arm5"}, epochs=12)  # read from its file: not kept
    assert trial._setup_of(by_name) is not trial._setup_of(by_name)


@pytest.mark.parametrize("kw", [
    {},
    dict(epochs=trial.DRAW_BLOCK + 30, evals_per_decade=3, snapshots=(7, trial.DRAW_BLOCK + 1),
         growth=dict(pattern="proximal_first", period=trial.DRAW_BLOCK + 10)),
    dict(learner={"name": "goal_babbling", "fast": False}, epochs=6, snapshots=(2,)),
    dict(learner={"name": "goal_babbling", "solver": "lstsq"}),
    dict(learner={"name": "online_goal_babbling"}),
    dict(learner={"name": "motor_babbling"}),
    dict(learner={"name": "example_memory"}, snapshots=()),
])
def test_a_shared_setup_gives_the_bytes_of_a_fresh_one(kw, monkeypatch):
    spec = _spec(**kw)
    fresh = []
    for seed in range(3):
        trial._SETUPS.clear()
        fresh.append(_bytes(gbmodel.run_trial(spec, np.random.default_rng(seed))))
    shared = [_bytes(gbmodel.run_trial(spec, np.random.default_rng(seed))) for seed in range(3)]
    assert shared == fresh


def test_a_results_arrays_are_its_own():
    spec = _spec()
    first = gbmodel.run_trial(spec, np.random.default_rng(0))
    first.epoch[:] = -1  # a caller may write into its result
    second = gbmodel.run_trial(spec, np.random.default_rng(0))
    assert second.epoch.tolist() == gbmodel.evaluation.eval_epochs(12).tolist()
    assert _bytes(second)[1:] == _bytes(first)[1:]


def test_a_learner_registered_again_gets_a_setup_of_its_own(monkeypatch):
    monkeypatch.setattr(gbmodel.learners, "_REGISTERED", dict(gbmodel.learners._REGISTERED))
    one, two = stay_home_module(), stay_home_module()
    spec = _spec(learner={"name": "stay_home"})
    gbmodel.learners.register("stay_home", one)
    assert trial._setup_of(spec).learner is one
    gbmodel.learners.register("stay_home", two)
    assert trial._setup_of(spec).learner is two
