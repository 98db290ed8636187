"""The scorecard's verdicts with uncertainty, on constructed data with known answers."""
import numpy as np
import pandas as pd
import pytest

from pipeline.studies import scorecard as sc
from tests.studies.coverage_tables import covered


COVERED = covered()


def _test(values, lo=0.9, hi=1.1):
    t = sc.Test("figX", "final", "c", np.asarray(values, float), lo, hi, unit="x", kind="final")
    return sc.run_test(t, COVERED)


def test_the_point_lies_inside_its_interval():
    rng = np.random.default_rng(5)
    for n in (2, 3, 5, 20):
        for scale in (0.01, 1.0):
            r = _test(1 + scale * rng.lognormal(size=n))
            assert r["low"] <= r["value"] <= r["high"]


def test_a_clear_pass_a_clear_fail_and_a_straddle():
    rng = np.random.default_rng(0)
    tight = 1.0 + 0.01 * rng.standard_normal(20)  # all trials near 1.0: within [0.9, 1.1]
    far = 1.5 + 0.01 * rng.standard_normal(20)  # all near 1.5: outside
    wide = 1.1 + 0.2 * rng.standard_normal(6)  # around the bound 1.1, wide: straddles
    assert _test(tight)["verdict"] == sc.REPRODUCED
    assert _test(far)["verdict"] == sc.NOT
    r = _test(wide)
    assert r["verdict"] == sc.INCONCLUSIVE
    assert r["low"] < 1.1 < r["high"]


def test_the_verdict_follows_the_interval_not_the_mean():
    # the mean (1.05) lies within the criterion, but the interval reaches beyond it
    r = _test([0.8, 1.3, 0.9, 1.2, 1.05])
    assert 0.9 < r["value"] < 1.1 and r["verdict"] == sc.INCONCLUSIVE
    assert sc.verdict(0.95, 1.05, 0.9, 1.1) == sc.REPRODUCED
    assert sc.verdict(1.2, 1.3, 0.9, 1.1) == sc.NOT
    assert sc.verdict(1.0, 1.2, 0.9, 1.1) == sc.INCONCLUSIVE
    assert sc.verdict(np.nan, np.nan, 0.9, 1.1) == sc.INCONCLUSIVE  # one trial: no interval


def test_trials_to_decide_at_the_observed_spread():
    # point 1.0, bound 1.1 at distance 0.1, half-width toward it 0.2 with 5 trials:
    # the half-width must shrink by 2, i.e. 4 x the trials
    assert sc.trials_to_decide(1.0, 0.9, 1.2, -np.inf, 1.1, 5) == 20
    assert sc.trials_to_decide(1.0, 0.95, 1.05, -np.inf, 1.1, 5) is None  # decided already
    assert sc.trials_to_decide(1.1, 1.0, 1.2, -np.inf, 1.1, 5) is None  # on the bound
    # and the estimate holds: that many trials of the same spread decide the straddle
    rng = np.random.default_rng(1)
    base = rng.standard_normal(400)
    small = 1.04 + 0.1 * (base[:5] - base[:5].mean()) / base[:5].std(ddof=1)
    r = _test(small, lo=-np.inf, hi=1.1)
    assert r["verdict"] == sc.INCONCLUSIVE and r["trials_to_decide"] > 5
    n = r["trials_to_decide"]
    big = 1.04 + 0.1 * (base[:2 * n] - base[:2 * n].mean()) / base[:2 * n].std(ddof=1)
    assert _test(big, lo=-np.inf, hi=1.1)["verdict"] == sc.REPRODUCED


def test_the_interval_is_byte_stable():
    v = np.linspace(0.8, 1.2, 7)
    assert _test(v) == _test(v)


def _figure(n_trials, noise):
    """A figure's trial curves: two references and a body grown over 10 epochs that rises to
    twice its start error, `noise` the trials' relative spread."""
    rng = np.random.default_rng(3)
    epochs = np.array([1, 2, 5, 10, 11, 20, 50, 100])
    short = np.linspace(0.2, 0.01, len(epochs))
    long_ = np.linspace(0.4, 0.02, len(epochs))
    grown = np.array([0.2, 0.3, 0.4, 0.5, 0.45, 0.2, 0.1, 0.02])
    rows = []
    for name, err, size in [("TG10", grown, 1.0), ("const0.5", short, 0.5),
                            ("const1.0", long_, 1.0)]:
        for t in range(n_trials):
            e = err * (1 + noise * rng.standard_normal(len(epochs)))
            rows += [dict(condition=name, trial=t, epoch=ep, abs_error=a, rel_error=a / size,
                          path_abs_error=a, uniform_abs_error=a)
                     for ep, a in zip(epochs, e)]
    base = dict(paper_final_abs_error=0.02, n_bootstrap_failures=0, n_run_failures=0,
                n_diverged=0, n_trials=n_trials)
    summary = pd.DataFrame([
        dict(condition="TG10", growth="proportional", growth_period=10, end_size=1.0, **base),
        dict(condition="const0.5", growth="none", growth_period=0, end_size=0.5, **base),
        dict(condition="const1.0", growth="none", growth_period=0, end_size=1.0, **base)])
    return dict(trials=pd.DataFrame(rows), summary=summary)


