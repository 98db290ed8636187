"""The reporting conventions' measured alternatives (pipeline/studies/conventions.py), on synthetic
aggregates whose numbers are known: the ddof ratio, the failure flags at other factors, trial 0's
rank, the growth rise of subsampled curves, and the two normalisations of the relative error."""
import numpy as np
import pandas as pd
import pytest

import gbmodel
from pipeline import aggregate_stats
from pipeline.studies import conventions


def _curves(figure, condition, finals, growth="none", period=0, epochs=(1, 2, 3, 4)):
    """Per-trial curves (the trials.parquet columns) ending at the given final abs. errors,
    the body at full size (so rel_error = abs_error)."""
    rows = []
    for trial, final in enumerate(finals):
        for i, e in enumerate(epochs):
            err = final * (len(epochs) - i)  # falling to `final` at the last epoch
            rows.append(dict(figure=figure, body="arm5", learner="goal_babbling", growth=growth,
                             growth_period=period, condition=condition, trial=trial, epoch=e,
                             samples=10 * e, size=1.0, abs_error=err, rel_error=err,
                             heldout_abs_error=err))
    return pd.DataFrame(rows)


def _summary(trials, fail_factor=3.0):
    """aggregate_stats.summarize on the synthetic trials (the numbers the report prints)."""
    conds = {}
    for (c, g, p), _ in trials.groupby(["condition", "growth", "growth_period"], sort=False):
        labels = dict(figure="fig4", body="arm5", learner="goal_babbling", growth=g,
                      growth_period=p, condition=c)
        conds[c] = dict(labels=labels, variant=None, trials={}, diverged={}, missing=[],
                        spec=dict(epochs=int(trials["epoch"].max()), body=dict(name="arm5"),
                                  growth=dict(start_size=1.0, end_size=1.0)))
    curves = aggregate_stats.curve_stats(trials)
    return aggregate_stats.summarize(trials, curves, conds, {}, fail_factor), curves


def test_spread_ratio_is_measured_and_equals_sqrt_n_minus_1_over_n():
    rng = np.random.default_rng(0)
    trials = pd.concat([_curves("fig4", "a", rng.uniform(0.01, 0.03, 4)),
                        _curves("fig4", "b", rng.uniform(0.01, 0.03, 7)),
                        _curves("fig4", "single", [0.02])], ignore_index=True)
    sp = conventions.spread(conventions.finals({"fig4": trials}))
    assert set(sp["ratio"]) == {4, 7}  # one trial has no ddof-1 spread
    for n in (4, 7):
        assert sp["ratio"][n] == pytest.approx(np.sqrt((n - 1) / n), rel=1e-12)
        assert sp["conditions"][n] == 1
    assert sp["deviation"] < 1e-12
    # the ddof-1 spread is the one summary.parquet prints
    summary, _ = _summary(trials)
    fin = conventions.finals({"fig4": trials})
    for c in ("a", "b"):
        std1 = fin.loc[fin["condition"] == c, "rel_error"].std(ddof=1)
        assert summary.set_index("condition").loc[c, "final_rel_error_std"] == pytest.approx(std1)


def test_a_trial_at_4x_the_median_is_flagged_at_1_5_2_3_but_not_5():
    trials = pd.concat([_curves("fig4", "a", [0.01, 0.01, 0.01, 0.01, 0.04]),
                        _curves("fig4", "b", [0.02, 0.021, 0.019])], ignore_index=True)
    fl = conventions.flagged(conventions.finals({"fig4": trials}), (1.5, 2.0, 3.0, 5.0))
    assert fl["counts"] == {1.5: 1, 2.0: 1, 3.0: 1, 5.0: 0}
    assert fl["trials"] == 8
    assert fl["largest"] == pytest.approx(4.0) and fl["where"] == "fig4 a, trial 4"
    # at the configured factor, the same count as aggregate.summarize
    summary, _ = _summary(trials, fail_factor=3.0)
    assert summary["n_bootstrap_failures"].sum() == fl["counts"][3.0]


def test_trial_0_rank_percentile_and_median():
    trials = _curves("fig4", "TG1000", [0.03, 0.01, 0.02, 0.04, 0.05])
    (r,) = conventions.trial0_rank(conventions.finals({"fig4": trials}),
                                   [("fig3", "fig4", "TG1000"), ("fig3", "fig4", "absent")])
    assert (r["rank"], r["n"]) == (3, 5) and r["percentile"] == 50
    assert r["error"] == pytest.approx(0.03) and r["median"] == pytest.approx(0.03)


def _growing(errors, period):
    """One growing condition of fig4 whose mean abs. error at evaluations 1, 2, ... is `errors`."""
    epochs = np.arange(1, len(errors) + 1)
    trials = pd.DataFrame(dict(figure="fig4", body="arm5", learner="goal_babbling",
                               growth="proportional", growth_period=period, condition="TG",
                               trial=0, epoch=epochs, samples=10 * epochs, size=1.0,
                               abs_error=errors, rel_error=errors, heldout_abs_error=errors))
    summary, curves = _summary(trials)
    return summary, curves


