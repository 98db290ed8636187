"""The baselines study's parts: the memory that keeps everything (gbmodel.nearest), goals chosen by
learning progress, and the held-out evaluation points."""
import numpy as np
import pytest
from scipy.spatial import cKDTree

import gbmodel
from gbmodel.learners import example_memory
from gbmodel.nearest import Nearest


def _brute(points, xs):
    """The definition: smallest squared distance, ties to the lowest index (argmin's first)."""
    d = ((xs[:, None, :] - points[None, :, :]) ** 2).sum(-1)
    return d.argmin(axis=1)


def _grown(points, batches):
    store = Nearest(points.shape[1], 1)
    for chunk in np.array_split(np.arange(len(points)), batches):
        store.add(points[chunk], chunk[:, None].astype(float))
    return store


def test_nearest_in_levels_answers_as_one_tree_and_as_brute_force():
    rng = np.random.default_rng(0)
    points = rng.uniform(-1, 1, size=(3000, 2))
    xs = rng.uniform(-1.2, 1.2, size=(500, 2))
    grown = _grown(points, 37)  # batches of uneven size, several levels
    assert 2 <= len(grown._levels) <= 1 + np.log2(37)
    rebuilt = _grown(points, 1)  # one tree over everything: the full rebuild
    assert len(rebuilt._levels) == 1
    got = grown.query(xs)
    np.testing.assert_array_equal(got, rebuilt.query(xs))
    np.testing.assert_array_equal(got, _brute(points, xs))
    np.testing.assert_array_equal(got, cKDTree(points).query(xs)[1])  # no ties here
    np.testing.assert_array_equal(grown.values[got, 0], got)  # the values travel with them


def test_nearest_ties_go_to_the_oldest_example_in_every_split():
    """Duplicated points, within a level and across levels, and points equally far from a query
    (a lattice): the answer is always the lowest index, as brute force's argmin."""
    lattice = np.stack(np.meshgrid(np.arange(6.0), np.arange(6.0)), -1).reshape(-1, 2)
    points = np.concatenate([lattice, lattice[::-1], lattice, lattice[5:9]])
    xs = np.concatenate([lattice, lattice + 0.5, lattice + [0.5, 0.0]])  # ties of 1, 2, 4 points
    want = _brute(points, xs)
    assert len(set(want)) > 10 and want.max() < len(lattice)  # the first copy always
    for batches in (1, 2, 3, 7, len(points)):
        np.testing.assert_array_equal(_grown(points, batches).query(xs), want)


def test_memory_that_keeps_everything_recalls_all_and_copies_a_reused_state():
    body = gbmodel.make_body("arm5")
    rng = np.random.default_rng(1)
    params = example_memory.Params(goals=40, window=0).validate()
    state = example_memory.init(params, body, 1.0, rng)
    draws = example_memory.draw(params, body, 12, rng)
    after = example_memory.train(state, params, body, np.ones(12), np.ones((12, 5)), draws)
    x, q = example_memory.memory(after)
    assert len(x) == 1 + 12 * 40  # nothing forgotten, the home example included
    np.testing.assert_array_equal(example_memory.predict(after, params, body, x[1:]), q[1:])
    # the same epochs again from the first state: the same examples (the first state's store
    # grew under it, so it is copied, not shared)
    again = example_memory.train(state, params, body, np.ones(12), np.ones((12, 5)), draws)
    np.testing.assert_array_equal(example_memory.memory(again)[0], x)
    # one epoch at a time gives the epoch-block's result
    step = state
    for e in range(12):
        step = example_memory.train(step, params, body, np.ones(1), np.ones((1, 5)),
                                    tuple(d[e:e + 1] for d in draws))
    np.testing.assert_array_equal(example_memory.memory(step)[1], q)


def test_memory_window_zero_is_accepted_and_negative_is_not():
    example_memory.Params(window=0).validate()
    with pytest.raises(ValueError, match="learner.window"):
        example_memory.Params(window=-1).validate()


# ---- goals chosen by learning progress ----------------------------------------------------------
from gbmodel.learners import online_goal_babbling  # noqa: E402
from gbmodel import goals  # noqa: E402

GROWING = {"pattern": "proportional", "period": 20, "start_size": 0.5}


@pytest.mark.parametrize("body, digest", [("arm5", "294d8775bfc29d33"),
                                          ("icub", "617190af3df0ee01")])
def test_random_goal_selection_is_byte_identical_to_before(body, digest):
    """goal_selection=random (the default) gives the bytes of the code before the option
    existed (digest of the curve and M, computed on commit 7a54fd5)."""
    import hashlib
    for learner in ({"name": "goal_babbling"},
                    {"name": "goal_babbling", "goal_selection": "random"}):
        r = gbmodel.run_trial(gbmodel.TrialSpec(body={"name": body}, learner=learner, epochs=30,
                                                growth=GROWING), np.random.default_rng(3))
        assert hashlib.sha256(r.abs_error.tobytes() + r.M.tobytes()).hexdigest()[:16] == digest