def test_growth_claims_on_trial_curves():
    res = sc.results({"figX": _figure(8, 0.01)}, table=COVERED)
    cards = sc.cells(res).set_index("claim")
    assert cards.loc["rise", "verdict"] == sc.REPRODUCED
    assert cards.loc["above_start", "verdict"] == sc.REPRODUCED
    # const0.5 ends at 10 mm on a half-size body: 20 mm per full size, the paper's value
    assert cards.loc["final", "verdict"] == sc.REPRODUCED
    assert cards.loc["bootstrap", "verdict"] == sc.REPRODUCED
    md = sc.markdown(sc.cells(res), res)
    assert "| claim of the paper | figX |" in md and "our reading" not in md
    md = sc.markdown(sc.cells(res), res, readings={"rise": "it rises"})
    assert "| claim of the paper | figX | our reading |" in md and "it rises" in md
    for r in res:  # no measure's point lies outside its interval
        assert r["claim"] == "bootstrap" or r["low"] <= r["value"] <= r["high"]
    # one trial per condition: no interval, so nothing is decided but the exact count
    one = sc.cells(sc.results({"figX": _figure(1, 0.01)}, table=COVERED)).set_index("claim")
    assert set(one.drop(index="bootstrap")["verdict"]) == {sc.NOT_A_VERDICT}


def test_the_scorecard_figure_draws_every_cell(tmp_path):
    cards = sc.cells(sc.results({"figX": _figure(4, 0.05), "figY": _figure(4, 0.3)},
                                table=COVERED))
    fig = sc.figure(cards, "scorecard")
    assert len(fig.axes[0].patches) == len(cards["claim"].unique()) * 2
    # every trial of a judged spread is a dot: 4 per cell, but the exact failure count's
    dots = sum(len(c.get_offsets()) for c in fig.axes[0].collections)
    assert dots == 4 * int((cards["claim"] != "bootstrap").sum())
    fig.savefig(tmp_path / "s.png")


def test_each_reading_of_the_readings_study_gets_its_own_intervals():
    from pipeline.studies import readings
    parts = {"tight": _figure(6, 0.01), "noisy": _figure(3, 0.8)}
    trials, summaries = [], []
    for label, f in parts.items():
        t, s = f["trials"].copy(), f["summary"].copy()
        t["condition"] = label + " | " + t["condition"]
        s["condition"] = label + " | " + s["condition"]
        s["variant"] = label
        trials.append(t)
        summaries.append(s)
    agg = dict(trials=pd.concat(trials), summary=pd.concat(summaries))
    t = readings.intervals({"readings_fig4": agg}).set_index(["reading", "claim"])
    assert t.loc[("tight", "rise"), "verdict"] == sc.REPRODUCED
    assert t.loc[("tight", "rise"), "trials"] == 6
    assert t.loc[("noisy", "rise"), "verdict"] != sc.REPRODUCED  # the spread hides the rise
    md = readings.intervals_markdown(readings.intervals({"readings_fig4": agg}))
    assert "(6 trials per condition and reading)" in md and "| noisy |" in md


def test_no_estimate_of_trials_to_decide_beyond_a_thousand():
    # point 1.0, bound 1.1, half-width 10 toward it on 2 trials: 20,000 trials is no estimate
    assert sc.trials_to_decide(1.0, -9.0, 11.0, -np.inf, 1.1, 2) is None
    assert sc.trials_to_decide(1.0, 0.9, 1.2, -np.inf, 1.1, 5) == 20


def test_a_reduced_scale_run_decides_nothing():
    res = sc.no_verdicts(sc.results({"figX": _figure(20, 0.01)}, table=COVERED), "smoke")
    cards = sc.cells(res)
    assert set(cards["verdict"]) == {sc.NOT_A_VERDICT}
    md = sc.markdown(cards, res, counted=["figX"])
    assert "**no verdict" in md and "would decide" not in md and "our reading" not in md
    assert "**reproduced**" not in md and "**not reproduced**" not in md
