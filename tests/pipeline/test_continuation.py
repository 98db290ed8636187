"""A continuation starts from the saved state of the run it continues (issue 43 item 2): its
bytes are those of an uninterrupted run, its base is a trial like any other (Fig. 7's const1.0
for explain_fig7_continuation), run or found in the cache first, and the epochs both share are
computed once. In gbmodel's tests the draw block is 10 epochs (20 + 10 epochs is 30); through
the pipeline (whose code fingerprint refuses an edited constant) 1000 + 1000 on the 2-DOF arm."""
from __future__ import annotations

import json

import numpy as np
import pytest

import gbmodel
import gbmodel.trial
from pipeline import cache, checkpoint, planned, simulate
from pipeline.config import ConfigError, compose
from pipeline.plan import plan


@pytest.fixture
def block(monkeypatch):
    monkeypatch.setattr(gbmodel.trial, "DRAW_BLOCK", 10)
    return 10


def _run(epochs, resume=None, **learner):
    spec = gbmodel.TrialSpec(body={"name": "arm2"}, learner={"name": "goal_babbling", **learner},
                             epochs=epochs, evals_per_decade=5,
                             snapshots=tuple(e for e in (5, 25) if e <= epochs))
    rng = np.random.default_rng(np.random.SeedSequence(2010, spawn_key=(7, 1)))
    return gbmodel.run_trial(spec, rng, resume=resume)


def _through_json(res, learner="goal_babbling"):
    """A base's checkpoint as the cache keeps it (JSON) and a worker gets it back."""
    final = json.loads(json.dumps(checkpoint.final_state(res)))
    curve = {c: getattr(res, c).tolist() for c in checkpoint.CURVE}
    snaps = {str(e): m.tolist() for e, m in res.snapshots.items()}
    return checkpoint.checkpoint(dict(final, curve=curve, snapshots=snaps), learner)


STEP = dict(rate_schedule="step", rate_step_epoch=20, rate_step_factor=0.1)


@pytest.mark.parametrize("learner", [{}, {"fast": False}, {"solver": "lstsq"},
                                     {"goal_selection": "progress", "progress_period": 3}],
                         ids=["kernel", "reference", "lstsq", "progress"])
def test_a_continuation_gives_the_bytes_of_an_uninterrupted_run(block, learner):
    whole, base = _run(30, **learner), _run(20, **learner)
    assert base.epoch[-1] == 20
    cont = _run(30, resume=_through_json(base), **learner)
    for f in ("epoch", "size", "abs_error", "rel_error", "heldout_abs_error", "M"):
        assert getattr(cont, f).tobytes() == getattr(whole, f).tobytes(), f
    assert sorted(cont.snapshots) == sorted(whole.snapshots) == [5, 25]
    assert all(cont.snapshots[e].tobytes() == whole.snapshots[e].tobytes() for e in (5, 25))
    assert cont.largest_jump == whole.largest_jump
    # the step variant continues the same base: an uninterrupted step run's bytes, which
    # differ from the constant rate's only after the step
    step = _run(30, resume=_through_json(base), **learner, **STEP)
    assert step.abs_error.tobytes() == _run(30, **learner, **STEP).abs_error.tobytes()
    after = step.epoch > 20
    assert np.array_equal(step.abs_error[~after], whole.abs_error[~after])
    if learner.get("solver") != "lstsq":  # the solve has no rate: the step changes nothing
        assert not np.any(step.abs_error[after] == whole.abs_error[after])


def test_a_continuation_starts_only_at_a_draw_block(block):
    base = _run(15)
    with pytest.raises(gbmodel.SpecError, match="multiple of 10"):
        _run(30, resume=gbmodel.Checkpoint(15, base.state, base.rng, base))


TINY = ["body=arm2", "growth=none", "learner.epochs=2000", "trials.count=2", "workers=1",
        "conditions.snapshots=[500,1500]"]