def test_subsampling_a_curve_with_its_peak_on_an_odd_point_lowers_the_rise():
    # index 3 (an odd point: dropped by every 2nd) is the peak: 50 % above the minimum 0.2
    summary, curves = _growing([0.4, 0.3, 0.2, 0.3, 0.25, 0.22, 0.21, 0.2, 0.19], period=7)
    (r,) = conventions.subsampled_rise(curves, summary, (2, 4))
    assert r["where"] == "fig4 TG"
    # the full curve's rise is summary.parquet's
    s = summary.iloc[0]
    assert r["full"] == pytest.approx(100 * s["rise_abs_error_growth"]
                                      / (s["peak_abs_error_growth"] - s["rise_abs_error_growth"]))
    assert r["full"] == pytest.approx(50.0)
    assert r[2] == pytest.approx(25.0)  # 0.4, 0.2, 0.25, 0.21: 0.25 over 0.2
    assert r[4] == pytest.approx(0.0)  # 0.4, 0.25: never above the running minimum
    # a peak on an even point survives every 2nd point
    summary, curves = _growing([0.4, 0.3, 0.2, 0.25, 0.3, 0.22, 0.21], period=5)
    (r,) = conventions.subsampled_rise(curves, summary, (2,))
    assert r[2] == pytest.approx(r["full"]) == pytest.approx(50.0)


def _spec(pattern, body="arm5", fixed=1.0):
    return dict(body={"name": body}, epochs=1000, evals_per_decade=20,
                growth=dict(pattern=pattern, start_size=0.5, end_size=1.0, period=100,
                            fixed_scale=fixed))


def test_relative_error_normalisations_agree_for_proportional_growth():
    n = conventions.normalisations(_spec("proportional"))
    assert n["difference"] < 1e-12 and n["spread"] == pytest.approx((1.0, 1.0))
    n = conventions.normalisations(_spec("proportional", body="icub"))
    assert n["difference"] < 1e-12


@pytest.mark.parametrize("fixed", [1.0, 0.5])
def test_nonproportional_growth_has_unequal_segments_but_total_length_s(fixed):
    """Non-proportional growth scales the growing segments so that the total length is S x the
    full one (gbmodel.growth.factors): the segments differ from S, the normalisations do not."""
    n = conventions.normalisations(_spec("nonproportional", fixed=fixed))
    assert n["spread"][0] < 0.9 and n["spread"][1] > 1.1
    assert n["difference"] < 1e-12


def test_length_ratio_sees_a_growth_that_does_not_keep_the_total():
    """The measure can tell: only the growing segments at S, the others at full length."""
    body = gbmodel.make_body("arm5")
    S = 0.5
    scales = np.where(body.growing, S, 1.0)
    ratio = conventions.length_ratio(body, scales)
    assert ratio == pytest.approx((3 * 0.2 * S + 2 * 0.2) / 1.0)  # 0.7, not 0.5
    assert abs(S / ratio - 1) > 0.25
    assert conventions.length_ratio(body, np.full(body.m, S)) == pytest.approx(S)
    # segments of unequal length weigh by their length (the iCub's: sqrt(a^2 + d^2) of its DH)
    icub = gbmodel.make_body("icub")
    k = np.where(np.arange(icub.m) < 5, 0.5, 1.0)  # the torso and shoulder at half length
    seg = np.array([0.032, 0.0055, np.hypot(0.0233647, 0.1433), 0.10774, 0.0,
                    np.hypot(0.015, 0.15228), 0.015, 0.1373, 0.0, np.hypot(0.0625, 0.016)])
    assert conventions.length_ratio(icub, k) == pytest.approx((seg * k).sum() / seg.sum())
    assert conventions.length_ratio(icub, k) != pytest.approx(k.mean(), rel=1e-3)


def _agg(trials, spec):
    summary, curves = _summary(trials)
    return dict(summary=summary, curves=curves,
                models=dict(conditions={c: dict(spec=spec, trials={})
                                        for c in summary["condition"]}))


def test_table_rows_and_their_absence():
    rng = np.random.default_rng(1)
    trials = pd.concat([_curves("fig4", "const1.0", rng.uniform(0.01, 0.02, 5)),
                        _curves("fig4", "TG", rng.uniform(0.01, 0.02, 5), growth="proportional",
                                period=2)], ignore_index=True)
    aggs = {"fig4": _agg(trials, _spec("proportional")),
            "choices_arm5": _agg(trials, _spec("proportional"))}  # not a paper figure: ignored
    t = conventions.table(aggs, {"fig4": trials}, 3.0, {"fig3": [["fig4", "TG"]]})
    assert list(t.columns) == conventions.COLUMNS
    assert list(t["convention"]) == ["spread over trials", "failed to bootstrap",
                                     "Fig. 3 / 6 postures", "learning-curve sampling",
                                     "relative error (eq. 11)"]
    assert "0.894 for n = 5 (-10.6 %" in t["measured_effect"].iloc[0]
    assert "of 10:" in t["measured_effect"].iloc[1]
    md = conventions.markdown(t)
    assert md.startswith("## Reporting conventions: measured effect of the alternative")
    assert md.count("\n| ") == 1 + len(t)  # the header and one line per row
    # without the per-trial curves, the rows that need them are left out, not left blank
    t = conventions.table(aggs, {}, 3.0, {"fig3": [["fig4", "TG"]]})
    assert list(t["convention"]) == ["learning-curve sampling", "relative error (eq. 11)"]
    assert conventions.table({"choices_arm5": aggs["choices_arm5"]}, {"choices_arm5": trials},
                             3.0, {}).empty
