"""A trial's memory does not grow with its epochs (sizes and scales are built per block of
DRAW_BLOCK epochs), and building them per block gives the same bytes as for every epoch at once."""
import tracemalloc

import numpy as np
import pytest

import gbmodel
import gbmodel.learners
from gbmodel.trial import DRAW_BLOCK
from conftest import stay_home_module


@pytest.fixture
def stay_home(monkeypatch):
    """A learner that never learns, so that the trial loop's own memory is what is measured."""
    monkeypatch.setattr(gbmodel.learners, "_REGISTERED", dict(gbmodel.learners._REGISTERED))
    m = stay_home_module()
    gbmodel.learners.register("stay_home", m)
    return "stay_home"


def _peak(learner: str, epochs: int) -> int:
    spec = gbmodel.TrialSpec(learner={"name": learner}, epochs=epochs, evals_per_decade=2,
                             growth=dict(pattern="proximal_first", period=epochs // 2))
    tracemalloc.start()
    try:
        gbmodel.run_trial(spec, np.random.default_rng(0))
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_a_trials_memory_does_not_grow_with_its_epochs(stay_home):
    small, large = _peak(stay_home, 20_000), _peak(stay_home, 400_000)
    # for every epoch at once: 400k x (1 size + 5 scales + the epoch numbers) x 8 B = 22 MB more
    assert large - small < 1_000_000, (small, large)


@pytest.mark.parametrize("growth", [
    dict(pattern="proportional", period=1500),
    dict(pattern="proportional", period=1500, schedule="infant"),
    dict(pattern="nonproportional", period=1700),
    dict(pattern="proximal_first", period=2500, start_size=0.6),
    dict(pattern="proportional", period=0, end_size=0.5),
])
def test_sizes_and_scales_per_block_are_the_bytes_of_the_whole_run(growth):
    body = gbmodel.make_body("arm5")
    g = gbmodel.Growth(**growth).validate(body)
    epochs = 3 * DRAW_BLOCK + 17
    whole = g.sizes(np.arange(1, epochs + 1))
    whole_scales = g.scales(body, whole)
    for start in range(0, epochs, DRAW_BLOCK):
        stop = min(start + DRAW_BLOCK, epochs)
        part = g.sizes(np.arange(start + 1, stop + 1))
        assert part.tobytes() == whole[start:stop].tobytes()
        assert g.scales(body, part).tobytes() == whole_scales[start:stop].tobytes()


@pytest.mark.parametrize("learner", [{"name": "goal_babbling"}, {"name": "motor_babbling"},
                                     {"name": "goal_babbling", "solver": "lstsq"}])
def test_views_are_the_bytes_of_each_trial_run_alone(learner):
    """run_trial's views: trials whose learning is this one's first epochs (another evaluation,
    fewer epochs, other snapshots) give, field by field, what each gives alone; the trial itself
    is unchanged by its views."""
    spec = gbmodel.TrialSpec(learner=learner, epochs=2300, evals_per_decade=5, growth=dict(
        pattern="proportional", start_size=0.4, end_size=1.0, period=1500))
    views = [dict(evaluation={"points": "path", "path_steps": 4}), dict(
        evaluation={"formula": "rms"}, snapshots=(7, 2300)), dict(epochs=1000, snapshots=(5,)),
        dict(epochs=2000, evals_per_decade=20, evaluation={"points": "centres", "path_steps": 3,
                                                            "formula": "mean_squared"})]
    views = tuple(gbmodel.TrialSpec(**{**vars(spec), **v}) for v in views)
    res = gbmodel.run_trial(spec, np.random.default_rng(3), views=views)
    fields = ("epoch", "size", "abs_error", "rel_error", "heldout_abs_error",
              "uniform_abs_error", "path_abs_error", "M", "samples_per_epoch", "largest_jump")
    for one, got in zip((spec, *views), (res, *res.views)):
        alone = gbmodel.run_trial(one, np.random.default_rng(3))
        for f in fields:
            assert np.array_equal(getattr(alone, f), getattr(got, f)), (one, f)
        assert got.snapshots.keys() == alone.snapshots.keys()
        assert all(np.array_equal(alone.snapshots[e], got.snapshots[e]) for e in got.snapshots)
    assert len({r.abs_error[-1] for r in (res, *res.views)}) == 5  # five other numbers
    with pytest.raises(ValueError, match="first epochs"):  # 1500 epochs: not a whole block
        gbmodel.run_trial(spec, np.random.default_rng(3), views=(
            gbmodel.TrialSpec(**{**vars(spec), "epochs": 1500}),))


def test_a_view_diverges_on_its_own_and_the_trial_goes_on(monkeypatch):
    spec = gbmodel.TrialSpec(epochs=50)
    real = gbmodel.evaluation.error

    def error(d, formula="mean"):  # the rms view's error is not finite
        return float("inf") if formula == "rms" else real(d, formula)
    monkeypatch.setattr(gbmodel.evaluation, "error", error)
    view = gbmodel.TrialSpec(epochs=50, evaluation={"formula": "rms"})
    res = gbmodel.run_trial(spec, np.random.default_rng(0), views=(view,))
    assert isinstance(res.views[0], gbmodel.Diverged) and res.views[0].epoch == 1
    assert np.isfinite(res.abs_error).all()
    with pytest.raises(gbmodel.SpecError, match="evaluation.points"):
        gbmodel.run_trial(spec, np.random.default_rng(0), views=(
            gbmodel.TrialSpec(epochs=50, evaluation={"points": "nowhere"}),))
