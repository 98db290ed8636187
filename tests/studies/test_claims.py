"""The table of claims and their per-trial measures, on synthetic trial curves with known
answers; the discussion's stamp."""
import dataclasses

import numpy as np
import pandas as pd
import pytest

from pipeline.studies import discussion, paper
from pipeline.measures import growth_peak
from pipeline.studies import claims
from pipeline.studies import scorecard as sc
from tests.studies.coverage_tables import covered

EPOCHS = np.array([1, 2, 5, 10, 11, 20, 50, 100])
SHORT = np.linspace(0.2, 0.01, len(EPOCHS))
LONG = np.linspace(0.4, 0.02, len(EPOCHS))
RISING = [0.2, 0.3, 0.4, 0.5, 0.45, 0.2, 0.1, 0.02]


def test_growth_peak_is_the_largest_rise_above_the_running_minimum():
    curve = pd.DataFrame(dict(epoch=EPOCHS, abs_error_mean=[5, 4, 3, 6, 5, 2, 2.5, 1]))
    assert growth_peak(curve) == (10, 6.0, 3.0)
    falling = pd.DataFrame(dict(epoch=EPOCHS, abs_error_mean=np.linspace(5, 1, len(EPOCHS))))
    assert growth_peak(falling)[2] == 0.0
    # the per-trial rise of the claims is the same measure, relative to the error before it
    assert claims.rise(np.array([5, 4, 3, 6, 5, 2, 2.5, 1.0])) == pytest.approx(1.0)


def _figure(grown, periods=(10,), n=4, noise=0.01, seed=3, paper=0.02):
    """Trials and summary of a figure: references falling from 0.2 (half size) and 0.4 m, and
    bodies grown over each of `periods` whose absolute error is `grown`."""
    rng = np.random.default_rng(seed)
    rows, summ = [], []
    base = dict(paper_final_abs_error=paper, n_bootstrap_failures=0, n_run_failures=0,
                n_diverged=0, n_trials=n)
    conds = [(f"TG{p}", np.asarray(grown, float), 1.0, "proportional", p) for p in periods]
    conds += [("const0.5", SHORT, 0.5, "none", 0), ("const1.0", LONG, 1.0, "none", 0)]
    for name, err, size, growth, period in conds:
        for t in range(n):
            e = err * (1 + noise * rng.standard_normal(len(EPOCHS)))
            rows += [dict(condition=name, trial=t, epoch=ep, abs_error=a, rel_error=a / size,
                          path_abs_error=a, uniform_abs_error=a)
                     for ep, a in zip(EPOCHS, e)]
        summ.append(dict(condition=name, growth=growth, growth_period=period, end_size=size,
                         **base))
    return pd.DataFrame(rows), pd.DataFrame(summ)


def _cells(*args, **kw):
    return sc.cells(sc.results({"figX": dict(zip(("trials", "summary"), _figure(*args, **kw)))},
                               table=_covered())).set_index("claim")


def _covered(coverage=0.95):
    """A coverage table that calibrates every measure at 3 trials (coverage >= 90 %: the 95 %
    t interval) or none."""
    return covered(coverage)


def test_a_body_that_rises_during_growth_and_then_learns_reproduces_the_claims():
    c = _cells(RISING)
    assert c.loc["rise", "verdict"] == sc.REPRODUCED
    assert c.loc["above_start", "verdict"] == sc.REPRODUCED
    assert c.loc["bootstrap", "verdict"] == sc.REPRODUCED


def test_the_final_error_is_judged_in_metres_with_every_reading_beside():
    # const0.5 ends at 10 mm: 0.5x the paper's 20 mm in metres (at most about it: reproduced),
    # 1.0x per unit size (the diagnostic), and below 1 / 1.5 under the two-sided reading
    t = sc.results({"figX": dict(zip(("trials", "summary"), _figure(RISING)))}, table=_covered())
    half = {r["reading"]: r for r in t if r["claim"] == "final" and r["where"] == "const0.5"}
    assert half[""]["value"] == pytest.approx(0.5, rel=0.02)
    assert half[""]["verdict"] == sc.REPRODUCED and half[""]["lo"] == -np.inf
    assert half["per unit size"]["value"] == pytest.approx(1.0, rel=0.02)
    assert half["per unit size"]["diagnostic"] and half["per unit size"]["verdict"] == sc.REPRODUCED
    assert half["metres, two-sided"]["verdict"] == sc.NOT
    full = next(r for r in t if r["claim"] == "final" and r["where"] == "const1.0"
                and r["reading"] == "")
    assert np.isfinite(full["lo"])  # two-sided at full size: too accurate fails too
    c = sc.cells(t).set_index("claim")
    assert c.loc["final", "verdict"] == sc.REPRODUCED
    assert "metres, two-sided: not reproduced" in c.loc["final", "others"]
    assert "per unit size" not in c.loc["final", "others"]  # the same verdict: not repeated
    assert "other readings: metres, two-sided" in sc.cell_text(c.loc["final"].to_dict())


