"""The learners beside Goal Babbling: motor babbling (direct inverse learning), an example memory
(nearest neighbour) and online Goal Babbling, each through the plug-in protocol and the one trial
loop. Learning thresholds come from measured runs (numbers in the comments), with margin."""
import dataclasses
import math

import numpy as np
import pytest

import gbmodel
from gbmodel import SpecError, TrialSpec, learners, run_trial
from gbmodel.features import exponents, features
from gbmodel.learners import example_memory, motor_babbling, online_goal_babbling
from gbmodel.simd import sincos64

NEW = ["motor_babbling", "example_memory", "online_goal_babbling"]
ALL = learners.available()  # every registered learner: the protocol tests run over each
STATIC = {"start_size": 1.0, "end_size": 1.0}  # no growth, the full body
ICUB = {"online_goal_babbling": {"targets_per_epoch": 30, "steps": 10, "radius": 0.1,
                                 "learning_rate": 0.3}}


def _run(name, epochs, body="arm5", growth=STATIC, seed=0, snapshots=(), evaluation=None,
         **params):
    spec = TrialSpec(body={"name": body}, growth=growth, learner={"name": name, **params},
                     epochs=epochs, snapshots=snapshots, evaluation=evaluation or {})
    return run_trial(spec, np.random.default_rng(seed))


def _at(result, epoch):
    return result.abs_error[np.searchsorted(result.epoch, epoch)]


# ---- the protocol: every registered learner, Goal Babbling included ------------------------------
def _trained(module, params, body, epochs, seed=0, split=None):
    """The state after `epochs` epochs of the full body from init(seed), trained in one call or
    in two (split: the first call's epochs), and the draws it consumed."""
    rng = np.random.default_rng(seed)
    state = module.init(params, body, 1.0, rng)
    draws = module.draw(params, body, epochs, rng)
    sizes = np.ones(epochs)
    scales = gbmodel.Growth().scales(body, sizes)
    numbers = np.arange(1, epochs + 1)
    for lo, hi in ((0, split), (split, epochs)) if split else ((0, epochs),):
        state = module.train(state, params, body, sizes[lo:hi], scales[lo:hi],
                             tuple(d[lo:hi] for d in draws), numbers[lo:hi])
    return state, draws


@pytest.mark.parametrize("name", ALL)
def test_satisfies_the_protocol(name):
    """What gbmodel/learners/__init__.py asks of a learner, REQUIRED and OPTIONAL, on arm5."""
    module = learners.get(name)
    assert all(hasattr(module, attr) for attr in learners.REQUIRED)
    params = module.Params().validate()
    assert dataclasses.is_dataclass(params) and type(params).__dataclass_params__.frozen
    body = gbmodel.make_body("arm5")
    state, draws = _trained(module, params, body, 3)
    assert isinstance(draws, tuple) and all(len(d) == 3 for d in draws)  # leading axis: epochs
    x = body.targets[:4]
    q = module.predict(state, params, body, x)
    assert q.shape == (4, body.m) and np.isfinite(q).all()
    n = module.samples_per_epoch(params, body)
    assert isinstance(n, int) and n > 0
    stored = module.model(state)
    assert stored is None or isinstance(stored, np.ndarray)
    if stored is not None:  # a copy: what is stored never moves the learner
        stored[...] = 0.0
        np.testing.assert_array_equal(module.predict(state, params, body, x), q)
        stored = module.model(state)
    if hasattr(module, "sample_cost"):
        cost = module.sample_cost(params)
        assert isinstance(cost, float) and 0 < cost < math.inf
    if hasattr(module, "notes"):
        notes = module.notes(params, body)
        assert isinstance(notes, list) and all(isinstance(t, str) for t in notes)
    if hasattr(module, "predict_model"):  # the report draws postures with it
        assert stored is not None, "predict_model needs a stored model"
        np.testing.assert_array_equal(module.predict_model(stored, params, body, x), q)
    if hasattr(module, "distances"):  # its own way to f(g(x*)) - x*: the shared one's numbers
        scale = gbmodel.Growth().scales(body, np.ones(1))[0]
        own = module.distances(state, params, body, scale, body.targets)
        shared = gbmodel.evaluation.distances(lambda x: module.predict(state, params, body, x),
                                              body, scale, body.targets)
        assert own.shape == (len(body.targets),)
        np.testing.assert_allclose(own, shared, rtol=1e-5, atol=1e-6)  # a float32 rollout


