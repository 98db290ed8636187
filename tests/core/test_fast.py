"""The fast path of Goal Babbling (fast.py, float32 numba kernels) against the float64 numpy
reference (reference.py, and the shared numpy evaluation).

Tolerances, and what was measured (this kernel; the one before it measured alike):
- sin/cos: 2e-6 absolute for |x| <= 10 rad (measured 7e-8);
- one epoch from the same M and the same draws: positions 2e-6 m (measured <= 2e-7 m),
  postures 2e-6 (rad or normalised units; measured <= 4e-7), weights 1e-3 relative to the
  largest weight (measured <= 2e-4, on the 2-DOF arm: a weight divides the float32 difference of
  two near postures, |dx| / |dq|, so a short joint step magnifies their rounding), and the
  updated M 1e-6 (measured <= 1e-7);
- the evaluation's distances |f(g(x*)) - x*|: 2e-6 m (measured <= 2e-7 m);
- a 200-epoch learning curve: 1e-5 m (measured 3e-8 m for arm5 and for iCub), M 1e-4 (2e-7).
"""
import dataclasses
import hashlib

import numpy as np
import pytest

import gbmodel
from gbmodel import evaluation, simd
from gbmodel.features import exponents, monomial_tree
from gbmodel.growth import factors
from gbmodel.learners import goal_babbling as gb
from gbmodel.learners.goal_babbling import fast, online, reference

SETTINGS = {
    "arm2": dict(radius=0.2, targets_per_epoch=15, steps=7),
    "arm5": dict(radius=0.2, targets_per_epoch=15, steps=7),
    "icub": dict(radius=0.1, targets_per_epoch=30, steps=10),
}


def spec_for(name, pattern="proportional", fast_path=True, body=None, growth=None, **kw):
    learner = {"name": "goal_babbling", "fast": fast_path, **SETTINGS[name]}
    learner.update({k: v for k, v in kw.items() if k != "epochs"})
    return gbmodel.TrialSpec(body=body or {"name": name},
                             growth=growth or {"pattern": pattern, "period": 100,
                                               "start_size": 0.5},
                             learner=learner, epochs=kw.get("epochs", 200))


def test_sincos_accuracy():
    x = np.linspace(-10, 10, 200_001).astype(np.float32)
    s, c = simd.sincos_array(x)
    exact = x.astype(np.float64)
    assert np.abs(s - np.sin(exact)).max() < 2e-6
    assert np.abs(c - np.cos(exact)).max() < 2e-6


@pytest.mark.parametrize("name, pattern, size, degree", [
    ("arm2", "proportional", 1.0, 3), ("arm5", "proportional", 0.7, 3),
    ("arm5", "nonproportional", 0.6, 3), ("icub", "proportional", 0.5, 3),
    ("arm5", "proportional", 0.8, 2),  # p = 6: the kernel's tiles with a remainder
])
def test_one_epoch_matches_reference(name, pattern, size, degree):
    body = gbmodel.make_body(name)
    params = gb.Params(**SETTINGS[name], degree=degree)
    exps = exponents(body.n, params.degree)
    scale = factors(body, size, pattern)
    rng = np.random.default_rng(3)
    M = gb.init(params, body, size, rng)
    for _ in range(3):  # a few epochs, each from the reference's M
        idx, raw = gb.draw(params, body, 1, rng)
        M_ref, (xstar, x, q, w) = reference.epoch(M, body, size, scale, exps, idx[0], raw[0],
                                                  params.radius, params.steps,
                                                   params.learning_rate)
        M_fast, q_fast, x_fast, w_fast = fast.epoch_samples(M, body, params, exps, size, scale,
                                                            idx[0], raw[0])
        np.testing.assert_allclose(x_fast, x, atol=2e-6)
        np.testing.assert_allclose(q_fast, q, atol=2e-6)
        np.testing.assert_allclose(w_fast, w, atol=1e-3 * w.max())
        np.testing.assert_allclose(M_fast, M_ref, atol=1e-6)
        assert not np.allclose(M_ref, M, atol=1e-6), "the epoch must change M"
        M = M_ref