def test_a_body_that_never_rises_fails_the_rise_claims_in_the_worst_condition():
    c = _cells(np.linspace(0.2, 0.02, len(EPOCHS)), periods=(10, 100))
    assert c.loc["rise", "verdict"] == sc.NOT
    assert c.loc["rise", "measures"] == 2 and c.loc["rise", "reproduced"] == 0
    assert "1 of" not in sc.cell_text(c.loc["rise"].to_dict() | dict(claim="rise"))


def test_the_cell_shows_the_worst_condition_and_k_of_n():
    # T_G = 10 rises, T_G = 100 does not: 1 of 2 reproduced, the worst is TG100
    trials, summary = _figure(RISING, periods=(10, 100))
    flat = trials["condition"] == "TG100"
    for column in ("abs_error", "path_abs_error", "uniform_abs_error"):
        trials.loc[flat, column] = trials.loc[flat, "epoch"].map(
            dict(zip(EPOCHS, np.linspace(0.2, 0.02, len(EPOCHS)))))
    c = sc.cells(sc.results({"figX": dict(trials=trials, summary=summary)},
                           table=_covered())).set_index("claim")
    assert c.loc["rise", "verdict"] == sc.NOT and c.loc["rise", "where"] == "TG100"
    assert (c.loc["rise", "reproduced"], c.loc["rise", "measures"]) == (1, 2)
    assert "(1 of 2 reproduced)" in sc.cell_text(c.loc["rise"].to_dict())


def test_above_both_references_is_not_measured_where_it_cannot_pass():
    t = sc.results({"figX": dict(zip(("trials", "summary"),
                                     _figure(RISING, periods=(10, 100))))}, table=_covered())
    assert {r["where"] for r in t if r["claim"] == "above_refs"} == {"TG100"}


def test_a_rebound_after_growth_is_degeneration():
    c = _cells([0.2, 0.3, 0.4, 0.5, 0.45, 0.05, 0.2, 0.02])
    assert c.loc["after", "verdict"] == sc.NOT


def test_without_a_calibrated_interval_nothing_is_decided():
    flat = np.linspace(0.2, 0.02, len(EPOCHS))
    res = sc.results({"figX": dict(zip(("trials", "summary"), _figure(flat)))},
                     table=_covered(0.80))
    cells = sc.cells(res).set_index("claim")
    assert cells.loc["rise", "verdict"] == sc.INCONCLUSIVE
    assert sc.UNCALIBRATED in cells.loc["rise", "note"]
    assert "inconclusive: interval not calibrated" in sc.cell_text(cells.loc["rise"].to_dict())
    assert cells.loc["bootstrap", "verdict"] == sc.REPRODUCED  # an exact count needs none
    ok = sc.cells(sc.results({"figX": dict(zip(("trials", "summary"), _figure(flat)))},
                             table=_covered(0.95))).set_index("claim")
    assert ok.loc["rise", "verdict"] == sc.NOT


def test_two_trials_are_not_a_verdict():
    res = sc.results({"figX": dict(zip(("trials", "summary"), _figure(RISING, n=2)))},
                     table=_covered())
    cards = sc.cells(res)
    judged = cards[cards["claim"] != "bootstrap"]
    assert set(judged["verdict"]) == {sc.NOT_A_VERDICT}
    assert judged["trials_to_decide"].isna().all()
    md = sc.markdown(cards, res, counted=["figX"])
    assert "our reading" not in md and "would decide" not in md
    assert "**Not a verdict**" in md