@pytest.mark.parametrize("name", ALL)
def test_training_in_two_calls_is_training_in_one(name):
    """train consumes the draws of its epochs only: the trial loop cuts a trial into calls at
    every evaluation and snapshot, and that must change no number."""
    module = learners.get(name)
    params, body = module.Params().validate(), gbmodel.make_body("arm5")
    one, _ = _trained(module, params, body, 5)
    two, _ = _trained(module, params, body, 5, split=2)
    x = body.targets[::7]
    np.testing.assert_array_equal(module.predict(two, params, body, x),
                                  module.predict(one, params, body, x))


@pytest.mark.parametrize("name", ALL)
def test_deterministic(name):
    a = _run(name, 12, snapshots=(5,), growth={"period": 6})
    b = _run(name, 12, growth={"period": 6})  # snapshots cut the blocks, change no number
    c = _run(name, 12, growth={"period": 6}, seed=1)
    assert a.abs_error.tobytes() == b.abs_error.tobytes()
    assert a.abs_error.tobytes() != c.abs_error.tobytes()


@pytest.mark.parametrize("name, field, value", [
    ("motor_babbling", "samples", 0), ("motor_babbling", "spread", 0.0),
    ("motor_babbling", "window", -1), ("motor_babbling", "fit", "normal_equations"),
    ("motor_babbling", "ridge", -1e-3), ("motor_babbling", "learning_rate", 0.0),
    ("example_memory", "goals", 0), ("example_memory", "sigma", -0.1),
    ("example_memory", "window", -1), ("example_memory", "window", 2.5),
    ("online_goal_babbling", "steps", 0), ("online_goal_babbling", "radius", -0.2),
    ("online_goal_babbling", "drift", float("nan")),
    ("online_goal_babbling", "home_probability", 1.5),
    ("online_goal_babbling", "learning_rate", 0.0), ("online_goal_babbling", "fast", "yes"),
])
def test_bad_params_name_the_field(name, field, value):
    with pytest.raises(SpecError, match=f"^learner.{field}=") as err:
        TrialSpec(learner={"name": name, field: value}).validate()
    assert err.value.key == f"learner.{field}"
    with pytest.raises(SpecError, match="^learner="):  # a field the learner does not have
        TrialSpec(learner={"name": name, "variations": 20}).validate()


# ---- learning on arm5 without growth ----------------------------------------------------------
def test_motor_babbling_learns_locally_and_fails_globally():
    # measured (seeds 0-2): spread 0.4 rad, 10 epochs of 2120 samples: 30, 31, 29 mm (and 28-32
    # mm after the first epoch); over the whole joint range (spread pi) the averaged postures miss
    # by 41, 43, 41 cm; the gradient fit after 100 epochs: 0.43 -> 0.17 m
    local = _run("motor_babbling", 10)
    assert local.abs_error[-1] < 0.045, local.abs_error[-1]
    assert _run("motor_babbling", 10, spread=np.pi).abs_error[-1] > 0.3
    grad = _run("motor_babbling", 100, fit="gradient")
    assert grad.abs_error[0] > 0.3 and grad.abs_error[-1] < 0.25, grad.abs_error[-1]