@pytest.mark.parametrize("name", ["arm5", "icub"])
def test_one_epoch_takes_its_own_rate_as_the_reference_does(name):
    """The kernel's eta of one epoch (a schedule's, here half the learning rate) is the one it is
    given, not params.learning_rate: the same M as the reference at that rate."""
    body = gbmodel.make_body(name)
    params = gb.Params(**SETTINGS[name])
    exps = exponents(body.n, params.degree)
    scale = np.ones(body.m)
    rng = np.random.default_rng(9)
    M = gb.init(params, body, 1.0, rng)
    idx, raw = gb.draw(params, body, 1, rng)
    rate = 0.5 * params.learning_rate
    M_ref, _ = reference.epoch(M, body, 1.0, scale, exps, idx[0], raw[0], params.radius,
                               params.steps, rate)
    M_fast = fast.epoch_samples(M, body, params, exps, 1.0, scale, idx[0], raw[0], rate=rate)[0]
    M_full = fast.epoch_samples(M, body, params, exps, 1.0, scale, idx[0], raw[0])[0]
    np.testing.assert_allclose(M_fast, M_ref, atol=1e-6)
    np.testing.assert_allclose(M_fast - M, 0.5 * (M_full - M), atol=1e-9)


@pytest.mark.parametrize("name, pattern, size", [
    ("arm2", "proportional", 1.0), ("arm5", "nonproportional", 0.6),
    ("icub", "proportional", 0.5), ("icub", "proportional", 1.0),
])
def test_distances_match_numpy_evaluation(name, pattern, size):
    """The kernel's float32 rollout of the evaluation against gbmodel.evaluation's numpy one,
    for an initial and a learned M, on the grid and off it."""
    body = gbmodel.make_body(name)
    params = gb.Params(**SETTINGS[name])
    scale = factors(body, size, pattern)
    rng = np.random.default_rng(5)
    M0 = gb.init(params, body, size, rng)
    M1 = gb.train(M0, params, body, np.full(20, size), np.tile(scale, (20, 1)),
                  gb.draw(params, body, 20, rng), np.arange(1, 21))
    for M in (M0, M1):
        for points in ("grid", "centres", "path"):
            xs = evaluation.eval_points(body, size, points)
            d_fast = gb.distances(M, params, body, scale, xs)
            d_ref = evaluation.distances(lambda x: gb.predict(M, params, body, x), body, scale,
                                         xs)
            assert d_fast.shape == (len(xs),)
            np.testing.assert_allclose(d_fast, d_ref, atol=2e-6)


@pytest.mark.parametrize("name", ["arm2", "arm5", "icub"])
def test_each_points_distance_is_its_own(name):
    """The kernel's distances of 1,100 points (three blocks of the rollout, the last padded)
    are, bit for bit, those of each point alone; no points give none."""
    body = gbmodel.make_body(name)
    params = gb.Params(**SETTINGS[name])
    scale = factors(body, 0.8, "proportional")
    rng = np.random.default_rng(9)
    M = gb.init(params, body, 0.8, rng)
    lo, hi = body.target_box(0.8)
    xs = rng.uniform(lo - 0.1, hi + 0.1, size=(1100, body.n))
    together = gb.distances(M, params, body, scale, xs)
    alone = np.concatenate([gb.distances(M, params, body, scale, xs[i:i + 1])
                            for i in range(len(xs))])
    assert together.tobytes() == alone.tobytes()
    assert gb.distances(M, params, body, scale, xs[:0]).shape == (0,)


@pytest.mark.parametrize("name, pattern", [("arm5", "nonproportional"), ("icub", "proportional")])
def test_learning_curve_matches_reference(name, pattern):
    ref = gbmodel.run_trial(spec_for(name, pattern, fast_path=False), np.random.default_rng(8))
    fst = gbmodel.run_trial(spec_for(name, pattern, fast_path=True), np.random.default_rng(8))
    np.testing.assert_array_equal(fst.epoch, ref.epoch)
    np.testing.assert_allclose(fst.abs_error, ref.abs_error, atol=1e-5)
    np.testing.assert_allclose(fst.M, ref.M, atol=1e-4)
    assert ref.rel_error[-1] < ref.rel_error[0]