def test_progress_probabilities_follow_the_regions_change_of_error():
    """Constructed errors: region 0 of 4 improves by 3 mm, region 2 by 1 mm, the others stay.
    The chosen targets' frequencies match share / N + (1 - share) progress share / N_r."""
    targets = gbmodel.make_body("arm5").targets
    region = goals.regions(targets)
    assert sorted(set(region)) == [0, 1, 2, 3]
    tracker = goals.start(targets)
    window = 2
    for drop in (0.0, 0.0, 3e-3, 3e-3):  # the older window, then the newer one
        errors = 0.01 - np.where(region == 0, drop, 0.0) - np.where(region == 2, drop / 3, 0.0)
        tracker = tracker.measured(errors, region, window)
    progress = tracker.progress(window)
    np.testing.assert_allclose(progress, [3e-3, 0.0, 1e-3, 0.0], atol=1e-15)
    p = goals.probabilities(progress, region, share=0.2)
    N, n_r = len(targets), np.bincount(region)
    want_region = 0.2 * n_r / N + 0.8 * np.array([0.75, 0.0, 0.25, 0.0])
    np.testing.assert_allclose(np.bincount(region, weights=p), want_region, rtol=1e-12)
    u = np.random.default_rng(0).uniform(size=200_000)
    freq = np.bincount(region[goals.choose(u, p)], minlength=4) / len(u)
    np.testing.assert_allclose(freq, want_region, atol=4e-3)
    # no measurement window yet, or no progress anywhere: uniform
    np.testing.assert_array_equal(goals.probabilities(None, region, 0.2), np.full(N, 1 / N))
    np.testing.assert_array_equal(goals.probabilities(np.zeros(4), region, 0.2),
                                  np.full(N, 1 / N))


@pytest.mark.parametrize("name", ["goal_babbling", "online_goal_babbling"])
def test_progress_selection_learns_and_does_not_depend_on_the_evaluation_cuts(name):
    learner = {"name": name, "goal_selection": "progress", "progress_period": 3}
    runs = [gbmodel.run_trial(gbmodel.TrialSpec(learner=learner, epochs=40, growth=GROWING,
                                                evals_per_decade=k), np.random.default_rng(5))
            for k in (2, 20)]
    np.testing.assert_array_equal(runs[0].M, runs[1].M)
    random = gbmodel.run_trial(gbmodel.TrialSpec(learner={"name": name}, epochs=40,
                                                 growth=GROWING), np.random.default_rng(5))
    assert not np.array_equal(random.M, runs[1].M)  # the choice acts
    assert 0.5 < runs[1].rel_error[-1] / random.rel_error[-1] < 2  # and learns as well
    assert runs[1].samples_per_epoch == random.samples_per_epoch + 22  # 66 targets / 3


def test_progress_selection_online_paths_follow_the_chosen_targets():
    """The chosen targets reach the online kernel as hops: with all progress in one region
    (share 0), every target of the epoch lies in it; fast and reference paths agree."""
    body = gbmodel.make_body("arm5")
    p = online_goal_babbling.Params(goal_selection="progress", progress_period=1,
                                    progress_window=1, progress_share=0.0)
    rng = np.random.default_rng(2)
    state = online_goal_babbling.init(p, body, 1.0, rng)
    region = goals.regions(body.targets)
    tracker = goals.start(body.targets).measured(np.full(len(region), 0.01), region, 1)
    tracker = tracker.measured(np.where(region == 3, 0.05, 0.01), region, 1)  # only region 3
    state = online_goal_babbling.replace(state, tracker=tracker)
    draws = online_goal_babbling.draw(p, body, 1, rng)
    probs = goals.probabilities(state.tracker.progress(1), region, 0.0)
    chosen = goals.choose(draws[0][0], probs)
    assert set(region[chosen]) == {3}
    a = online_goal_babbling.train(state, p, body, np.ones(1), np.ones((1, 5)), draws, [1])
    assert a.target == chosen[-1]
    ref = online_goal_babbling.train(state, online_goal_babbling.replace(p, fast=False), body,
                                     np.ones(1), np.ones((1, 5)), draws, [1])
    np.testing.assert_allclose(a.M, ref.M, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("field, value", [("goal_selection", "curious"),
                                          ("progress_period", 0), ("progress_share", 1.5)])
def test_bad_goal_selection_names_the_field(field, value):
    from gbmodel.learners import goal_babbling
    for module in (goal_babbling, online_goal_babbling):
        with pytest.raises(ValueError, match=f"learner.{field}"):
            module.Params(**{field: value}).validate()


# ---- the held-out set -----------------------------------------------------------------------------
from gbmodel import evaluation  # noqa: E402


@pytest.mark.parametrize("name", ["arm5", "icub"])
def test_heldout_points_are_fixed_inside_the_box_off_the_grid_and_scale_with_the_body(name):
    body = gbmodel.make_body(name)
    x = evaluation.heldout_points(body)
    np.testing.assert_array_equal(x, evaluation.heldout_points(body))  # fixed
    np.testing.assert_array_equal(evaluation.heldout_points(body, 0.6), 0.6 * x)
    lo, hi = body.target_box()
    assert (x >= lo).all() and (x <= hi).all()
    assert len(x) == len(gbmodel.bodies.cell_centres(body.targets)) + evaluation.HELDOUT_UNIFORM
    gap = np.linalg.norm(x[:, None] - body.targets[None], axis=-1).min(axis=1)
    assert gap.min() > 1e-4  # no held-out point is a training target


def test_every_trial_scores_the_heldout_set_beside_its_points():
    spec = gbmodel.TrialSpec(learner={"name": "example_memory", "goals": 200}, epochs=5,
                             growth=GROWING)
    r = gbmodel.run_trial(spec, np.random.default_rng(0))
    held = gbmodel.run_trial(gbmodel.TrialSpec(**{**spec.to_dict(), "snapshots": (),
                                                  "evaluation": {"points": "heldout"}}),
                             np.random.default_rng(0))
    np.testing.assert_array_equal(r.heldout_abs_error, held.abs_error)
    assert not np.array_equal(r.heldout_abs_error, r.abs_error)