def test_motor_babbling_fits_the_window_by_least_squares():
    """The ring of per-epoch statistics gives the ridge fit to exactly the window's examples."""
    body, rng = gbmodel.make_body("arm5"), np.random.default_rng(3)
    params = motor_babbling.Params(samples=50, window=2, ridge=1e-4).validate()
    state = motor_babbling.init(params, body, 1.0, rng)
    (offsets,) = motor_babbling.draw(params, body, 5, rng)
    scales = np.ones((5, 5)) * np.linspace(0.6, 1.0, 5)[:, None]  # a growing body
    state = motor_babbling.train(state, params, body, np.ones(3), scales[:3], (offsets[:3],))
    state = motor_babbling.train(state, params, body, np.ones(2), scales[3:], (offsets[3:],))
    qs = [body.saturate(body.home + params.spread * offsets[e]) for e in (3, 4)]
    x = np.concatenate([body.forward(q, scales[e]) for q, e in zip(qs, (3, 4))])
    q = np.concatenate(qs)
    phi = features(x, exponents(2))
    expected = np.linalg.solve(phi.T @ phi / len(q) + 1e-4 * np.eye(10), phi.T @ q / len(q)).T
    np.testing.assert_allclose(state.M, expected, rtol=1e-9, atol=1e-12)
    assert state.epochs == 5 and state.gram.shape == (2, 10, 10)


def test_example_memory_learns():
    # measured (seeds 0-2, sigma 0.1, 2120 goals an epoch): 0.20-0.23 m after 1 epoch, 46-50 mm
    # after 3, 2.9-3.0 mm after 10 (2.9 mm after 30); between the targets (cell centres) 3.0-3.2
    # mm after 10
    r = _run("example_memory", 10)
    assert r.abs_error[0] > 0.1 and r.abs_error[-1] < 0.006, r.abs_error[-1]
    off_grid = _run("example_memory", 10, evaluation={"points": "centres"})
    assert off_grid.abs_error[-1] < 0.007, off_grid.abs_error[-1]


def test_example_memory_is_bounded_and_recalls():
    body, rng = gbmodel.make_body("arm5"), np.random.default_rng(4)
    params = example_memory.Params(goals=30, window=3).validate()
    state = example_memory.init(params, body, 1.0, rng)
    x, q = example_memory.memory(state)
    np.testing.assert_array_equal(q, [body.home])  # it starts from the home example
    state = example_memory.train(state, params, body, np.ones(7), np.ones((7, 5)),
                                 example_memory.draw(params, body, 7, rng))
    x, q = example_memory.memory(state)
    assert x.shape == (90, 2) and q.shape == (90, 5)  # window * goals, the home example gone
    np.testing.assert_allclose(body.forward(q), x, atol=1e-15)
    np.testing.assert_array_equal(example_memory.predict(state, params, body, x), q)


def test_online_goal_babbling_learns():
    # measured (200 epochs of 106 samples, seeds 0-4): 0.43-0.50 m at first; the mean over
    # epochs 100-200, 21k samples at most, 78, 66, 75, 70, 63 mm (single points 48-121 mm: one
    # global polynomial, stepped sample by sample along a path, wavers); 500 epochs: 26-38 mm.
    # Goal Babbling (batch) after 300 epochs of 2120 samples: 82 mm (tests/core/test_numerics.py)
    r = _run("online_goal_babbling", 200)
    late = r.abs_error[r.epoch >= 100].mean()
    assert r.abs_error[0] > 0.3 and late < 0.11, late
    assert r.samples_per_epoch == 106