def test_body_variant_without_saturation():
    """A body variant (here: the iCub with its joint limits ignored) runs on both paths alike,
    and ignoring the limits does change the outcome."""
    free = gbmodel.make_body("icub", saturate=False)
    q = np.full(10, 1.5)
    assert not np.allclose(free.forward(q), gbmodel.make_body("icub").forward(q))

    def spec(body, fast_path):
        return spec_for("icub", body=body, fast_path=fast_path, growth={"start_size": 1.0},
                        radius=0.6, epochs=30)

    ref = gbmodel.run_trial(spec({"name": "icub", "saturate": False}, False),
                            np.random.default_rng(2))
    fst = gbmodel.run_trial(spec({"name": "icub", "saturate": False}, True),
                            np.random.default_rng(2))
    clipped = gbmodel.run_trial(spec({"name": "icub"}, True), np.random.default_rng(2))
    np.testing.assert_allclose(fst.abs_error, ref.abs_error, atol=1e-5)
    assert not np.allclose(fst.abs_error, clipped.abs_error, atol=1e-5)


def test_arrays_cached_per_body():
    """The body's kernel arrays are built once per body object and monomial table."""
    body = gbmodel.make_body("arm5")
    exps = exponents(body.n)
    assert fast._arrays(body, exps) is fast._arrays(body, exponents(body.n))
    other = dataclasses.replace(body, saturates=not body.saturates)
    assert fast._arrays(other, exps) is not fast._arrays(body, exps)


@pytest.mark.parametrize("name, kw", [
    ("arm5", dict(variations=6)), ("icub", dict(variations=3)),
    ("icub_urdf", dict(variations=3)), ("arm5", dict(variations=6, degree=2)),  # p = 6
])
def test_online_updates_match_the_reference_steps(name, kw):
    """The kernel's per-sample steps (vectors over the rows of M, the prediction pipelined) are
    reference.update's, sample by sample, on the epoch's own samples, to 1e-9; and with some
    weights set to 0 (a step by 0; runs of them across the kernel's chunks of samples)."""
    body = gbmodel.make_body(name)
    params = gb.Params(**SETTINGS["icub" if body.n == 3 else name], updates="online", **kw)
    exps = exponents(body.n, params.degree)
    rng = np.random.default_rng(5)
    M = gb.init(params, body, 1.0, rng)
    idx, raw = gb.draw(params, body, 1, rng)
    M_fast, q, x, w = fast.epoch_samples(M, body, params, exps, 1.0, np.ones(body.m), idx[0],
                                         raw[0])
    x, q, w = (np.asarray(a, np.float64) for a in (x, q, w))

    def expect(w):
        return reference.update(M, x, q, w, exps, params.learning_rate, updates="online")
    assert np.abs(expect(w) - M).max() > 1e-3, "the epoch must change M"
    np.testing.assert_allclose(M_fast, expect(w), rtol=0, atol=1e-9)
    w = w.copy()
    w[:, ::7] = 0
    w[1, 3:] = 0
    N = w.size
    X = np.zeros((body.n, N + 16), np.float32)  # the columns the kernel reads past N
    Q = np.zeros((body.m, N + 16), np.float32)
    X[:, :N], Q[:, :N] = x.reshape(N, -1).T, q.reshape(N, -1).T
    parent, var = monomial_tree(exps)
    M_zero = np.array(M)
    online.online(M_zero, X, Q, w.reshape(-1).astype(np.float32), N, parent, var,
                  params.learning_rate)
    np.testing.assert_allclose(M_zero, expect(w), rtol=0, atol=1e-9)
    # one sample fewer (the kernel takes samples in pairs: an odd count ends on a single one);
    # the reference's last sample then has weight 0 and leaves M as it is
    w[-1, -1] = 1.0
    M_odd = np.array(M)
    online.online(M_odd, X, Q, w.reshape(-1).astype(np.float32), N - 1, parent, var,
                  params.learning_rate)
    w[-1, -1] = 0
    np.testing.assert_allclose(M_odd, expect(w), rtol=0, atol=1e-9)


# sha256[:16] of a 30-epoch trial's curve and final M (updates=online, seed 1)
ONLINE_TRIALS = {"arm2": "adcac5c21e7acbc0", "arm5": "7c775ca61b9b621e",
                 "icub": "4650ce38ad902866"}


@pytest.mark.parametrize("name", sorted(ONLINE_TRIALS))
def test_online_updates_trial_bytes_are_pinned(name):
    spec = gbmodel.TrialSpec(body={"name": name},
                             learner={"name": "goal_babbling", "fast": True,
                                      "updates": "online"}, epochs=30)
    r = gbmodel.run_trial(spec, np.random.default_rng(1))
    digest = hashlib.sha256(r.abs_error.tobytes() + r.M.tobytes()).hexdigest()[:16]
    assert digest == ONLINE_TRIALS[name]
