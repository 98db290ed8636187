"""The fast path (gbmodel.fast, float32 numba kernels) against the float64 numpy reference.

Tolerances, and what was measured when they were set:
- sin/cos: 2e-6 absolute for |x| <= 10 rad (measured 9e-7);
- one epoch from the same M and the same draws: positions 2e-6 m (measured ~3e-7 m),
  postures 2e-6 (rad or normalised units), weights 1e-4 relative to the largest weight, and the
  updated M 1e-6 (measured ~1e-7);
- a 200-epoch learning curve: 1e-5 m (measured 3e-8 m for arm5, 3e-8 m for iCub).
"""
import numpy as np
import pytest

import gbmodel
from gbmodel import fast, learner, trial
from gbmodel.features import exponents

SETTINGS = {
    "arm2": dict(radius=0.2, targets_per_epoch=15, steps=7),
    "arm5": dict(radius=0.2, targets_per_epoch=15, steps=7),
    "icub": dict(radius=0.1, targets_per_epoch=30, steps=10),
}


def test_sincos_accuracy():
    x = np.linspace(-10, 10, 200_001).astype(np.float32)
    s, c = np.vectorize(fast.sincos.py_func)(x)
    exact = x.astype(np.float64)
    assert np.abs(s - np.sin(exact)).max() < 2e-6
    assert np.abs(c - np.cos(exact)).max() < 2e-6


@pytest.mark.parametrize("name, pattern, size", [
    ("arm2", "proportional", 1.0), ("arm5", "proportional", 0.7),
    ("arm5", "nonproportional", 0.6), ("icub", "proportional", 0.5),
])
def test_one_epoch_matches_reference(name, pattern, size):
    body = gbmodel.make_body(name)
    spec = gbmodel.TrialSpec(body=name, pattern=pattern, **SETTINGS[name])
    exps = exponents(body.n)
    rng = np.random.default_rng(3)
    M = learner.init_inverse(body.home, *body.target_box(size), exps, 0.1, rng)
    for _ in range(3):  # a few epochs, each from the reference's M
        idx, raw = trial._draw(rng, 1, len(body.targets), V=spec.variations, m=body.m, n=body.n,
                               K=spec.targets_per_epoch)
        M_ref, (xstar, x, q, w) = learner.epoch(M, body, size, pattern, exps, idx[0], raw[0],
                                                spec.radius, spec.steps, spec.learning_rate)
        M_fast, q_fast, x_fast, w_fast = fast.epoch_samples(M, body, spec, exps, size, idx[0],
                                                            raw[0])
        np.testing.assert_allclose(x_fast, x, atol=2e-6)
        np.testing.assert_allclose(q_fast, q, atol=2e-6)
        np.testing.assert_allclose(w_fast, w, atol=1e-4 * w.max())
        np.testing.assert_allclose(M_fast, M_ref, atol=1e-6)
        assert not np.allclose(M_ref, M, atol=1e-6), "the epoch must change M"
        M = M_ref


@pytest.mark.parametrize("name, pattern", [("arm5", "nonproportional"), ("icub", "proportional")])
def test_learning_curve_matches_reference(name, pattern):
    spec = gbmodel.TrialSpec(body=name, pattern=pattern, epochs=200, period=100,
                             **SETTINGS[name])
    ref = gbmodel.run_trial(spec, np.random.default_rng(8), fast=False)
    fst = gbmodel.run_trial(spec, np.random.default_rng(8), fast=True)
    np.testing.assert_array_equal(fst.epoch, ref.epoch)
    np.testing.assert_allclose(fst.abs_error, ref.abs_error, atol=1e-5)
    np.testing.assert_allclose(fst.M, ref.M, atol=1e-4)
    assert ref.rel_error[-1] < ref.rel_error[0]


def test_body_variant_without_saturation():
    """A body passed to run_trial replaces the named one on both paths (here: iCub with its
    joint limits ignored), and ignoring the limits does change the outcome."""
    import dataclasses

    free = dataclasses.replace(gbmodel.make_body("icub"), saturates=False)
    q = np.full(10, 1.5)
    assert not np.allclose(free.forward(q), gbmodel.make_body("icub").forward(q))
    spec = gbmodel.TrialSpec(body="icub", epochs=30, start_size=1.0, radius=0.6,
                             **{k: v for k, v in SETTINGS["icub"].items() if k != "radius"})
    ref = gbmodel.run_trial(spec, np.random.default_rng(2), fast=False, body=free)
    fst = gbmodel.run_trial(spec, np.random.default_rng(2), fast=True, body=free)
    clipped = gbmodel.run_trial(spec, np.random.default_rng(2), fast=True)
    np.testing.assert_allclose(fst.abs_error, ref.abs_error, atol=1e-5)
    assert not np.allclose(fst.abs_error, clipped.abs_error, atol=1e-5)
