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
