"""The readings of the paper that it leaves open: evaluation points and formulas, the gradient
step, the disturbance amplitude, the updates per epoch, the rate schedule, successive targets;
each on both paths (reference and kernel, the same draws); and the study's pieces."""
import numpy as np
import pandas as pd
import pytest

import gbmodel
from gbmodel import evaluation
from gbmodel.learners import goal_babbling as gb
from gbmodel.learners.goal_babbling import reference
from pipeline.studies import claims, readings


def test_path_points_are_every_ordered_pair_in_steps():
    body = gbmodel.make_body("arm5")
    pts = evaluation.eval_points(body, 0.5, "path", path_steps=7)
    n = len(body.targets)
    assert pts.shape == (n * (n - 1) * 7, 2)
    lo, hi = body.target_box(0.5)
    assert (pts >= lo - 1e-12).all() and (pts <= hi + 1e-12).all()
    # every grid target starts n - 1 paths
    grid = {tuple(np.round(t, 9)) for t in body.target_set(0.5)}
    starts = [tuple(np.round(p, 9)) for p in pts[::7]]
    assert set(starts) == grid and len(starts) == n * (n - 1)


def test_cell_centres_lie_between_the_targets():
    body = gbmodel.make_body("icub")
    c = evaluation.eval_points(body, 1.0, "centres")
    assert c.shape == (27, 3)
    grid = {tuple(np.round(t, 9)) for t in body.targets}
    assert not grid & {tuple(np.round(p, 9)) for p in c}


def test_formulas_relate_as_they_should():
    d = np.array([0.01, 0.02, 0.04])
    mean, rms, msq = (evaluation.error(d, f) for f in ("mean", "rms", "mean_squared"))
    assert mean == pytest.approx(0.07 / 3) and rms == pytest.approx(np.sqrt(msq))
    assert rms > mean and msq == pytest.approx(np.mean(d ** 2))


def _epoch_inputs(seed=0):
    body = gbmodel.make_body("arm5")
    p = gb.Params(fast=False)
    rng = np.random.default_rng(seed)
    M = gb.init(p, body, 1.0, rng)
    idx, raw = gb.draw(p, body, 1, rng)
    return body, p, M, idx[0], raw[0], gbmodel.exponents(2, 3)


def test_plain_step_is_the_normalised_one_times_sum_w():
    body, p, M, idx, raw, exps = _epoch_inputs()
    one = np.ones(body.m)
    M_norm, (_, _, _, w) = reference.epoch(M, body, 1.0, one, exps, idx, raw, p.radius, p.steps,
                                           1.0, step="normalised")
    M_plain, _ = reference.epoch(M, body, 1.0, one, exps, idx, raw, p.radius, p.steps,
                                 1.0 / w.sum(), step="plain")
    np.testing.assert_allclose(M_plain, M_norm, rtol=0, atol=1e-12)


def test_steps_with_one_step_is_the_batch_step_and_more_steps_move_further():
    body, p, M, idx, raw, exps = _epoch_inputs()
    one = np.ones(body.m)
    args = (M, body, 1.0, one, exps, idx, raw, p.radius, p.steps, 0.5 / 1142)
    M1, _ = reference.epoch(*args)
    Ms, _ = reference.epoch(*args, updates="steps", update_steps=1)
    M3, _ = reference.epoch(*args, updates="steps", update_steps=3)
    np.testing.assert_array_equal(M1, Ms)
    assert np.abs(M3 - M).sum() > np.abs(M1 - M).sum()


def test_online_updates_visit_every_sample_and_approach_the_batch_step_for_small_rates():
    body, p, M, idx, raw, exps = _epoch_inputs()
    one = np.ones(body.m)
    args = (M, body, 1.0, one, exps, idx, raw, p.radius, p.steps, 1e-4 / 1142)
    M_batch, _ = reference.epoch(*args)
    M_online, _ = reference.epoch(*args, updates="online")
    step = np.abs(M_batch - M).max()
    assert np.abs(M_online - M_batch).max() < 1e-3 * step