def test_diagnostics_are_shown_and_never_counted():
    cards = _cells(np.linspace(0.2, 0.02, len(EPOCHS))).reset_index()
    diag = cards[cards["diagnostic"]]
    assert set(diag["claim"]) >= {"above_start", "during"}
    n = sc.headline(cards)
    assert sum(n.values()) == int((~cards["diagnostic"]).sum())
    assert sum(sc.headline(cards, counted=["figY"]).values()) == 0
    md = sc.markdown(cards, [], counted=["figX"])
    assert "(diagnostic)" in md and f"**{n['reproduced']} reproduced" in md


def test_claims_csv_and_scorecard_csv_agree():
    """claims.csv's verdict of a cell is the verdict its measures in scorecard.csv give."""
    res = sc.results({"figX": dict(zip(("trials", "summary"),
                                       _figure(RISING, periods=(10, 100), noise=0.3))),
                      "figY": dict(zip(("trials", "summary"), _figure(RISING, noise=0.01)))},
                     table=_covered())
    table = sc.claims_table(sc.cells(res))
    per = pd.DataFrame(res)
    per = per[per["reading"] == ""]  # the cells are the primary reading's
    for r in table.to_dict("records"):
        vs = set(per[(per["figure"] == r["figure"]) & (per["claim"] == r["claim"])]["verdict"])
        want = (sc.NOT if sc.NOT in vs else sc.INCONCLUSIVE if sc.INCONCLUSIVE in vs
                else sc.REPRODUCED)
        assert r["verdict"] == want
        assert r["words"] == claims.BY_ID[r["claim"]].words


def test_every_claim_has_words_a_criterion_and_a_measure():
    assert len({c.id for c in claims.CLAIMS}) == len(claims.CLAIMS)
    for c in claims.CLAIMS:
        assert c.words and c.criterion and c.measure and c.figures
    md = paper.claims_markdown()
    assert md.count("\n") == len(claims.CLAIMS) + 2


def test_our_reading_is_shown_only_beside_the_verdicts_it_was_written_for():
    cards = pd.DataFrame([dict(claim="rise", figure="fig4", verdict=sc.REPRODUCED),
                          dict(claim="rise", figure="fig5", verdict=sc.NOT)])
    register = [dataclasses.replace(claims.BY_ID["rise"], our_reading=dict(
        written_for={"fig4": "reproduced", "fig5": "not reproduced"}, text="rises at T_G <= 100"))]
    assert paper.our_reading(cards, register) == {"rise": "rises at T_G <= 100"}
    cards.loc[1, "verdict"] = sc.INCONCLUSIVE
    assert "written for other verdicts: fig5: not reproduced, now inconclusive" \
        in paper.our_reading(cards, register)["rise"]


def test_the_committed_readings_name_known_claims():
    ours = {c.id: c.our_reading for c in claims.CLAIMS if c.our_reading}
    assert set(ours) >= {"final", "rise", "stages"}
    for o in ours.values():
        assert o["text"] and set(o["written_for"]) <= {"fig2", "fig4", "fig5", "fig7",
                                                       "fig7_20trials"}


def test_the_discussion_is_shown_only_beside_the_numbers_it_was_written_for(tmp_path,
                                                                            monkeypatch):
    """findings.md is included when findings_numbers.csv matches the run (the same rows and
    verdicts, numbers within discussion.TOLERANCE), and left out otherwise, or when nothing was
    stamped."""
    text = "## Why\n\nBecause 17.5 mm.\n"
    (tmp_path / "findings.md").write_text(text)
    monkeypatch.setattr(discussion, "FINDINGS", tmp_path / "findings.md")
    monkeypatch.setattr(discussion, "FINDINGS_NUMBERS", tmp_path / "findings_numbers.csv")
    trials, summary = _figure(RISING)
    summary["figure"] = "figX"
    for col in discussion.FINDINGS_COLUMNS:
        summary[col] = 0.01
    rows = sc.claims_table(sc.cells(sc.results({"figX": dict(trials=trials, summary=summary)},
                                               table=_covered()))).to_dict("records")
    assert "left out" in discussion.findings(summary, rows)  # nothing stamped yet
    discussion.stamp_findings(summary, rows)
    assert discussion.findings(summary, rows) == text
    other = summary.copy()
    other.loc[0, "final_abs_error_mean"] *= 1 + 1e-4  # another run
    assert "left out" in discussion.findings(other, rows)
    assert "left out" in discussion.findings(summary.iloc[:2], rows)  # a condition fewer
    flipped = [dict(r, verdict="not reproduced") for r in rows]
    assert flipped != rows and "left out" in discussion.findings(summary, flipped)