def test_a_continuation_runs_after_its_base_and_equals_the_whole_run(tmp_path):
    root = [f"paths.root={tmp_path}"]
    cont_cfg = compose([*TINY, *root, "conditions.continues=1000", "figure=cont"])
    trials = plan(cont_cfg)
    assert [t["start"]["epoch"] for t in trials] == [1000, 1000]
    first = simulate.simulate(cont_cfg)
    assert (first.total, first.ran, first.cached) == (4, 4, 0)  # two bases, two continuations
    cache_dir = cont_cfg.paths.cache
    assert all(checkpoint.has(cache_dir, t["base"]) for t in trials)
    # the bases are the 1000-epoch trials of the same condition: cached, computed once
    base = simulate.simulate(compose([*TINY, *root, "learner.epochs=1000", "figure=base"]))
    assert (base.total, base.cached, base.ran) == (2, 2, 0)
    # the uninterrupted 2000-epoch trials: other keys, the same bytes
    whole = plan(compose([*TINY, *root, "figure=whole"]))
    simulate.simulate(compose([*TINY, *root, "figure=whole"]))
    for c, w in zip(trials, whole):
        assert c["key"] != w["key"] and c["seed"] == w["seed"]
        sc, sw = cache.check(cache_dir, c)[0], cache.check(cache_dir, w)[0]
        for k in ("curve_sha256", "M", "snapshots", "largest_jump"):
            assert sc[k] == sw[k], k
        assert sc["start"] == c["start"]
        # its curve is its base's up to epoch 1000, and then its own
        cu, bu = cache.read_curve(cache_dir, c), cache.read_curve(cache_dir, c["base"])
        assert cu[cu["epoch"] <= 1000].reset_index(drop=True).equals(bu)
        assert sorted(sc["snapshots"], key=int) == ["500", "1500"]
    again = simulate.simulate(cont_cfg)
    assert (again.total, again.cached, again.ran) == (4, 4, 0)
    packed = simulate.pack_jobs(simulate.jobs_of(cont_cfg))
    assert planned.misplanned(packed["specs"], packed["jobs"]) is None


def test_a_base_cached_without_its_state_runs_again_first(tmp_path):
    root = [f"paths.root={tmp_path}"]
    simulate.simulate(compose([*TINY, *root, "learner.epochs=1000"]))
    s = simulate.simulate(compose([*TINY, *root, "conditions.continues=1000", "figure=cont"]))
    assert (s.total, s.cached, s.ran, s.failed) == (4, 0, 4, {})


@pytest.mark.parametrize("over, why", [
    (["conditions.continues=1500"], "multiple of 1000"),
    (["conditions.continues=1000", "conditions.budget=100000"], "not a sample budget"),
])
def test_a_continuation_that_cannot_be_is_one_line(over, why):
    with pytest.raises(ConfigError, match=why):
        plan(compose([*TINY, *over]))


def test_only_a_rate_after_the_base_may_differ_from_it():
    """explain_fig7_continuation's step variant continues Fig. 7's const1.0 trials (the rate
    changes after epoch 100,000); a variant that changes the learner before is refused."""
    c = plan(compose(["experiment=explain_fig7_continuation"]))
    fig7 = {t["labels"]["trial"]: t["key"] for t in plan(compose(["experiment=fig7"]))
            if t["growth_label"] == "const1.0"}
    assert {t["base"]["key"] for t in c} == set(fig7.values())
    assert all(t["base"]["key"] == fig7[t["labels"]["trial"]] for t in c)
    cfg = compose(["experiment=explain_fig7_continuation"])
    cfg.conditions.variants[1].set = ["learner.rate_schedule=step",
                                      "learner.rate_step_epoch=50000",
                                      "learner.rate_step_factor=0.1"]
    with pytest.raises(ConfigError, match="changes learner.rate_s.* before epoch 100000"):
        plan(cfg)
    cfg.conditions.variants[1].set = ["learner.radius=0.05"]
    with pytest.raises(ConfigError, match="changes learner.radius"):
        plan(cfg)


def test_a_state_of_dataclasses_continues_and_names_only_its_learners_classes(block):
    """A learner whose state is a dataclass (online Goal Babbling) continues to the bit; the class
    is found by name among gbmodel's loaded dataclasses, never imported: a checkpoint naming
    anything else is refused in one line."""
    spec = dict(body={"name": "arm2"}, learner={"name": "online_goal_babbling"},
                evals_per_decade=5)
    rng = lambda: np.random.default_rng(np.random.SeedSequence(2010, spawn_key=(7, 1)))  # noqa: E731
    whole = gbmodel.run_trial(gbmodel.TrialSpec(epochs=30, **spec), rng())
    base = gbmodel.run_trial(gbmodel.TrialSpec(epochs=20, **spec), rng())
    cont = gbmodel.run_trial(gbmodel.TrialSpec(epochs=30, **spec), rng(),
                             resume=_through_json(base, "online_goal_babbling"))
    assert cont.abs_error.tobytes() == whole.abs_error.tobytes()
    assert cont.M.tobytes() == whole.M.tobytes()
    kinds = checkpoint.state_kinds("online_goal_babbling")
    text = json.dumps(checkpoint.encode(base.state))
    for other in ("subprocess:CompletedProcess", "pipeline.io:Sealed", "gbmodel.nowhere:State"):
        forged = json.loads(text.replace("gbmodel.learners.online_goal_babbling:State", other))
        with pytest.raises(ValueError, match="not a dataclass of gbmodel"):
            checkpoint.decode(forged, kinds)