def test_uniform_amplitude_never_exceeds_R_and_exact_reaches_it():
    body = gbmodel.make_body("arm5")
    rng = np.random.default_rng(3)
    raw = rng.uniform(-1, 1, size=(20, body.m, body.n + 1))
    amp = rng.uniform(0, 1, size=(20, body.m))
    lo, hi = body.target_box(1.0)
    corners = np.array([[x, y] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])])
    for a, want in ((None, np.full((20, body.m), 0.2)), (amp, 0.2 * amp)):
        A, b = reference.scale_perturbations(raw, lo, hi, 0.2, a)
        peak = np.abs(corners @ A.transpose(0, 2, 1) + b[:, None, :]).max(axis=1)
        np.testing.assert_allclose(peak, want, rtol=1e-12)


def test_uniform_amplitude_draws_after_the_exact_draws():
    body = gbmodel.make_body("arm5")
    exact = gb.draw(gb.Params(), body, 5, np.random.default_rng(0))
    uniform = gb.draw(gb.Params(amplitude="uniform", fast=False), body, 5, np.random.default_rng(0))
    for a, b in zip(exact, uniform):
        np.testing.assert_array_equal(a, b)
    assert uniform[2].shape == (5, 20, 5) and (0 <= uniform[2]).all() and (uniform[2] <= 1).all()


READINGS = [dict(), dict(step="normalised", learning_rate=1.0), dict(amplitude="uniform"),
            dict(updates="steps", update_steps=2, learning_rate=0.5 / 1142), dict(updates="online"),
            dict(rate_schedule="annealed", anneal_epochs=40.0), dict(targets="any")]


@pytest.mark.parametrize("kw", READINGS)
def test_every_reading_learns(kw):
    spec = gbmodel.TrialSpec(body={"name": "arm5"},
                             learner={"name": "goal_babbling", "fast": False, **kw}, epochs=40)
    res = gbmodel.run_trial(spec, np.random.default_rng(0))
    assert res.abs_error[-1] < 0.75 * res.abs_error[0]


def test_diagnostics_see_a_rise_above_the_start_body_and_a_rebound_during_growth():
    # T_G = 4: the growing body's error climbs above the short reference while it grows
    conds = {"TG4": [0.10, 0.12, 0.15, 0.16, 0.10, 0.08],
             "const0.5": [0.10, 0.09, 0.08, 0.07, 0.06, 0.05],
             "const1.0": [0.40, 0.30, 0.20, 0.15, 0.12, 0.10]}
    trials = pd.DataFrame([dict(condition=c, trial=t, epoch=e, abs_error=v, rel_error=v)
                           for c, vs in conds.items() for t in range(2)
                           for e, v in enumerate(vs, start=1)])
    summary = pd.DataFrame([
        dict(figure="f", condition="TG4", growth="proportional", growth_period=4, end_size=1.0,
             n_trials=2, n_bootstrap_failures=0, n_run_failures=0, paper_final_abs_error=np.nan),
        *[dict(figure="f", condition=c, growth="none", growth_period=0, end_size=s, n_trials=2,
               n_bootstrap_failures=0, n_run_failures=0, paper_final_abs_error=np.nan)
          for c, s in (("const0.5", 0.5), ("const1.0", 1.0))]])
    tests = {t.claim: t for t in claims.judge(claims.measures("f", trials, summary))}
    assert tests["above_start"].values == pytest.approx([0.16 / 0.07 - 1] * 2)
    assert tests["during"].values == pytest.approx([0.6] * 2)  # 0.16 over the minimum 0.10


def test_readings_split_names_conditions_as_in_the_figure():
    summary = pd.DataFrame(dict(variant=["a", "a", "b"], condition=["a | TG10", "a | const1.0",
                                                                       "b | TG10"]))
    curves = pd.DataFrame(dict(condition=["a | TG10", "b | TG10"], epoch=[1, 1]))
    out = readings.split(dict(summary=summary, curves=curves))
    assert list(out) == ["a", "b"]
    assert out["a"][1]["condition"].tolist() == ["TG10", "const1.0"]
    assert out["b"][0]["condition"].tolist() == ["TG10"]


def test_common_start_reading_grows_the_half_size_arm_into_an_unequal_one():
    body = gbmodel.make_body("arm5")
    g = gbmodel.Growth(pattern="nonproportional", period=10, fixed_scale=0.5).validate(body)
    start, end = g.scales(body, [0.5, 1.0])
    np.testing.assert_allclose(start, 0.5)  # the proportionally halved arm, 5 x 0.1 m
    np.testing.assert_allclose(end, [4 / 3, 0.5, 4 / 3, 0.5, 4 / 3])  # segments 1, 3, 5 grow
    for size, k in ((0.5, start), (1.0, end)):
        assert (0.2 * k).sum() == pytest.approx(size)
    # the paper's other reading (ours): the full-size arm is the common end
    common_end = gbmodel.Growth(pattern="nonproportional", period=10).scales(body, [0.5, 1.0])
    np.testing.assert_allclose(common_end[1], 1.0)
    assert common_end[0][1] == 1.0 and common_end[0][0] == pytest.approx(1 / 6)