def _stages(spread):
    import gbmodel

    exps = gbmodel.exponents(1)
    start = np.zeros((2, len(exps)))
    start[0, 0] = spread  # g(x) = home + (spread, 0) everywhere
    final = np.zeros((2, len(exps)))
    final[0, 1] = np.pi / 2  # q1 = pi/2 * x: reaches heights +-1 m exactly, and 0 at home
    spec = dict(body=dict(name="arm2"), growth=dict(pattern="proportional", end_size=1.0),
                learner=dict(name="goal_babbling", degree=3))
    return spec, [start, final]


@pytest.mark.parametrize("spread, verdict", [(0.06, "reproduced"), (0.5, "not reproduced")])
def test_fig2_stages_start_near_home(spread, verdict):
    spec, ms = _stages(spread)
    tests = claims.judge(claims.stage_measures("fig2", spec, [ms] * 3))
    res = [sc.run_test(t, _covered()) for t in tests]
    home = next(r for r in res if r["claim"] == "stages_home")
    assert home["verdict"] == verdict and home["diagnostic"]
    extremes = next(r for r in res if r["claim"] == "stages")
    assert extremes["verdict"] == "reproduced" and extremes["unit"] == "m"
    assert sc.fmt(0.0745, "m") == "74.5 mm"


def test_fig2_extremes_need_three_trials():
    spec, ms = _stages(0.06)
    tests = claims.judge(claims.stage_measures("fig2", spec, [ms] * 2))
    res = [sc.run_test(t, _covered()) for t in tests]
    assert next(r for r in res if r["claim"] == "stages")["verdict"] == sc.NOT_A_VERDICT


def test_a_trials_jitter_is_no_rebound_but_a_lasting_one_is():
    x = np.linspace(1.0, 0.5, 40)
    jitter = x * (1 + 0.15 * (-1) ** np.arange(40))  # +-15 % from point to point
    assert claims.rebound(jitter) > 0.3 and claims.rebound(claims.smooth(jitter)) < 0.1
    lasting = x.copy()
    lasting[20:] *= 1.5  # a step up that stays
    assert claims.rebound(claims.smooth(lasting)) > 0.3
    assert claims.smooth(x[:9]).shape == (9,)  # too short to smooth


def test_per_trial_is_the_pivot_of_a_conditions_rows():
    """claims.per_trial (each table grouped once, the curves placed by numpy) gives what the
    pivot of the condition's rows gives: trials and epochs ascending, an epoch some trial lacks
    (or holds as NaN) dropped, the same values to the bit; an epoch twice is an error."""
    rng = np.random.default_rng(5)
    rows = [dict(condition=c, trial=t, epoch=e, abs_error=rng.random())
            for c in ("TG10", "const1.0") for t in (2, 0, 1) for e in (50, 1, 10, 5, 100)
            if not (c == "TG10" and t == 1 and e == 5)]
    rows[0]["abs_error"] = np.nan  # TG10, trial 2, epoch 50
    trials = pd.DataFrame(rows).sample(frac=1.0, random_state=1).reset_index(drop=True)
    for c in ("TG10", "const1.0", "absent"):
        want = trials[trials["condition"] == c].pivot(
            index="trial", columns="epoch", values="abs_error").sort_index(axis=1).dropna(axis=1)
        epochs, values = claims.per_trial(trials, c, "abs_error")
        assert epochs.dtype == want.columns.dtype and values.dtype == want.to_numpy().dtype
        assert epochs.tolist() == want.columns.tolist()
        assert values.tobytes() == want.to_numpy().tobytes() and values.shape == want.shape
    assert claims.per_trial(trials, "TG10", "abs_error")[0].tolist() == [1, 10, 100]
    twice = pd.concat([trials, trials.iloc[:1]], ignore_index=True)
    with pytest.raises(ValueError, match="twice"):
        claims.per_trial(twice, trials["condition"].iloc[0], "abs_error")