def test_online_paths_and_returns_home():
    body, rng = gbmodel.make_body("arm5"), np.random.default_rng(5)
    params = online_goal_babbling.Params(targets_per_epoch=4, steps=5, home_probability=1.0)
    state = online_goal_babbling.init(params, body, 1.0, rng)
    hops, coins, walk = online_goal_babbling.draw(params, body, 1, rng)
    targets, x_home = body.targets, state.last[1]
    xs, home, target, at_home = online_goal_babbling.plan(state, params, targets, x_home,
                                                          hops[0], coins[0])
    assert len(xs) == 4 * 6 and home.sum() == 4 and at_home
    segments = xs.reshape(4, 6, 2)  # 5 path steps, then home
    np.testing.assert_array_equal(segments[:, -1], np.broadcast_to(x_home, (4, 2)))
    reached = targets[np.cumsum(hops[0]) % len(targets)]
    np.testing.assert_allclose(segments[:, 4], reached)  # each path ends on its target
    np.testing.assert_allclose(segments[:, 0], x_home + 0.2 * (reached - x_home))
    # the perturbation peaks at exactly R over the target box, sample by sample, and drifts
    lo, hi = body.target_box(1.0)
    A, b, P = online_goal_babbling.perturbations(rng.standard_normal((5, 3)),
                                                 rng.standard_normal((100, 5, 3)), params, lo, hi)
    e = np.abs(body.targets @ A.transpose(0, 2, 1) + b[:, None, :])  # (samples, targets, m)
    np.testing.assert_allclose(e.max(axis=1), params.radius)
    step = np.abs(np.diff(A, axis=0)).mean() / np.abs(A).mean()
    assert 0.01 < step < 0.5, step  # slowly: a small change from sample to sample
    # the random walk keeps the spread of the parameters: entries stay N(0, 1)
    ends = []
    for _ in range(200):  # 50 steps apart, nearly independent (correlation 1.09^-25 = 0.12)
        P = online_goal_babbling.perturbations(P, rng.standard_normal((50, 5, 3)), params, lo,
                                               hi)[2]
        ends.append(P)
    assert 0.9 < np.std(ends) < 1.1 and abs(np.mean(ends)) < 0.1


@pytest.mark.parametrize("body, growth", [
    ("arm5", {"pattern": "nonproportional", "period": 10}),
    ("icub", {"pattern": "proximal_first", "period": 10, "schedule": "infant"}),
])
def test_online_fast_path_matches_the_reference(body, growth):
    """The compiled per-sample loop computes the numpy loop's curve from the same draws: they
    differ by rounding only (measured: 2e-15 relative after 30 epochs; the final error of 2000
    epochs on arm5 and of 500 on the iCub, 4e-15)."""
    params = ICUB["online_goal_babbling"] if body == "icub" else {}
    ref = _run("online_goal_babbling", 30, body=body, growth=growth, fast=False, **params)
    fast = _run("online_goal_babbling", 30, body=body, growth=growth, **params)
    np.testing.assert_allclose(fast.abs_error, ref.abs_error, rtol=1e-9)
    np.testing.assert_allclose(fast.M, ref.M, rtol=1e-9, atol=1e-12)
    # the state after three epochs of a growing body, returns home among them: the same path,
    # perturbation and last sample
    body = gbmodel.make_body(body)
    p = online_goal_babbling.Params(**params)
    rng = np.random.default_rng(7)
    state = online_goal_babbling.init(p, body, 0.6, rng)
    before = (state.M.copy(), state.P.copy())
    draws = online_goal_babbling.draw(p, body, 3, rng)
    assert (draws[1] < p.home_probability).any()
    sizes = np.array([0.6, 0.7, 0.8])
    scales = gbmodel.Growth().scales(body, sizes)
    a = online_goal_babbling.train_reference(state, p, body, sizes, scales, draws)
    b = online_goal_babbling.train_fast(state, p, body, sizes, scales, draws)
    assert (a.target, a.at_home) == (b.target, b.at_home)
    np.testing.assert_array_equal(a.P, b.P)  # the random walk: elementwise, the same operations
    np.testing.assert_allclose(b.M, a.M, rtol=1e-12, atol=1e-14)
    for u, v in zip(a.last, b.last):
        np.testing.assert_allclose(v, u, rtol=1e-12, atol=1e-14)
    np.testing.assert_array_equal(state.M, before[0])  # neither path changes its input state
    np.testing.assert_array_equal(state.P, before[1])


def test_online_draws_are_numpys_normals():
    """The random walk comes from numba's Generator: numpy's numbers, and numpy's state after."""
    shape = (3, 7, 5, 3)
    for bits in (np.random.PCG64, np.random.Philox):
        ours, theirs = np.random.Generator(bits(11)), np.random.Generator(bits(11))
        walk = online_goal_babbling.fast.normals(ours, int(np.prod(shape))).reshape(shape)
        np.testing.assert_array_equal(walk, theirs.standard_normal(shape))
        np.testing.assert_array_equal(ours.random(9), theirs.random(9))  # the state after