@pytest.mark.parametrize("body", ["arm5", "icub"])
@pytest.mark.parametrize("kw", READINGS)
def test_the_kernel_takes_the_readings_as_the_reference_does(body, kw):
    """The same draws on both paths give the same curve and M (the kernel's float32 rollout)."""
    if body == "icub":
        kw = {**dict(radius=0.1, targets_per_epoch=30, steps=10, learning_rate=1 / 1791), **kw}
    growth = {"pattern": "proportional", "period": 20, "start_size": 0.5}
    runs = [gbmodel.run_trial(gbmodel.TrialSpec(body={"name": body}, growth=growth, epochs=40,
                                                learner={"name": "goal_babbling", "fast": f,
                                                         **kw}), np.random.default_rng(5))
            for f in (True, False)]
    np.testing.assert_allclose(runs[0].abs_error, runs[1].abs_error, rtol=0, atol=1e-5)
    np.testing.assert_allclose(runs[0].M, runs[1].M, rtol=0, atol=1e-5)


@pytest.mark.parametrize("fixed_scale", [1.0, 0.5])
def test_the_kernel_grows_both_non_proportional_readings_as_the_reference_does(fixed_scale):
    growth = {"pattern": "nonproportional", "period": 20, "start_size": 0.5,
              "fixed_scale": fixed_scale}
    runs = [gbmodel.run_trial(gbmodel.TrialSpec(body={"name": "arm5"}, growth=growth, epochs=40,
                                                learner={"name": "goal_babbling", "fast": f}),
                              np.random.default_rng(6)) for f in (True, False)]
    np.testing.assert_allclose(runs[0].abs_error, runs[1].abs_error, rtol=0, atol=1e-5)
    np.testing.assert_allclose(runs[0].M, runs[1].M, rtol=0, atol=1e-5)


@pytest.mark.parametrize("key, value", [("updates", "sample"), ("rate_schedule", "cosine"),
                                        ("anneal_epochs", 0.0), ("targets", "same"),
                                        ("step", "normalized")])
def test_a_bad_reading_is_refused_naming_its_key(key, value):
    with pytest.raises(gbmodel.SpecError, match=f"learner.{key}"):
        gb.Params(**{key: value}).validate()


def test_the_annealed_rate_falls_as_tau_over_tau_plus_epochs():
    p = gb.Params(rate_schedule="annealed", anneal_epochs=10_000.0, learning_rate=0.001)
    np.testing.assert_allclose(p.rates([1, 10_001, 90_001]), [0.001, 0.0005, 0.0001])
    np.testing.assert_array_equal(gb.Params(learning_rate=0.001).rates([1, 5, 10**5]), 0.001)


def test_the_annealed_rate_changes_the_run_and_the_schedule_follows_the_epoch_number():
    """Annealing acts through the epoch number the trial passes: a trial of E epochs equals E
    annealed epochs from the start, whatever the evaluation schedule cuts them into."""
    def run(epochs, kw, per_decade=20):
        spec = gbmodel.TrialSpec(body={"name": "arm5"}, learner={"name": "goal_babbling", **kw},
                                 epochs=epochs, evals_per_decade=per_decade)
        return gbmodel.run_trial(spec, np.random.default_rng(4))
    annealed = dict(rate_schedule="annealed", anneal_epochs=5.0)
    a, b = run(60, annealed), run(60, annealed, per_decade=3)
    np.testing.assert_array_equal(a.M, b.M)
    assert not np.allclose(a.M, run(60, {}).M, atol=1e-6)


def test_successive_targets_may_repeat_only_with_targets_any():
    body = gbmodel.make_body("arm5")
    for targets, repeats in (("distinct", False), ("any", True)):
        idx = gb.draw(gb.Params(targets=targets), body, 200, np.random.default_rng(1))[0]
        assert (np.diff(idx, axis=1) == 0).any() == repeats
        assert idx.min() == 0 and idx.max() == len(body.targets) - 1