def test_online_sincos_is_the_c_librarys_within_two_ulp():
    """The kernel's own sin and cos: within 2 ulp of the C library's (math.sin) over joint
    angles and far beyond them, exact multiples of pi/4 included; past 2^24 (a diverging
    command) the C library's own; NaN and inf give NaN."""
    rng = np.random.default_rng(3)
    x = np.concatenate([np.linspace(-40, 40, 20001), rng.uniform(-1e4, 1e4, 20000),
                        np.arange(-64, 65) * np.pi / 4, [0.0, 1e-300, -1e-12],
                        [2.0 ** 24 - 1, 2.0 ** 24, 1e10, -1e16, 1e20, 1e300]])
    got = np.array([sincos64(v) for v in x])
    want = np.array([(math.sin(v), math.cos(v)) for v in x])
    ulp = np.spacing(np.maximum(np.abs(want), 1e-3))  # absolute near the zeros
    assert (np.abs(got - want) <= 2 * ulp).all(), np.abs(got - want).max()
    for bad in (np.nan, np.inf, -np.inf):
        assert np.isnan(sincos64(bad)).all()


@pytest.mark.parametrize("body", ["arm5", "icub"])
def test_online_distances_match_the_numpy_evaluation(body):
    """The fast path's evaluation (its compiled distances) and the shared numpy one agree to
    rounding, on the grid and the held-out set of a grown body with a learned M."""
    body = gbmodel.make_body(body)
    p = online_goal_babbling.Params(**(ICUB["online_goal_babbling"] if body.name == "icub"
                                       else {}))
    rng = np.random.default_rng(4)
    state = online_goal_babbling.init(p, body, 0.7, rng)
    scales = gbmodel.Growth(pattern="nonproportional").scales(body, np.full(3, 0.7))
    state = online_goal_babbling.train(state, p, body, np.full(3, 0.7), scales,
                                       online_goal_babbling.draw(p, body, 3, rng))
    for points in ("grid", "heldout"):
        xs = gbmodel.evaluation.eval_points(body, 0.7, points)
        fast = online_goal_babbling.distances(state, p, body, scales[-1], xs)
        ref = online_goal_babbling.distances(state, online_goal_babbling.replace(p, fast=False),
                                             body, scales[-1], xs)
        assert fast.shape == (len(xs),) and fast.min() > 0
        np.testing.assert_allclose(fast, ref, rtol=1e-12, atol=1e-15)


# ---- under growth, and on the iCub ------------------------------------------------------------
@pytest.mark.parametrize("name", NEW)
@pytest.mark.parametrize("growth", [
    {"pattern": "nonproportional", "period": 10},
    {"pattern": "proximal_first", "period": 10, "schedule": "infant"},
])
def test_runs_under_growth(name, growth):
    # measured relative errors at epochs 1 and 15 (seed 0): motor babbling 6.4 -> 14.5 % (its
    # window of 10 epochs holds outcomes of the smaller body), example memory 27 -> 4.6 %, online
    # Goal Babbling 50 -> 23 % (nonproportional); proximal_first alike
    r = _run(name, 15, growth=growth)
    assert r.size[0] == 0.5 and r.size[-1] == 1.0
    assert np.isfinite(r.abs_error).all() and r.rel_error[-1] < 0.3, r.rel_error[-1]


@pytest.mark.parametrize("name, epochs, end_max", [
    # measured (seed 0, no growth): motor babbling 14 mm from the first epoch on; example memory
    # 46 mm -> 6.1 mm after 10 epochs; online Goal Babbling (eta 0.3, K 30, L 10, R 0.1: 300
    # samples an epoch) 0.15 -> 0.13 m after 10 epochs, 0.22 -> 0.081 m after 40 (Goal
    # Babbling, 6020 samples an epoch: 0.15 -> 0.14 m after 40)
    ("motor_babbling", 5, 0.025), ("example_memory", 10, 0.012),
    ("online_goal_babbling", 10, 0.2),
])
def test_icub(name, epochs, end_max):
    r = _run(name, epochs, body="icub", **ICUB.get(name, {}))
    assert np.isfinite(r.abs_error).all() and r.abs_error[-1] < end_max, r.abs_error[-1]
